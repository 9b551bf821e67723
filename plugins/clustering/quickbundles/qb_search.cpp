// The searches of QuickBundles and QuickBundlesX (DIPY-QBX.md sections 3.4
// and 3.5): exact mode with DIPY 1.6's arithmetic, fast mode in float32.
// Highway compiles this file once per SIMD target (foreach_target.h) and
// run_qb / run_qbx dispatch to the best one the CPU supports, so the
// distance kernel and every plain loop here run at the CPU's vector width
// (AVX-512 on this project's machines) without the build assuming it.
// Exact mode's values do not depend on the target: its arithmetic is scalar
// double or element-wise float32, and this file is compiled with
// -ffp-contract=off. Fast mode's sums follow the vector width, so a near-tie
// may resolve differently on a CPU of another width.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "qb_search.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "qb_internal.hpp"
#include "qb_reduce-inl.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <deque>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>

HWY_BEFORE_NAMESPACE();
namespace qb::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

namespace {

// DIPY's AveragePointwiseEuclideanMetric.c_dist (float32 differences,
// double sums in point order, divided by P) when it can beat `bound`, +inf when it cannot. The partial
// sums only grow, and rounding is monotonic, so stopping once
// partial / P >= bound never changes which candidate wins: the result is the
// same as DIPY's full computation followed by the comparison.
inline double mdf_below(const float *a, const float *b, std::uint32_t P, double bound) {
    // sum >= stop_sum implies sum / P >= bound: the (1 + 2^-50) factor
    // outweighs the two roundings of the products.
    const double stop_sum = bound * static_cast<double>(P) * (1.0 + 0x1p-50);
    double sum = 0.0;
    std::uint32_t n = 0;
    while (n < P) {
        // Four points at a time: the per-point terms are independent (the
        // compiler vectorises them); only the sum is sequential, as in DIPY.
        const std::uint32_t m = std::min<std::uint32_t>(P - n, 4);
        double r[4];
        for (std::uint32_t j = 0; j < m; ++j) {
            const std::uint32_t p = n + j;
            const double dx = static_cast<float>(a[p] - b[p]);
            const double dy = static_cast<float>(a[P + p] - b[P + p]);
            const double dz = static_cast<float>(a[2 * P + p] - b[2 * P + p]);
            r[j] = std::sqrt(((0.0 + dx * dx) + dy * dy) + dz * dz);
        }
        for (std::uint32_t j = 0; j < m; ++j) sum += r[j];
        n += m;
        if (n < P && sum >= stop_sum) return std::numeric_limits<double>::infinity();
    }
    return sum / static_cast<double>(P);
}

// Fast mode: the distances from centroid c to the streamline's direct (f)
// and flipped (g) features, float32 differences and sums: one vector of
// points per axis at a time (P = 12 is one masked vector of 16 lanes with
// AVX-512), the two orientations as independent chains of per-lane sums
// (af, ag: mdf_pair_lanes, below), which the caller reduces across lanes,
// two candidates' at a time (sum_lanes4). No early exit: the whole distance
// costs about what one exit test would. Blocks are 3P floats; the masked
// loads of the last axis may touch the kTail floats after them.
// sqrt(s) as s * rsqrt(s) with one Newton step: within a few ulp of the
// rounded square root (the float32 sums around it round as much), at a
// fraction of the cost of a vector square root. s = 0 gives 0.
template <class D, class V>
HWY_INLINE V fast_sqrt(D d, V s) {
    const V y = hn::ApproximateReciprocalSqrt(hn::Max(s, hn::Set(d, std::numeric_limits<float>::min())));
    const V r = hn::Mul(s, y);
    return hn::Mul(r, hn::NegMulAdd(hn::Mul(r, hn::Set(d, 0.5f)), y, hn::Set(d, 1.5f)));  // r (1.5 - r y / 2)
}

template <class D, class V>
HWY_INLINE V point_dists(D d, V cx, V cy, V cz, V x, V y, V z) {
    const V dx = hn::Sub(cx, x), dy = hn::Sub(cy, y), dz = hn::Sub(cz, z);
    return fast_sqrt(d, hn::MulAdd(dz, dz, hn::MulAdd(dy, dy, hn::Mul(dx, dx))));
}

template <class D, class V = hn::Vec<D>>
HWY_INLINE void mdf_pair_lanes(D d, const float *HWY_RESTRICT c, const float *HWY_RESTRICT f, const float *HWY_RESTRICT g, std::uint32_t P,
                               V &af, V &ag) {
    const std::size_t N = hn::Lanes(d);
    af = hn::Zero(d);
    ag = hn::Zero(d);
    std::size_t i = 0;
    for (; i + N <= P; i += N) {
        const auto cx = hn::LoadU(d, c + i), cy = hn::LoadU(d, c + P + i), cz = hn::LoadU(d, c + 2 * P + i);
        af = hn::Add(af, point_dists(d, cx, cy, cz, hn::LoadU(d, f + i), hn::LoadU(d, f + P + i), hn::LoadU(d, f + 2 * P + i)));
        ag = hn::Add(ag, point_dists(d, cx, cy, cz, hn::LoadU(d, g + i), hn::LoadU(d, g + P + i), hn::LoadU(d, g + 2 * P + i)));
    }
    if (i < P) {  // masked-off lanes load zeros in both, which add 0
        const auto m = hn::FirstN(d, P - i);
        const auto cx = hn::MaskedLoad(m, d, c + i), cy = hn::MaskedLoad(m, d, c + P + i), cz = hn::MaskedLoad(m, d, c + 2 * P + i);
        af = hn::Add(af, point_dists(d, cx, cy, cz, hn::MaskedLoad(m, d, f + i), hn::MaskedLoad(m, d, f + P + i),
                                     hn::MaskedLoad(m, d, f + 2 * P + i)));
        ag = hn::Add(ag, point_dists(d, cx, cy, cz, hn::MaskedLoad(m, d, g + i), hn::MaskedLoad(m, d, g + P + i),
                                     hn::MaskedLoad(m, d, g + 2 * P + i)));
    }
}

// The sums of the lanes of four vectors at once, into out[0..4): within
// each 128-bit block by two rounds of interleaving adds (a, b and c, d,
// then the pairs), then across the blocks: about a third of the
// instructions of four separate reductions (16-lane targets: 13 against
// 32). The scalar target reduces each vector on its own.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void sum_lanes4(D d, V a, V b, V c, V e, float *HWY_RESTRICT out) {
#if HWY_TARGET == HWY_SCALAR
    out[0] = hn::GetLane(hn::SumOfLanes(d, a));
    out[1] = hn::GetLane(hn::SumOfLanes(d, b));
    out[2] = hn::GetLane(hn::SumOfLanes(d, c));
    out[3] = hn::GetLane(hn::SumOfLanes(d, e));
#else
    // Per block: ab = [a0+a2, b0+b2, a1+a3, b1+b3], ce likewise; then as
    // 64-bit pairs: [a0123, b0123, c0123, e0123].
    const V ab = hn::Add(hn::InterleaveLower(d, a, b), hn::InterleaveUpper(d, a, b));
    const V ce = hn::Add(hn::InterleaveLower(d, c, e), hn::InterleaveUpper(d, c, e));
    const hn::Repartition<double, D> d64;
    const auto ab64 = hn::BitCast(d64, ab), ce64 = hn::BitCast(d64, ce);
    const V v = hn::Add(hn::BitCast(d, hn::InterleaveLower(d64, ab64, ce64)), hn::BitCast(d, hn::InterleaveUpper(d64, ab64, ce64)));
    if constexpr (hn::MaxLanes(D()) == 4) {
        hn::StoreU(v, d, out);
    } else if constexpr (hn::MaxLanes(D()) == 8) {
        const hn::Half<D> dh;
        hn::StoreU(hn::Add(hn::LowerHalf(dh, v), hn::UpperHalf(dh, v)), dh, out);
    } else {
        static_assert(hn::MaxLanes(D()) == 16);
        const hn::Half<D> dh;
        const hn::Half<decltype(dh)> dq;
        const auto h = hn::Add(hn::LowerHalf(dh, v), hn::UpperHalf(dh, v));
        hn::StoreU(hn::Add(hn::LowerHalf(dq, h), hn::UpperHalf(dq, h)), dq, out);
    }
#endif
}

