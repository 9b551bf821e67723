// hz.shader/1: Lambert, Blinn-Phong (classic and normalised BRDF) and the two
// illuminated-line models, one library with five plugins. classic_models.hpp
// holds the CPU references; each GLSL snippet is the same function.
#include "classic_models.hpp"

#include <hz/cpp/plugin.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace {

constexpr hz_param_info color(const char *name, const char *label, const char *tip, double r, double g, double b) {
    return {sizeof(hz_param_info), HZ_PARAM_COLOR3, name,         label,   "", "",     tip, 0, 3,
            {0, 0, 0, 0},          {1, 1, 1, 0},    {r, g, b, 0}, nullptr, 0,  nullptr};
}
constexpr hz_param_info scalar(const char *name, const char *label, const char *tip, double lo, double hi, double def) {
    return {sizeof(hz_param_info), HZ_PARAM_FLOAT, name,           label,   "", "",     tip, HZ_PARAM_FLAG_LOG_SCALE, 1,
            {lo, 0, 0, 0},         {hi, 0, 0, 0},  {def, 0, 0, 0}, nullptr, 0,  nullptr};
}

const hz_param_info kLambertParams[] = {color("albedo", "Albedo", "linear diffuse reflectance", 0.8, 0.8, 0.8)};
const hz_param_info kBlinnParams[] = {color("kd", "Diffuse", "diffuse colour", 0.6, 0.6, 0.6),
                                      color("ks", "Specular", "specular colour", 0.3, 0.3, 0.3),
                                      color("ka", "Ambient", "ambient term, added as is", 0.02, 0.02, 0.02),
                                      scalar("shininess", "Shininess", "Blinn exponent", 1, 10000, 32)};
const hz_param_info kBlinnBrdfParams[] = {color("kd", "Diffuse", "diffuse albedo", 0.6, 0.6, 0.6),
                                          color("ks", "Specular", "specular albedo", 0.3, 0.3, 0.3),
                                          scalar("shininess", "Shininess", "Blinn exponent", 1, 10000, 32)};
const hz_param_info kStallingParams[] = {color("kd", "Diffuse", "diffuse colour", 0.7, 0.4, 0.2),
                                         color("ks", "Specular", "specular colour", 0.4, 0.4, 0.4),
                                         color("ka", "Ambient", "ambient term, added as is", 0.02, 0.02, 0.02),
                                         scalar("shininess", "Shininess", "specular exponent", 1, 10000, 32),
                                         scalar("p_diffuse", "Diffuse exponent", "Zoeckler et al.'s exponent on L.N", 1, 100, 1)};
const hz_param_info kMalloParams[] = {color("kd", "Diffuse", "diffuse albedo", 0.7, 0.4, 0.2)};
const hz_param_info kFlatParams[] = {color("color", "Colour", "the radiance shown, unlit", 0.8, 0.8, 0.8)};

// The surface models below skip normalising n, l, v where the host passes
// them as unit vectors (HZ_UNIT_VECTORS) and select instead of branching
// (llvmpipe pays for both sides of a branch).
#define CLASSIC_UNIT_NLV                                                     \
    "#ifdef HZ_UNIT_VECTORS\n"                                               \
    "    vec3 n = p.n, l = p.l, v = p.v;\n"                                  \
    "#else\n"                                                                \
    "    vec3 n = normalize(p.n), l = normalize(p.l), v = normalize(p.v);\n" \
    "#endif\n"
