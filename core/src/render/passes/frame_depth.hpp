// The frame's depth as a texture, for the passes after the geometry
// (private to the renderer): resolved once per frame from the framebuffer
// the scene was drawn into (a renderbuffer, possibly multisampled), then
// sampled by every pass that reads depth (ambient occlusion, depth cue).
// Threading: the GL context's thread.
#pragma once

#include "../targets.hpp"
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
    GLuint texture() const { return target_.depth_tex; }  // DEPTH_COMPONENT24, NEAREST; 0 before resolve
    int width() const { return target_.width; }
    int height() const { return target_.height; }
    // Window depths in [0, 1] (1: the background), rows bottom to top: for
    // the tests. Reads back; slow.
    std::vector<float> read() const;

private:
    targets::Tex2dFbo target_;  // (depth only)
};

}  // namespace hz::core::render
