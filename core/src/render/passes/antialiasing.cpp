#include "antialiasing.hpp"

#include "../targets.hpp"

namespace hz::core::render {

namespace {

const char *kEdgeAaFS = R"glsl(#version 410 core
in vec2 v_uv;
uniform sampler2D u_image;  // display values, linear filtering
out vec4 o;
float luma(vec3 c) { return dot(c, vec3(0.299, 0.587, 0.114)); }
ivec2 g_last;
float at(ivec2 p) { return luma(texelFetch(u_image, clamp(p, ivec2(0), g_last), 0).rgb); }
void main() {
    g_last = textureSize(u_image, 0) - 1;
    vec2 texel = 1.0 / vec2(textureSize(u_image, 0));
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = texelFetch(u_image, p, 0);
    float m = luma(c.rgb);
    float n = at(p + ivec2(0, 1)), s = at(p - ivec2(0, 1)), e = at(p + ivec2(1, 0)), w = at(p - ivec2(1, 0));
    float lo = min(m, min(min(n, s), min(e, w))), hi = max(m, max(max(n, s), max(e, w)));
    if (hi - lo < max(0.03, 0.125 * hi)) {  // (no edge: most of a picture)
        o = c;
        return;
    }
    float ne = at(p + ivec2(1, 1)), nw = at(p + ivec2(-1, 1)), se = at(p + ivec2(1, -1)), sw = at(p + ivec2(-1, -1));
    // The axis across the edge, as a doubled angle (an axis has no sign):
    // the luma gradient's (Sobel), plus the axis of the curvature's larger
    // eigenvalue in magnitude (the Hessian's), which a line one pixel wide
    // has at its centre where its gradient vanishes; both weighted as
    // squares of luma differences.
    vec2 g = 0.25 * vec2((ne + 2.0 * e + se) - (nw + 2.0 * w + sw), (nw + 2.0 * n + ne) - (sw + 2.0 * s + se));
    float hxx = e + w - 2.0 * m, hyy = n + s - 2.0 * m, hxy = 0.25 * (ne + sw - nw - se);
    vec2 hd = vec2(hxx - hyy, 2.0 * hxy);  // (towards the larger eigenvalue's axis; its length the eigenvalues' gap)
    vec2 across = vec2(g.x * g.x - g.y * g.y, 2.0 * g.x * g.y) + (hxx + hyy >= 0.0 ? hd : -hd) * length(hd);
    if (dot(across, across) < 1e-12) {
        o = c;
        return;
    }
    float phi = 0.5 * atan(across.y, across.x);
    vec2 along = vec2(-sin(phi), cos(phi));
    // One step of the staircase along a shallow edge is 1/slope pixels
    // long: the average spans that, up to 4 pixels (8 blurred more than
    // it smoothed: 7.2 against 6.7 rms from a 16x supersampled picture).
    float k = 1.0 / max(min(abs(along.x), abs(along.y)), 0.25);
    vec2 d = along * k * texel;
    vec3 a = 0.5 * (texture(u_image, v_uv - 0.125 * d).rgb + texture(u_image, v_uv + 0.125 * d).rgb);
    vec3 b = 0.5 * a + 0.25 * (texture(u_image, v_uv - 0.375 * d).rgb + texture(u_image, v_uv + 0.375 * d).rgb);
    float lb = luma(b);
    o = vec4(lb < lo || lb > hi ? a : b, c.a);
}
)glsl";

const char *kWeightedFS = R"glsl(#version 410 core
uniform sampler2D u_src;
uniform float u_weight;
out vec4 o;
void main() { o = u_weight * texelFetch(u_src, ivec2(gl_FragCoord.xy), 0); }
)glsl";

double radical_inverse(int i, int base) {
    double f = 1.0, r = 0.0;
    for (; i > 0; i /= base) f /= base, r += f * (i % base);
    return r;
}

void fullscreen(Program &p, GLuint empty_vao) {
    glUseProgram(p.id);
    glBindVertexArray(empty_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
}

}  // namespace

std::array<double, 2> jitter_offset(int i) { return {radical_inverse(i + 1, 2) - 0.5, radical_inverse(i + 1, 3) - 0.5}; }

EdgeAaPass::EdgeAaPass(MakeProgram make) : make_(std::move(make)) {}

EdgeAaPass::~EdgeAaPass() {
    if (program_) glDeleteProgram(program_->id);
    copy_.destroy();
}

void EdgeAaPass::apply(GLuint colour_fbo, int w, int h, GLuint empty_vao) {
    if (!program_) program_ = make_(glsl::kFullscreenVS, kEdgeAaFS, "edge anti-aliasing");
    copy_.ensure(w, h, GL_RGBA8, GL_RGBA, GL_UNSIGNED_BYTE);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, colour_fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, copy_.fbo);
    glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, colour_fbo);
    glViewport(0, 0, w, h);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    glUseProgram(program_->id);
    bind_sampler(*program_, "u_image", 0, GL_TEXTURE_2D, copy_.tex);
    fullscreen(*program_, empty_vao);
}

Accumulation::Accumulation(MakeProgram make) : make_(std::move(make)) {}

Accumulation::~Accumulation() {
    if (program_) glDeleteProgram(program_->id);
    sum_.destroy();
}

void Accumulation::begin(int w, int h) {
    if (!program_) program_ = make_(glsl::kFullscreenVS, kWeightedFS, "accumulation");
    sum_.ensure(w, h, GL_RGBA32F, GL_RGBA, GL_FLOAT);
    glBindFramebuffer(GL_FRAMEBUFFER, sum_.fbo);
    glClearColor(0, 0, 0, 0);
    glClear(GL_COLOR_BUFFER_BIT);
}

void Accumulation::draw(GLuint to_fbo, GLuint from_tex, double weight, bool add, GLuint empty_vao) {
    glBindFramebuffer(GL_FRAMEBUFFER, to_fbo);
    glViewport(0, 0, sum_.width, sum_.height);
    glDisable(GL_DEPTH_TEST);
    if (add) glEnable(GL_BLEND), glBlendFunc(GL_ONE, GL_ONE);
    glUseProgram(program_->id);
    bind_sampler(*program_, "u_src", 0, GL_TEXTURE_2D, from_tex);
    glUniform1f(program_->loc("u_weight"), float(weight));
    fullscreen(*program_, empty_vao);
    glDisable(GL_BLEND);
}

void Accumulation::add(GLuint tex, double weight, GLuint empty_vao) { draw(sum_.fbo, tex, weight, true, empty_vao); }

void Accumulation::resolve(GLuint fbo, GLuint empty_vao, double scale) { draw(fbo, sum_.tex, scale, false, empty_vao); }

}  // namespace hz::core::render