const char kLambertGlsl[] = "vec3 hz_shade(HzShadePoint p) {\n" CLASSIC_UNIT_NLV R"glsl(
    bool lit = dot(n, l) > 0.0 && dot(n, v) > 0.0;
    return lit ? max(u_albedo, vec3(0.0)) * 0.3183098861837907 : vec3(0.0);
}
)glsl";
const char kFlatGlsl[] = R"glsl(
vec3 hz_shade(HzShadePoint p) { return max(u_color, vec3(0.0)); }
)glsl";
const char kBlinnGlsl[] = "vec3 hz_shade(HzShadePoint p) {\n" CLASSIC_UNIT_NLV R"glsl(
    float NoL = dot(n, l), NoV = dot(n, v);
    vec3 h = l + v;
    float NoH = dot(h, h) > 0.0 ? max(dot(n, normalize(h)), 0.0) : 0.0;
    float spec = (NoL > 0.0 && NoV > 0.0) ? pow(NoH, max(u_shininess, 1.0)) : 0.0;
    return max(u_ka, vec3(0.0)) + max(u_kd, vec3(0.0)) * max(NoL, 0.0) + max(u_ks, vec3(0.0)) * spec;
}
)glsl";
const char kBlinnBrdfGlsl[] = "vec3 hz_shade(HzShadePoint p) {\n" CLASSIC_UNIT_NLV R"glsl(
    bool lit = dot(n, l) > 0.0 && dot(n, v) > 0.0;
    float s = max(u_shininess, 1.0);
    float NoH = max(dot(n, normalize(l + v)), 0.0);
    vec3 f = max(u_kd, vec3(0.0)) * 0.3183098861837907 + max(u_ks, vec3(0.0)) * (s + 8.0) / 25.132741228718345 * pow(NoH, s);
    return lit ? f : vec3(0.0);
}
)glsl";
const char kStallingGlsl[] = R"glsl(
vec3 hz_shade(HzShadePoint p) {
    vec3 t = normalize(p.t), l = normalize(p.l), v = normalize(p.v);
    float LoT = clamp(dot(l, t), -1.0, 1.0), VoT = clamp(dot(v, t), -1.0, 1.0);
    float LoN = sqrt(max(0.0, 1.0 - LoT * LoT));
    float VoR = LoN * sqrt(max(0.0, 1.0 - VoT * VoT)) - LoT * VoT;
    return max(u_ka, vec3(0.0)) + max(u_kd, vec3(0.0)) * pow(LoN, max(u_p_diffuse, 1e-6)) +
           max(u_ks, vec3(0.0)) * pow(max(VoR, 0.0), max(u_shininess, 1.0));
}
)glsl";
const char kMalloGlsl[] = R"glsl(
vec3 hz_shade(HzShadePoint p) {
    vec3 t = normalize(p.t), l = normalize(p.l), v = normalize(p.v);
    float LoT = clamp(dot(l, t), -1.0, 1.0), VoT = clamp(dot(v, t), -1.0, 1.0);
    float sinL = sqrt(max(0.0, 1.0 - LoT * LoT));
    vec3 lp = l - LoT * t, vp = v - VoT * t;
    float f;
    if (length(vp) < 1e-6) f = sinL * 0.3183098861837907;
    else if (length(lp) < 1e-30) f = 0.0;
    else {
        float a = acos(clamp(dot(normalize(lp), normalize(vp)), -1.0, 1.0));
        f = sinL * (sin(a) + (3.14159265358979 - a) * cos(a)) * 0.25;
    }
    return max(u_kd, vec3(0.0)) * max(f, 0.0);
}
)glsl";

using classic::V3;
V3 v3(const double *a) { return {a[0], a[1], a[2]}; }

