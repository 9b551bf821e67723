// Fast mode's resampling: every streamline to P points equally spaced along
// its arc length, in float32 vectors. Highway compiles this file once per
// SIMD target (foreach_target.h) and resample_fast dispatches to the best
// one the CPU supports.
//
// Exact mode resamples with DIPY's arithmetic instead (qb_algorithm.cpp):
// double sums in point order and a serial walk, bit for bit DIPY's points.
// Here the same points are computed with float32 rounding, a vector at a time:
//   1. the points deinterleaved once into per-axis scratch arrays;
//   2. segment lengths, N segments at once (a segment's end points are two
//      unaligned loads from those arrays), and cumulative lengths by an
//      in-register prefix sum per vector, each vector offset by the double
//      sum of the vectors before it, so the error of a cumulative length
//      stays a few float32 ulps of it even on a 10-million-point streamline;
//   3. for N targets at once, the segment each falls in: the count of
//      cumulative lengths below it (no data-dependent branch; four counts
//      at once, each step a compare and a masked add);
//   4. the segment's end points gathered, interpolated, and stored per axis.
// (Steps 1 and 3 took this form on 2026-11-24: 9-11% less time for the
// features of 100k streamlines, the same points bit for bit.)
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "qb_resample.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>
#include <hwy/cache_control.h>

#include "qb_internal.hpp"
#include "qb_reduce-inl.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

HWY_BEFORE_NAMESPACE();
namespace qb::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

namespace {

// Inclusive prefix sum of v's lanes (log2(N) shifted adds).
template <class D, class V = hn::VFromD<D>>
HWY_INLINE V prefix_sum(D d, V v) {
    const hn::RebindToSigned<D> di;
    const auto iota = hn::Iota(di, 0);
    for (int k = 1; k < static_cast<int>(hn::Lanes(d)); k <<= 1) {
        const auto from = hn::Max(hn::Sub(iota, hn::Set(di, k)), hn::Zero(di));
        const V shifted = hn::TableLookupLanes(v, hn::IndicesFromVec(d, from));
        v = hn::Add(v, hn::IfThenElseZero(hn::RebindMask(d, hn::Gt(iota, hn::Set(di, k - 1))), shifted));
    }
    return v;
}

// Features::geom of a 12-point block from its per-axis minima, maxima and
// sums (axes_min_max_sum_12); returns its largest |coordinate|.
HWY_INLINE float geom_from_12(const float lo[3], const float hi[3], const float sum[3], float *HWY_RESTRICT g) {
    box_mean_12(lo, hi, sum, g, g + 3, g + 6);
    float big = 0.0f;
    for (int a = 0; a < 3; ++a) {
        g[9 + a] = g[6 + a];
        big = std::max({big, std::fabs(lo[a]), std::fabs(hi[a])});
    }
    return big;
}

// A feature block's Features::geom (AABB centre and half-size as
// feature_box computes them, bit for bit; the mean point, summed in
// float32, for both orientations) and its largest |coordinate|, one vector per axis at a time, while
// the block is still in L1.
HWY_INLINE float geom_of(const float *HWY_RESTRICT x, std::uint32_t P, float *HWY_RESTRICT g) {
    const hn::ScalableTag<float> d;
    if (float lo[3], hi[3], sum[3]; P == 12 && axes_min_max_sum_12(d, x, lo, hi, sum))  // (all three axes at once)
        return geom_from_12(lo, hi, sum, g);
    const std::size_t N = hn::Lanes(d);
    const auto inf = hn::Set(d, HUGE_VALF), ninf = hn::Neg(inf);
    auto big = hn::Zero(d);
    for (int a = 0; a < 3; ++a) {
        const float *p = x + a * P;
        auto mn = inf, mx = ninf, sum = hn::Zero(d);
        for (std::size_t i = 0; i < P; i += N) {
            const auto m = hn::FirstN(d, P - i);
            const auto v = hn::MaskedLoad(m, d, p + i);  // (zeros in the lanes past P)
            mn = hn::Min(mn, hn::IfThenElse(m, v, inf));
            mx = hn::Max(mx, hn::IfThenElse(m, v, ninf));
            sum = hn::Add(sum, v);
            big = hn::Max(big, hn::Abs(v));
        }
        const float lo = hn::GetLane(hn::MinOfLanes(d, mn)), hi = hn::GetLane(hn::MaxOfLanes(d, mx));
        g[3 + a] = (hi - lo) / 2.0f;
        g[a] = lo + g[3 + a];
        g[6 + a] = g[9 + a] = hn::GetLane(hn::SumOfLanes(d, sum)) / static_cast<float>(P);
    }
    return hn::GetLane(hn::MaxOfLanes(d, big));
}

// A 12-point block from its three axis vectors (lanes 0..11 resampled; lane
// 11 becomes the last point, as it does below): stored into out[0..36), its
// geom into g from the same registers (store_12_min_max_sum). 16-lane
// targets only (returns false elsewhere, having done nothing).
template <class D, class V>
HWY_INLINE bool store_12_with_geom(D d, V (&res)[3], const float *last, float *HWY_RESTRICT out, float *HWY_RESTRICT g, float &big) {
    if constexpr (hn::MaxLanes(D()) != 16) {
        (void)d, (void)res, (void)last, (void)out, (void)g, (void)big;
        return false;
    } else {
        const hn::RebindToSigned<D> di;
        const auto lane = hn::Iota(di, 0);
        const auto at11 = hn::RebindMask(d, hn::Eq(lane, hn::Set(di, 11)));
        V r[3];
        for (int a = 0; a < 3; ++a) r[a] = hn::IfThenElse(at11, hn::Set(d, last[a]), res[a]);
        // v0 = x0..11 y0..3; v1 = y4..11 z0..7; t = z8..11.
        alignas(64) static constexpr std::int32_t iy0[16] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3};
        alignas(64) static constexpr std::int32_t iy1[16] = {4, 5, 6, 7, 8, 9, 10, 11, 0, 0, 0, 0, 0, 0, 0, 0};
        alignas(64) static constexpr std::int32_t iz1[16] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7};
        alignas(64) static constexpr std::int32_t iz2[16] = {8, 9, 10, 11, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
        const auto first12 = hn::RebindMask(d, hn::Lt(lane, hn::Set(di, 12)));
        const auto first8 = hn::RebindMask(d, hn::Lt(lane, hn::Set(di, 8)));
        const V v0 = hn::IfThenElse(first12, r[0], hn::TableLookupLanes(r[1], hn::SetTableIndices(d, iy0)));
        const V v1 = hn::IfThenElse(first8, hn::TableLookupLanes(r[1], hn::SetTableIndices(d, iy1)),
                                    hn::TableLookupLanes(r[2], hn::SetTableIndices(d, iz1)));
        const V t = hn::TableLookupLanes(r[2], hn::SetTableIndices(d, iz2));
        float lo[3], hi[3], sum[3];
        store_12_min_max_sum(d, v0, v1, t, out, lo, hi, sum);
        big = std::max(big, geom_from_12(lo, hi, sum, g));
        return true;
    }
}

