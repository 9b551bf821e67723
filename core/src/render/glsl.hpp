// The host's GLSL: the prelude every shading program starts with, the
// geometry stages and main() around a plugin's hz_shade(), and the
// environment, slice, sky and tonemapping programs.
#pragma once

namespace hz::core::render::glsl {

// After "#version 410 core" and the HZ_* defines; before the uniforms and the
// plugin snippet.
inline constexpr const char *kPrelude = R"glsl(
struct HzShadePoint { vec3 n; vec3 t; vec3 b; vec3 l; vec3 v; float thickness_mm; };

uniform samplerCube hz_env_specular_map;
uniform samplerCube hz_env_diffuse_map;
uniform sampler2D hz_env_lut;
uniform float hz_env_intensity;
uniform float hz_env_max_lod;
uniform mat3 hz_env_rotation;
uniform sampler2D hz_behind;      // the opaque scene behind a translucent object
uniform vec2 hz_viewport;
uniform mat3 hz_view_rotation;    // world -> camera (x right, y up, z back)

// Radiance arriving from direction `dir` (world, pointing away from the
// surface), prefiltered for a GGX lobe of perceptual roughness `roughness`.
vec3 hz_env_radiance(vec3 dir, float roughness) {
    return hz_env_intensity * textureLod(hz_env_specular_map, hz_env_rotation * dir, clamp(roughness, 0.0, 1.0) * hz_env_max_lod).rgb;
}
// Irradiance E(n) = integral of L(w) max(n.w, 0) dw over the sphere.
vec3 hz_env_irradiance(vec3 n) {
    return hz_env_intensity * texture(hz_env_diffuse_map, hz_env_rotation * n).rgb;
}
// Split-sum GGX terms (scale, bias) with F = F0 * scale + bias.
vec2 hz_env_brdf(float NoV, float roughness) {
    return texture(hz_env_lut, vec2(clamp(NoV, 0.0, 1.0), clamp(roughness, 0.0, 1.0))).rg;
}
// Radiance of the opaque scene seen through this pixel, displaced by `offset_px`.
vec3 hz_scene_behind(vec2 offset_px) {
    vec2 uv = (gl_FragCoord.xy + offset_px) / hz_viewport;
    return texture(hz_behind, clamp(uv, vec2(0.0), vec2(1.0))).rgb;
}
)glsl";