// A centroid's AABB (as feature_box: min/max are exact, so the same values)
// and its mean point, summed in float32 (LowerBound's slack covers that
// rounding): what update() refreshes after every change, one vector per
// axis at a time.
// (P = 12 on 16-lane targets: all three axes at once, qb_reduce-inl.h.)
HWY_INLINE void box_and_mean(const float *HWY_RESTRICT x, std::uint32_t P, float c[3], float r[3], float mean[3]) {
    const hn::ScalableTag<float> d;
    if (float lo[3], hi[3], sum[3]; P == 12 && axes_min_max_sum_12(d, x, lo, hi, sum)) {
        box_mean_12(lo, hi, sum, c, r, mean);
        return;
    }
    const std::size_t N = hn::Lanes(d);
    const auto inf = hn::Set(d, std::numeric_limits<float>::infinity()), ninf = hn::Neg(inf);
    for (int a = 0; a < 3; ++a) {
        const float *p = x + a * P;
        auto mn = inf, mx = ninf, sum = hn::Zero(d);
        std::size_t i = 0;
        for (; i + N <= P; i += N) {
            const auto v = hn::LoadU(d, p + i);
            mn = hn::Min(mn, v);
            mx = hn::Max(mx, v);
            sum = hn::Add(sum, v);
        }
        if (i < P) {
            const auto m = hn::FirstN(d, P - i);
            const auto v = hn::MaskedLoad(m, d, p + i);
            mn = hn::Min(mn, hn::IfThenElse(m, v, inf));
            mx = hn::Max(mx, hn::IfThenElse(m, v, ninf));
            sum = hn::Add(sum, v);
        }
        const float lo = hn::GetLane(hn::MinOfLanes(d, mn)), hi = hn::GetLane(hn::MaxOfLanes(d, mx));
        r[a] = (hi - lo) / 2.0f;
        c[a] = lo + r[a];
        mean[a] = hn::GetLane(hn::SumOfLanes(d, sum)) / static_cast<float>(P);
    }
}

// The reversal of a feature block (its flipped features in fast mode),
// per axis; a loop the compiler vectorises.
inline void reverse_block(const float *HWY_RESTRICT x, std::uint32_t P, float *HWY_RESTRICT out) {
    for (int d = 0; d < 3; ++d)
        for (std::uint32_t i = 0; i < P; ++i) out[d * P + i] = x[d * P + (P - 1 - i)];
}

struct ExactMetric {
    static double dist(const float *a, const float *b, std::uint32_t P, double bound) { return mdf_below(a, b, P, bound); }
    static constexpr double kBoundFactor = 1.0 - 1e-7;  // DIPY's value vs the real MDF
};
struct FastMetric {                                     // (its searches are search_fast's, below)
    static constexpr double kBoundFactor = 1.0 - 1e-5;  // float32 sums of up to 1000 terms
};
template <class Metric>
constexpr bool kFast = std::is_same_v<Metric, FastMetric>;

// The flipped features of streamline idx: stored (exact mode), or the
// reversal of the direct ones in `buf`.
inline const float *flipped_of(const Features &f, std::uint64_t idx, float *buf, std::uint32_t P) {
    if (!f.flipped.empty()) return f.flipped.data() + idx * P * 3;
    reverse_block(f.direct.data() + idx * P * 3, P, buf);
    return buf;
}

// C = ((C * (float)size) + e) / (float)(size + 1), in float32, as DIPY.
inline void update_centroid(float *c, std::uint64_t size, const float *e, std::uint32_t P) {
    const float fs = static_cast<float>(size), fs1 = static_cast<float>(size + 1);
    for (std::uint32_t i = 0; i < 3 * P; ++i) c[i] = ((c[i] * fs) + e[i]) / fs1;
}
// Fast mode's form of the same update: a product by 1 / (size + 1) instead
// of a division per coordinate (within an ulp of it).
inline void update_centroid_fast(float *c, std::uint64_t size, const float *e, std::uint32_t P) {
    const float fs = static_cast<float>(size), inv = 1.0f / static_cast<float>(size + 1);
    for (std::uint32_t i = 0; i < 3 * P; ++i) c[i] = ((c[i] * fs) + e[i]) * inv;
}
template <class Metric>
inline void update_centroid_as(float *c, std::uint64_t size, const float *e, std::uint32_t P) {
    if constexpr (kFast<Metric>)
        update_centroid_fast(c, size, e, P);
    else
        update_centroid(c, size, e, P);
}
// Fast mode, 12 points, 16-lane targets: update_centroid_fast and then
// box_and_mean's results, computed from the registers the update leaves
// instead of reading the centroid back while its stores are in flight (a
// load that spans two of them cannot be forwarded and waits). The same
// floats bit for bit. Returns false (and does nothing) elsewhere.
template <class Metric, class D>
HWY_INLINE bool update_with_box_12(D d, float *HWY_RESTRICT c, std::uint64_t size, const float *HWY_RESTRICT e, std::uint32_t P,
                                   float bc[3], float br[3], float mean[3]) {
    if constexpr (!kFast<Metric> || hn::MaxLanes(D()) != 16) {
        (void)d, (void)c, (void)size, (void)e, (void)P, (void)bc, (void)br, (void)mean;
        return false;
    } else {
        if (P != 12) return false;
        const auto fs = hn::Set(d, static_cast<float>(size)), inv = hn::Set(d, 1.0f / static_cast<float>(size + 1));
        const auto first4 = hn::FirstN(d, 4);
        auto up = [&](hn::Vec<D> cv, hn::Vec<D> ev) { return hn::Mul(hn::Add(hn::Mul(cv, fs), ev), inv); };
        const auto v0 = up(hn::LoadU(d, c), hn::LoadU(d, e)), v1 = up(hn::LoadU(d, c + 16), hn::LoadU(d, e + 16));
        const auto t = up(hn::MaskedLoad(first4, d, c + 32), hn::MaskedLoad(first4, d, e + 32));
        float lo[3], hi[3], sum[3];
        store_12_min_max_sum(d, v0, v1, t, c, lo, hi, sum);
        box_mean_12(lo, hi, sum, bc, br, mean);
        return true;
    }
}
// C = the update of update_centroid_as, then its AABB and mean point
// (box_and_mean): fused where update_with_box_12 can. QB's and QBX's update.
template <class Metric>
inline void update_with_box(float *c, std::uint64_t size, const float *e, std::uint32_t P, float bc[3], float br[3], float mean[3]) {
    if (update_with_box_12<Metric>(hn::ScalableTag<float>(), c, size, e, P, bc, br, mean)) return;
    update_centroid_as<Metric>(c, size, e, P);
    box_and_mean(c, P, bc, br, mean);
}

