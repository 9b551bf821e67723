// The vectorised voxmm -> RAS+ mm transform of scalar-free TRK points
// (trk_transform.cpp).
#pragma once

#include <cstdint>

namespace trk::detail {

// out[3i..3i+3) = A (row-major 4x4, first three rows) applied to
// in[3i..3i+3), i < n, in double, rounded to float32: the scalar decoder's
// values bit for bit. in: n xyz float32 triples in host byte order (any
// 4-byte alignment); out must not overlap in. Returns false when any input
// coordinate is NaN or infinite (the caller then finds which).
bool transform_points(const float *in, std::uint64_t n, const double *A, float *out);

}  // namespace trk::detail