// Host main() of every shading program, after the plugin snippet.
inline constexpr const char *kShadeMain = R"glsl(
#if defined(HZ_GEOM_VOLUME)
// The fibre volume (a tractogram's proxy): the ray through this pixel,
// composited front to back; then shaded once as a line, with the mean colour
// of what it saw, at the point where it became half opaque, with the main
// direction of the streamlines there.
in vec3 v_ray_end;                 // where the ray meets the far plane
uniform mat4 hz_view_proj;
uniform vec3 hz_vol_origin;        // corner of voxel (0, 0, 0), mm
uniform vec3 hz_vol_dim;           // voxels along x, y, z
uniform float hz_vol_voxel;        // edge of a voxel, mm
uniform float hz_px_angle;         // a full-size pixel's width per mm of distance
uniform sampler3D hz_vol_colour;   // rgb x density, density (mm / mm^3)
uniform sampler3D hz_vol_tangent;  // direction * 0.5 + 0.5, how many run along it
uniform sampler3D hz_vol_skip;     // the Chebyshev distance to a voxel with streamlines / 255
vec3 v_pos;
vec4 v_color;
vec3 v_tangent;
float hz_vol_alpha;
void hz_vol_march(vec3 eye) {
    vec3 d = normalize(v_ray_end - eye);
    vec3 dd = mix(d, vec3(1e-12), lessThan(abs(d), vec3(1e-12)));
    vec3 lo = hz_vol_origin, hi = hz_vol_origin + hz_vol_dim * hz_vol_voxel;
    vec3 ta = (lo - eye) / dd, tb = (hi - eye) / dd;
    vec3 tn = min(ta, tb), tf = max(ta, tb);
    float t = max(max(max(tn.x, tn.y), tn.z), 0.0);
    float t1 = min(min(tf.x, tf.y), tf.z);
    float step = 1.5 * hz_vol_voxel;
    float a_sum = 0.0;
    vec3 c_sum = vec3(0.0), t_sum = vec3(0.0);
    float along_sum = 0.0;
    v_pos = eye + d * t;
    v_tangent = vec3(0.0, 0.0, 1.0);
    ivec3 top = ivec3(hz_vol_dim) - 1;
    float inv_max = 1.0 / max(max(abs(d.x), abs(d.y)), abs(d.z));
    for (int i = 0; i < 256 && t < t1 && a_sum < 0.9; ++i) {
        vec3 x = eye + d * t;
        vec3 g = (x - hz_vol_origin) / hz_vol_voxel;
        // Until the first streamlines: empty space skipped by its distance
        // to them (none within skip - 1 voxels, nor in the samples' reach).
        if (a_sum == 0.0) {
            float skip = texelFetch(hz_vol_skip, clamp(ivec3(g), ivec3(0), top), 0).r * 255.0;
            if (skip >= 3.0) {  // (a Chebyshev distance: along the ray, 1 / max |d_i| times farther)
                t += (skip - 2.0) * hz_vol_voxel * inv_max;
                continue;
            }
        }
        vec3 uvw = g / hz_vol_dim;
        vec4 cd = texture(hz_vol_colour, uvw);
        vec4 ts = texture(hz_vol_tangent, uvw);
        vec3 e = ts.xyz * (255.0 / 127.5) - 1.0;
        // A line of length L at angle theta to the ray covers w L sin(theta):
        // sin^2 averaged over the voxel's directions, taken as lambda along
        // e and the rest spread evenly around it.
        float ee = dot(e, e);
        float c2 = ee > 1e-12 ? dot(e, d) * dot(e, d) / ee : 0.0;
        float lambda = ts.a / 1.5 + 1.0 / 3.0;
        float along = lambda * c2 + 0.5 * (1.0 - lambda) * (1.0 - c2);
        float a = 1.0 - exp(-cd.a * hz_px_angle * t * step * sqrt(max(1.0 - along, 0.0)));
        if (a > 0.0) {
            if (a_sum < 0.5) v_pos = x;
            // The directions seen, weighted as the colours (filtered: a
            // block's lines, not one voxel's), each turned to agree with
            // the sum so far (a direction has no sign).
            t_sum += (1.0 - a_sum) * a * (dot(e, t_sum) < 0.0 ? -e : e);
            c_sum += (1.0 - a_sum) * a * cd.rgb / max(cd.a, 1e-20);
            along_sum += (1.0 - a_sum) * a * along;
            a_sum += (1.0 - a_sum) * a;
        }
        t += step;
    }
    if (a_sum < 1.0 / 255.0) discard;
    v_color = vec4(c_sum / a_sum, 1.0);
    // Shaded as one line: the mean direction's azimuth around the ray, at
    // the mean inclination of the lines seen (the mean of directions
    // spread around the ray points along it, which no line seen does).
    vec3 across = t_sum - dot(t_sum, d) * d;
    float aa = dot(across, across);
    across = aa > 1e-20 ? across * inversesqrt(aa) : normalize(cross(d, abs(d.z) < 0.9 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
    float cos_in = sqrt(clamp(along_sum / a_sum, 0.0, 1.0));
    v_tangent = cos_in * (dot(t_sum, d) < 0.0 ? -d : d) + sqrt(1.0 - cos_in * cos_in) * across;
    hz_vol_alpha = a_sum;
    vec4 clip = hz_view_proj * vec4(v_pos, 1.0);
    gl_FragDepth = clamp(0.5 * clip.z / clip.w + 0.5, 0.0, 1.0);
}
#define HZ_OUT_ALPHA (hz_opacity * hz_vol_alpha)
#else
in vec3 v_pos;
in vec4 v_color;
#define HZ_OUT_ALPHA hz_opacity
#endif
#if defined(HZ_GEOM_MESH)
in vec3 v_normal;
#elif !defined(HZ_GEOM_VOLUME)
in vec3 v_tangent;
#endif
#if defined(HZ_GEOM_TUBE)
in vec3 v_side;
in vec3 v_front;
in float v_across;
#endif
uniform vec3 hz_eye;
uniform vec3 hz_tangent_hint;
// HZ_NB_LIGHTS (1..8) and HZ_ENV (0/1) are compile-time constants: llvmpipe
// executes both sides of every branch, so dead code must not be compiled.
uniform vec4 hz_light_vec[HZ_NB_LIGHTS];
uniform vec3 hz_light_radiance[HZ_NB_LIGHTS];
uniform float hz_opacity;
#ifdef HZ_SHADOW
// Shadows of the key light, light HZ_SHADOW_LIGHT (directional;
// passes/shadow.hpp): its shadow map, compared through a filter.
uniform sampler2DShadow hz_shadow_map;
uniform mat4 hz_shadow_matrix;     // world mm -> the map's texture coordinates and depth
uniform float hz_shadow_texel_mm;  // a texel's side
uniform float hz_shadow_soft_mm;   // the filter's radius
uniform float hz_shadow_extent_mm; // the side of the square the map covers
uniform float hz_shadow_strength;  // 0: no darkening; 1: the key light fully blocked
#if defined(HZ_GEOM_TUBE)
in float v_radius;
#endif
// A disc of 12 taps (Poisson, radius 1), each compared bilinearly.
const vec2 hz_shadow_taps[12] = vec2[](vec2(-0.326, -0.406), vec2(-0.840, -0.074), vec2(-0.696, 0.457), vec2(-0.203, 0.621),
                                       vec2(0.962, -0.195), vec2(0.473, -0.480), vec2(0.519, 0.767), vec2(0.185, -0.893),
                                       vec2(0.507, 0.064), vec2(0.896, 0.412), vec2(-0.322, -0.933), vec2(-0.792, -0.598));
// How much of the key light (towards l) reaches x: 1 lit, 1 - strength in
// full shadow. `n`: the receiver's normal turned to the light, or 0 for a
// line; `slope`: the tangent of its angle to the map's plane, by which its
// own depth changes across the filter, hence the bias.
float hz_shadow_at(vec3 x, vec3 l, vec3 n, float slope) {
    float s = min(slope, 8.0);
    float bias = 1.5 * hz_shadow_texel_mm + s * (1.5 * hz_shadow_texel_mm + hz_shadow_soft_mm);
    vec3 q = (hz_shadow_matrix * vec4(x + n * (1.5 * hz_shadow_texel_mm) + l * bias, 1.0)).xyz;
    if (any(lessThan(q, vec3(0.0))) || any(greaterThan(q, vec3(1.0)))) return 1.0;  // outside the map: lit
    float r = hz_shadow_soft_mm / hz_shadow_extent_mm;
    float lit = texture(hz_shadow_map, q);
    for (int k = 0; k < 12; ++k) lit += texture(hz_shadow_map, vec3(q.xy + r * hz_shadow_taps[k], q.z));
    return 1.0 - hz_shadow_strength * (1.0 - lit / 13.0);
}
#define HZ_SHADOWED(i) ((i) == HZ_SHADOW_LIGHT ? hz_key_lit : 1.0)
#else
#define HZ_SHADOWED(i) 1.0
#endif
#ifdef HZ_PEEL
// Depth peeling (passes/transparency.hpp): the last layer's window depths;
// only what lies behind them is drawn.
uniform sampler2D hz_peel_depth;
#endif
layout(location = 0) out vec4 o_color;
#ifdef HZ_DEBUG_OUTPUTS
layout(location = 1) out vec4 o_n;
layout(location = 2) out vec4 o_l;
layout(location = 3) out vec4 o_v;
layout(location = 4) out vec4 o_t;
#endif

vec3 hz_safe_normalize(vec3 a, vec3 fallback) {
    float m = dot(a, a);
    return m > 1e-30 ? a * inversesqrt(m) : fallback;
}
#if defined(HZ_FIBRE_ANISOTROPY) && !defined(HZ_GEOM_TUBE)
// A line has no normal of its own: shaded at its front (the point of a thin
// cylinder facing the viewer), or, by the material's anisotropy, towards its
// glint for each light (the cylinder's point whose normal is the half
// vector's part across the line: where it reflects that light to the eye, as
// in hair and illuminated-line shading, Stalling et al. 1997), with the
// anisotropic lobe's wide axis around the cylinder and its narrow one along
// the line: the highlight is where the tangent is nearly perpendicular to the
// half vector, so that along a curved bundle it comes and goes with the
// tangent (bright and dark bands, the paper's Fig. 7). p.l and p.v set;
// `tangent` unit length.
void hz_fibre_glint(inout HzShadePoint p, vec3 front, vec3 tangent) {
    vec3 h = hz_safe_normalize(p.l + p.v, front);
    vec3 glint = hz_safe_normalize(h - dot(h, tangent) * tangent, front);
    p.n = hz_safe_normalize(mix(front, glint, clamp(float(HZ_FIBRE_ANISOTROPY), 0.0, 1.0)), front);
    p.t = hz_safe_normalize(cross(tangent, p.n), p.b);
    p.b = cross(p.n, p.t);
}
#endif

void main() {
#ifdef HZ_PEEL
    if (gl_FragCoord.z <= texelFetch(hz_peel_depth, ivec2(gl_FragCoord.xy), 0).r) discard;
#endif
#if defined(HZ_GEOM_VOLUME)
    hz_vol_march(hz_eye);
#endif
    HzShadePoint p;
    vec3 vn = hz_safe_normalize(hz_eye - v_pos, vec3(0.0, 0.0, 1.0));
    p.v = vn;
    p.thickness_mm = 0.0;
#if defined(HZ_GEOM_MESH)
    vec3 n = hz_safe_normalize(v_normal, vn);
    if (dot(n, vn) < 0.0) n = -n;  // two-sided, whatever the winding
    p.n = n;
    p.t = hz_tangent_hint;
    p.b = cross(n, hz_tangent_hint);
#ifdef HZ_SHADOW
    vec3 hz_recv = v_pos, hz_recv_n = n;
#endif
#elif defined(HZ_GEOM_POINT)
    // A crossing of the slab's plane: a small sphere facing the camera,
    // drawn on the point's square (gl_PointCoord: y down).
    vec2 q = gl_PointCoord * 2.0 - 1.0;
    float r2 = dot(q, q);
    if (r2 > 1.0) discard;
    p.n = transpose(hz_view_rotation) * vec3(q.x, -q.y, sqrt(1.0 - r2));
    vec3 t = hz_safe_normalize(v_tangent, vec3(0.0, 0.0, 1.0));
    p.t = hz_safe_normalize(t - dot(t, p.n) * p.n, hz_safe_normalize(cross(p.n, vec3(0.0, 0.0, 1.0)), vec3(1.0, 0.0, 0.0)));
    p.b = cross(p.n, p.t);
#ifdef HZ_SHADOW
    vec3 hz_recv = v_pos, hz_recv_n = p.n;
#endif
#elif defined(HZ_GEOM_TUBE)
    vec3 t = hz_safe_normalize(v_tangent, vec3(0.0, 0.0, 1.0));
    vec3 front = hz_safe_normalize(v_front, vn);
    vec3 side = hz_safe_normalize(v_side, hz_safe_normalize(cross(t, front), vec3(1.0, 0.0, 0.0)));
    float a = clamp(v_across, -1.0, 1.0);
    p.n = hz_safe_normalize(a * side + sqrt(max(0.0, 1.0 - a * a)) * front, front);
    p.t = t;
    p.b = cross(p.n, t);
#ifdef HZ_FIBRE_ANISOTROPY
    // An anisotropic material's tangent goes around the tube, as a hair's:
    // its highlight spreads around the fibre and stays narrow along it (see
    // the lines' glint below).
    p.t = hz_safe_normalize(cross(t, p.n), side);
    p.b = cross(p.n, p.t);
#endif
#ifdef HZ_SHADOW
    // (the round tube's surface, in front of its quad by the radius there)
    vec3 hz_recv = v_pos + v_radius * sqrt(max(0.0, 1.0 - a * a)) * front, hz_recv_n = p.n;
#endif
#else
    vec3 t = v_tangent;
    p.t = t;
    float tt = dot(t, t);
    p.n = hz_safe_normalize(tt > 1e-30 ? p.v - dot(p.v, t) / tt * t : p.v, vn);
    p.b = cross(p.n, t);
    vec3 hz_front = p.n;  // (HZ_FIBRE_ANISOTROPY: each light's normal turns from it towards the line's glint)
#ifdef HZ_SHADOW
    vec3 hz_recv = v_pos, hz_recv_n = vec3(0.0);
#endif
#endif
#ifdef HZ_SHADOW
    float hz_key_lit;
    {
        vec3 l = hz_light_vec[HZ_SHADOW_LIGHT].xyz;
        float c;
        if (dot(hz_recv_n, hz_recv_n) > 0.0) {  // a surface: its normal on the light's side
            if (dot(hz_recv_n, l) < 0.0) hz_recv_n = -hz_recv_n;
            c = dot(hz_recv_n, l);
        } else {  // a line: its tangent's angle to the light
            float tl = abs(dot(hz_safe_normalize(p.t, vec3(0.0, 0.0, 1.0)), l));
            c = sqrt(max(1.0 - tl * tl, 0.0));
        }
        float slope = sqrt(max(1.0 - c * c, 0.0)) / max(c, 0.12);
        // A line's neighbours (a bundle's lines side by side, a sheet) lie
        // within the filter at depths its own slope does not tell: taken as
        // a surface of slope 3 at least (72 degrees to the map's plane).
        if (dot(hz_recv_n, hz_recv_n) == 0.0) slope = max(slope, 3.0);
        hz_key_lit = hz_shadow_at(hz_recv, l, hz_recv_n, slope);
    }
#endif
#ifdef HZ_ALBEDO_PER_VERTEX
    HZ_ALBEDO = v_color.rgb;
#endif
    vec3 c = vec3(0.0);
    vec3 first = vec3(0.0), l0 = vec3(0.0), n0 = p.n, tl0 = p.t;
#ifdef HZ_OUTPUT_EMISSION
    p.l = p.n;
    c = hz_shade(p);
    first = c;
    l0 = p.l;
#else
    // HZ_APPLY_LIGHTS (generated by the host) sets p.l for each light, a
    // unit vector (directional lights: a uniform), and expands HZ_LIGHT_TERM.
#if defined(HZ_FIBRE_ANISOTROPY) && !defined(HZ_GEOM_TUBE)
    vec3 hz_tangent = hz_safe_normalize(p.t, vec3(0.0)), t0 = p.t;
#define HZ_LINE_LIGHT_NORMAL hz_fibre_glint(p, hz_front, hz_tangent);
#else
#define HZ_LINE_LIGHT_NORMAL
#endif
#ifdef HZ_OUTPUT_BRDF
#define HZ_LIGHT_TERM(i) { HZ_LINE_LIGHT_NORMAL vec3 f = hz_shade(p); if (i == 0) { first = f; l0 = p.l; n0 = p.n; tl0 = p.t; } c += f * max(dot(p.n, p.l), 0.0) * hz_light_radiance[i] * HZ_SHADOWED(i); }
#else
#define HZ_LIGHT_TERM(i) { HZ_LINE_LIGHT_NORMAL vec3 f = hz_shade(p); if (i == 0) { first = f; l0 = p.l; n0 = p.n; tl0 = p.t; } c += f * hz_light_radiance[i] * HZ_SHADOWED(i); }
#endif
    HZ_APPLY_LIGHTS
#if defined(HZ_FIBRE_ANISOTROPY) && !defined(HZ_GEOM_TUBE)
    p.n = hz_front, p.t = t0, p.b = cross(hz_front, t0);  // (the environment's light: the front)
#endif
#if defined(HZ_HAS_AMBIENT) && (HZ_ENV || defined(HZ_REFRACTIVE))
    c += hz_ambient(p);  // the hz_env_* functions give 0 without an environment
#elif HZ_ENV && !defined(HZ_HAS_AMBIENT)
    {
        HzShadePoint q = p;
        q.l = p.n;
#ifdef HZ_OUTPUT_BRDF
        c += hz_shade(q) * hz_env_irradiance(p.n);
#else
        c += hz_shade(q) * hz_env_irradiance(p.n) * 0.318309886;
#endif
    }
#endif
#endif
#ifdef HZ_DEBUG_OUTPUTS
    o_color = vec4(first, 1.0);
    o_n = vec4(n0, 1.0);
    o_l = vec4(l0, 1.0);
    o_v = vec4(p.v, 1.0);
    o_t = vec4(tl0, 1.0);
#elif defined(HZ_DISPLAY) && defined(HZ_OUTPUT_AS_IS)
    o_color = vec4(hz_encode(c * hz_exposure), HZ_OUT_ALPHA);  // (a model shown as it is: no tone curve)
#elif defined(HZ_DISPLAY)
    o_color = vec4(hz_display(max(c, vec3(0.0))), HZ_OUT_ALPHA);
#elif defined(HZ_OUTPUT_AS_IS)
    // The HDR buffer is tonemapped afterwards: what the tonemapping pass
    // turns back into c, clamped.
    o_color = vec4(hz_display_inverse(clamp(c * hz_exposure, 0.0, 1.0)), HZ_OUT_ALPHA);
#else
    o_color = vec4(max(c, vec3(0.0)), HZ_OUT_ALPHA);
#endif
}
)glsl";

inline constexpr const char *kMeshVS = R"glsl(#version 410 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec4 a_color;
uniform mat4 hz_view_proj;
out vec3 v_pos;
out vec3 v_normal;
out vec4 v_color;
void main() {
    v_pos = a_pos;
    v_normal = a_normal;
    v_color = a_color;
    gl_Position = hz_view_proj * vec4(a_pos, 1.0);
}
)glsl";

