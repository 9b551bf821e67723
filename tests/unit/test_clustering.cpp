// The bundled QuickBundlesX plugin through its ABI table, on tractograms
// large enough (>= 20 000 streamlines) for its search to run on two threads
// and, in fast mode, to compute the features as it goes, in a ring shared by
// both threads: the tree must be the one-thread tree, an invalid streamline
// must stop the run with its index, and a cancellation must stop it cleanly.
#include <hz/core/phantom.hpp>
#include <hz/core/plugin_host.hpp>

#include <catch2/catch.hpp>

#include "simd_targets.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

using namespace hz::core;

namespace {

struct Result {
    hz_status status = HZ_OK;
    std::string message;
    std::vector<std::int64_t> parent;
    std::vector<std::uint32_t> level;
    std::vector<float> centroids;
    std::vector<std::uint64_t> offsets, members;
};

// The bundled QBX plugin's table, from the plugin dir scanned once for all
// the tests here.
const hz_clustering &qbx() {
    static const Registry reg = [] {
        Registry r;
        r.scan({HZ_TEST_PLUGIN_DIR});
        return r;
    }();
    const LoadedPlugin *p = reg.find("org.horizon.clustering.qbx");
    REQUIRE(p != nullptr);
    REQUIRE(p->clustering() != nullptr);
    return *p->clustering();
}

// One run: mode 0 exact / 1 fast, `threads` as the plugin's parameter.
Result cluster(const hz_clustering &c, const Tractogram &t, double mode, double threads, const std::uint64_t *order = nullptr,
               const hz_task *task = nullptr) {
    Result r;
    hz_error err{};
    err.struct_size = sizeof err;
    hz_clusterer *obj = nullptr;
    REQUIRE(c.create(host_services(), &obj, &err) == HZ_OK);
    REQUIRE(c.set_param(obj, "mode", &mode, 1, &err) == HZ_OK);
    REQUIRE(c.set_param(obj, "threads", &threads, 1, &err) == HZ_OK);
    const hz_streamlines_view view = t.view();
    r.status = c.run(obj, &view, order, task, &err);
    if (r.status == HZ_OK) {
        hz_cluster_tree_view v{};
        v.struct_size = sizeof v;
        REQUIRE(c.get_result(obj, &v, &err) == HZ_OK);
        r.parent.assign(v.parent, v.parent + v.nb_nodes);
        r.level.assign(v.level, v.level + v.nb_nodes);
        r.centroids.assign(v.centroids, v.centroids + v.nb_nodes * v.nb_points * 3);
        r.offsets.assign(v.member_offsets, v.member_offsets + v.nb_nodes + 1);
        r.members.assign(v.members, v.members + r.offsets.back());
    } else {
        r.message = err.message;
    }
    c.destroy(obj);
    return r;
}

Tractogram phantom(std::uint64_t n) { return make_phantom({.nb_streamlines = n, .seed = 7}); }

}  // namespace

TEST_CASE("QuickBundlesX on two threads builds the one-thread tree, bit for bit") {
    const hz_clustering &c = qbx();
    const Tractogram t = phantom(30000);
    std::vector<std::uint64_t> shuffled(t.nb_streamlines());
    std::iota(shuffled.begin(), shuffled.end(), 0);
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937_64(3));
    for (const double mode : {0.0, 1.0})
        for (const std::uint64_t *order : std::vector<const std::uint64_t *>{nullptr, shuffled.data()}) {
            CAPTURE(mode, order != nullptr);
            const Result one = cluster(c, t, mode, 1, order), two = cluster(c, t, mode, 2, order);
            REQUIRE(one.status == HZ_OK);
            REQUIRE(two.status == HZ_OK);
            CHECK(one.parent.size() > 300);  // (a real tree: hundreds of clusters)
            CHECK(one.parent == two.parent);
            CHECK(one.level == two.level);
            CHECK(one.offsets == two.offsets);
            CHECK(one.members == two.members);
            CHECK(std::memcmp(one.centroids.data(), two.centroids.data(), one.centroids.size() * sizeof(float)) == 0);
        }
}

