// The vectorised classifying pass of the TCK scan over Float32LE data
// (tck_scan.cpp).
#pragma once

#include <cstdint>
#include <vector>

namespace tck::detail {

// Triples [b, e) of `data` (12 bytes each, little-endian float32 in the
// host's byte order, any byte alignment): every triple with a float whose
// exponent is all ones (NaN or Inf) is appended to `out` as
// (index << 4 | nans << 2 | infs), its NaN and Inf component counts, in
// file order; every other float is folded into lo[c] / hi[c] (c = x, y, z,
// started by the caller, at +/-inf for an empty chunk).
void scan_chunk(const unsigned char *data, std::uint64_t b, std::uint64_t e, std::vector<std::uint64_t> &out, float *lo, float *hi);

}  // namespace tck::detail
