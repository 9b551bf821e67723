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
#include <limits>
#include <thread>

namespace qb {

namespace {

// Points of the streamline, forward or reversed, without copying it.
struct Poly {
    const float *p;
    std::uint64_t n;
    bool rev;
    const float *at(std::uint64_t i) const { return p + 3 * (rev ? n - 1 - i : i); }
};

inline double seg_len(const Poly &s, std::uint64_t i) {  // |p[i] - p[i-1]|, DIPY's c_arclengths
    const float *a = s.at(i), *b = s.at(i - 1);
    double q = 0.0;
    for (int d = 0; d < 3; ++d) {
        const double dn = static_cast<double>(static_cast<float>(a[d] - b[d]));
        q += dn * dn;
    }
    return std::sqrt(q);
}

}  // namespace

void resample(const float *p, std::uint64_t n, std::uint32_t P, bool reversed, float *out) {
    const Poly s{p, n, reversed};
    // Total length: the same additions, in the same order, as DIPY's arc array.
    double L = 0.0;
    for (std::uint64_t i = 1; i < n; ++i) L += seg_len(s, i);
    if (!(L > 0.0)) {  // zero length: DIPY leaves uninitialised memory here
        for (std::uint32_t i = 0; i < P; ++i)
            for (int d = 0; d < 3; ++d) out[3 * i + d] = s.at(n - 1)[d];
        return;
    }
    const double step = L / static_cast<double>(P - 1);
    double t = 0.0;
    std::uint32_t i = 0;
    std::uint64_t k = 0;
    double arc_k = 0.0, arc_km1 = 0.0;  // arc[k], arc[k-1], walked incrementally
    while (t < L && i < P) {
        if (t == arc_k) {
            for (int d = 0; d < 3; ++d) out[3 * i + d] = s.at(k)[d];
            t += step;
            ++i;
            ++k;
            arc_km1 = arc_k;
            arc_k = k < n ? arc_k + seg_len(s, k) : arc_k;
        } else if (t < arc_k) {
            const double ratio = 1.0 - ((arc_k - t) / (arc_k - arc_km1));
            const float *a = s.at(k - 1), *b = s.at(k);
            for (int d = 0; d < 3; ++d)
                out[3 * i + d] = static_cast<float>(static_cast<double>(a[d]) +
                                                    ratio * static_cast<double>(static_cast<float>(b[d] - a[d])));
            t += step;
            ++i;
        } else {
            ++k;
            arc_km1 = arc_k;
            arc_k = k < n ? arc_k + seg_len(s, k) : arc_k;
        }
    }
    for (int d = 0; d < 3; ++d) out[3 * (P - 1) + d] = s.at(n - 1)[d];
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

void check_input(const Input &in) {
    for (std::uint64_t s = 0; s < in.nb_streamlines; ++s) {
        if (in.offsets[s + 1] <= in.offsets[s])
            throw InputError("streamline " + std::to_string(s) + " has no points (remove empty streamlines before clustering)");
        for (std::uint64_t v = 3 * in.offsets[s]; v < 3 * in.offsets[s + 1]; ++v)
            if (!std::isfinite(in.positions[v]))
                throw InputError("streamline " + std::to_string(s) + " has a non-finite coordinate at vertex " + std::to_string(v / 3));
    }
}

Features extract_features(const Input &in, std::uint32_t P, unsigned threads, const CancelFn &cancel) {
    Features f;
    f.nb_points = P;
    const std::uint64_t N = in.nb_streamlines;
    f.direct.resize(N * P * 3);
    f.flipped.resize(N * P * 3);
    threads = std::max(1u, std::min<unsigned>(threads, static_cast<unsigned>(std::max<std::uint64_t>(1, N / 4096))));
    std::vector<std::thread> pool;
    std::atomic<bool> stop{false};
    auto work = [&](std::uint64_t begin, std::uint64_t end, bool poll) {
        for (std::uint64_t s = begin; s < end && !stop; ++s) {
            if (poll && (s & 4095) == 0 && cancel && cancel()) stop = true;
            const float *p = in.positions + 3 * in.offsets[s];
            const std::uint64_t n = in.offsets[s + 1] - in.offsets[s];
            resample(p, n, P, false, &f.direct[s * P * 3]);
            resample(p, n, P, true, &f.flipped[s * P * 3]);
        }
    };
    const std::uint64_t chunk = (N + threads - 1) / threads;
    for (unsigned t = 1; t < threads; ++t)
        pool.emplace_back(work, std::min(N, t * chunk), std::min(N, (t + 1) * chunk), false);
    work(0, std::min(N, chunk), true);  // the calling thread polls cancellation
    for (auto &th : pool) th.join();
    if (stop) throw Cancelled{};
    return f;
}

Features identity_features(const float *points, std::uint64_t n, std::uint32_t P) {
    Features f;
    f.nb_points = P;
    f.direct.assign(points, points + n * P * 3);
    f.flipped.resize(n * P * 3);
    for (std::uint64_t s = 0; s < n; ++s)
        for (std::uint32_t i = 0; i < P; ++i)
            for (int d = 0; d < 3; ++d) f.flipped[(s * P + i) * 3 + d] = f.direct[(s * P + (P - 1 - i)) * 3 + d];
    return f;
}

namespace {

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
    std::int64_t parent = -1;
    std::uint32_t level = 0;
    double threshold = 0;  // used to split its children
    std::vector<float> c;
    std::uint64_t size = 0;
    std::vector<std::uint64_t> indices;
    std::vector<std::uint32_t> children;
    float box_c[3] = {0, 0, 0}, box_r[3] = {0, 0, 0};
};

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

// Flattens nodes into the ABI layout: by level, DFS pre-order within a level.
Tree flatten(const std::vector<Node> &nodes, std::uint32_t levels, const std::vector<double> &thresholds, std::uint32_t P) {
    std::vector<std::uint32_t> dfs;
    std::vector<std::uint32_t> stack = {0};
    while (!stack.empty()) {
        const std::uint32_t k = stack.back();
        stack.pop_back();
        dfs.push_back(k);
        for (auto it = nodes[k].children.rbegin(); it != nodes[k].children.rend(); ++it) stack.push_back(*it);
    }
    std::vector<std::uint32_t> order;  // old ids in output order
    for (std::uint32_t l = 0; l <= levels; ++l)
        for (auto k : dfs)
            if (nodes[k].level == l) order.push_back(k);
    std::vector<std::int64_t> new_id(nodes.size(), -1);
    for (std::size_t i = 0; i < order.size(); ++i) new_id[order[i]] = static_cast<std::int64_t>(i);
    Tree t;
    t.thresholds = thresholds;
    t.nb_points = P;
    t.member_offsets.push_back(0);
    for (auto k : order) {
        const Node &n = nodes[k];
        t.parent.push_back(n.parent < 0 ? -1 : new_id[n.parent]);
        t.level.push_back(n.level);
        t.centroids.insert(t.centroids.end(), n.c.begin(), n.c.end());
        t.members.insert(t.members.end(), n.indices.begin(), n.indices.end());
        t.member_offsets.push_back(t.members.size());
    }
    return t;
}

}  // namespace

Tree quickbundles(const Features &f, double T, const std::vector<std::uint64_t> &order, const CancelFn &cancel,
                  const ProgressFn &progress) {
    const std::uint32_t P = f.nb_points;
    const std::uint64_t N = f.direct.size() / (3 * std::max<std::uint32_t>(P, 1));
    check_order(order, N);
    std::vector<float> C;  // K x P x 3
    std::vector<std::uint64_t> sizes;
    std::vector<std::vector<std::uint64_t>> indices;
    for (std::uint64_t it = 0; it < N; ++it) {
        if ((it & 1023) == 0) {
            if (cancel && cancel()) throw Cancelled{};
            if (progress) progress(double(it) / double(N));
        }
        const std::uint64_t idx = order[it];
        const float *fd = &f.direct[idx * P * 3], *fg = &f.flipped[idx * P * 3];
        const std::uint64_t K = sizes.size();
        std::uint64_t k1 = 0, k2 = 0;
        double d1 = std::numeric_limits<double>::infinity(), d2 = d1;
        for (std::uint64_t k = 0; k < K; ++k) {  // first strict minimum
            const double d = mdf_direct(&C[k * P * 3], fd, P);
            if (d < d1) d1 = d, k1 = k;
        }
        for (std::uint64_t k = 0; k < K; ++k) {
            const double d = mdf_direct(&C[k * P * 3], fg, P);
            if (d < d2) d2 = d, k2 = k;
        }
        const bool use_g = d2 < d1;  // tie -> direct
        std::uint64_t k = use_g ? k2 : k1;
        const double d = use_g ? d2 : d1;
        const float *e = use_g ? fg : fd;
        if (!(d < T)) {  // join iff d < T (strict)
            k = K;
            C.resize(C.size() + P * 3, 0.0f);
            sizes.push_back(0);
            indices.emplace_back();
        }
        update_centroid(&C[k * P * 3], sizes[k], e, P);
        ++sizes[k];
        indices[k].push_back(idx);
    }
    // Root: every streamline in processing order, mean of the oriented features.
    std::vector<Node> nodes(1);
    nodes[0].threshold = T;
    nodes[0].c.assign(P * 3, 0.0f);
    for (std::uint64_t k = 0; k < sizes.size(); ++k) {
        Node n;
        n.parent = 0;
        n.level = 1;
        n.c.assign(C.begin() + k * P * 3, C.begin() + (k + 1) * P * 3);
        n.size = sizes[k];
        n.indices = std::move(indices[k]);
        nodes[0].children.push_back(static_cast<std::uint32_t>(nodes.size()));
        nodes.push_back(std::move(n));
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
    return flatten(nodes, 1, {T}, P);
}

Tree quickbundlesx(const Features &f, const std::vector<double> &t, const std::vector<std::uint64_t> &order, const CancelFn &cancel,
                   const ProgressFn &progress) {
    const std::uint32_t P = f.nb_points;
    const std::uint64_t N = f.direct.size() / (3 * std::max<std::uint32_t>(P, 1));
    const std::uint32_t L = static_cast<std::uint32_t>(t.size());
    if (L == 0) throw InputError("QuickBundlesX needs at least one threshold");
    check_order(order, N);
    std::vector<Node> nodes(1);
    nodes[0].threshold = t[0];
    nodes[0].c.assign(P * 3, 0.0f);
    bool use_flip = false;  // persists across streamlines, as in DIPY
    for (std::uint64_t it = 0; it < N; ++it) {
        if ((it & 1023) == 0) {
            if (cancel && cancel()) throw Cancelled{};
            if (progress) progress(double(it) / double(N));
        }
        const std::uint64_t idx = order[it];
        const float *fd = &f.direct[idx * P * 3], *fg = &f.flipped[idx * P * 3];
        float bc[3], br[3];
        aabb(fd, P, bc, br);
        std::uint32_t node = 0;
        for (;;) {
            Node &n = nodes[node];
            update_centroid(n.c.data(), n.size, use_flip ? fg : fd, P);
            ++n.size;
            n.indices.push_back(idx);
            aabb(n.c.data(), P, n.box_c, n.box_r);
            if (n.level == L) break;
            double best = DBL_MAX;
            std::int64_t kid = -1;
            bool flip = false;
            const float pad = static_cast<float>(n.threshold);
            for (std::size_t k = 0; k < n.children.size(); ++k) {
                const Node &ch = nodes[n.children[k]];
                bool overlap = true;
                for (int d = 0; d < 3 && overlap; ++d)
                    overlap = std::fabs(ch.box_c[d] - bc[d]) <= ch.box_r[d] + br[d] + pad;
                if (!overlap) continue;
                const double dd = static_cast<float>(mdf_direct(ch.c.data(), fd, P));
                if (dd < best) best = dd, kid = static_cast<std::int64_t>(k), flip = false;
                const double dg = static_cast<float>(mdf_direct(ch.c.data(), fg, P));
                if (dg < best) best = dg, kid = static_cast<std::int64_t>(k), flip = true;
            }
            if (best > n.threshold) {  // join iff dist <= threshold (non-strict)
                Node c;
                c.parent = node;
                c.level = n.level + 1;
                c.threshold = c.level < L ? t[c.level] : 0.0;
                c.c.assign(P * 3, 0.0f);
                kid = static_cast<std::int64_t>(n.children.size());
                n.children.push_back(static_cast<std::uint32_t>(nodes.size()));
                nodes.push_back(std::move(c));  // invalidates `n`
            }
            use_flip = flip;
            node = nodes[node].children[static_cast<std::size_t>(kid)];
        }
    }
    if (progress) progress(1.0);
    return flatten(nodes, L, t, P);
}

Tree qbx_and_merge(const Input &in, const std::vector<double> &thresholds, std::uint32_t P, const std::vector<std::uint64_t> &order,
                   const std::vector<std::uint64_t> &merge_order, unsigned threads, const CancelFn &cancel,
                   const ProgressFn &progress) {
    if (thresholds.empty()) throw InputError("qbx_and_merge needs at least one threshold");
    // set_number_of_points(streamlines, P), then identity features.
    const Features resampled = extract_features(in, P, threads, cancel);
    const Features f = identity_features(resampled.direct.data(), in.nb_streamlines, P);
    const Tree qbx = quickbundlesx(f, thresholds, order, cancel, progress);
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
    const Tree merged = quickbundlesx(cf, {thresholds.back()}, morder, cancel, {});
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
