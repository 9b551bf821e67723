#include "ambient_occlusion.hpp"

#include <algorithm>
#include <cmath>

namespace hz::core::render {

namespace {

// The sampling pattern, shared by the GLSL and the C++ reference: pair k
// of n at angle k x the golden angle plus a per-pixel turn (a 4 x 4 Bayer
// pattern, so neighbouring pixels sample between each other's samples), at
// sqrt((k + 0.5) / n) of the disc's radius (uniform over the disc).
constexpr double kGoldenAngle = 2.399963229728653;
constexpr int kBayer[16] = {0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5};
constexpr double kTwoPi = 6.283185307179586;

const char *kAoFS = R"glsl(
in vec2 v_uv;
uniform sampler2D u_depth;  // window depth, NEAREST
uniform ivec2 u_size;
uniform float u_near, u_far, u_focal_px, u_radius_mm, u_strength;
uniform int u_pairs;
out vec4 o;
const int kBayer[16] = int[16](0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5);
float linear_depth(float d) { return u_near * u_far / (u_far - d * (u_far - u_near)); }
// dz: how far in front of the fragment the sample at `at` lies (0 for the background).
float in_front(ivec2 at, float zp) {
    float d = texelFetch(u_depth, clamp(at, ivec2(0), u_size - 1), 0).r;
    return d >= 1.0 ? 0.0 : zp - linear_depth(d);
}
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float d = texelFetch(u_depth, px, 0).r;
    float ao = 1.0;
    if (d < 1.0) {
        float zp = linear_depth(d);
        float r_px = clamp(u_radius_mm * u_focal_px / zp, 1.0, 0.25 * float(max(u_size.x, u_size.y)));
        float turn = float(kBayer[(px.x & 3) + 4 * (px.y & 3)]) / 16.0;
        float occ = 0.0;
        for (int k = 0; k < u_pairs; ++k) {
            float a = float(k) * 2.399963229728653 + 6.283185307179586 * turn;
            float r = r_px * sqrt((float(k) + 0.5) / float(u_pairs));
            vec2 off = r * vec2(cos(a), sin(a));
            ivec2 oi = ivec2(floor(off + 0.5));
            float da = in_front(px + oi, zp), db = in_front(px - oi, zp);
            float c = clamp(0.5 * (da + db) / u_radius_mm, 0.0, 1.0);
            occ += c * (1.0 - smoothstep(2.0 * u_radius_mm, 4.0 * u_radius_mm, max(da, db)));
        }
        ao = 1.0 - u_strength * occ / float(u_pairs);
    }
    o = vec4(ao, 0.0, 0.0, 1.0);
}
)glsl";

// The factors averaged over the 4 x 4 pixels around each one (offsets -2
// to 1: one whole period of the Bayer turns, which would otherwise show as
// a fine grain), over those within a quarter of the radius in depth of it
// (no factor crosses a silhouette: the darkened floor beside a streamline
// does not darken the streamline); then multiplied into the picture.
const char *kBlurFS = R"glsl(
in vec2 v_uv;
uniform sampler2D u_depth, u_raw;
uniform ivec2 u_size;
uniform float u_near, u_far, u_radius_mm;
uniform bool u_encoded;
out vec4 o;
float linear_depth(float d) { return u_near * u_far / (u_far - d * (u_far - u_near)); }
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    float d = texelFetch(u_depth, px, 0).r;
    float ao = 1.0;
    if (d < 1.0) {
        float zc = linear_depth(d), sum = 0.0, n = 0.0;
        for (int dy = -2; dy < 2; ++dy)
            for (int dx = -2; dx < 2; ++dx) {
                ivec2 q = clamp(px + ivec2(dx, dy), ivec2(0), u_size - 1);
                float ds = texelFetch(u_depth, q, 0).r;
                if (ds >= 1.0 || abs(linear_depth(ds) - zc) > 0.25 * u_radius_mm) continue;
                sum += texelFetch(u_raw, q, 0).r;
                n += 1.0;
            }
        ao = sum / max(n, 1.0);
    }
