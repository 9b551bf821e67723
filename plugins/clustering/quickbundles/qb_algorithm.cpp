// QuickBundles / QuickBundlesX with DIPY 1.6's exact arithmetic.
// Garyfallidis et al. 2012, "QuickBundles, a method for tractography
// simplification"; Garyfallidis et al. 2016, "QuickBundlesX: sequential
// clustering of millions of streamlines in multiple levels of detail".
// Every cast below mirrors a float32/double boundary in DIPY's Cython code;
// this file is compiled with -ffp-contract=off (no fused multiply-adds).
#include "qb_algorithm.hpp"

#include <algorithm>
#include <atomic>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <limits>
#include <thread>
#include <deque>
#include <unordered_map>

namespace qb {

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#  define QB_SEG_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#  define QB_SEG_CLONES
#endif

namespace {

// DIPY's c_set_number_of_points walk (DIPY-QBX.md section 3.2) over the
// cumulative arc lengths arc[0..n): arc[k] is the same sum, in the same
// order, that DIPY accumulates as it walks, so the output is bitwise the
// same; the serial additions are done once, beforehand, and the walk itself
// only compares. at(k) = the k-th point. A zero-length polyline gives
// copies of its last point, where DIPY reads uninitialised memory.
template <class At>
void walk_arcs(std::uint64_t n, std::uint32_t P, const double *arc, At at, float *out) {
    const double L = arc[n - 1];
    if (!(L > 0.0)) {
        for (std::uint32_t i = 0; i < P; ++i)
            for (int d = 0; d < 3; ++d) out[3 * i + d] = at(n - 1)[d];
        return;
    }
    const double step = L / static_cast<double>(P - 1);
    double t = 0.0;
    std::uint32_t i = 0;
    std::uint64_t k = 0;
    while (t < L && i < P) {
        while (t > arc[k]) ++k;  // DIPY's "else: k++" steps (t < L = arc[n-1] bounds k)
        if (t == arc[k]) {
            for (int d = 0; d < 3; ++d) out[3 * i + d] = at(k)[d];
            ++k;
        } else {
            const double ratio = 1.0 - ((arc[k] - t) / (arc[k] - arc[k - 1]));
            const float *a = at(k - 1), *b = at(k);
            for (int d = 0; d < 3; ++d)
                out[3 * i + d] = static_cast<float>(static_cast<double>(a[d]) +
                                                    ratio * static_cast<double>(static_cast<float>(b[d] - a[d])));
        }
        t += step;
        ++i;
    }
    for (int d = 0; d < 3; ++d) out[3 * (P - 1) + d] = at(n - 1)[d];
}

}  // namespace

QB_SEG_CLONES
void segment_lengths(const float *p, std::uint64_t n, double *seg) {  // |p[i] - p[i-1]|, DIPY's c_arclengths
    for (std::uint64_t i = 1; i < n; ++i) {
        const double dx = static_cast<float>(p[3 * i] - p[3 * i - 3]);
        const double dy = static_cast<float>(p[3 * i + 1] - p[3 * i - 2]);
        const double dz = static_cast<float>(p[3 * i + 2] - p[3 * i - 1]);
        seg[i] = std::sqrt(((0.0 + dx * dx) + dy * dy) + dz * dz);
    }
}

double resample_both(const float *p, std::uint64_t n, std::uint32_t P, float *fwd, float *rev, std::vector<double> &scratch) {
    // Each segment's length once: the reversed polyline's float differences
    // are the exact negations of the forward ones, so its segment i is the
    // forward segment n - i, bit for bit. Only the summation order differs.
    scratch.resize(3 * n);
    double *seg = scratch.data(), *arc = seg + n, *arc_r = arc + n;
    segment_lengths(p, n, seg);
    arc[0] = arc_r[0] = 0.0;
    if (rev != nullptr) {
        double a = 0.0, b = 0.0;  // two independent chains, one loop
        for (std::uint64_t i = 1; i < n; ++i) {
            arc[i] = a += seg[i];
            arc_r[i] = b += seg[n - i];
        }
    } else {
        double a = 0.0;
        for (std::uint64_t i = 1; i < n; ++i) arc[i] = a += seg[i];
    }
    walk_arcs(n, P, arc, [&](std::uint64_t k) { return p + 3 * k; }, fwd);
    if (rev != nullptr) walk_arcs(n, P, arc_r, [&](std::uint64_t k) { return p + 3 * (n - 1 - k); }, rev);
    return arc[n - 1];
}

double mdf_direct(const float *a, const float *b, std::uint32_t P) {
    double sum = 0.0;
    for (std::uint32_t n = 0; n < P; ++n) {
        double q = 0.0;
        for (int d = 0; d < 3; ++d) {
            const double dd = static_cast<double>(static_cast<float>(a[3 * n + d] - b[3 * n + d]));
            q += dd * dd;
        }
        sum += std::sqrt(q);
    }
    return sum / static_cast<double>(P);
}

Features extract_features(const Input &in, std::uint32_t P, unsigned threads, const CancelFn &cancel, bool exact_flip) {
    Features f;
    f.nb_points = P;
    const std::uint64_t N = in.nb_streamlines;
    f.direct.resize(N * P * 3);
    if (exact_flip) f.flipped.resize(N * P * 3);
    threads = std::max(1u, std::min<unsigned>(threads, static_cast<unsigned>(std::max<std::uint64_t>(1, N / 4096))));
    std::vector<std::thread> pool;
    std::atomic<bool> stop{false};
    std::vector<std::string> errors(threads);
    // Each worker validates its streamlines (non-empty, finite) while it
    // resamples them: one pass over the input.
    auto work = [&](unsigned w, std::uint64_t begin, std::uint64_t end) {
        std::vector<double> seg;  // segment lengths, reused across streamlines
        for (std::uint64_t s = begin; s < end && !stop; ++s) {
            if (w == 0 && (s & 4095) == 0 && cancel && cancel()) stop = true;
            const float *p = in.positions + 3 * in.offsets[s];
            const std::uint64_t n = in.offsets[s + 1] > in.offsets[s] ? in.offsets[s + 1] - in.offsets[s] : 0;
            if (n == 0) {
                errors[w] = "streamline " + std::to_string(s) + " has no points (remove empty streamlines before clustering)";
                stop = true;
                break;
            }
            float *fd = &f.direct[s * P * 3], *fg = exact_flip ? &f.flipped[s * P * 3] : nullptr;
            // DIPY resamples the reversed polyline for the flipped features.
            // A non-finite coordinate makes the length non-finite, so the
            // coordinates are only searched then (or for a single point).
            const double L = resample_both(p, n, P, fd, fg, seg);
            if (!std::isfinite(L) || n == 1)
                for (std::uint64_t v = 0; v < 3 * n; ++v)
                    if (!std::isfinite(p[v])) {
                        errors[w] = "streamline " + std::to_string(s) + " has a non-finite coordinate at vertex " +
                                    std::to_string(in.offsets[s] + v / 3);
                        stop = true;
                        break;
                    }
            if (stop) break;
        }
    };
    const std::uint64_t chunk = (N + threads - 1) / threads;
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, t, std::min(N, t * chunk), std::min(N, (t + 1) * chunk));
    work(0, 0, std::min(N, chunk));  // the calling thread polls cancellation
    for (auto &th : pool) th.join();
    for (const auto &e : errors)
        if (!e.empty()) throw InputError(e);
    if (stop) throw Cancelled{};
    return f;
}

