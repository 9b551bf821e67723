// The last complete frame, reprojected (private to the renderer): while the
// camera moves, the finished still image the window showed last is drawn
// again from the new camera, as one point per block of scale x scale pixels
// placed at the depth it had, under the level-of-detail proxy, which fills
// what the still did not see. A still of a dense tractogram is what a
// proxy of a few hundred thousand points cannot look like; its reprojection
// keeps the picture while the view turns, and is exact where it has not.
// Threading: the GL context's thread.
#pragma once

#include "gpu_object.hpp"

#include <glm/glm.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace hz::core::render {

class Reprojection {
public:
    using MakeProgram = std::function<std::unique_ptr<Program>(const std::string &vs, const std::string &fs, const std::string &what)>;
    explicit Reprojection(MakeProgram make);
    ~Reprojection();
    Reprojection(const Reprojection &) = delete;
    Reprojection &operator=(const Reprojection &) = delete;

    // Reads the display picture of `colour_fbo` and the depth of
    // `depth_fbo` (single-sampled, both w x h, drawn with the camera whose
    // inverse view-projection is `inv_view_proj`) and keeps one point per
    // scale x scale block that shows something: at the nearest depth in the
    // block, with the block's mean colour (background included, as a
    // downsampled picture has it). `generation` names what the frame showed.
    void capture(GLuint colour_fbo, GLuint depth_fbo, int w, int h, const glm::dmat4 &inv_view_proj, int scale, std::uint64_t generation,
                 const glm::dvec3 &eye, const glm::dvec3 &target);
    // Drops the capture (the scene changed).
    void clear();
    // A capture of this generation for pictures of w x h is there, taken
    // from a camera near this one: its direction within `max_turn_deg` and
    // its distance within 20 %. (Beyond, what the still's blocks show has
    // moved so much that the proxy alone is closer to the full-detail
    // picture: measured at 1M, bench/results/reproject.md, past about 15
    // degrees for the shell proxy and past about 3 for the fibre volume.)
    bool usable(std::uint64_t generation, int w, int h, const glm::dvec3 &eye, const glm::dvec3 &target, double max_turn_deg) const;
    static constexpr double kMaxTurnDeg = 15.0, kMaxTurnOverVolumeDeg = 3.0;
    // Draws the points into the bound framebuffer (display values, depth
    // tested), `point_px` pixels across, each moved `lift_mm` towards `eye`
    // so that it wins over the proxy's lines on the same surface.
    void draw(const glm::mat4 &view_proj, const glm::dvec3 &eye, double point_px, double lift_mm);
    std::uint64_t points() const { return count_; }
    int scale() const { return scale_; }  // the capture's block size (pixels)

private:
    MakeProgram make_;
    std::unique_ptr<Program> program_;
    GLuint vao_ = 0, vbo_ = 0;
    std::uint64_t count_ = 0, generation_ = 0;
    int w_ = 0, h_ = 0, scale_ = 1;
    glm::dvec3 eye_{0.0}, target_{0.0};
    bool valid_ = false;
};

}  // namespace hz::core::render