#ifdef HZ_AO_FACTORS
    o = vec4(ao, 0.0, 0.0, 1.0);
#else
    // Multiplied into sRGB-encoded values by the blend (dst x src): a
    // factor of ao on the linear radiance is about ao^(1/2.2) on the
    // encoded value.
    o = vec4(vec3(u_encoded ? pow(ao, 1.0 / 2.2) : ao), 1.0);
#endif
}
)glsl";

double focal_px(const AoParams &p, int h) { return 0.5 * h / std::tan(p.fov_deg * kTwoPi / 720.0); }

}  // namespace

AmbientOcclusionPass::AmbientOcclusionPass(MakeProgram make) : make_(std::move(make)) {}

AmbientOcclusionPass::~AmbientOcclusionPass() {
    raw_target_.destroy();
    for (auto *p : {&raw_, &blur_, &blur_factors_})
        if (*p) glDeleteProgram((*p)->id);
}

namespace {
void set_camera(Program &p, const FrameDepth &depth, const AoParams &a) {
    glUseProgram(p.id);
    glUniform1i(p.loc("u_depth"), 0);
    glUniform2i(p.loc("u_size"), depth.width(), depth.height());
    glUniform1f(p.loc("u_near"), float(a.near_mm));
    glUniform1f(p.loc("u_far"), float(a.far_mm));
    glUniform1f(p.loc("u_radius_mm"), float(a.radius_mm));
    glViewport(0, 0, depth.width(), depth.height());
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, depth.texture());
}
void draw_triangle(GLuint empty_vao) {
    glBindVertexArray(empty_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
}
}  // namespace

void AmbientOcclusionPass::prepare() {
    const std::string v = "#version 410 core\n";
    if (!raw_) raw_ = make_(glsl::kFullscreenVS, v + kAoFS, "ambient occlusion");
    if (!blur_) blur_ = make_(glsl::kFullscreenVS, v + kBlurFS, "ambient occlusion (blur)");
}

// The raw factors of `depth` into raw_target_ (R32F, the depth's size).
void AmbientOcclusionPass::raw_factors(const FrameDepth &depth, const AoParams &p, GLuint empty_vao) {
    const int w = depth.width(), h = depth.height();
    raw_target_.ensure(w, h, GL_R32F, GL_RED, GL_FLOAT, GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, raw_target_.fbo);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    set_camera(*raw_, depth, p);
    glUniform1f(raw_->loc("u_focal_px"), float(focal_px(p, h)));
    glUniform1f(raw_->loc("u_strength"), float(p.strength));
    glUniform1i(raw_->loc("u_pairs"), std::max(1, p.pairs));
    draw_triangle(empty_vao);
}

// The blur of the raw factors, drawn by `prog` into the bound framebuffer.
void AmbientOcclusionPass::blurred(Program &prog, const FrameDepth &depth, const AoParams &p, GLuint empty_vao, bool encoded) {
    set_camera(prog, depth, p);
    glUniform1i(prog.loc("u_raw"), 1);
    glUniform1i(prog.loc("u_encoded"), encoded ? 1 : 0);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, raw_target_.tex);
    draw_triangle(empty_vao);
    glActiveTexture(GL_TEXTURE0);
}

void AmbientOcclusionPass::apply(GLuint colour_fbo, const FrameDepth &depth, const AoParams &p, GLuint empty_vao, bool encoded) {
    prepare();
    raw_factors(depth, p, empty_vao);
    glBindFramebuffer(GL_FRAMEBUFFER, colour_fbo);
    glDepthMask(GL_FALSE);
    glEnable(GL_BLEND);
    glBlendFunc(GL_ZERO, GL_SRC_COLOR);
    blurred(*blur_, depth, p, empty_vao, encoded);
    glDisable(GL_BLEND);
    glDepthMask(GL_TRUE);
}

