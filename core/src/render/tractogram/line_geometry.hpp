// Streamline geometry on the CPU (private to the renderer): the vertex the
// line and tube programs read, an object's colouring resolved per
// streamline, and the decimated vertices of a chunk of streamlines, built on
// any thread. The GL side (buffers, the ring, drawing) is line_stream.hpp.
#pragma once

#include "../gl.hpp"
#include "shell_proxy.hpp"

#include <hz/core/render/scene.hpp>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hz::core::render {

// A streamline vertex as the line and tube programs read it.
struct LineVertex {
    float pos[3];
    std::uint32_t tangent;  // snorm 2_10_10_10
    std::uint8_t rgba[4];   // linear colour
    float radius;           // tube radius, mm
};
static_assert(sizeof(LineVertex) == 24);

// What building the vertices of a run of streamlines reads: the object's
// tractogram (its positions may be a mapping of the file) and its colouring
// resolved per streamline. Shared with the threads that build chunks.
struct LineData {
    const Tractogram *t = nullptr;
    enum class Mode { Direction, Solid, Data, Cluster } mode = Mode::Solid;
    std::array<std::uint8_t, 4> solid{};
    std::string colormap;
    std::array<double, 2> range{0, 1};
    const DataArray *per_vertex = nullptr;             // data colouring by a per-point array
    std::vector<double> per_streamline;                // ... or by a per-streamline array
    std::vector<std::array<std::uint8_t, 4>> cluster;  // cluster colouring, per streamline
    std::vector<float> radius;                         // per streamline
    std::vector<float> highlight;                      // per streamline; empty: none
    const DataArray *mark = nullptr;                   // per point: drawn in mark_rgba where not 0 (Coloring::mark)
    std::array<std::uint8_t, 4> mark_rgba{};
};

// Streamline geometry is cut into chunks of at most kChunkPoints input
// points: no GL buffer grows with the data (llvmpipe faults on vertex
// buffers past 2^31 bytes; drivers cap buffer sizes), a frame can be drawn
// a chunk at a time (progressive refinement), and chunks beyond the
// renderer's memory budget are built again each frame into a ring buffer
// instead of being kept.
constexpr std::uint64_t kChunkPoints = 1u << 18;
constexpr std::uint32_t kRestart = 0xFFFFFFFFu;  // the primitive restart index

struct LineChunk {
    std::uint64_t a = 0, b = 0;  // streamlines [a, b) (of the object, or pieces [a, b) of its proxy)
    std::uint64_t points = 0;    // input points
    GLuint vao = 0, vbo = 0;     // resident geometry; 0: built and streamed when drawn
    std::vector<GLint> firsts;   // per drawn streamline, into the chunk's vertices
    std::vector<GLsizei> counts;
    GLuint ebo = 0;  // the strips' indices (BuiltLines::indices)
    GLsizei nb_indices = 0;
    std::uint64_t segments = 0, kept = 0, bytes = 0;
    bool built = false;  // firsts/counts known
    // Over pieces of bricks (Bricks): the streamlines whose first piece it
    // holds, counted as drawn when it is; UINT64_MAX otherwise.
    std::uint64_t starts = UINT64_MAX;
};

struct BuiltLines {
    std::vector<LineVertex> verts;
    std::vector<GLint> firsts;
    std::vector<GLsizei> counts;
    // One line strip per streamline, separated by kRestart: a chunk is one
    // glDrawElements (llvmpipe sets up each draw of a glMultiDrawArrays
    // separately: microseconds each, seconds for a million streamlines).
    std::vector<std::uint32_t> indices;
    std::uint64_t segments = 0, kept = 0;
};

// The colouring of tractogram object `o`, resolved per streamline.
std::shared_ptr<LineData> line_data(const Object &o);
// The colour every vertex of `d` has, if it is one (solid colouring, or
// per-streamline colours that happen to be equal): with baked materials it
// is a constant of the program.
std::optional<std::array<std::uint8_t, 4>> uniform_colour(const LineData &d);
// The vertices of streamlines [a, b) of `d`, or of pieces [a, b) of
// `pieces`, decimated at `tol` mm (decimate.hpp), with their draw lists and
// strip indices. Touches nothing but its arguments: chunks are built on
// other threads.
void build_lines(const LineData &d, const Piece *pieces, std::uint64_t a, std::uint64_t b, double tol, BuiltLines &out);
// Where streamlines [a, b) of `d` cross the plane x[axis] = centre (RAS+
// mm): one vertex per crossing, appended to `out`: the crossing point, the
// crossing segment's direction as its tangent, and the colour the streamline
// has there (as build_lines colours it). Returns early, leaving `out`
// partial, once `cancel` is set. Touches nothing but its arguments.
void slab_crossings(const LineData &d, int axis, double centre, std::uint64_t a, std::uint64_t b, std::vector<LineVertex> &out,
                    const std::atomic<bool> *cancel);