// Streamlines write two clip distances against the slab's planes
// (hz_clip; (0, 0, 0, 1) each when there is no slab: never clipped).
inline constexpr const char *kLineVS = R"glsl(#version 410 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_tangent;
layout(location = 2) in vec4 a_color;
uniform mat4 hz_view_proj;
uniform vec4 hz_clip[2];
out vec3 v_pos;
out vec3 v_tangent;
out vec4 v_color;
void main() {
    v_pos = a_pos;
    v_tangent = a_tangent.xyz;
    v_color = a_color;
    gl_Position = hz_view_proj * vec4(a_pos, 1.0);
    gl_ClipDistance[0] = dot(hz_clip[0], vec4(a_pos, 1.0));
    gl_ClipDistance[1] = dot(hz_clip[1], vec4(a_pos, 1.0));
}
)glsl";

// The slab's crossings as points (GL_PROGRAM_POINT_SIZE): lifted
// hz_point_lift mm towards the eye, so that a slice drawn in the same plane
// does not hide them. (Also the reprojected still's points: reprojection.cpp.)
inline constexpr const char *kPointVS = R"glsl(#version 410 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_tangent;
layout(location = 2) in vec4 a_color;
uniform mat4 hz_view_proj;
uniform vec3 hz_eye;
uniform float hz_point_px;
uniform float hz_point_lift;
out vec3 v_pos;
out vec3 v_tangent;
out vec4 v_color;
void main() {
    vec3 to_eye = hz_eye - a_pos;
    float d = length(to_eye);
    vec3 p = d > 0.0 ? a_pos + to_eye * (min(hz_point_lift, 0.5 * d) / d) : a_pos;
    v_pos = p;
    v_tangent = a_tangent.xyz;
    v_color = a_color;
    gl_Position = hz_view_proj * vec4(p, 1.0);
    gl_PointSize = hz_point_px;
}
)glsl";