std::vector<float> AmbientOcclusionPass::read_factors(const FrameDepth &depth, const AoParams &p, GLuint empty_vao, bool blur) {
    if (!depth.texture()) return {};
    prepare();
    if (!blur_factors_)
        blur_factors_ = make_(glsl::kFullscreenVS, std::string("#version 410 core\n#define HZ_AO_FACTORS 1\n") + kBlurFS,
                              "ambient occlusion factors (blur)");
    const int w = depth.width(), h = depth.height();
    raw_factors(depth, p, empty_vao);
    std::vector<float> out(std::size_t(w) * h);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    if (!blur) {
        glBindFramebuffer(GL_READ_FRAMEBUFFER, raw_target_.fbo);
        glReadPixels(0, 0, w, h, GL_RED, GL_FLOAT, out.data());
        return out;
    }
    targets::Tex2dFbo blurred_target;
    blurred_target.ensure(w, h, GL_R32F, GL_RED, GL_FLOAT, GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, blurred_target.fbo);
    blurred(*blur_factors_, depth, p, empty_vao, false);
    glReadPixels(0, 0, w, h, GL_RED, GL_FLOAT, out.data());
    blurred_target.destroy();
    return out;
}

std::vector<float> ao_reference(const std::vector<float> &depth, int w, int h, const AoParams &p) {
    std::vector<float> out(std::size_t(w) * h, 1.0f);
    const double n = p.near_mm, f = p.far_mm, R = p.radius_mm, fpx = focal_px(p, h);
    const int pairs = std::max(1, p.pairs);
    auto lin = [&](double d) { return n * f / (f - d * (f - n)); };
    auto at = [&](int x, int y) { return depth[std::size_t(std::clamp(y, 0, h - 1)) * w + std::clamp(x, 0, w - 1)]; };
    auto smoothstep = [](double e0, double e1, double x) {
        const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
        return t * t * (3 - 2 * t);
    };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double d = at(x, y);
            if (d >= 1.0) continue;
            const double zp = lin(d);
            const double r_px = std::clamp(R * fpx / zp, 1.0, 0.25 * std::max(w, h));
            const double turn = kBayer[(x & 3) + 4 * (y & 3)] / 16.0;
            auto in_front = [&](int sx, int sy) {
                const double ds = at(sx, sy);
                return ds >= 1.0 ? 0.0 : zp - lin(ds);
            };
            double occ = 0;
            for (int k = 0; k < pairs; ++k) {
                const double a = k * kGoldenAngle + kTwoPi * turn;
                const double r = r_px * std::sqrt((k + 0.5) / pairs);
                const int ox = int(std::floor(r * std::cos(a) + 0.5)), oy = int(std::floor(r * std::sin(a) + 0.5));
                const double da = in_front(x + ox, y + oy), db = in_front(x - ox, y - oy);
                const double c = std::clamp(0.5 * (da + db) / R, 0.0, 1.0);
                occ += c * (1.0 - smoothstep(2 * R, 4 * R, std::max(da, db)));
            }
            out[std::size_t(y) * w + x] = float(1.0 - p.strength * occ / pairs);
        }
    return out;
}

}  // namespace hz::core::render

namespace hz::core::render {

std::vector<float> ao_blur_reference(const std::vector<float> &raw, const std::vector<float> &depth, int w, int h, const AoParams &p) {
    std::vector<float> out(std::size_t(w) * h, 1.0f);
    const double n = p.near_mm, f = p.far_mm;
    auto lin = [&](double d) { return n * f / (f - d * (f - n)); };
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double d = depth[std::size_t(y) * w + x];
            if (d >= 1.0) continue;
            const double zc = lin(d);
            double sum = 0, k = 0;
            for (int dy = -2; dy < 2; ++dy)
                for (int dx = -2; dx < 2; ++dx) {
                    const std::size_t q = std::size_t(std::clamp(y + dy, 0, h - 1)) * w + std::clamp(x + dx, 0, w - 1);
                    if (depth[q] >= 1.0 || std::abs(lin(depth[q]) - zc) > 0.25 * p.radius_mm) continue;
                    sum += raw[q], k += 1;
                }
            out[std::size_t(y) * w + x] = float(sum / std::max(k, 1.0));
        }
    return out;
}

}  // namespace hz::core::render
