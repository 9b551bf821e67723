// Per-axis minimum, maximum and sum of a 12-point feature block (x0..x11,
// y0..y11, z0..z11: 36 contiguous floats) for the 16-lane targets
// (AVX-512), shared by the searches (a centroid's box and mean after each
// update) and the fast resampling (a streamline's box and mean).
//
// A Highway "-inl" header: compiled once per SIMD target by the
// translation units that include it after <hwy/highway.h> (foreach_target).
//
// The 36 floats are nine 128-bit blocks of 4 (x0..x3, x4..x7, ...). They
// are rearranged into three vectors whose blocks 0, 1, 2 hold a block of x,
// of y and of z; two vector operations combine each axis's three blocks and
// two in-block shuffles finish all three axes at once, instead of three
// full-width reductions per axis. Minima and maxima are exact; the sum is
// taken in another order than a lane-by-lane reduction would take it.

#if defined(HZ_QB_REDUCE_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef HZ_QB_REDUCE_INL_H_
#undef HZ_QB_REDUCE_INL_H_
#else
#define HZ_QB_REDUCE_INL_H_
#endif

#include <hwy/highway.h>

#include <cstdint>

HWY_BEFORE_NAMESPACE();
namespace qb::detail {
namespace HWY_NAMESPACE {

// The block's floats held in registers: v0 = floats 0..15, v1 = 16..31,
// t = 32..35 in lanes 0..3 (its other lanes are ignored); 16-lane targets
// only. For a block just computed (a centroid update), whose box is then not
// read back from stores still in flight.
template <class D, class V = hwy::HWY_NAMESPACE::Vec<D>>
HWY_INLINE void axes_min_max_sum_12_regs(D d, V v0, V v1, V t, float lo[3], float hi[3], float sum[3]) {
    namespace hn = hwy::HWY_NAMESPACE;
    static_assert(hn::MaxLanes(D()) == 16);
    const hn::RebindToSigned<D> di;
    // v0 = x0..3 x4..7 x8..11 y0..3; v1 = y4..7 y8..11 z0..3 z4..7; t = z8..11.
    alignas(64) static constexpr std::int32_t ia0[16] = {0, 1, 2, 3, 12, 13, 14, 15, 0, 0, 0, 0, 0, 0, 0, 0};
    alignas(64) static constexpr std::int32_t ia1[16] = {0, 0, 0, 0, 0, 0, 0, 0, 8, 9, 10, 11, 8, 9, 10, 11};
    alignas(64) static constexpr std::int32_t ib0[16] = {4, 5, 6, 7, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    alignas(64) static constexpr std::int32_t ib1[16] = {0, 0, 0, 0, 0, 1, 2, 3, 12, 13, 14, 15, 12, 13, 14, 15};
    alignas(64) static constexpr std::int32_t ie0[16] = {8, 9, 10, 11, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    alignas(64) static constexpr std::int32_t ie1[16] = {0, 0, 0, 0, 4, 5, 6, 7, 0, 0, 0, 0, 0, 0, 0, 0};
    alignas(64) static constexpr std::int32_t ie2[16] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3, 0, 1, 2, 3};
    const auto lane = hn::Iota(di, 0);
    const auto first8 = hn::RebindMask(d, hn::Lt(lane, hn::Set(di, 8))), first4 = hn::RebindMask(d, hn::Lt(lane, hn::Set(di, 4)));
    const V a = hn::IfThenElse(first8, hn::TableLookupLanes(v0, hn::SetTableIndices(d, ia0)),
                               hn::TableLookupLanes(v1, hn::SetTableIndices(d, ia1)));
    const V b = hn::IfThenElse(first4, hn::TableLookupLanes(v0, hn::SetTableIndices(d, ib0)),
                               hn::TableLookupLanes(v1, hn::SetTableIndices(d, ib1)));
    const V e = hn::IfThenElse(first4, hn::TableLookupLanes(v0, hn::SetTableIndices(d, ie0)),
                               hn::IfThenElse(first8, hn::TableLookupLanes(v1, hn::SetTableIndices(d, ie1)),
                                              hn::TableLookupLanes(t, hn::SetTableIndices(d, ie2))));
    V mn = hn::Min(hn::Min(a, b), e), mx = hn::Max(hn::Max(a, b), e), sm = hn::Add(hn::Add(a, b), e);
    // (Unqualified: found by argument-dependent lookup when instantiated,
    // which only the 16-lane targets do.)
    mn = hn::Min(mn, Shuffle2301(mn));
    mn = hn::Min(mn, Shuffle1032(mn));
    mx = hn::Max(mx, Shuffle2301(mx));
    mx = hn::Max(mx, Shuffle1032(mx));
    sm = hn::Add(sm, Shuffle2301(sm));
    sm = hn::Add(sm, Shuffle1032(sm));
    alignas(64) float l[16], h[16], s[16];
    hn::Store(mn, d, l);
    hn::Store(mx, d, h);
    hn::Store(sm, d, s);
    for (int k = 0; k < 3; ++k) lo[k] = l[4 * k], hi[k] = h[4 * k], sum[k] = s[4 * k];
}

// Stores the block (v0, v1, t as above) into x[0..36) (two full stores and
// one of 4 lanes) and takes its minima, maxima and sums from the same
// registers, not from x: a load spanning two of those stores would wait for
// both to complete. 16-lane targets only.
template <class D, class V = hwy::HWY_NAMESPACE::Vec<D>>
HWY_INLINE void store_12_min_max_sum(D d, V v0, V v1, V t, float *HWY_RESTRICT x, float lo[3], float hi[3], float sum[3]) {
    namespace hn = hwy::HWY_NAMESPACE;
    hn::StoreU(v0, d, x);
    hn::StoreU(v1, d, x + 16);
    hn::BlendedStore(t, hn::FirstN(d, 4), d, x + 32);
    axes_min_max_sum_12_regs(d, v0, v1, t, lo, hi, sum);
}

// A 12-point block's box (centre c, half-size r, as feature_box computes
// them) and mean point from its per-axis minima, maxima and sums.
inline void box_mean_12(const float lo[3], const float hi[3], const float sum[3], float c[3], float r[3], float mean[3]) {
    for (int a = 0; a < 3; ++a) {
        r[a] = (hi[a] - lo[a]) / 2.0f;
        c[a] = lo[a] + r[a];
        mean[a] = sum[a] / 12.0f;
    }
}

// The block read from x[0..36); returns false (and writes nothing) on
// targets without 16 float lanes.
template <class D>
HWY_INLINE bool axes_min_max_sum_12(D d, const float *HWY_RESTRICT x, float lo[3], float hi[3], float sum[3]) {
    namespace hn = hwy::HWY_NAMESPACE;
    if constexpr (hn::MaxLanes(D()) != 16) {
        (void)d, (void)x, (void)lo, (void)hi, (void)sum;
        return false;
    } else {
        axes_min_max_sum_12_regs(d, hn::LoadU(d, x), hn::LoadU(d, x + 16), hn::MaskedLoad(hn::FirstN(d, 4), d, x + 32), lo, hi, sum);
        return true;
    }
}

}  // namespace HWY_NAMESPACE
}  // namespace qb::detail
HWY_AFTER_NAMESPACE();

#endif  // HZ_QB_REDUCE_INL_H_