// A rigorous lower bound on the distance DIPY computes, from mean points.
// By the triangle inequality, the real-valued MDF is at least the distance
// between the two mean points. DIPY's value differs from the real one only
// by the float32 rounding of each coordinate difference (relative 2^-24)
// and double roundings. A streamline's mean point is computed in double and
// stored as float32 (error below 2^-24 m per axis, m = the largest
// |coordinate|); a centroid's is summed in float32 (error below P 2^-24 m
// per axis); together below `slack` in length. Their squared distance q is
// computed in float32 (relative error below 2^-21). So
// mdf >= (sqrt(q / (1 + 2^-21)) - slack) * (1 - 1e-7): when that is already
// >= the bound a candidate must beat, computing its MDF cannot change the
// result, and it is skipped.
struct LowerBound {
    double slack = 0;
    double factor = 1.0 - 1e-7;
    // m: at least the largest |coordinate| of every feature and centroid
    // the bound is applied to.
    void prepare(float m, std::uint32_t nb_points, bool float_means) {
        const double P = std::max<std::uint32_t>(nb_points, 1);
        slack = 4e-12 * double(m) * P + 0x1p-21 * double(m) + 2.0 * P * 0x1p-24 * double(m) + 1e-300;
        // A streamline's mean point summed in float32 (Features::float_means)
        // is within P 2^-24 m per axis instead of 2^-24 m: sqrt(3) (2P) 2^-24 m
        // in length with the centroid's, which 4 P 2^-24 m + 2^-21 m covers.
        if (float_means) slack += 2.0 * P * 0x1p-24 * double(m);
    }
    void prepare(const Features &f) { prepare(f.max_abs, f.nb_points, f.float_means); }
    // Squared form, without a square root per candidate: hopeless when
    // q >= limit2(bound) = ((bound / factor) + slack)^2 (1 + 2^-20), rounded
    // up to float32.
    float limit2(double bound) const {
        const double lim = bound / factor + slack;
        const double l2 = lim * lim * (1.0 + 0x1p-20);
        if (!(l2 < double(std::numeric_limits<float>::max()))) return std::numeric_limits<float>::infinity();
        float f = static_cast<float>(l2);
        std::uint32_t u;
        std::memcpy(&u, &f, 4);
        ++u;  // rounded up (l2 > 0)
        std::memcpy(&f, &u, 4);
        return f;
    }
};

// Squared float32 distances from the mean points (mx, my, mz)[0..K) to `a`:
// every candidate's lower bound at once, a vector of candidates at a time at
// the full width of this file's target (QB's thousands of clusters; the
// file's compiler-vectorised loops are held to 128 bits, CMakeLists.txt).
// Returns the smallest of them. ((dx dx + dy dy) + dz dz, no fused
// multiply-add: the same values as the scalar form.)
float screen1(std::size_t K, const float *mx, const float *my, const float *mz, const float a[3], float *q) {
    const hn::ScalableTag<float> d;
    const hn::RebindToSigned<decltype(d)> di;
    const std::size_t N = hn::Lanes(d);
    const auto ax = hn::Set(d, a[0]), ay = hn::Set(d, a[1]), az = hn::Set(d, a[2]);
    auto sq = [&](auto x, auto y, auto z) {
        const auto dx = hn::Sub(x, ax), dy = hn::Sub(y, ay), dz = hn::Sub(z, az);
        return hn::Add(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy)), hn::Mul(dz, dz));
    };
    // (The minimum of the bit patterns, which order as the non-negative
    // floats do: a one-cycle integer minimum carries the loop.)
    auto mn = hn::Set(di, 0x7f800000);  // +inf
    std::size_t k = 0;
    for (; k + N <= K; k += N) {
        const auto v = sq(hn::LoadU(d, mx + k), hn::LoadU(d, my + k), hn::LoadU(d, mz + k));
        hn::StoreU(v, d, q + k);
        mn = hn::Min(mn, hn::BitCast(di, v));
    }
    std::int32_t r = hn::GetLane(hn::MinOfLanes(di, mn));
    // The rest one at a time: the arrays end at K (a masked load is a full
    // load on targets before AVX-512, which would read past them).
    for (; k < K; ++k) {
        const float dx = mx[k] - a[0], dy = my[k] - a[1], dz = mz[k] - a[2];
        const float v = dx * dx + dy * dy + dz * dz;
        q[k] = v;
        std::int32_t iv;
        std::memcpy(&iv, &v, 4);
        r = std::min(r, iv);
    }
    float f;
    std::memcpy(&f, &r, 4);
    return f;
}

// Both orientations' bounds (exact mode: the flipped features have their own
// mean point `b`); returns the smallest of all.
inline float screen(std::size_t K, const float *mx, const float *my, const float *mz, const float a[3], const float b[3], float *la,
                    float *lb) {
    return std::min(screen1(K, mx, my, mz, a, la), screen1(K, mx, my, mz, b, lb));
}

// The smallest value that compares greater than v after the rounding the
// caller applies (float32 for QBX, none for QB).
// (v >= 0; the next representable value is the bit pattern plus one.)
inline float next_float(float v) {
    if (!(v < std::numeric_limits<float>::infinity())) return v;
    std::uint32_t u;
    std::memcpy(&u, &v, 4);
    ++u;
    std::memcpy(&v, &u, 4);
    return v;
}
template <bool F32>
inline double next_up(double v) {
    if constexpr (F32)
        return next_float(static_cast<float>(v));
    else
        return std::nextafter(v, std::numeric_limits<double>::infinity());
}

// The candidates of one search: K clusters, each in two orientations, with
// their lower bounds (la: direct, lb: flipped) and their positions in
// DIPY's scan order. QBX scans child 0 direct, child 0 flipped, child 1
// direct, ... (key 2k + flip); QB scans every cluster direct, then every
// cluster flipped (key flip K + k).
struct Candidates {
    std::size_t K = 0;
    const float *la = nullptr, *lb = nullptr;
    float min_lb = 0;         // the smallest of them
    bool interleaved = true;  // QBX keys; QB otherwise
    std::int64_t key(std::size_t k, bool flip) const {
        return interleaved ? static_cast<std::int64_t>(2 * k + flip) : static_cast<std::int64_t>(flip ? K + k : k);
    }
};