Features identity_features(const float *points, std::uint64_t n, std::uint32_t P) {
    Features f;
    f.nb_points = P;
    f.direct.assign(points, points + n * P * 3);
    return f;
}

namespace {

// mdf_direct(a, b) when it can beat `bound`, +inf when it cannot. The partial
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
            const float *pa = a + 3 * (n + j), *pb = b + 3 * (n + j);
            const double dx = static_cast<float>(pa[0] - pb[0]);
            const double dy = static_cast<float>(pa[1] - pb[1]);
            const double dz = static_cast<float>(pa[2] - pb[2]);
            r[j] = std::sqrt(((0.0 + dx * dx) + dy * dy) + dz * dz);
        }
        for (std::uint32_t j = 0; j < m; ++j) sum += r[j];
        n += m;
        if (n < P && sum >= stop_sum) return std::numeric_limits<double>::infinity();
    }
    return sum / static_cast<double>(P);
}

// Fast mode: the same MDF in float32, blocks of 4 points whose squared
// differences and square roots the compiler vectorises; early exit as above
// (after the first block, a wrongly oriented candidate usually stops).
inline double mdf_fast(const float *a, const float *b, std::uint32_t P, double bound) {
    const double stop_sum = bound * static_cast<double>(P);
    float sum = 0.0f;
    std::uint32_t n = 0;
    for (; n + 4 <= P; n += 4) {
        float sq[12], r[4];
        const float *pa = a + 3 * n, *pb = b + 3 * n;
        for (int i = 0; i < 12; ++i) {
            const float t = pa[i] - pb[i];
            sq[i] = t * t;
        }
        for (int j = 0; j < 4; ++j) r[j] = std::sqrt(sq[3 * j] + sq[3 * j + 1] + sq[3 * j + 2]);
        sum += (r[0] + r[1]) + (r[2] + r[3]);
        if (n + 4 < P && double(sum) >= stop_sum) return std::numeric_limits<double>::infinity();
    }
    for (; n < P; ++n) {
        const float *pa = a + 3 * n, *pb = b + 3 * n;
        const float x = pa[0] - pb[0], y = pa[1] - pb[1], z = pa[2] - pb[2];
        sum += std::sqrt(x * x + y * y + z * z);
    }
    return double(sum) / double(P);
}