// The fibre volume: the level-of-detail proxy of a dense tractogram as a
// participating medium. Lines thinner than a pixel and too many to draw are,
// seen from a distance, a cloud: each voxel keeps how much streamline passes
// through it (mm per mm^3), their mean colour and their main direction, and
// a ray through the voxels composites them front to back, each voxel as
// opaque as its lines would cover of a pixel (1 - exp(-density x line width
// x step)). That is the picture the full frame shows once averaged over a few
// pixels, at any camera, for the cost of a pass over the picture.
struct FibreVolume {
    std::array<int, 3> dim{};       // voxels along x, y, z
    std::array<float, 3> origin{};  // the corner of voxel (0, 0, 0), RAS+ mm
    float voxel_mm = 1;             // edge of a voxel
    // Per voxel (x fastest): linear r, g, b times the density, and the
    // density (mm of streamline per mm^3): premultiplied, so that linear
    // filtering between a full voxel and an empty one keeps the colour.
    std::vector<float> colour_density;
    // Per voxel: the main direction of its streamlines, e (the principal
    // eigenvector of the mean of t t^T, the sign that makes its largest
    // component positive), as e * 127.5 + 127.5, and how many run along it,
    // its eigenvalue (1/3: every direction alike; 1: all along e) as
    // (lambda - 1/3) * 1.5 * 255. A ray sees lines along it end-on.
    std::vector<std::uint8_t> direction;
    // Per voxel: the Chebyshev distance to the nearest voxel with
    // streamlines, capped at 255 (0 in a voxel with streamlines): a ray
    // skips empty space.
    std::vector<std::uint8_t> skip;
    bool empty() const { return colour_density.empty(); }
};
// The fibre volume of `d` (every segment of every streamline when they hold
// at most `budget_points` points, else every k-th, weighted k), on a grid of `grid` voxels along the longest side of
// bounds `b` (which must hold every point). Runs on up to `threads` threads
// (each with a grid of its own: about 40 bytes per voxel). Empty when
// `cancel` is set. Touches nothing but its arguments.
FibreVolume fibre_volume(const LineData &d, const Bounds &b, int grid, double budget_points, unsigned threads,
                         const std::atomic<bool> &cancel);
// A tractogram cut into bricks, for drawing front to back and skipping what
// is hidden. A dense whole-brain tractogram is drawn hundreds of times over
// at every pixel (1M streamlines at 1280x800: about 500 fragments a pixel),
// and llvmpipe's time goes to rasterising fragments that fail the depth test.
// Cut into bricks (cells of a grid over the bounds), its pieces can be drawn
// brick by brick from the nearest, and a brick whose bounds project behind
// what is already drawn at every pixel they cover is skipped: it would not
// change one pixel.
// A piece of a brick in 8 bytes (a whole-brain tractogram has about 11
// pieces per streamline at 12 bricks a side): its streamline, its first
// point (below 2^24) and its number of points (2 to kMaxPoints: a longer run
// is several pieces, each starting at the last point of the one before).
struct BrickPiece {
    static constexpr std::uint32_t kMaxPoints = 255, kMaxFirst = (1u << 24) - 1;
    std::uint32_t s = 0, first_count = 0;
    BrickPiece() = default;
    BrickPiece(std::uint64_t s_, std::uint32_t first, std::uint32_t count) : s(std::uint32_t(s_)), first_count(first << 8 | count) {}
    std::uint32_t first() const { return first_count >> 8; }
    std::uint32_t count() const { return first_count & 0xFF; }
    Piece piece() const { return Piece{s, first(), count()}; }
};
struct Bricks {
    std::array<int, 3> dim{};  // bricks along x, y, z (x fastest)
    // The pieces, brick by brick: each the run of points of one streamline
    // in one brick, and the next point (the segment leaving the brick is the
    // piece's: every segment is in exactly one piece). Brick k's pieces are
    // [begin[k], begin[k + 1]).
    std::vector<BrickPiece> pieces;
    std::vector<std::uint64_t> begin;
    // Brick k's bounds: of its pieces' points (min x, y, z, max x, y, z);
    // min > max when it has none.
    std::vector<std::array<float, 6>> box;
    bool empty() const { return pieces.empty(); }
};
// The bricks of `t` on a grid of `per_side` bricks along the longest side of
// bounds `b` (points outside them count in the bricks at its edges, whose
// boxes grow to hold them), on up to `threads` threads. Two passes over the
// points (count, then fill: no memory beyond the result, 8 bytes a piece).
// Empty when `cancel` is set, and for what BrickPiece cannot hold (2^32
// streamlines or more, a streamline of 2^24 points or more).
Bricks bricks_of(const Tractogram &t, const Bounds &b, int per_side, unsigned threads, const std::atomic<bool> &cancel);
// The finest grid of at most `max_side` bricks along the longest side of
// `b` whose pieces number at most `max_pieces`, estimated from a sample of
// the streamlines (every k-th, about 4096 of them); 0 when even `min_side`
// bricks would take more, or for 2^32 streamlines or more.
int brick_side_for(const Tractogram &t, const Bounds &b, int min_side, int max_side, std::uint64_t max_pieces);

// Chunks of at most max_points input points over streamlines [0, n) (or
// over pieces[0..n)).
std::vector<LineChunk> partition(const Tractogram &t, const Piece *pieces, std::uint64_t n, std::uint64_t max_points = kChunkPoints);
std::vector<LineChunk> partition(const BrickPiece *pieces, std::uint64_t n, std::uint64_t max_points);

}  // namespace hz::core::render
