// The fibre volume (core/src/render/tractogram/line_geometry.hpp): per voxel, the
// streamlines' density, mean colour and main direction, and the distance to
// the nearest voxel with streamlines, as the renderer's ray march reads them.
#include "tractogram/line_geometry.hpp"

#include <hz/core/render/scene.hpp>

#include "polylines.hpp"

#include <catch2/catch.hpp>

#include <atomic>
#include <cmath>
#include <random>
#include <vector>

using namespace hz::core;
using namespace hz::core::render;

namespace {

FibreVolume volume_of(const Tractogram &t, const Bounds &b, int grid, double budget, unsigned threads, bool cancel = false) {
    Object o;
    o.kind = HZ_DATA_STREAMLINES;
    o.data.kind = HZ_DATA_STREAMLINES;
    o.data.tractogram = t.shared();
    o.coloring.mode = "direction";
    const auto d = line_data(o);
    std::atomic<bool> stop{cancel};
    return fibre_volume(*d, b, grid, budget, threads, stop);
}

Bounds box(double lo, double hi) {
    Bounds b;
    b.min = {lo, lo, lo}, b.max = {hi, hi, hi};
    b.empty = false;
    return b;
}

// A straight line of `n` points `step` mm apart from `from` along axis `axis`.
std::vector<float> straight(std::array<float, 3> from, int axis, int n, float step) {
    std::vector<float> l;
    for (int i = 0; i < n; ++i) {
        std::array<float, 3> p = from;
        p[axis] += float(i) * step;
        l.insert(l.end(), p.begin(), p.end());
    }
    return l;
}

}  // namespace

TEST_CASE("fibre volume: density, colour, direction and skip distance of known lines", "[render][lod]") {
    // A 10 mm box on a grid of 10: 1 mm voxels, one empty voxel around
    // (13 per side, voxel (i, j, k) holds [i - 1, i) x [j - 1, j) x [k - 1, k)).
    // Line 0 along x at y = z = 2.5 (voxels y = z = 3), 0.5 mm steps; line 1
    // along z at x = y = 7.5 (voxels x = y = 8).
    const Tractogram t = polylines({straight({0.25f, 2.5f, 2.5f}, 0, 20, 0.5f), straight({7.5f, 7.5f, 0.25f}, 2, 20, 0.5f)});
    const FibreVolume v = volume_of(t, box(0, 10), 10, 1e9, 2);
    REQUIRE(v.dim == std::array<int, 3>{13, 13, 13});
    CHECK(v.voxel_mm == Approx(1.0f));
    CHECK(v.origin[0] == Approx(-1.0f));
    auto at = [&](int x, int y, int z) { return (std::size_t(z) * 13 + y) * 13 + x; };
    // Two 0.5 mm segments' midpoints in voxel (5, 3, 3): 1 mm of streamline
    // in 1 mm^3, red (along x), main direction x.
    const std::size_t a = at(5, 3, 3);
    CHECK(v.colour_density[a * 4 + 3] == Approx(1.0f));
    CHECK(v.colour_density[a * 4 + 0] == Approx(1.0f));
    CHECK(v.colour_density[a * 4 + 1] == Approx(0.0f).margin(1e-6));
    CHECK(v.colour_density[a * 4 + 2] == Approx(0.0f).margin(1e-6));
    CHECK(int(v.direction[a * 4 + 0]) == 255);
    CHECK(int(v.direction[a * 4 + 1]) == 128);
    CHECK(int(v.direction[a * 4 + 2]) == 128);
    CHECK(int(v.direction[a * 4 + 3]) == 255);  // all along it
    CHECK(int(v.skip[a]) == 0);
    // Line 1: blue, along z.
    const std::size_t b = at(8, 8, 6);
    CHECK(v.colour_density[b * 4 + 3] == Approx(1.0f));
    CHECK(v.colour_density[b * 4 + 2] == Approx(1.0f));
    CHECK(v.colour_density[b * 4 + 0] == Approx(0.0f).margin(1e-6));
    CHECK(int(v.direction[b * 4 + 2]) == 255);
    CHECK(int(v.direction[b * 4 + 0]) == 128);
    // Empty voxels: no density, and their Chebyshev distance to line 0 or 1.
    const std::size_t e1 = at(5, 4, 4), e2 = at(5, 3, 5), e3 = at(0, 12, 0);
    CHECK(v.colour_density[e1 * 4 + 3] == 0.0f);
    CHECK(int(v.skip[e1]) == 1);
    CHECK(int(v.skip[e2]) == 2);
    CHECK(int(v.skip[e3]) == 8);  // to line 1's (8, 8, 1): max(8, 4, 1)
    // All the length is there: 19 segments of 0.5 mm each.
    double total = 0;
    for (std::size_t k = 0; k < v.colour_density.size() / 4; ++k) total += v.colour_density[k * 4 + 3];
    CHECK(total == Approx(2 * 19 * 0.5));
}

TEST_CASE("fibre volume: a subsample above the budget weighs up to the same density, and cancel gives none", "[render][lod]") {
    std::mt19937 rng(7);
    std::normal_distribution<float> step(0.0f, 0.4f);
    std::uniform_real_distribution<float> start(10.0f, 30.0f);
    std::vector<std::vector<float>> lines;
    for (int s = 0; s < 4000; ++s) {
        std::vector<float> l;
        float p[3] = {start(rng), start(rng), start(rng)};
        for (int i = 0; i < 50; ++i) {
            l.insert(l.end(), p, p + 3);
            for (float &c : p) c = std::clamp(c + step(rng), 0.0f, 40.0f);
        }
        lines.push_back(std::move(l));
    }
    const Tractogram t = polylines(lines);
    const FibreVolume all = volume_of(t, box(0, 40), 20, 1e9, 1);
    const FibreVolume some = volume_of(t, box(0, 40), 20, 50000, 2);  // a quarter of the 200,000 points
    REQUIRE(all.colour_density.size() == some.colour_density.size());
    double sa = 0, ss = 0, diff = 0;
    for (std::size_t k = 0; k < all.colour_density.size() / 4; ++k) {
        sa += all.colour_density[k * 4 + 3], ss += some.colour_density[k * 4 + 3];
        diff += std::abs(all.colour_density[k * 4 + 3] - some.colour_density[k * 4 + 3]);
    }
    CHECK(ss == Approx(sa).epsilon(0.05));  // the same total length, within the subsample's spread
    CHECK(ss != Approx(sa).epsilon(1e-6));  // (and it is a subsample)
    CHECK(diff / sa < 0.6);                 // voxel by voxel, the same within its noise (measured 0.41)
    CHECK(volume_of(t, box(0, 40), 20, 1e9, 2, true).empty());
}
