// Occlusion culling of what a frame is about to draw, against what it has
// drawn: the farthest depth in each tile of pixels.
#pragma once
#include <glm/mat4x4.hpp>

#include <array>
#include <vector>

namespace hz::core::render {

// A frame's depth buffer reduced to tiles of kTile x kTile pixels, each
// holding the farthest depth drawn in it. Geometry inside a box whose
// nearest point is behind that depth in every tile the box covers draws
// only fragments that fail the depth test (GL_LESS): skipping it changes no
// pixel. Depth only ever comes nearer as a frame is drawn, so a box hidden
// now stays hidden.
class DepthTiles {
public:
    static constexpr int kTile = 8;
    // From window depths in [0, 1] (w x h, rows bottom up: glReadPixels'
    // GL_DEPTH_COMPONENT as floats).
    void build(const float *depth, int w, int h);
    bool empty() const { return far_.empty(); }
    // Whether a box of world points (min x, y, z, max x, y, z) grown by
    // margin_mm, seen through view_proj (world to clip space; the viewport
    // of build()'s size, depth range [0, 1]), is hidden: wholly off the
    // picture, or behind the farthest depth of every tile its projection
    // covers, grown by margin_px (a line's half width and rounding). Never
    // hidden when the box reaches the eye's plane or in front of the near
    // plane. Thread-compatible: const after build().
    bool hidden(const std::array<float, 6> &box, float margin_mm, const glm::mat4 &view_proj, float margin_px) const;

private:
    int w_ = 0, h_ = 0, tx_ = 0, ty_ = 0;
    std::vector<float> far_;  // per tile, rows bottom up
};

}  // namespace hz::core::render
