// PLY and Wavefront OBJ triangle meshes. Pure C++ without SDK types;
// plyobj_plugin.cpp adapts it to hz.loader/1.
//
// Reading goes through Debian's libraries: PLY through Assimp (ASCII and
// both binary byte orders), OBJ through tinyobjloader. Both keep the file's
// vertices in file order, one per vertex record, so per-vertex overlays
// (thickness, labels) stay aligned. Before Assimp sees a PLY file its header
// is parsed here and every element's declared size is checked against the
// bytes after the header, so a 100-byte file cannot ask for 2^31 records.
//
// Writing is done here, not by Assimp's exporters: Assimp 5.2's binary PLY
// exporter writes files its own importer misreads, and its OBJ exporter
// drops unused vertices and renumbers the rest, which would break overlays.
// PLY is written as binary little-endian, OBJ as text with "%.9g" (float32
// round-trips exactly).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace plyobj {

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// A scalar per-vertex property other than position, normal and colour
// (MeshLab's quality, a curvature, a label): read into a per-vertex array of
// the same name and type, and written back as a property.
struct VertexProperty {
    std::string name;
    std::string type;                    // canonical PLY type: char uchar short ushort int uint float double
    std::vector<unsigned char> bytes;    // one value per vertex, host (little-endian) order
};

// The size of a canonical or alias PLY type name (int8 ... float64), 0 if unknown.
unsigned ply_type_size(const std::string &type);
// The canonical name of a PLY type (float32 -> float), or "" if unknown.
std::string ply_canonical_type(const std::string &type);

struct Mesh {
    std::vector<float> vertices;         // N x 3, as stored (RAS+ mm by convention)
    std::vector<std::uint32_t> faces;    // M x 3, 0-based, < N
    std::vector<float> colors;           // N x 3 in [0, 1], or empty
    std::vector<VertexProperty> properties;  // PLY: the vertex element's other scalar properties, in file order
    std::vector<std::pair<std::string, std::string>> metadata;  // PLY comments, ignored elements
};

struct PlyProperty {
    std::string name, type;  // type: the value type (of a list: its items)
    std::string count_type;  // a list's length type; empty for a scalar
};
struct PlyElement {
    std::string name;
    std::uint64_t count = 0;
    std::vector<PlyProperty> properties;
};

// The declared layout of a PLY file's header (used to bound what a reader
// may allocate, and to list comments).
struct PlyHeader {
    std::uint64_t header_bytes = 0;      // up to and including "end_header\n"
    std::string format;                  // ascii | binary_little_endian | binary_big_endian
    std::uint64_t vertices = 0, faces = 0;
    std::vector<std::string> comments;
    std::vector<std::string> other_elements;  // e.g. "edge 12"
    std::vector<PlyElement> elements;         // in file order
};

// Parses and checks a PLY header (needs the whole file for the size check);
// throws FormatError naming the problem.
PlyHeader check_ply_header(const unsigned char *data, std::uint64_t size);

// Walks the body record by record as `h` declares it (sizes, list lengths,
// numbers, face indices); throws FormatError naming the element and record.
// With `properties`, also collects the vertex element's scalar properties
// other than x y z, nx ny nz and red green blue alpha (an integer outside
// its type's range is an error).
void check_ply_body(const PlyHeader &h, const unsigned char *data, std::uint64_t size,
                    std::vector<VertexProperty> *properties = nullptr);

// Reads a whole PLY file held in memory (header and body checked first, then
// Assimp); throws FormatError.
Mesh read_ply(const unsigned char *data, std::uint64_t size);

// Reads a whole OBJ file held in memory (materials are not read: an mtllib
// line names a file, and a mesh needs none); throws FormatError.
Mesh read_obj(const unsigned char *data, std::uint64_t size);

// Writers: `colors` is N x 4 uint8 RGBA or empty; `comments` go into the PLY
// header (OBJ: "#" lines). Throw FormatError on I/O errors.
struct WriteInput {
    const float *vertices = nullptr;
    std::uint64_t nb_vertices = 0;
    const std::uint32_t *faces = nullptr;
    std::uint64_t nb_faces = 0;
    std::vector<std::uint8_t> colors;
    std::vector<std::string> comments;
    // PLY only: extra vertex properties, each `nb_vertices` values of its
    // canonical type, host order; `data` is borrowed for the call.
    struct Property {
        std::string name, type;
        const unsigned char *data = nullptr;
    };
    std::vector<Property> properties;
};
void write_ply(const std::string &path, const WriteInput &in);
void write_obj(const std::string &path, const WriteInput &in);

}  // namespace plyobj