// One streamline p[0..n) (n >= 1, n < 2^29) into out (x[0..P), y[0..P),
// z[0..P)), and its Features::geom into g. Returns its length, summed in
// double (non-finite when a coordinate is); big: raised to the largest
// |coordinate| of out. work: scratch of at least 4 (n + 2 N) floats.
// [p, readable): memory that may be read (the input's positions up to its
// end: the streamlines after this one).
double resample_one(const float *HWY_RESTRICT p, std::uint64_t n, std::uint32_t P, float *HWY_RESTRICT out, float *HWY_RESTRICT g,
                    float &big, float *HWY_RESTRICT work, const float *readable) {
    const hn::ScalableTag<float> d;
    const hn::RebindToSigned<decltype(d)> di;
    using V = hn::Vec<decltype(d)>;
    const std::size_t N = hn::Lanes(d);
    const std::size_t stride = n + 2 * N;
    float *HWY_RESTRICT xs = work, *HWY_RESTRICT ys = xs + stride, *HWY_RESTRICT zs = ys + stride, *HWY_RESTRICT arc = zs + stride;
    const float *last = p + 3 * (n - 1);
    // 1. The points per axis (one deinterleaving per N points), padded
    // with copies of the last point (zero-length segments). The last,
    // partial group is loaded whole where the vertices after it are
    // readable (every streamline but the input's last few), its lanes past
    // the streamline then replaced in registers: no copy into a buffer,
    // whose scalar stores a vector load cannot take forwarded (2-3 % less
    // time for the features of 100k streamlines; the same points).
    {
        const V lx = hn::Set(d, last[0]), ly = hn::Set(d, last[1]), lz = hn::Set(d, last[2]);
        for (std::uint64_t i = 0; i < n; i += N) {
            const float *src = p + 3 * i;
            V x, y, z;
            if (i + N <= n) {
                hn::LoadInterleaved3(d, src, x, y, z);
            } else {
                const std::uint64_t have = n - i;
                if (static_cast<std::uint64_t>(readable - src) >= 3 * N) {
                    hn::LoadInterleaved3(d, src, x, y, z);
                } else {
                    float tail[3 * (HWY_MAX_BYTES / sizeof(float))] = {};  // (lanes past `have` replaced below)
                    std::copy_n(src, 3 * have, tail);
                    hn::LoadInterleaved3(d, tail, x, y, z);
                }
                const auto keep = hn::FirstN(d, have);
                x = hn::IfThenElse(keep, x, lx);
                y = hn::IfThenElse(keep, y, ly);
                z = hn::IfThenElse(keep, z, lz);
            }
            hn::StoreU(x, d, xs + i);
            hn::StoreU(y, d, ys + i);
            hn::StoreU(z, d, zs + i);
        }
        const std::uint64_t filled = (n + N - 1) / N * N;
        hn::StoreU(lx, d, xs + filled);
        hn::StoreU(ly, d, ys + filled);
        hn::StoreU(lz, d, zs + filled);
    }
    // 2. arc[k] = length of the polyline up to point k: N segments at a
    // time, an in-register prefix sum offset by the double sum before it.
    arc[0] = 0.0f;
    double carry = 0.0;
    for (std::uint64_t i = 0; i + 1 < n; i += N) {
        const V dx = hn::Sub(hn::LoadU(d, xs + i + 1), hn::LoadU(d, xs + i));
        const V dy = hn::Sub(hn::LoadU(d, ys + i + 1), hn::LoadU(d, ys + i));
        const V dz = hn::Sub(hn::LoadU(d, zs + i + 1), hn::LoadU(d, zs + i));
        const V seg = hn::Sqrt(hn::MulAdd(dx, dx, hn::MulAdd(dy, dy, hn::Mul(dz, dz))));
        const V pre = prefix_sum(d, seg);
        hn::StoreU(hn::Add(hn::Set(d, static_cast<float>(carry)), pre), d, arc + i + 1);
        carry += static_cast<double>(hn::GetLane(hn::SumOfLanes(d, seg)));
    }
    const double length = carry;
    if (!(length > 0.0) || !(length < HUGE_VAL)) {  // one point, zero length, or non-finite: copies of the last point
        for (std::uint32_t j = 0; j < P; ++j)
            for (int a = 0; a < 3; ++a) out[a * P + j] = last[a];
        big = std::max(big, geom_of(out, P, g));
        return length;
    }
    // 3-4. Target j at j * step; the segment [k-1, k] it falls in has
    // k = 1 + #{m in [1, n): arc[m] < t}, clamped to n - 1.
    const float step = static_cast<float>(length / static_cast<double>(P - 1));
    const auto top = hn::Set(di, static_cast<std::int32_t>(n - 1));
    const auto one = hn::Set(di, 1);
    for (std::uint32_t j0 = 0; j0 < P; j0 += static_cast<std::uint32_t>(N)) {
        const V t = hn::Mul(hn::ConvertTo(d, hn::Add(hn::Iota(di, 0), hn::Set(di, static_cast<std::int32_t>(j0)))), hn::Set(d, step));
        // (Four independent counts: each step is a compare and a masked add.)
        auto c0 = one, c1 = hn::Zero(di), c2 = hn::Zero(di), c3 = hn::Zero(di);
        std::uint64_t m = 1;
        for (; m + 4 <= n; m += 4) {
            c0 = hn::IfThenElse(hn::RebindMask(di, hn::Lt(hn::Set(d, arc[m]), t)), hn::Add(c0, one), c0);
            c1 = hn::IfThenElse(hn::RebindMask(di, hn::Lt(hn::Set(d, arc[m + 1]), t)), hn::Add(c1, one), c1);
            c2 = hn::IfThenElse(hn::RebindMask(di, hn::Lt(hn::Set(d, arc[m + 2]), t)), hn::Add(c2, one), c2);
            c3 = hn::IfThenElse(hn::RebindMask(di, hn::Lt(hn::Set(d, arc[m + 3]), t)), hn::Add(c3, one), c3);
        }
        for (; m < n; ++m) c0 = hn::IfThenElse(hn::RebindMask(di, hn::Lt(hn::Set(d, arc[m]), t)), hn::Add(c0, one), c0);
        const auto k = hn::Min(hn::Add(hn::Add(c0, c1), hn::Add(c2, c3)), top);
        const auto k1 = hn::Sub(k, one);
        // arr[idx] per lane. For a streamline of at most 4 N points, from the
        // vectors that hold the whole array: one permutation per vector and
        // a select per bit of the vector's number (a few cycles each) rather
        // than a gather (several times that): the same values, and 8-17 %
        // less time for the features of 100k synthetic streamlines / of the
        // DIPY bundles (one thread). (Indices are below n; the arrays are
        // padded to n + 2 N floats, so the vectors past n read padding.)
        const auto low = hn::Set(di, static_cast<std::int32_t>(N - 1));
        auto fetch = [&](const float *arr, hn::Vec<decltype(di)> idx) -> V {
            if (n > 4 * N) return hn::GatherIndex(d, arr, idx);
            const auto i = hn::IndicesFromVec(d, hn::And(idx, low));
            auto lookup = [&](std::size_t v) { return hn::TableLookupLanes(hn::LoadU(d, arr + v * N), i); };
            if (n <= N) return lookup(0);
            const auto b1 = hn::RebindMask(d, hn::TestBit(idx, hn::Set(di, static_cast<std::int32_t>(N))));
            const V lo = hn::IfThenElse(b1, lookup(1), lookup(0));
            if (n <= 2 * N) return lo;
            const auto b2 = hn::RebindMask(d, hn::TestBit(idx, hn::Set(di, static_cast<std::int32_t>(2 * N))));
            return hn::IfThenElse(b2, hn::IfThenElse(b1, lookup(3), lookup(2)), lo);
        };
        const V a = fetch(arc, k1), b = fetch(arc, k);
        const V span = hn::Sub(b, a);
        const auto ok = hn::Gt(span, hn::Zero(d));
        V r = hn::Div(hn::Sub(t, a), hn::IfThenElse(ok, span, hn::Set(d, 1.0f)));
        r = hn::IfThenElseZero(ok, hn::Min(hn::Max(r, hn::Zero(d)), hn::Set(d, 1.0f)));
        const auto keep = hn::FirstN(d, P - j0);
        const float *axes[3] = {xs, ys, zs};
        V res[3];
        for (int ax = 0; ax < 3; ++ax) {
            const V pa = fetch(axes[ax], k1), pb = fetch(axes[ax], k);
            res[ax] = hn::MulAdd(r, hn::Sub(pb, pa), pa);
        }
        if (P == 12 && store_12_with_geom(d, res, last, out, g, big)) return length;
        for (int ax = 0; ax < 3; ++ax) hn::BlendedStore(res[ax], keep, d, out + ax * P + j0);
    }
    for (int a = 0; a < 3; ++a) out[a * P + (P - 1)] = last[a];
    big = std::max(big, geom_of(out, P, g));
    return length;
}

}  // namespace

