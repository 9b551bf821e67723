// hz.shader/1: glass. Lights give a GGX reflection lobe (hz_shade / the CPU
// reference); the environment gives reflection and, through a slab of the
// given thickness, the refracted scene behind, attenuated by Beer-Lambert
// absorption (hz_ambient): F * reflected + (1 - F) * T * refracted.
#include "glass_model.hpp"

#include <hz/cpp/plugin.hpp>

#include <cstring>

namespace {

constexpr const char *kId = "org.horizon.shader.glass";

const char *const kFresnelModes[] = {"exact", "schlick", nullptr};
const hz_param_info kParams[] = {
    {sizeof(hz_param_info),
     HZ_PARAM_COLOR3,
     "tint",
     "Tint",
     "Absorption",
     "",
     "transmittance through 1 mm at concentration 1 (sets alpha = -ln(tint) per mm)",
     0,
     3,
     {0, 0, 0, 0},
     {1, 1, 1, 0},
     {0.93, 0.97, 1.0, 0},
     nullptr,
     0,
     nullptr},
    {sizeof(hz_param_info),
     HZ_PARAM_FLOAT,
     "ior",
     "Index of refraction",
     "Optics",
     "",
     "relative index n_t / n_i",
     0,
     1,
     {1, 0, 0, 0},
     {3, 0, 0, 0},
     {1.5, 0, 0, 0},
     nullptr,
     0,
     nullptr},
    {sizeof(hz_param_info),
     HZ_PARAM_FLOAT,
     "roughness",
     "Roughness",
     "Optics",
     "",
     "blur of reflections and refractions",
     0,
     1,
     {0, 0, 0, 0},
     {1, 0, 0, 0},
     {0.05, 0, 0, 0},
     nullptr,
     0,
     nullptr},
    {sizeof(hz_param_info),
     HZ_PARAM_FLOAT,
     "thickness",
     "Thickness",
     "Absorption",
     "mm",
     "slab thickness the light crosses",
     0,
     1,
     {0, 0, 0, 0},
     {50, 0, 0, 0},
     {2, 0, 0, 0},
     nullptr,
     0,
     nullptr},
    {sizeof(hz_param_info),
     HZ_PARAM_FLOAT,
     "concentration",
     "Concentration",
     "Absorption",
     "",
     "absorber concentration c of Eq. 14",
     0,
     1,
     {0, 0, 0, 0},
     {10, 0, 0, 0},
     {1, 0, 0, 0},
     nullptr,
     0,
     nullptr},
    {sizeof(hz_param_info),
     HZ_PARAM_ENUM,
     "fresnel",
     "Fresnel",
     "Optics",
     "",
     "exact dielectric Fresnel or Schlick's approximation",
     0,
     1,
     {0, 0, 0, 0},
     {1, 0, 0, 0},
     {0, 0, 0, 0},
     kFresnelModes,
     0,
     nullptr},
};
constexpr uint32_t kParamCount = sizeof kParams / sizeof kParams[0];
constexpr uint32_t kValueCount = 8;

const hz_param_info *HZ_ABI get_param(uint32_t i) { return i < kParamCount ? &kParams[i] : nullptr; }

const char kGlsl[] = R"glsl(
const float glass_PI = 3.14159265358979;

float glass_fresnel_exact(float c, float eta) {
    c = clamp(c, 0.0, 1.0);
    float s2 = (1.0 - c * c) / (eta * eta);
    if (s2 >= 1.0) return 1.0;
    float ct = sqrt(1.0 - s2);
    float rs = (c - eta * ct) / (c + eta * ct);
    float rp = (eta * c - ct) / (eta * c + ct);
    return clamp(0.5 * (rs * rs + rp * rp), 0.0, 1.0);
}
float glass_fresnel(float c, float eta) {
    if (u_fresnel == 1) {
        float f0 = (eta - 1.0) / (eta + 1.0);
        f0 *= f0;
        float m = clamp(1.0 - c, 0.0, 1.0);
        float m2 = m * m;
        return f0 + (1.0 - f0) * m2 * m2 * m;
    }
    return glass_fresnel_exact(c, eta);
}
bool glass_normalize(inout vec3 a) {
    float m = max(max(abs(a.x), abs(a.y)), abs(a.z));
    if (!(m > 0.0) || isinf(m) || isnan(m)) return false;
    a = a / m;
    a = a / sqrt(dot(a, a));
    return true;
}

vec3 hz_shade(HzShadePoint p) {
    vec3 n = p.n, l = p.l, v = p.v;
    if (!glass_normalize(n) || !glass_normalize(l) || !glass_normalize(v)) return vec3(0.0);
    float NoL = dot(n, l), NoV = dot(n, v);
    if (!(NoL > 0.0) || !(NoV > 0.0)) return vec3(0.0);
    vec3 h = l + v;
    if (!glass_normalize(h)) return vec3(0.0);
    float NoH = dot(n, h), VoH = clamp(dot(v, h), 0.0, 1.0);
    float r = clamp(u_roughness, 0.0, 1.0);
    float a = max(0.001, r * r), aa = a * a;
    vec3 nxh = cross(n, h);
    float dd = dot(nxh, nxh) + aa * NoH * NoH;
    float D = aa / (glass_PI * dd * dd);
    float vl = 1.0 / (NoL + sqrt(aa * (1.0 - NoL * NoL) + NoL * NoL));
    float vv = 1.0 / (NoV + sqrt(aa * (1.0 - NoV * NoV) + NoV * NoV));
    float F = glass_fresnel(VoH, clamp(u_ior, 1.0, 3.0));
    return vec3(D * vl * vv * F);
}

vec3 hz_ambient(HzShadePoint p) {
    vec3 n = p.n, v = p.v;
    if (!glass_normalize(n) || !glass_normalize(v)) return vec3(0.0);
    float NoV = dot(n, v);
    if (!(NoV > 0.0)) return vec3(0.0);
    float eta = clamp(u_ior, 1.0, 3.0);
    float F = glass_fresnel(NoV, eta);
    float r = clamp(u_roughness, 0.0, 1.0);
    vec3 reflected = hz_env_radiance(2.0 * NoV * n - v, r);
    // Refraction through a slab: the path d / cos(theta_t), Beer-Lambert
    // per channel with alpha = -ln(tint) per mm.
    float s2 = (1.0 - NoV * NoV) / (eta * eta);
    float ct = sqrt(max(1.0 - s2, 0.0));
    float path = max(u_thickness, 0.0) / max(ct, 1e-3);
    vec3 alpha = -log(clamp(u_tint, vec3(1e-4), vec3(1.0)));
    vec3 T = exp(-alpha * path * max(u_concentration, 0.0));
    vec3 t = refract(-v, n, 1.0 / eta);
    vec2 shift = (hz_view_rotation * (t + v)).xy * (4.0 * max(u_thickness, 0.0) + 6.0);
    vec3 refracted = hz_scene_behind(shift);
    return F * reflected + (1.0 - F) * T * refracted;
}
)glsl";