// Best-first search for DIPY's choice: the lexicographic minimum of
// (value, key) among the candidates, where value = the distance (rounded
// to float32 when F32) and key = the position in DIPY's scan order (its
// "first strict minimum" is exactly that minimum). Only candidates for
// which `tested(k)` holds take part, as in DIPY. A candidate whose distance
// is >= `cap` is irrelevant to the caller and may be skipped.
//
// The candidate with the smallest lower bound goes first, so the bound is
// tight from the start; every other one is skipped when its lower bound
// shows it cannot beat the best so far under the tie rule (a smaller key
// wins ties, so those get the next representable value as their bound).
// The answer is therefore the one a full scan gives whenever that answer's
// distance is below `cap`. Returns the key, or -1 when none qualified.
template <class Metric, bool F32, class Centroid, class Tested>
std::int64_t best_first(const Candidates &cs, const float *fd, const float *fg, double cap, const LowerBound &lbound, std::uint32_t P,
                        Centroid centroid, Tested tested, double &best_out) {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    double best = std::numeric_limits<double>::infinity();
    std::int64_t key = -1;
    double bound_lo = cap, bound_hi = cap;  // for keys below / above `key`
    float lim_lo = lbound.limit2(cap), lim_hi = lim_lo;
    auto consider = [&](std::size_t k, bool flip) {
        const std::int64_t c = cs.key(k, flip);
        const bool below = c < key;
        // (An infinite limit prunes nothing, even a bound that overflowed
        // float32 for coordinates beyond 1e19 mm.)
        const float lim = below ? lim_lo : lim_hi;
        if (((flip ? cs.lb : cs.la)[k] >= lim && lim < kInf) || !tested(k)) return;
        const double bound = below ? bound_lo : bound_hi;
        double d = Metric::dist(centroid(k), flip ? fg : fd, P, bound);
        if (!(d < bound)) return;  // cannot win (or pruned by the metric)
        if constexpr (F32) d = static_cast<float>(d);
        if (key < 0 || d < best || (d == best && below)) {
            best = d;
            key = c;
            bound_hi = std::min(cap, best);
            bound_lo = std::min(cap, next_up<F32>(best));
            lim_hi = lbound.limit2(bound_hi);
            lim_lo = lbound.limit2(bound_lo);
        }
    };
    const std::size_t K = cs.K;
    if (K == 0) return -1;
    // The first candidate with the smallest lower bound.
    std::size_t first = 0;
    bool first_flip = false;
    for (std::size_t k = 0; k < K; ++k) {
        if (cs.la[k] == cs.min_lb) {
            first = k;
            break;
        }
        if (cs.lb[k] == cs.min_lb) {
            first = k;
            first_flip = true;
            break;
        }
    }
    consider(first, first_flip);
    // The rest, through a filter at the current lim_lo (>= lim_hi, and it
    // only shrinks), kept in a register; consider() applies the exact test.
    const float lim = lim_lo;
    const bool all = !(lim < kInf);
    for (std::size_t k = 0; k < K; ++k) {
        if ((cs.la[k] < lim || all) && (k != first || first_flip)) [[unlikely]]
            consider(k, false);
        if ((cs.lb[k] < lim || all) && (k != first || !first_flip)) [[unlikely]]
            consider(k, true);
    }
    best_out = best;
    return key;
}

// Nodes with at most this many children are searched without lower bounds.
constexpr std::size_t kSearchAll = 8;

// Fast mode's search: the same choice as best_first (the lexicographic
// minimum of (distance, key) over the candidates for which tested(k)
// holds), uncapped, from float32 distances. The flipped features' mean
// point is the direct one's, so both orientations of a child share one
// lower bound and are computed together by mdf_pair_lanes. The children of a
// node below level 1 (about 5) are all computed, independent of each other
// and without a branch between them; more go best-first: the one with the
// smallest lower bound, then every other one whose bound can still win.
// Keys as in Candidates. Returns the key, or -1 when none was tested.
template <bool F32, class Tested>
std::int64_t search_fast(std::size_t K, bool interleaved, const float *kid_c, const float *mx, const float *my, const float *mz,
                         const float *fd, const float *fg, const float mf[3], std::uint32_t P, const LowerBound &lbound, Tested tested,
                         std::vector<float> &scratch, double &best_out) {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    double best = std::numeric_limits<double>::infinity();
    std::int64_t key = -1;
    auto take = [&](double d, std::int64_t c) {
        if constexpr (F32) d = static_cast<float>(d);
        if (d < best || (d == best && c < key)) {
            best = d;
            key = c;
        }
    };
    // The distances of a batch of candidates first, then the choice: the
    // batch's distances do not wait for each other's comparisons, so the
    // CPU overlaps them.
    std::size_t batch[kSearchAll];
    float sum[2 * kSearchAll];                         // (sum_lanes4 fills four from an even j: up to sum[2 * kSearchAll - 1])
    const float inv_p = 1.0f / static_cast<float>(P);  // (a product, not a division, per distance)
    const hn::ScalableTag<float> d;
    auto run = [&](std::size_t n) {
        // Two candidates at a time, both orientations each, their four sums
        // reduced together.
        for (std::size_t j = 0; j < n; j += 2) {
            hn::Vec<decltype(d)> f0, g0, f1 = hn::Zero(d), g1 = hn::Zero(d);
            mdf_pair_lanes(d, kid_c + batch[j] * 3 * P, fd, fg, P, f0, g0);
            if (j + 1 < n) mdf_pair_lanes(d, kid_c + batch[j + 1] * 3 * P, fd, fg, P, f1, g1);
            sum_lanes4(d, f0, g0, f1, g1, sum + 2 * j);
        }
        for (std::size_t j = 0; j < n; ++j) {
            const std::size_t k = batch[j];
            take(sum[2 * j] * inv_p, interleaved ? std::int64_t(2 * k) : std::int64_t(k));
            take(sum[2 * j + 1] * inv_p, interleaved ? std::int64_t(2 * k + 1) : std::int64_t(K + k));
        }
    };
    if (K <= kSearchAll) {
        std::size_t n = 0;
        for (std::size_t k = 0; k < K; ++k)
            if (tested(k)) batch[n++] = k;
        run(n);
    } else {
        const std::size_t N = hn::Lanes(d), Kp = (K + N - 1) / N * N;
        scratch.resize(Kp);
        float *q = scratch.data();
        const float mn = screen1(K, mx, my, mz, mf, q);
        std::fill(q + K, q + Kp, kInf);
        std::size_t first = 0;
        for (std::size_t k0 = 0; k0 < Kp; k0 += N) {
            const std::intptr_t j = hn::FindFirstTrue(d, hn::Eq(hn::LoadU(d, q + k0), hn::Set(d, mn)));
            if (j >= 0) {
                first = k0 + static_cast<std::size_t>(j);
                break;
            }
        }
        if (tested(first)) {
            batch[0] = first;
            run(1);
        }
        // The rest whose bound is below the limit, a vector of bounds at a
        // time. (An infinite limit prunes nothing, even a bound that
        // overflowed float32 for coordinates beyond 1e19 mm.)
        float lim = key < 0 ? kInf : lbound.limit2(next_up<F32>(best));
        std::size_t n = 0;
        auto add = [&](std::size_t k) {
            if (k == first || !tested(k)) return;
            batch[n++] = k;
            if (n == kSearchAll) {
                run(n);
                n = 0;
                if (key >= 0) lim = lbound.limit2(next_up<F32>(best));
            }
        };
        if (!(lim < kInf)) {
            for (std::size_t k = 0; k < K; ++k) add(k);
        } else {
            for (std::size_t k0 = 0; k0 < Kp; k0 += N) {
                std::uint64_t bits = 0;  // (at most 16 lanes of float32)
                hn::StoreMaskBits(d, hn::Lt(hn::LoadU(d, q + k0), hn::Set(d, lim)), reinterpret_cast<std::uint8_t *>(&bits));
                for (; bits != 0; bits &= bits - 1) {
                    const std::size_t k = k0 + static_cast<std::size_t>(__builtin_ctzll(bits));
                    if (q[k] < lim) add(k);
                }
            }
        }
        run(n);
    }
    best_out = best;
    return key;
}

}  // namespace

