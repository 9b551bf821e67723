// Order-independent transparency by depth peeling (Everitt, "Interactive
// order-independent transparency", NVIDIA 2001), a pass of the frame
// (private to the renderer). Translucent geometry is drawn once per layer:
// each time only its fragments behind the layer before (the shading
// programs built with HZ_PEEL discard the others, reading that layer's
// depth) and in front of the opaque geometry, the nearest of them kept;
// the layers are composited front to back ("under"), then over the opaque
// picture. The result is sorted compositing per pixel whatever the order of
// the objects, and within an object (a closed translucent surface's front
// and back), up to `max_layers` layers; beyond them, what is left is
// blended in drawing order as one last layer (its weight is what the
// layers in front let through). Layers are single-sampled.
// Threading: the GL context's thread.
#pragma once

#include "../gl.hpp"
#include "../gpu_object.hpp"

#include <functional>
#include <memory>
#include <string>

namespace hz::core::render {

class DepthPeeling {
public:
    using MakeProgram = std::function<std::unique_ptr<Program>(const std::string &vs, const std::string &fs, const std::string &what)>;
    explicit DepthPeeling(MakeProgram make);
    ~DepthPeeling();
    DepthPeeling(const DepthPeeling &) = delete;
    DepthPeeling &operator=(const DepthPeeling &) = delete;

    // Composites the translucent geometry over the picture in `target_fbo`
    // (single-sampled, w x h, linear RGBA16F: the opaque picture). Its depth
    // is that of `opaque_fbo` (24-bit; multisampled: one sample each).
    // `draw(previous_depth)` draws every translucent object with its peel
    // program, the texture `previous_depth` (the last layer's window depths)
    // bound to it as hz_peel_depth; the depth test and the blending are this
    // pass's. `between(near, far)`, where given, composites what lies
    // between two layers (direct volume rendering) under what the layers in
    // front accumulated: called before each layer with the depth textures of
    // the layer in front (`near`; all 0 before the first) and of this one
    // (`far`; the opaque depth where it has no fragment), and once after the
    // last (`far` the opaque depth), with the accumulation bound, full
    // screen, blending "under" (premultiplied: GL_ONE_MINUS_DST_ALPHA,
    // GL_ONE) and no depth test; it draws a full-screen triangle of
    // premultiplied colour. Returns the number of layers peeled (the last
    // partial one included). Leaves blending off and depth writes on.
    int composite(GLuint opaque_fbo, GLuint target_fbo, int w, int h, int max_layers, const std::function<void(GLuint)> &draw,
                  GLuint empty_vao, const std::function<void(GLuint near, GLuint far)> &between = {});

private:
    void ensure(int w, int h);
    void release();
    MakeProgram make_;
    std::unique_ptr<Program> under_, over_;
    int w_ = 0, h_ = 0;
    GLuint layer_fbo_ = 0, layer_tex_ = 0, depth_[2] = {0, 0};
    GLuint acc_fbo_ = 0, acc_tex_ = 0;
    GLuint query_ = 0;
};

}  // namespace hz::core::render
