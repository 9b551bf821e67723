// Peak glyphs (core/render/peaks.hpp): each peak a segment centred on its
// voxel, along its vector, as long as its amplitude says; the slices' voxels
// only; thresholds, frames, scaled integer volumes and refused layouts.
#include <hz/core/render/peaks.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <vector>

using namespace hz::core;
using namespace hz::core::render;

namespace {

// A float32 peak volume of dims (X, Y, Z, 3N), value (x, y, z, c) = f(...).
template <class F>
Volume peak_volume(std::uint64_t X, std::uint64_t Y, std::uint64_t Z, std::uint64_t N, const Affine &a, F f) {
    Volume v;
    v.dtype = HZ_DTYPE_F32;
    v.dims = {X, Y, Z, 3 * N};
    v.voxel_to_ras = a;
    v.voxels = Buffer<std::byte>(X * Y * Z * 3 * N * 4);
    for (std::uint64_t c = 0; c < 3 * N; ++c)
        for (std::uint64_t z = 0; z < Z; ++z)
            for (std::uint64_t y = 0; y < Y; ++y)
                for (std::uint64_t x = 0; x < X; ++x) {
                    const float val = f(x, y, z, c);
                    std::memcpy(v.voxels.data() + (x + X * (y + Y * (z + Z * c))) * 4, &val, 4);
                }
    return v;
}

// The expected segment of vector d at voxel ijk: centre A ijk, half-vector
// 0.5 x smallest voxel side x scale x d / longest (by value), written out.
void expect_segment(const Tractogram &t, std::uint64_t s, const Affine &a, const double ijk[3], const double d[3], double half_over_len) {
    REQUIRE(t.size(s) == 2);
    const float *p = t.positions.data() + 3 * t.begin(s);
    for (int r = 0; r < 3; ++r) {
        const double c = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
        CHECK(p[r] == Approx(c - d[r] * half_over_len).margin(1e-4));
        CHECK(p[3 + r] == Approx(c + d[r] * half_over_len).margin(1e-4));
    }
}

}  // namespace

TEST_CASE("peak_lines: every voxel's peaks, centred, scaled by amplitude", "[peaks]") {
    const Affine a = {2, 0, 0, -10, 0, 3, 0, 5, 0, 0, 4, 1, 0, 0, 0, 1};  // (voxels 2 x 3 x 4 mm)
    // Peak 0: (x+1, y, 1) per voxel; peak 1: (0, 0, 0.5) where z == 1, else none.
    const Volume v = peak_volume(3, 2, 2, 2, a, [](auto x, auto y, auto z, auto c) -> float {
        const double d0[3] = {double(x) + 1, double(y), 1};
        if (c < 3) return float(d0[c]);
        return z == 1 && c == 5 ? 0.5f : 0.0f;
    });
    PeakOptions o;
    o.whole = true;
    o.scale = 1.5;
    const PeakField f = make_peak_field(v, o, "test");
    CHECK(f.peaks_per_voxel == 2);
    CHECK(f.voxel_mm == Approx(2));
    CHECK(f.max_amplitude == Approx(std::sqrt(3.0 * 3.0 + 1 + 1)));  // (x = 2, y = 1)
    const Tractogram t = peak_lines(f, std::nullopt, std::nullopt, std::nullopt);
    REQUIRE(t.nb_streamlines() == 12 + 6);
    REQUIRE(t.arrays.size() == 1);
    CHECK(t.arrays[0].name == "amplitude");
    const double k = 0.5 * 2 * 1.5 / f.max_amplitude;  // (half a segment per unit of amplitude)
    std::uint64_t s = 0;
    for (std::uint64_t z = 0; z < 2; ++z)
        for (std::uint64_t y = 0; y < 2; ++y)
            for (std::uint64_t x = 0; x < 3; ++x) {
                const double ijk[3] = {double(x), double(y), double(z)};
                const double d0[3] = {double(x) + 1, double(y), 1};
                expect_segment(t, s, a, ijk, d0, k);
                float amp;
                std::memcpy(&amp, t.arrays[0].bytes.data() + 4 * s, 4);
                CHECK(amp == Approx(std::sqrt(d0[0] * d0[0] + d0[1] * d0[1] + 1)));
                ++s;
                if (z == 1) {
                    const double d1[3] = {0, 0, 0.5};
                    expect_segment(t, s++, a, ijk, d1, k);
                }
            }

    SECTION("unit length: every peak as long") {
        o.by_value = false;
        const Tractogram u = peak_lines(make_peak_field(v, o, "test"), std::nullopt, std::nullopt, std::nullopt);
        for (std::uint64_t i = 0; i < u.nb_streamlines(); ++i) {
            const float *p = u.positions.data() + 3 * u.begin(i);
            CHECK(std::hypot(p[3] - p[0], p[4] - p[1], p[5] - p[2]) == Approx(2 * 1.5));
        }
    }
    SECTION("threshold: peaks shorter than the fraction of the longest dropped") {
        o.threshold = 0.2;  // (0.5 / 3.32 = 0.15: the second peaks go)
        CHECK(peak_lines(make_peak_field(v, o, "test"), std::nullopt, std::nullopt, std::nullopt).nb_streamlines() == 12);
    }
}