hz_status HZ_ABI eval_lambert(const hz_shade_point *p, const double *q, uint32_t n, double out[3]) {
    if (!p || !q || !out || n < 3) return HZ_E_INVALID_ARGUMENT;
    const V3 f = classic::lambert(v3(q), v3(p->n), v3(p->l), v3(p->v));
    std::copy(f.begin(), f.end(), out);
    return HZ_OK;
}
hz_status HZ_ABI eval_flat(const hz_shade_point *p, const double *q, uint32_t n, double out[3]) {
    if (!p || !q || !out || n < 3) return HZ_E_INVALID_ARGUMENT;
    for (int i = 0; i < 3; ++i) out[i] = std::isfinite(q[i]) ? std::max(q[i], 0.0) : 0.0;
    return HZ_OK;
}
hz_status HZ_ABI eval_blinn(const hz_shade_point *p, const double *q, uint32_t n, double out[3]) {
    if (!p || !q || !out || n < 10) return HZ_E_INVALID_ARGUMENT;
    const V3 f = classic::blinn_phong(v3(q), v3(q + 3), v3(q + 6), q[9], v3(p->n), v3(p->l), v3(p->v));
    std::copy(f.begin(), f.end(), out);
    return HZ_OK;
}
hz_status HZ_ABI eval_blinn_brdf(const hz_shade_point *p, const double *q, uint32_t n, double out[3]) {
    if (!p || !q || !out || n < 7) return HZ_E_INVALID_ARGUMENT;
    const V3 f = classic::blinn_phong_brdf(v3(q), v3(q + 3), q[6], v3(p->n), v3(p->l), v3(p->v));
    std::copy(f.begin(), f.end(), out);
    return HZ_OK;
}
hz_status HZ_ABI eval_stalling(const hz_shade_point *p, const double *q, uint32_t n, double out[3]) {
    if (!p || !q || !out || n < 11) return HZ_E_INVALID_ARGUMENT;
    const V3 f = classic::line_stalling(v3(q), v3(q + 3), v3(q + 6), q[9], q[10], v3(p->t), v3(p->l), v3(p->v));
    std::copy(f.begin(), f.end(), out);
    return HZ_OK;
}
hz_status HZ_ABI eval_mallo(const hz_shade_point *p, const double *q, uint32_t n, double out[3]) {
    if (!p || !q || !out || n < 3) return HZ_E_INVALID_ARGUMENT;
    const V3 f = classic::line_mallo_diffuse(v3(q), v3(p->t), v3(p->l), v3(p->v));
    std::copy(f.begin(), f.end(), out);
    return HZ_OK;
}

template <const hz_param_info *P, uint32_t N>
const hz_param_info *HZ_ABI params(uint32_t i) {
    return i < N ? &P[i] : nullptr;
}
template <const char *G, hz_shade_domain D>
const char *HZ_ABI glsl(hz_shade_domain d, uint32_t) {
    return (d & D) ? G : nullptr;
}

constexpr uint32_t kReciprocal = HZ_CLAIM_NONNEGATIVE | HZ_CLAIM_RECIPROCAL;
const hz_shader kShaders[] = {
    {
        .struct_size = sizeof(hz_shader),
        .domains = HZ_SHADE_SURFACE,
        .output = HZ_SHADER_OUTPUT_BRDF,
        .claims = kReciprocal,
        .glsl_prefix = "lambert_",
        .param_count = 1,
        .get_param = params<kLambertParams, 1>,
        .glsl_source = glsl<kLambertGlsl, HZ_SHADE_SURFACE>,
        .eval_reference = eval_lambert,
        .functions = nullptr,
        .eval_function = nullptr,
        .display = HZ_SHADER_DISPLAY_TONE_MAPPED,
        .reserved0 = 0,
    },
    {
        .struct_size = sizeof(hz_shader),
        .domains = HZ_SHADE_SURFACE,
        .output = HZ_SHADER_OUTPUT_RADIANCE_FACTOR,
        .claims = HZ_CLAIM_NONNEGATIVE,
        .glsl_prefix = "blinn_",
        .param_count = 4,
        .get_param = params<kBlinnParams, 4>,
        .glsl_source = glsl<kBlinnGlsl, HZ_SHADE_SURFACE>,
        .eval_reference = eval_blinn,
        .functions = nullptr,
        .eval_function = nullptr,
        .display = HZ_SHADER_DISPLAY_AS_IS,  // (non-PBR: the user's colours, not a filmic curve's)
        .reserved0 = 0,
    },
    {
        .struct_size = sizeof(hz_shader),
        .domains = HZ_SHADE_SURFACE,
        .output = HZ_SHADER_OUTPUT_BRDF,
        .claims = kReciprocal,
        .glsl_prefix = "blinnbrdf_",
        .param_count = 3,
        .get_param = params<kBlinnBrdfParams, 3>,
        .glsl_source = glsl<kBlinnBrdfGlsl, HZ_SHADE_SURFACE>,
        .eval_reference = eval_blinn_brdf,
        .functions = nullptr,
        .eval_function = nullptr,
        .display = HZ_SHADER_DISPLAY_TONE_MAPPED,
        .reserved0 = 0,
    },
    {
        .struct_size = sizeof(hz_shader),
        .domains = HZ_SHADE_LINE,
        .output = HZ_SHADER_OUTPUT_RADIANCE_FACTOR,
        .claims = HZ_CLAIM_NONNEGATIVE,
        .glsl_prefix = "stalling_",
        .param_count = 5,
        .get_param = params<kStallingParams, 5>,
        .glsl_source = glsl<kStallingGlsl, HZ_SHADE_LINE>,
        .eval_reference = eval_stalling,
        .functions = nullptr,
        .eval_function = nullptr,
        .display = HZ_SHADER_DISPLAY_TONE_MAPPED,
        .reserved0 = 0,
    },
    {
        .struct_size = sizeof(hz_shader),
        .domains = HZ_SHADE_LINE,
        .output = HZ_SHADER_OUTPUT_RADIANCE_FACTOR,
        .claims = HZ_CLAIM_NONNEGATIVE,
        .glsl_prefix = "mallo_",
        .param_count = 1,
        .get_param = params<kMalloParams, 1>,
        .glsl_source = glsl<kMalloGlsl, HZ_SHADE_LINE>,
        .eval_reference = eval_mallo,
        .functions = nullptr,
        .eval_function = nullptr,
        .display = HZ_SHADER_DISPLAY_TONE_MAPPED,
        .reserved0 = 0,
    },
    {
        .struct_size = sizeof(hz_shader),
        .domains = HZ_SHADE_SURFACE | HZ_SHADE_LINE,
        .output = HZ_SHADER_OUTPUT_EMISSION,
        .claims = HZ_CLAIM_NONNEGATIVE,
        .glsl_prefix = "flat_",
        .param_count = 1,
        .get_param = params<kFlatParams, 1>,
        .glsl_source = glsl<kFlatGlsl, HZ_SHADE_SURFACE | HZ_SHADE_LINE>,
        .eval_reference = eval_flat,
        .functions = nullptr,
        .eval_function = nullptr,
        .display = HZ_SHADER_DISPLAY_AS_IS,  // (non-PBR: the user's colours, not a filmic curve's)
        .reserved0 = 0,
    },
};
const char *const kInterfaces[] = {HZ_INTERFACE_SHADER, nullptr};
#define HZ_DESC(id, name, text) \
    { sizeof(hz_plugin_descriptor), HZ_ABI_VERSION_INIT, HZ_KIND_SHADER, id, name, "1.0.0", "Horizon", text, "MIT", kInterfaces }
