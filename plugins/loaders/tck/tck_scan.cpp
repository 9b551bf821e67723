// The classifying pass of the TCK scan, a vector of points at a time.
// Highway compiles this file once per SIMD target (foreach_target.h) and
// scan_chunk dispatches to the best one the CPU supports.
//
// A group of N triples is 3 vectors of N floats (lane k of vector j holds
// coordinate (jN + k) % 3, the same in every group). Floats with an
// all-ones exponent (NaN, Inf) are flagged by an integer compare and left
// out of the running minima/maxima; a group with any flagged float (about
// one in six with 100-point streamlines: the NaN delimiters) also has its
// flagged triples recorded, one set bit at a time.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "tck_scan.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "tck_scan.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

#ifndef TCK_SCAN_ONCE
#define TCK_SCAN_ONCE
namespace tck::detail {
namespace {

constexpr std::uint32_t kExp = 0x7F800000u, kMant = 0x007FFFFFu;

// Triple i (its 3 floats' bits) as scan_chunk records it.
inline std::uint64_t packed(std::uint64_t i, const std::uint32_t *t) {
    std::uint64_t nans = 0, infs = 0;
    for (int d = 0; d < 3; ++d) {
        const bool special = (t[d] & kExp) == kExp;
        nans += special && (t[d] & kMant) != 0;
        infs += special && (t[d] & kMant) == 0;
    }
    return i << 4 | nans << 2 | infs;
}

// Triples [i, e) one at a time, as scan_chunk treats them.
inline void one_by_one(const unsigned char *data, std::uint64_t i, std::uint64_t e, std::vector<std::uint64_t> &out, float *lo, float *hi) {
    for (; i < e; ++i) {
        std::uint32_t t[3];
        std::memcpy(t, data + 12 * i, sizeof t);
        if (((t[0] & kExp) == kExp) | ((t[1] & kExp) == kExp) | ((t[2] & kExp) == kExp)) {
            out.push_back(packed(i, t));
            continue;
        }
        float v[3];
        std::memcpy(v, t, sizeof v);
        for (int d = 0; d < 3; ++d) {
            lo[d] = std::min(lo[d], v[d]);
            hi[d] = std::max(hi[d], v[d]);
        }
    }
}

// The triples of the group at triple i whose floats are set in `flagged`
// (bit k: float k of the group).
__attribute__((noinline)) void record(const unsigned char *data, std::uint64_t i, std::uint64_t flagged, std::vector<std::uint64_t> &out) {
    while (flagged != 0) {
        const int t = std::countr_zero(flagged) / 3;
        flagged &= ~(std::uint64_t{7} << (3 * t));
        std::uint32_t bits[3];
        std::memcpy(bits, data + 12 * (i + t), sizeof bits);
        out.push_back(packed(i + t, bits));
    }
}

}  // namespace
}  // namespace tck::detail
#endif  // TCK_SCAN_ONCE

HWY_BEFORE_NAMESPACE();
namespace tck::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void ScanChunk(const unsigned char *HWY_RESTRICT data, std::uint64_t b, std::uint64_t e, std::vector<std::uint64_t> *out, float *lo3,
               float *hi3) {
    const hn::ScalableTag<std::uint32_t> du;
    const hn::Rebind<float, decltype(du)> df;
    const std::size_t N = hn::Lanes(du);
    std::uint64_t i = b;
    if (3 * N <= 64) {  // (the flagged floats of a group fit a 64-bit mask)
        const auto exp = hn::Set(du, kExp);
        hn::Vec<decltype(df)> lo[3], hi[3];
        for (int j = 0; j < 3; ++j) {
            lo[j] = hn::Set(df, HUGE_VALF);
            hi[j] = hn::Set(df, -HUGE_VALF);
        }
        for (; i + N <= e; i += N) {
            const auto *p = reinterpret_cast<const std::uint32_t *>(data + 12 * i);
            hn::Mask<decltype(du)> flagged[3];
            for (int j = 0; j < 3; ++j) {
                const auto u = hn::LoadU(du, p + j * N);
                flagged[j] = hn::Eq(hn::And(u, exp), exp);
                const auto v = hn::BitCast(df, u);
                const auto keep = hn::RebindMask(df, flagged[j]);
                lo[j] = hn::IfThenElse(keep, lo[j], hn::Min(lo[j], v));
                hi[j] = hn::IfThenElse(keep, hi[j], hn::Max(hi[j], v));
            }
            if (HWY_UNLIKELY(!hn::AllFalse(du, hn::Or(flagged[0], hn::Or(flagged[1], flagged[2]))))) {
                std::uint64_t bits = 0;
                for (int j = 0; j < 3; ++j) {
                    std::uint8_t m[8] = {};
                    hn::StoreMaskBits(du, flagged[j], m);
                    std::uint64_t w;
                    std::memcpy(&w, m, sizeof w);
                    bits |= (w & ((std::uint64_t{1} << N) - 1)) << (j * N);  // (N <= 21 here)
                }
                record(data, i, bits, *out);
            }
        }
        HWY_ALIGN float l[3 * hn::MaxLanes(df)], h[3 * hn::MaxLanes(df)];
        for (int j = 0; j < 3; ++j) {
            hn::Store(lo[j], df, l + j * N);
            hn::Store(hi[j], df, h + j * N);
        }
        for (std::size_t k = 0; k < 3 * N; ++k) {
            lo3[k % 3] = std::min(lo3[k % 3], l[k]);
            hi3[k % 3] = std::max(hi3[k % 3], h[k]);
        }
    }
    one_by_one(data, i, e, *out, lo3, hi3);
}

}  // namespace HWY_NAMESPACE
}  // namespace tck::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace tck::detail {

HWY_EXPORT(ScanChunk);

void scan_chunk(const unsigned char *data, std::uint64_t b, std::uint64_t e, std::vector<std::uint64_t> &out, float *lo, float *hi) {
    HWY_DYNAMIC_DISPATCH(ScanChunk)(data, b, e, &out, lo, hi);
}

}  // namespace tck::detail
#endif  // HWY_ONCE
