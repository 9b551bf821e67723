// Picking (core/render/pick.hpp): the streamline under a window point.
#include <hz/core/render/pick.hpp>

#include "polylines.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

using namespace hz::core;
using render::pick_streamline;

namespace {

// Looking down -z at the origin from 100 mm, 200 x 100 pixels: the origin is
// at pixel (100, 50); 1 mm at depth 100 mm is 50 / tan(15 deg) / 100 pixels.
render::View down_z() {
    render::View v;
    v.eye = {0, 0, 100};
    v.target = {0, 0, 0};
    v.up = {0, 1, 0};
    v.fov_deg = 30;
    v.near_mm = 1;
    v.far_mm = 1000;
    return v;
}
const double kPxPerMm = 50.0 / std::tan(15.0 * M_PI / 180.0) / 100.0;  // 1.866

}  // namespace

TEST_CASE("view_projection puts the target at the centre and w at the depth", "[pick]") {
    const auto m = render::view_projection(down_z(), 200, 100);
    // The point (0, 0, -50): depth 150 along the view axis.
    const double w = m[3] * 0 + m[7] * 0 + m[11] * -50 + m[15];
    CHECK(w == Approx(150));
    CHECK(m[12] / m[15] == Approx(0).margin(1e-12));  // target -> ndc x 0
}

TEST_CASE("pick_streamline finds the streamline under the point", "[pick]") {
    const Tractogram t = polylines({{-10, 0, 0, 10, 0, 0}, {-10, 5, 0, 10, 5, 0}});
    const auto v = down_z();
    auto hit = pick_streamline(t, {}, v, 200, 100, 100, 50);
    REQUIRE(hit);
    CHECK(hit->streamline == 0);
    CHECK(hit->pixels == Approx(0).margin(1e-9));
    CHECK(hit->depth_mm == Approx(100));
    // y = 5 mm is 9.33 pixels up the screen (y down): beyond 6 px of tolerance
    // from the point below it, within 10.
    const double up = 5 * kPxPerMm;
    hit = pick_streamline(t, {}, v, 200, 100, 100, 50 - up + 0.5);
    REQUIRE(hit);
    CHECK(hit->streamline == 1);
    CHECK(hit->pixels == Approx(0.5).epsilon(1e-6));
    CHECK_FALSE(pick_streamline(t, {}, v, 200, 100, 100, 50 + 7));
    hit = pick_streamline(t, {}, v, 200, 100, 100, 50 + 7, 10.0);
    REQUIRE(hit);
    CHECK(hit->streamline == 0);
    // Beyond the ends, and off the window.
    CHECK_FALSE(pick_streamline(t, {}, v, 200, 100, 100 + 10 * kPxPerMm + 7, 50));
    CHECK_FALSE(pick_streamline(Tractogram{}, {}, v, 200, 100, 100, 50));
    CHECK_FALSE(pick_streamline(t, {}, v, 0, 0, 100, 50));
}

TEST_CASE("pick_streamline: tubes nearer the eye win where the point is on both", "[pick]") {
    // Two crossing tubes of radius 1 mm: streamline 0 at z = 0 (depth 100),
    // streamline 1 at z = 20 (depth 80), listed after it.
    const Tractogram t = polylines({{-10, 0, 0, 10, 0, 0}, {0, -10, 20, 0, 10, 20}});
    const std::vector<float> radius{1.0f, 1.0f};
    auto hit = pick_streamline(t, radius, down_z(), 200, 100, 100, 50);
    REQUIRE(hit);
    CHECK(hit->streamline == 1);
    CHECK(hit->depth_mm == Approx(80));
    // Off streamline 1's tube but on streamline 0's: streamline 0, although
    // streamline 1's axis passes within the tolerance.
    hit = pick_streamline(t, radius, down_z(), 200, 100, 100 + 4, 50);
    REQUIRE(hit);
    CHECK(hit->streamline == 0);
    // The tube's projected radius counts: 3 mm wide at depth 100 is 5.6 px.
    const std::vector<float> wide{3.0f, 0.0f};
    hit = pick_streamline(t, wide, down_z(), 200, 100, 110, 50 + 3 * kPxPerMm + 5);
    REQUIRE(hit);
    CHECK(hit->streamline == 0);
    CHECK_FALSE(pick_streamline(t, wide, down_z(), 200, 100, 110, 50 + 3 * kPxPerMm + 7));
}