TEST_CASE("file order (no ordering array) is the identity ordering, bit for bit") {
    // The plugin runs file order without an array of indices: the same tree
    // as the identity permutation passed explicitly, in both modes, on one
    // thread and two; a shuffled order gives another tree.
    const hz_clustering &c = qbx();
    const Tractogram t = phantom(25000);
    std::vector<std::uint64_t> identity(t.nb_streamlines()), shuffled(t.nb_streamlines());
    std::iota(identity.begin(), identity.end(), 0);
    std::iota(shuffled.begin(), shuffled.end(), 0);
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937_64(11));
    for (const double mode : {0.0, 1.0})
        for (const double threads : {1.0, 2.0}) {
            CAPTURE(mode, threads);
            const Result file = cluster(c, t, mode, threads), ident = cluster(c, t, mode, threads, identity.data()),
                         shuf = cluster(c, t, mode, threads, shuffled.data());
            REQUIRE(file.status == HZ_OK);
            REQUIRE(ident.status == HZ_OK);
            REQUIRE(shuf.status == HZ_OK);
            CHECK(file.parent == ident.parent);
            CHECK(file.offsets == ident.offsets);
            CHECK(file.members == ident.members);
            CHECK(std::memcmp(file.centroids.data(), ident.centroids.data(), file.centroids.size() * sizeof(float)) == 0);
            CHECK(std::equal(file.members.begin(), file.members.begin() + t.nb_streamlines(), identity.begin()));  // the root
            CHECK(std::equal(shuf.members.begin(), shuf.members.begin() + t.nb_streamlines(), shuffled.begin()));
            CHECK(shuf.members != file.members);
        }
}

TEST_CASE("an invalid streamline stops QuickBundlesX with its index, on one thread or two") {
    const hz_clustering &c = qbx();
    // Early (the first block of features) and late (blocks the worker
    // computes ahead of the main thread in fast mode).
    for (const std::uint64_t bad : {std::uint64_t{5}, std::uint64_t{25000}})
        for (const double mode : {0.0, 1.0})
            for (const double threads : {1.0, 2.0}) {
                CAPTURE(bad, mode, threads);
                Tractogram t = phantom(30000);
                t.positions[3 * (t.begin(bad) + 1) + 2] = std::numeric_limits<float>::quiet_NaN();
                const Result r = cluster(c, t, mode, threads);
                CHECK(r.status == HZ_E_FORMAT);
                CHECK_THAT(r.message, Catch::Contains("streamline " + std::to_string(bad) + " has a non-finite coordinate at vertex " +
                                                      std::to_string(t.begin(bad) + 1)));
            }
}

TEST_CASE("QuickBundlesX cancelled halfway through on two threads stops cleanly") {
    const hz_clustering &c = qbx();
    const Tractogram t = phantom(30000);
    for (const double mode : {0.0, 1.0}) {
        CAPTURE(mode);
        Task task;
        double last = 0;
        task.on_progress = [&](double f, const char *) {
            last = f;
            if (f > 0.4) task.cancel();
        };
        const Result r = cluster(c, t, mode, 2, nullptr, task.get());
        CHECK(r.status == HZ_E_CANCELLED);
        CHECK(last > 0.4);
        CHECK(last < 1.0);
        // The clusterer is still usable afterwards, with the same answer as ever.
        CHECK(cluster(c, t, mode, 2).members == cluster(c, t, mode, 1).members);
    }
}

