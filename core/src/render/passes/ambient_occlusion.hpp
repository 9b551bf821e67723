// Ambient occlusion as a pass of the frame (private to the renderer): after
// the scene is drawn, a screen-space estimate of how much of the ambient
// light each pixel's neighbours in front of it hide, computed from the
// frame's depth alone and multiplied into its picture.
//
// Why depth alone: streamlines drawn as lines have no surface normal, only
// a tangent, so the normal-based hemisphere estimators of surfaces (SSAO,
// HBAO) do not apply; LineAO (Eichelbaum, Hlawitschka and Scheuermann,
// IEEE TVCG 19(5), 2013) samples the depth buffer around each fragment at
// several radii instead. This is its idea in the form of depth unsharp
// masking (Luft, Colditz and Deussen, SIGGRAPH 2006): samples are taken in
// pairs at opposite offsets on a disc `radius_mm` wide at the fragment's
// depth, and a pair occludes by how far the mean of its two depths lies in
// front of the fragment. On any plane the two offsets cancel (a surface
// seen at a grazing angle is not darkened); a streamline behind others, or
// the floor of a sulcus, is. A pair's contribution fades out where its
// samples lie more than two radii in front (a distant occluder casts no
// contact shadow), and the background never occludes.
//
// The same estimate is written in C++ (ao_reference) for the tests: the
// GPU's factors equal it on a depth buffer read back.
//
// Threading: the GL context's thread.
#pragma once

#include "../glsl.hpp"
#include "../gpu_object.hpp"
#include "frame_depth.hpp"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace hz::core::render {

struct AoParams {
    double radius_mm = 3.0;  // the disc sampled around each fragment, at its depth
    double strength = 0.8;   // 0: no darkening; 1: a fully hidden fragment goes black
    int pairs = 16;          // sample pairs per pixel
    // The camera: vertical field of view, near and far planes (the frame's
    // perspective projection), for linear depth and the disc's size in pixels.
    double fov_deg = 30, near_mm = 1, far_mm = 1000;
};

class AmbientOcclusionPass {
public:
    using MakeProgram = std::function<std::unique_ptr<Program>(const std::string &vs, const std::string &fs, const std::string &what)>;
    explicit AmbientOcclusionPass(MakeProgram make);
    ~AmbientOcclusionPass();
    AmbientOcclusionPass(const AmbientOcclusionPass &) = delete;
    AmbientOcclusionPass &operator=(const AmbientOcclusionPass &) = delete;

    // Darkens the picture in `colour_fbo` (sRGB-encoded display values, or
    // linear radiance; the size of `depth`) by the occlusion that the
    // frame's depth gives, for `p`. `empty_vao`: a vertex array for a
    // full-screen triangle. Leaves depth testing and blending off.
    // `encoded`: false where the picture is linear radiance (the HDR path,
    // before its tone curve): then the factor multiplies it as it is.
    void apply(GLuint colour_fbo, const FrameDepth &depth, const AoParams &p, GLuint empty_vao, bool encoded = true);
    // Compiles the pass's program now (apply() would on its first call):
    // so that the pass's first timing is the pass's, not the compiler's.
    void prepare();
    // The factors (1: unoccluded) of `depth` for `p`, rows bottom to top,
    // as the pass multiplies them in (`blur`), or before their blur: for
    // the tests. Reads back; slow.
    std::vector<float> read_factors(const FrameDepth &depth, const AoParams &p, GLuint empty_vao, bool blur);

private:
    void raw_factors(const FrameDepth &depth, const AoParams &p, GLuint empty_vao);
    void blurred(Program &prog, const FrameDepth &depth, const AoParams &p, GLuint empty_vao, bool encoded);
    MakeProgram make_;
    std::unique_ptr<Program> raw_, blur_, blur_factors_;
    targets::Tex2dFbo raw_target_;  // the factors before their blur (R32F, NEAREST)
};

// The estimate on the CPU, from window depths (rows bottom to top, 1 =
// background): each pixel's factor in [0, 1], as the pass computes it
// before its blur.
std::vector<float> ao_reference(const std::vector<float> &depth, int w, int h, const AoParams &p);
// The blur of factors `raw` as the pass does it: over the 4 x 4 pixels
// (offsets -2..1) around each one within radius_mm / 4 of it in depth.
std::vector<float> ao_blur_reference(const std::vector<float> &raw, const std::vector<float> &depth, int w, int h, const AoParams &p);

}  // namespace hz::core::render