TEST_CASE("pick_streamline clips at the near plane and takes single points", "[pick]") {
    const auto v = down_z();
    // From x = 5 mm at depth 100 to a point 99 mm behind the eye: drawn from
    // 9.3 px right of the centre off to the right edge. Projected without
    // clipping, its far end would land 9.4 px left of the centre, and the
    // segment would cross the centre.
    const Tractogram t = polylines({{5, 0, 0, 5, 0, 199}});
    CHECK_FALSE(pick_streamline(t, {}, v, 200, 100, 95, 50, 1.0));
    CHECK_FALSE(pick_streamline(t, {}, v, 200, 100, 100, 50, 1.0));
    auto hit = pick_streamline(t, {}, v, 200, 100, 150, 50, 1.0);
    REQUIRE(hit);
    CHECK(hit->depth_mm < 100);
    // Entirely behind the eye: nothing.
    CHECK_FALSE(pick_streamline(polylines({{0, 0, 150, 1, 0, 150}}), {}, v, 200, 100, 100, 50, 50.0));
    // One point at the origin.
    hit = pick_streamline(polylines({{0, 0, 0}}), {}, v, 200, 100, 101, 50);
    REQUIRE(hit);
    CHECK(hit->pixels == Approx(1));
}

TEST_CASE("streamlines_crossing picks exactly what a stroke crosses", "[pick]") {
    // Vertical streamlines (along y) at x = -8, -4, 0, 4, 8 mm, 10 mm long,
    // seen from above: on screen, vertical lines at 100 + 1.866 x pixels,
    // from y = 50 - 9.33 to 50 + 9.33. A horizontal stroke at y = 50 from
    // pixel 95 to 110 (x from -2.7 to 5.4 mm) crosses those at 0 and 4; one
    // that ends just short of x = 8 (pixel 114.9) does not cross it; one
    // above the streamlines' ends (y = 35) crosses none; a stroke's vertex on
    // a streamline counts (touching).
    std::vector<std::vector<float>> lines;
    for (float x : {-8.f, -4.f, 0.f, 4.f, 8.f}) lines.push_back({x, -5, 0, x, 5, 0});  // (one segment each: strokes cross it inside)
    lines.push_back({20, 0, 0});                                                       // (a single point, off every stroke)
    const Tractogram t = polylines(lines);
    const auto v = down_z();
    using P = std::array<double, 2>;
    auto cross = [&](std::vector<P> stroke) { return render::streamlines_crossing(t, v, 200, 100, stroke); };
    CHECK(cross({{95, 50}, {110, 50}}) == std::vector<std::uint64_t>{2, 3});
    CHECK(cross({{95, 50}, {114.8, 50}}) == std::vector<std::uint64_t>{2, 3});
    CHECK(cross({{95, 50}, {115.2, 50}}) == std::vector<std::uint64_t>{2, 3, 4});
    CHECK(cross({{80, 35}, {120, 35}}).empty());
    CHECK(cross({{80, 45}, {100, 45}, {100, 60}}) == std::vector<std::uint64_t>{0, 1, 2});  // (a polyline; its corner lies on streamline 2)
    CHECK(cross({{100, 45}, {104, 47}}) == std::vector<std::uint64_t>{2});                  // (it only touches streamline 2)
    CHECK(cross({{100, 50}}).empty());                                                      // (one point is no stroke)
}

namespace {

// The reference of streamlines_crossing: every segment of every streamline
// clipped to the near plane, projected and tested against every segment of
// the stroke, nothing skipped.
std::vector<std::uint64_t> crossing_reference(const Tractogram &t, const render::View &v, int w, int h,
                                              const std::vector<std::array<double, 2>> &stroke) {
    const auto m = render::view_projection(v, w, h);
    auto clip = [&](const float *p) {
        std::array<double, 4> c{};
        for (int r = 0; r < 4; ++r) c[r] = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
        return c;
    };
    auto cross2 = [](double ax, double ay, double bx, double by, double cx, double cy) {
        return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    };
    auto meet = [&](double ax, double ay, double bx, double by, double cx, double cy, double dx, double dy) {
        const double d1 = cross2(ax, ay, bx, by, cx, cy), d2 = cross2(ax, ay, bx, by, dx, dy);
        const double d3 = cross2(cx, cy, dx, dy, ax, ay), d4 = cross2(cx, cy, dx, dy, bx, by);
        return ((d1 > 0) != (d2 > 0) || d1 == 0 || d2 == 0) && ((d3 > 0) != (d4 > 0) || d3 == 0 || d4 == 0);
    };
    std::vector<std::uint64_t> out;
    for (std::uint64_t s = 0; s < t.nb_streamlines(); ++s) {
        bool hit = false;
        for (std::uint64_t i = t.begin(s) + 1; i < t.end(s) && !hit; ++i) {
            auto a = clip(&t.positions[3 * (i - 1)]), b = clip(&t.positions[3 * i]);
            if (a[3] < v.near_mm && b[3] < v.near_mm) continue;
            auto at = [](std::array<double, 4> p, std::array<double, 4> q, double f) {
                for (int r = 0; r < 4; ++r) p[r] += (q[r] - p[r]) * f;
                return p;
            };
            if (a[3] < v.near_mm) a = at(a, b, (v.near_mm - a[3]) / (b[3] - a[3]));
            if (b[3] < v.near_mm) b = at(b, a, (v.near_mm - b[3]) / (a[3] - b[3]));
            const double ax = (a[0] / a[3] * 0.5 + 0.5) * w, ay = (0.5 - a[1] / a[3] * 0.5) * h;
            const double bx = (b[0] / b[3] * 0.5 + 0.5) * w, by = (0.5 - b[1] / b[3] * 0.5) * h;
            for (std::size_t k = 1; k < stroke.size() && !hit; ++k)
                hit = meet(ax, ay, bx, by, stroke[k - 1][0], stroke[k - 1][1], stroke[k][0], stroke[k][1]);
        }
        if (hit) out.push_back(s);
    }
    return out;
}

}  // namespace

