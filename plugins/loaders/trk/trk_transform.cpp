// The voxmm -> RAS+ mm transform of TRK points stored without scalars (12
// bytes per point, the file's byte order the host's), a vector of points at
// a time. Highway compiles this file once per SIMD target (foreach_target.h)
// and transform_points dispatches to the best one the CPU supports.
// The arithmetic is the scalar decoder's, operation for operation: float32
// coordinates widened to double, ((a0 x + a1 y) + a2 z) + a3 without fused
// multiply-adds (-ffp-contract=off), rounded to float32 once; so the output
// is bit for bit what the scalar loop writes.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "trk_transform.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "trk_transform.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

HWY_BEFORE_NAMESPACE();
namespace trk::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

namespace {

// One point, as the vector loop computes it.
inline bool one(const float *p, const double *A, float *out, float *lo, float *hi) {
    bool ok = true;
    for (int c = 0; c < 3; ++c) ok &= std::fabs(p[c]) <= 3.4028235e38f;
    for (int r = 0; r < 3; ++r) {
        out[r] = static_cast<float>(A[4 * r] * double(p[0]) + A[4 * r + 1] * double(p[1]) + A[4 * r + 2] * double(p[2]) + A[4 * r + 3]);
        lo[r] = std::min(lo[r], out[r]);
        hi[r] = std::max(hi[r], out[r]);
    }
    return ok;
}

}  // namespace

bool TransformPoints(const float *HWY_RESTRICT in, std::uint64_t n, const double *HWY_RESTRICT A, float *HWY_RESTRICT out,
                     float *HWY_RESTRICT lo, float *HWY_RESTRICT hi) {
    const hn::ScalableTag<double> dd;
    const hn::Rebind<float, decltype(dd)> df;  // as many float32 lanes as double lanes
    const std::size_t N = hn::Lanes(dd);
    using VD = hn::Vec<decltype(dd)>;
    VD a[12];
    for (int k = 0; k < 12; ++k) a[k] = hn::Set(dd, A[k]);
    const auto big = hn::Set(df, 3.4028235e38f);
    auto finite = hn::FirstN(df, N);  // all true
    using VF = hn::Vec<decltype(df)>;
    VF mn[3], mx[3];  // the bounds of what is written, per axis
    for (int r = 0; r < 3; ++r) {
        mn[r] = hn::Set(df, lo[r]);
        mx[r] = hn::Set(df, hi[r]);
    }
    std::uint64_t i = 0;
    for (; i + N <= n; i += N) {
        VF x, y, z;
        hn::LoadInterleaved3(df, in + 3 * i, x, y, z);
        finite = hn::And(finite, hn::And(hn::Le(hn::Abs(x), big), hn::And(hn::Le(hn::Abs(y), big), hn::Le(hn::Abs(z), big))));
        const VD X = hn::PromoteTo(dd, x), Y = hn::PromoteTo(dd, y), Z = hn::PromoteTo(dd, z);
        VF o[3];
        for (int r = 0; r < 3; ++r) {
            o[r] = hn::DemoteTo(
                df, hn::Add(hn::Add(hn::Add(hn::Mul(a[4 * r], X), hn::Mul(a[4 * r + 1], Y)), hn::Mul(a[4 * r + 2], Z)), a[4 * r + 3]));
            mn[r] = hn::Min(mn[r], o[r]);
            mx[r] = hn::Max(mx[r], o[r]);
        }
        hn::StoreInterleaved3(o[0], o[1], o[2], df, out + 3 * i);
    }
    for (int r = 0; r < 3; ++r) {
        lo[r] = hn::GetLane(hn::MinOfLanes(df, mn[r]));
        hi[r] = hn::GetLane(hn::MaxOfLanes(df, mx[r]));
    }
    bool ok = hn::AllTrue(df, finite);
    for (; i < n; ++i) ok &= one(in + 3 * i, A, out + 3 * i, lo, hi);
    return ok;
}

}  // namespace HWY_NAMESPACE
}  // namespace trk::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace trk::detail {

HWY_EXPORT(TransformPoints);

bool transform_points(const float *in, std::uint64_t n, const double *A, float *out, float *lo, float *hi) {
    return HWY_DYNAMIC_DISPATCH(TransformPoints)(in, n, A, out, lo, hi);
}

}  // namespace trk::detail
#endif  // HWY_ONCE