template <class Metric>
Tree qb_impl(const Features &f, double T, const std::vector<std::uint64_t> &order, const CancelFn &cancel, const ProgressFn &progress) {
    const std::uint32_t P = f.nb_points;
    const std::uint64_t N = f.count;
    check_order(order, N);
    const Order ord(order);
    std::vector<float> C(kTail, 0.0f);                             // K feature blocks, then kTail floats
    std::vector<float> mx, my, mz, la, lb, fg_buf(3 * P + kTail);  // the clusters' mean points; scratch
    LowerBound lbound;
    lbound.prepare(f);
    lbound.factor = Metric::kBoundFactor;
    std::vector<std::uint64_t> sizes;
    std::vector<std::vector<std::uint64_t>> indices;
    for (std::uint64_t it = 0; it < N; ++it) {
        if ((it & 1023) == 0) {
            if (cancel && cancel()) throw Cancelled{};
            if (progress) progress(double(it) / double(N));
        }
        const std::uint64_t idx = ord[it];
        const float *fd = &f.direct[idx * P * 3], *fg = flipped_of(f, idx, fg_buf.data(), P);
        const float *mf = &f.geom[idx * Features::kGeom + 6], *mg = mf + 3;
        const std::uint64_t K = sizes.size();
        auto all = [](std::size_t) { return true; };
        double d = 0;
        std::int64_t key;
        if constexpr (kFast<Metric>) {
            key = search_fast<false>(K, false, C.data(), mx.data(), my.data(), mz.data(), fd, fg, mf, P, lbound, all, la, d);
        } else {
            la.resize(K);
            lb.resize(K);
            Candidates cs;
            cs.K = K;
            cs.la = la.data();
            cs.lb = lb.data();
            cs.interleaved = false;
            cs.min_lb = screen(K, mx.data(), my.data(), mz.data(), mf, mg, la.data(), lb.data());
            auto centroid = [&](std::size_t k) { return &C[k * P * 3]; };
            key = best_first<Metric, false>(cs, fd, fg, T, lbound, P, centroid, all, d);
            if (key < 0 || !(d < T))  // a new cluster, seeded in the nearest one's orientation
                key = best_first<Metric, false>(cs, fd, fg, std::numeric_limits<double>::infinity(), lbound, P, centroid, all, d);
        }
        const bool use_g = key >= 0 && static_cast<std::uint64_t>(key) >= K;
        std::uint64_t k = key < 0 ? 0 : (use_g ? key - K : key);
        const float *e = use_g ? fg : fd;
        if (key < 0 || !(d < T)) {  // join iff d < T (strict)
            k = K;
            C.resize(C.size() + P * 3, 0.0f);  // (a block of zeros before the tail)
            mx.push_back(0);
            my.push_back(0);
            mz.push_back(0);
            sizes.push_back(0);
            indices.emplace_back();
        }
        float m[3], unused[6];
        update_with_box<Metric>(&C[k * P * 3], sizes[k], e, P, unused, unused + 3, m);
        mx[k] = m[0];
        my[k] = m[1];
        mz[k] = m[2];
        ++sizes[k];
        indices[k].push_back(idx);
    }
    // Root: every streamline in processing order, mean of the oriented features.
    std::deque<Node> nodes(1);
    nodes[0].threshold = T;
    nodes[0].c.assign(P * 3 + kTail, 0.0f);
    for (std::uint64_t k = 0; k < sizes.size(); ++k) {
        Node &n = nodes.emplace_back();
        n.parent = &nodes[0];
        n.level = 1;
        n.slot = static_cast<std::uint32_t>(k);
        n.size = sizes[k];
        n.indices = std::move(indices[k]);
        nodes[0].children.push_back(&n);
    }
    nodes[0].indices.resize(N);
    ord.copy(N, nodes[0].indices.data());
    nodes[0].size = N;
    // Root centroid: size-weighted mean of the clusters (float64, then float32).
    for (std::uint32_t i = 0; i < P * 3; ++i) {
        double acc = 0;
        for (std::size_t k = 0; k < sizes.size(); ++k) acc += double(C[k * P * 3 + i]) * double(sizes[k]);
        nodes[0].c[i] = N ? static_cast<float>(acc / double(N)) : 0.0f;
    }
    nodes[0].kid_c = std::move(C);
    if (progress) progress(1.0);
    return flatten(nodes[0], 1, {T}, P);
}

// The two halves of one QBX step at node `n` (DIPY-QBX.md section 3.5).
template <class Metric>
struct QbxOps {
    std::uint32_t P, L;
    const std::vector<double> &t;

    // n.C = ((n.C * size) + e) / (size + 1); refresh n's record in its parent.
    void update(Node &n, const float *e) const {
        Node::Kid &me = n.parent->kids[n.slot];
        float m[3];
        float *c = n.parent->kid_c.data() + std::size_t(n.slot) * 3 * P;
        update_with_box<Metric>(c, n.size, e, P, me.box_c, me.box_r, m);
        ++n.size;
        n.parent->mx[n.slot] = m[0];
        n.parent->my[n.slot] = m[1];
        n.parent->mz[n.slot] = m[2];
    }

