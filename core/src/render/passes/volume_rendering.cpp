// Direct volume rendering (volume_rendering.hpp).
#include "volume_rendering.hpp"

#include "../glsl.hpp"

#include <hz/core/render/renderer.hpp>

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cmath>

namespace hz::core::render {

namespace {

// Each pixel's ray: from the eye through the pixel, clipped to the volume's
// box (in its texture coordinates, where the box is [0, 1]^3; the ray's
// parameter is the same in both spaces, the map being affine) and ended at
// the frame's depth; n equal steps of at most u_step mm, sampled at their
// middles, composited front to back.
constexpr const char *kMarchFS = R"glsl(
in vec2 v_uv;
uniform sampler3D u_volume;
uniform sampler2D u_transfer;
uniform sampler2D u_depth;
#ifdef HZ_SEGMENT
uniform sampler2D u_near;  // where the ray starts (window depth; 0: at the eye)
#endif
uniform mat4 u_inv_view_proj;
uniform vec3 u_eye;
uniform mat4 u_ras_to_tex;
uniform vec2 u_window;
uniform float u_step;
uniform float u_opacity;
uniform int u_shade;
uniform vec3 u_light;      // towards the key light, world, unit
uniform mat3 u_normal_to_world;  // a gradient in texture coordinates to one in world mm (the transpose of world -> texture)
uniform vec3 u_texel;      // one voxel in texture coordinates
out vec4 o;
void main() {
    vec2 ndc = v_uv * 2.0 - 1.0;
    vec4 f = u_inv_view_proj * vec4(ndc, 1.0, 1.0);
    vec3 d = normalize(f.xyz / f.w - u_eye);
    float z = texelFetch(u_depth, ivec2(gl_FragCoord.xy), 0).r;
    float t_end = 1e30;
    if (z < 1.0) {
        vec4 s = u_inv_view_proj * vec4(ndc, z * 2.0 - 1.0, 1.0);
        t_end = dot(s.xyz / s.w - u_eye, d);
    }
    vec3 ot = (u_ras_to_tex * vec4(u_eye, 1.0)).xyz;
    vec3 dt = mat3(u_ras_to_tex) * d;
    // (a zero component: the ray runs within that slab or never meets it)
    vec3 inv = vec3(abs(dt.x) > 1e-20 ? 1.0 / dt.x : 1e30, abs(dt.y) > 1e-20 ? 1.0 / dt.y : 1e30, abs(dt.z) > 1e-20 ? 1.0 / dt.z : 1e30);
    vec3 ta = -ot * inv, tb = (1.0 - ot) * inv;
    vec3 lo = min(ta, tb), hi = max(ta, tb);
    for (int k = 0; k < 3; ++k)
        if (abs(dt[k]) <= 1e-20) {
            bool inside = ot[k] >= 0.0 && ot[k] <= 1.0;
            lo[k] = inside ? -1e30 : 1e30;
            hi[k] = inside ? 1e30 : -1e30;
        }
    float t_start = 0.0;
#ifdef HZ_SEGMENT
    float zn = texelFetch(u_near, ivec2(gl_FragCoord.xy), 0).r;
    if (zn > 0.0) {
        vec4 s = u_inv_view_proj * vec4(ndc, zn * 2.0 - 1.0, 1.0);
        t_start = dot(s.xyz / s.w - u_eye, d);
    }
#endif
    float t0 = max(max(lo.x, lo.y), max(lo.z, t_start));
    float t1 = min(min(min(hi.x, hi.y), hi.z), t_end);
    if (!(t1 > t0)) discard;
    int n = min(int(ceil((t1 - t0) / u_step)), 4096);
    n = max(n, 1);
    float h = (t1 - t0) / float(n);
    vec4 acc = vec4(0.0);
    float scale = 1.0 / max(u_window.y - u_window.x, 1e-30);
    for (int i = 0; i < n; ++i) {
        vec3 tc = ot + dt * (t0 + (float(i) + 0.5) * h);
        float v = texture(u_volume, tc).r;
        if (isnan(v)) continue;
        float w = clamp((v - u_window.x) * scale, 0.0, 1.0);
        vec4 c = texture(u_transfer, vec2((w * 255.0 + 0.5) / 256.0, 0.5));
        if (c.a <= 0.0) continue;
        float a = 1.0 - pow(max(1.0 - c.a, 0.0), h);
        if (u_shade != 0) {
            // The gradient (central differences, one voxel) as the normal:
            // two-sided Lambert with an ambient third; where the values
            // hardly change (within a window's thousandth per voxel), unlit.
            vec3 g = vec3(texture(u_volume, tc + vec3(u_texel.x, 0.0, 0.0)).r - texture(u_volume, tc - vec3(u_texel.x, 0.0, 0.0)).r,
                          texture(u_volume, tc + vec3(0.0, u_texel.y, 0.0)).r - texture(u_volume, tc - vec3(0.0, u_texel.y, 0.0)).r,
                          texture(u_volume, tc + vec3(0.0, 0.0, u_texel.z)).r - texture(u_volume, tc - vec3(0.0, 0.0, u_texel.z)).r) *
                     scale;
            vec3 gt = g / u_texel;  // (differences over one voxel each: per unit of texture coordinate)
            vec3 n = u_normal_to_world * gt;
            float m = length(n);
            if (length(gt) * min(u_texel.x, min(u_texel.y, u_texel.z)) > 2e-3) c.rgb *= 0.3 + 0.7 * abs(dot(n / m, u_light));
        }
        acc.rgb += (1.0 - acc.a) * a * c.rgb;
        acc.a += (1.0 - acc.a) * a;
        if (acc.a > 0.996) break;
    }
    if (acc.a <= 0.0) discard;
#ifndef HZ_DISPLAY
    // A linear picture: what the tonemapping pass turns back into the
    // composited display value.
    vec3 c = acc.rgb / acc.a;
    c = mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
    acc.rgb = hz_display_inverse(c) * acc.a;
#endif
    o = acc * u_opacity;
}
)glsl";

}  // namespace

