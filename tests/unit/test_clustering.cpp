// The bundled QuickBundlesX plugin through its ABI table, on tractograms
// large enough (>= 20 000 streamlines) for its search to run on two threads
// and, in fast mode, to compute the features as it goes, in a ring shared by
// both threads: the tree must be the one-thread tree, an invalid streamline
// must stop the run with its index, and a cancellation must stop it cleanly.
#include <hz/core/phantom.hpp>
#include <hz/core/plugin_host.hpp>

#include <catch2/catch.hpp>

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

const hz_clustering &qbx(const Registry &reg) {
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
    Registry reg;
    reg.scan({HZ_TEST_PLUGIN_DIR});
    const hz_clustering &c = qbx(reg);
    const Tractogram t = phantom(30000);
    std::vector<std::uint64_t> shuffled(t.nb_streamlines());
    std::iota(shuffled.begin(), shuffled.end(), 0);
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937_64(3));
    for (const double mode : {0.0, 1.0})
        for (const std::uint64_t *order : std::vector<const std::uint64_t *>{nullptr, shuffled.data()}) {
            CAPTURE(mode, order != nullptr);
            const Result one = cluster(c, t, mode, 1), two = cluster(c, t, mode, 2);
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

TEST_CASE("an invalid streamline stops QuickBundlesX with its index, on one thread or two") {
    Registry reg;
    reg.scan({HZ_TEST_PLUGIN_DIR});
    const hz_clustering &c = qbx(reg);
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
    Registry reg;
    reg.scan({HZ_TEST_PLUGIN_DIR});
    const hz_clustering &c = qbx(reg);
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
