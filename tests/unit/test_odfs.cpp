// ODF glyphs (core/render/odfs.hpp): the icosphere, glyph radii from the
// ODF under each normalisation, the slices' voxels, refused layouts. (The
// SH basis itself is checked against DIPY: tests/python, sh_to_sf.)
#include <hz/core/render/odfs.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <numbers>

using namespace hz::core;
using namespace hz::core::render;

namespace {

// A float32 volume (X, Y, Z, C) with voxel v's coefficient j = f(v, j).
template <class F>
Volume sh_volume(std::uint64_t X, std::uint64_t Y, std::uint64_t Z, std::uint64_t C, const Affine &a, F f) {
    Volume v;
    v.dims = {X, Y, Z, C};
    v.voxel_to_ras = a;
    v.voxels = Buffer<std::byte>(X * Y * Z * C * 4);
    for (std::uint64_t j = 0; j < C; ++j)
        for (std::uint64_t k = 0; k < X * Y * Z; ++k) {
            const float val = f(k, j);
            std::memcpy(v.voxels.data() + (k + X * Y * Z * j) * 4, &val, 4);
        }
    return v;
}

}  // namespace

TEST_CASE("icosphere: counts, unit vertices, faces outward", "[odfs]") {
    for (int s = 0; s <= 4; ++s) {
        const SphereMesh m = icosphere(s);
        const std::uint64_t faces = 20u << (2 * s);
        CHECK(m.faces.size() == 3 * faces);
        CHECK(m.nb_vertices() == faces / 2 + 2);  // (Euler: V - E + F = 2, E = 3F/2)
        for (std::uint64_t i = 0; i < m.nb_vertices(); ++i)
            CHECK(std::hypot(m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]) == Approx(1).epsilon(1e-12));
        for (std::size_t k = 0; k < m.faces.size(); k += 3) {
            const double *a = &m.vertices[3 * m.faces[k]], *b = &m.vertices[3 * m.faces[k + 1]], *c = &m.vertices[3 * m.faces[k + 2]];
            const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
            const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
            REQUIRE(n[0] * (a[0] + b[0] + c[0]) + n[1] * (a[1] + b[1] + c[1]) + n[2] * (a[2] + b[2] + c[2]) > 0);
        }
    }
    CHECK_THROWS(icosphere(8));
}

TEST_CASE("real_sh: order 0 is the constant 1 / (2 sqrt(pi)), order 2 with m = 0 is P2 of Legendre", "[odfs]") {
    const double c0 = 0.5 / std::sqrt(std::numbers::pi);
    for (const char *basis : {"descoteaux07", "tournier07"})
        for (bool legacy : {true, false}) {
            CHECK(real_sh(basis, legacy, 0, 0, 0.3, 1.1) == Approx(c0));
            const double t = 0.7, p2 = 0.5 * (3 * std::cos(t) * std::cos(t) - 1);
            CHECK(real_sh(basis, legacy, 2, 0, t, 2.0) == Approx(std::sqrt(5 / (4 * std::numbers::pi)) * p2));
        }
    CHECK_THROWS_WITH(real_sh("mrtrix", false, 2, 0, 0, 0), Catch::Contains("neither"));
}