    // Searches n's children for the streamline; returns the chosen child
    // (created when none is within n's threshold) and the orientation it is
    // to be updated with. Candidate key 2k + flip is DIPY's scan order
    // (child 0 direct, child 0 flipped, child 1 direct, ...); a candidate
    // takes part only when its box overlaps the streamline's, as in DIPY.
    // `geom`: the streamline's Features::geom (box centre, half-size, mean
    // points of both orientations); `lbound`: the calling thread's bound.
    Node *search(Node &n, const float *fd, const float *fg, const float *geom, const LowerBound &lbound, bool &flip_out,
                 std::deque<Node> &store, std::uint32_t tag, std::vector<float> &scratch) const {
        const float *bc = geom, *br = geom + 3, *mf = geom + 6, *mg = geom + 9;
        const std::size_t K = n.kids.size();
        const float pad = static_cast<float>(n.threshold);
        auto tested = [&](std::size_t k) {
            const Node::Kid &ch = n.kids[k];
            return std::fabs(ch.box_c[0] - bc[0]) <= ch.box_r[0] + br[0] + pad &&
                   std::fabs(ch.box_c[1] - bc[1]) <= ch.box_r[1] + br[1] + pad &&
                   std::fabs(ch.box_c[2] - bc[2]) <= ch.box_r[2] + br[2] + pad;
        };
        const float *kid_c = n.kid_c.data();
        double best = 0;
        std::int64_t key;
        if constexpr (kFast<Metric>) {
            key = search_fast<true>(K, true, kid_c, n.mx.data(), n.my.data(), n.mz.data(), fd, fg, mf, P, lbound, tested, scratch, best);
        } else {
            scratch.resize(2 * K);
            Candidates cs;
            cs.K = K;
            cs.la = scratch.data();
            cs.lb = scratch.data() + K;
            cs.min_lb = screen(K, n.mx.data(), n.my.data(), n.mz.data(), mf, mg, scratch.data(), scratch.data() + K);
            auto centroid = [&](std::size_t k) { return kid_c + k * 3 * P; };
            // Children farther than the threshold only matter when none is
            // within it: then DIPY seeds the new child with the orientation
            // of the nearest one, which the second, uncapped search finds.
            key = best_first<Metric, true>(cs, fd, fg, next_up<true>(n.threshold), lbound, P, centroid, tested, best);
            if (!(key >= 0 && best <= n.threshold))
                key = best_first<Metric, true>(cs, fd, fg, std::numeric_limits<double>::infinity(), lbound, P, centroid, tested, best);
        }
        std::int64_t kid;
        bool flip;
        if (key >= 0 && best <= n.threshold) {  // join iff dist <= threshold (non-strict)
            kid = key / 2;
            flip = key & 1;
        } else {  // a new child, seeded in the nearest one's orientation
            flip = key >= 0 && (key & 1);
            Node &c = store.emplace_back();
            c.uid = tag | static_cast<std::uint32_t>(store.size() - 1);
            c.parent = &n;
            c.level = n.level + 1;
            c.threshold = c.level < L ? t[c.level] : 0.0;
            kid = static_cast<std::int64_t>(n.children.size());
            c.slot = static_cast<std::uint32_t>(kid);
            n.children.push_back(&c);
            n.kids.push_back({});
            n.kid_c.resize(n.children.size() * 3 * P + kTail, 0.0f);
            n.mx.push_back(0);
            n.my.push_back(0);
            n.mz.push_back(0);
        }
        flip_out = flip;
        return n.children[static_cast<std::size_t>(kid)];
    }
};

// QuickBundlesX on two threads, computing exactly what the sequential
// algorithm computes. The main thread searches the root's children and
// updates the chosen level-1 node for every streamline, in order; below
// level 1, each level-1 node's subtree is continued either by the main
// thread itself or by a worker, which follows the main thread through
// `handoff`. Level-1 decisions depend only on level-1 centroids, deeper
// ones only on the nodes of the same subtree, and a subtree is only ever
// continued by one thread at a time, in streamline order: the main thread
// takes a subtree over only once the worker has finished every streamline
// it was sent for it, and hands one back at any time (the worker then sees
// the main thread's updates through the release/acquire of `published`).
// Which thread continues a subtree decides only the speed: the main thread
// takes subtrees while the worker lags behind and gives them back once it
// has caught up, so both stay busy. The one coupling across streamlines,
// DIPY's orientation of the root update by the previous streamline's leaf
// flip, touches only the root centroid, which no search reads: the worker
// replays it in order as it goes (the leaf flips before `done` are known).
// Streamed features (fast mode) are computed a block at a time into a ring
// (see Source): by the worker ahead of the main thread while it keeps up,
// by the main thread when it reaches a block nobody has computed; with one
// thread, in turn with the search. The tree does not depend on which thread
// computed what, nor on whether there are two.
// Where the searches find a streamline's features: in an array of all of
// them, by streamline (`f`), or streamed from the streamlines (`in`, fast
// mode): computed a block at a time into a ring indexed by processing step,
// which both threads read.
struct Source {
    const Features *f = nullptr;
    const Input *in = nullptr;
    std::uint32_t P = 0;
    std::uint64_t N = 0;
    unsigned threads = 2;  // 1: the calling thread only
};

// Streamed features: the ring holds this many steps (at most; a power of
// two: 768 KiB at 12 points), computed this many at a time. The worker
// computes blocks ahead only while it lags the main thread by at most
// kProduceLag steps; further behind, it leaves them to the main thread,
// which shares the work that way.
constexpr std::uint64_t kRingSteps = 4096, kRingBlock = 256, kProduceLag = 512;