// The fibre volume's pass: a triangle over the whole viewport; each pixel's
// ray ends on the far plane (hz_inv_view_proj: clip -> world).
inline constexpr const char *kVolumeVS = R"glsl(#version 410 core
uniform mat4 hz_inv_view_proj;
out vec3 v_ray_end;
void main() {
    vec2 q = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2)) * 2.0 - 1.0;
    vec4 w = hz_inv_view_proj * vec4(q, 1.0, 1.0);
    v_ray_end = w.xyz / w.w;
    gl_Position = vec4(q, 0.0, 1.0);
}
)glsl";

inline constexpr const char *kTubeVS = R"glsl(#version 410 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec4 a_tangent;
layout(location = 2) in vec4 a_color;
layout(location = 3) in float a_radius;
out vec3 g_pos;
out vec3 g_tangent;
out vec4 g_color;
out float g_radius;
void main() {
    g_pos = a_pos;
    g_tangent = a_tangent.xyz;
    g_color = a_color;
    g_radius = a_radius;
}
)glsl";

// Tubes: each segment becomes a view-facing quad whose across-coordinate
// gives the fragment shader the normal of the round tube (an impostor: the
// shading of a cylinder at 2 triangles per segment). Quads of adjacent
// segments share their end edges (both use the vertex tangent), so there are
// no gaps at the joints.
inline constexpr const char *kTubeGS = R"glsl(#version 410 core
layout(lines) in;
layout(triangle_strip, max_vertices = 4) out;
in vec3 g_pos[];
in vec3 g_tangent[];
in vec4 g_color[];
in float g_radius[];
uniform mat4 hz_view_proj;
uniform vec3 hz_eye;
uniform vec4 hz_clip[2];
out vec3 v_pos;
out vec3 v_tangent;
out vec4 v_color;
out vec3 v_side;
out vec3 v_front;
out float v_across;
out float v_radius;
void main() {
    vec3 seg = g_pos[1] - g_pos[0];
    for (int i = 0; i < 2; ++i) {
        vec3 t = g_tangent[i];
        if (dot(t, t) < 1e-12) t = seg;
        if (dot(t, t) < 1e-24) t = vec3(0.0, 0.0, 1.0);
        t = normalize(t);
        vec3 e = hz_eye - g_pos[i];
        vec3 front = e - dot(e, t) * t;
        if (dot(front, front) < 1e-12) front = abs(t.z) < 0.9 ? cross(t, vec3(0.0, 0.0, 1.0)) : cross(t, vec3(1.0, 0.0, 0.0));
        front = normalize(front);
        vec3 side = normalize(cross(t, front));
        for (int s = -1; s <= 1; s += 2) {
            vec3 p = g_pos[i] + float(s) * g_radius[i] * side;
            v_pos = p;
            v_tangent = t;
            v_color = g_color[i];
            v_side = side;
            v_front = front;
            v_across = float(s);
            v_radius = g_radius[i];
            gl_Position = hz_view_proj * vec4(p, 1.0);
            gl_ClipDistance[0] = dot(hz_clip[0], vec4(p, 1.0));
            gl_ClipDistance[1] = dot(hz_clip[1], vec4(p, 1.0));
            EmitVertex();
        }
    }
    EndPrimitive();
}
)glsl";

