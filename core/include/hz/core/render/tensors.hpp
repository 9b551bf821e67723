// Tensor glyphs: diffusion tensors (6 values a voxel) drawn as ellipsoids,
// each the unit sphere through its tensor (axes along the eigenvectors, as
// long as the eigenvalues), coloured by FA times the principal direction
// (DIPY's color_fa), on slices.
//
// The six values' order: "dipy" (Dxx, Dxy, Dyy, Dxz, Dyz, Dzz: DIPY's
// lower_triangular, NIfTI's symmetric-matrix intent, a 5D (x, y, z, 1, 6)
// volume), "fsl" (dtifit's --save_tensor: Dxx, Dxy, Dxz, Dyy, Dyz, Dzz) or
// "mrtrix3" (dwi2tensor: Dxx, Dyy, Dzz, Dxy, Dxz, Dyz); the tensor in world
// (RAS+) axes.
#pragma once

#include <hz/core/data.hpp>

#include <array>
#include <optional>
#include <string>

namespace hz::core::render {

struct TensorOptions {
    std::string order = "dipy";  // dipy | fsl | mrtrix3
    int sphere = 2;              // icosphere subdivisions of a glyph (0 to 5)
    double scale = 1.0;          // the longest axis shown spans `scale` voxels
    // "max": each glyph's longest axis spans it (shapes compared); "none":
    // sizes over the largest eigenvalue shown (diffusivities compared).
    std::string normalise = "max";
};

struct TensorField {
    Volume volume;  // (x, y, z, 6), voxels shared
    TensorOptions options;
    double voxel_mm = 1;
};

// Checks `v` (3 spatial dimensions and 6 values a voxel, numbers) and the
// options; throws Error naming `what`.
TensorField make_tensor_field(const Volume &v, const TensorOptions &o, const std::string &what);

// The eigenvalues (descending) and eigenvectors (columns, unit, in the same
// order) of the symmetric matrix [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
// (Jacobi rotations), and its FA (0 for a zero tensor).
struct Eigen3 {
    std::array<double, 3> values{};
    std::array<std::array<double, 3>, 3> vectors{};  // vectors[k] is the k-th eigenvector
    double fa = 0;
};
Eigen3 tensor_eigen(double xx, double xy, double xz, double yy, double yz, double zz);

// The ellipsoids of the voxels the slices at x, y, z pass through (RAS+
// mm, as peak_lines selects them), negative eigenvalues taken as 0, as one
// mesh with a per-vertex "color_fa" array (FA x |principal eigenvector|,
// linear RGB, 3 floats; the glyph's one colour). Voxels whose tensor is zero
// or not finite get none.
Mesh tensor_glyphs(const TensorField &f, std::optional<double> x, std::optional<double> y, std::optional<double> z);

// The RAS+ box of the field's voxels grown by half the largest glyph.
Bounds tensor_bounds(const TensorField &f);

}  // namespace hz::core::render
