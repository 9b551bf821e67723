// The demo's brain (make_brain_phantom, make_brain_surface, make_t1_volume):
// each named bundle runs the way its anatomy does, in its hemisphere, inside
// the cortex; the T1 volume has T1 contrast where the anatomy says.
#include <hz/core/phantom.hpp>
#include <hz/core/render/scene.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <map>
#include <string>

using namespace hz::core;
using hz::core::render::make_brain_surface;
using hz::core::render::make_t1_volume;

namespace {

struct BundleStats {
    double n = 0, points = 0, mean_x = 0, mean_z = 0;
    double span[3] = {0, 0, 0};  // mean |end - start| per axis
    double min_z = 1e9, max_z = -1e9;
};

}  // namespace

TEST_CASE("brain phantom: each named bundle's course, side and extent") {
    const Tractogram t = make_brain_phantom(6000, 4);
    REQUIRE(t.nb_streamlines() == 6000);
    CHECK_NOTHROW(t.validate("brain phantom"));
    const auto &names = brain_bundle_names();
    REQUIRE(names.size() == 13);
    REQUIRE(t.arrays.size() == 1);
    REQUIRE(t.arrays[0].name == "bundle");
    const float *bundle = reinterpret_cast<const float *>(t.arrays[0].bytes.data());
    std::map<std::string, BundleStats> st;
    for (std::uint64_t s = 0; s < t.nb_streamlines(); ++s) {
        REQUIRE(bundle[s] >= 0);
        REQUIRE(bundle[s] < names.size());
        BundleStats &b = st[names[std::size_t(bundle[s])]];
        const float *a = &t.positions[3 * t.begin(s)], *e = &t.positions[3 * (t.end(s) - 1)];
        b.n += 1;
        for (int k = 0; k < 3; ++k) b.span[k] += std::abs(e[k] - a[k]);
        for (std::uint64_t i = t.begin(s); i < t.end(s); ++i) {
            b.mean_x += t.positions[3 * i], b.mean_z += t.positions[3 * i + 2], b.points += 1;
            b.min_z = std::min(b.min_z, double(t.positions[3 * i + 2]));
            b.max_z = std::max(b.max_z, double(t.positions[3 * i + 2]));
        }
    }
    for (auto &[name, b] : st) {
        b.mean_x /= std::max(1.0, b.points), b.mean_z /= std::max(1.0, b.points);
        for (double &v : b.span) v /= std::max(1.0, b.n);
    }
    REQUIRE(st.size() == 13);
    auto dominant = [](const BundleStats &b) {
        return b.span[0] > b.span[1] ? (b.span[0] > b.span[2] ? 0 : 2) : (b.span[1] > b.span[2] ? 1 : 2);
    };
    for (const char *side : {"_L", "_R"}) {
        const double sign = std::string(side) == "_L" ? -1.0 : 1.0;
        for (const char *name : {"CST", "AF", "CG", "IFOF", "UF", "ILF"}) {
            const BundleStats &b = st[std::string(name) + side];
            INFO(name << side);
            CHECK(b.n > 100);
            CHECK(b.mean_x * sign > 0);  // in its own hemisphere
        }
        CHECK(dominant(st[std::string("CST") + side]) == 2);   // descending: inferior-superior
        CHECK(st[std::string("CST") + side].min_z < -35);      // down to the brainstem
        CHECK(dominant(st[std::string("IFOF") + side]) == 1);  // occipital to frontal: anterior-posterior
        CHECK(dominant(st[std::string("ILF") + side]) == 1);
        CHECK(dominant(st[std::string("CG") + side]) == 1);
        CHECK(st[std::string("ILF") + side].mean_z < 0);  // along the temporal lobe's floor
        CHECK(st[std::string("CG") + side].mean_z > 10);  // above the corpus callosum
    }
    CHECK(dominant(st["CC"]) == 0);  // left to right
    CHECK(std::abs(st["CC"].mean_x) < 0.05 * st["CC"].span[0]);
}

