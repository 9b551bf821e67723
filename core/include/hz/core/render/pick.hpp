// Picking: which streamline of a drawn tractogram lies under a window point.
// Computed on the CPU from the same camera matrix the renderer draws with
// (no GL read-back), so it answers the same in the window, headless and in
// tests, and costs microseconds for the few thousand centroids the
// exploration of the paper's Fig. 5 shows.
//
// Threading: pure functions; any thread.
#pragma once

#include <hz/core/data.hpp>
#include <hz/core/render/renderer.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace hz::core::render {

// The matrix the renderer draws with for `v` in a width x height viewport:
// perspective(fov_deg, width / height, near_mm, far_mm) * lookAt(eye, target,
// up), column-major (element [c * 4 + r] is row r, column c), as GL takes it.
std::array<double, 16> view_projection(const View &v, int width, int height);

struct PickHit {
    std::uint64_t streamline = 0;
    double pixels = 0;    // screen distance from the point to the streamline's axis
    double depth_mm = 0;  // distance from the eye along the view axis there
};

// The streamline of `t` under window point (x, y) of a width x height view
// (pixels, origin at the top left, y down: GLFW's cursor coordinates scaled
// to the framebuffer). Streamline s is drawn with radius radius_mm[s] (tubes;
// radius_mm empty: lines, radius 0); it is under the point when the point is
// within its projected radius plus `tolerance_px` of its axis. Of those, the
// nearest to the eye where the point falls on the tube itself, otherwise the
// one whose axis passes closest on screen. Segments are clipped to the near
// plane; a single-point streamline is a point. nullopt when none is.
// With `subset`, only those streamlines are candidates. Runs on every core.
std::optional<PickHit> pick_streamline(const Tractogram &t, std::span<const float> radius_mm, const View &v, int width, int height,
                                       double x, double y, double tolerance_px = 6.0, const std::vector<std::uint64_t> *subset = nullptr);

// The streamlines of `t` whose drawn axis crosses `stroke` (a polyline of
// window points, pixels, origin at the top left, as pick_streamline's x,
// y), ascending: some segment of the streamline, projected with the
// renderer's matrix and clipped to the near plane, meets some segment of the
// stroke (touching counts). A single-point streamline crosses where its
// point lies on the stroke. Runs on every core (a million streamlines,
// 164M points: 0.4-0.7 s here, as long as reading them).
std::vector<std::uint64_t> streamlines_crossing(const Tractogram &t, const View &v, int width, int height,
                                                std::span<const std::array<double, 2>> stroke);

// Where the ray o + t d (t > 0) first meets a triangle of `m`: the nearest
// t, or nullopt. Runs on every core (a cortex of 300k triangles in a few ms).
std::optional<double> ray_mesh(const Mesh &m, const std::array<double, 3> &o, const std::array<double, 3> &d);

}  // namespace hz::core::render
