// QuickBundles (Garyfallidis et al. 2012) and QuickBundlesX (Garyfallidis et
// al. 2016), reproducing DIPY 1.6's arithmetic exactly (see
// ../shared/clustering/DIPY-QBX.md): the same labels at every level and the
// same float32 centroids, bit for bit, for the same processing order.
// Pure C++, no SDK types; compiled with -ffp-contract=off.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <memory>
#include <utility>
#include <vector>

namespace qb {

struct Input {
    const float *positions = nullptr;        // V x 3
    const std::uint64_t *offsets = nullptr;  // N + 1
    std::uint64_t nb_streamlines = 0;
    // Vertices after each streamline that belong to none (a mapped TCK's
    // delimiters): streamline s is [offsets[s], offsets[s+1] - gap).
    std::uint64_t gap = 0;
    std::uint64_t size(std::uint64_t s) const { return offsets[s + 1] - offsets[s] >= gap ? offsets[s + 1] - offsets[s] - gap : 0; }
};

// Thrown for invalid input (non-finite coordinates, empty streamlines).
struct InputError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
struct Cancelled {};

// Polled between streamlines; return true to stop (throws Cancelled).
using CancelFn = std::function<bool()>;
using ProgressFn = std::function<void(double)>;

// Floats after the last feature or centroid block of an array: a SIMD load
// of a block's last axis may read (and mask off) up to one vector past it.
inline constexpr std::size_t kTail = 16;

// A std::allocator that leaves values uninitialised: feature arrays are
// written by the resampling workers, so their pages are first touched there,
// in parallel, instead of being zeroed by one thread beforehand.
template <class T>
struct UninitAllocator : std::allocator<T> {
    template <class U>
    struct rebind {
        using other = UninitAllocator<U>;
    };
    UninitAllocator() = default;
    template <class U>
    UninitAllocator(const UninitAllocator<U> &) noexcept {}
    template <class U, class... Args>
    void construct(U *p, Args &&...args) {
        if constexpr (sizeof...(Args) == 0)
            ::new (static_cast<void *>(p)) U;
        else
            ::new (static_cast<void *>(p)) U(std::forward<Args>(args)...);
    }
};
using FloatArray = std::vector<float, UninitAllocator<float>>;

// Direct and flipped features of every streamline: one block of 3P floats
// per streamline, per axis (x[0..P), y[0..P), z[0..P)), then kTail floats.
// The per-axis layout lets a distance load P coordinates of one axis at
// once; every computation is element-wise or per axis in point order, so
// the values are those of DIPY's interleaved arrays. `flipped` is empty
// when the flipped features are the exact reversal of the direct ones
// (fast mode, identity features): the searches then build them on demand,
// which saves a third of the memory at 5M streamlines.
struct Features {
    std::uint32_t nb_points = 0;
    std::uint64_t count = 0;  // streamlines
    FloatArray direct, flipped;
    // Per streamline, kGeom floats that every search reads: the AABB of the
    // direct features (centre xyz, half-size xyz) and the mean points of
    // the direct and the flipped features (xyz each).
    FloatArray geom;
    float max_abs = 0;  // the largest |coordinate| of any feature
    // Whether the streamlines' mean points may have been summed in float32
    // (fast resampling) rather than in double: the lower bounds of the
    // searches then allow for the larger rounding.
    bool float_means = false;
    static constexpr std::size_t kGeom = 12;
};
// How extract_features resamples:
// * Dipy: DIPY's arithmetic, bit for bit, and flipped features resampled
//   from the reversed polyline, as DIPY does (bitwise different from
//   reversing the direct features for ~10% of streamlines): exact QB/QBX;
// * DipyDirect: DIPY's arithmetic; flipped features are the reversal of
//   the direct ones (not stored): exact qbx_and_merge;
// * Fast: float32 vectors (qb_resample.cpp), flipped as the reversal: fast
//   mode. The points differ from DIPY's by float32 rounding (~1e-6 relative).
enum class Resampling { Dipy, DipyDirect, Fast };
// Also validates the input (InputError for an empty streamline or a
// non-finite coordinate).
Features extract_features(const Input &in, std::uint32_t nb_points, unsigned threads, const CancelFn &cancel, Resampling how);
// Features are the points themselves, given xyz-interleaved, n x P x 3
// (qbx_and_merge's centroids): flipped is then the exact reversal (not stored).
Features identity_features(const float *points, std::uint64_t n, std::uint32_t nb_points);

enum class Mode { Exact, Fast };

// A clustering tree in the ABI's layout: node 0 = root; nodes ordered by
// level, then as DIPY lists them (QB: creation order; QBX: DFS pre-order).
struct Tree {
    std::vector<double> thresholds;  // per level below the root
    std::uint32_t nb_points = 0;
    std::vector<std::int64_t> parent;
    std::vector<std::uint32_t> level;
    std::vector<float> centroids;  // nodes x P x 3
    std::vector<std::uint64_t> member_offsets, members;
    std::uint64_t nb_nodes() const { return parent.size(); }
};

// `order` (every function below): the processing order, step it taking
// streamline order[it]; a permutation of 0..N-1, or empty for file order.
// QuickBundles with threshold T: one level below the root.
// Exact: DIPY's arithmetic, bit for bit. Fast: float32 distances (labels
// agree with exact mode except where rounding decides a near-tie).
Tree quickbundles(const Features &f, double threshold, const std::vector<std::uint64_t> &order, Mode mode, const CancelFn &cancel,
                  const ProgressFn &progress);

// QuickBundlesX with thresholds t[0..L-1]: L levels below the root.
// threads: 1 runs it on the calling thread alone; more lets it use a second
// one (for at least 20 000 streamlines and two levels). The tree is the same.
Tree quickbundlesx(const Features &f, const std::vector<double> &thresholds, const std::vector<std::uint64_t> &order, Mode mode,
                   const CancelFn &cancel, const ProgressFn &progress, unsigned threads = 2);

// QuickBundlesX from the streamlines themselves, what the plugin runs:
// exact mode resamples them all first (Resampling::Dipy, on `threads`
// threads; the search, as above); fast mode computes each streamline's features as the search
// reaches it (the same tree as quickbundlesx(extract_features(in,
// nb_points, .., Resampling::Fast), .., Mode::Fast, ..), with no array of
// all the features).
Tree quickbundlesx(const Input &in, std::uint32_t nb_points, const std::vector<double> &thresholds, const std::vector<std::uint64_t> &order,
                   Mode mode, unsigned threads, const CancelFn &cancel, const ProgressFn &progress);

// Horizon's qbx_and_merge: resample to nb_points, QBX, then a one-threshold
// QBX over the last level's centroids in `merge_order` (empty = identity);
// one level of merged clusters below the root.
Tree qbx_and_merge(const Input &in, const std::vector<double> &thresholds, std::uint32_t nb_points, const std::vector<std::uint64_t> &order,
                   const std::vector<std::uint64_t> &merge_order, Mode mode, unsigned threads, const CancelFn &cancel,
                   const ProgressFn &progress);

}  // namespace qb
