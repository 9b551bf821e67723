// Streamline decimation at a screen tolerance (core/render/decimate.hpp).
#include <hz/core/render/decimate.hpp>

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using hz::core::render::decimate;
using hz::core::render::kDecimateWindow;

namespace {

// Distance from q to the segment a-b, the plain way (a projection clamped to
// the segment), in double.
double segment_distance(const float *q, const float *a, const float *b) {
    double d[3], w[3];
    for (int k = 0; k < 3; ++k) d[k] = double(b[k]) - a[k], w[k] = double(q[k]) - a[k];
    const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    const double t = dd > 0 ? std::clamp((w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd, 0.0, 1.0) : 0.0;
    double e = 0;
    for (int k = 0; k < 3; ++k) e += (w[k] - t * d[k]) * (w[k] - t * d[k]);
    return std::sqrt(e);
}

// The greedy rule written the obvious way: the segment from a grows to j
// while every point between lies within tol of it and it spans at most the
// window.
std::vector<std::uint32_t> reference(const std::vector<float> &p, double tol) {
    const std::uint64_t n = p.size() / 3;
    std::vector<std::uint32_t> keep{0};
    if (n < 2) return keep;
    std::uint64_t a = 0;
    for (std::uint64_t j = 2; j < n; ++j) {
        bool ok = j - a <= kDecimateWindow;
        for (std::uint64_t m = a + 1; ok && m < j; ++m) ok = segment_distance(&p[m * 3], &p[a * 3], &p[j * 3]) <= tol;
        if (!ok) keep.push_back(std::uint32_t(a = j - 1));
    }
    keep.push_back(std::uint32_t(n - 1));
    return keep;
}

// A random walk with momentum: smooth stretches, sharp turns, repeated
// points and reversals (the cases the distance rule must get right).
std::vector<float> walk(std::mt19937 &rng, int n) {
    std::normal_distribution<float> g(0, 1);
    std::uniform_real_distribution<float> u(0, 1);
    std::vector<float> p;
    float x = 0, y = 0, z = 0, vx = 0.7f, vy = 0, vz = 0;
    for (int i = 0; i < n; ++i) {
        p.insert(p.end(), {x, y, z});
        const float r = u(rng);
        if (r < 0.05f) continue;                                           // a repeated point
        if (r < 0.08f) vx = -vx, vy = -vy, vz = -vz;                       // a reversal
        vx += 0.15f * g(rng), vy += 0.15f * g(rng), vz += 0.15f * g(rng);  // a slow turn
        x += vx, y += vy, z += vz;
    }
    return p;
}

}  // namespace

TEST_CASE("decimation keeps every dropped point within the tolerance of its segment", "[render][decimate]") {
    std::mt19937 rng(7);
    std::vector<std::uint32_t> keep;
    for (double tol : {0.01, 0.125, 0.5, 2.0, 50.0})
        for (int trial = 0; trial < 200; ++trial) {
            const auto p = walk(rng, 2 + int(rng() % 300));
            const std::uint64_t n = p.size() / 3;
            decimate(p.data(), n, tol, keep);
            REQUIRE(keep.front() == 0);
            REQUIRE(keep.back() == n - 1);
            for (std::size_t k = 0; k + 1 < keep.size(); ++k) {
                REQUIRE(keep[k] < keep[k + 1]);
                REQUIRE(keep[k + 1] - keep[k] <= kDecimateWindow);
                for (std::uint32_t m = keep[k] + 1; m < keep[k + 1]; ++m)
                    REQUIRE(segment_distance(&p[m * 3], &p[keep[k] * 3], &p[keep[k + 1] * 3]) <= tol * (1 + 1e-12));
            }
            // The same points as the greedy rule written plainly.
            REQUIRE(keep == reference(p, tol));
        }
}

TEST_CASE("decimation of short, straight and degenerate polylines", "[render][decimate]") {
    std::vector<std::uint32_t> keep;
    decimate(nullptr, 0, 1.0, keep);
    CHECK(keep.empty());
    const std::vector<float> one{1, 2, 3};
    decimate(one.data(), 1, 1.0, keep);
    CHECK(keep == std::vector<std::uint32_t>{0});
    // A straight line of 200 points: one segment per window.
    std::vector<float> line;
    for (int i = 0; i < 200; ++i) line.insert(line.end(), {float(i), 0, 0});
    decimate(line.data(), 200, 0.1, keep);
    CHECK(keep == std::vector<std::uint32_t>{0, 64, 128, 192, 199});
    // Every point when the tolerance is zero or NaN.
    decimate(line.data(), 5, 0.0, keep);
    CHECK(keep == std::vector<std::uint32_t>{0, 1, 2, 3, 4});
    decimate(line.data(), 5, std::nan(""), keep);
    CHECK(keep.size() == 5);
    // A point repeated many times, and a streamline that goes back on itself:
    // the turning point is kept (the segment from the start to the end would
    // pass 10 mm from it).
    const std::vector<float> same(3 * 50, 4.0f);
    decimate(same.data(), 50, 0.5, keep);
    CHECK(keep == std::vector<std::uint32_t>{0, 49});
    std::vector<float> back;
    for (int i = 0; i <= 10; ++i) back.insert(back.end(), {float(i), 0, 0});
    for (int i = 9; i >= 0; --i) back.insert(back.end(), {float(i), 0, 0});
    decimate(back.data(), back.size() / 3, 0.5, keep);
    CHECK(std::find(keep.begin(), keep.end(), 10u) != keep.end());
}
