// The slab's crossings (core/src/render/tractogram/line_geometry.hpp): where each
// streamline crosses the plane axis = centre, as the renderer draws them.
#include "tractogram/line_geometry.hpp"

#include <hz/core/render/scene.hpp>

#include "polylines.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <vector>

using namespace hz::core;
using namespace hz::core::render;

namespace {

std::vector<LineVertex> crossings(const Tractogram &t, int axis, double c, const std::string &colour = "direction") {
    Object o;
    o.kind = HZ_DATA_STREAMLINES;
    o.data.kind = HZ_DATA_STREAMLINES;
    o.data.tractogram = t.shared();
    o.coloring.mode = colour;
    const auto d = line_data(o);
    std::vector<LineVertex> out;
    slab_crossings(*d, axis, c, 0, t.nb_streamlines(), out, nullptr);
    return out;
}

}  // namespace

TEST_CASE("slab crossings: the point, the direction and the colour of each crossing", "[render][slab]") {
    // 0: along +z through z = 0.25 once; 1: a U-turn in z that crosses twice;
    // 2: never reaches the plane; 3: a point exactly on the plane (counted
    // once, on the segment that reaches the upper side); 4: one point only.
    const Tractogram t = polylines(
        {{1, 2, -1, 1, 2, 0, 1, 2, 1}, {0, 0, -1, 1, 0, 1, 2, 0, -1}, {5, 5, 3, 5, 5, 4}, {0, 0, -1, 0, 0, 0.25f, 0, 0, 1}, {9, 9, 9}});
    const auto v = crossings(t, 2, 0.25);
    REQUIRE(v.size() == 4);
    // streamline 0: from (1, 2, 0) to (1, 2, 1), a quarter of the way
    CHECK(v[0].pos[0] == Approx(1));
    CHECK(v[0].pos[1] == Approx(2));
    CHECK(v[0].pos[2] == 0.25f);
    CHECK(v[0].rgba[0] == 0);
    CHECK(v[0].rgba[1] == 0);
    CHECK(v[0].rgba[2] == 255);  // direction colouring: along z, blue
    // streamline 1: up at x = 0.625, down at x = 1.375
    CHECK(v[1].pos[0] == Approx(0.625));
    CHECK(v[2].pos[0] == Approx(1.375));
    CHECK(v[1].pos[2] == 0.25f);
    CHECK(v[2].pos[2] == 0.25f);
    // the crossing segment runs along (1, 0, 2): more blue than red, no green
    CHECK(v[1].rgba[2] > v[1].rgba[0]);
    CHECK(v[1].rgba[0] > 0);
    CHECK(v[1].rgba[1] == 0);
    // streamline 3: the point on the plane itself
    CHECK(v[3].pos[0] == 0);
    CHECK(v[3].pos[2] == 0.25f);
    // other axes
    CHECK(crossings(t, 0, 0.5).size() == 1);  // only streamline 1 goes across x = 0.5 (from 0 to 1)
    CHECK(crossings(t, 1, 1.0).empty());      // y is 0, 2 or 5 throughout
    // a solid colour is the object's colour at every crossing
    const auto s = crossings(t, 2, 0.25, "solid");
    REQUIRE(s.size() == 4);
    for (const auto &x : s) CHECK((x.rgba[0] == s[0].rgba[0] && x.rgba[1] == s[0].rgba[1] && x.rgba[2] == s[0].rgba[2]));
}

TEST_CASE("slab crossings: as many as sign changes along each streamline, on random walks", "[render][slab]") {
    std::mt19937 rng(7);
    std::normal_distribution<float> step(0.0f, 1.0f);
    std::vector<std::vector<float>> lines;
    for (int s = 0; s < 200; ++s) {
        std::vector<float> l;
        float p[3] = {0, 0, float(s % 7) - 3};
        const int n = 2 + s % 50;
        for (int i = 0; i < n; ++i) {
            for (float &x : p) x += step(rng);
            l.insert(l.end(), p, p + 3);
        }
        lines.push_back(l);
    }
    const Tractogram t = polylines(lines);
    for (int axis = 0; axis < 3; ++axis)
        for (double c : {-1.5, 0.0, 2.0}) {
            std::size_t expected = 0;
            for (const auto &l : lines)
                for (std::size_t i = 1; i < l.size() / 3; ++i)
                    expected += (l[(i - 1) * 3 + axis] < float(c)) != (l[i * 3 + axis] < float(c));
            const auto v = crossings(t, axis, c);
            CHECK(v.size() == expected);
            for (const auto &x : v) CHECK(x.pos[axis] == float(c));
        }
}
