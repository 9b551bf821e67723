// TrackVis TRK: header parsing, validation, decoding to RAS+ mm, writing.
// Pure C++ without SDK types; trk_plugin.cpp adapts it to hz.loader/1.
// Spec facts: ../shared/formats/FORMATS.md section 1.3 (TrackVis doc,
// nibabel's trk.py).
#pragma once

#include <array>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace trk {

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
struct Cancelled {};

using Mat4 = std::array<double, 16>;  // row-major

// A named group of columns of scalars (per point) or properties (per
// streamline): "fa" = 1 column; "rgb\0" + "3" = 3 columns named rgb.
struct Column {
    std::string name;
    std::uint32_t count = 1;
};

struct Header {
    bool swap = false;  // file byte order differs from the host's
    std::int16_t dim[3] = {0, 0, 0};
    float voxel_size[3] = {0, 0, 0};
    std::int32_t version = 2;
    std::string voxel_order;  // upper-cased; "LPS" when empty
    Mat4 vox_to_ras{};        // identity for v1 or when not recorded
    std::uint32_t n_scalars = 0, n_properties = 0;
    std::vector<Column> scalars, properties;
    std::int32_t n_count = 0;  // 0 = unknown
    std::vector<std::string> warnings;
    // voxmm -> RAS+ mm, nibabel's get_affine_trackvis_to_rasmm.
    Mat4 to_rasmm{};
};

// Parses and validates the 1000-byte header of a file of `size` bytes.
Header parse_header(const unsigned char *bytes, std::uint64_t size);

// Polled now and then, on the calling thread, with the vertices decoded so
// far (decode) or 0 (scan); returns true to cancel.
using Tick = std::function<bool(std::uint64_t)>;

// Where a run of whole records starts: decode() splits the file at these.
struct Chunk {
    std::uint64_t streamline = 0, byte = 0, vertex = 0;
};
struct Layout {
    std::uint64_t nb_streamlines = 0, nb_vertices = 0;
    // Starts of runs of about 16 MiB, then {N, end of the records, V}.
    std::vector<Chunk> chunks;
};
// Called, from any thread, with byte ranges of the file a pass is done
// with (the plugin drops those mapped pages).
using Release = std::function<void(std::uint64_t, std::uint64_t)>;

// How scan() splits its walk: `chains` walks at once (0: scan() chooses,
// one below 64 MiB of records, else 8 per thread) over `threads` threads
// (0: up to 2). Only tests set them; the result does not depend on them.
struct ScanPlan {
    unsigned chains = 0, threads = 0;
};

// Walks the records once, checking every count against the file size:
// several chains of the walk at once from guessed record starts, assembled
// into exactly the single walk's result and first error (see trk_format.cpp).
// `cancelled` is polled on the calling thread. The pages walked stay mapped
// for decode(), which drops them chunk by chunk once decoded: dropping them
// here made decode() map every page a second time (1.2 GB of records:
// 0.42-0.44 s -> 0.38-0.40 s for the whole load in alternating runs, peak
// RSS 1.03x -> 1.04x the decoded data).
Layout scan(const unsigned char *bytes, std::uint64_t size, const Header &h, const Tick &cancelled = {}, ScanPlan plan = {});

// Decodes into host buffers: positions (V x 3, RAS+ mm), offsets (N + 1),
// scalars (V x n_scalars, may be null), properties (N x n_properties, may
// be null). Non-finite coordinates are rejected (FormatError; the first in
// file order). The chunks are decoded in parallel (hzio::parallel_chunks);
// `cancelled` is polled on the calling thread between chunks, and
// `release(begin, end)` (may be empty) is called for each decoded chunk's
// byte range, from any thread.
// With `box` (and positions), also the smallest and largest x, y, z it wrote
// to positions, in the same pass (lo > hi when it wrote none; a value that
// overflowed float32 shows up as an infinite bound).
struct Box {
    float lo[3] = {HUGE_VALF, HUGE_VALF, HUGE_VALF}, hi[3] = {-HUGE_VALF, -HUGE_VALF, -HUGE_VALF};
    void merge(const Box &o) {
        for (int d = 0; d < 3; ++d) {
            lo[d] = std::min(lo[d], o.lo[d]);
            hi[d] = std::max(hi[d], o.hi[d]);
        }
    }
};
void decode(const unsigned char *bytes, std::uint64_t size, const Header &h, const Layout &l, float *positions, std::uint64_t *offsets,
            float *scalars, float *properties, const Tick &cancelled = {}, const Release &release = {}, Box *box = nullptr);

// What write() needs beyond the streamlines.
struct WriteSpec {
    Mat4 vox_to_ras{};  // reference grid voxel -> RAS+ mm
    std::array<std::uint64_t, 3> dims{};
    std::vector<Column> scalars, properties;  // names and widths, <= 10 each, names <= 20 bytes incl. count
    const float *scalar_data = nullptr;       // V x sum(scalars.count)
    const float *property_data = nullptr;     // N x sum(properties.count)
    // Vertices after each streamline that belong to none (0, or 1 for a
    // mapped TCK's delimiters): streamline s is [offsets[s], offsets[s+1] -
    // gap); scalar rows are indexed like the positions.
    std::uint32_t gap = 0;
    // When set, the file holds streamlines selection[0 .. nb_selected)
    // only; property rows are then the selection's (row k for the file's
    // streamline k), scalar rows still indexed like the positions.
    const std::uint64_t *selection = nullptr;
    std::uint64_t nb_selected = 0;
};
// Streamlines without points are left out when there are properties (TRK
// readers, nibabel's among them, cannot read such a record then); returns
// how many were.
std::uint64_t write(const std::string &path, const float *positions, std::uint64_t nb_vertices, const std::uint64_t *offsets,
                    std::uint64_t nb_streamlines, const WriteSpec &spec);

int probe(const unsigned char *head, std::uint64_t size);

// Orientation codes of an affine's columns ("RAS", "LPS", ...), as nibabel's aff2axcodes.
std::string axcodes(const Mat4 &a);

}  // namespace trk