const hz_plugin_descriptor kDescriptors[] = {
    HZ_DESC("org.horizon.shader.lambert", "Lambert", "Lambertian diffuse BRDF, albedo / pi"),
    HZ_DESC("org.horizon.shader.blinn_phong", "Blinn-Phong", "classic Blinn-Phong: ambient + diffuse n.l + specular (n.h)^s"),
    HZ_DESC("org.horizon.shader.blinn_phong_brdf", "Blinn-Phong BRDF", "normalised Blinn-Phong BRDF"),
    HZ_DESC("org.horizon.shader.line_stalling", "Illuminated lines", "Stalling et al. 1997 illuminated streamlines (tangent only)"),
    HZ_DESC("org.horizon.shader.line_mallo_diffuse", "Cylinder-averaged lines", "Mallo et al. 2005 diffuse term averaged over a thin tube"),
    HZ_DESC("org.horizon.shader.flat", "Flat", "unlit: the colour as is, for labels and quick looks"),
};
#undef HZ_DESC
constexpr uint32_t kCount = 6;

bool HZ_ABI init(const hz_host *, const char *) { return true; }
void HZ_ABI deinit() {}
uint32_t HZ_ABI count() { return kCount; }
const hz_plugin_descriptor *HZ_ABI descriptor(uint32_t i) { return i < kCount ? &kDescriptors[i] : nullptr; }
const void *HZ_ABI get_interface(const char *id, const char *iface) {
    if (id == nullptr || iface == nullptr || std::strcmp(iface, HZ_INTERFACE_SHADER) != 0) return nullptr;
    for (uint32_t i = 0; i < kCount; ++i)
        if (std::strcmp(id, kDescriptors[i].id) == 0) return &kShaders[i];
    return nullptr;
}

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = {
    .struct_size = sizeof(hz_plugin_entry),
    .abi = HZ_ABI_VERSION_INIT,
    .init = init,
    .deinit = deinit,
    .get_plugin_count = count,
    .get_plugin_descriptor = descriptor,
    .get_interface = get_interface,
};