struct ExactMetric {
    static double dist(const float *a, const float *b, std::uint32_t P, double bound) { return mdf_below(a, b, P, bound); }
    static constexpr double kBoundFactor = 1.0 - 1e-7;  // DIPY's value vs the real MDF
};
struct FastMetric {
    static double dist(const float *a, const float *b, std::uint32_t P, double bound) { return mdf_fast(a, b, P, bound); }
    static constexpr double kBoundFactor = 1.0 - 1e-5;  // float32 sums of up to 1000 terms
};

// C = ((C * (float)size) + e) / (float)(size + 1), in float32, as DIPY.
inline void update_centroid(float *c, std::uint64_t size, const float *e, std::uint32_t P) {
    const float fs = static_cast<float>(size), fs1 = static_cast<float>(size + 1);
    for (std::uint32_t i = 0; i < 3 * P; ++i) c[i] = ((c[i] * fs) + e[i]) / fs1;
}


void check_order(const std::vector<std::uint64_t> &order, std::uint64_t N) {
    if (order.size() != N) throw InputError("ordering has " + std::to_string(order.size()) + " entries for " + std::to_string(N) + " streamlines");
    std::vector<bool> seen(N, false);
    for (auto i : order) {
        if (i >= N || seen[i]) throw InputError("ordering is not a permutation of the streamline indices");
        seen[i] = true;
    }
}

struct Node {
    // Written by the stage that updates this node (the one that searched
    // its parent's children) ...
    Node *parent = nullptr;
    std::uint32_t level = 0;
    std::uint32_t slot = 0;  // this node's index in its parent's kids
    double threshold = 0;  // used to split its children
    std::vector<float> c;
    std::uint64_t size = 0;
    std::vector<std::uint64_t> indices;  // QB's members (QBX records paths instead)
    std::uint32_t uid = 0;  // QBX: which stage's store holds it, and where
    std::uint64_t out = 0;  // its position in the flattened tree
    // ... and by the stage that searches its children: on a cache line of
    // their own, so that the two pipeline stages never share one.
    // What the search needs of each child, contiguous (the hot loop of QBX):
    // its centroid's AABB and mean point, refreshed when the child changes.
    struct Kid {
        float box_c[3], box_r[3];
    };
    alignas(64) std::vector<Node *> children;  // creation order
    std::vector<Kid> kids;  // parallel to `children`
    std::vector<float> mx, my, mz;  // the children's mean points, one array per axis
    char pad_[64];
};

