// Peak glyphs (peaks.hpp).
#include <hz/core/render/peaks.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

namespace hz::core::render {

namespace {

// Voxel v's component c (x fastest, the 4th dimension slowest), scaled.
double component(const Volume &v, std::uint64_t nvox, std::uint64_t voxel, std::uint64_t c, std::size_t es) {
    return value_at(v.voxels.data() + (voxel + nvox * c) * es, v.dtype) * (v.scale_slope == 0 ? 1.0 : v.scale_slope) + v.scale_inter;
}

std::uint64_t voxels_of(const Volume &v) { return v.dims[0] * v.dims[1] * v.dims[2]; }

}  // namespace

PeakField make_peak_field(const Volume &v, const PeakOptions &o, const std::string &what) {
    if (!(o.scale > 0 && o.scale <= 100)) throw Error(what + ": peak scale " + std::to_string(o.scale) + " is outside (0, 100]");
    if (!(o.threshold >= 0 && o.threshold < 1))
        throw Error(what + ": peak threshold " + std::to_string(o.threshold) + " is outside [0, 1)");
    if (o.frame != "world" && o.frame != "voxel") throw Error(what + ": peak frame '" + o.frame + "' is neither world nor voxel");
    GlyphVolume g = glyph_volume(v, what, "peaks need 3 values a peak (x, y, z, 3 x peaks)");
    if (g.volume.dims[3] % 3 != 0 || g.volume.dims[3] == 0)
        throw Error(what + ": " + std::to_string(g.volume.dims[3]) + " values a voxel: peaks need 3 a peak (x, y, z), so a multiple of 3");
    const std::size_t es = dtype_size(v.dtype);
    const std::uint64_t nvox = voxels_of(v);
    PeakField f;
    f.volume = std::move(g.volume);
    f.voxel_mm = g.voxel_mm;
    f.options = o;
    f.peaks_per_voxel = f.volume.dims[3] / 3;
    for (std::uint64_t vox = 0; vox < nvox; ++vox)
        for (std::uint64_t p = 0; p < f.peaks_per_voxel; ++p) {
            double n2 = 0;
            for (int k = 0; k < 3; ++k) {
                const double c = component(f.volume, nvox, vox, 3 * p + std::uint64_t(k), es);
                n2 += c * c;
            }
            if (std::isfinite(n2)) f.max_amplitude = std::max(f.max_amplitude, std::sqrt(n2));
        }
    return f;
}

GlyphVolume glyph_volume(const Volume &v, const std::string &what, const std::string &holds) {
    // The values a voxel: the one dimension after the third that is not 1
    // (a NIfTI symmetric matrix is (x, y, z, 1, 6)).
    std::size_t longer = 0;
    std::uint64_t values = 1;
    for (std::size_t k = 3; k < v.dims.size(); ++k) longer += v.dims[k] != 1, values *= v.dims[k];
    if (v.dims.size() < 4 || longer > 1 || v.dims[0] == 0 || v.dims[1] == 0 || v.dims[2] == 0 || values == 0)
        throw Error(what + ": " + holds + " along a 4th dimension, not a volume of " + std::to_string(v.dims.size()) + " dimensions");
    const std::size_t es = dtype_size(v.dtype);
    if (es == 0 || v.dtype == HZ_DTYPE_RGB8 || v.dtype == HZ_DTYPE_RGBA8 || v.dtype == HZ_DTYPE_F16)
        throw Error(what + ": glyphs need numbers (integers or floats), not this voxel type");
    if (v.voxels.size() < voxels_of(v) * values * es) throw Error(what + ": the voxels are fewer than the dimensions say");
    GlyphVolume g;
    g.volume.dtype = v.dtype;
    g.volume.dims = {v.dims[0], v.dims[1], v.dims[2], values};
    g.volume.voxels = v.voxels.shared();
    g.volume.scale_slope = v.scale_slope, g.volume.scale_inter = v.scale_inter;
    g.volume.voxel_to_ras = v.voxel_to_ras;
    const auto &a = v.voxel_to_ras;
    g.voxel_mm = 1e300;
    for (int k = 0; k < 3; ++k) g.voxel_mm = std::min(g.voxel_mm, std::hypot(a[k], a[4 + k], a[8 + k]));
    if (!(g.voxel_mm > 0 && std::isfinite(g.voxel_mm))) throw Error(what + ": the volume's affine has a voxel side of zero");
    return g;
}

Bounds grid_box(const std::vector<std::uint64_t> &dims, const Affine &a) {
    Bounds b;
    for (int corner = 0; corner < 8; ++corner) {
        double ijk[3];
        for (int k = 0; k < 3; ++k) ijk[k] = (corner >> k & 1) ? double(dims[std::size_t(k)]) - 0.5 : -0.5;
        for (int r = 0; r < 3; ++r) {
            const double w = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
            b.min[r] = b.empty ? w : std::min(b.min[r], w);
            b.max[r] = b.empty ? w : std::max(b.max[r], w);
        }
        b.empty = false;
    }
    return b;
}

Bounds peak_grid_box(const PeakField &f) { return grid_box(f.volume.dims, f.volume.voxel_to_ras); }

std::vector<std::uint64_t> slice_voxels(const std::vector<std::uint64_t> &dims, const Affine &a, std::optional<double> x,
                                        std::optional<double> y, std::optional<double> z, bool whole) {
    const std::uint64_t X = dims[0], Y = dims[1], nvox = dims[0] * dims[1] * dims[2];
    // Half a voxel's extent along each world axis: the slab a slice takes.
    double half[3];
    for (int r = 0; r < 3; ++r) half[r] = 0.5 * (std::abs(a[4 * r]) + std::abs(a[4 * r + 1]) + std::abs(a[4 * r + 2]));
    const std::optional<double> at[3] = {x, y, z};
    std::vector<std::uint64_t> out;
    for (std::uint64_t vox = 0; vox < nvox; ++vox) {
        if (!whole) {
            const double ijk[3] = {double(vox % X), double(vox / X % Y), double(vox / X / Y)};
            bool on = false;
            for (int r = 0; r < 3 && !on; ++r) {
                const double c = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
                on = at[r] && c > *at[r] - half[r] && c <= *at[r] + half[r];
            }
            if (!on) continue;
        }
        out.push_back(vox);
    }
    return out;
}

Bounds peak_bounds(const PeakField &f, const Tractogram &lines) {
    Bounds b = peak_grid_box(f);
    merge_bounds(b, bounds_of(lines.positions.data(), lines.nb_stored()));
    return b;
}

Tractogram peak_lines(const PeakField &f, std::optional<double> x, std::optional<double> y, std::optional<double> z) {
    const Volume &v = f.volume;
    const std::uint64_t X = v.dims[0], Y = v.dims[1], nvox = voxels_of(v);
    const std::size_t es = dtype_size(v.dtype);
    const auto &a = v.voxel_to_ras;
    const double longest = f.max_amplitude, cut = f.options.threshold * longest;
    const double full = 0.5 * f.voxel_mm * f.options.scale;  // half the longest peak, mm
    // Voxel axes -> world directions (frame "voxel"): the affine's columns, each of unit length.
    double turn[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    if (f.options.frame == "voxel")
        for (int k = 0; k < 3; ++k) {
            const double n = std::hypot(a[k], a[4 + k], a[8 + k]);
            for (int r = 0; r < 3; ++r) turn[r][k] = a[4 * r + k] / n;
        }
    std::vector<float> pos;
    std::vector<float> amp;
    const std::vector<std::uint64_t> shown = longest > 0 ? slice_voxels(v.dims, a, x, y, z, f.options.whole) : std::vector<std::uint64_t>{};
    for (const std::uint64_t vox : shown) {
        const double ijk[3] = {double(vox % X), double(vox / X % Y), double(vox / X / Y)};
        double c[3];
        for (int r = 0; r < 3; ++r) c[r] = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
        for (std::uint64_t p = 0; p < f.peaks_per_voxel; ++p) {
            double d[3];
            for (int k = 0; k < 3; ++k) d[k] = component(v, nvox, vox, 3 * p + std::uint64_t(k), es);
            const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            if (!(n > 0) || !std::isfinite(n) || n < cut) continue;
            const double h = (f.options.by_value ? full * n / longest : full) / n;
            double w[3];
            for (int r = 0; r < 3; ++r) w[r] = (turn[r][0] * d[0] + turn[r][1] * d[1] + turn[r][2] * d[2]) * h;
            for (int r = 0; r < 3; ++r) pos.push_back(float(c[r] - w[r]));
            for (int r = 0; r < 3; ++r) pos.push_back(float(c[r] + w[r]));
            amp.push_back(float(n));
        }
    }
    Tractogram t;
    t.positions = Buffer<float>::copy_of(pos);
    t.offsets = Buffer<std::uint64_t>(amp.size() + 1);
    for (std::uint64_t i = 0; i <= amp.size(); ++i) t.offsets[i] = 2 * i;
    t.arrays.push_back(f32_array("amplitude", HZ_ATTACH_STREAMLINE, amp));
    t.reference = v.voxel_to_ras;
    t.reference_dims = {v.dims[0], v.dims[1], v.dims[2]};
    return t;
}

}  // namespace hz::core::render
