// Tensor glyphs (core/render/tensors.hpp): the eigen-decomposition, FA,
// the ellipsoid's axes and the value orders. (Colours against DIPY's
// color_fa: tests/scripts/test_glyphs.py.)
#include <hz/core/render/odfs.hpp>
#include <hz/core/render/tensors.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <random>

using namespace hz::core;
using namespace hz::core::render;

TEST_CASE("tensor_eigen: V diag(values) V^T is the matrix, values descending, vectors orthonormal", "[tensors]") {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int trial = 0; trial < 200; ++trial) {
        double m[6];
        for (double &x : m) x = u(rng);
        if (trial % 5 == 0) m[1] = m[2] = m[4] = 0;    // (diagonal already)
        if (trial % 7 == 0) m[3] = m[0], m[5] = m[0];  // (repeated eigenvalues)
        const Eigen3 e = tensor_eigen(m[0], m[1], m[2], m[3], m[4], m[5]);
        CHECK(e.values[0] >= e.values[1]);
        CHECK(e.values[1] >= e.values[2]);
        const double A[3][3] = {{m[0], m[1], m[2]}, {m[1], m[3], m[4]}, {m[2], m[4], m[5]}};
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) {
                double s = 0, dot = 0;
                for (int k = 0; k < 3; ++k) s += e.vectors[k][r] * e.values[k] * e.vectors[k][c], dot += e.vectors[r][k] * e.vectors[c][k];
                REQUIRE(s == Approx(A[r][c]).margin(1e-10));
                REQUIRE(dot == Approx(r == c ? 1.0 : 0.0).margin(1e-10));
            }
    }
    // FA of (3, 1, 1): sqrt(1/2) sqrt(4 + 0 + 4) / sqrt(11).
    CHECK(tensor_eigen(3, 0, 0, 1, 0, 1).fa == Approx(std::sqrt(0.5 * 8 / 11)));
    CHECK(tensor_eigen(1, 0, 0, 1, 0, 1).fa == Approx(0).margin(1e-12));
    CHECK(tensor_eigen(0, 0, 0, 0, 0, 0).fa == 0);
}

namespace {
// One voxel holding the tensor diag(3, 1, 1) (1e-3) in the six values' `order`.
Volume one_tensor(const std::string &order) {
    const double xx = 3e-3, yy = 1e-3, zz = 1e-3;
    const float dipy[6] = {float(xx), 0, float(yy), 0, 0, float(zz)}, fsl[6] = {float(xx), 0, 0, float(yy), 0, float(zz)},
                mrtrix[6] = {float(xx), float(yy), float(zz), 0, 0, 0};
    Volume v;
    v.dims = {1, 1, 1, 6};
    v.voxel_to_ras = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1};
    v.voxels = Buffer<std::byte>(24);
    std::memcpy(v.voxels.data(), order == "dipy" ? dipy : order == "fsl" ? fsl : mrtrix, 24);
    return v;
}
}  // namespace

TEST_CASE("tensor_glyphs: the ellipsoid's axes are the eigenvalues, in every order of the six values", "[tensors]") {
    for (const char *order : {"dipy", "fsl", "mrtrix3"}) {
        TensorOptions o;
        o.order = order;
        o.sphere = 3;
        const Mesh m = tensor_glyphs(make_tensor_field(one_tensor(order), o, "t"), 0.0, std::nullopt, std::nullopt);
        REQUIRE(m.nb_vertices() == icosphere(3).nb_vertices());
        double ext[3] = {0, 0, 0};
        for (std::uint64_t i = 0; i < m.nb_vertices(); ++i)
            for (int k = 0; k < 3; ++k) ext[k] = std::max(ext[k], double(std::abs(m.vertices[3 * i + k])));
        CHECK(ext[0] == Approx(1.0));  // (the longest axis: half the 2 mm voxel)
        CHECK(ext[1] == Approx(1.0 / 3));
        CHECK(ext[2] == Approx(1.0 / 3));
        REQUIRE(m.arrays.size() == 1);
        float rgb[3];
        std::memcpy(rgb, m.arrays[0].bytes.data(), 12);
        CHECK(rgb[0] == Approx(std::sqrt(0.5 * 8 / 11)));  // (FA x |e1| = FA x (1, 0, 0))
        CHECK(rgb[1] == Approx(0).margin(1e-6));
    }
    TensorOptions bad;
    bad.order = "afni";
    CHECK_THROWS_WITH(make_tensor_field(one_tensor("dipy"), bad, "t"), Catch::Contains("order"));
    Volume five = one_tensor("dipy");
    five.dims[3] = 5;
    CHECK_THROWS_WITH(make_tensor_field(five, {}, "f.nii"), Catch::Contains("f.nii") && Catch::Contains("5 values a voxel"));
    // A NIfTI symmetric matrix: (x, y, z, 1, 6).
    Volume sym = one_tensor("dipy");
    sym.dims = {1, 1, 1, 1, 6};
    CHECK(make_tensor_field(sym, {}, "t").volume.dims == std::vector<std::uint64_t>{1, 1, 1, 6});
}
