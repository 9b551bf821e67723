// Occlusion culling of full-detail frames (core/src/render/tractogram/occlusion.hpp and
// line_geometry.hpp: Bricks): the cut of streamlines into bricks, and the
// test of a brick's box against the depth already drawn.
#include "tractogram/line_geometry.hpp"
#include "tractogram/occlusion.hpp"

#include "polylines.hpp"

#include <catch2/catch.hpp>

#include <glm/gtc/matrix_transform.hpp>

#include <atomic>
#include <random>
#include <set>
#include <vector>

using namespace hz::core;
using namespace hz::core::render;

namespace {

Bounds cube(double lo, double hi) {
    Bounds b;
    b.min = {lo, lo, lo}, b.max = {hi, hi, hi};
    b.empty = false;
    return b;
}

}  // namespace

TEST_CASE("bricks: every segment in exactly one piece, each piece in its brick's box", "[render][occlusion]") {
    // Random walks in a 40 mm cube, on 1, 2 and 3 threads, grids of 1-7.
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, 40.0f), step(-3.0f, 3.0f);
    std::vector<std::vector<float>> lines;
    for (int s = 0; s < 300; ++s) {
        std::vector<float> l;
        float p[3] = {u(rng), u(rng), u(rng)};
        // (some of a single point: no segment, no piece; some longer than a
        // BrickPiece holds: 256 or 700 points, in 2 or 3 pieces in a brick)
        const int n = s % 17 == 0 ? 1 : s == 5 ? 700 : s == 7 ? 256 : 2 + s % 60;
        for (int i = 0; i < n; ++i) {
            for (float &x : p) x = std::clamp(x + step(rng), 0.0f, 40.0f);
            l.insert(l.end(), p, p + 3);
        }
        lines.push_back(l);
    }
    const Tractogram t = polylines(lines);
    std::uint64_t segments = 0;
    for (std::uint64_t s = 0; s < t.nb_streamlines(); ++s) segments += t.size(s) > 1 ? t.size(s) - 1 : 0;
    const std::atomic<bool> go{false};
    // The data's bounds, and bounds a loader got wrong (points outside them
    // on every side: still inside their pieces' boxes, never culled wrongly).
    for (const Bounds &bounds : {cube(0, 40), cube(10, 30)})
        for (int side : {1, 2, 5, 7})
            for (unsigned threads : {1u, 3u}) {
                const Bricks b = bricks_of(t, bounds, side, threads, go);
                REQUIRE(b.dim == std::array<int, 3>{side, side, side});
                REQUIRE(b.begin.size() == b.box.size() + 1);
                REQUIRE(b.begin.back() == b.pieces.size());
                std::set<std::pair<std::uint64_t, std::uint64_t>> seen;  // (streamline, first segment)
                std::uint64_t cut_segments = 0;
                for (std::size_t k = 0; k < b.box.size(); ++k)
                    for (std::uint64_t i = b.begin[k]; i < b.begin[k + 1]; ++i) {
                        const Piece p = b.pieces[i].piece();
                        REQUIRE(p.count >= 2);
                        cut_segments += p.count - 1;
                        for (std::uint32_t q = 0; q + 1 < p.count; ++q) REQUIRE(seen.insert({p.s, p.first + q}).second);
                        for (std::uint32_t q = 0; q < p.count; ++q) {
                            const float *x = t.positions.data() + (t.begin(p.s) + p.first + q) * 3;
                            for (int a = 0; a < 3; ++a) {
                                REQUIRE(x[a] >= b.box[k][a]);
                                REQUIRE(x[a] <= b.box[k][3 + a]);
                            }
                        }
                    }
                REQUIRE(cut_segments == segments);
                // One brick: a piece per streamline, and one or two more
                // for the long ones.
                if (side == 1) REQUIRE(b.pieces.size() == t.nb_streamlines() - (t.nb_streamlines() + 16) / 17 + 2 + 1);
            }
    std::atomic<bool> stop{true};
    REQUIRE(bricks_of(t, cube(0, 40), 4, 2, stop).empty());
}

