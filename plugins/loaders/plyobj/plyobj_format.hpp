// PLY and Wavefront OBJ triangle meshes. Pure C++ without SDK types;
// plyobj_plugin.cpp adapts it to hz.loader/1.
//
// PLY is read by Horizon's own decoder: every record is walked as the
// header declares it, every value checked, the header's declared sizes
// checked against the file before anything is allocated. (Until 2026-11 it
// went through Assimp after these checks; fuzzing kept finding inputs the
// checks passed and Assimp 5.2 still mis-parsed into crashes or allocations
// of several GB, and the checking walk already decoded every value.) OBJ is
// read through tinyobjloader. Both keep the file's vertices in file order,
// one per vertex record, so per-vertex overlays (thickness, labels) stay
// aligned.
//
// Writing is done here: PLY as binary little-endian, OBJ as text with
// "%.9g" (float32 round-trips exactly); Assimp's OBJ exporter drops unused
// vertices and renumbers the rest, which would break overlays.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
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
    std::string type;                  // canonical PLY type: char uchar short ushort int uint float double
    std::vector<unsigned char> bytes;  // one value per vertex, host (little-endian) order
};

// The size of a canonical or alias PLY type name (int8 ... float64), 0 if unknown.
unsigned ply_type_size(const std::string &type);
// The canonical name of a PLY type (float32 -> float), or "" if unknown.
std::string ply_canonical_type(const std::string &type);
// A vertex property Horizon reads for geometry or colour (x y z, nx ny nz,
// red green blue alpha), as opposed to one kept as a per-vertex array.
bool is_role_property(std::string_view name);

struct Mesh {
    std::vector<float> vertices;                                // N x 3, as stored (RAS+ mm by convention)
    std::vector<std::uint32_t> faces;                           // M x 3, 0-based, < N
    std::vector<float> colors;                                  // N x 3 in [0, 1], or empty
    std::vector<VertexProperty> properties;                     // PLY: the vertex element's other scalar properties, in file order
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
    std::uint64_t header_bytes = 0;  // up to and including "end_header\n"
    std::string format;              // ascii | binary_little_endian | binary_big_endian
    std::uint64_t vertices = 0, faces = 0;
    std::vector<std::string> comments;
    std::vector<std::string> other_elements;  // e.g. "edge 12"
    std::vector<PlyElement> elements;         // in file order
};

// Parses and checks a PLY header (needs the whole file for the size check);
// throws FormatError naming the problem.
PlyHeader check_ply_header(const unsigned char *data, std::uint64_t size);

// Decodes the body record by record as `h` declares it: every value is read
// and checked (inside the file, a number of its type, an integer within its
// type's range, list lengths that fit, faces of at least 3 vertices that
// exist). The vertex element's coordinates, colours (red green blue) and its
// other scalar properties, and the face element's polygons split into fans,
// go to `out`. Throws FormatError naming the element and record.
void decode_ply_body(const PlyHeader &h, const unsigned char *data, std::uint64_t size, Mesh &out);

// Reads a whole PLY file held in memory; throws FormatError.
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
