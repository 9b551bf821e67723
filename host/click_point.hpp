// What a click meets in the window: the world point under a window point,
// for placing a region where the user clicks (a streamline, a centroid, a
// surface or a slice, whichever is nearest along the ray). On the CPU, with
// the camera the frame was drawn with. Threading: the window's thread.
#pragma once

#include "session.hpp"

#include <hz/core/render/renderer.hpp>

#include <array>
#include <cstddef>
#include <optional>

namespace hz::host {

struct ClickTarget {
    const core::render::Scene *scene = nullptr;  // what the window draws
    std::size_t object = 0;                      // the streamlines a click can meet: the session's, or the centroids
    bool centroids = false;                      // `object` is an exploration's centroids (few: tested whole)
    const Session *session = nullptr;            // the streamlines shown and their spatial grid (when not centroids)
    bool slices_only = false;                    // only the slices (the slicer's readout): no streamline, no mesh
};

// A volume's voxel and value at a world point: the first visible volume
// drawn as slices whose grid holds `p` (the voxel nearest it: the affine's
// inverse, rounded half away from zero), in the 3D volume it shows.
struct VoxelValue {
    std::size_t object = 0;
    std::array<std::int64_t, 3> ijk{};
    double value = 0;  // scaled (scl_slope, scl_inter)
    // A colour volume's (core::render::shows_rgb) three values there,
    // scaled (its first one is `value`); empty for others.
    std::vector<double> colour;
};
std::optional<VoxelValue> voxel_at(const core::render::Scene &scene, const std::array<double, 3> &p);
// The same of object `k` (a volume; shown or not): nullopt outside its grid
// or for another kind of object.
std::optional<VoxelValue> voxel_of(const core::render::Scene &scene, std::size_t k, const std::array<double, 3> &p);
// voxel_of for many points of one object (a 2D view's pixels): the affine
// inverted once. Holds `scene`'s object by reference: use it while the
// scene's objects are unchanged.
class VoxelLookup {
public:
    VoxelLookup(const core::render::Scene &scene, std::size_t k);
    std::optional<VoxelValue> operator()(const std::array<double, 3> &p) const;

private:
    const core::render::Object *ob_ = nullptr;  // null: not a volume, or a singular affine
    std::size_t k_ = 0;
    double inv_[3][3]{};
    bool rgb_ = false;
};

// The world point (RAS+ mm) under window point (x, y) of a ww x wh window
// whose framebuffer is fw x fh, seen with camera `v`: the nearest of the
// picked streamline (within 6 pixels; its depth along the ray), the visible
// meshes and the visible slices; nullopt over nothing. A session's
// streamlines are tested through its spatial grid when it is built, front
// to back (a million streamlines cost a few thousand tests).
std::optional<std::array<double, 3>> point_under(const ClickTarget &target, int ww, int wh, int fw, int fh, double x, double y,
                                                 const core::render::View &v);

}  // namespace hz::host