// A full-screen triangle from gl_VertexID (no vertex buffer).
inline constexpr const char *kFullscreenVS = R"glsl(#version 410 core
out vec2 v_uv;
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    v_uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
)glsl";

// Direction of a cube-map texel (OpenGL's face conventions).
inline constexpr const char *kCubeCommon = R"glsl(
const float PI = 3.14159265358979;
uniform int u_face;
vec3 cube_dir(vec2 st) {
    vec2 c = st * 2.0 - 1.0;
    vec3 d;
    if (u_face == 0) d = vec3(1.0, -c.y, -c.x);
    else if (u_face == 1) d = vec3(-1.0, -c.y, c.x);
    else if (u_face == 2) d = vec3(c.x, 1.0, c.y);
    else if (u_face == 3) d = vec3(c.x, -1.0, -c.y);
    else if (u_face == 4) d = vec3(c.x, -c.y, 1.0);
    else d = vec3(-c.x, -c.y, -1.0);
    return normalize(d);
}
float radical_inverse(uint b) {
    b = (b << 16u) | (b >> 16u);
    b = ((b & 0x55555555u) << 1u) | ((b & 0xAAAAAAAAu) >> 1u);
    b = ((b & 0x33333333u) << 2u) | ((b & 0xCCCCCCCCu) >> 2u);
    b = ((b & 0x0F0F0F0Fu) << 4u) | ((b & 0xF0F0F0F0u) >> 4u);
    b = ((b & 0x00FF00FFu) << 8u) | ((b & 0xFF00FF00u) >> 8u);
    return float(b) * 2.3283064365386963e-10;
}
vec2 hammersley(uint i, uint n) { return vec2((float(i) + 0.5) / float(n), radical_inverse(i)); }
void basis(vec3 n, out vec3 x, out vec3 y) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float b = n.x * n.y * a;
    x = vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    y = vec3(b, s + n.y * n.y * a, -n.y);
}
)glsl";

