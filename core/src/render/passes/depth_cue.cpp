#include "depth_cue.hpp"

#include <algorithm>

namespace hz::core::render {

namespace {
const char *kDepthCueFS = R"glsl(#version 410 core
in vec2 v_uv;
uniform sampler2D u_depth;
uniform float u_near, u_far, u_from, u_to, u_strength;
uniform vec3 u_background;
out vec4 o;
void main() {
    float d = texelFetch(u_depth, ivec2(gl_FragCoord.xy), 0).r;
    if (d >= 1.0) discard;
    float z = u_near * u_far / (u_far - d * (u_far - u_near));
    o = vec4(u_background, u_strength * clamp((z - u_from) / max(u_to - u_from, 1e-6), 0.0, 1.0));
}
)glsl";
}  // namespace

double depth_cue_weight(double d, const DepthCueParams &p) {
    if (d >= 1.0) return 0.0;
    const double z = p.near_mm * p.far_mm / (p.far_mm - d * (p.far_mm - p.near_mm));
    return p.strength * std::clamp((z - p.from_mm) / std::max(p.to_mm - p.from_mm, 1e-6), 0.0, 1.0);
}

DepthCuePass::DepthCuePass(MakeProgram make) : make_(std::move(make)) {}

DepthCuePass::~DepthCuePass() {
    if (program_) glDeleteProgram(program_->id);
}

void DepthCuePass::prepare() {
    if (!program_) program_ = make_(glsl::kFullscreenVS, kDepthCueFS, "depth cue");
}

void DepthCuePass::apply(GLuint colour_fbo, const FrameDepth &depth, const DepthCueParams &p, GLuint empty_vao) {
    prepare();
    glBindFramebuffer(GL_FRAMEBUFFER, colour_fbo);
    glViewport(0, 0, depth.width(), depth.height());
    glDisable(GL_DEPTH_TEST);
    glDepthMask(GL_FALSE);
    glEnable(GL_BLEND);
    glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);  // (the picture's alpha kept)
    glUseProgram(program_->id);
    glUniform1i(program_->loc("u_depth"), 0);
    glUniform1f(program_->loc("u_near"), float(p.near_mm));
    glUniform1f(program_->loc("u_far"), float(p.far_mm));
    glUniform1f(program_->loc("u_from"), float(p.from_mm));
    glUniform1f(program_->loc("u_to"), float(p.to_mm));
    glUniform1f(program_->loc("u_strength"), float(p.strength));
    glUniform3f(program_->loc("u_background"), p.background[0], p.background[1], p.background[2]);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, depth.texture());
    glBindVertexArray(empty_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDisable(GL_BLEND);
    glDepthMask(GL_TRUE);
}

}  // namespace hz::core::render
