// Anti-aliasing that survives scale, as passes of the frame (private to the
// renderer). Multisampling is off for large tractograms (llvmpipe rasterises
// multisampled lines 5-8 times slower, and a multisampled frame cannot be
// culled by occlusion), so two passes that cost the same at any size stand
// in for it:
// - EdgeAaPass: a post-process over the finished picture (display values),
//   every frame without multisampling, moving or still. Where the luma of a
//   pixel's neighbourhood varies (its contrast above a threshold), the pixel
//   is averaged along the edge or line through it: the direction is across
//   the luma gradient, or across the luma's curvature where a line one pixel
//   wide has no gradient at its centre (the two combined as the structure
//   tensor combines gradients); the taps reach farther along shallow edges
//   (up to 4 pixels), and the wider average is kept only while it stays
//   within the neighbourhood's range of luma (else the narrower one: no
//   colour leaks across a line's end). After the idea of FXAA (Lottes 2009),
//   with its own direction estimate.
// - Accumulation: several frames of the same still, each moved by a
//   different fraction of a pixel (a Halton (2, 3) sequence), averaged:
//   supersampling whose cost is that many frames, with occlusion culling
//   intact. The renderer draws the frames; this class keeps their sum.
// Threading: the GL context's thread.
#pragma once

#include "../glsl.hpp"
#include "../gpu_object.hpp"
#include "../targets.hpp"

#include <array>
#include <functional>
#include <memory>
#include <string>

namespace hz::core::render {

// The offset of jittered frame `i` (0-based) from a pixel's centre, in
// pixels: (H2(i + 1) - 1/2, H3(i + 1) - 1/2), H the radical inverses in
// bases 2 and 3 (the Halton sequence), each component in (-1/2, 1/2).
std::array<double, 2> jitter_offset(int i);

class EdgeAaPass {
public:
    using MakeProgram = std::function<std::unique_ptr<Program>(const std::string &vs, const std::string &fs, const std::string &what)>;
    explicit EdgeAaPass(MakeProgram make);
    ~EdgeAaPass();
    EdgeAaPass(const EdgeAaPass &) = delete;
    EdgeAaPass &operator=(const EdgeAaPass &) = delete;

    // Anti-aliases the picture (RGBA8, display values) in `colour_fbo`, w x h
    // pixels, in place (through a copy the pass keeps); its alpha is kept.
    void apply(GLuint colour_fbo, int w, int h, GLuint empty_vao);

private:
    MakeProgram make_;
    std::unique_ptr<Program> program_;
    targets::Tex2dFbo copy_;  // (the picture read while the pass writes it)
};

class Accumulation {
public:
    using MakeProgram = EdgeAaPass::MakeProgram;
    explicit Accumulation(MakeProgram make);
    ~Accumulation();
    Accumulation(const Accumulation &) = delete;
    Accumulation &operator=(const Accumulation &) = delete;

    // Starts a sum of w x h pixels (zero).
    void begin(int w, int h);
    // Adds `weight` times the picture in texture `tex` (w x h).
    void add(GLuint tex, double weight, GLuint empty_vao);
    // Writes `scale` times the sum into `fbo` (w x h; blending off).
    void resolve(GLuint fbo, GLuint empty_vao, double scale = 1.0);

private:
    // Draws `weight` times texture `from_tex` into `to_fbo` (added to it with `add`).
    void draw(GLuint to_fbo, GLuint from_tex, double weight, bool add, GLuint empty_vao);
    MakeProgram make_;
    std::unique_ptr<Program> program_;
    targets::Tex2dFbo sum_;
};

}  // namespace hz::core::render