// A rigorous lower bound on the distance DIPY computes, from mean points.
// By the triangle inequality, the real-valued MDF is at least the distance
// between the two mean points. DIPY's value differs from the real one only
// by the float32 rounding of each coordinate difference (relative 2^-24)
// and double roundings. The mean points are computed in double and stored
// as float32 (absolute error below `slack` in all), and their squared
// distance q is computed in float32 (relative error below 2^-21). So
// mdf >= (sqrt(q / (1 + 2^-21)) - slack) * (1 - 1e-7): when that is already
// >= the bound a candidate must beat, computing its MDF cannot change the
// result, and it is skipped.
struct LowerBound {
    double slack = 0;
    double factor = 1.0 - 1e-7;
    void prepare(const Features &f) {
        float m = 0;
        for (float v : f.direct) m = std::max(m, std::fabs(v));
        slack = 4e-12 * double(m) * double(std::max<std::uint32_t>(f.nb_points, 1)) + 0x1p-21 * double(m) + 1e-300;
    }
    static void mean(const float *x, std::uint32_t P, float out[3]) {
        double s[3] = {0, 0, 0};
        for (std::uint32_t i = 0; i < P; ++i)
            for (int d = 0; d < 3; ++d) s[d] += x[3 * i + d];
        for (int d = 0; d < 3; ++d) out[d] = static_cast<float>(s[d] / P);
    }
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

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#  define QB_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#  define QB_SIMD_CLONES
#endif

// Squared float32 distances from the mean points (mx, my, mz)[0..K) to `a`
// and to `b`: every candidate's lower bound at once, a plain loop the
// compiler vectorises at the width of the clone picked at load time.
// Returns the smallest of them (the bit patterns of non-negative floats
// order as integers, which keeps the reduction vectorisable).
QB_SIMD_CLONES
float screen(std::size_t K, const float *mx, const float *my, const float *mz, const float a[3], const float b[3], float *la,
             float *lb) {
    std::int32_t mn = 0x7f800000;  // +inf
    const float ax = a[0], ay = a[1], az = a[2], bx = b[0], by = b[1], bz = b[2];
    for (std::size_t k = 0; k < K; ++k) {
        const float dx = mx[k] - ax, dy = my[k] - ay, dz = mz[k] - az;
        const float ex = mx[k] - bx, ey = my[k] - by, ez = mz[k] - bz;
        const float qa = dx * dx + dy * dy + dz * dz, qb = ex * ex + ey * ey + ez * ez;
        la[k] = qa;
        lb[k] = qb;
        std::int32_t ia, ib;
        std::memcpy(&ia, &qa, 4);
        std::memcpy(&ib, &qb, 4);
        mn = std::min(mn, std::min(ia, ib));
    }
    float r;
    std::memcpy(&r, &mn, 4);
    return r;
}

// AABB(X): per axis min/max (float32), r = (mx - mn) / 2, c = mn + r.
inline void aabb(const float *x, std::uint32_t P, float c[3], float r[3]) {
    for (int d = 0; d < 3; ++d) {
        float mn = x[d], mx = x[d];
        for (std::uint32_t i = 1; i < P; ++i) {
            mn = std::min(mn, x[3 * i + d]);
            mx = std::max(mx, x[3 * i + d]);
        }
        r[d] = (mx - mn) / 2.0f;
        c[d] = mn + r[d];
    }
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
    if constexpr (F32) return next_float(static_cast<float>(v));
    else return std::nextafter(v, std::numeric_limits<double>::infinity());
}

// The candidates of one search: K clusters, each in two orientations, with
// their lower bounds (la: direct, lb: flipped) and their positions in
// DIPY's scan order. QBX scans child 0 direct, child 0 flipped, child 1
// direct, ... (key 2k + flip); QB scans every cluster direct, then every
// cluster flipped (key flip K + k).
struct Candidates {
    std::size_t K = 0;
    const float *la = nullptr, *lb = nullptr;
    float min_lb = 0;  // the smallest of them
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
std::int64_t best_first(const Candidates &cs, const float *fd, const float *fg, double cap, const LowerBound &lbound,
                        std::uint32_t P, Centroid centroid, Tested tested, double &best_out) {
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
        if ((cs.la[k] < lim || all) && (k != first || first_flip)) [[unlikely]] consider(k, false);
        if ((cs.lb[k] < lim || all) && (k != first || !first_flip)) [[unlikely]] consider(k, true);
    }
    best_out = best;
    return key;
}

// Flattens nodes into the ABI layout: by level, DFS pre-order within a level.
// QBX's members, recorded per streamline rather than per node: the node
// that processing step `it` joined at level l (1..L) is node(path[it * L + l - 1]).
struct Paths {
    const std::vector<std::uint32_t> &path;
    std::uint32_t L;
    const std::vector<std::uint64_t> &order;
    const std::deque<Node> &store_a, &store_b;  // uid = index in A's store, or kStageB | index in B's
    static constexpr std::uint32_t kStageB = 0x80000000u;
    const Node &node(std::uint32_t uid) const { return uid & kStageB ? store_b[uid & ~kStageB] : store_a[uid]; }
};

Tree flatten(const Node &root, std::uint32_t levels, const std::vector<double> &thresholds, std::uint32_t P,
             const Paths *paths = nullptr) {
    std::vector<const Node *> dfs;
    std::vector<const Node *> stack = {&root};
    while (!stack.empty()) {
        const Node *k = stack.back();
        stack.pop_back();
        dfs.push_back(k);
        for (auto it = k->children.rbegin(); it != k->children.rend(); ++it) stack.push_back(*it);
    }
    std::vector<const Node *> order;  // output order: by level, DFS within a level
    for (std::uint32_t l = 0; l <= levels; ++l)
        for (auto k : dfs)
            if (k->level == l) order.push_back(k);
    Tree t;
    t.thresholds = thresholds;
    t.nb_points = P;
    t.member_offsets.reserve(order.size() + 1);
    t.member_offsets.push_back(0);
    for (std::size_t i = 0; i < order.size(); ++i) {
        const Node *k = order[i];
        const_cast<Node *>(k)->out = i;
        t.parent.push_back(k->parent ? static_cast<std::int64_t>(k->parent->out) : -1);
        t.level.push_back(k->level);
        t.centroids.insert(t.centroids.end(), k->c.begin(), k->c.end());
        t.member_offsets.push_back(t.member_offsets.back() + k->size);
    }
    if (paths == nullptr) {
        t.members.reserve(t.member_offsets.back());
        for (auto k : order) t.members.insert(t.members.end(), k->indices.begin(), k->indices.end());
    } else {
        // Every node's members in processing order, scattered level by
        // level (the levels' ranges are disjoint: one thread each, two at once).
        t.members.resize(t.member_offsets.back());
        std::copy(paths->order.begin(), paths->order.end(), t.members.begin());  // the root
        const std::uint64_t N = paths->order.size();
        const std::uint32_t L = paths->L;
        auto scatter = [&](std::uint32_t l) {
            std::vector<std::uint64_t> cursor(t.member_offsets.begin(), t.member_offsets.end() - 1);
            for (std::uint64_t it = 0; it < N; ++it) t.members[cursor[paths->node(paths->path[it * L + l]).out]++] = paths->order[it];
        };
        std::thread helper;
        if (L >= 2 && N >= 100000)
            helper = std::thread([&] {
                for (std::uint32_t l = 1; l < L; l += 2) scatter(l);
            });
        for (std::uint32_t l = 0; l < L; l += helper.joinable() ? 2 : 1) scatter(l);
        if (helper.joinable()) helper.join();
    }
    return t;
}

}  // namespace

