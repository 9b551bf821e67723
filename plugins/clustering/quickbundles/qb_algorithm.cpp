// QuickBundles / QuickBundlesX with DIPY 1.6's exact arithmetic: the
// resampling into features, the flattening of the tree into the ABI layout,
// and qbx_and_merge (the searches themselves are in qb_search.cpp).
// Garyfallidis et al. 2012, "QuickBundles, a method for tractography
// simplification"; Garyfallidis et al. 2016, "QuickBundlesX: sequential
// clustering of millions of streamlines in multiple levels of detail".
// Every cast below mirrors a float32/double boundary in DIPY's Cython code;
// this file is compiled with -ffp-contract=off (no fused multiply-adds).
#include "qb_algorithm.hpp"
#include "qb_internal.hpp"

#include <algorithm>
#include <atomic>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <limits>
#include <thread>

#include "parallel.hpp"  // hzio::prefault_write (plugins/common)

namespace qb {

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define QB_SEG_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define QB_SEG_CLONES
#endif

namespace {

// DIPY's c_set_number_of_points walk (DIPY-QBX.md section 3.2) over the
// cumulative arc lengths arc[0..n): arc[k] is the same sum, in the same
// order, that DIPY accumulates as it walks, so the output is bitwise the
// same; the serial additions are done once, beforehand, and the walk itself
// only compares. at(k) = the k-th point; `out` holds x[0..P), y[0..P), z[0..P). A zero-length polyline gives
// copies of its last point, where DIPY reads uninitialised memory.
template <class At>
void walk_arcs(std::uint64_t n, std::uint32_t P, const double *arc, At at, float *out) {
    const double L = arc[n - 1];
    if (!(L > 0.0)) {
        for (std::uint32_t i = 0; i < P; ++i)
            for (int d = 0; d < 3; ++d) out[d * P + i] = at(n - 1)[d];
        return;
    }
    const double step = L / static_cast<double>(P - 1);
    double t = 0.0;
    std::uint32_t i = 0;
    std::uint64_t k = 0;
    while (t < L && i < P) {
        while (t > arc[k]) ++k;  // DIPY's "else: k++" steps (t < L = arc[n-1] bounds k)
        if (t == arc[k]) {
            for (int d = 0; d < 3; ++d) out[d * P + i] = at(k)[d];
            ++k;
        } else {
            const double ratio = 1.0 - ((arc[k] - t) / (arc[k] - arc[k - 1]));
            const float *a = at(k - 1), *b = at(k);
            for (int d = 0; d < 3; ++d)
                out[d * P + i] =
                    static_cast<float>(static_cast<double>(a[d]) + ratio * static_cast<double>(static_cast<float>(b[d] - a[d])));
        }
        t += step;
        ++i;
    }
    for (int d = 0; d < 3; ++d) out[d * P + (P - 1)] = at(n - 1)[d];
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

namespace {

// DIPY's c_set_number_of_points on two streamlines at once, a (na >= 1
// points) and b (nb = 0: none), into fa / fb and, for their reversals
// (when ga is not NULL), into ga / gb; P points each, stored per axis.
// Zero-length streamlines (all points equal, or a single point) give P
// copies of the point, where DIPY reads uninitialised memory. The
// arc-length sums of both (and of their reversals) are interleaved in one
// loop. Each sum is a chain of
// dependent additions in DIPY's order; independent chains side by side let
// the CPU overlap their latencies. Returns the polyline lengths in L.
void resample_pair(const float *pa, std::uint64_t na, float *fa, float *ga, const float *pb, std::uint64_t nb, float *fb, float *gb,
                   std::uint32_t P, std::vector<double> &scratch, double L[2]) {
    // Each segment's length once: the reversed polyline's float differences
    // are the exact negations of the forward ones, so its segment i is the
    // forward segment n - i, bit for bit. Only the summation order differs.
    scratch.resize(3 * (na + nb));
    double *sa = scratch.data(), *aa = sa + na, *ra = aa + na;
    double *sb = ra + na, *ab = sb + nb, *rb = ab + nb;
    segment_lengths(pa, na, sa);
    if (nb) segment_lengths(pb, nb, sb);
    const bool rev = ga != nullptr;
    aa[0] = ra[0] = 0.0;
    if (nb) ab[0] = rb[0] = 0.0;
    double x = 0.0, u = 0.0, y = 0.0, v = 0.0;
    const std::uint64_t m = std::min(na, nb);
    std::uint64_t i = 1;
    if (rev)
        for (; i < m; ++i) {
            aa[i] = x += sa[i];
            ra[i] = u += sa[na - i];
            ab[i] = y += sb[i];
            rb[i] = v += sb[nb - i];
        }
    else
        for (; i < m; ++i) {
            aa[i] = x += sa[i];
            ab[i] = y += sb[i];
        }
    for (std::uint64_t k = i; k < na; ++k) {
        aa[k] = x += sa[k];
        if (rev) ra[k] = u += sa[na - k];
    }
    for (std::uint64_t k = i; k < nb; ++k) {
        ab[k] = y += sb[k];
        if (rev) rb[k] = v += sb[nb - k];
    }
    walk_arcs(
        na, P, aa, [&](std::uint64_t k) { return pa + 3 * k; }, fa);
    if (rev)
        walk_arcs(
            na, P, ra, [&](std::uint64_t k) { return pa + 3 * (na - 1 - k); }, ga);
    L[0] = aa[na - 1];
    L[1] = 0.0;
    if (nb) {
        walk_arcs(
            nb, P, ab, [&](std::uint64_t k) { return pb + 3 * k; }, fb);
        if (rev)
            walk_arcs(
                nb, P, rb, [&](std::uint64_t k) { return pb + 3 * (nb - 1 - k); }, gb);
        L[1] = ab[nb - 1];
    }
}

// A streamline's Features::geom from its direct features fd and its
// flipped ones fg (NULL: the reversal of fd, whose mean point is fd's; the
// bound's slack covers the summation order). Returns its largest |coordinate|.
float fill_geom(const float *fd, const float *fg, std::uint32_t P, float *g) {
    detail::feature_box(fd, P, g, g + 3);
    detail::feature_mean(fd, P, g + 6);
    if (fg != nullptr)
        detail::feature_mean(fg, P, g + 9);
    else
        std::copy_n(g + 6, 3, g + 9);
    float m = 0.0f;
    for (std::uint32_t i = 0; i < 3 * P; ++i) m = std::max(m, std::fabs(fd[i]));
    return m;
}

}  // namespace

namespace detail {

bool extract_block(const Input &in, const std::uint64_t *idx, std::uint64_t begin, std::uint64_t end, std::uint32_t P, Resampling how,
                   float *direct, float *flipped, float *geom, BlockScratch &scratch, float &max_abs, std::string &error) {
    const bool exact_flip = how == Resampling::Dipy;
    const std::size_t B = std::size_t(P) * 3;
    constexpr std::uint64_t kBatch = 64;  // streamlines per step (even: resample_pair takes two)
    double L[kBatch];
    for (std::uint64_t s0 = begin; s0 < end; s0 += kBatch) {
        const std::uint64_t s1 = std::min(end, s0 + kBatch);
        auto id = [&](std::uint64_t t) { return idx ? idx[t] : t; };
        auto fd_of = [&](std::uint64_t t) { return direct + (t - begin) * B; };
        bool fast = how == Resampling::Fast;
        for (std::uint64_t t = s0; t < s1; ++t) {
            const std::uint64_t n = in.size(id(t));
            if (n == 0) {
                error = "streamline " + std::to_string(id(t)) + " has no points (remove empty streamlines before clustering)";
                return false;
            }
            if (n >= (std::uint64_t{1} << 29)) fast = false;  // beyond resample_fast's 32-bit gathers
        }
        if (fast) {
            resample_fast(in, idx, s0, s1, P, fd_of(s0), geom + (s0 - begin) * Features::kGeom, scratch.points, L, max_abs);
        } else {
            // DIPY resamples the reversed polyline for the flipped features.
            for (std::uint64_t s = s0; s < s1; s += 2) {
                const std::uint64_t cnt = std::min<std::uint64_t>(2, s1 - s);
                const float *p[2] = {nullptr, nullptr};
                std::uint64_t n[2] = {0, 0};
                float *fd[2] = {nullptr, nullptr}, *fg[2] = {nullptr, nullptr};
                for (std::uint64_t j = 0; j < cnt; ++j) {
                    const std::uint64_t t = s + j;
                    p[j] = in.positions + 3 * in.offsets[id(t)];
                    n[j] = in.size(id(t));
                    fd[j] = fd_of(t);
                    if (exact_flip) fg[j] = flipped + (t - begin) * B;
                }
                resample_pair(p[0], n[0], fd[0], fg[0], p[1], n[1], fd[1], fg[1], P, scratch.seg, &L[s - s0]);
            }
        }
        for (std::uint64_t t = s0; t < s1; ++t) {
            const std::uint64_t s = id(t), n = in.size(s);
            const float *p = in.positions + 3 * in.offsets[s];
            // A non-finite coordinate makes the length non-finite, so
            // the coordinates are only searched then (or for a single point).
            // Fast mode's float32 squares overflow beyond ~1e19 mm and
            // underflow below ~1e-19 mm: such streamlines (and any shorter
            // than 1e-6 mm) are resampled with DIPY's double arithmetic.
            const bool redo = fast && n > 1 && !(L[t - s0] >= 1e-6 && L[t - s0] <= DBL_MAX);
            if (!std::isfinite(L[t - s0]) || n == 1 || redo) {
                for (std::uint64_t v = 0; v < 3 * n; ++v)
                    if (!std::isfinite(p[v])) {
                        error = "streamline " + std::to_string(s) + " has a non-finite coordinate at vertex " +
                                std::to_string(in.offsets[s] - s * in.gap + v / 3);
                        return false;
                    }
                if (redo) {
                    double len[2];
                    resample_pair(p, n, fd_of(t), nullptr, nullptr, 0, nullptr, nullptr, P, scratch.seg, len);
                }
            }
            if (fast && !redo) continue;  // (resample_fast filled its geom)
            max_abs = std::max(
                max_abs, fill_geom(fd_of(t), exact_flip ? flipped + (t - begin) * B : nullptr, P, geom + (t - begin) * Features::kGeom));
        }
    }
    return true;
}

}  // namespace detail

Features extract_features(const Input &in, std::uint32_t P, unsigned threads, const CancelFn &cancel, Resampling how) {
    Features f;
    f.nb_points = P;
    f.float_means = how == Resampling::Fast;
    const std::uint64_t N = in.nb_streamlines;
    const bool exact_flip = how == Resampling::Dipy;
    f.count = N;
    f.direct.resize(N * P * 3 + kTail);
    if (exact_flip) f.flipped.resize(N * P * 3 + kTail);
    f.geom.resize(N * Features::kGeom);
    threads = std::max(1u, std::min<unsigned>(threads, static_cast<unsigned>(std::max<std::uint64_t>(1, N / 4096))));
    std::vector<std::thread> pool;
    std::atomic<bool> stop{false};
    std::vector<std::string> errors(threads);
    std::vector<float> max_abs(threads, 0.0f);
    // Each worker validates its streamlines (non-empty, finite) while it
    // resamples them: one pass over the input.
    auto work = [&](unsigned w, std::uint64_t begin, std::uint64_t end) {
        // This worker's share of the output, mapped in one call before it is
        // written (instead of a page fault per page).
        hzio::prefault_write(f.direct.data() + begin * P * 3, (end - begin) * P * 3 * sizeof(float));
        if (exact_flip) hzio::prefault_write(f.flipped.data() + begin * P * 3, (end - begin) * P * 3 * sizeof(float));
        hzio::prefault_write(f.geom.data() + begin * Features::kGeom, (end - begin) * Features::kGeom * sizeof(float));
        detail::BlockScratch scratch;
        constexpr std::uint64_t kStep = 256;  // streamlines between cancellation polls (thread 0)
        for (std::uint64_t s0 = begin; s0 < end && !stop; s0 += kStep) {
            if (w == 0 && (s0 - begin) % 4096 == 0 && cancel && cancel()) stop = true;
            const std::uint64_t s1 = std::min(end, s0 + kStep);
            if (!detail::extract_block(in, nullptr, s0, s1, P, how, &f.direct[s0 * P * 3], exact_flip ? &f.flipped[s0 * P * 3] : nullptr,
                                       &f.geom[s0 * Features::kGeom], scratch, max_abs[w], errors[w]))
                stop = true;
        }
    };
    const std::uint64_t chunk = (N + threads - 1) / threads;
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, t, std::min(N, t * chunk), std::min(N, (t + 1) * chunk));
    work(0, 0, std::min(N, chunk));  // the calling thread polls cancellation
    for (auto &th : pool) th.join();
    std::fill(f.direct.end() - kTail, f.direct.end(), 0.0f);
    if (exact_flip) std::fill(f.flipped.end() - kTail, f.flipped.end(), 0.0f);
    for (float m : max_abs) f.max_abs = std::max(f.max_abs, m);
    for (const auto &e : errors)
        if (!e.empty()) throw InputError(e);
    if (stop) throw Cancelled{};
    return f;
}

Features identity_features(const float *points, std::uint64_t n, std::uint32_t P) {
    Features f;
    f.nb_points = P;
    f.count = n;
    f.direct.assign(n * P * 3 + kTail, 0.0f);
    for (std::uint64_t s = 0; s < n; ++s)
        for (std::uint32_t i = 0; i < P; ++i)
            for (int d = 0; d < 3; ++d) f.direct[s * P * 3 + d * P + i] = points[(s * P + i) * 3 + d];
    f.geom.resize(n * Features::kGeom);
    for (std::uint64_t s = 0; s < n; ++s)
        f.max_abs = std::max(f.max_abs, fill_geom(&f.direct[s * P * 3], nullptr, P, &f.geom[s * Features::kGeom]));
    return f;
}

namespace detail {

void check_order(const std::vector<std::uint64_t> &order, std::uint64_t N) {
    if (order.empty()) return;  // file order
    if (order.size() != N)
        throw InputError("ordering has " + std::to_string(order.size()) + " entries for " + std::to_string(N) + " streamlines");
    std::vector<bool> seen(N, false);
    for (auto i : order) {
        if (i >= N || seen[i]) throw InputError("ordering is not a permutation of the streamline indices");
        seen[i] = true;
    }
}

Tree flatten(const Node &root, std::uint32_t levels, const std::vector<double> &thresholds, std::uint32_t P, const Paths *paths) {
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
    t.centroids.resize(order.size() * P * 3);
    for (std::size_t i = 0; i < order.size(); ++i) {
        const Node *k = order[i];
        const_cast<Node *>(k)->out = i;
        t.parent.push_back(k->parent ? static_cast<std::int64_t>(k->parent->out) : -1);
        t.level.push_back(k->level);
        const float *c = k->centroid(P);  // per axis -> xyz-interleaved
        for (std::uint32_t p = 0; p < P; ++p)
            for (int d = 0; d < 3; ++d) t.centroids[(i * P + p) * 3 + d] = c[d * P + p];
        t.member_offsets.push_back(t.member_offsets.back() + k->size);
    }
    if (paths == nullptr) {
        t.members.reserve(t.member_offsets.back());
        for (auto k : order) t.members.insert(t.members.end(), k->indices.begin(), k->indices.end());
    } else {
        // Every node's members in processing order, scattered level by
        // level (the levels' ranges are disjoint: one thread each, two at once).
        hzio::resize_prefaulted(t.members, t.member_offsets.back());
        const std::uint64_t N = paths->N;
        paths->order.copy(N, t.members.data());  // the root
        const std::uint32_t L = paths->L;
        // Each node's output position by uid, in two flat tables.
        std::vector<std::uint32_t> out_a(paths->store_a.size()), out_b(paths->store_b.size());
        for (std::size_t i = 0; i < out_a.size(); ++i) out_a[i] = static_cast<std::uint32_t>(paths->store_a[i].out);
        for (std::size_t i = 0; i < out_b.size(); ++i) out_b[i] = static_cast<std::uint32_t>(paths->store_b[i].out);
        auto scatter = [&](std::uint32_t l) {
            std::vector<std::uint64_t> cursor(t.member_offsets.begin(), t.member_offsets.end() - 1);
            for (std::uint64_t it = 0; it < N; ++it) {
                const std::uint32_t uid = paths->path[it * L + l];
                t.members[cursor[uid & Paths::kStageB ? out_b[uid & ~Paths::kStageB] : out_a[uid]]++] = paths->order[it];
            }
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

}  // namespace detail

Tree quickbundles(const Features &f, double T, const std::vector<std::uint64_t> &order, Mode mode, const CancelFn &cancel,
                  const ProgressFn &progress) {
    return detail::run_qb(f, T, order, mode, cancel, progress);
}

Tree quickbundlesx(const Features &f, const std::vector<double> &t, const std::vector<std::uint64_t> &order, Mode mode,
                   const CancelFn &cancel, const ProgressFn &progress, unsigned threads) {
    return detail::run_qbx(f, t, order, mode, threads, cancel, progress);
}

Tree quickbundlesx(const Input &in, std::uint32_t P, const std::vector<double> &t, const std::vector<std::uint64_t> &order, Mode mode,
                   unsigned threads, const CancelFn &cancel, const ProgressFn &progress) {
    if (mode == Mode::Fast) return detail::run_qbx_streamed(in, P, t, order, threads, cancel, progress);
    return quickbundlesx(extract_features(in, P, threads, cancel, Resampling::Dipy), t, order, mode, cancel, progress, threads);
}

Tree qbx_and_merge(const Input &in, const std::vector<double> &thresholds, std::uint32_t P, const std::vector<std::uint64_t> &order,
                   const std::vector<std::uint64_t> &merge_order, Mode mode, unsigned threads, const CancelFn &cancel,
                   const ProgressFn &progress) {
    if (thresholds.empty()) throw InputError("qbx_and_merge needs at least one threshold");
    // set_number_of_points(streamlines, P), then identity features: the
    // resampled points themselves, flipped by reversal.
    const Tree qbx = mode == Mode::Fast ? detail::run_qbx_streamed(in, P, thresholds, order, threads, cancel, progress)
                                        : quickbundlesx(extract_features(in, P, threads, cancel, Resampling::DipyDirect), thresholds, order,
                                                        mode, cancel, progress, threads);
    const std::uint32_t L = static_cast<std::uint32_t>(thresholds.size());
    std::vector<std::uint64_t> leaves;  // node ids of the last level, DFS order
    for (std::uint64_t k = 0; k < qbx.nb_nodes(); ++k)
        if (qbx.level[k] == L) leaves.push_back(k);
    const std::uint64_t K = leaves.size();
    std::vector<float> cents(K * P * 3);
    for (std::uint64_t i = 0; i < K; ++i) std::copy_n(&qbx.centroids[leaves[i] * P * 3], P * 3, &cents[i * P * 3]);
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
