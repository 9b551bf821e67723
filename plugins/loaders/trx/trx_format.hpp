// TRX tractograms (tee-ar-ex/trx-spec): zip (stored or deflated) or
// directory; header.json, positions, offsets, dpv, dps, groups, dpg.
// Pure C++ without SDK types; trx_plugin.cpp adapts it to hz.loader/1.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace trx {

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
struct Cancelled {};

enum class DType { I8, I16, I32, I64, U8, U16, U32, U64, F16, F32, F64, Bit };
std::size_t dtype_size(DType t);
const char *dtype_name(DType t);

// Where an array lives and how to read its raw bytes (little-endian, C order).
class Container;
struct Entry {
    std::string path;  // e.g. "dpv/fa.float32"
    std::uint64_t bytes = 0;
};

enum class Kind { Dpv, Dps, Group, Dpg };
struct Array {
    Kind kind;
    std::string name;  // dpg: "<group>/<name>"
    DType dtype;
    std::uint32_t cols = 1;
    std::uint64_t rows = 0;
    Entry entry;
};

struct File {
    std::unique_ptr<Container> container;
    std::array<double, 16> voxel_to_rasmm{};
    std::array<std::uint64_t, 3> dims{};
    std::uint64_t nb_streamlines = 0, nb_vertices = 0;
    DType positions_dtype = DType::F32, offsets_dtype = DType::U64;
    Entry positions, offsets;
    bool has_sentinel = true;
    bool has_positions = false;
    std::vector<Array> arrays;
    std::vector<std::pair<std::string, std::string>> header_extra;  // other header.json keys (as JSON text)
    std::string container_kind;                                     // "zip" or "directory"
    File();
    File(File &&) noexcept;
    File &operator=(File &&) noexcept;
    ~File();
};

// Opens and validates everything that can be validated without reading the
// bulk arrays (names, dtypes, sizes against the header); throws FormatError.
File open(const std::string &path);

// Reads positions (converted to float32) and offsets (with the sentinel) into
// host buffers; validates offsets and finiteness. positions == nullptr reads
// the offsets only (the host mapped the positions, see locate_positions).
void read_streamlines(const File &f, float *positions, std::uint64_t *offsets, const std::function<bool()> &cancelled);

// Where float32 positions lie in a file, for mapping them without a copy.
struct Extent {
    std::string file;          // the archive, or the directory's positions file
    std::uint64_t offset = 0;  // byte offset of the first coordinate (a multiple of 4)
    bool has_crc = false;      // zip entries: the stored CRC-32 of the bytes
    std::uint32_t crc = 0;
};
// True, filling `out`, when the positions are float32 and stored as plain
// bytes at a 4-byte aligned offset (a directory, or a stored zip entry);
// false otherwise (the caller reads them with read_streamlines).
bool locate_positions(const File &f, Extent &out);
// Reads one array's raw bytes (rows x cols x dtype_size) into `out`; groups
// are range-checked.
void read_array(const File &f, const Array &a, void *out);

struct WriteArray {
    Kind kind;
    std::string name;
    DType dtype;
    std::uint32_t cols = 1;
    std::uint64_t rows = 0;
    const void *data = nullptr;
};
// Writes a stored (uncompressed) zip with the sentinel in offsets.
// Streamline s is positions[offsets[s] .. offsets[s+1] - gap): with gap 1
// (a mapped TCK's delimiters) the positions entry is streamed into the zip
// without the gap vertices, never read, and the offsets are shifted; no
// per-vertex array may come with it. With `selection`, the zip holds the
// streamlines selection[0 .. nb_selected) only, their positions and dpv rows
// streamed from where they lie; dps, groups and dpg are then the
// selection's already (as hz.ext.write-selection/1 passes them).
void write(const std::string &path, const float *positions, std::uint64_t nb_vertices, const std::uint64_t *offsets,
           std::uint64_t nb_streamlines, const std::array<double, 16> &voxel_to_rasmm, const std::array<std::uint64_t, 3> &dims,
           const std::vector<WriteArray> &arrays, const std::vector<std::pair<std::string, std::string>> &header_extra,
           std::uint32_t gap = 0, const std::uint64_t *selection = nullptr, std::uint64_t nb_selected = 0);

int probe(const unsigned char *head, std::uint64_t size);

float half_to_float(std::uint16_t h);

}  // namespace trx
