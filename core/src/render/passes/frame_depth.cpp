#include "frame_depth.hpp"

#include <hz/core/data.hpp>

namespace hz::core::render {

FrameDepth::~FrameDepth() { target_.destroy(); }

void FrameDepth::resolve(GLuint fbo, int w, int h) {
    target_.ensure_depth_only(w, h);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, target_.fbo);
    glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_DEPTH_BUFFER_BIT, GL_NEAREST);
}

std::vector<float> FrameDepth::read() const {
    if (!target_.depth_tex) return {};
    std::vector<float> out(std::size_t(target_.width) * target_.height);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, target_.fbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, target_.width, target_.height, GL_DEPTH_COMPONENT, GL_FLOAT, out.data());
    return out;
}

}  // namespace hz::core::render