const char *HZ_ABI glsl_source(hz_shade_domain domain, uint32_t) { return domain == HZ_SHADE_SURFACE ? kGlsl : nullptr; }

hz_status HZ_ABI eval_reference(const hz_shade_point *sp, const double *q, uint32_t count, double out[3]) {
    if (sp == nullptr || q == nullptr || out == nullptr || count < kValueCount) return HZ_E_INVALID_ARGUMENT;
    auto v3 = [](const double *a) { return glass::V3{a[0], a[1], a[2]}; };
    const glass::V3 f = glass::reflection_brdf(q[3], q[4], q[7] >= 0.5, v3(sp->n), v3(sp->l), v3(sp->v));
    std::copy(f.begin(), f.end(), out);
    return HZ_OK;
}

const char *const kFunctions[] = {"beer_lambert(alpha[3], length, concentration)", "fresnel_dielectric(cos_i, eta)",
                                  "fresnel_schlick(f0, cos_i)", "slab_path_length(d, cos_i, eta)", nullptr};

hz_status HZ_ABI eval_function(const char *name, const double *a, uint32_t n, double out[3]) {
    if (name == nullptr || out == nullptr || (n > 0 && a == nullptr)) return HZ_E_INVALID_ARGUMENT;
    auto all = [&](double x) { out[0] = out[1] = out[2] = x; };
    if (std::strcmp(name, "beer_lambert") == 0) {
        if (n != 5) return HZ_E_INVALID_ARGUMENT;
        for (int i = 0; i < 3; ++i) out[i] = glass::beer_lambert(a[i], a[3], a[4]);
    } else if (std::strcmp(name, "fresnel_dielectric") == 0) {
        if (n != 2) return HZ_E_INVALID_ARGUMENT;
        all(glass::fresnel_dielectric(a[0], a[1]));
    } else if (std::strcmp(name, "fresnel_schlick") == 0) {
        if (n != 2) return HZ_E_INVALID_ARGUMENT;
        all(glass::fresnel_schlick(a[0], a[1]));
    } else if (std::strcmp(name, "slab_path_length") == 0) {
        if (n != 3) return HZ_E_INVALID_ARGUMENT;
        all(glass::slab_path_length(a[0], a[1], a[2]));
    } else {
        return HZ_E_NOT_FOUND;
    }
    return HZ_OK;
}

const hz_shader kShader = {
    .struct_size = sizeof(hz_shader),
    .domains = HZ_SHADE_SURFACE,
    .output = HZ_SHADER_OUTPUT_BRDF,
    .claims = HZ_CLAIM_NONNEGATIVE | HZ_CLAIM_RECIPROCAL,
    .glsl_prefix = "glass_",
    .param_count = kParamCount,
    .get_param = get_param,
    .glsl_source = glsl_source,
    .eval_reference = eval_reference,
    .functions = kFunctions,
    .eval_function = eval_function,
    .display = HZ_SHADER_DISPLAY_TONE_MAPPED,
    .reserved0 = 0,
};
const char *const kInterfaces[] = {HZ_INTERFACE_SHADER, nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_SHADER,
    .id = kId,
    .name = "Glass",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description =
        "Glass: Fresnel reflection and refraction of the environment and the scene behind, Beer-Lambert absorption (paper Eq. 14)",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kShader>::entry;
