#include <hz/core/phantom.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

namespace hz::core {

namespace {

using V3 = std::array<double, 3>;

V3 add(V3 a, V3 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
V3 mul(V3 a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }

// A bundle core: a cubic Bezier curve inside a 140 x 170 x 120 mm box
// (roughly a brain in RAS+ mm, centred on the origin).
struct Core {
    std::array<V3, 4> c;
    double length;  // approximate arc length
    V3 at(double t) const {
        const double u = 1 - t;
        return add(add(mul(c[0], u * u * u), mul(c[1], 3 * u * u * t)), add(mul(c[2], 3 * u * t * t), mul(c[3], t * t * t)));
    }
};

using Rng = SplitMix64;

const V3 kHalfBox = {70, 85, 60};

V3 random_point(Rng &r, double shrink = 1.0) {
    return {r.uniform(-kHalfBox[0], kHalfBox[0]) * shrink, r.uniform(-kHalfBox[1], kHalfBox[1]) * shrink,
            r.uniform(-kHalfBox[2], kHalfBox[2]) * shrink};
}

Core make_core(Rng &r, double min_len, double max_len) {
    // Bundles stay inside the box: try directions until the end point fits,
    // shortening the bundle if none does.
    double target = r.uniform(min_len, max_len);
    const V3 start = random_point(r, 0.7);
    V3 end = start;
    for (int attempt = 0; attempt < 64; ++attempt) {
        const double z = r.uniform(-1, 1), phi = r.uniform(0, 2 * M_PI), s = std::sqrt(1 - z * z);
        const V3 dir = {s * std::cos(phi), s * std::sin(phi), z};
        const V3 e = add(start, mul(dir, target * 0.85));
        if (std::fabs(e[0]) < kHalfBox[0] * 0.8 && std::fabs(e[1]) < kHalfBox[1] * 0.8 && std::fabs(e[2]) < kHalfBox[2] * 0.8) {
            end = e;
            break;
        }
        if (attempt % 8 == 7) target = std::max(min_len, target * 0.8);
        end = e;
    }
    Core c;
    c.c[0] = start;
    c.c[3] = end;
    // Bend the curve with two control points displaced sideways.
    for (int k = 1; k <= 2; ++k) {
        const V3 mid = add(mul(start, 1 - k / 3.0), mul(end, k / 3.0));
        c.c[k] = add(mid, {r.normal() * target * 0.1, r.normal() * target * 0.1, r.normal() * target * 0.1});
    }
    double len = 0;
    V3 prev = c.at(0);
    for (int i = 1; i <= 64; ++i) {
        const V3 p = c.at(i / 64.0);
        len += std::sqrt((p[0] - prev[0]) * (p[0] - prev[0]) + (p[1] - prev[1]) * (p[1] - prev[1]) + (p[2] - prev[2]) * (p[2] - prev[2]));
        prev = p;
    }
    c.length = len;
    return c;
}

}  // namespace

Tractogram make_phantom(const PhantomOptions &o) {
    Rng rng{o.seed * 0x2545F4914F6CDD1Dull + 17};
    std::vector<Core> cores;
    for (std::uint32_t b = 0; b < std::max<std::uint32_t>(o.nb_bundles, 1); ++b)
        cores.push_back(make_core(rng, o.min_length_mm, o.max_length_mm));

    std::vector<float> pos;
    std::vector<std::uint64_t> off{0};
    for (std::uint64_t s = 0; s < o.nb_streamlines; ++s) {
        const bool stray = rng.uniform(0, 1) < o.stray_fraction;
        const Core core = stray ? make_core(rng, o.min_length_mm, o.max_length_mm) : cores[rng.next() % cores.size()];
        // Each streamline: the core displaced by a smooth offset, trimmed at
        // random ends, sampled every step_mm, in a random direction.
        const V3 shift0 = {rng.normal() * o.bundle_radius_mm, rng.normal() * o.bundle_radius_mm, rng.normal() * o.bundle_radius_mm};
        const V3 shift1 = {rng.normal() * o.bundle_radius_mm, rng.normal() * o.bundle_radius_mm, rng.normal() * o.bundle_radius_mm};
        const double t0 = rng.uniform(0, 0.1), t1 = rng.uniform(0.9, 1.0);
        const int n = std::max(2, static_cast<int>(core.length * (t1 - t0) / o.step_mm) + 1);
        const bool reverse = rng.next() & 1;
        for (int i = 0; i < n; ++i) {
            const int j = reverse ? n - 1 - i : i;
            const double u = double(j) / (n - 1);
            const V3 p = add(core.at(t0 + (t1 - t0) * u), add(mul(shift0, 1 - u), mul(shift1, u)));
            pos.insert(pos.end(), {float(p[0]), float(p[1]), float(p[2])});
        }
        off.push_back(pos.size() / 3);
    }
    Tractogram t;
    t.positions = Buffer<float>::copy_of(pos);
    t.offsets = Buffer<std::uint64_t>::copy_of(off);
    // A 1 mm reference grid covering the box, for formats that need one.
    t.reference = {1, 0, 0, -kHalfBox[0], 0, 1, 0, -kHalfBox[1], 0, 0, 1, -kHalfBox[2], 0, 0, 0, 1};
    t.reference_dims = {141, 171, 121};
    return t;
}

}  // namespace hz::core
