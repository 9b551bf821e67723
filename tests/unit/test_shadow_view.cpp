// The shadow map's view of a scene (passes/shadow.hpp): every point of the
// box lies inside the light's clip volume, whatever the light's direction,
// the map covers the same extent from every direction (the shadows do not
// swim in scale as a camera-space light turns), and depth grows away from
// the light.
#include "passes/shadow.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <random>

using namespace hz::core::render;

TEST_CASE("shadow view: the box inside the light's clip volume from every direction", "[shadow]") {
    hz::core::Bounds box;
    box.min = {-70, -100, -50}, box.max = {70, 80, 75}, box.empty = false;
    std::mt19937 rng(7);
    std::normal_distribution<double> n01;
    double extent = -1;
    for (int k = 0; k < 200; ++k) {
        glm::dvec3 d(n01(rng), n01(rng), n01(rng));
        if (k == 0) d = {0, 0, 1};  // (straight down the z axis: the up vector changes there)
        if (k == 1) d = {0, 0, -1};
        d = glm::normalize(d);
        const ShadowView v = fit_shadow_view(d, box);
        if (extent < 0) extent = v.extent_mm;
        CHECK(v.extent_mm == Approx(extent));
        for (int c = 0; c < 8; ++c) {
            const glm::dvec4 p((c & 1) ? box.max[0] : box.min[0], (c & 2) ? box.max[1] : box.min[1], (c & 4) ? box.max[2] : box.min[2],
                               1.0);
            const glm::dvec4 q = v.view_proj * p;
            CHECK(q.w == Approx(1.0));  // (orthographic)
            for (int a = 0; a < 3; ++a) CHECK(std::abs(q[a]) < 1.0);
        }
        // Nearer the light: nearer in the map.
        const glm::dvec3 c(0, -10, 12.5);
        const double z0 = (v.view_proj * glm::dvec4(c, 1.0)).z, z1 = (v.view_proj * glm::dvec4(c + 10.0 * d, 1.0)).z;
        CHECK(z1 < z0);
    }
    // The sphere around the box, a little more.
    const double r = 0.5 * std::sqrt(140.0 * 140 + 180 * 180 + 125 * 125);
    CHECK(extent >= 2 * r);
    CHECK(extent <= 2.2 * r);
}
