// Masks and label volumes (a parcellation, FreeSurfer's aseg, a tract's
// mask): each whole-number value a region with its colour from a lookup
// table, drawn on slices as filled areas with their outlines and in 3D as
// each region's boundary surface.
//
// Lookup tables are read in FreeSurfer's `FreeSurferColorLUT.txt` format:
// one label a line, `INDEX NAME R G B A` (whitespace separated; R, G, B in
// 0..255; A is read and not used: FreeSurfer writes 0 for every label); `#`
// starts a comment. Labels a table does not list get a colour of their own
// (label_colour).
#pragma once

#include <hz/core/data.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

namespace hz::core::render {

struct LabelEntry {
    std::string name;
    std::array<std::uint8_t, 3> rgb{};  // sRGB-encoded
};
using LabelTable = std::map<std::int64_t, LabelEntry>;

// Reads a FreeSurferColorLUT-format table (at most 16 MiB); throws Error
// naming the file and the line ("lut.txt: line 4: R G B must be whole
// numbers in 0..255").
LabelTable read_label_table(const std::filesystem::path &path);
// The same from text; `what` names it in errors.
LabelTable parse_label_table(std::string_view text, const std::string &what);

// The colour of `label`: the table's, else one of its own (hues spread by
// the golden ratio, the same for a label in every run and every file, and
// the colour the GIFTI and FreeSurfer loaders give a label without one).
std::array<std::uint8_t, 3> label_colour(const LabelTable &table, std::int64_t label);
// Its name: the table's, else the number.
std::string label_name(const LabelTable &table, std::int64_t label);

// How a label volume is drawn.
struct LabelOptions {
    LabelTable table;                // empty: every label its own colour
    std::vector<std::int64_t> only;  // the labels shown (empty: every label but 0, the background)
    double fill = 0.4;               // slices: the opacity of a region's area (0: outlines only)
    bool outline = true;             // slices: each region's border drawn opaque, about 2 pixels wide
    bool surfaces = false;           // 3D: each region's boundary as a surface (label_surfaces)
    int smoothing = 10;              // surfaces: the constrained smoothing's iterations (0: none)
};

// A label volume read once: its labels, one a voxel (x fastest), and those
// present. Built by make_label_field.
struct LabelField {
    std::array<std::uint64_t, 3> dims{};
    Affine voxel_to_ras = kIdentity;
    std::vector<std::int32_t> labels;
    std::vector<std::int64_t> present;  // in increasing order, 0 included when present
    LabelOptions options;
    bool shown(std::int64_t label) const;  // not the background, and in options.only when it is set
};

// The labels of a 3D volume (or of the first 3D volume of a series with
// trailing dimensions of 1), scaled by its slope and intercept. Throws
// Error naming `what` for anything else: more dimensions, colour voxels, a
// value that is not a whole number (naming the voxel), a label beyond
// +-2^31, more than 65536 distinct labels, a label of `opt.only` the volume
// does not hold, or options out of range.
LabelField make_label_field(const Volume &v, const LabelOptions &opt, const std::string &what);

// The RGBA texture of the slices: per voxel the label's colour (sRGB, 0..1)
// and the label as the 4th value (0 where it is not shown), x fastest.
std::vector<float> label_texture(const LabelField &f);

// Each shown label's boundary as a closed surface (RAS+ mm) by surface nets
// (Gibson, "Constrained elastic surface nets", 1998): a vertex in each cell
// of 2x2x2 voxel centres that the boundary crosses, a quad across each
// pair of neighbouring voxels of which one is inside; then `smoothing`
// passes of Taubin's smoothing (towards the neighbours' mean by 0.5, then
// away by 0.53: no shrinking), each vertex kept within its cell (so the
// surface stays within a voxel of the voxels' boundary). Faces wind
// counter-clockwise seen from outside. Per-vertex arrays: "label" (float)
// and "rgb" (u8 x 3, the label's colour). Labels are meshed one by one over
// their own bounding boxes.
Mesh label_surfaces(const LabelField &f);

// The boundary of the voxels of `v` (its first 3D volume, scaled) above
// `above` as one surface (RAS+ mm): a brain mask's, or a T1's where it is
// brighter than the background (a glass brain). label_surfaces of that
// mask with `smoothing` passes. Throws Error naming `what` for a volume of
// another shape, colour voxels, no voxel above, or too many triangles.
Mesh mask_surface(const Volume &v, double above, int smoothing, const std::string &what);

}  // namespace hz::core::render