TEST_CASE("peak_lines: the voxels a slice passes through, half-open", "[peaks]") {
    const Affine a = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 3, 0, 0, 0, 0, 1};
    const Volume v = peak_volume(4, 5, 6, 1, a, [](auto, auto, auto, auto c) -> float { return c == 0 ? 1.0f : 0.0f; });
    const PeakField f = make_peak_field(v, PeakOptions{}, "test");
    // z = 6 mm is voxel plane 2's centre; [4.5, 7.5) is plane 2; 7.5 is plane 3.
    CHECK(peak_lines(f, std::nullopt, std::nullopt, 6.0).nb_streamlines() == 4 * 5);
    const Tractogram at = peak_lines(f, std::nullopt, std::nullopt, 7.5);
    REQUIRE(at.nb_streamlines() == 4 * 5);
    CHECK(at.positions[2] == Approx(9));  // (plane 3: z = 9 mm)
    CHECK(peak_lines(f, std::nullopt, std::nullopt, 100.0).nb_streamlines() == 0);
    // Two slices: their union (the shared row once).
    CHECK(peak_lines(f, 2.0, std::nullopt, 6.0).nb_streamlines() == 4 * 5 + 5 * 6 - 5);
    // Reference grid: the volume's.
    CHECK(at.reference_dims == std::array<std::uint64_t, 3>{4, 5, 6});
}

TEST_CASE("peak_lines: vectors in the voxel axes are turned by the affine", "[peaks]") {
    // A 90-degree turn about z: voxel x is world y, voxel y is world -x.
    const Affine a = {0, -2, 0, 0, 2, 0, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1};
    const Volume v = peak_volume(1, 1, 1, 1, a, [](auto, auto, auto, auto c) -> float { return c == 0 ? 1.0f : 0.0f; });
    PeakOptions o;
    o.whole = true;
    const Tractogram world = peak_lines(make_peak_field(v, o, "t"), std::nullopt, std::nullopt, std::nullopt);
    o.frame = "voxel";
    const Tractogram voxel = peak_lines(make_peak_field(v, o, "t"), std::nullopt, std::nullopt, std::nullopt);
    const double ijk[3] = {0, 0, 0}, x[3] = {1, 0, 0}, y[3] = {0, 1, 0};
    expect_segment(world, 0, a, ijk, x, 1.0);
    expect_segment(voxel, 0, a, ijk, y, 1.0);
}

TEST_CASE("peak_lines: scaled integers, and no peak where a vector is zero or not finite", "[peaks]") {
    Volume v;
    v.dtype = HZ_DTYPE_I16;
    v.dims = {2, 1, 1, 3};
    v.scale_slope = 0.5, v.scale_inter = 0;
    const std::int16_t raw[6] = {4, 0, 0, 0, 0, 0};  // (voxel 0: (2, 0, 0) after scaling; voxel 1: zero)
    v.voxels = Buffer<std::byte>(sizeof raw);
    std::memcpy(v.voxels.data(), raw, sizeof raw);
    PeakOptions o;
    o.whole = true;
    const PeakField f = make_peak_field(v, o, "t");
    CHECK(f.max_amplitude == Approx(2));
    CHECK(peak_lines(f, std::nullopt, std::nullopt, std::nullopt).nb_streamlines() == 1);
    const Volume n = peak_volume(1, 1, 1, 2, kIdentity, [](auto, auto, auto, auto c) -> float { return c < 3 ? NAN : 1.0f; });
    const Tractogram t = peak_lines(make_peak_field(n, o, "t"), std::nullopt, std::nullopt, std::nullopt);
    CHECK(t.nb_streamlines() == 1);
}

TEST_CASE("make_peak_field refuses what is not a peak volume", "[peaks]") {
    const Volume four = peak_volume(2, 2, 2, 1, kIdentity, [](auto...) { return 1.0f; });
    Volume wrong = peak_volume(2, 2, 2, 2, kIdentity, [](auto...) { return 1.0f; });
    wrong.dims[3] = 4;  // (4 values a voxel, all there)
    CHECK_THROWS_WITH(make_peak_field(wrong, {}, "f.nii"), Catch::Contains("f.nii") && Catch::Contains("4 values a voxel"));
    Volume flat = peak_volume(2, 2, 2, 1, kIdentity, [](auto...) { return 1.0f; });
    flat.dims = {2, 2, 6};
    CHECK_THROWS_WITH(make_peak_field(flat, {}, "f.nii"), Catch::Contains("3 dimensions"));
    PeakOptions bad;
    bad.scale = 0;
    CHECK_THROWS_WITH(make_peak_field(four, bad, "f"), Catch::Contains("scale"));
    bad = {};
    bad.threshold = 1;
    CHECK_THROWS_WITH(make_peak_field(four, bad, "f"), Catch::Contains("threshold"));
    bad = {};
    bad.frame = "scanner";
    CHECK_THROWS_WITH(make_peak_field(four, bad, "f"), Catch::Contains("frame"));
    Volume small = peak_volume(2, 2, 2, 1, kIdentity, [](auto...) { return 1.0f; });
    small.voxels = Buffer<std::byte>(8);
    CHECK_THROWS_WITH(make_peak_field(small, {}, "f"), Catch::Contains("fewer"));
}
