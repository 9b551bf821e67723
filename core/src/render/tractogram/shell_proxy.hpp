// The level-of-detail proxy of a large tractogram: which runs of points it draws.
#pragma once
#include <hz/core/data.hpp>

#include <array>
#include <atomic>
#include <cstdint>
#include <vector>

namespace hz::core::render {

// A run of points of one streamline: points [first, first + count) of
// streamline s (indices relative to the streamline's first point).
struct Piece {
    std::uint64_t s = 0;
    std::uint32_t first = 0, count = 0;
};

// A streamline's place in a uniform order (SplitMix64's finaliser of s + 1):
// the hash by which the proxies take uniform subsamples.
std::uint64_t streamline_hash(std::uint64_t s);

// Steps from the nearest seed, 26-connected (the Chebyshev distance), on a
// grid of dim[0] x dim[1] x dim[2] voxels (x fastest): `d` holds 0 at the
// seeds, listed in `seeds`, and 255 elsewhere; on return every voxel within
// 254 steps holds its distance (the rest stay 255). Breadth first from all
// seeds at once.
void chebyshev_steps(const std::array<int, 3> &dim, std::vector<std::uint8_t> &d, std::vector<std::uint32_t> seeds);

// A uniform subsample: every whole streamline whose hash falls below
// budget_points / nb_vertices (in expectation `budget_points` points, the same
// density everywhere), in hash order (a prefix is a uniform subsample too). Reads only the offsets: immediate at any size.
std::vector<Piece> uniform_proxy(const Tractogram &t, double budget_points);

// The shell proxy. Seen from outside, a whole-brain tractogram of a million
// streamlines is its outermost layer: every pixel shows the nearest streamline,
// and a uniform subsample shows streamlines from deep inside instead (other
// directions, other colours; SSIM about 0.7 against the full frame). This
// proxy spends the same budget on the outer layer only:
//   1. a grid of about `grid` voxels along the longest side marks the voxels
//      the streamlines pass through; a morphological closing fills the gaps
//      between streamlines; the empty voxels connected to the grid's border
//      are the outside;
//   2. each voxel's depth is its distance (26-neighbour steps) from the
//      outside;
//   3. streamlines are taken in order of their smallest depth (ties broken by
//      a hash: uniform within a layer), and of each only the runs of at least
//      two points within `shell_voxels` of the outside, until `budget_points`
//      points are taken. The runs come in that order: a prefix is the shell
//      of a smaller budget.
// Reads every point twice, on every core (std::thread over streamline
// ranges) with `all_cores`, else on the calling thread: meant for a
// background thread. `cancel` is polled; when set the result is empty.
// Bounds `b` must hold every point (the reader's bounds).
std::vector<Piece> shell_proxy(const Tractogram &t, const Bounds &b, double budget_points, const std::atomic<bool> &cancel, bool all_cores,
                               int grid = 96, int shell_voxels = 4);

}  // namespace hz::core::render
