// hz.shader/1: the paper's principled BRDF (principled_brdf.hpp is the CPU
// reference; the GLSL below is the same function in float precision).
#include "principled_albedo.hpp"
#include "principled_brdf.hpp"

#include <hz/cpp/plugin.hpp>

#include <cstring>

namespace {

constexpr const char *kId = "org.horizon.shader.principled";

constexpr hz_param_info unit(const char *name, const char *label, const char *group, const char *tip, double def) {
    return {sizeof(hz_param_info), HZ_PARAM_FLOAT, name,           label,   group, "",     tip, 0, 1,
            {0, 0, 0, 0},          {1, 0, 0, 0},   {def, 0, 0, 0}, nullptr, 0,     nullptr};
}

const char *const kDiffuseModes[] = {"burley", "lambert", nullptr};
const char *const kFresnelModes[] = {"schlick", "exact", nullptr};
const char *const kVisibilityModes[] = {"separable", "height_correlated", nullptr};
constexpr hz_param_info variant(const char *name, const char *label, const char *const *modes, const char *tip) {
    return {
        sizeof(hz_param_info), HZ_PARAM_ENUM, name,  label, "Approximations", "", tip, HZ_PARAM_FLAG_REQUIRES_RECOMPILE, 1, {0, 0, 0, 0},
        {1, 0, 0, 0},          {0, 0, 0, 0},  modes, 0,     nullptr};
}

// Schema order = the order of values in eval_reference's params.
const hz_param_info kParams[] = {
    {sizeof(hz_param_info),
     HZ_PARAM_COLOR3,
     "base_color",
     "Base colour",
     "Base",
     "",
     "linear RGB albedo",
     0,
     3,
     {0, 0, 0, 0},
     {1, 1, 1, 0},
     {0.8, 0.8, 0.8, 0},
     nullptr,
     0,
     nullptr},
    unit("subsurface", "Subsurface", "Base", "blend of Burley diffuse and its subsurface approximation", 0),
    unit("metallic", "Metallic", "Base", "0 dielectric, 1 metal", 0),
    unit("specular", "Specular", "Specular", "dielectric reflectance (0.5 = 4%)", 0.5),
    unit("specular_tint", "Specular tint", "Specular", "tints the dielectric specular towards the base colour", 0),
    unit("roughness", "Roughness", "Specular", "perceptual roughness (alpha = roughness^2)", 0.5),
    unit("anisotropic", "Anisotropic", "Specular", "aspect of the highlight along the tangent", 0),
    unit("sheen", "Sheen", "Sheen", "grazing retro-reflection for cloth-like materials", 0),
    unit("sheen_tint", "Sheen tint", "Sheen", "tints the sheen towards the base colour", 0.5),
    unit("clearcoat", "Clearcoat", "Clearcoat", "second, fixed-index specular lobe", 0),
    unit("clearcoat_gloss", "Clearcoat gloss", "Clearcoat", "0 satin to 1 gloss", 1),
    variant("diffuse", "Diffuse term", kDiffuseModes, "Burley 2012 (the paper) or Lambert (cheaper)"),
    variant("fresnel", "Fresnel term", kFresnelModes, "Schlick (the paper) or exact dielectric Fresnel"),
    variant("visibility", "Shadowing term", kVisibilityModes, "separable Smith GGX (the paper) or height-correlated Smith"),
};
constexpr uint32_t kParamCount = sizeof kParams / sizeof kParams[0];
constexpr uint32_t kValueCount = 16;  // base_color (3) + 10 scalars + 3 variant switches

const hz_param_info *HZ_ABI get_param(uint32_t i) { return i < kParamCount ? &kParams[i] : nullptr; }

// GLSL 4.10+. The host declares the uniforms (u_<name>) and HzShadePoint.
const char kGlsl[] = R"glsl(
const float principled_PI = 3.14159265358979;

// Schlick weight (1 - u)^5, u clamped.
float principled_schlick(float u) {
    float m = clamp(1.0 - u, 0.0, 1.0);
    float m2 = m * m;
    return m2 * m2 * m;
}

// The GLSL below has no branches: every guard of the reference becomes a
// validity flag, and the result is selected at the end. On llvmpipe a branch
// costs both of its sides, and it would keep the compiler from sharing the
// work that does not depend on the light (normalising n and v, the tangent
// frame, the view terms, the colour terms) between the host's per-light calls.

// Scale-safe normalisation; `ok` is false for a zero or non-finite vector
// (the result is then meaningless but finite or NaN, never selected).
vec3 principled_unit(vec3 a, out bool ok) {
    float m = max(max(abs(a.x), abs(a.y)), abs(a.z));
    ok = m > 0.0 && !isinf(m) && !isnan(m);
    vec3 s = a * (1.0 / (ok ? m : 1.0));
    return s * inversesqrt(max(dot(s, s), 1e-30));
}

// The unit part of w orthogonal to n; `ok` false when w is zero, non-finite
// or (nearly) parallel to n.
vec3 principled_perp(vec3 w, vec3 n, out bool ok) {
    float m = max(max(abs(w.x), abs(w.y)), abs(w.z));
    bool finite = m > 0.0 && !isinf(m) && !isnan(m);
    vec3 s = w / (finite ? m : 1.0);
    vec3 q = s - dot(s, n) * n;
    ok = finite && length(q) > 1e-6 * length(s);
    return normalize(ok ? q : vec3(1.0, 0.0, 0.0));
}

// Contract frame: X orthogonalised, else Y's, else Duff et al. 2017.
void principled_frame(vec3 n, vec3 x, vec3 y, out vec3 tx, out vec3 ty) {
    bool okx, oky;
    vec3 px = principled_perp(x, n, okx);
    vec3 py = principled_perp(y, n, oky);
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float b = n.x * n.y * a;
    vec3 duff = vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    tx = okx ? px : (oky ? normalize(cross(py, n)) : duff);
    ty = cross(n, tx);
}

vec3 hz_shade(HzShadePoint sp) {
    bool okh;
#ifdef HZ_UNIT_VECTORS
    // The host passes n, l and v unit length and finite (l = 0 at a point
    // light's own position, which NoL > 0 below rejects).
    vec3 n = sp.n, l = sp.l, v = sp.v;
    const bool okn = true, okl = true, okv = true;
#else
    bool okn, okl, okv;
    vec3 n = principled_unit(sp.n, okn), l = principled_unit(sp.l, okl), v = principled_unit(sp.v, okv);
#endif
    float NoL = dot(n, l), NoV = dot(n, v);
    vec3 C = clamp(u_base_color, 0.0, 1.0);
    float subsurface = clamp(u_subsurface, 0.0, 1.0), metallic = clamp(u_metallic, 0.0, 1.0);
    float specular = clamp(u_specular, 0.0, 1.0), specular_tint = clamp(u_specular_tint, 0.0, 1.0);
    float roughness = clamp(u_roughness, 0.0, 1.0), anisotropic = clamp(u_anisotropic, 0.0, 1.0);
    float sheen = clamp(u_sheen, 0.0, 1.0), sheen_tint = clamp(u_sheen_tint, 0.0, 1.0);
    float clearcoat = clamp(u_clearcoat, 0.0, 1.0), clearcoat_gloss = clamp(u_clearcoat_gloss, 0.0, 1.0);

#ifdef HZ_UNIT_VECTORS
    // |l + v| is in [0, 2]: no rescaling needed.
    vec3 h = l + v;
    float hh = dot(h, h);
    okh = hh > 1e-30;
    h *= inversesqrt(okh ? hh : 1.0);
#else
    vec3 h = principled_unit(l + v, okh);
#endif
    float NoH = dot(n, h), LoH = dot(l, h);

    float FL = principled_schlick(NoL), FV = principled_schlick(NoV), FH = principled_schlick(LoH);
    float lum = dot(vec3(0.3, 0.6, 0.1), C);
    vec3 Ctint = lum > 0.0 ? C / lum : vec3(1.0);

    // Burley 2012 diffuse and subsurface.
    float Fd90 = 0.5 + 2.0 * roughness * LoH * LoH;
#if HZ_PARAM_diffuse == 1
    float Fd = 1.0;
#else
    float Fd = mix(1.0, Fd90, FL) * mix(1.0, Fd90, FV);
#endif
#ifdef HZ_ZERO_subsurface
    float diff = Fd;
#else
    float Fss90 = roughness * LoH * LoH;
    float Fss = mix(1.0, Fss90, FL) * mix(1.0, Fss90, FV);
    float ss = 1.25 * (Fss * (1.0 / max(NoL + NoV, 1e-6) - 0.5) + 0.5);
    float diff = mix(Fd, ss, subsurface);
#endif

    // GGX, Walter et al. 2007 (anisotropic; the isotropic path when
    // anisotropic = 0 needs no tangent frame).
    float r2 = roughness * roughness;
#ifdef HZ_ZERO_anisotropic
    float a = max(0.001, r2), aa = a * a;
    // |n x h|^2 = 1 - NoH^2. The cross product keeps it exact near NoH = 1,
    // which only matters for a tiny alpha: with alpha^2 >= 1e-2 the
    // subtraction's rounding stays below 1e-5 of dd. (Baked programs have a
    // constant alpha, so the compiler keeps only one of the two forms.)
    vec3 nxh0 = cross(n, h);
    float sin2h = aa >= 1e-2 ? max(1.0 - NoH * NoH, 0.0) : dot(nxh0, nxh0);
    float dd = sin2h + aa * NoH * NoH;
    float dl = NoL + sqrt(aa * (1.0 - NoL * NoL) + NoL * NoL);
    float dv = NoV + sqrt(aa * (1.0 - NoV * NoV) + NoV * NoV);
#else
    vec3 X, Y;
    principled_frame(n, sp.t, sp.b, X, Y);
    float aspect = sqrt(1.0 - 0.9 * anisotropic);
    float ax = max(0.001, r2 / aspect), ay = max(0.001, r2 * aspect);
    float HoX = dot(h, X), HoY = dot(h, Y);
    float dden = (HoX / ax) * (HoX / ax) + (HoY / ay) * (HoY / ay) + NoH * NoH;
    float Dden = principled_PI * ax * ay * dden * dden;
    vec2 lxy = vec2(dot(l, X) * ax, dot(l, Y) * ay), vxy = vec2(dot(v, X) * ax, dot(v, Y) * ay);
    float dl = NoL + sqrt(dot(lxy, lxy) + NoL * NoL);
    float dv = NoV + sqrt(dot(vxy, vxy) + NoV * NoV);
#endif
#if HZ_PARAM_visibility == 1
#ifdef HZ_ZERO_anisotropic
    float Gden = 2.0 * (NoL * sqrt(aa * (1.0 - NoV * NoV) + NoV * NoV) + NoV * sqrt(aa * (1.0 - NoL * NoL) + NoL * NoL));
#else
    float Gden = 2.0 * (NoL * sqrt(dot(vxy, vxy) + NoV * NoV) + NoV * sqrt(dot(lxy, lxy) + NoL * NoL));
#endif
#else
    float Gden = dl * dv;
#endif
    // D * G with one division: D = aa / (pi dd^2) (isotropic) or
    // 1 / (pi ax ay dden^2); G = 1 / Gden.
#ifdef HZ_ZERO_anisotropic
    float DsGs = aa / (principled_PI * dd * dd * Gden);
#else
    float DsGs = 1.0 / (Dden * Gden);
#endif

    vec3 Cspec0 = mix(0.08 * specular * mix(vec3(1.0), Ctint, specular_tint), C, metallic);
#if HZ_PARAM_fresnel == 1
    vec3 Fs;
    for (int i = 0; i < 3; ++i) {
        float r0 = sqrt(clamp(Cspec0[i], 0.0, 0.999));
        float eta = (1.0 + r0) / (1.0 - r0), c = clamp(LoH, 0.0, 1.0);
        float s2 = (1.0 - c * c) / (eta * eta), ct = sqrt(max(0.0, 1.0 - s2));
        float rs = (c - eta * ct) / (c + eta * ct), rp = (eta * c - ct) / (eta * c + ct);
        Fs[i] = s2 >= 1.0 ? 1.0 : 0.5 * (rs * rs + rp * rp);
    }
#else
    vec3 Fs = mix(Cspec0, vec3(1.0), FH);
#endif
    vec3 diffuse = (1.0 / principled_PI) * diff * C;
#ifndef HZ_ZERO_sheen
    diffuse += FH * sheen * mix(vec3(1.0), Ctint, sheen_tint);
#endif
    vec3 f = diffuse * (1.0 - metallic) + DsGs * Fs;

#ifndef HZ_ZERO_clearcoat
    // Clearcoat: GTR1, Burley 2012.
    float ac = max(0.001, mix(0.1, 0.001, clearcoat_gloss));
    float a2 = ac * ac;
    vec3 nxh = cross(n, h);
    float t = a2 - 1.0;
    float ratio = t == 0.0 ? 1.0 : t / log(a2);
    float Dr = ratio / (principled_PI * (dot(nxh, nxh) + a2 * NoH * NoH));
    float gl = 1.0 / (NoL + sqrt(0.0625 + NoL * NoL - 0.0625 * NoL * NoL));
    float gv = 1.0 / (NoV + sqrt(0.0625 + NoV * NoV - 0.0625 * NoV * NoV));
    float Fr = mix(0.04, 1.0, FH);
    f += 0.25 * clearcoat * Dr * Fr * gl * gv;
#endif
    bool ok = okn && okl && okv && okh && NoL > 0.0 && NoV > 0.0;
    return ok ? f : vec3(0.0);
}

// Image-based lighting, split-sum (Karis 2013): diffuse from the irradiance,
// specular and clearcoat from the prefiltered environment.
vec3 hz_ambient(HzShadePoint sp) {
#ifdef HZ_UNIT_VECTORS
    vec3 n = sp.n, v = sp.v;
    const bool okn = true, okv = true;
#else
    bool okn, okv;
    vec3 n = principled_unit(sp.n, okn), v = principled_unit(sp.v, okv);
#endif
    float NoV = dot(n, v);
    vec3 C = clamp(u_base_color, 0.0, 1.0);
    float metallic = clamp(u_metallic, 0.0, 1.0), roughness = clamp(u_roughness, 0.0, 1.0);
    float lum = dot(vec3(0.3, 0.6, 0.1), C);
    vec3 Ctint = lum > 0.0 ? C / lum : vec3(1.0);
    vec3 Cspec0 = mix(0.08 * clamp(u_specular, 0.0, 1.0) * mix(vec3(1.0), Ctint, clamp(u_specular_tint, 0.0, 1.0)), C, metallic);
    vec3 r = 2.0 * NoV * n - v;
    vec2 ab = hz_env_brdf(NoV, roughness);
    vec3 c = (1.0 - metallic) * C * (1.0 / principled_PI) * hz_env_irradiance(n)
           + hz_env_radiance(r, roughness) * (Cspec0 * ab.x + ab.y);
#ifndef HZ_ZERO_clearcoat
    float cr = mix(0.3, 0.03, clamp(u_clearcoat_gloss, 0.0, 1.0));
    vec2 cb = hz_env_brdf(NoV, cr);
    c += 0.25 * clamp(u_clearcoat, 0.0, 1.0) * hz_env_radiance(r, cr) * (0.04 * cb.x + cb.y);
#endif
    return okn && okv && NoV > 0.0 ? c : vec3(0.0);
}
)glsl";

