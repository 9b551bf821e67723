// Tensor glyphs (tensors.hpp).
#include <hz/core/render/odfs.hpp>
#include <hz/core/render/peaks.hpp>
#include <hz/core/render/tensors.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <vector>

namespace hz::core::render {

TensorField make_tensor_field(const Volume &v, const TensorOptions &o, const std::string &what) {
    if (o.order != "dipy" && o.order != "fsl" && o.order != "mrtrix3")
        throw Error(what + ": tensor order '" + o.order + "' is none of dipy, fsl, mrtrix3");
    if (o.sphere < 0 || o.sphere > 5) throw Error(what + ": glyph sphere subdivisions must be 0 to 5");
    if (!(o.scale > 0 && o.scale <= 100)) throw Error(what + ": tensor scale " + std::to_string(o.scale) + " is outside (0, 100]");
    if (o.normalise != "max" && o.normalise != "none")
        throw Error(what + ": tensor normalisation '" + o.normalise + "' is neither max nor none");
    GlyphVolume g = glyph_volume(v, what, "tensors need 6 values a voxel");
    if (g.volume.dims[3] != 6)
        throw Error(what + ": " + std::to_string(g.volume.dims[3]) +
                    " values a voxel: a diffusion tensor has 6 (Dxx, Dxy, Dyy, Dxz, Dyz, Dzz)");
    TensorField f;
    f.volume = std::move(g.volume);
    f.voxel_mm = g.voxel_mm;
    f.options = o;
    return f;
}

Eigen3 tensor_eigen(double xx, double xy, double xz, double yy, double yz, double zz) {
    double a[3][3] = {{xx, xy, xz}, {xy, yy, yz}, {xz, yz, zz}};
    double q[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    // Cyclic Jacobi: rotate away the largest off-diagonal element until none is left.
    for (int sweep = 0; sweep < 50; ++sweep) {
        const double off = std::abs(a[0][1]) + std::abs(a[0][2]) + std::abs(a[1][2]);
        const double scale = std::abs(a[0][0]) + std::abs(a[1][1]) + std::abs(a[2][2]);
        if (off <= 1e-15 * scale || off == 0) break;
        for (int p = 0; p < 2; ++p)
            for (int r = p + 1; r < 3; ++r) {
                if (a[p][r] == 0) continue;
                const double theta = (a[r][r] - a[p][p]) / (2 * a[p][r]);
                const double t = (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1));
                const double c = 1 / std::sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 3; ++k) {  // A <- A J (columns p, r)
                    const double akp = a[k][p], akr = a[k][r];
                    a[k][p] = c * akp - s * akr, a[k][r] = s * akp + c * akr;
                }
                for (int k = 0; k < 3; ++k) {  // A <- J^T A (rows p, r)
                    const double apk = a[p][k], ark = a[r][k];
                    a[p][k] = c * apk - s * ark, a[r][k] = s * apk + c * ark;
                }
                for (int k = 0; k < 3; ++k) {  // Q <- Q J
                    const double qkp = q[k][p], qkr = q[k][r];
                    q[k][p] = c * qkp - s * qkr, q[k][r] = s * qkp + c * qkr;
                }
            }
    }
    std::array<int, 3> idx{0, 1, 2};
    std::sort(idx.begin(), idx.end(), [&](int i, int j) { return a[i][i] > a[j][j]; });
    Eigen3 e;
    for (int k = 0; k < 3; ++k) {
        e.values[std::size_t(k)] = a[idx[std::size_t(k)]][idx[std::size_t(k)]];
        for (int r = 0; r < 3; ++r) e.vectors[std::size_t(k)][std::size_t(r)] = q[r][idx[std::size_t(k)]];
    }
    const double l1 = e.values[0], l2 = e.values[1], l3 = e.values[2];
    const double n = l1 * l1 + l2 * l2 + l3 * l3;
    e.fa = n > 0 ? std::sqrt(0.5 * ((l1 - l2) * (l1 - l2) + (l2 - l3) * (l2 - l3) + (l3 - l1) * (l3 - l1)) / n) : 0.0;
    return e;
}

