#include "frame_depth.hpp"

#include <hz/core/data.hpp>

namespace hz::core::render {

FrameDepth::~FrameDepth() {
    if (fbo_) glDeleteFramebuffers(1, &fbo_);
    if (tex_) glDeleteTextures(1, &tex_);
}

void FrameDepth::resolve(GLuint fbo, int w, int h) {
    if (!tex_ || w != w_ || h != h_) {
        if (tex_) glDeleteTextures(1, &tex_);
        if (!fbo_) glGenFramebuffers(1, &fbo_);
        glGenTextures(1, &tex_);
        glBindTexture(GL_TEXTURE_2D, tex_);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT24, w, h, 0, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT, nullptr);
        clamped_texture_2d(GL_NEAREST);
        glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, tex_, 0);
        glDrawBuffer(GL_NONE);
        glReadBuffer(GL_NONE);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw Error("renderer: the frame's depth: incomplete framebuffer");
        w_ = w, h_ = h;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fbo_);
    glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_DEPTH_BUFFER_BIT, GL_NEAREST);
}

std::vector<float> FrameDepth::read() const {
    if (!tex_) return {};
    std::vector<float> out(std::size_t(w_) * h_);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, w_, h_, GL_DEPTH_COMPONENT, GL_FLOAT, out.data());
    return out;
}

}  // namespace hz::core::render