template <class Metric>
Tree qbx_impl(const Source &src, const std::vector<double> &t, const std::vector<std::uint64_t> &order, const CancelFn &cancel,
              const ProgressFn &progress) {
    const std::uint32_t P = src.P;
    const std::uint64_t N = src.N;
    const std::uint32_t L = static_cast<std::uint32_t>(t.size());
    if (L == 0) throw InputError("QuickBundlesX needs at least one threshold");
    check_order(order, N);
    const Order ord(order);
    std::deque<Node> store_a, store_b;  // each thread's nodes (stable addresses)
    Node &root = store_a.emplace_back();
    root.threshold = t[0];
    root.c.assign(P * 3 + kTail, 0.0f);
    const QbxOps<Metric> ops{P, L, t};

    // The features: by streamline (rows order[it]), or the ring (rows
    // it & (R - 1)). Ring rows are written by either thread, a block of B
    // steps at a time, once both threads are done with the steps they held.
    // The ring holds the flipped features too (the reversal of the direct
    // ones), computed with the block, once per streamline and ahead of the
    // searches, rather than by each search thread as it reaches the
    // streamline (whose vector loads would then wait for the reversal's
    // scalar stores).
    const bool streamed = src.in != nullptr;
    std::uint64_t R = kRingBlock;
    FloatArray ring_direct, ring_flipped, ring_geom;
    if (streamed) {
        while (R < kRingSteps && R < N) R <<= 1;
        for (FloatArray *a : {&ring_direct, &ring_flipped}) {
            a->resize(R * P * 3 + kTail);
            std::fill(a->end() - kTail, a->end(), 0.0f);
        }
        ring_geom.resize(R * Features::kGeom);
    }
    const float *direct = streamed ? ring_direct.data() : src.f->direct.data();
    const float *flipped = streamed ? ring_flipped.data() : src.f->flipped.empty() ? nullptr : src.f->flipped.data();
    const float *geom = streamed ? ring_geom.data() : src.f->geom.data();
    auto row = [&](std::uint64_t it) { return streamed ? (it & (R - 1)) : ord[it]; };
    // The flipped features of row r: stored (exact mode, the ring), or the
    // reversal of the direct ones into `buf`.
    auto flipped_row = [&](std::uint64_t r, float *buf) -> const float * {
        if (flipped) return flipped + r * P * 3;
        reverse_block(direct + r * P * 3, P, buf);
        return buf;
    };
    // The lower bounds' slack follows the largest |coordinate| of the
    // features: of all of them, or (streamed) of those computed so far, which
    // covers every streamline and centroid a search up to there involves.
    auto bound = [&](float max_abs) {
        LowerBound b;
        if (streamed)
            b.prepare(max_abs, P, true);
        else
            b.prepare(*src.f);
        b.factor = Metric::kBoundFactor;
        return b;
    };

    // The hand-off, one word per step: its level-1 node | its flip (bit 0),
    // or 0 when the main thread went on below that node itself.
    static_assert(alignof(Node) >= 2);
    std::vector<std::uint64_t> handoff;
    hzio::resize_prefaulted(handoff, N);
    auto handoff_word = [](Node *node, bool flip) { return static_cast<std::uint64_t>(reinterpret_cast<std::uintptr_t>(node)) | flip; };
    auto handoff_node = [](std::uint64_t h) { return reinterpret_cast<Node *>(static_cast<std::uintptr_t>(h & ~std::uint64_t{1})); };
    std::vector<std::uint8_t> leaf_flip;
    std::vector<std::uint32_t> path;  // each step's node per level
    hzio::resize_prefaulted(leaf_flip, N);
    hzio::resize_prefaulted(path, N * L);
    constexpr std::uint32_t kStageB = Paths::kStageB;  // uid tag of the worker's nodes
    // (Each on a cache line of its own: they are written by different threads.)
    alignas(64) std::atomic<std::uint64_t> published{0};  // main -> worker: handoff[0..published) is set
    alignas(64) std::atomic<std::uint64_t> done{0};       // worker -> main: it has continued every streamline below this
    alignas(64) std::atomic<bool> stop{false};

    // One thread's view of a streamline: its features in both orientations
    // and its Features::geom; its lower bound; and its buffers. (Cache-line
    // aligned: the worker's lives on its own stack, and the two are written
    // per streamline.)
    struct alignas(64) Lane {
        std::vector<float> fg, scratch;
        const float *fd = nullptr, *g = nullptr, *geom = nullptr;
        LowerBound lb;
    };
    Lane main_lane;
    main_lane.fg.resize(3 * P + kTail);
    main_lane.lb = bound(0.0f);
    auto load = [&](Lane &ln, std::uint64_t it) {
        const std::uint64_t r = row(it);
        ln.fd = direct + r * P * 3;
        ln.g = flipped_row(r, ln.fg.data());
        ln.geom = geom + r * Features::kGeom;
    };
    // Levels 2..L of streamline `it`, from its level-1 node.
    auto below = [&](Lane &ln, std::uint64_t it, Node *node, bool flip, std::deque<Node> &store, std::uint32_t tag) {
        while (node->level < L) {
            bool next_flip = false;
            Node *child = ops.search(*node, ln.fd, ln.g, ln.geom, ln.lb, next_flip, store, tag, ln.scratch);
            ops.update(*child, next_flip ? ln.g : ln.fd);
            path[it * L + child->level - 1] = child->uid;
            node = child;
            flip = next_flip;
        }
        leaf_flip[it] = flip;
    };

    // The root, replayed in order up to `end`: every streamline, oriented by
    // the previous one's leaf flip (by the worker as it goes when there is
    // one, else by the main thread).
    std::uint64_t replayed = 0;
    bool use_flip = false;
    auto replay = [&](std::uint64_t end, float *buf) {
        for (; replayed < end; ++replayed) {
            const std::uint64_t r = row(replayed);
            update_centroid(root.c.data(), root.size, use_flip ? flipped_row(r, buf) : direct + r * P * 3, P);
            ++root.size;
            use_flip = leaf_flip[replayed];
        }
    };
    // Streamed: the ring's rows hold R steps, B to a block. Block [b0, b0 + B)
    // goes into the rows that steps R earlier held, once both threads are
    // done with those (and the root has been replayed past them). Either
    // thread computes a block: the worker ahead of the main thread while it
    // has room, the main thread when it would otherwise wait. A block is
    // claimed first (`next_block`), then published in its slot.
    const std::uint64_t nb_slots = R / kRingBlock;
    std::unique_ptr<std::atomic<std::uint64_t>[]> slot_holds(new std::atomic<std::uint64_t>[nb_slots]);  // 1 + its block's b0; 0: none
    for (std::uint64_t k = 0; k < nb_slots; ++k) slot_holds[k].store(0, std::memory_order_relaxed);
    alignas(64) std::atomic<std::uint64_t> next_block{0};  // b0 of the first block nobody has claimed
    std::atomic<float> feature_max{0.0f};                  // the largest |coordinate| of the blocks published so far
    constexpr std::uint64_t kNone = std::numeric_limits<std::uint64_t>::max();
    std::atomic<std::uint64_t> failed_at{kNone};  // b0 of the first block found invalid
    std::mutex error_mutex;
    std::string error;  // (its message)
    auto claim = [&](std::uint64_t b0) { return next_block.compare_exchange_strong(b0, b0 + kRingBlock, std::memory_order_relaxed); };
    auto produce = [&](std::uint64_t b0, BlockScratch &scratch) {
        const std::uint64_t end = std::min(N, b0 + kRingBlock), r0 = b0 & (R - 1);
        float m = 0.0f;
        std::string bad;
        if (!extract_block(*src.in, ord.p, b0, end, P, Resampling::Fast, ring_direct.data() + r0 * P * 3, nullptr,
                           ring_geom.data() + r0 * Features::kGeom, scratch, m, bad)) {
            const std::lock_guard<std::mutex> lock(error_mutex);
            if (b0 < failed_at.load(std::memory_order_relaxed)) {
                error = bad;
                failed_at.store(b0, std::memory_order_release);
            }
            return false;
        }
        for (std::uint64_t r = r0; r < r0 + (end - b0); ++r)
            reverse_block(ring_direct.data() + r * P * 3, P, ring_flipped.data() + r * P * 3);
        float cur = feature_max.load(std::memory_order_relaxed);
        while (m > cur && !feature_max.compare_exchange_weak(cur, m, std::memory_order_relaxed)) {}
        slot_holds[(b0 / kRingBlock) % nb_slots].store(b0 + 1, std::memory_order_release);
        return true;
    };

    const bool threaded = src.threads >= 2 && L >= 2 && N >= 20000;
    std::thread worker;
    if (threaded) {
        worker = std::thread([&] {
            Lane worker_lane;
            worker_lane.fg.resize(3 * P + kTail);
            worker_lane.lb = main_lane.lb;
            BlockScratch block_scratch;
            std::uint64_t it = 0;
            while (it < N) {
                // Blocks ahead, into rows of steps before `it` (which the
                // main thread has passed too).
                while (streamed && !stop.load(std::memory_order_relaxed) && failed_at.load(std::memory_order_relaxed) == kNone) {
                    const std::uint64_t b0 = next_block.load(std::memory_order_relaxed);
                    if (b0 >= N || b0 + kRingBlock > it + R || published.load(std::memory_order_relaxed) > it + kProduceLag) break;
                    if (claim(b0) && !produce(b0, block_scratch)) break;
                }
                const std::uint64_t avail = published.load(std::memory_order_acquire);
                if (avail == it) {
                    if (stop.load(std::memory_order_acquire) && published.load(std::memory_order_acquire) == it) return;
                    std::this_thread::yield();
                    continue;
                }
                if (streamed) worker_lane.lb = bound(feature_max.load(std::memory_order_relaxed));
                // (At most a block at a time while blocks remain to be
                // computed, so that the worker computes them ahead.)
                const std::uint64_t until =
                    streamed && next_block.load(std::memory_order_relaxed) < N ? std::min(avail, it + kRingBlock) : avail;
                for (; it < until; ++it) {
                    const std::uint64_t h = handoff[it];
                    if (h == 0) continue;
                    load(worker_lane, it);
                    below(worker_lane, it, handoff_node(h), h & 1, store_b, kStageB);
                }
                replay(it, worker_lane.fg.data());
                done.store(it, std::memory_order_release);
            }
        });
    }
    // The worker's lag (streamlines published but not yet continued) above
    // which the main thread takes subtrees over, and below which it gives
    // them back.
    constexpr std::uint64_t kTakeLag = 1024, kGiveLag = 128;
    std::uint64_t worker_done = 0;  // `done`, as last read
    BlockScratch block_scratch;
    bool cancelled = false;
    std::exception_ptr failed;
    try {
        for (std::uint64_t it = 0; it < N; ++it) {
            if ((it & 1023) == 0) {
                if (cancel && cancel()) {
                    cancelled = true;
                    break;
                }
                if (progress) progress(double(it) / double(N));
            }
            if (streamed && it % kRingBlock == 0) {  // this block's features: published, or computed here
                if (threaded)
                    published.store(it, std::memory_order_release);  // (every step before `it` is handed off)
                else
                    replay(it, main_lane.fg.data());  // (every step before `it` is finished)
                std::atomic<std::uint64_t> &slot = slot_holds[(it / kRingBlock) % nb_slots];
                while (slot.load(std::memory_order_acquire) != it + 1) {
                    if (failed_at.load(std::memory_order_acquire) == it) {
                        const std::lock_guard<std::mutex> lock(error_mutex);
                        throw InputError(error);
                    }
                    const bool room = !threaded || it + kRingBlock <= R || done.load(std::memory_order_acquire) + R >= it + kRingBlock;
                    if (!(room && next_block.load(std::memory_order_relaxed) == it && claim(it) && produce(it, block_scratch)))
                        std::this_thread::yield();
                }
                main_lane.lb = bound(feature_max.load(std::memory_order_relaxed));
            }
            if ((it & 63) == 0 && threaded) worker_done = done.load(std::memory_order_acquire);
            load(main_lane, it);
            bool flip = false;
            Node *n1 = ops.search(root, main_lane.fd, main_lane.g, main_lane.geom, main_lane.lb, flip, store_a, 0, main_lane.scratch);
            ops.update(*n1, flip ? main_lane.g : main_lane.fd);
            path[it * L] = n1->uid;
            if (!threaded) {
                below(main_lane, it, n1, flip, store_a, 0);
                continue;
            }
            const std::uint64_t lag = it - worker_done;
            if (!n1->deep_main && lag > kTakeLag && worker_done >= n1->last_sent)
                n1->deep_main = true;
            else if (n1->deep_main && lag < kGiveLag)
                n1->deep_main = false;
            if (n1->deep_main) {
                below(main_lane, it, n1, flip, store_a, 0);
                handoff[it] = 0;
            } else {
                handoff[it] = handoff_word(n1, flip);
                n1->last_sent = it + 1;
            }
            if ((it & 63) == 63) published.store(it + 1, std::memory_order_release);
        }
    } catch (...) {  // (an invalid streamline, found as its features were computed)
        failed = std::current_exception();
    }
    if (threaded) {
        if (!cancelled && !failed) published.store(N, std::memory_order_release);
        stop.store(true, std::memory_order_release);
        worker.join();
    }
    if (failed) std::rethrow_exception(failed);
    if (cancelled) throw Cancelled{};
    replay(N, main_lane.fg.data());
    if (progress) progress(1.0);
    const Paths paths{path, L, N, ord, store_a, store_b};
    return flatten(root, L, t, P, &paths);
}

