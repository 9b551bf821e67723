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
 *
 * Since 1.2 the host also guarantees, before the snippet:
 *   - The first HZ_PARAM_COLOR3 parameter is the surface colour: the host
 *     declares it as a plain global (not a uniform) and assigns it from the
 *     object's colouring (direction, colormap, cluster, solid) before each
 *     hz_shade call. `#define HZ_ALBEDO u_<name>` names it.
 *   - `#define HZ_ZERO_<name> 1` for every HZ_PARAM_FLOAT parameter whose
 *     value is exactly 0 in the material being compiled, so a snippet can
 *     leave out the terms that vanish (`#ifndef HZ_ZERO_clearcoat`). The
 *     result must equal the unspecialised function for those values.
 *   - `#define HZ_PARAM_<name> <value>` for every INT, ENUM or BOOL parameter
 *     flagged HZ_PARAM_FLAG_REQUIRES_RECOMPILE (a value that selects code:
 *     `#if HZ_PARAM_fresnel == 1`); the host recompiles when it changes.
 *   - HZ_DOMAIN_SURFACE or HZ_DOMAIN_LINE, and HZ_OUTPUT_BRDF when `output`
 *     is HZ_SHADER_OUTPUT_BRDF.
 *   - Baked materials (host behaviour, no ABI change): where a material's
 *     values stay fixed (`horizon render`; the window once its material
 *     panel is idle) the host declares float, int, enum, bool, vec2, vec3
 *     and colour parameters as `const <type> u_<name> = <value>;` instead
 *     of uniforms, and the HZ_ALBEDO colour too when every vertex of the
 *     object has the same colour (HZ_ALBEDO still names it). A snippet
 *     therefore only reads u_<name>, never assigns it, and must compute the
 *     same result either way; float arrays stay uniforms.
 *   - Environment lighting (world-space directions pointing away from the
 *     surface; all return 0 when the scene has no environment):
 *       vec3 hz_env_radiance(vec3 dir, float roughness);  prefiltered radiance
 *       vec3 hz_env_irradiance(vec3 n);   E(n) = integral of L max(n.w,0) dw
 *       vec2 hz_env_brdf(float NoV, float roughness);  split-sum (scale, bias)
 *       vec3 hz_scene_behind(vec2 offset_px);  the opaque scene behind this
 *                                          pixel, displaced by offset_px
 *       mat3 hz_view_rotation;             world -> camera (x right, y up)
 *   A snippet that calls hz_scene_behind is drawn after the opaque objects
 *   and composites what it transmits itself (no blending).
 *   - `#define HZ_UNIT_VECTORS 1` (newer 1.2 hosts; test it with #ifdef):
 *     p.n, p.l and p.v are finite and unit length (p.l is the zero
 *     vector only at a point light's own position), so the snippet may skip
 *     normalising them. p.t and p.b carry no such promise. Without the
 *     macro, normalise them yourself; eval_reference must do so always.
 *   A snippet may define `vec3 hz_ambient(HzShadePoint p)`: the radiance it
 *   reflects (or transmits) from the environment towards p.v. Without it the
 *   host uses hz_shade(p with l = n) * hz_env_irradiance(n) (BRDF output) or
 *   that divided by pi (radiance-factor output).
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
    HZ_SHADER_OUTPUT_RADIANCE_FACTOR = 2,
    /* Since 1.2. The final radiance, independent of lights and environment
       (flat / unlit shading): the host calls hz_shade once per fragment with
       l = n and uses its value as is. */
    HZ_SHADER_OUTPUT_EMISSION = 3
};

/* Since 1.12. How the host shows a model's output (hz_shader.display). */
typedef uint32_t hz_shader_display;
enum {
    /* Linear radiance: the scene's exposure and tone curve (ACES by default)
       map it to the screen. Physically based models. */
    HZ_SHADER_DISPLAY_TONE_MAPPED = 0,
    /* The colour to show: times the scene's exposure (1 by default),
       clamped to [0, 1] and sRGB-encoded, without the tone curve (non-PBR
       models whose colours are the user's own, e.g. flat shading or classic
       Blinn-Phong, which a filmic curve would wash out). Depth cues,
       shadows and transparency still apply. */
    HZ_SHADER_DISPLAY_AS_IS = 1
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

    /*
     * Since 1.2 (test HZ_HAS_FIELD). Named building blocks of the model that
     * tests can evaluate on their own (e.g. a Fresnel term), as a
     * NULL-terminated list of signatures "name(arg, arg[3], ...)": every
     * argument is a double or a fixed-size array of doubles. `horizon brdf`
     * answers a test case whose model is `name` by reading the arguments
     * from the case's fields of the same names. NULL when there are none.
     * PLUGIN-owned static text.
     */
    const char *const *functions;

    /*
     * Evaluates function `name` (one of `functions`) at `args`: its arguments
     * flattened in signature order, `nargs` doubles. Writes out_rgb (a scalar
     * result repeated 3 times). HZ_E_NOT_FOUND for an unknown name,
     * HZ_E_INVALID_ARGUMENT for a wrong count. Pure, reentrant, no
     * allocation, no exceptions. May be NULL. [thread-safe]
     */
    hz_status(HZ_ABI *eval_function)(const char *name, const double *args, uint32_t nargs, double out_rgb[3]);

    /* Since 1.12 (test HZ_HAS_FIELD): an hz_shader_display; older tables
       read as HZ_SHADER_DISPLAY_TONE_MAPPED. */
    hz_shader_display display;
    uint32_t reserved0; /* zero */
} hz_shader;

HZ_EXTERN_C_END

#endif /* HZ_SHADER_H */
