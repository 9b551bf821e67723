// OpenGL contexts for the renderer.
//
// Headless: EGL on Mesa's surfaceless platform, no X server, no window; the
// renderer draws into its own framebuffer objects. Window: GLFW (X11), used by
// `horizon view`. Both give an OpenGL 4.1+ core context; GL calls go through
// GLVND, so the renderer code is the same for both.
#pragma once

#include <memory>
#include <string>

namespace hz::core::render {

class GlContext {
public:
    virtual ~GlContext() = default;
    virtual void make_current() = 0;
    // "OpenGL 4.5 (Core Profile) Mesa 22.3.6, llvmpipe (LLVM 15.0.6, 256 bits)"
    std::string description() const;
};

// Creates a headless context (4.5 core, else 4.3, else 4.1) and makes it
// current on the calling thread. Throws Error with the EGL reason when the
// machine has no usable EGL/GL (e.g. "no EGL display: ...").
std::unique_ptr<GlContext> make_headless_context();

}  // namespace hz::core::render
