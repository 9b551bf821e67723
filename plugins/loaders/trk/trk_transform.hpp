// The vectorised voxmm -> RAS+ mm transform of scalar-free TRK points
// (trk_transform.cpp).
#pragma once

#include <cstdint>

namespace trk::detail {

// out[3i..3i+3) = A (row-major 4x4, first three rows) applied to
// in[3i..3i+3), i < n, in double, rounded to float32: the scalar decoder's
// values bit for bit. in: n xyz float32 triples in host byte order (any
// 4-byte alignment); out must not overlap in. lo[0..3) and hi[0..3) are
// lowered / raised to the smallest / largest x, y, z written to out (the
// minimum and maximum are exact, so the vector width does not change them).
// Returns false when any input coordinate is NaN or infinite (the caller
// then finds which; lo and hi are then meaningless).
bool transform_points(const float *in, std::uint64_t n, const double *A, float *out, float *lo, float *hi);

}  // namespace trk::detail