void ResampleFast(const Input &in, const std::uint64_t *idx, std::uint64_t begin, std::uint64_t end, std::uint32_t P, float *direct,
                  float *geom, std::vector<float> &scratch, double *lengths, float &max_abs) {
    const std::size_t N = hn::Lanes(hn::ScalableTag<float>());
    float big = max_abs;
    const float *readable = in.positions + 3 * in.offsets[in.nb_streamlines];  // (the input's vertices)
    for (std::uint64_t t = begin; t < end; ++t) {
        const std::uint64_t s = idx ? idx[t] : t, n = in.size(s);
        // The next streamline's cache lines requested now: this one's first
        // read is its last point, which the sequential prefetcher has not
        // reached (2 % less time for the features of 100k streamlines).
        if (t + 1 < end) {
            const std::uint64_t s1 = idx ? idx[t + 1] : t + 1;
            const char *a = reinterpret_cast<const char *>(in.positions + 3 * in.offsets[s1]);
            const char *b = reinterpret_cast<const char *>(in.positions + 3 * in.offsets[s1 + 1]);
            const std::size_t bytes = static_cast<std::size_t>(b - a);
            for (std::size_t o = 0; o < std::min<std::size_t>(bytes, 1024); o += 64) hwy::Prefetch(a + o);  // (its start, and)
            if (bytes >= 12) hwy::Prefetch(b - 12);                                                         // (its last point)
        }
        if (scratch.size() < 4 * (n + 2 * N)) scratch.resize(4 * (n + 2 * N));
        lengths[t - begin] = resample_one(in.positions + 3 * in.offsets[s], n, P, direct + (t - begin) * P * 3,
                                          geom + (t - begin) * Features::kGeom, big, scratch.data(), readable);
    }
    max_abs = big;
}

}  // namespace HWY_NAMESPACE
}  // namespace qb::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace qb::detail {

HWY_EXPORT(ResampleFast);

void resample_fast(const Input &in, const std::uint64_t *idx, std::uint64_t begin, std::uint64_t end, std::uint32_t P, float *direct,
                   float *geom, std::vector<float> &scratch, double *lengths, float &max_abs) {
    HWY_DYNAMIC_DISPATCH(ResampleFast)(in, idx, begin, end, P, direct, geom, scratch, lengths, max_abs);
}

}  // namespace qb::detail
#endif  // HWY_ONCE
