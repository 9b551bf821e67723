// The last complete frame, reprojected (reprojection.hpp).
#include "reprojection.hpp"

#include "glsl.hpp"

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

namespace hz::core::render {

namespace {

// The vertex stage is the slab crossings' (glsl::kPointVS: a point lifted
// towards the eye); the colour is its attribute 2, the tangent unused.
struct SplatVertex {
    float pos[3];
    std::uint8_t rgba[4];
};
static_assert(sizeof(SplatVertex) == 16);

constexpr const char *kSplatFS = R"glsl(#version 410 core
in vec4 v_color;
layout(location = 0) out vec4 o_color;
void main() { o_color = vec4(v_color.rgb, 1.0); }
)glsl";

}  // namespace

Reprojection::Reprojection(MakeProgram make) : make_(std::move(make)) {}

Reprojection::~Reprojection() {
    if (vao_) glDeleteVertexArrays(1, &vao_);
    if (vbo_) glDeleteBuffers(1, &vbo_);
    if (program_) glDeleteProgram(program_->id);
}

void Reprojection::clear() { valid_ = false; }

bool Reprojection::usable(std::uint64_t generation, int w, int h, const glm::dvec3 &eye, const glm::dvec3 &target,
                          double max_turn_deg) const {
    if (!valid_ || count_ == 0 || generation != generation_ || w != w_ || h != h_) return false;
    const glm::dvec3 a = eye_ - target_, b = eye - target;
    const double la = glm::length(a), lb = glm::length(b);
    if (!(la > 0) || !(lb > 0) || lb > 1.2 * la || lb < la / 1.2) return false;
    const double c = glm::dot(a, b) / (la * lb);
    return c >= std::cos(glm::radians(max_turn_deg));
}

void Reprojection::capture(GLuint colour_fbo, GLuint depth_fbo, int w, int h, const glm::dmat4 &inv_view_proj, int scale,
                           std::uint64_t generation, const glm::dvec3 &eye, const glm::dvec3 &target) {
    valid_ = false;
    eye_ = eye, target_ = target;
    if (w <= 0 || h <= 0 || scale < 1) return;
    std::vector<std::uint8_t> rgba(std::size_t(w) * h * 4);
    std::vector<float> depth(std::size_t(w) * h);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, colour_fbo);
    glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    glBindFramebuffer(GL_READ_FRAMEBUFFER, depth_fbo);
    glReadPixels(0, 0, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, depth.data());
    std::vector<SplatVertex> out;
    out.reserve(std::size_t(w / scale + 1) * (h / scale + 1));
    for (int by = 0; by < h; by += scale)
        for (int bx = 0; bx < w; bx += scale) {
            float dmin = 1.0f;
            int dx = 0, dy = 0;
            unsigned sum[3] = {0, 0, 0}, n = 0;
            for (int y = by; y < std::min(h, by + scale); ++y)
                for (int x = bx; x < std::min(w, bx + scale); ++x) {
                    const std::size_t i = std::size_t(y) * w + x;
                    for (int c = 0; c < 3; ++c) sum[c] += rgba[i * 4 + c];
                    ++n;
                    if (depth[i] < dmin) dmin = depth[i], dx = x, dy = y;
                }
            if (!(dmin < 1.0f)) continue;  // nothing drawn in the block
            const glm::dvec4 ndc((dx + 0.5) / w * 2 - 1, (dy + 0.5) / h * 2 - 1, double(dmin) * 2 - 1, 1.0);
            const glm::dvec4 wp = inv_view_proj * ndc;
            if (!(std::abs(wp.w) > 1e-12)) continue;
            SplatVertex v;
            for (int k = 0; k < 3; ++k) v.pos[k] = float(wp[k] / wp.w);
            for (int c = 0; c < 3; ++c) v.rgba[c] = std::uint8_t((sum[c] + n / 2) / n);
            v.rgba[3] = 255;
            out.push_back(v);
        }
    if (!vao_) {
        glGenVertexArrays(1, &vao_);
        glGenBuffers(1, &vbo_);
        glBindVertexArray(vao_);
        glBindBuffer(GL_ARRAY_BUFFER, vbo_);
        glEnableVertexAttribArray(0);
        glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(SplatVertex), reinterpret_cast<void *>(0));
        glEnableVertexAttribArray(2);
        glVertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(SplatVertex), reinterpret_cast<void *>(12));
    }
    glBindBuffer(GL_ARRAY_BUFFER, vbo_);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(out.size() * sizeof(SplatVertex)), out.data(), GL_STATIC_DRAW);
    count_ = out.size();
    generation_ = generation;
    w_ = w, h_ = h, scale_ = scale;
    valid_ = true;
}

void Reprojection::draw(const glm::mat4 &view_proj, const glm::dvec3 &eye, double point_px, double lift_mm) {
    if (!valid_ || count_ == 0) return;
    if (!program_) program_ = make_(glsl::kPointVS, kSplatFS, "reprojection");
    glUseProgram(program_->id);
    glUniformMatrix4fv(program_->loc("hz_view_proj"), 1, GL_FALSE, glm::value_ptr(view_proj));
    glUniform3f(program_->loc("hz_eye"), float(eye.x), float(eye.y), float(eye.z));
    glUniform1f(program_->loc("hz_point_px"), float(point_px));
    glUniform1f(program_->loc("hz_point_lift"), float(lift_mm));
    glEnable(GL_PROGRAM_POINT_SIZE);
    glBindVertexArray(vao_);
    glDrawArrays(GL_POINTS, 0, GLsizei(count_));
    glDisable(GL_PROGRAM_POINT_SIZE);
}

}  // namespace hz::core::render
