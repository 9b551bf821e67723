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

// ------------------------------------------------------------ brain phantom

namespace {

// A named bundle's course through waypoints (the left hemisphere's: the
// right one's is the mirror image in x), its spread around that course
// (mm) and how much wider it grows towards its first and last ends, and its
// share of the streamlines.
struct BundleCourse {
    const char *name;
    std::vector<V3> waypoints;
    double radius_mm, fan_start, fan_end, weight;
};

const std::vector<BundleCourse> &bundle_courses() {
    static const std::vector<BundleCourse> courses = {
        // Corticospinal: precentral gyrus, corona radiata, internal capsule, cerebral peduncle, pons, medulla.
        {"CST", {{-34, -18, 52}, {-28, -14, 38}, {-21, -10, 16}, {-15, -17, -10}, {-9, -24, -30}, {-5, -30, -50}}, 2.5, 2.0, 0.2, 1.3},
        // Arcuate: inferior frontal gyrus, around the Sylvian fissure's end, middle and inferior temporal gyri.
        {"AF", {{-46, 20, 12}, {-41, 0, 26}, {-38, -26, 30}, {-44, -46, 14}, {-51, -36, -4}, {-54, -16, -16}}, 2.5, 1.5, 1.5, 0.9},
        // Cingulum: subgenual cingulate, over the corpus callosum, the isthmus, the parahippocampal gyrus.
        {"CG",
         {{-7, 38, -2}, {-8, 24, 26}, {-9, -8, 36}, {-9, -40, 30}, {-12, -54, 8}, {-20, -38, -10}, {-24, -20, -20}},
         2.0,
         1.0,
         1.0,
         0.8},
        // Inferior fronto-occipital: occipital pole, the temporal stem (external capsule), the frontal lobe.
        {"IFOF", {{-26, -90, 4}, {-34, -62, 0}, {-35, -26, -4}, {-31, 2, -5}, {-27, 26, 2}, {-25, 50, 10}}, 2.5, 2.0, 2.0, 1.0},
        // Uncinate: temporal pole, a hook through the temporal stem, the orbitofrontal cortex.
        {"UF", {{-40, 12, -32}, {-36, 2, -18}, {-29, 8, -8}, {-24, 26, -10}, {-20, 44, -12}}, 2.0, 1.2, 1.5, 0.5},
        // Inferior longitudinal: occipital pole along the temporal lobe's floor to its pole.
        {"ILF", {{-34, -90, 0}, {-42, -64, -6}, {-45, -34, -16}, {-43, -6, -26}, {-38, 10, -32}}, 2.5, 2.0, 1.5, 0.8},
    };
    return courses;
}

// A Catmull-Rom spline through `w` (its ends repeated), evaluated densely
// and resampled every `step` mm along its length.
std::vector<V3> smooth_course(const std::vector<V3> &w, double step) {
    std::vector<V3> dense;
    for (std::size_t i = 0; i + 1 < w.size(); ++i) {
        const V3 p0 = w[i == 0 ? 0 : i - 1], p1 = w[i], p2 = w[i + 1], p3 = w[std::min(i + 2, w.size() - 1)];
        for (int k = 0; k < 32; ++k) {
            const double t = k / 32.0, t2 = t * t, t3 = t2 * t;
            V3 p;
            for (int c = 0; c < 3; ++c)
                p[c] = 0.5 * (2 * p1[c] + (p2[c] - p0[c]) * t + (2 * p0[c] - 5 * p1[c] + 4 * p2[c] - p3[c]) * t2 +
                              (3 * p1[c] - p0[c] - 3 * p2[c] + p3[c]) * t3);
            dense.push_back(p);
        }
    }
    dense.push_back(w.back());
    std::vector<V3> out{dense.front()};
    double since = 0;
    for (std::size_t i = 1; i < dense.size(); ++i) {
        const V3 a = dense[i - 1], b = dense[i];
        const double len = std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
        double at = step - since;
        while (at <= len) {
            const double f = at / len;
            out.push_back(add(a, mul(add(b, mul(a, -1)), f)));
            at += step;
        }
        since = len - (at - step);
    }
    return out;
}

}  // namespace

const std::vector<std::string> &brain_bundle_names() {
    static const std::vector<std::string> names = [] {
        std::vector<std::string> n;
        for (const char *side : {"_L", "_R"})
            for (const auto &b : bundle_courses()) n.push_back(std::string(b.name) + side);
        n.push_back("CC");
        return n;
    }();
    return names;
}

