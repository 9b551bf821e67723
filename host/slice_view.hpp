// The window's 2D view of one slice of a volume (mrview's 2D mode, beside
// the 3D view): the world plane of one axis at a position, sampled on a
// grid as fine as the volume's finest voxel over its box, each pixel the
// voxel nearest its centre (the slicer readout's rule: no interpolation,
// the voxels as stored), through the object's window and colormap; label
// volumes in their labels' colours, colour volumes as they are.
// Neurological orientation: the subject's right on the right; axial seen
// from above (anterior up), coronal from the front (superior up), sagittal
// from the subject's left (anterior to the left, superior up).
// Threading: the window's thread.
#pragma once

#include <hz/core/render/renderer.hpp>
#include <hz/core/render/scene.hpp>

#include <array>
#include <cstddef>
#include <optional>
#include <string>

namespace hz::host {

struct SliceImage {
    core::render::Image image;  // RGBA8, rows top to bottom; outside the volume black
    int axis = 2;               // the world axis across the plane: 0 sagittal (x), 1 coronal (y), 2 axial (z)
    double position = 0;        // its RAS+ mm
    double mm_per_pixel = 1;
    // The world axes of the image's columns (left to right) and rows
    // (bottom to top), each +1 or -1 along it, and the world point of the
    // image's top left corner.
    int u_axis = 0, v_axis = 1;
    double u_sign = 1, v_sign = 1;
    std::array<double, 3> corner{};
    // The world point (RAS+ mm) at image point (x, y) (pixels, from the top
    // left corner; a pixel's centre at + 0.5).
    std::array<double, 3> world(double x, double y) const;
    // The image point of world point p (its projection on the plane).
    std::array<double, 2> pixel(const std::array<double, 3> &p) const;
};

// The image of object `object`'s plane across world axis `axis` (0, 1, 2) at
// `position` mm, in the 3D volume the object shows, through `window` (the
// renderer's: a volume whose scene sets none has one found for it). Throws
// Error naming the object when it is not a volume drawn as slices. At most
// 2048 pixels a side (a coarser grid beyond).
SliceImage slice_image(const core::render::Scene &scene, std::size_t object, int axis, double position, const std::array<double, 2> &window,
                       const core::Bounds &box);

// "sagittal", "coronal", "axial" of 0, 1, 2; the axis of x|y|z or those
// names (nullopt: neither).
const char *axis_view_name(int axis);
std::optional<int> axis_of(const std::string &word);

}  // namespace hz::host