std::vector<float> transfer_table(const TransferFunction &tf) {
    std::vector<float> t(256 * 4);
    const auto &pts = tf.opacity;
    for (int i = 0; i < 256; ++i) {
        const double f = i / 255.0;
        const auto c = colormap(tf.colormap, f);
        double a = pts.front()[1];
        if (f >= pts.back()[0]) {
            a = pts.back()[1];
        } else {
            for (std::size_t k = 1; k < pts.size(); ++k)
                if (f <= pts[k][0]) {
                    const double u = (f - pts[k - 1][0]) / std::max(pts[k][0] - pts[k - 1][0], 1e-12);
                    a = f < pts[k - 1][0] ? pts[k - 1][1] : pts[k - 1][1] + std::clamp(u, 0.0, 1.0) * (pts[k][1] - pts[k - 1][1]);
                    break;
                }
        }
        t[std::size_t(i) * 4 + 0] = c[0], t[std::size_t(i) * 4 + 1] = c[1], t[std::size_t(i) * 4 + 2] = c[2];
        t[std::size_t(i) * 4 + 3] = float(a);
    }
    return t;
}

VolumeRendering::VolumeRendering(MakeProgram make) : make_(std::move(make)) {}

VolumeRendering::~VolumeRendering() {
    for (auto &[k, p] : programs_) glDeleteProgram(p->id);
}

Program &VolumeRendering::program(bool encoded, int tone_curve, bool segment) {
    const int key = (tone_curve * 2 + (encoded ? 1 : 0)) * 2 + (segment ? 1 : 0);
    auto &p = programs_[key];
    if (!p) {
        std::string fs = "#version 410 core\n#define HZ_TONEMAP " + std::to_string(tone_curve) + "\n";
        if (encoded) fs += "#define HZ_DISPLAY 1\n";
        if (segment) fs += "#define HZ_SEGMENT 1\n";
        p = make_(glsl::kFullscreenVS, fs + glsl::kDisplay + kMarchFS, "volume rendering");
    }
    return *p;
}

void VolumeRendering::apply(GLuint colour_fbo, const FrameDepth &depth, const VolumeRayParams &p, GLuint empty_vao, bool encoded) {
    Program &prog = program(encoded, p.tone_curve, false);
    glBindFramebuffer(GL_FRAMEBUFFER, colour_fbo);
    glViewport(0, 0, depth.width(), depth.height());
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);  // premultiplied, over the picture
    march(prog, p, depth.texture(), 0, empty_vao);
    glDisable(GL_BLEND);
}

void VolumeRendering::apply_segment(GLuint near_depth, GLuint far_depth, const VolumeRayParams &p, GLuint empty_vao) {
    Program &prog = program(false, p.tone_curve, true);
    march(prog, p, far_depth, near_depth, empty_vao);
}

void VolumeRendering::march(Program &prog, const VolumeRayParams &p, GLuint far_depth, GLuint near_depth, GLuint empty_vao) {
    glUseProgram(prog.id);
    bind_sampler(prog, "u_volume", 0, GL_TEXTURE_3D, p.volume_tex);
    bind_sampler(prog, "u_transfer", 1, GL_TEXTURE_2D, p.transfer_tex);
    bind_sampler(prog, "u_depth", 2, GL_TEXTURE_2D, far_depth);
    if (near_depth) bind_sampler(prog, "u_near", 3, GL_TEXTURE_2D, near_depth);
    glUniformMatrix4fv(prog.loc("u_inv_view_proj"), 1, GL_FALSE, glm::value_ptr(p.inv_view_proj));
    glUniform3f(prog.loc("u_eye"), p.eye.x, p.eye.y, p.eye.z);
    glUniformMatrix4fv(prog.loc("u_ras_to_tex"), 1, GL_FALSE, glm::value_ptr(p.ras_to_tex));
    glUniform2f(prog.loc("u_window"), p.window.x, p.window.y);
    glUniform1f(prog.loc("u_step"), p.step_mm);
    glUniform1f(prog.loc("u_opacity"), p.opacity);
    glUniform1i(prog.loc("u_shade"), p.shade ? 1 : 0);
    // f(x) = F(A x + b): the world gradient is A^T times the texture one.
    const glm::mat3 to_tex(p.ras_to_tex);
    const glm::mat3 at = glm::transpose(to_tex);
    glUniformMatrix3fv(prog.loc("u_normal_to_world"), 1, GL_FALSE, glm::value_ptr(at));
    const glm::vec3 l = glm::normalize(p.to_light);
    glUniform3f(prog.loc("u_light"), l.x, l.y, l.z);
    GLint dims[3] = {1, 1, 1};
    glBindTexture(GL_TEXTURE_3D, p.volume_tex);
    glGetTexLevelParameteriv(GL_TEXTURE_3D, 0, GL_TEXTURE_WIDTH, &dims[0]);
    glGetTexLevelParameteriv(GL_TEXTURE_3D, 0, GL_TEXTURE_HEIGHT, &dims[1]);
    glGetTexLevelParameteriv(GL_TEXTURE_3D, 0, GL_TEXTURE_DEPTH, &dims[2]);
    glUniform3f(prog.loc("u_texel"), 1.0f / float(std::max(dims[0], 1)), 1.0f / float(std::max(dims[1], 1)),
                1.0f / float(std::max(dims[2], 1)));
    glUniform1f(prog.loc("hz_exposure"), p.exposure);
    glBindVertexArray(empty_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
}

}  // namespace hz::core::render