Tractogram make_brain_phantom(std::uint64_t nb_streamlines, std::uint64_t seed) {
    Rng rng{seed * 0x9E3779B97F4A7C15ull + 101};
    const auto &courses = bundle_courses();
    const std::size_t nb = courses.size();
    // The corpus callosum's share: as much as two of the others.
    std::vector<double> cumulative;
    double total = 0;
    for (int side = 0; side < 2; ++side)
        for (const auto &b : courses) cumulative.push_back(total += b.weight);
    cumulative.push_back(total += 2.0);
    std::vector<float> pos, bundle;
    std::vector<std::uint64_t> off{0};
    for (std::uint64_t s = 0; s < nb_streamlines; ++s) {
        const double pick = rng.uniform(0, total);
        const std::size_t k = std::size_t(std::lower_bound(cumulative.begin(), cumulative.end(), pick) - cumulative.begin());
        const std::size_t which = std::min(k, cumulative.size() - 1);
        std::vector<V3> way;
        double radius = 2.5, fan0 = 1.0, fan1 = 1.0;
        V3 sub_bundle = {0, 0, 0};
        // (the MNI-like waypoints narrowed and moved forward onto the brain of
        // make_brain_surface: x 0.72 times, y 15 mm ahead)
        if (which < 2 * nb) {
            const BundleCourse &b = courses[which % nb];
            const double mirror = which < nb ? 0.72 : -0.72;
            for (V3 p : b.waypoints) way.push_back({mirror * p[0], p[1] + 15, p[2]});
            radius = b.radius_mm, fan0 = b.fan_start, fan1 = b.fan_end;
            // Three sub-bundles, as a bundle's fibres end in neighbouring
            // cortical regions (the corticospinal tract's leg, hand and face
            // areas): the same core, their ends 5 mm apart across the course
            // (horizontally, or along y for a vertical course).
            const V3 along = add(way.back(), mul(way.front(), -1));
            V3 across = {-along[1], along[0], 0};
            if (std::abs(along[2]) > 2 * std::hypot(along[0], along[1])) across = {0, 1, 0};
            const double len = std::sqrt(across[0] * across[0] + across[1] * across[1] + across[2] * across[2]);
            sub_bundle = mul(across, 5.0 * (double(rng.next() % 3) - 1.0) / len);
        } else {
            // Corpus callosum: one arc from a hemisphere's cortex to the
            // other's, through the midline at a place along its length
            // (genu in front, splenium behind, the body between, arched).
            const double t = rng.uniform(0, 1);
            const double y = 30 - 68 * t, z = 6 + 16 * std::sqrt(std::sin(M_PI * t));
            const double reach = rng.uniform(0.75, 1.0), y_end = 1.2 * y;
            way = {{-33 * reach, y_end + 15, z + 22},
                   {-16, 1.1 * y + 15, z + 12},
                   {0, y + 15, z},
                   {16, 1.1 * y + 15, z + 12},
                   {33 * reach, y_end + 15, z + 22}};
            radius = 1.5, fan0 = fan1 = 1.5;
        }
        if (rng.next() & 1) std::reverse(way.begin(), way.end()), std::swap(fan0, fan1);
        // Each streamline: the course moved by a smooth offset (wider
        // towards the fanning ends), trimmed at random ends.
        const std::vector<V3> course = smooth_course(way, 1.0);
        V3 shift[3];
        // (normal draws cut at 2 sigma: a fanning end stays within its lobe)
        auto draw = [&] { return std::clamp(rng.normal(), -2.0, 2.0) * radius; };
        for (V3 &v : shift) v = {draw(), draw(), draw()};
        const std::size_t n = course.size();
        const std::size_t a = std::size_t(rng.uniform(0, 0.06) * n), e = n - std::size_t(rng.uniform(0, 0.06) * n);
        for (std::size_t i = a; i < e; ++i) {
            const double u = double(i) / double(n - 1);
            const double fan = 1.0 + fan0 * (1 - u) * (1 - u) * (1 - u) + fan1 * u * u * u;
            const V3 d = add(add(mul(shift[0], (1 - u) * (1 - u)), mul(shift[1], 2 * u * (1 - u))), mul(shift[2], u * u));
            const double spread = std::pow(std::abs(2 * u - 1), 1.5);  // (0 at the core's middle, 1 at its ends)
            const V3 p = add(add(course[i], mul(d, fan)), mul(sub_bundle, spread));
            pos.insert(pos.end(), {float(p[0]), float(p[1]), float(p[2])});
        }
        off.push_back(pos.size() / 3);
        bundle.push_back(float(which));
    }
    Tractogram t;
    t.positions = Buffer<float>::copy_of(pos);
    t.offsets = Buffer<std::uint64_t>::copy_of(off);
    t.arrays.push_back(f32_array("bundle", HZ_ATTACH_STREAMLINE, bundle));
    t.reference = {1, 0, 0, -kHalfBox[0], 0, 1, 0, -kHalfBox[1] - 10, 0, 0, 1, -kHalfBox[2], 0, 0, 0, 1};
    t.reference_dims = {141, 191, 131};
    return t;
}

}  // namespace hz::core
