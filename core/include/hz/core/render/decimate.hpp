// Polyline decimation at a screen tolerance: the points of a streamline the
// renderer draws (level of detail, "decimation at screen tolerance").
//
// Threading: pure functions; any thread.
#pragma once

#include <cstdint>
#include <vector>

namespace hz::core::render {

// The longest run of input points one kept segment may replace.
inline constexpr std::uint32_t kDecimateWindow = 64;

// Writes to `keep` the indices, ascending, of the points of the polyline
// p[0 .. 3n) (x y z float triples) to draw within `tol` mm: always the first
// and the last; every dropped point lies within `tol` of the segment between
// the kept points around it, and no kept segment spans more than
// kDecimateWindow input steps. Greedy: a segment grows from its first point
// while it still covers every point it passes. tol <= 0 (or NaN) keeps every
// point. `keep` is cleared first; its capacity is reused.
void decimate(const float *p, std::uint64_t n, double tol, std::vector<std::uint32_t> &keep);

}  // namespace hz::core::render
