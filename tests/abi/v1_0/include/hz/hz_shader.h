/*
 * Horizon plugin SDK: the shading-model interface ("hz.shader/1").
 *
 * A shader plugin describes one shading function three ways:
 *   1. a parameter schema (hz_param_info), from which the host generates GLSL
 *      uniforms, scene-file keys and UI controls;
 *   2. a GLSL snippet the host assembles with its own prelude and main();
 *   3. a CPU reference of the same function, used by `horizon validate`,
 *      `horizon brdf` and the GPU-equals-CPU tests.
 * Plugins never call OpenGL: the host compiles and binds everything.
 *
 * GLSL contract. The snippet defines exactly one public function
 *     vec3 hz_shade(HzShadePoint p)
 * plus private helpers whose names start with glsl_prefix. It has no
 * #version line, no main() and no uniform declarations: for every schema
 * parameter the host declares `uniform <type> u_<name>;` (float, int, bool,
 * vec2, vec3, vec3, int, float[N]) before the snippet. The host prelude
 * declares
 *     struct HzShadePoint { vec3 n; vec3 t; vec3 b; vec3 l; vec3 v; float thickness_mm; };
 * with the same meaning as hz_shade_point below.
 */
#ifndef HZ_SHADER_H
#define HZ_SHADER_H

#include "hz_host.h"

HZ_EXTERN_C_BEGIN

/* Geometry domains a model can shade (bit set). */
typedef uint32_t hz_shade_domain;
enum {
    HZ_SHADE_SURFACE = 1u << 0, /* meshes, slices, tubes: n is the surface normal   */
    HZ_SHADE_LINE = 1u << 1     /* streamlines as lines: t is the line tangent     */
};

/* What hz_shade / eval_reference return. */
typedef uint32_t hz_shader_output;
enum {
    /* f_r in sr^-1, cosine NOT included: the host multiplies by max(n.l,0)
       and the light's radiance. */
    HZ_SHADER_OUTPUT_BRDF = 1,
    /* a reflected-radiance factor that already includes the geometry term
       (classic Blinn-Phong, illuminated lines): the host multiplies by the
       light's radiance only. */
    HZ_SHADER_OUTPUT_RADIANCE_FACTOR = 2
};

/* Properties the plugin claims; `horizon validate` tests exactly these. */
typedef uint32_t hz_shader_claims;
enum {
    HZ_CLAIM_NONNEGATIVE = 1u << 0,      /* output >= 0 and finite everywhere      */
    HZ_CLAIM_RECIPROCAL = 1u << 1,       /* f(l, v) == f(v, l)                     */
    HZ_CLAIM_ENERGY_CONSERVING = 1u << 2 /* directional albedo <= 1 (white input)  */
};

/*
 * One shading point, world space. CALLER-owned, valid for the call.
 * Vectors need not be normalised (a model normalises what it uses) but are
 * finite; l and v point away from the surface.
 */
typedef struct hz_shade_point {
    uint32_t struct_size;
    uint32_t domain;      /* one hz_shade_domain bit                               */
    double n[3];          /* surface normal (SURFACE); unused for LINE             */
    double t[3];          /* tangent: anisotropy direction X (SURFACE), line direction (LINE) */
    double b[3];          /* bitangent hint Y (SURFACE, used when t is degenerate) */
    double l[3];          /* towards the light                                     */
    double v[3];          /* towards the viewer                                    */
    double thickness_mm;  /* path length through the medium (glass); 0 if unused   */
} hz_shade_point;

/* The shader interface table. PLUGIN-owned, valid until deinit(). */
typedef struct hz_shader {
    uint32_t struct_size;
    hz_shade_domain domains;
    hz_shader_output output;
    hz_shader_claims claims;
    const char *glsl_prefix;  /* prefix of every private GLSL helper, e.g. "principled_" */
    uint32_t param_count;

    /* Parameter `index` < param_count, or NULL. PLUGIN-owned, static. [thread-safe] */
    const hz_param_info *(HZ_ABI *get_param)(uint32_t index);

    /*
     * The GLSL snippet for `domain` (one hz_shade_domain bit) and a target
     * `glsl_version` (e.g. 410, 450). NULL when the domain is unsupported.
     * PLUGIN-owned static text. [thread-safe]
     */
    const char *(HZ_ABI *glsl_source)(hz_shade_domain domain, uint32_t glsl_version);

    /*
     * The CPU reference: the same function as hz_shade, in double precision.
     * `params` holds every parameter's `components` values, concatenated in
     * schema order (`params_count` doubles, the sum of components). Writes
     * out_rgb. Pure, reentrant, no allocation, no exceptions. [thread-safe]
     */
    hz_status(HZ_ABI *eval_reference)(const hz_shade_point *point, const double *params,
                                      uint32_t params_count, double out_rgb[3]);
} hz_shader;

HZ_EXTERN_C_END

#endif /* HZ_SHADER_H */
