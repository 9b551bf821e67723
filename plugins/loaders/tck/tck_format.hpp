// MRtrix TCK streamlines: parsing, validation, decoding and writing.
// Pure C++ with no SDK types, so the format logic is testable on its own;
// tck_plugin.cpp adapts it to the hz.loader/1 ABI.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace tck {

// Every format problem is reported as this exception with a one-line message
// (the plugin prefixes the file name). `io` marks operating-system failures.
struct FormatError : std::runtime_error {
    explicit FormatError(const std::string &m, bool io_error = false) : std::runtime_error(m), io(io_error) {}
    bool io;
};

enum class DataType { Float32LE, Float32BE, Float64LE, Float64BE };
const char *to_string(DataType t);

struct Header {
    std::vector<std::pair<std::string, std::string>> entries;  // file order, incl. repeats
    DataType datatype = DataType::Float32LE;
    std::uint64_t data_offset = 0;
    std::vector<std::string> warnings;  // quirks tolerated (missing datatype, file, ...)
};

// Parses the text header of `bytes[0..size)`. Throws FormatError.
Header parse_header(const unsigned char *bytes, std::uint64_t size);

// The streamline count the header declares (its last `count` field, a
// decimal integer; blanks around it allowed), or nothing when it has none
// or it is not such an integer. Readers never size anything from it: the
// data decide (an interrupted mrtrix write leaves `count: 0000000000`).
std::optional<std::uint64_t> declared_count(const Header &h);

// Called about every million points with the byte offset reached; returns
// true to cancel. The plugin also uses it to drop the mapped pages behind.
using Tick = std::function<bool(std::uint64_t)>;
// Called, from any thread, for each byte range of the file a parallel pass
// has finished with (the plugin drops those mapped pages).
using Release = std::function<void(std::uint64_t, std::uint64_t)>;

// Result of the validating scan of the data section.
struct Layout {
    std::uint64_t nb_streamlines = 0;
    std::uint64_t nb_vertices = 0;
    std::uint64_t end_offset = 0;      // byte just after the Inf terminator
    std::uint64_t trailing_bytes = 0;  // bytes after the terminator (ignored, as mrtrix does)
    // Float32LE files: the triple index of every NaN delimiter, so decode()
    // copies the runs between them without looking at the data again.
    std::vector<std::uint64_t> delimiters;
    // Float32LE files: the bounds of every point (the delimiters and the
    // terminator excluded), found in the same pass; has_bounds is false for
    // the other datatypes and when there is no point.
    bool has_bounds = false;
    float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
};

// Walks the data once, checking every triple (and, for Float32LE, finding
// the bounds in the same pass); throws FormatError on a partial
// NaN/Inf triple, a missing terminator, a streamline not closed by NaN, or a
// truncated triple. `cancelled` is polled periodically (may be empty).
// Float32LE data is classified in parallel chunks (hzio::parallel_chunks;
// `cancelled` then runs on the calling thread with offset 0), and the rare
// NaN/Inf triples are walked in order afterwards: the same rules, the same
// first error.
Layout scan(const unsigned char *bytes, std::uint64_t size, const Header &h, const Tick &cancelled = {}, const Release &release = {});

// Decodes positions (float32, RAS+ mm) and offsets (nb_streamlines + 1).
// The buffers must hold layout.nb_vertices * 3 floats and
// layout.nb_streamlines + 1 offsets.
// Float32LE files are copied in parallel chunks of whole streamlines.
void decode(const unsigned char *bytes, const Header &h, const Layout &layout, float *positions, std::uint64_t *offsets,
            const Tick &cancelled = {}, const Release &release = {});

// True when cancelled() stopped scan/decode.
struct Cancelled {};

// Writes a Float32LE TCK file. `metadata` entries are carried over except the
// keys the writer owns (datatype, file, count); `count` is recomputed.
// Streamline s is positions[offsets[s] .. offsets[s+1] - gap): gap 1 skips
// the vertex after each (a mapped TCK's delimiter), whatever it holds. With
// `selection`, the file holds streamlines selection[0 .. nb_selected) only.
void write(const std::string &path, const float *positions, std::uint64_t nb_vertices, const std::uint64_t *offsets,
           std::uint64_t nb_streamlines, const std::vector<std::pair<std::string, std::string>> &metadata, std::uint32_t gap = 0,
           const std::uint64_t *selection = nullptr, std::uint64_t nb_selected = 0);

// Confidence that `head` starts a TCK file (0..100). Pure.
int probe(const unsigned char *head, std::uint64_t size);

}  // namespace tck