const char *HZ_ABI glsl_source(hz_shade_domain domain, uint32_t) { return domain == HZ_SHADE_SURFACE ? kGlsl : nullptr; }

hz_status HZ_ABI eval_reference(const hz_shade_point *sp, const double *params, uint32_t count, double out[3]) {
    if (sp == nullptr || params == nullptr || out == nullptr || count < kValueCount) return HZ_E_INVALID_ARGUMENT;
    principled::Params p;
    p.base_color = {params[0], params[1], params[2]};
    p.subsurface = params[3];
    p.metallic = params[4];
    p.specular = params[5];
    p.specular_tint = params[6];
    p.roughness = params[7];
    p.anisotropic = params[8];
    p.sheen = params[9];
    p.sheen_tint = params[10];
    p.clearcoat = params[11];
    p.clearcoat_gloss = params[12];
    p.diffuse = int(params[13] >= 0.5), p.fresnel = int(params[14] >= 0.5), p.visibility = int(params[15] >= 0.5);
    auto v3 = [](const double *a) { return principled::V3{a[0], a[1], a[2]}; };
    const principled::V3 f = principled::eval(p, v3(sp->n), v3(sp->l), v3(sp->v), v3(sp->t), v3(sp->b));
    std::copy(f.begin(), f.end(), out);
    return HZ_OK;
}

