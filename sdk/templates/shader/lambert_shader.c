/*
 * Template shading plugin: Lambertian diffuse, f_r = albedo / pi.
 * Copy this directory, rename the id, and replace the math in both places
 * (GLSL and CPU reference) with your model: `horizon validate` checks the
 * reference for you, the renderer checks that GPU and CPU agree.
 */
#include <hz/hz.h>

#include <math.h>
#include <string.h>

#define PLUGIN_ID "org.example.shader.lambert"

static const hz_param_info k_params[] = {
    {
        .struct_size = sizeof(hz_param_info),
        .type = HZ_PARAM_COLOR3,
        .name = "albedo",
        .label = "Albedo",
        .group = "Material",
        .unit = "",
        .tooltip = "linear diffuse reflectance",
        .flags = 0,
        .components = 3,
        .min_value = {0, 0, 0, 0},
        .max_value = {1, 1, 1, 0},
        .default_value = {0.8, 0.8, 0.8, 0},
        .enum_labels = NULL,
        .default_array_count = 0,
        .default_array = NULL,
    },
};

static const hz_param_info *HZ_ABI get_param(uint32_t index) {
    return index < sizeof k_params / sizeof k_params[0] ? &k_params[index] : NULL;
}

/* The host declares `uniform vec3 u_albedo;` and the HzShadePoint struct. */
static const char k_glsl[] =
    "vec3 hz_shade(HzShadePoint p) {\n"
    "    vec3 n = normalize(p.n);\n"
    "    float NoL = dot(n, normalize(p.l));\n"
    "    float NoV = dot(n, normalize(p.v));\n"
    "    if (NoL <= 0.0 || NoV <= 0.0) return vec3(0.0);\n"
    "    return u_albedo * 0.3183098861837907;\n"
    "}\n";

static const char *HZ_ABI glsl_source(hz_shade_domain domain, uint32_t glsl_version) {
    (void)glsl_version;
    return domain == HZ_SHADE_SURFACE ? k_glsl : NULL;
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static hz_status HZ_ABI eval_reference(const hz_shade_point *p, const double *params, uint32_t count, double out[3]) {
    double nl, nv, ln, vn, nn;
    int k;
    if (p == NULL || params == NULL || count < 3 || out == NULL) return HZ_E_INVALID_ARGUMENT;
    nn = sqrt(dot3(p->n, p->n));
    ln = sqrt(dot3(p->l, p->l));
    vn = sqrt(dot3(p->v, p->v));
    out[0] = out[1] = out[2] = 0.0;
    if (!(nn > 0) || !(ln > 0) || !(vn > 0)) return HZ_OK; /* degenerate input shades black */
    nl = dot3(p->n, p->l) / (nn * ln);
    nv = dot3(p->n, p->v) / (nn * vn);
    if (!(nl > 0) || !(nv > 0)) return HZ_OK;
    for (k = 0; k < 3; ++k) {
        const double a = params[k];
        out[k] = (a > 0 ? (a < 1 ? a : 1) : 0) / 3.14159265358979323846;
    }
    return HZ_OK;
}

static const hz_shader k_shader = {
    .struct_size = sizeof(hz_shader),
    .domains = HZ_SHADE_SURFACE,
    .output = HZ_SHADER_OUTPUT_BRDF,
    .claims = HZ_CLAIM_NONNEGATIVE | HZ_CLAIM_RECIPROCAL,
    .glsl_prefix = "lambert_",
    .param_count = 1,
    .get_param = get_param,
    .glsl_source = glsl_source,
    .eval_reference = eval_reference,
    .functions = NULL, /* no named building blocks (1.2) */
    .eval_function = NULL,
};

static const char *const k_interfaces[] = {HZ_INTERFACE_SHADER, NULL};
static const hz_plugin_descriptor k_descriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_SHADER,
    .id = PLUGIN_ID,
    .name = "Lambert (template)",
    .version = "1.0.0",
    .vendor = "Example Vendor",
    .description = "Lambertian diffuse shading: a starting point for new models",
    .license = "MIT",
    .interfaces = k_interfaces,
};

static bool HZ_ABI init(const hz_host *host, const char *path) {
    (void)host;
    (void)path;
    return true;
}
static void HZ_ABI deinit(void) {}
static uint32_t HZ_ABI count(void) { return 1; }
static const hz_plugin_descriptor *HZ_ABI descriptor(uint32_t i) { return i == 0 ? &k_descriptor : NULL; }
static const void *HZ_ABI get_interface(const char *id, const char *iface) {
    if (id && iface && strcmp(id, PLUGIN_ID) == 0 && strcmp(iface, HZ_INTERFACE_SHADER) == 0) return &k_shader;
    return NULL;
}

HZ_DECLARE_PLUGIN_ENTRY = {
    .struct_size = sizeof(hz_plugin_entry),
    .abi = HZ_ABI_VERSION_INIT,
    .init = init,
    .deinit = deinit,
    .get_plugin_count = count,
    .get_plugin_descriptor = descriptor,
    .get_interface = get_interface,
};
