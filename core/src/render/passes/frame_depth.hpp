// The frame's depth as a texture, for the passes after the geometry
// (private to the renderer): resolved once per frame from the framebuffer
// the scene was drawn into (a renderbuffer, possibly multisampled), then
// sampled by every pass that reads depth (ambient occlusion, depth cue).
// Threading: the GL context's thread.
#pragma once

#include "../gl.hpp"

#include <vector>

namespace hz::core::render {

class FrameDepth {
public:
    FrameDepth() = default;
    ~FrameDepth();
    FrameDepth(const FrameDepth &) = delete;
    FrameDepth &operator=(const FrameDepth &) = delete;

    // Copies the depth of `fbo` (w x h; multisampled: one sample each) into
    // the texture. Throws Error if the driver cannot make the target.
    void resolve(GLuint fbo, int w, int h);
    GLuint texture() const { return tex_; }  // DEPTH_COMPONENT24, NEAREST; 0 before resolve
    int width() const { return w_; }
    int height() const { return h_; }
    // Window depths in [0, 1] (1: the background), rows bottom to top: for
    // the tests. Reads back; slow.
    std::vector<float> read() const;

private:
    GLuint fbo_ = 0, tex_ = 0;
    int w_ = 0, h_ = 0;
};

}  // namespace hz::core::render
