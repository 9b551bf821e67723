// What qb_algorithm.cpp (shared code) and qb_search.cpp (the searches,
// compiled once per SIMD target by Highway) both need: the tree's nodes, the
// flattening into the ABI layout, and the entry points of the searches.
#pragma once

#include "parallel.hpp"  // hzio::resize_prefaulted (plugins/common)
#include "qb_algorithm.hpp"

#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

namespace qb::detail {

// AABB of a feature block: per axis min/max (float32), r = (max - min) / 2,
// c = min + r (DIPY's test, DIPY-QBX.md section 3.5).
inline void feature_box(const float *x, std::uint32_t P, float c[3], float r[3]) {
    for (int d = 0; d < 3; ++d) {
        const float *a = x + d * P;
        float mn = a[0], mx = a[0];
        for (std::uint32_t i = 1; i < P; ++i) {
            mn = a[i] < mn ? a[i] : mn;
            mx = a[i] > mx ? a[i] : mx;
        }
        r[d] = (mx - mn) / 2.0f;
        c[d] = mn + r[d];
    }
}

// Mean point of a feature block, summed in double in point order, stored
// as float32.
inline void feature_mean(const float *x, std::uint32_t P, float out[3]) {
    double s[3] = {0, 0, 0};
    for (int d = 0; d < 3; ++d)
        for (std::uint32_t i = 0; i < P; ++i) s[d] += x[d * P + i];
    for (int d = 0; d < 3; ++d) out[d] = static_cast<float>(s[d] / P);
}

// A QBX/QB tree node while the tree grows. A node's centroid lives in its
// parent's `kid_c` (the root's in `c`), so that a search reads one
// contiguous array of its candidates.
struct Node {
    // Set when the node is created, then only read (by both threads: the
    // worker reads a level-1 node's level and threshold for every streamline
    // it continues below it) ...
    Node *parent = nullptr;
    std::uint32_t level = 0;
    std::uint32_t slot = 0;  // this node's index in its parent's children
    double threshold = 0;    // used to split its children
    std::vector<float> c;    // the root's centroid (SoA, 3P + kTail floats)
    std::uint32_t uid = 0;   // QBX: which stage's store holds it, and where
    std::uint64_t out = 0;   // its position in the flattened tree (set by flatten)
    // ... written by the stage that updates this node (the one that searched
    // its parent's children), on a cache line of its own: for a level-1 node
    // that is the main thread, for every streamline joining it, while the
    // worker reads the fields above (they shared a line until 2026-11-25,
    // and each of those reads then missed) ...
    alignas(64) std::uint64_t size = 0;
    std::vector<std::uint64_t> indices;  // QB's members (QBX records paths instead)
    // QBX, level-1 nodes, main thread only: whether the main thread
    // continues below this node itself, and 1 + the last streamline it sent
    // the worker to continue below it.
    bool deep_main = false;
    std::uint64_t last_sent = 0;
    // ... and by the stage that searches its children: on a cache line of
    // their own, so that the two pipeline stages never share one.
    // What the search needs of each child, contiguous (the hot loop of QBX):
    // its centroid, its centroid's AABB and mean point, refreshed when the
    // child changes.
    struct Kid {
        float box_c[3], box_r[3];
    };
    alignas(64) std::vector<Node *> children;  // creation order
    std::vector<float> kid_c;                  // children's centroids, SoA blocks of 3P floats, then kTail
    std::vector<Kid> kids;                     // parallel to `children`
    std::vector<float> mx, my, mz;             // the children's mean points, one array per axis
    char pad_[64];