TEST_CASE("odf_glyphs: radii by normalisation, centred on the voxels of the slices", "[odfs]") {
    const Affine a = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1};
    // Order 2: voxel 0 isotropic (c0 only), voxel 1 c0 + a z-lobe (Y_2^0), voxel 2 zero.
    const Volume v = sh_volume(3, 1, 1, 6, a, [](std::uint64_t k, std::uint64_t j) -> float {
        if (k == 2) return 0;
        if (j == 0) return 1;
        return k == 1 && j == 3 ? 0.5f : 0.0f;  // (j = 3: n = 2, m = 0)
    });
    OdfOptions o;
    o.sphere = 1;
    const SphereMesh s = icosphere(1);
    const std::uint64_t V = s.nb_vertices();
    SECTION("minmax: a flat ODF has no glyph; the lobe spans the voxel from 0 to the largest radius") {
        const Mesh m = odf_glyphs(make_odf_field(v, o, "t"), std::nullopt, std::nullopt, 0.0, 1);
        REQUIRE(m.nb_vertices() == V);  // (voxel 1 alone)
        double lo = 1e9, hi = 0;
        for (std::uint64_t i = 0; i < V; ++i) {
            const double d = std::hypot(m.vertices[3 * i] - 2.0, m.vertices[3 * i + 1], m.vertices[3 * i + 2]);
            lo = std::min(lo, d), hi = std::max(hi, d);
        }
        CHECK(lo == Approx(0).margin(1e-5));
        CHECK(hi == Approx(1.0));  // (half the 2 mm voxel)
        REQUIRE(m.arrays.size() == 1);
        CHECK(m.arrays[0].name == "direction");
        CHECK(m.arrays[0].components == 3);
        CHECK(m.nb_faces() == s.faces.size() / 3);
    }
    SECTION("max and none: the isotropic ODF a sphere; none keeps sizes comparable across voxels") {
        o.normalise = "max";
        const Mesh m = odf_glyphs(make_odf_field(v, o, "t"), std::nullopt, std::nullopt, 0.0, 1);
        REQUIRE(m.nb_vertices() == 2 * V);
        for (std::uint64_t i = 0; i < V; ++i)
            CHECK(std::hypot(m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]) == Approx(1.0));
        o.normalise = "none";
        const Mesh n = odf_glyphs(make_odf_field(v, o, "t"), std::nullopt, std::nullopt, 0.0, 1);
        double r0 = 0, r1 = 0;
        for (std::uint64_t i = 0; i < V; ++i) {
            r0 = std::max(r0, double(std::hypot(n.vertices[3 * i], n.vertices[3 * i + 1], n.vertices[3 * i + 2])));
            r1 = std::max(r1, double(std::hypot(n.vertices[3 * (V + i)] - 2.0, n.vertices[3 * (V + i) + 1], n.vertices[3 * (V + i) + 2])));
        }
        CHECK(r1 == Approx(1.0));  // (the largest glyph spans the voxel)
        CHECK(r0 < r1);            // (the isotropic one is smaller: its largest value is)
    }
    SECTION("a level coarser: the mean series of each block's voxels that have one, at the block's centre") {
        // (3 x 1 x 1 of 2 mm: blocks {0, 1} and {2} along x; y and z of one voxel stay)
        const OdfField c = coarser_odf_field(make_odf_field(v, o, "t"));
        REQUIRE(c.volume.dims == std::vector<std::uint64_t>{2, 1, 1, 6});
        CHECK(c.voxel_mm == Approx(2.0));  // (the smallest side: y and z keep 2 mm; x is 4 mm)
        CHECK(c.volume.voxel_to_ras[0] == 4.0);
        CHECK(c.volume.voxel_to_ras[3] == 1.0);  // (block 0's centre: between voxels 0 and 1, x = 1 mm)
        CHECK(c.volume.voxel_to_ras[5] == 2.0);
        CHECK(c.volume.voxel_to_ras[7] == 0.0);
        float got[12];
        std::memcpy(got, c.volume.voxels.data(), sizeof got);
        CHECK(got[0] == 1.0f);   // (block 0, c0: the mean of 1 and 1)
        CHECK(got[6] == 0.25f);  // (block 0, j = 3: the mean of 0 and 0.5)
        CHECK(got[1] == 0.0f);   // (block 1: voxel 2 is empty, so is it)
        CHECK(got[7] == 0.0f);
        CHECK(odf_glyphs(c, std::nullopt, std::nullopt, 0.0, 0).nb_vertices() == icosphere(0).nb_vertices());
    }
    SECTION("the slice picks the voxels") {
        o.normalise = "max";
        CHECK(odf_glyphs(make_odf_field(v, o, "t"), 0.0, std::nullopt, std::nullopt, 1).nb_vertices() == V);
        CHECK(odf_glyphs(make_odf_field(v, o, "t"), 100.0, std::nullopt, std::nullopt, 1).nb_vertices() == 0);
    }
}

TEST_CASE("make_odf_field refuses what is not a SH volume", "[odfs]") {
    const auto one = [](std::uint64_t, std::uint64_t) { return 1.0f; };
    CHECK_THROWS_WITH(make_odf_field(sh_volume(2, 2, 2, 7, kIdentity, one), {}, "f.nii"),
                      Catch::Contains("f.nii") && Catch::Contains("7 values a voxel"));
    Volume flat = sh_volume(2, 2, 2, 1, kIdentity, one);
    flat.dims = {2, 2, 2};
    CHECK_THROWS_WITH(make_odf_field(flat, {}, "f"), Catch::Contains("4th dimension"));
    OdfOptions o;
    o.basis = "mrtrix";
    CHECK_THROWS_WITH(make_odf_field(sh_volume(2, 2, 2, 15, kIdentity, one), o, "f"), Catch::Contains("basis"));
    o = {};
    o.normalise = "sum";
    CHECK_THROWS_WITH(make_odf_field(sh_volume(2, 2, 2, 15, kIdentity, one), o, "f"), Catch::Contains("normalisation"));
    CHECK(make_odf_field(sh_volume(2, 2, 2, 45, kIdentity, one), {}, "f").order == 8);
}