template <class Metric>
Tree qb_impl(const Features &f, double T, const std::vector<std::uint64_t> &order, const CancelFn &cancel, const ProgressFn &progress) {
    const std::uint32_t P = f.nb_points;
    const std::uint64_t N = f.direct.size() / (3 * std::max<std::uint32_t>(P, 1));
    check_order(order, N);
    std::vector<float> C;  // K x P x 3
    std::vector<float> mx, my, mz, la, lb, fg_buf(3 * P);  // the clusters' mean points; scratch
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
        const std::uint64_t idx = order[it];
        const float *fd = &f.direct[idx * P * 3], *fg = flipped_of(f, idx, fg_buf.data());
        float mf[3], mg[3];
        LowerBound::mean(fd, P, mf);
        LowerBound::mean(fg, P, mg);
        const std::uint64_t K = sizes.size();
        la.resize(K);
        lb.resize(K);
        Candidates cs;
        cs.K = K;
        cs.la = la.data();
        cs.lb = lb.data();
        cs.interleaved = false;
        cs.min_lb = screen(K, mx.data(), my.data(), mz.data(), mf, mg, la.data(), lb.data());
        auto centroid = [&](std::size_t k) { return &C[k * P * 3]; };
        auto all = [](std::size_t) { return true; };
        double d = 0;
        std::int64_t key = best_first<Metric, false>(cs, fd, fg, T, lbound, P, centroid, all, d);
        if (key < 0 || !(d < T))  // a new cluster, seeded in the nearest one's orientation
            key = best_first<Metric, false>(cs, fd, fg, std::numeric_limits<double>::infinity(), lbound, P, centroid, all, d);
        const bool use_g = key >= 0 && static_cast<std::uint64_t>(key) >= K;
        std::uint64_t k = key < 0 ? 0 : (use_g ? key - K : key);
        const float *e = use_g ? fg : fd;
        if (key < 0 || !(d < T)) {  // join iff d < T (strict)
            k = K;
            C.resize(C.size() + P * 3, 0.0f);
            mx.push_back(0);
            my.push_back(0);
            mz.push_back(0);
            sizes.push_back(0);
            indices.emplace_back();
        }
        update_centroid(&C[k * P * 3], sizes[k], e, P);
        float m[3];
        LowerBound::mean(&C[k * P * 3], P, m);
        mx[k] = m[0];
        my[k] = m[1];
        mz[k] = m[2];
        ++sizes[k];
        indices[k].push_back(idx);
    }
    // Root: every streamline in processing order, mean of the oriented features.
    std::deque<Node> nodes(1);
    nodes[0].threshold = T;
    nodes[0].c.assign(P * 3, 0.0f);
    for (std::uint64_t k = 0; k < sizes.size(); ++k) {
        Node &n = nodes.emplace_back();
        n.parent = &nodes[0];
        n.level = 1;
        n.c.assign(C.begin() + k * P * 3, C.begin() + (k + 1) * P * 3);
        n.size = sizes[k];
        n.indices = std::move(indices[k]);
        nodes[0].children.push_back(&n);
    }
    nodes[0].indices = order;
    nodes[0].size = N;
    // Root centroid: size-weighted mean of the clusters (float64, then float32).
    for (std::uint32_t i = 0; i < P * 3; ++i) {
        double acc = 0;
        for (std::size_t k = 1; k < nodes.size(); ++k) acc += double(nodes[k].c[i]) * double(nodes[k].size);
        nodes[0].c[i] = N ? static_cast<float>(acc / double(N)) : 0.0f;
    }
    if (progress) progress(1.0);
    return flatten(nodes[0], 1, {T}, P);
}