TEST_CASE("streamlines_crossing agrees with every segment tested, on random walks around the camera", "[pick]") {
    // 400 random walks of 1-300 points through a box that holds the eye:
    // many segments cross the near plane or lie behind it.
    std::uint64_t state = 12345;
    auto uniform = [&] {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return double(state >> 11) / double(1ull << 53);
    };
    std::vector<std::vector<float>> lines;
    for (int s = 0; s < 400; ++s) {
        std::vector<float> l;
        double p[3] = {uniform() * 60 - 30, uniform() * 60 - 30, uniform() * 140 - 20};
        const int n = 1 + int(uniform() * 300);
        for (int i = 0; i < n; ++i) {
            for (int k = 0; k < 3; ++k) l.push_back(float(p[k])), p[k] += uniform() * 3 - 1.5;
        }
        lines.push_back(l);
    }
    const Tractogram t = polylines(lines);
    const auto v = down_z();  // (the eye at z = 100, inside the walks' box)
    using P = std::array<double, 2>;
    const std::vector<std::vector<P>> strokes = {{{20, 10}, {180, 90}},
                                                 {{100, 5}, {100, 95}},
                                                 {{30, 50}, {60, 20}, {150, 80}, {170, 30}},
                                                 {{99, 49}, {101, 51}},
                                                 {{-50, 50}, {250, 50}}};
    std::size_t picked = 0;
    for (const auto &stroke : strokes) {
        const auto ours = render::streamlines_crossing(t, v, 200, 100, stroke);
        CHECK(ours == crossing_reference(t, v, 200, 100, stroke));
        picked += ours.size();
    }
    CHECK(picked > 100);               // (the strokes do cross many)
    CHECK(picked < 5 * lines.size());  // (and not all of them)
    // A segment from the left of the picture to a point just behind the
    // eye, on its right: clipped, it runs off to the right across the
    // centre (unclipped, both its ends would project to the left).
    const Tractogram across = polylines({{-20, 0, 50, 5, 0, 101}});
    const std::vector<P> centre = {{100, 40}, {100, 60}};
    CHECK(render::streamlines_crossing(across, v, 200, 100, centre) == std::vector<std::uint64_t>{0});
    CHECK(crossing_reference(across, v, 200, 100, centre) == std::vector<std::uint64_t>{0});
}

TEST_CASE("ray_mesh finds the nearest triangle along a ray", "[pick]") {
    Mesh m;
    // Two triangles across the z axis, at z = 10 and z = 30, and one beside it.
    m.vertices = Buffer<float>{-1, -1, 10, 1, -1, 10, 0, 1, 10, -1, -1, 30, 1, -1, 30, 0, 1, 30, 5, 5, 0, 6, 5, 0, 5, 6, 0};
    m.faces = Buffer<std::uint32_t>{3, 4, 5, 0, 1, 2, 6, 7, 8};
    const auto t = render::ray_mesh(m, {0, 0, 0}, {0, 0, 1});
    REQUIRE(t);
    CHECK(*t == Approx(10));
    CHECK(*render::ray_mesh(m, {0, 0, 20}, {0, 0, 1}) == Approx(10));  // (t from the origin given)
    CHECK_FALSE(render::ray_mesh(m, {0, 0, 40}, {0, 0, 1}));           // (everything behind)
    CHECK_FALSE(render::ray_mesh(m, {3, 3, 0}, {0, 0, 1}));            // (beside every triangle)
}