// The procedural studio: a soft grey gradient dome, a darker floor and
// three soft boxes (key, fill, rim). World space, RAS+ (z up).
inline constexpr const char *kEnvSource = R"glsl(
uniform int u_source;          // 0 studio, 1 equirectangular image
uniform sampler2D u_equirect;
float softbox(vec3 d, vec3 axis, float hw, float hh) {
    float c = dot(d, axis);
    if (c <= 0.0) return 0.0;
    vec3 u = normalize(cross(axis, abs(axis.z) < 0.95 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0)));
    vec3 w = cross(u, axis);
    vec2 p = vec2(dot(d, u), dot(d, w)) / c;
    vec2 q = abs(p) - vec2(hw, hh);
    return 1.0 - smoothstep(-0.02, 0.02, max(q.x, q.y));
}
vec3 env_source(vec3 d) {
    if (u_source == 1) {
        float u = atan(d.y, d.x) / (2.0 * PI) + 0.5;
        float v = acos(clamp(d.z, -1.0, 1.0)) / PI;
        return texture(u_equirect, vec2(u, v)).rgb;
    }
    float z = d.z;
    vec3 dome = mix(vec3(0.16, 0.17, 0.19), vec3(0.50, 0.53, 0.58), smoothstep(-0.05, 0.9, z));
    vec3 ground = vec3(0.09, 0.085, 0.08) * (0.5 + 0.5 * smoothstep(-1.0, -0.1, z));
    vec3 c = mix(ground, dome, smoothstep(-0.06, 0.02, z));
    c += vec3(4.5, 4.35, 4.1) * softbox(d, normalize(vec3(-0.55, 0.45, 0.70)), 0.45, 0.28);
    c += vec3(1.3, 1.4, 1.6) * softbox(d, normalize(vec3(0.85, 0.25, 0.35)), 0.25, 0.5);
    c += vec3(3.0, 3.0, 3.0) * softbox(d, normalize(vec3(0.05, -0.92, 0.40)), 0.6, 0.10);
    return c;
}
)glsl";

inline constexpr const char *kEnvFaceFS = R"glsl(
in vec2 v_uv;
uniform float u_size;
out vec4 o;
void main() { o = vec4(env_source(cube_dir(gl_FragCoord.xy / u_size)), 1.0); }
)glsl";

// GGX-prefiltered radiance (Karis 2013, filtered importance sampling).
inline constexpr const char *kPrefilterFS = R"glsl(
uniform samplerCube u_env;
uniform float u_size;
uniform float u_roughness;
uniform float u_env_size;
out vec4 o;
void main() {
    vec3 n = cube_dir(gl_FragCoord.xy / u_size);
    if (u_roughness <= 0.0) { o = vec4(textureLod(u_env, n, 0.0).rgb, 1.0); return; }
    vec3 x, y;
    basis(n, x, y);
    float a = max(u_roughness * u_roughness, 1e-3);
    float a2 = a * a;
    const uint N = 48u;
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
    for (uint i = 0u; i < N; ++i) {
        vec2 e = hammersley(i, N);
        float phi = 2.0 * PI * e.y;
        float ct = sqrt((1.0 - e.x) / (1.0 + (a2 - 1.0) * e.x));
        float st = sqrt(max(0.0, 1.0 - ct * ct));
        vec3 h = st * cos(phi) * x + st * sin(phi) * y + ct * n;
        vec3 l = 2.0 * dot(n, h) * h - n;
        float nl = dot(n, l);
        if (nl <= 0.0) continue;
        float d = (a2 - 1.0) * ct * ct + 1.0;
        float D = a2 / (PI * d * d);
        float pdf = D / 4.0;  // D * ct / (4 v.h) with v = n
        float omega_s = 1.0 / (float(N) * pdf + 1e-6);
        float omega_p = 4.0 * PI / (6.0 * u_env_size * u_env_size);
        float lod = max(0.5 * log2(omega_s / omega_p) + 1.0, 0.0);
        sum += textureLod(u_env, l, lod).rgb * nl;
        wsum += nl;
    }
    o = vec4(sum / max(wsum, 1e-6), 1.0);
}
)glsl";

