// Peak glyphs: the fibre directions of each voxel (MRtrix3's sh2peaks,
// DIPY's peaks, a PAM5 file) drawn as short line segments centred on the
// voxel, on slices or through the whole volume.
//
// A peak volume holds 3 x N values a voxel (a 4th dimension of 3N): N
// vectors (x, y, z) whose length is the peak's amplitude; a zero, NaN or
// shorter-than-threshold vector is no peak. The vectors are in world (RAS+)
// axes, as MRtrix3 writes them and DIPY draws them; `frame` "voxel" reads
// them in the voxel axes instead (turned by the affine).
#pragma once

#include <hz/core/data.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hz::core::render {

struct PeakOptions {
    // The longest peak spans `scale` voxels (the smallest voxel side);
    // with `by_value` false every peak is that long.
    double scale = 1.0;
    bool by_value = true;
    // Peaks shorter than this fraction of the longest are not drawn.
    double threshold = 0.0;
    std::string frame = "world";  // world | voxel
    // The whole volume's peaks rather than those on the slices.
    bool whole = false;
};

// A peak volume ready to be drawn: the volume (its voxels shared, not
// copied), the options, and what was found in it.
struct PeakField {
    Volume volume;
    PeakOptions options;
    std::uint64_t peaks_per_voxel = 0;
    double max_amplitude = 0;  // the longest vector (0: no peak at all)
    double voxel_mm = 1;       // the smallest voxel side
};

// Checks `v` is a peak volume (3 spatial dimensions, a 4th of 3N values, no
// further one, numeric) and finds its longest vector; throws Error naming
// `what` otherwise ("... has 4 values a voxel: peaks need 3 per peak").
// Throws for options out of range (scale in (0, 100], threshold in [0, 1),
// frame world or voxel).
PeakField make_peak_field(const Volume &v, const PeakOptions &o, const std::string &what);

// The segments of the peaks shown, as two-point streamlines (RAS+ mm), each
// centred on its voxel, with a per-streamline "amplitude" array (the
// vector's length in the file's units): those of the voxels the slices at
// x, y, z (slice_voxels), or of every voxel with PeakOptions::whole. The
// reference grid is the volume's.
Tractogram peak_lines(const PeakField &f, std::optional<double> x, std::optional<double> y, std::optional<double> z);

// What peak and ODF glyphs read: `v` as a 4D volume whose voxels are
// shared (not copied), and the smallest side of its voxels (mm), once it is
// checked to have 3 spatial dimensions and a 4th (`holds` says what the
// 4th must hold: "peaks need 3 values a peak"; further dimensions of 1
// before or after it are dropped: a NIfTI symmetric matrix is (x, y, z, 1,
// 6)), numbers (integers or
// floats), its voxels all there and a voxel side above zero. Throws Error
// naming `what`.
struct GlyphVolume {
    Volume volume;
    double voxel_mm = 1;
};
GlyphVolume glyph_volume(const Volume &v, const std::string &what, const std::string &holds);

// The voxels (indices, x fastest) of a grid of `dims` (x, y, z) and affine
// `a` that slices at x, y, z (RAS+ mm; absent: that slice is off) pass
// through, in index order: a voxel whose centre lies within half its extent
// along that axis of the plane (on the boundary between two, the upper
// one, as a voxel index rounds); every voxel with `whole`. Shared by the
// peak and ODF glyphs.
std::vector<std::uint64_t> slice_voxels(const std::vector<std::uint64_t> &dims, const Affine &a, std::optional<double> x,
                                        std::optional<double> y, std::optional<double> z, bool whole);
// The RAS+ box of a grid's voxels (their outer faces).
Bounds grid_box(const std::vector<std::uint64_t> &dims, const Affine &a);

// The RAS+ box of the field's voxels (their outer faces).
Bounds peak_grid_box(const PeakField &f);
// That box grown to hold the segments `lines` (glyphs longer than a voxel
// reach out of it): the object's bounds whatever its slices show, so that
// a camera fitted to it does not move as they do (as a volume's slices).
Bounds peak_bounds(const PeakField &f, const Tractogram &lines);

}  // namespace hz::core::render
