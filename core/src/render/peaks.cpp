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
    std::size_t dims = v.dims.size();
    while (dims > 4 && v.dims[dims - 1] == 1) --dims;
    if (dims != 4 || v.dims[0] == 0 || v.dims[1] == 0 || v.dims[2] == 0)
        throw Error(what + ": peaks need a volume of 3 values a peak along a 4th dimension (x, y, z, 3 x peaks), not " +
                    std::to_string(v.dims.size()) + " dimensions");
    if (v.dims[3] % 3 != 0 || v.dims[3] == 0)
        throw Error(what + ": " + std::to_string(v.dims[3]) + " values a voxel: peaks need 3 a peak (x, y, z), so a multiple of 3");
    const std::size_t es = dtype_size(v.dtype);
    if (es == 0 || v.dtype == HZ_DTYPE_RGB8 || v.dtype == HZ_DTYPE_RGBA8 || v.dtype == HZ_DTYPE_F16)
        throw Error(what + ": peaks need numbers (integers or floats), not this voxel type");
    const std::uint64_t nvox = voxels_of(v);
    if (v.voxels.size() < nvox * v.dims[3] * es) throw Error(what + ": the voxels are fewer than the dimensions say");
    PeakField f;
    f.volume.dtype = v.dtype;
    f.volume.dims = {v.dims[0], v.dims[1], v.dims[2], v.dims[3]};
    f.volume.voxels = v.voxels.shared();
    f.volume.scale_slope = v.scale_slope, f.volume.scale_inter = v.scale_inter;
    f.volume.voxel_to_ras = v.voxel_to_ras;
    f.options = o;
    f.peaks_per_voxel = v.dims[3] / 3;
    for (std::uint64_t vox = 0; vox < nvox; ++vox)
        for (std::uint64_t p = 0; p < f.peaks_per_voxel; ++p) {
            double n2 = 0;
            for (int k = 0; k < 3; ++k) {
                const double c = component(f.volume, nvox, vox, 3 * p + std::uint64_t(k), es);
                n2 += c * c;
            }
            if (std::isfinite(n2)) f.max_amplitude = std::max(f.max_amplitude, std::sqrt(n2));
        }
    const auto &a = v.voxel_to_ras;
    f.voxel_mm = 1e300;
    for (int k = 0; k < 3; ++k) f.voxel_mm = std::min(f.voxel_mm, std::hypot(a[k], a[4 + k], a[8 + k]));
    if (!(f.voxel_mm > 0 && std::isfinite(f.voxel_mm))) throw Error(what + ": the volume's affine has a voxel side of zero");
    return f;
}

Bounds peak_grid_box(const PeakField &f) {
    Bounds b;
    const auto &a = f.volume.voxel_to_ras;
    for (int corner = 0; corner < 8; ++corner) {
        double ijk[3];
        for (int k = 0; k < 3; ++k) ijk[k] = (corner >> k & 1) ? double(f.volume.dims[std::size_t(k)]) - 0.5 : -0.5;
        for (int r = 0; r < 3; ++r) {
            const double w = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
            b.min[r] = b.empty ? w : std::min(b.min[r], w);
            b.max[r] = b.empty ? w : std::max(b.max[r], w);
        }
        if (corner == 0) b.empty = false;
    }
    return b;
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
    // Half a voxel's extent along each world axis: the slab a slice takes.
    double half[3];
    for (int r = 0; r < 3; ++r) half[r] = 0.5 * (std::abs(a[4 * r]) + std::abs(a[4 * r + 1]) + std::abs(a[4 * r + 2]));
    const std::optional<double> at[3] = {x, y, z};
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
    for (std::uint64_t vox = 0; vox < nvox && longest > 0; ++vox) {
        const double ijk[3] = {double(vox % X), double(vox / X % Y), double(vox / X / Y)};
        double c[3];
        for (int r = 0; r < 3; ++r) c[r] = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
        if (!f.options.whole) {
            bool on = false;
            for (int r = 0; r < 3 && !on; ++r) on = at[r] && c[r] > *at[r] - half[r] && c[r] <= *at[r] + half[r];
            if (!on) continue;
        }
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
