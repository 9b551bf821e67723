// ODF glyphs: orientation distribution functions stored as real
// spherical-harmonic (SH) coefficients (DIPY's `descoteaux07` and
// `tournier07` bases, legacy or not; MRtrix3's is tournier07, not legacy),
// each voxel's ODF evaluated on a sphere and drawn as that sphere deformed
// by it, on slices.
//
// A SH volume holds (L + 1)(L + 2) / 2 coefficients a voxel along its 4th
// dimension (even orders 0, 2, ..., L: 1, 6, 15, 28, 45, 66, 91, ...), in
// DIPY's order: for each even order n, the degrees m = -n ... n.
#pragma once

#include <hz/core/data.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hz::core::render {

// The real SH basis function of order n (even, >= 0) and degree m
// (|m| <= n) at polar angle `theta` and azimuth `phi` (radians), as DIPY
// defines it (dipy.reconst.shm.real_sh_descoteaux_from_index,
// real_sh_tournier_from_index): `basis` "descoteaux07" or "tournier07".
double real_sh(const std::string &basis, bool legacy, int n, int m, double theta, double phi);

// The coefficients of an even-order series of order L: (L + 1)(L + 2) / 2.
inline std::uint64_t sh_coefficients(int order) { return std::uint64_t(order + 1) * std::uint64_t(order + 2) / 2; }

// A unit sphere: an icosahedron whose faces are split in four
// `subdivisions` times (0 to 7; 0: 12 vertices, 1: 42, 2: 162, 3: 642, 4:
// 2562), each new vertex the normalised midpoint of an edge, faces
// counter-clockwise seen from outside. Throws Error outside 0 to 7.
struct SphereMesh {
    std::vector<double> vertices;      // nb x 3
    std::vector<std::uint32_t> faces;  // nb x 3
    std::uint64_t nb_vertices() const { return vertices.size() / 3; }
};
SphereMesh icosphere(int subdivisions);

// Glyphs made of one sphere each, as one mesh (ODF and tensor glyphs):
// `count` glyphs of `sphere`'s faces, glyph g's vertices at g x V ...
// (g + 1) x V - 1 (V the sphere's), each placed by `place(g, i, xyz, rgb)`
// (vertex i of the sphere: its position, RAS+ mm, and its colour, linear
// RGB), the colours a per-vertex array called `colours` (none: "").
Mesh sphere_glyphs(const SphereMesh &sphere, std::size_t count, const std::string &colours,
                   const std::function<void(std::size_t g, std::uint64_t i, float *xyz, float *rgb)> &place);
// The RAS+ box of a grid's voxels grown by `grow` mm on every side.
Bounds grown_grid_box(const Volume &grid, double grow);

// The matrix B (vertices x coefficients, row-major) with B[v][j] the j-th
// basis function of order <= `order` at vertex v: an ODF's values on the
// sphere are B times its coefficients (dipy.reconst.shm.sh_to_sf).
std::vector<double> sh_matrix(const std::vector<double> &unit_vertices, int order, const std::string &basis, bool legacy);

struct OdfOptions {
    std::string basis = "descoteaux07";  // descoteaux07 | tournier07 (MRtrix3's: tournier07, legacy false)
    bool legacy = true;                  // DIPY's default for descoteaux07
    // Icosphere subdivisions of a glyph (0 to 5). 2 (162 vertices) draws a
    // whole-brain slice (96 x 96) in 0.7 s on llvmpipe, its surface 3.8 %
    // of a glyph's size from the ODF on average (36 % at the tips of the
    // sharpest lobes); 3: 1.2 % (10 %) in 2.3 s (bench/results/odfs.md).
    int sphere = 2;
    // The largest glyph spans `scale` voxels (the smallest voxel side).
    double scale = 1.0;
    // Each glyph's radii from its values f on the sphere: "minmax" (f -
    // min f) / (max f - min f), its shape's contrast as DIPY's odf_slicer
    // shows it; "max" max(f, 0) / max f; "none" max(f, 0) / the largest f
    // of the glyphs shown (sizes comparable across voxels).
    std::string normalise = "minmax";
};

// A SH volume ready to be drawn (its voxels shared, not copied).
struct OdfField {
    Volume volume;
    OdfOptions options;
    int order = 0;
    double voxel_mm = 1;
    // Its level of detail (coarser_odf_field), or null.
    std::shared_ptr<const OdfField> coarser;
};

// Checks `v` (3 spatial dimensions, a 4th of (L + 1)(L + 2) / 2 values
// for an even L <= 16, numeric) and the options; throws Error naming
// `what` ("... 7 values a voxel: not the coefficients of an even-order SH
// series (1, 6, 15, 28, 45, ...)").
OdfField make_odf_field(const Volume &v, const OdfOptions &o, const std::string &what);

// The glyphs of the voxels the slices at x, y, z pass through (RAS+ mm,
// as peak_lines selects them), each a sphere of `subdivisions` centred on
// its voxel with radii from its ODF, as one mesh with a per-vertex
// "direction" colour array (|unit vertex| as linear RGB, 3 floats: the
// direction colours of streamlines). Voxels whose coefficients are all
// zero or not finite, or whose ODF is flat ("minmax") or nowhere positive,
// get none.
Mesh odf_glyphs(const OdfField &f, std::optional<double> x, std::optional<double> y, std::optional<double> z, int subdivisions);

// The field a level coarser, as a mipmap is: each block of 2 x 2 x 2
// voxels (2 x 2 of a single slice) one voxel at the block's centre, twice
// the size, holding the mean of the block's coefficients (of its voxels
// that have any: a non-zero, finite series), which is the SH series of the
// mean of their ODFs (the SH transform is linear). float32, scale 1.
OdfField coarser_odf_field(const OdfField &f);

// The RAS+ box of the field's voxels (their outer faces) grown by half the
// largest glyph.
Bounds odf_bounds(const OdfField &f);

}  // namespace hz::core::render
