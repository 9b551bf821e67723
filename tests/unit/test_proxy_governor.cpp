// The proxy's levels (renderer.hpp: proxy_levels) and the governor that
// picks one from a window's moving frame times (proxy_governor.hpp).
#include <hz/core/render/proxy_governor.hpp>
#include <hz/core/render/renderer.hpp>

#include <catch2/catch.hpp>

using namespace hz::core::render;

TEST_CASE("proxy levels: coarser and finer around the base, cheapest first", "[lod]") {
    const auto L = proxy_levels(4, 2e5);
    REQUIRE(L.size() == 7);
    const int scales[] = {8, 8, 4, 2, 2, 1, 1};
    const double points[] = {1e5, 2e5, 2e5, 2e5, 4e5, 4e5, 8e5};
    for (std::size_t i = 0; i < L.size(); ++i) {
        CHECK(L[i].scale == scales[i]);
        CHECK(L[i].points == points[i]);
    }
    CHECK(proxy_base_level(4, 2e5) == 2);
    // At scale 1 the finer levels only add points; at 16 the coarser only drop them.
    const auto F = proxy_levels(1, 1e5);
    REQUIRE(F.size() == 5);
    CHECK((F[2].scale == 1 && F[2].points == 1e5));
    CHECK((F[3].scale == 1 && F[3].points == 2e5 && F[4].points == 4e5));
    const auto C = proxy_levels(16, 1e5);
    CHECK((C[0].scale == 16 && C[0].points == 2.5e4 && C[1].points == 5e4));
}

namespace {
// Feeds `n` frames of `ms` each; returns the level after them.
int feed(ProxyGovernor &g, int n, double ms) {
    for (int i = 0; i < n; ++i) g.add(ms);
    return g.level();
}
}  // namespace

TEST_CASE("proxy governor: slow frames go coarser, down to the cheapest level", "[lod]") {
    constexpr int slow = ProxyGovernor::kSlowFrames;
    ProxyGovernor g(33, 7, 2);
    CHECK(feed(g, slow - 1, 50) == 2);  // (not yet a median of kSlowFrames)
    CHECK(feed(g, 1, 50) == 1);
    CHECK(feed(g, 1, 50) == 1);  // (the first frame at a new level is not counted)
    CHECK(feed(g, slow, 50) == 0);
    CHECK(feed(g, 20, 50) == 0);
    // One slow frame among fast ones is not enough.
    ProxyGovernor h(33, 7, 2);
    for (double ms : {30.0, 90.0, 30.0, 30.0, 90.0, 30.0, 30.0, 90.0}) h.add(ms);
    CHECK(h.level() == 2);
}

TEST_CASE("proxy governor: fast frames go finer, up to the finest level", "[lod]") {
    ProxyGovernor g(33, 7, 2);
    CHECK(feed(g, 7, 10) == 2);  // (eight frames under 0.8 x the budget)
    CHECK(feed(g, 1, 10) == 3);
    CHECK(feed(g, 9, 10) == 4);
    CHECK(feed(g, 100, 10) == 6);
    // Frames between 0.8 x the budget and the budget keep the level.
    ProxyGovernor k(33, 7, 2);
    CHECK(feed(k, 100, 30) == 2);
}

TEST_CASE("proxy governor: a level found too slow is on hold, longer each time", "[lod]") {
    ProxyGovernor g(33, 7, 2);
    CHECK(feed(g, 8, 20) == 3);                               // fast: tries level 3
    CHECK(feed(g, 1 + ProxyGovernor::kSlowFrames, 40) == 2);  // too slow there: back
    CHECK(g.hold(3) == ProxyGovernor::kHoldFrames);
    CHECK(feed(g, ProxyGovernor::kHoldFrames - 1, 20) == 2);  // fast, but 3 is on hold
    CHECK(g.hold(3) == 1);
    CHECK(feed(g, 1, 20) == 3);                               // the hold is over: tried again
    CHECK(feed(g, 1 + ProxyGovernor::kSlowFrames, 40) == 2);  // slow again: held twice as long
    CHECK(g.hold(3) == 2 * ProxyGovernor::kHoldFrames);
    CHECK(feed(g, 2 * ProxyGovernor::kHoldFrames - 1, 20) == 2);
    CHECK(feed(g, 1, 20) == 3);
}

TEST_CASE("proxy governor: a budget of 0 never changes the level", "[lod]") {
    ProxyGovernor g(0, 7, 2);
    CHECK(feed(g, 50, 500) == 2);
    CHECK(feed(g, 50, 1) == 2);
    ProxyGovernor one(33, 1, 5);  // (one level: clamped to it)
    CHECK(feed(one, 20, 500) == 0);
    CHECK(feed(one, 20, 1) == 0);
}

TEST_CASE("proxy governor: the finest level it may step to is capped, and lowering the cap moves down at once", "[lod]") {
    ProxyGovernor g(33, 8, 2);  // (levels 0-6 the proxy's, 7 the window's full detail)
    CHECK(g.finest() == 7);
    g.set_finest(6);
    CHECK(feed(g, 200, 10) == 6);  // fast frames stop under the cap
    g.set_finest(7);
    CHECK(feed(g, 9, 10) == 7);  // the cap raised: the next fast frames go there
    g.set_finest(6);
    CHECK(g.level() == 6);        // lowered below the level: there at once
    CHECK(feed(g, 1, 500) == 6);  // (the first frame after the change is not counted)
    g.set_finest(-3);
    CHECK((g.finest() == 0 && g.level() == 0));
    g.set_finest(99);
    CHECK(g.finest() == 7);
}
