// Streamline selection (core/filter.hpp): the vector loops of every SIMD
// target answer what the scalar region test answers, vertex for vertex,
// including points on or within a rounding of a region's boundary.
#include "simd_targets.hpp"

#include <hz/core/filter.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <vector>

using namespace hz::core;

namespace {

// Streamlines of 37 vertices (lanes and a tail), far from everything
// except vertex `at` of each, which lies near the region's boundary.
Tractogram probes(const std::vector<std::array<float, 3>> &near, std::mt19937 &rng) {
    const std::uint64_t P = 37;
    Tractogram t;
    t.positions = Buffer<float>(near.size() * P * 3);
    t.offsets = Buffer<std::uint64_t>(near.size() + 1);
    std::uniform_int_distribution<std::uint64_t> pick(0, P - 1);
    for (std::size_t s = 0; s < near.size(); ++s) {
        t.offsets[s] = s * P;
        const std::uint64_t at = pick(rng);
        for (std::uint64_t v = 0; v < P; ++v)
            for (int i = 0; i < 3; ++i) t.positions[(s * P + v) * 3 + i] = v == at ? near[s][i] : 1000.0f + float(v);
    }
    t.offsets[near.size()] = near.size() * P;
    return t;
}

}  // namespace

TEST_CASE("filter: every SIMD target agrees with the scalar region test at the boundary", "[filter]") {
    std::mt19937 rng(7);
    std::normal_distribution<double> g(0, 1);
    Roi sphere;
    sphere.shape = Roi::Shape::Sphere;
    sphere.center = {1.25, -3.5, 7.125};
    sphere.radius = 4.1;
    Roi box;
    box.shape = Roi::Shape::Box;
    box.lo = {-2.3, 0.7, -1.1};
    box.hi = {3.9, 5.3, 2.2};
    for (const Roi *r : {&sphere, &box}) {
        std::vector<std::array<float, 3>> near;
        for (int k = 0; k < 4000; ++k) {
            std::array<float, 3> p;
            if (r == &sphere) {  // on the sphere, nudged by a few ulps either way
                double d[3] = {g(rng), g(rng), g(rng)};
                const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                for (int i = 0; i < 3; ++i) p[i] = float(r->center[i] + r->radius * d[i] / n);
                for (int i = 0; i < 3; ++i)
                    for (int u = int(rng() % 5); u > 0; --u) p[i] = std::nextafter(p[i], (rng() & 1) ? 1e9f : -1e9f);
            } else {  // on a face of the box, or just off it
                for (int i = 0; i < 3; ++i)
                    p[i] = float(r->lo[i] + (r->hi[i] - r->lo[i]) * std::uniform_real_distribution<double>(0, 1)(rng));
                const int axis = int(rng() % 3);
                p[axis] = float((rng() & 1) ? r->lo[axis] : r->hi[axis]);
                if (rng() & 1) p[axis] = std::nextafter(p[axis], (rng() & 1) ? 1e9f : -1e9f);
            }
            near.push_back(p);
        }
        const Tractogram t = probes(near, rng);
        std::vector<std::uint64_t> want;
        for (std::size_t s = 0; s < near.size(); ++s)
            if (r->contains(near[s].data())) want.push_back(s);
        REQUIRE(want.size() > 500);
        REQUIRE(want.size() < near.size() - 500);
        FilterSpec f;
        f.rois = {*r};
        hz::test::for_each_simd_target([&](const char *) {
            CHECK(filter_streamlines(t, f) == want);
            // Exclusion: exactly the others.
            FilterSpec x = f;
            x.rois[0].include = false;
            const std::vector<std::uint64_t> rest = filter_streamlines(t, x);
            CHECK(rest.size() + want.size() == near.size());
        });
    }
}

TEST_CASE("filter: the spatial grid selects exactly what the full scan selects", "[filter]") {
    // Random walks through a 100 mm box, regions of every kind near and
    // across cell boundaries, with and without invert and ends_only.
    std::mt19937 rng(11);
    std::normal_distribution<float> step(0.f, 1.f);
    std::uniform_real_distribution<float> u(-50.f, 50.f);
    const std::uint64_t S = 3000;
    Tractogram t;
    std::vector<float> pos;
    std::vector<std::uint64_t> offs{0};
    for (std::uint64_t s = 0; s < S; ++s) {
        float p[3] = {u(rng), u(rng), u(rng)};
        const int n = s % 97 == 0 ? 0 : 1 + int(rng() % 80);  // (some empty, some single points)
        for (int v = 0; v < n; ++v) {
            for (float &c : p) c += step(rng);
            pos.insert(pos.end(), p, p + 3);
        }
        offs.push_back(pos.size() / 3);
    }
    t.positions = Buffer<float>::copy_of(pos);
    t.offsets = Buffer<std::uint64_t>::copy_of(offs);
    const StreamlineGrid grid = StreamlineGrid::of(t, 6.0);
    REQUIRE(grid.ids.size() >= S / 2);
    auto sphere = [](double x, double y, double z, double r, bool inc) {
        Roi roi;
        roi.center = {x, y, z}, roi.radius = r, roi.include = inc;
        return roi;
    };
    Roi box;
    box.shape = Roi::Shape::Box;
    box.lo = {-12, -6, 0}, box.hi = {6, 18, 12};  // (faces on cell boundaries of the grid's origin plus multiples of 6 are likely)
    for (int trial = 0; trial < 40; ++trial) {
        FilterSpec f;
        const int kinds = trial % 4;
        f.rois.push_back(sphere(u(rng), u(rng), u(rng), 3 + (rng() % 20), kinds != 1));
        if (kinds >= 2) f.rois.push_back(sphere(u(rng), u(rng), u(rng), 5 + (rng() % 15), false));
        if (kinds == 3) f.rois.push_back(box);
        f.invert = trial % 5 == 0;
        f.ends_only = trial % 7 == 0;
        INFO("trial " << trial << ": " << f.describe());
        const std::vector<std::uint64_t> by_grid = filter_streamlines(t, f, nullptr, nullptr, &grid);
        CHECK(by_grid == filter_streamlines(t, f));
        // And against the documented rule written here again, vertex by
        // vertex (not Roi::contains, which both paths above share): float32
        // ((dx^2 + dy^2) + dz^2) <= r^2 for spheres, closed float32 bounds
        // for boxes; every include hit, no exclude hit, by the two ends only
        // with ends_only; empty streamlines never selected, invert or not.
        std::vector<std::uint64_t> want;
        for (std::uint64_t s = 0; s < S; ++s) {
            const std::uint64_t b = offs[s], e = offs[s + 1];
            if (b == e) continue;
            bool keep = true;
            for (const Roi &roi : f.rois) {
                bool hit = false;
                for (std::uint64_t v = b; v < e; ++v) {
                    if (f.ends_only && v != b && v != e - 1) continue;
                    const float *q = &pos[v * 3];
                    if (roi.shape == Roi::Shape::Sphere) {
                        const float dx = float(roi.center[0]) - q[0], dy = float(roi.center[1]) - q[1], dz = float(roi.center[2]) - q[2];
                        hit = hit || (dx * dx + dy * dy) + dz * dz <= float(roi.radius) * float(roi.radius);
                    } else {
                        bool in = true;
                        for (int k = 0; k < 3; ++k) in = in && q[k] >= float(roi.lo[k]) && q[k] <= float(roi.hi[k]);
                        hit = hit || in;
                    }
                }
                keep = keep && hit == roi.include;
            }
            if (keep != f.invert) want.push_back(s);
        }
        CHECK(by_grid == want);
    }
}