// Irradiance E(n) by cosine-weighted sampling of a blurred mip.
inline constexpr const char *kIrradianceFS = R"glsl(
uniform samplerCube u_env;
uniform float u_size;
uniform float u_lod;
out vec4 o;
void main() {
    vec3 n = cube_dir(gl_FragCoord.xy / u_size);
    vec3 x, y;
    basis(n, x, y);
    const uint N = 256u;
    vec3 sum = vec3(0.0);
    for (uint i = 0u; i < N; ++i) {
        vec2 e = hammersley(i, N);
        float r = sqrt(e.x), phi = 2.0 * PI * e.y;
        vec3 l = r * cos(phi) * x + r * sin(phi) * y + sqrt(max(0.0, 1.0 - e.x)) * n;
        sum += textureLod(u_env, l, u_lod).rgb;
    }
    o = vec4(PI * sum / float(N), 1.0);
}
)glsl";

// Split-sum BRDF table: x = n.v, y = perceptual roughness; GGX with the
// separable Smith G of the principled model.
inline constexpr const char *kLutFS = R"glsl(
uniform float u_size;
out vec4 o;
float g1(float c, float a2) { return 2.0 * c / (c + sqrt(a2 + (1.0 - a2) * c * c)); }
void main() {
    vec2 st = gl_FragCoord.xy / u_size;
    float NoV = max(st.x, 1e-3), r = st.y;
    float a = max(r * r, 1e-3), a2 = a * a;
    vec3 v = vec3(sqrt(1.0 - NoV * NoV), 0.0, NoV);
    float A = 0.0, B = 0.0;
    const uint N = 256u;
    for (uint i = 0u; i < N; ++i) {
        vec2 e = hammersley(i, N);
        float phi = 2.0 * PI * e.y;
        float ct = sqrt((1.0 - e.x) / (1.0 + (a2 - 1.0) * e.x));
        float st2 = sqrt(max(0.0, 1.0 - ct * ct));
        vec3 h = vec3(st2 * cos(phi), st2 * sin(phi), ct);
        vec3 l = 2.0 * dot(v, h) * h - v;
        float NoL = l.z, VoH = max(dot(v, h), 0.0);
        if (NoL <= 0.0) continue;
        float G = g1(NoL, a2) * g1(NoV, a2);
        float Gv = G * VoH / (ct * NoV);
        float Fc = pow(1.0 - VoH, 5.0);
        A += (1.0 - Fc) * Gv;
        B += Fc * Gv;
    }
    o = vec4(A / float(N), B / float(N), 0.0, 1.0);
}
)glsl";

inline constexpr const char *kSkyFS = R"glsl(
in vec2 v_uv;
uniform mat4 u_inv_view_proj;
uniform samplerCube u_env;
uniform mat3 u_rotation;
uniform float u_intensity;
out vec4 o;
void main() {
    vec4 a = u_inv_view_proj * vec4(v_uv * 2.0 - 1.0, -1.0, 1.0);
    vec4 b = u_inv_view_proj * vec4(v_uv * 2.0 - 1.0, 1.0, 1.0);
    vec3 d = normalize(b.xyz / b.w - a.xyz / a.w);
    vec3 c = u_intensity * textureLod(u_env, u_rotation * d, 0.0).rgb;
#ifdef HZ_DISPLAY
    c = hz_display(c);
#endif
    o = vec4(c, 1.0);
}
)glsl";