TEST_CASE("brain phantom: deterministic for a seed") {
    const Tractogram a = make_brain_phantom(300, 9), b = make_brain_phantom(300, 9), c = make_brain_phantom(300, 10);
    REQUIRE(a.positions.size() == b.positions.size());
    CHECK(std::equal(a.positions.begin(), a.positions.end(), b.positions.begin()));
    CHECK((a.positions.size() != c.positions.size() || !std::equal(a.positions.begin(), a.positions.end(), c.positions.begin())));
}

TEST_CASE("T1 volume: white brighter than grey, CSF dark, the scalp bright, nothing outside the head") {
    const Volume v = make_t1_volume(1.0);
    const float *f = reinterpret_cast<const float *>(v.voxels.data());
    auto at = [&](double x, double y, double z) {
        const auto i = std::uint64_t(std::lround(x - v.voxel_to_ras[3])), j = std::uint64_t(std::lround(y - v.voxel_to_ras[7])),
                   k = std::uint64_t(std::lround(z - v.voxel_to_ras[11]));
        return double(f[(k * v.dims[1] + j) * v.dims[0] + i]);
    };
    CHECK(at(30, 0, 30) > 700);  // centrum semiovale: white matter
    CHECK(at(-30, 0, 30) > 700);
    CHECK(at(9, -2, 16) < 200);  // a lateral ventricle: CSF
    CHECK(at(0, 0, 60) < 200);   // the interhemispheric fissure
    CHECK(at(0, -4, 91) < 1);    // above the scalp
    CHECK(at(70, 0, 0) < 1);     // beside it
    // Along a line out of the right hemisphere, the values fall from white
    // to grey to CSF, then the skull is dark and the scalp bright.
    const double white = at(30, 10, 20);
    double grey_at = 0, csf_at = 0, scalp = 0;
    for (double x = 30; x < 70; x += 1) {
        const double value = at(x, 10, 20);
        if (!grey_at && value > 300 && value < 560) grey_at = x;  // (T1 grey matter: 420)
        if (!csf_at && value < 150) csf_at = x;
        if (x > 50) scalp = std::max(scalp, value);
    }
    CHECK(white > 700);
    CHECK(grey_at > 30);
    CHECK(csf_at > grey_at);
    CHECK(scalp > 450);
}

TEST_CASE("brain surface: two closed hemispheres around the bundles, with a sulcal depth overlay") {
    const Mesh m = make_brain_surface(4);
    REQUIRE(m.arrays.size() == 1);
    CHECK(m.arrays[0].name == "sulc");
    const Bounds box = bounds_of(m.vertices.data(), m.vertices.size() / 3);
    CHECK(box.min[0] < -40);
    CHECK(box.max[0] > 40);
    CHECK(box.max[1] - box.min[1] > 150);
    // The bundles lie within the brain's box (a few mm of fanning aside).
    const Tractogram t = make_brain_phantom(2000, 1);
    const Bounds tb = bounds_of(t.positions.data(), t.nb_vertices());
    for (int k = 0; k < 2; ++k) {
        CHECK(tb.min[std::size_t(k)] > box.min[std::size_t(k)] - 8);
        CHECK(tb.max[std::size_t(k)] < box.max[std::size_t(k)] + 8);
    }
    CHECK(tb.max[2] < box.max[2] + 8);
    const float *sulc = reinterpret_cast<const float *>(m.arrays[0].bytes.data());
    float lo = 1e9f, hi = -1e9f;
    for (std::uint64_t i = 0; i < m.arrays[0].count; ++i) lo = std::min(lo, sulc[i]), hi = std::max(hi, sulc[i]);
    CHECK(lo >= 0);
    CHECK(lo < 0.05f);  // gyral crowns
    CHECK(hi > 0.8f);   // sulcal fundi
}