TEST_CASE("bricks: the grid whose pieces fit a budget", "[render][occlusion]") {
    // Straight lines along x across a 12 mm cube, one per (y, z): with n
    // bricks per side, n pieces each.
    std::vector<std::vector<float>> lines;
    for (int y = 0; y < 10; ++y)
        for (int z = 0; z < 10; ++z) {
            std::vector<float> l;
            for (int i = 0; i <= 120; ++i) l.insert(l.end(), {0.1f * float(i), 0.6f + float(y), 0.6f + float(z)});
            lines.push_back(l);
        }
    const Tractogram t = polylines(lines);
    REQUIRE(brick_side_for(t, cube(0, 12), 2, 12, 100 * 12) == 12);
    REQUIRE(brick_side_for(t, cube(0, 12), 2, 12, 100 * 6) == 6);
    REQUIRE(brick_side_for(t, cube(0, 12), 8, 12, 100 * 6) == 0);
}

TEST_CASE("depth tiles: a box is hidden only behind every tile it covers", "[render][occlusion]") {
    // A 64 x 48 picture looking down -z from z = 100 at a 20 mm wide field;
    // the near plane at 1, the far at 200.
    const int w = 64, h = 48;
    const glm::mat4 view = glm::lookAt(glm::vec3(0, 0, 100), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
    const glm::mat4 proj = glm::perspective(glm::radians(30.0f), float(w) / float(h), 1.0f, 200.0f);
    const glm::mat4 vp = proj * view;
    auto depth_at = [&](float z) {  // window depth of a point at world z on the axis
        const glm::vec4 q = vp * glm::vec4(0, 0, z, 1);
        return q.z / q.w * 0.5f + 0.5f;
    };
    // Drawn: a wall at z = 0 over the whole picture.
    std::vector<float> depth(std::size_t(w) * h, depth_at(0.0f));
    DepthTiles tiles;
    REQUIRE(tiles.empty());
    REQUIRE_FALSE(tiles.hidden({-1, -1, -10, 1, 1, -5}, 0, vp, 1));  // (nothing read yet: nothing hidden)
    tiles.build(depth.data(), w, h);
    const std::array<float, 6> behind{-1, -1, -10, 1, 1, -5}, in_front{-1, -1, 5, 1, 1, 10}, across{-1, -1, -5, 1, 1, 5};
    CHECK(tiles.hidden(behind, 0, vp, 1));
    CHECK_FALSE(tiles.hidden(in_front, 0, vp, 1));
    CHECK_FALSE(tiles.hidden(across, 0, vp, 1));
    CHECK_FALSE(tiles.hidden(behind, 6, vp, 1));  // (grown by 6 mm it reaches the wall)
    // Off the picture: hidden whatever its depth.
    CHECK(tiles.hidden({500, 500, 50, 510, 510, 60}, 0, vp, 1));
    // Reaching the eye's plane, or cut by the near plane: never hidden.
    CHECK_FALSE(tiles.hidden({-1, -1, 90, 1, 1, 150}, 0, vp, 1));
    CHECK_FALSE(tiles.hidden({-1, -1, 99.5f, 1, 1, 99.8f}, 0, vp, 1));
    // One pixel of the wall missing (the far plane's depth there), under
    // the projection of a box off the picture's centre (to the right, above):
    // the box shows through it; and a box the mirror image of it, left and
    // below, does not.
    const std::array<float, 6> off_centre{20, 14, -10, 21, 15, -5}, mirrored{-21, -15, -10, -20, -14, -5};
    const glm::vec4 c = vp * glm::vec4(20.5f, 14.5f, -7.5f, 1);
    const int px = int((c.x / c.w * 0.5f + 0.5f) * w), py = int((c.y / c.w * 0.5f + 0.5f) * h);
    REQUIRE(px > w / 2 + DepthTiles::kTile);
    REQUIRE(py > h / 2 + DepthTiles::kTile);  // (rows bottom up)
    depth[std::size_t(py) * w + px] = 1.0f;
    tiles.build(depth.data(), w, h);
    CHECK_FALSE(tiles.hidden(off_centre, 0, vp, 1));
    CHECK(tiles.hidden(mirrored, 0, vp, 1));
    CHECK(tiles.hidden(behind, 0, vp, 1));
    // ... and one far from it: hidden again.
    depth[std::size_t(py) * w + px] = depth_at(0.0f);
    depth[0] = 1.0f;
    tiles.build(depth.data(), w, h);
    CHECK(tiles.hidden(off_centre, 0, vp, 1));
    // An empty box is never hidden (it has no corners to project).
    CHECK_FALSE(tiles.hidden({1, 1, 1, -1, -1, -1}, 0, vp, 1));
}