Tree RunQb(const Features &f, double T, const std::vector<std::uint64_t> &order, Mode mode, const CancelFn &cancel,
           const ProgressFn &progress) {
    return mode == Mode::Exact ? qb_impl<ExactMetric>(f, T, order, cancel, progress) : qb_impl<FastMetric>(f, T, order, cancel, progress);
}

Tree RunQbx(const Features &f, const std::vector<double> &t, const std::vector<std::uint64_t> &order, Mode mode, unsigned threads,
            const CancelFn &cancel, const ProgressFn &progress) {
    const Source src{&f, nullptr, f.nb_points, f.count, threads};
    return mode == Mode::Exact ? qbx_impl<ExactMetric>(src, t, order, cancel, progress)
                               : qbx_impl<FastMetric>(src, t, order, cancel, progress);
}

Tree RunQbxStreamed(const Input &in, std::uint32_t P, const std::vector<double> &t, const std::vector<std::uint64_t> &order,
                    unsigned threads, const CancelFn &cancel, const ProgressFn &progress) {
    return qbx_impl<FastMetric>(Source{nullptr, &in, P, in.nb_streamlines, threads}, t, order, cancel, progress);
}

}  // namespace HWY_NAMESPACE
}  // namespace qb::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace qb::detail {

HWY_EXPORT(RunQb);
HWY_EXPORT(RunQbx);
HWY_EXPORT(RunQbxStreamed);

Tree run_qb(const Features &f, double threshold, const std::vector<std::uint64_t> &order, Mode mode, const CancelFn &cancel,
            const ProgressFn &progress) {
    return HWY_DYNAMIC_DISPATCH(RunQb)(f, threshold, order, mode, cancel, progress);
}

Tree run_qbx(const Features &f, const std::vector<double> &thresholds, const std::vector<std::uint64_t> &order, Mode mode, unsigned threads,
             const CancelFn &cancel, const ProgressFn &progress) {
    return HWY_DYNAMIC_DISPATCH(RunQbx)(f, thresholds, order, mode, threads, cancel, progress);
}

Tree run_qbx_streamed(const Input &in, std::uint32_t P, const std::vector<double> &thresholds, const std::vector<std::uint64_t> &order,
                      unsigned threads, const CancelFn &cancel, const ProgressFn &progress) {
    return HWY_DYNAMIC_DISPATCH(RunQbxStreamed)(in, P, thresholds, order, threads, cancel, progress);
}

}  // namespace qb::detail
#endif  // HWY_ONCE
