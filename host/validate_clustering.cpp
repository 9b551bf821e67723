// `horizon validate`: the clustering checks (see validate_checks.hpp).
#include "validate_checks.hpp"

#include <hz/core/render/context.hpp>

#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
#include <hz/core/phantom.hpp>

#include <boost/dll/library_info.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <iostream>
#include <random>
#include <set>
#include <sys/mman.h>
#include <unistd.h>

namespace hz::host::validation {

using nlohmann::json;

namespace {

struct Tree {
    hz_cluster_tree_view v{};
    std::vector<double> thresholds;
    std::vector<int64_t> parent;
    std::vector<uint32_t> level;
    std::vector<uint64_t> offsets, members;
    std::vector<float> centroids;
};

hz_status run_clustering(const hz_clustering &c, const core::Tractogram &t, const uint64_t *ordering, Tree &out, std::string &msg,
                         const hz_task *task = nullptr) {
    hz_error err = new_error();
    hz_clusterer *cl = nullptr;
    hz_status st = c.create(core::host_services(), &cl, &err);
    if (st != HZ_OK) {
        msg = std::string("create: ") + err.message;
        return st;
    }
    const hz_streamlines_view view = t.view();
    st = c.run(cl, &view, ordering, task, &err);
    if (st == HZ_OK) {
        out.v.struct_size = sizeof out.v;
        st = c.get_result(cl, &out.v, &err);
        if (st == HZ_OK) {
            const auto &v = out.v;
            out.thresholds.assign(v.level_thresholds, v.level_thresholds + v.nb_levels);
            out.parent.assign(v.parent, v.parent + v.nb_nodes);
            out.level.assign(v.level, v.level + v.nb_nodes);
            out.offsets.assign(v.member_offsets, v.member_offsets + v.nb_nodes + 1);
            out.members.assign(v.members, v.members + out.offsets.back());
            out.centroids.assign(v.centroids, v.centroids + v.nb_nodes * v.nb_points * 3);
        }
    }
    if (st != HZ_OK) msg = err.message;
    c.destroy(cl);
    return st;
}

// Label of every streamline at every level (-1 where missing); checks the
// tree invariants on the way.
bool tree_labels(const Tree &tr, uint64_t n, std::vector<std::vector<int64_t>> &labels, std::string &why) {
    const auto &v = tr.v;
    if (v.nb_nodes < 1) return why = "no root node", false;
    if (tr.parent[0] != -1 || tr.level[0] != 0) return why = "node 0 is not the root", false;
    if (tr.offsets[0] != 0) return why = "member_offsets[0] != 0", false;
    for (uint64_t k = 0; k < v.nb_nodes; ++k)
        if (tr.offsets[k + 1] < tr.offsets[k]) return why = "member_offsets decrease at node " + std::to_string(k), false;
    if (tr.offsets[0 + 1] - tr.offsets[0] != n) return why = "root does not hold every streamline", false;
    for (float f : tr.centroids)
        if (!std::isfinite(f)) return why = "non-finite centroid value", false;
    labels.assign(v.nb_levels + 1, std::vector<int64_t>(n, -1));
    std::vector<std::set<uint64_t>> member_sets(v.nb_nodes);
    for (uint64_t k = 0; k < v.nb_nodes; ++k) {
        const uint32_t lvl = tr.level[k];
        if (lvl > v.nb_levels) return why = "node " + std::to_string(k) + " has level > nb_levels", false;
        if (k > 0) {
            const int64_t p = tr.parent[k];
            if (p < 0 || uint64_t(p) >= v.nb_nodes) return why = "node " + std::to_string(k) + " has an invalid parent", false;
            if (tr.level[p] + 1 != lvl) return why = "node " + std::to_string(k) + " is not one level below its parent", false;
        }
        for (uint64_t m = tr.offsets[k]; m < tr.offsets[k + 1]; ++m) {
            const uint64_t s = tr.members[m];
            if (s >= n) return why = "member index " + std::to_string(s) + " out of range", false;
            if (labels[lvl][s] != -1)
                return why = "streamline " + std::to_string(s) + " is in two clusters of level " + std::to_string(lvl), false;
            labels[lvl][s] = static_cast<int64_t>(k);
            member_sets[k].insert(s);
        }
    }
    for (uint32_t l = 0; l <= v.nb_levels; ++l)
        for (uint64_t s = 0; s < n; ++s)
            if (labels[l][s] == -1)
                return why = "streamline " + std::to_string(s) + " is in no cluster of level " + std::to_string(l), false;
    for (uint64_t k = 1; k < v.nb_nodes; ++k)
        for (uint64_t s : member_sets[k])
            if (!member_sets[tr.parent[k]].count(s))
                return why = "node " + std::to_string(k) + " holds streamline " + std::to_string(s) + " that its parent lacks", false;
    return true;
}

// Two labelings describe the same partition (cluster ids may differ).
bool same_partition(const std::vector<int64_t> &a, const std::vector<int64_t> &b) {
    std::map<int64_t, int64_t> ab, ba;
    for (std::size_t i = 0; i < a.size(); ++i) {
        auto [it1, new1] = ab.emplace(a[i], b[i]);
        auto [it2, new2] = ba.emplace(b[i], a[i]);
        if (it1->second != b[i] || it2->second != a[i]) return false;
    }
    return true;
}

// Well-separated bundles: any sane clustering agrees on them.
core::Tractogram clustering_sample(std::uint64_t seed) {
    core::PhantomOptions o;
    o.nb_streamlines = 300;
    o.nb_bundles = 6;
    o.bundle_radius_mm = 1.0;
    o.stray_fraction = 0.0;
    o.seed = seed;
    return core::make_phantom(o);
}

// ------------------------------------------------------------ the catalogue

}  // namespace

void add_clustering_checks(std::vector<Check> &c) {
    c.push_back(
        {"clustering-schema-wellformed", HZ_KIND_CLUSTERING, "parameter names, types, ranges and defaults are sane", [](const Ctx &x) {
             const hz_clustering &cl = clustering_of(x);
             if (!cl.create || !cl.run || !cl.get_result || !cl.destroy || !cl.set_param) return fail("NULL function in the table");
             return check_schema(cl.param_count, cl.get_param);
         }});
    c.push_back({"clustering-empty-input", HZ_KIND_CLUSTERING, "zero streamlines give HZ_OK and a root-only partition", [](const Ctx &x) {
                     core::Tractogram t;
                     Tree tr;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, tr, msg) != HZ_OK) return fail("run failed on empty input: " + msg);
                     std::vector<std::vector<int64_t>> labels;
                     if (!tree_labels(tr, 0, labels, msg)) return fail(msg);
                     return pass();
                 }});
    c.push_back({"clustering-partition-invariants", HZ_KIND_CLUSTERING,
                 "every streamline in exactly one cluster per level; children within parents; CSR sentinel; finite centroids",
                 [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     Tree tr;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, tr, msg) != HZ_OK) return fail("run failed: " + msg);
                     std::vector<std::vector<int64_t>> labels;
                     if (!tree_labels(tr, t.nb_streamlines(), labels, msg)) return fail(msg);
                     if (tr.v.nb_levels < 1) return fail("no level below the root");
                     return pass(std::to_string(tr.v.nb_nodes) + " nodes over " + std::to_string(tr.v.nb_levels) + " levels");
                 }});
    c.push_back({"clustering-determinism", HZ_KIND_CLUSTERING, "the same input and ordering give the same tree", [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     Tree a, b;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, a, msg) != HZ_OK) return fail(msg);
                     if (run_clustering(clustering_of(x), t, nullptr, b, msg) != HZ_OK) return fail(msg);
                     if (a.parent != b.parent || a.offsets != b.offsets || a.members != b.members)
                         return fail("two runs gave different trees");
                     for (std::size_t i = 0; i < a.centroids.size(); ++i)
                         if (std::fabs(a.centroids[i] - b.centroids[i]) > 1e-6) return fail("two runs gave different centroids");
                     return pass();
                 }});
    c.push_back({"clustering-delimited-input", HZ_KIND_CLUSTERING,
                 "with HZ_EXT_DELIMITED_STREAMLINES offered, input with a NaN vertex after each streamline gives the same tree",
                 [](const Ctx &x) {
                     if (!extension_of<hz_ext_delimited_streamlines>(x, HZ_EXT_DELIMITED_STREAMLINES))
                         return skip("does not offer HZ_EXT_DELIMITED_STREAMLINES");
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     Tree a, b;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, a, msg) != HZ_OK) return fail(msg);
                     if (run_clustering(clustering_of(x), with_gap(t, std::numeric_limits<float>::quiet_NaN()), nullptr, b, msg) != HZ_OK)
                         return fail("with gap 1 (NaN delimiters): " + msg);
                     if (a.parent != b.parent || a.offsets != b.offsets || a.members != b.members || a.centroids != b.centroids)
                         return fail("gap 1 (NaN delimiters) gives another tree than the same streamlines without them");
                     return pass(std::to_string(t.nb_streamlines()) + " streamlines, same tree with and without delimiters");
                 }});
    c.push_back({"clustering-ordering", HZ_KIND_CLUSTERING,
                 "an explicit ordering is honoured: the same ordering gives the same tree, and the result is still a partition",
                 [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     std::vector<uint64_t> order(t.nb_streamlines());
                     std::iota(order.begin(), order.end(), 0);
                     std::mt19937_64 rng(x.opts.seed);
                     std::shuffle(order.begin(), order.end(), rng);
                     Tree a, b;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, order.data(), a, msg) != HZ_OK) return fail(msg);
                     if (run_clustering(clustering_of(x), t, order.data(), b, msg) != HZ_OK) return fail(msg);
                     if (a.parent != b.parent || a.members != b.members) return fail("same ordering, different trees");
                     std::vector<std::vector<int64_t>> labels;
                     if (!tree_labels(a, t.nb_streamlines(), labels, msg)) return fail(msg);
                     return pass();
                 }});
    c.push_back({"clustering-flip-invariance", HZ_KIND_CLUSTERING, "reversing every streamline gives the same partition at every level",
                 [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     core::Tractogram r;
                     r.positions = core::Buffer<float>(t.positions.size());
                     r.offsets = core::Buffer<uint64_t>(t.offsets.size());
                     std::copy(t.offsets.begin(), t.offsets.end(), r.offsets.begin());
                     for (uint64_t s = 0; s < t.nb_streamlines(); ++s)
                         for (uint64_t i = t.offsets[s], j = t.offsets[s + 1] - 1; i < t.offsets[s + 1]; ++i, --j)
                             std::copy(&t.positions[3 * j], &t.positions[3 * j] + 3, &r.positions[3 * i]);
                     Tree a, b;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, a, msg) != HZ_OK) return fail(msg);
                     if (run_clustering(clustering_of(x), r, nullptr, b, msg) != HZ_OK) return fail(msg);
                     std::vector<std::vector<int64_t>> la, lb;
                     if (!tree_labels(a, t.nb_streamlines(), la, msg) || !tree_labels(b, t.nb_streamlines(), lb, msg)) return fail(msg);
                     if (la.size() != lb.size()) return fail("different number of levels");
                     for (std::size_t l = 0; l < la.size(); ++l)
                         if (!same_partition(la[l], lb[l]))
                             return fail("level " + std::to_string(l) + " partition changes when streamlines are reversed");
                     return pass();
                 }});
    c.push_back({"clustering-nonfinite-input", HZ_KIND_CLUSTERING, "a NaN coordinate gives a clean error, not a crash", [](const Ctx &x) {
                     core::Tractogram t = clustering_sample(x.opts.seed);
                     t.positions[7] = std::numeric_limits<float>::quiet_NaN();
                     Tree tr;
                     std::string msg;
                     const hz_status st = run_clustering(clustering_of(x), t, nullptr, tr, msg);
                     if (st == HZ_OK) return fail("NaN input accepted");
                     if (msg.empty()) return fail("rejected without a message");
                     return pass();
                 }});
    c.push_back({"clustering-cancel", HZ_KIND_CLUSTERING, "a pre-cancelled task gives HZ_E_CANCELLED", [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     core::Task task;
                     task.cancel();
                     Tree tr;
                     std::string msg;
                     const hz_status st = run_clustering(clustering_of(x), t, nullptr, tr, msg, task.get());
                     if (st != HZ_E_CANCELLED) return fail("status " + std::to_string(st) + " instead of HZ_E_CANCELLED");
                     return pass();
                 }});
}

}  // namespace hz::host::validation