// The two halves of one QBX step at node `n` (DIPY-QBX.md section 3.5).
template <class Metric>
struct QbxOps {
    std::uint32_t P, L;
    const std::vector<double> &t;
    const LowerBound &lbound;

    // n.C = ((n.C * size) + e) / (size + 1); refresh n's record in its parent.
    void update(Node &n, const float *e) const {
        Node::Kid &me = n.parent->kids[n.slot];
        float m[3];
        update_centroid(n.c.data(), n.size, e, P);
        aabb(n.c.data(), P, me.box_c, me.box_r);
        LowerBound::mean(n.c.data(), P, m);
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
    Node *search(Node &n, const float *fd, const float *fg, const float bc[3], const float br[3], const float mf[3],
                 const float mg[3], bool &flip_out, std::deque<Node> &store, std::uint32_t tag, std::vector<float> &scratch) const {
        const std::size_t K = n.kids.size();
        scratch.resize(2 * K);
        Candidates cs;
        cs.K = K;
        cs.la = scratch.data();
        cs.lb = scratch.data() + K;
        cs.min_lb = screen(K, n.mx.data(), n.my.data(), n.mz.data(), mf, mg, scratch.data(), scratch.data() + K);
        const float pad = static_cast<float>(n.threshold);
        auto tested = [&](std::size_t k) {
            const Node::Kid &ch = n.kids[k];
            return std::fabs(ch.box_c[0] - bc[0]) <= ch.box_r[0] + br[0] + pad &&
                   std::fabs(ch.box_c[1] - bc[1]) <= ch.box_r[1] + br[1] + pad &&
                   std::fabs(ch.box_c[2] - bc[2]) <= ch.box_r[2] + br[2] + pad;
        };
        auto centroid = [&](std::size_t k) { return n.children[k]->c.data(); };
        // Children farther than the threshold only matter when none is
        // within it: then DIPY seeds the new child with the orientation of
        // the nearest one, which the second, uncapped search finds.
        double best = 0;
        std::int64_t key = best_first<Metric, true>(cs, fd, fg, next_up<true>(n.threshold), lbound, P, centroid, tested, best);
        std::int64_t kid;
        bool flip;
        if (key >= 0 && best <= n.threshold) {  // join iff dist <= threshold (non-strict)
            kid = key / 2;
            flip = key & 1;
        } else {
            key = best_first<Metric, true>(cs, fd, fg, std::numeric_limits<double>::infinity(), lbound, P, centroid, tested, best);
            flip = key >= 0 && (key & 1);
            Node &c = store.emplace_back();
            c.uid = tag | static_cast<std::uint32_t>(store.size() - 1);
            c.parent = &n;
            c.level = n.level + 1;
            c.threshold = c.level < L ? t[c.level] : 0.0;
            c.c.assign(P * 3, 0.0f);
            kid = static_cast<std::int64_t>(n.children.size());
            c.slot = static_cast<std::uint32_t>(kid);
            n.children.push_back(&c);
            n.kids.push_back({});
            n.mx.push_back(0);
            n.my.push_back(0);
            n.mz.push_back(0);
        }
        flip_out = flip;
        return n.children[static_cast<std::size_t>(kid)];
    }
};

// QuickBundlesX as a two-stage pipeline computing exactly what the
// sequential algorithm computes. Stage A (calling thread) searches the
// root's children and updates the chosen level-1 node; stage B (a worker)
// continues below it. Level-1 decisions depend only on level-1 centroids
// (stage A's), deeper ones only on the nodes below (stage B's). The one
// coupling across streamlines, DIPY's orientation of the root update by the
// previous streamline's leaf flip, touches only the root centroid, which no
// search reads: it is replayed once both stages are done.
template <class Metric>
Tree qbx_impl(const Features &f, const std::vector<double> &t, const std::vector<std::uint64_t> &order, const CancelFn &cancel,
              const ProgressFn &progress) {
    const std::uint32_t P = f.nb_points;
    const std::uint64_t N = f.direct.size() / (3 * std::max<std::uint32_t>(P, 1));
    const std::uint32_t L = static_cast<std::uint32_t>(t.size());
    if (L == 0) throw InputError("QuickBundlesX needs at least one threshold");
    check_order(order, N);
    std::deque<Node> store_a, store_b;  // each stage's nodes (stable addresses)
    Node &root = store_a.emplace_back();
    root.threshold = t[0];
    root.c.assign(P * 3, 0.0f);
    LowerBound lbound;
    lbound.prepare(f);
    lbound.factor = Metric::kBoundFactor;
    const QbxOps<Metric> ops{P, L, t, lbound};

    struct Handoff {
        Node *node;
        bool flip;
    };
    std::vector<Handoff> handoff(N);
    std::vector<std::uint8_t> leaf_flip(N, 0);
    std::vector<std::uint32_t> path(N * L);  // each step's node per level
    constexpr std::uint32_t kStageB = Paths::kStageB;  // uid tag of stage B's nodes
    std::atomic<std::uint64_t> published{0};
    std::atomic<bool> stop{false};

    struct Geometry {
        const float *fd, *fg;
        float bc[3], br[3];
        float mf[3], mg[3];
    };
    std::vector<float> fg_a(3 * P), fg_b(3 * P), fg_r(3 * P);  // each stage's flipped features
    auto geometry = [&](std::uint64_t idx, float *fg_buf) {
        Geometry g;
        g.fd = &f.direct[idx * P * 3];
        g.fg = flipped_of(f, idx, fg_buf);
        aabb(g.fd, P, g.bc, g.br);
        LowerBound::mean(g.fd, P, g.mf);
        LowerBound::mean(g.fg, P, g.mg);
        return g;
    };
    std::vector<float> scratch_a, scratch_b;  // each stage's lower bounds
    auto stage_a = [&](std::uint64_t it) {
        const Geometry g = geometry(order[it], fg_a.data());
        bool flip = false;
        Node *n1 = ops.search(root, g.fd, g.fg, g.bc, g.br, g.mf, g.mg, flip, store_a, 0, scratch_a);
        ops.update(*n1, flip ? g.fg : g.fd);
        path[it * L] = n1->uid;
        handoff[it] = {n1, flip};
    };
    auto stage_b = [&](std::uint64_t it) {
        Node *node = handoff[it].node;
        bool flip = handoff[it].flip;
        if (node->level < L) {
            const Geometry g = geometry(order[it], fg_b.data());
            while (node->level < L) {
                bool next_flip = false;
                Node *child = ops.search(*node, g.fd, g.fg, g.bc, g.br, g.mf, g.mg, next_flip, store_b, kStageB, scratch_b);
                ops.update(*child, next_flip ? g.fg : g.fd);
                path[it * L + child->level - 1] = child->uid;
                node = child;
                flip = next_flip;
            }
        }
        leaf_flip[it] = flip;
    };

    const bool threaded = L >= 2 && N >= 20000;
    std::thread worker;
    if (threaded) {
        worker = std::thread([&] {
            std::uint64_t it = 0;
            while (it < N) {
                const std::uint64_t avail = published.load(std::memory_order_acquire);
                if (avail == it) {
                    if (stop.load(std::memory_order_acquire) && published.load(std::memory_order_acquire) == it) return;
                    std::this_thread::yield();
                    continue;
                }
                for (; it < avail; ++it) stage_b(it);
            }
        });
    }
    bool cancelled = false;
    for (std::uint64_t it = 0; it < N; ++it) {
        if ((it & 1023) == 0) {
            if (cancel && cancel()) {
                cancelled = true;
                break;
            }
            if (progress) progress(double(it) / double(N));
        }
        stage_a(it);
        if (!threaded) stage_b(it);
        else if ((it & 63) == 63) published.store(it + 1, std::memory_order_release);
    }
    if (threaded) {
        if (!cancelled) published.store(N, std::memory_order_release);
        stop.store(true, std::memory_order_release);
        worker.join();
    }
    if (cancelled) throw Cancelled{};
    // Replay the root: every streamline, oriented by the previous one's leaf flip.
    bool use_flip = false;
    for (std::uint64_t it = 0; it < N; ++it) {
        const std::uint64_t idx = order[it];
        update_centroid(root.c.data(), root.size, use_flip ? flipped_of(f, idx, fg_r.data()) : &f.direct[idx * P * 3], P);
        ++root.size;
        use_flip = leaf_flip[it];
    }
    if (progress) progress(1.0);
    const Paths paths{path, L, order, store_a, store_b};
    return flatten(root, L, t, P, &paths);
}

Tree quickbundles(const Features &f, double T, const std::vector<std::uint64_t> &order, Mode mode, const CancelFn &cancel,
                  const ProgressFn &progress) {
    return mode == Mode::Exact ? qb_impl<ExactMetric>(f, T, order, cancel, progress)
                               : qb_impl<FastMetric>(f, T, order, cancel, progress);
}

Tree quickbundlesx(const Features &f, const std::vector<double> &t, const std::vector<std::uint64_t> &order, Mode mode,
                   const CancelFn &cancel, const ProgressFn &progress) {
    return mode == Mode::Exact ? qbx_impl<ExactMetric>(f, t, order, cancel, progress)
                               : qbx_impl<FastMetric>(f, t, order, cancel, progress);
}

Tree qbx_and_merge(const Input &in, const std::vector<double> &thresholds, std::uint32_t P, const std::vector<std::uint64_t> &order,
                   const std::vector<std::uint64_t> &merge_order, Mode mode, unsigned threads, const CancelFn &cancel,
                   const ProgressFn &progress) {
    if (thresholds.empty()) throw InputError("qbx_and_merge needs at least one threshold");
    // set_number_of_points(streamlines, P), then identity features.
    const Features resampled = extract_features(in, P, threads, cancel, false);
    const Features f = identity_features(resampled.direct.data(), in.nb_streamlines, P);
    const Tree qbx = quickbundlesx(f, thresholds, order, mode, cancel, progress);
    const std::uint32_t L = static_cast<std::uint32_t>(thresholds.size());
    std::vector<std::uint64_t> leaves;  // node ids of the last level, DFS order
    for (std::uint64_t k = 0; k < qbx.nb_nodes(); ++k)
        if (qbx.level[k] == L) leaves.push_back(k);
    const std::uint64_t K = leaves.size();
    std::vector<float> cents(K * P * 3);
    for (std::uint64_t i = 0; i < K; ++i)
        std::copy_n(&qbx.centroids[leaves[i] * P * 3], P * 3, &cents[i * P * 3]);
    const Features cf = identity_features(cents.data(), K, P);
    std::vector<std::uint64_t> morder = merge_order;
    if (morder.empty()) {
        morder.resize(K);
        for (std::uint64_t i = 0; i < K; ++i) morder[i] = i;
    }
    const Tree merged = quickbundlesx(cf, {thresholds.back()}, morder, mode, cancel, {});
    // Merged cluster: its centroid, and its members' streamlines concatenated
    // in merge-insertion order.
    Tree out;
    out.thresholds = {thresholds.back()};
    out.nb_points = P;
    out.parent.push_back(-1);
    out.level.push_back(0);
    out.centroids.insert(out.centroids.end(), qbx.centroids.begin(), qbx.centroids.begin() + P * 3);
    out.member_offsets = {0};
    out.members.assign(qbx.members.begin(), qbx.members.begin() + qbx.member_offsets[1]);
    out.member_offsets.push_back(out.members.size());
    for (std::uint64_t m = 1; m < merged.nb_nodes(); ++m) {
        out.parent.push_back(0);
        out.level.push_back(1);
        out.centroids.insert(out.centroids.end(), merged.centroids.begin() + m * P * 3, merged.centroids.begin() + (m + 1) * P * 3);
        for (std::uint64_t j = merged.member_offsets[m]; j < merged.member_offsets[m + 1]; ++j) {
            const std::uint64_t leaf = leaves[merged.members[j]];
            out.members.insert(out.members.end(), qbx.members.begin() + qbx.member_offsets[leaf],
                               qbx.members.begin() + qbx.member_offsets[leaf + 1]);
        }
        out.member_offsets.push_back(out.members.size());
    }
    return out;
}

}  // namespace qb
