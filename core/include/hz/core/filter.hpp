// Streamline selection by regions of interest and length: the one
// implementation behind `horizon filter`, the window's ROIs and scene files.
//
// The semantics are MRtrix3 tckedit's (3.0), so that a selection made here
// and one made with tckedit on the same file agree streamline for streamline:
// - a streamline is kept when each include region holds at least one of its
//   vertices, no exclude region holds any, and its length is within
//   [min_length, max_length] (both inclusive);
// - only vertices are tested (a segment that crosses a small region between
//   two vertices does not count), as tckedit does;
// - the length is the sum of its segments' lengths, added in float32 in
//   vertex order (tckedit's arithmetic); an empty streamline has no length
//   and is never kept;
// - a sphere holds p when |p - c|^2 <= r^2 (float32); a mask holds p when
//   the voxel nearest to p (voxel coordinates from the RAS -> voxel affine
//   in float32, rounded half away from zero) is inside the image and not
//   zero (NaN voxels are outside here; tckedit counts them in);
// - with ends_only, only the first and last vertices are tested;
// - invert keeps exactly the streamlines the other settings drop (tckedit's
//   -inverse, without its mask cropping).
// Boxes (axis-aligned, inclusive) are Horizon's own; tckedit has none.
#pragma once

#include <hz/core/data.hpp>
#include <hz/core/plugin_host.hpp>

#include <array>
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace hz::core {

// A region of interest, RAS+ mm.
struct Roi {
    enum class Shape { Sphere, Box, Mask };
    Shape shape = Shape::Sphere;
    bool include = true;
    std::array<double, 3> center{};  // sphere
    double radius = 0;
    std::array<double, 3> lo{}, hi{};  // box, lo <= hi
    // mask: one byte per voxel (x fastest), 1 where the voxel is set; the
    // RAS+ mm -> voxel affine; the name of the file it came from.
    std::shared_ptr<const std::vector<std::uint8_t>> mask;
    std::array<std::uint64_t, 3> dims{};
    Affine ras_to_voxel = kIdentity;
    std::array<float, 12> r2v{};  // its first three rows in float32 (what contains() uses, as tckedit does)
    Bounds mask_bounds;           // (the set voxels' RAS bounds, found once by mask_roi)
    std::string file;

    bool contains(const float *p) const;
    // Bounds in RAS+ mm outside which contains() is false.
    Bounds bounds() const;
    // The spec that parse_roi reads back ("sphere:X,Y,Z,R", "box:...", the file).
    std::string spec() const;
};

// "sphere:X,Y,Z,R", "box:X0,Y0,Z0,X1,Y1,Z1" (any two opposite corners) or a
// mask volume's file name (read through `reg`, any volume format; the first
// 3D volume of a 4D one). Throws Error, one line naming `spec`: bad numbers,
// a radius <= 0, an empty box side, an unreadable file, a file that is not a
// volume, a mask with no voxel set.
Roi parse_roi(const Registry &reg, const std::string &spec, bool include);
// A mask ROI from a volume already read (nonzero voxels); `file` names it.
Roi mask_roi(const Volume &v, const std::string &file, bool include);

struct FilterSpec {
    std::vector<Roi> rois;  // include and exclude regions, any order
    double min_length = 0;
    double max_length = std::numeric_limits<double>::infinity();
    bool ends_only = false;
    bool invert = false;
    // Whether anything is asked at all (otherwise every non-empty streamline passes).
    bool active() const { return !rois.empty() || min_length > 0 || max_length < std::numeric_limits<double>::infinity() || invert; }
    // One line for headers and reports ("include sphere:1,2,3,4; min_length 40").
    std::string describe() const;
};

// The length of streamline s as tckedit measures it (NaN when empty).
float streamline_length(const Tractogram &t, std::uint64_t s);

// Per-streamline axis-aligned boxes (float32, min xyz then max xyz), built
// once per tractogram on every core: a streamline whose box misses an
// include region's bounds fails without a look at its vertices, one whose
// box misses every exclude region's is not scanned for them.
struct StreamlineBoxes {
    std::vector<std::array<float, 6>> box;  // empty streamline: min > max
    static StreamlineBoxes of(const Tractogram &t);
};

// A spatial index for selecting again and again (the window, while a
// region is dragged): a uniform grid of `cell_mm` cells over the
// tractogram's bounds, each listing the streamlines with a vertex in it (a
// streamline once per run of its vertices in the cell). A region's
// candidates are the streamlines listed in the cells its bounds overlap;
// only those are tested vertex by vertex. Memory is bounded: where the
// entries would pass 13 per streamline (at least 48M, at most 128M: 192 to
// 512 MB), the cells grow until they fit (a sample of streamlines
// estimates the count first). Built in two passes
// over the vertices (a counting sort).
struct StreamlineGrid {
    Bounds bounds;
    double cell = 0;
    std::array<std::uint64_t, 3> n{};
    std::vector<std::uint64_t> start;  // per cell + 1: where its entries begin in ids
    std::vector<std::uint32_t> ids;    // streamline indices, cell by cell
    std::uint64_t nb_streamlines = 0;
    // On `threads` threads (0: every core). A set `*cancel` stops the
    // build early (then the grid returned is empty: nb_streamlines 0).
    static StreamlineGrid of(const Tractogram &t, double cell_mm = 6.0, unsigned threads = 0, const std::atomic<bool> *cancel = nullptr);
    // Sets the bit of every streamline listed in a cell that `r` overlaps
    // (bits: nb_streamlines bits, 64 to a word).
    void mark(const Bounds &r, std::vector<std::uint64_t> &bits) const;
};

// The streamlines of `t` that `f` keeps, in ascending order; over `subset`
// only (ascending or not; the result keeps its order) when given. `boxes`
// (StreamlineBoxes::of(t)) or `grid` (StreamlineGrid::of(t)) speed it up
// when given (the grid is not used with a subset). Runs on every core.
std::vector<std::uint64_t> filter_streamlines(const Tractogram &t, const FilterSpec &f, const StreamlineBoxes *boxes = nullptr,
                                              const std::vector<std::uint64_t> *subset = nullptr, const StreamlineGrid *grid = nullptr);

// The streamlines `ids` of `t` in that order, with their per-vertex and
// per-streamline arrays, and groups (TRX) narrowed to the streamlines kept
// and renumbered; group data is kept for the groups that keep members.
// `spill` and `cancel`: as select_streamlines'.
Tractogram subset_with_arrays(const Tractogram &t, const std::vector<std::uint64_t> &ids, bool spill = false,
                              const std::atomic<bool> *cancel = nullptr);

// The arrays subset_with_arrays gives the streamlines `ids` (per-streamline
// rows picked, groups renumbered, group data of the groups kept), except
// that per-vertex arrays are shared whole, not gathered, unless
// `gather_vertex_arrays`: rows indexed like t's positions, as a writer
// offering hz.ext.write-selection/1 takes them.
std::vector<DataArray> arrays_of_selection(const Tractogram &t, const std::vector<std::uint64_t> &ids, bool gather_vertex_arrays);

}  // namespace hz::core