    const float *centroid(std::uint32_t P) const { return parent ? parent->kid_c.data() + std::size_t(slot) * 3 * P : c.data(); }
};

// A processing order as the searches read it: step it processes streamline
// order[it], where `order` is a permutation of 0..N-1 or, empty, file order
// (no array: a fresh process would be given its N words page by page).
struct Order {
    const std::uint64_t *p = nullptr;  // null: file order
    explicit Order(const std::vector<std::uint64_t> &order) : p(order.empty() ? nullptr : order.data()) {}
    std::uint64_t operator[](std::uint64_t it) const { return p ? p[it] : it; }
    // out[0..N) = the streamlines of steps 0..N-1 (a root's members).
    void copy(std::uint64_t N, std::uint64_t *out) const {
        for (std::uint64_t it = 0; it < N; ++it) out[it] = (*this)[it];
    }
};

// QBX's members, recorded per streamline rather than per node: the node
// that processing step `it` joined at level l (1..L) is node(path[it * L + l - 1]).
struct Paths {
    const std::vector<std::uint32_t> &path;
    std::uint32_t L;
    std::uint64_t N;
    Order order;
    const std::deque<Node> &store_a, &store_b;  // uid = index in A's store, or kStageB | index in B's
    static constexpr std::uint32_t kStageB = 0x80000000u;
    const Node &node(std::uint32_t uid) const { return uid & kStageB ? store_b[uid & ~kStageB] : store_a[uid]; }
};

// Flattens the tree into the ABI layout (by level, DFS pre-order within a
// level; centroids converted to xyz-interleaved). Members from the nodes'
// `indices`, or from `paths` when given.
Tree flatten(const Node &root, std::uint32_t levels, const std::vector<double> &thresholds, std::uint32_t P, const Paths *paths = nullptr);

// InputError unless `order` is empty (file order) or a permutation of 0..N-1.
void check_order(const std::vector<std::uint64_t> &order, std::uint64_t N);

// The searches (qb_search.cpp), dispatched to the best SIMD target of the
// CPU they run on.
Tree run_qb(const Features &f, double threshold, const std::vector<std::uint64_t> &order, Mode mode, const CancelFn &cancel,
            const ProgressFn &progress);
// threads: 1 runs QBX on the calling thread alone; more (the default)
// lets it use a second one (for at least 20 000 streamlines and 2 levels).
Tree run_qbx(const Features &f, const std::vector<double> &thresholds, const std::vector<std::uint64_t> &order, Mode mode, unsigned threads,
             const CancelFn &cancel, const ProgressFn &progress);

// Fast mode's resampling (qb_resample.cpp, also dispatched per SIMD
// target): for t in [begin, end), streamline s = idx[t] (idx NULL: s = t,
// each with 1 to 2^29 - 1 points) to P >= 2 points in float32, into
// direct + (t - begin) * P * 3 (per axis), and its Features::geom into
// geom + (t - begin) * kGeom (mean points summed in float32); its length,
// summed in double, into lengths[t - begin]; max_abs raised to the largest
// |coordinate| of the features. A streamline of zero or non-finite length
// gets P copies of its last point. `scratch` is the caller's, reused across
// calls (one per thread).
void resample_fast(const Input &in, const std::uint64_t *idx, std::uint64_t begin, std::uint64_t end, std::uint32_t P, float *direct,
                   float *geom, std::vector<float> &scratch, double *lengths, float &max_abs);

// One thread's buffers for extract_block, reused across calls.
struct BlockScratch {
    std::vector<double> seg;
    std::vector<float> points;
};

// The features of a block of streamlines, what extract_features does for
// all of them: for t in [begin, end), streamline s = idx[t] (idx NULL:
// s = t) resampled as `how` says into direct + (t - begin) * P * 3 (and its
// resampled reversal into flipped + (t - begin) * P * 3 for
// Resampling::Dipy; `flipped` is NULL otherwise), its Features::geom into
// geom + (t - begin) * kGeom; max_abs raised to the largest |coordinate|.
// Validates as it goes: returns false, with a one-line `error` naming the
// streamline (s), at the first one that is empty or has a non-finite
// coordinate; the features of the block are then incomplete.
bool extract_block(const Input &in, const std::uint64_t *idx, std::uint64_t begin, std::uint64_t end, std::uint32_t P, Resampling how,
                   float *direct, float *flipped, float *geom, BlockScratch &scratch, float &max_abs, std::string &error);

// Fast-mode QuickBundlesX straight from the streamlines: each one's
// features are computed when the search reaches it, into a ring of a few
// thousand streamlines that both search threads share, instead of an array
// of all of them (which a fresh process has to be given page by page, and
// which leaves the caches before the search reads it back). The same tree
// as quickbundlesx(extract_features(in, P, .., Resampling::Fast), ..,
// Mode::Fast, ..). InputError for an empty streamline or a non-finite
// coordinate (the first in processing order).
Tree run_qbx_streamed(const Input &in, std::uint32_t P, const std::vector<double> &thresholds, const std::vector<std::uint64_t> &order,
                      unsigned threads, const CancelFn &cancel, const ProgressFn &progress);

}  // namespace qb::detail
