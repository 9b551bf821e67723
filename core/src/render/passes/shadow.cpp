// Shadows of the key light (shadow.hpp).
#include "shadow.hpp"

#include "../glsl.hpp"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <cmath>

namespace hz::core::render {

namespace {

// Casters write depth only.
constexpr const char *kCasterFS = "#version 410 core\nvoid main() {}\n";

}  // namespace

ShadowView fit_shadow_view(const glm::dvec3 &to_light, const Bounds &box) {
    ShadowView v;
    v.to_light = glm::normalize(to_light);
    const glm::dvec3 lo(box.min[0], box.min[1], box.min[2]), hi(box.max[0], box.max[1], box.max[2]);
    const glm::dvec3 centre = 0.5 * (lo + hi);
    // The sphere around the box (at least 1 mm): the same extent from every
    // direction, so that the map's texels keep their size as the light turns.
    const double r = std::max(0.5 * glm::length(hi - lo), 1.0);
    const double margin = 0.05 * r;  // (tubes' radii and the bias reach a little past the box)
    v.target = centre;
    v.eye = centre + v.to_light * (r + 2.0 * margin);
    const glm::dvec3 up = std::abs(v.to_light.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
    const glm::dmat4 view = glm::lookAt(v.eye, v.target, up);
    const double s = r + margin;
    v.view_proj = glm::ortho(-s, s, -s, s, margin, 2.0 * (r + 2.0 * margin)) * view;
    v.extent_mm = 2.0 * s;
    return v;
}

ShadowPass::ShadowPass(MakeProgram make) : make_(std::move(make)) {}

ShadowPass::~ShadowPass() {
    for (auto &p : casters_)
        if (p) glDeleteProgram(p->id);
    if (fbo_) glDeleteFramebuffers(1, &fbo_);
    if (tex_) glDeleteTextures(1, &tex_);
}

void ShadowPass::begin(const ShadowView &view, int size) {
    view_ = view;
    if (size != size_) {
        if (fbo_) glDeleteFramebuffers(1, &fbo_), fbo_ = 0;
        if (tex_) glDeleteTextures(1, &tex_), tex_ = 0;
        size_ = 0;
        glGenTextures(1, &tex_);
        glBindTexture(GL_TEXTURE_2D, tex_);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT24, size, size, 0, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT, nullptr);
        // Compared by the sampler (sampler2DShadow), bilinearly: four
        // texels' answers blended.
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
        glGenFramebuffers(1, &fbo_);
        glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, tex_, 0);
        glDrawBuffer(GL_NONE);
        glReadBuffer(GL_NONE);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw Error("shadows: a " + std::to_string(size) + "x" + std::to_string(size) + " shadow map does not fit in the GL driver");
        size_ = size;
    }
    resume();
    glClearDepth(1.0);
    glClear(GL_DEPTH_BUFFER_BIT);
}

void ShadowPass::resume() {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glViewport(0, 0, size_, size_);
    glDisable(GL_BLEND);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
    // Triangles (surfaces, tubes) stored a little farther than they lie, so
    // that a lit surface does not shadow itself (lines: the receivers' bias).
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.5f, 2.0f);
}

void ShadowPass::end() { glDisable(GL_POLYGON_OFFSET_FILL); }

Program &ShadowPass::caster(Geom g) {
    const int k = g == Geom::Mesh ? 0 : g == Geom::Tube ? 1 : 2;
    if (!casters_[k]) {
        if (g == Geom::Mesh)
            casters_[k] = make_(glsl::kMeshVS, "", kCasterFS, "shadows: surface caster");
        else if (g == Geom::Tube)
            casters_[k] = make_(glsl::kTubeVS, glsl::kTubeGS, kCasterFS, "shadows: tube caster");
        else
            casters_[k] = make_(glsl::kLineVS, "", kCasterFS, "shadows: line caster");
    }
    return *casters_[k];
}

void ShadowPass::bind(Program &p, int unit, const ShadowParams &params) const {
    if (p.loc("hz_shadow_map") < 0) return;
    glActiveTexture(GL_TEXTURE0 + unit);
    glBindTexture(GL_TEXTURE_2D, tex_);
    glUniform1i(p.loc("hz_shadow_map"), unit);
    // World mm -> the map's texture coordinates and depth, all in [0, 1].
    const glm::dmat4 bias = glm::translate(glm::dmat4(1.0), glm::dvec3(0.5)) * glm::scale(glm::dmat4(1.0), glm::dvec3(0.5));
    const glm::mat4 m(bias * view_.view_proj);
    glUniformMatrix4fv(p.loc("hz_shadow_matrix"), 1, GL_FALSE, glm::value_ptr(m));
    const double texel = view_.extent_mm / std::max(size_, 1);
    glUniform1f(p.loc("hz_shadow_texel_mm"), float(texel));
    // (at least a texel: the filter then always blends neighbours)
    glUniform1f(p.loc("hz_shadow_soft_mm"), float(std::max(params.softness_mm, texel)));
    glUniform1f(p.loc("hz_shadow_extent_mm"), float(view_.extent_mm));
    glUniform1f(p.loc("hz_shadow_strength"), float(params.strength));
}

std::vector<float> ShadowPass::read() const {
    std::vector<float> d(std::size_t(size_) * size_);
    if (!fbo_) return d;
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, size_, size_, GL_DEPTH_COMPONENT, GL_FLOAT, d.data());
    return d;
}

}  // namespace hz::core::render