namespace {

// Per level 1..L, each streamline's node (-1 where none holds it).
std::vector<std::vector<std::int64_t>> labels_by_level(const Result &r, std::uint64_t n) {
    const std::uint32_t L = r.level.empty() ? 0 : *std::max_element(r.level.begin(), r.level.end());
    std::vector<std::vector<std::int64_t>> out(L, std::vector<std::int64_t>(n, -1));
    for (std::size_t k = 0; k < r.parent.size(); ++k)
        if (r.level[k] >= 1)
            for (std::uint64_t m = r.offsets[k]; m < r.offsets[k + 1]; ++m) out[r.level[k] - 1][r.members[m]] = std::int64_t(k);
    return out;
}

// The fraction of streamlines whose cluster in `a` maps to their cluster in
// `b` when each a-cluster maps to the b-cluster holding most of its members
// (bench/cluster_bench.py's matched_fraction).
double matched_fraction(const std::vector<std::int64_t> &a, const std::vector<std::int64_t> &b) {
    std::vector<std::pair<std::int64_t, std::int64_t>> pairs(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) pairs[i] = {a[i], b[i]};
    std::sort(pairs.begin(), pairs.end());
    std::uint64_t matched = 0;
    for (std::size_t i = 0; i < pairs.size();) {  // per a-cluster, its largest run of one b-cluster
        std::uint64_t best = 0;
        const std::int64_t ca = pairs[i].first;
        while (i < pairs.size() && pairs[i].first == ca) {
            std::size_t j = i;
            while (j < pairs.size() && pairs[j] == pairs[i]) ++j;
            best = std::max<std::uint64_t>(best, j - i);
            i = j;
        }
        matched += best;
    }
    return a.empty() ? 1.0 : double(matched) / double(a.size());
}

}  // namespace

// Highway dispatches the plugin's kernels to the best target the CPU runs
// (AVX-512 on this project's machines); most users' CPUs take another
// (AVX2, SSE4). Each target this CPU can run is forced in turn (the test and
// the plugin share libhwy's choice): exact mode must give the same tree bit
// for bit at every one (its arithmetic does not follow the vector width),
// fast mode the same tree on one thread and two, with >= 99.9 % of the
// streamlines in exact mode's clusters at every level.
TEST_CASE("QuickBundlesX at every SIMD target the CPU runs: exact mode the same tree, fast mode within 0.1 % of it") {
    const hz_clustering &c = qbx();
    const Tractogram t = phantom(30000);
    const std::uint64_t n = t.nb_streamlines();
    const Result exact = cluster(c, t, 0, 2);
    REQUIRE(exact.status == HZ_OK);
    const auto exact_labels = labels_by_level(exact, n);
    REQUIRE(exact_labels.size() == 4);
    const std::size_t nb_targets = hz::test::simd_targets().size();
#if defined(__x86_64__)
    CHECK(nb_targets >= 2);  // (SSE4 and AVX2 at least, on any x86-64 CPU of the last decade)
#endif
    std::vector<float> first_fast;
    bool widths_differ = false;
    hz::test::for_each_simd_target([&](const char *) {
        const Result e = cluster(c, t, 0, 2);
        REQUIRE(e.status == HZ_OK);
        CHECK(e.parent == exact.parent);
        CHECK(e.members == exact.members);
        CHECK(std::memcmp(e.centroids.data(), exact.centroids.data(), exact.centroids.size() * sizeof(float)) == 0);
        const Result one = cluster(c, t, 1, 1), two = cluster(c, t, 1, 2);
        REQUIRE(one.status == HZ_OK);
        REQUIRE(two.status == HZ_OK);
        CHECK(one.parent == two.parent);
        CHECK(one.members == two.members);
        CHECK(one.centroids == two.centroids);
        const auto fast_labels = labels_by_level(two, n);
        REQUIRE(fast_labels.size() == exact_labels.size());
        for (std::size_t l = 0; l < exact_labels.size(); ++l) {
            CAPTURE(l + 1);
            CHECK(matched_fraction(fast_labels[l], exact_labels[l]) >= 0.999);
        }
        if (first_fast.empty())
            first_fast = two.centroids;
        else
            widths_differ = widths_differ || two.centroids != first_fast;
    });
    // The forcing reached the plugin: fast mode's float32 sums follow the
    // vector width, so its centroids are not the same at every width.
    if (nb_targets >= 2) CHECK(widths_differ);
}