Mesh tensor_glyphs(const TensorField &f, std::optional<double> x, std::optional<double> y, std::optional<double> z) {
    const Volume &v = f.volume;
    const SphereMesh sphere = icosphere(f.options.sphere);
    const std::uint64_t X = v.dims[0], Y = v.dims[1], nvox = v.dims[0] * v.dims[1] * v.dims[2];
    const std::size_t es = dtype_size(v.dtype);
    const double slope = v.scale_slope == 0 ? 1.0 : v.scale_slope;
    const auto &a = v.voxel_to_ras;
    // Where each of (xx, xy, xz, yy, yz, zz) is among the six values.
    const std::array<int, 6> at = f.options.order == "dipy"  ? std::array<int, 6>{0, 1, 3, 2, 4, 5}
                                  : f.options.order == "fsl" ? std::array<int, 6>{0, 1, 2, 3, 4, 5}
                                                             : std::array<int, 6>{0, 3, 4, 1, 5, 2};
    struct Glyph {
        std::uint64_t vox;
        Eigen3 e;
    };
    std::vector<Glyph> kept;
    double largest = 0;
    for (const std::uint64_t vox : slice_voxels(v.dims, a, x, y, z, false)) {
        double d[6];
        bool finite = true, any = false;
        for (int k = 0; k < 6; ++k) {
            d[k] = value_at(v.voxels.data() + (vox + nvox * std::uint64_t(at[std::size_t(k)])) * es, v.dtype) * slope + v.scale_inter;
            finite = finite && std::isfinite(d[k]);
            any = any || d[k] != 0;
        }
        if (!finite || !any) continue;
        Eigen3 e = tensor_eigen(d[0], d[1], d[2], d[3], d[4], d[5]);
        if (!(e.values[0] > 0)) continue;
        largest = std::max(largest, e.values[0]);
        kept.push_back({vox, e});
    }
    const double reach = 0.5 * f.voxel_mm * f.options.scale;
    // Each glyph: its centre, its axes' lengths and its colour.
    struct Shape {
        double centre[3], axes[3];
        float rgb[3];
    };
    std::vector<Shape> shapes(kept.size());
    for (std::size_t g = 0; g < kept.size(); ++g) {
        const Glyph &k = kept[g];
        const double ijk[3] = {double(k.vox % X), double(k.vox / X % Y), double(k.vox / X / Y)};
        Shape &s = shapes[g];
        for (int r = 0; r < 3; ++r) s.centre[r] = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
        const double norm = f.options.normalise == "max" ? k.e.values[0] : largest;
        for (int j = 0; j < 3; ++j) s.axes[j] = std::max(k.e.values[std::size_t(j)], 0.0) / norm * reach;
        for (int r = 0; r < 3; ++r) s.rgb[r] = float(std::clamp(k.e.fa, 0.0, 1.0) * std::abs(k.e.vectors[0][std::size_t(r)]));
    }
    return sphere_glyphs(sphere, kept.size(), "color_fa", [&](std::size_t g, std::uint64_t i, float *xyz, float *rgb) {
        const Shape &s = shapes[g];
        const double *u = &sphere.vertices[3 * i];
        // V diag(axes) V^T u: along each eigenvector, u's component times its axis.
        double p[3] = {s.centre[0], s.centre[1], s.centre[2]};
        for (int j = 0; j < 3; ++j) {
            const auto &ev = kept[g].e.vectors[std::size_t(j)];
            const double c = (ev[0] * u[0] + ev[1] * u[1] + ev[2] * u[2]) * s.axes[j];
            for (int r = 0; r < 3; ++r) p[r] += c * ev[std::size_t(r)];
        }
        for (int r = 0; r < 3; ++r) xyz[r] = float(p[r]), rgb[r] = s.rgb[r];
    });
}

Bounds tensor_bounds(const TensorField &f) { return grown_grid_box(f.volume, 0.5 * f.voxel_mm * f.options.scale); }

}  // namespace hz::core::render