const char *const kFunctions[] = {
    "principled_albedo(base_color[3], subsurface, metallic, specular, specular_tint, roughness, anisotropic, sheen, sheen_tint, "
    "clearcoat, clearcoat_gloss, N[3], X[3], Y[3], V[3])",
    nullptr};

// Directional albedo E(v) by deterministic quadrature (principled_albedo.hpp).
hz_status HZ_ABI eval_function(const char *name, const double *a, uint32_t n, double out[3]) {
    if (name == nullptr || out == nullptr) return HZ_E_INVALID_ARGUMENT;
    if (std::strcmp(name, "principled_albedo") != 0) return HZ_E_NOT_FOUND;
    if (n != 25 || a == nullptr) return HZ_E_INVALID_ARGUMENT;
    principled::Params p;
    p.base_color = {a[0], a[1], a[2]};
    p.subsurface = a[3], p.metallic = a[4], p.specular = a[5], p.specular_tint = a[6], p.roughness = a[7];
    p.anisotropic = a[8], p.sheen = a[9], p.sheen_tint = a[10], p.clearcoat = a[11], p.clearcoat_gloss = a[12];
    auto v3 = [](const double *x) { return principled::V3{x[0], x[1], x[2]}; };
    const principled::V3 e = principled::albedo(p, v3(a + 13), v3(a + 22), v3(a + 16), v3(a + 19));
    std::copy(e.begin(), e.end(), out);
    return HZ_OK;
}

const hz_shader kShader = {
    .struct_size = sizeof(hz_shader),
    .domains = HZ_SHADE_SURFACE,
    .output = HZ_SHADER_OUTPUT_BRDF,
    .claims = HZ_CLAIM_NONNEGATIVE | HZ_CLAIM_RECIPROCAL,
    .glsl_prefix = "principled_",
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
    .name = "Principled BRDF",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description =
        "The paper's principled BRDF (Burley 2012): subsurface, metallic, specular, tints, roughness, anisotropy, sheen, clearcoat",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kShader>::entry;