// Exposure, tone curve (ACES fit of Narkowicz 2015, or Reinhard; chosen by
// HZ_TONEMAP 0/1/2) and sRGB encoding: linear radiance to display values.
// Every program that writes the display image directly includes it (with
// HZ_DISPLAY defined); so does the tonemapping pass of the HDR path.
inline constexpr const char *kDisplay = R"glsl(
uniform float hz_exposure;
vec3 hz_encode(vec3 c);
vec3 hz_display(vec3 c) {
    c *= hz_exposure;
    if (any(isnan(c))) return vec3(1.0, 0.0, 1.0);
#if HZ_TONEMAP == 0
    c = (c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14);  // (clamped below)
#elif HZ_TONEMAP == 1
    c = c / (1.0 + c);
#endif
    return hz_encode(c);
}
// Linear [0, 1] (clamped) to display values: the sRGB encoding alone.
vec3 hz_encode(vec3 c) {
    if (any(isnan(c))) return vec3(1.0, 0.0, 1.0);
    c = clamp(c, 0.0, 1.0);
    // sRGB encoding. Above the linear toe, 1.055 c^(1/2.4) - 0.055 is replaced
    // by a degree-6 minimax polynomial in s = sqrt(c) (one square root, which
    // llvmpipe runs as one instruction, and six multiply-adds, instead of
    // pow's exp2/log2 polynomials): at most 0.04 of an 8-bit step from the
    // exact curve on [0.0031308, 1].
    vec3 s = sqrt(c);
    vec3 hi = ((((((-0.947712481 * s + 3.41879153) * s - 5.00326586) * s + 3.89848161) * s - 1.89948356) * s + 1.57527125) * s -
              0.0422319509);
    return mix(c * 12.92, hi, step(vec3(0.0031308), c));
}
// The radiance whose exposed, tone-curved value is d (in [0, 1]): data
// drawn into the HDR image (volume slices) through this comes out of the
// tonemapping pass as d, whatever the exposure and curve.
vec3 hz_display_inverse(vec3 d) {
    d = clamp(d, 0.0, 0.999);
#if HZ_TONEMAP == 0
    // c (2.51 c + 0.03) = d (c (2.43 c + 0.59) + 0.14), solved for c >= 0
    vec3 a = 2.51 - 2.43 * d, b = 0.03 - 0.59 * d;
    vec3 c = (-b + sqrt(b * b + 4.0 * a * 0.14 * d)) / (2.0 * a);
#elif HZ_TONEMAP == 1
    vec3 c = d / (1.0 - d);
#else
    vec3 c = d;
#endif
    return c / max(hz_exposure, 1e-30);
}
)glsl";

inline constexpr const char *kTonemapFS = R"glsl(
in vec2 v_uv;
uniform sampler2D u_hdr;
out vec4 o;
void main() {
    o = vec4(hz_display(texture(u_hdr, v_uv).rgb), 1.0);
}
)glsl";

inline constexpr const char *kSliceVS = R"glsl(#version 410 core
layout(location = 0) in vec3 a_pos;
uniform mat4 hz_view_proj;
out vec3 v_pos;
void main() {
    v_pos = a_pos;
    gl_Position = hz_view_proj * vec4(a_pos, 1.0);
}
)glsl";

inline constexpr const char *kSliceFS = R"glsl(
in vec3 v_pos;
uniform sampler3D u_volume;
uniform sampler2D u_colormap;
uniform mat4 u_ras_to_tex;
uniform vec2 u_window;
uniform float u_opacity;
uniform float u_clip_below;
uniform int u_rgb;  // a colour volume: each channel through the window is the display value
// A label volume (labels.hpp's label_texture: colour, and the label as
// alpha, 0 where none is shown): each region's area at u_fill, its border
// opaque, about u_outline_px pixels wide on the slice's plane.
uniform int u_labels;
uniform float u_fill;
uniform float u_outline_px;
uniform vec3 u_dims;
out vec4 o;
void main() {
    vec3 tc = (u_ras_to_tex * vec4(v_pos, 1.0)).xyz;
    // (derivatives before any discard: voxel coordinates, voxel i spanning [i, i + 1))
    vec3 vox = tc * u_dims;
    vec3 across = abs(cross(dFdx(vox), dFdy(vox)));  // the slice's normal, in voxels
    vec3 per_px = fwidth(vox);                       // voxels a pixel
    if (any(lessThan(tc, vec3(0.0))) || any(greaterThan(tc, vec3(1.0)))) discard;
    vec3 c;
    float alpha = 1.0;
    if (u_labels != 0) {
        ivec3 dims = ivec3(u_dims);
        ivec3 cell = clamp(ivec3(floor(vox)), ivec3(0), dims - 1);
        vec4 here = texelFetch(u_volume, cell, 0);
        if (here.a == 0.0) discard;
        int normal = across.x >= across.y && across.x >= across.z ? 0 : (across.y >= across.z ? 1 : 2);
        bool border = false;
        vec3 f = vox - vec3(cell);
        for (int b = 0; b < 3; ++b) {
            if (b == normal || u_outline_px <= 0.0) continue;
            float w = per_px[b] * u_outline_px;
            ivec3 e = ivec3(0);
            e[b] = 1;
            if (f[b] < w) border = border || cell[b] == 0 || texelFetch(u_volume, cell - e, 0).a != here.a;
            if (1.0 - f[b] < w) border = border || cell[b] == dims[b] - 1 || texelFetch(u_volume, cell + e, 0).a != here.a;
        }
        alpha = border ? 1.0 : u_fill;
        if (alpha <= 0.0) discard;
        c = here.rgb;
    } else if (u_rgb != 0) {
        c = clamp((texture(u_volume, tc).rgb - u_window.x) / max(u_window.y - u_window.x, 1e-30), 0.0, 1.0);
    } else {
        float v = texture(u_volume, tc).r;
        if (v < u_clip_below) discard;
        float t = clamp((v - u_window.x) / max(u_window.y - u_window.x, 1e-30), 0.0, 1.0);
        // Data are shown as they are: the window and colormap map a value to
        // exactly the colormap's (sRGB-encoded) entry, with no exposure or tone
        // curve (those are for lit geometry).
        c = texture(u_colormap, vec2(t, 0.5)).rgb;
    }
#ifndef HZ_DISPLAY
    // The HDR buffer is linear and tonemapped afterwards: store what the
    // tonemapping pass turns back into c.
    c = mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
    c = hz_display_inverse(c);
#endif
    o = vec4(c, alpha * u_opacity);
}
)glsl";

}  // namespace hz::core::render::glsl
