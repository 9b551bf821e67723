// Depth cueing as a pass of the frame (private to the renderer): what lies
// farther from the camera fades towards the background, linearly in depth
// across the scene's own depth range, so that in a whole brain the nearer
// streamlines stand out from the farther ones (the fog of mrview and of
// classic visualization systems). It reads the frame's depth only.
// Threading: the GL context's thread.
#pragma once

#include "../glsl.hpp"
#include "../gpu_object.hpp"
#include "frame_depth.hpp"

#include <array>
#include <functional>
#include <memory>
#include <string>

namespace hz::core::render {

struct DepthCueParams {
    double strength = 0.6;                     // the fraction of the background at the far end (0: none)
    double from_mm = 0, to_mm = 1;             // the scene's depth range from the eye: no fading before, full after
    double near_mm = 1, far_mm = 1e3;          // the camera's planes (linear depth)
    std::array<float, 3> background{0, 0, 0};  // as the picture stores it (display values or linear)
};

// The fraction of the background a pixel at window depth `d` gets (0 for
// the background itself): strength x clamp((z - from) / (to - from), 0, 1),
// z the linear depth. What the pass computes, for the tests.
double depth_cue_weight(double d, const DepthCueParams &p);

class DepthCuePass {
public:
    using MakeProgram = std::function<std::unique_ptr<Program>(const std::string &vs, const std::string &fs, const std::string &what)>;
    explicit DepthCuePass(MakeProgram make);
    ~DepthCuePass();
    DepthCuePass(const DepthCuePass &) = delete;
    DepthCuePass &operator=(const DepthCuePass &) = delete;

    // Mixes the picture in `colour_fbo` (the size of `depth`) towards the
    // background by each pixel's depth_cue_weight. Leaves blending off.
    void apply(GLuint colour_fbo, const FrameDepth &depth, const DepthCueParams &p, GLuint empty_vao);
    // Compiles the pass's program now (as AmbientOcclusionPass::prepare).
    void prepare();

private:
    MakeProgram make_;
    std::unique_ptr<Program> program_;
};

}  // namespace hz::core::render
