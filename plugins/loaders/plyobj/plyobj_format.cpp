// PLY (Horizon's decoder) and OBJ (tinyobjloader) meshes; see plyobj_format.hpp.
#include "plyobj_format.hpp"

#include <tiny_obj_loader.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <istream>
#include <memory>
#include <sstream>
#include <streambuf>
#include <string_view>

namespace plyobj {

namespace {

std::string trim(std::string s) {
    const auto a = s.find_first_not_of(" \t\r"), z = s.find_last_not_of(" \t\r");
    return a == std::string::npos ? std::string() : s.substr(a, z - a + 1);
}

std::vector<std::string> words(const std::string &line) {
    std::istringstream in(line);
    std::vector<std::string> w;
    for (std::string x; in >> x;) w.push_back(x);
    return w;
}

// Bytes of one binary PLY scalar, 0 for an unknown type name.
unsigned type_size(const std::string &t) {
    if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
    if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
    if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32") return 4;
    if (t == "double" || t == "float64") return 8;
    return 0;
}

bool is_float(const std::string &t) { return t == "float" || t == "float32" || t == "double" || t == "float64"; }

// An integer value's range check for a PLY integer type of `size` bytes.
bool fits(std::int64_t v, unsigned size, bool is_signed) {
    const int bits = int(8 * size);
    if (is_signed) return v >= -(std::int64_t(1) << (bits - 1)) && v < (std::int64_t(1) << (bits - 1));
    return v >= 0 && v < (std::int64_t(1) << bits);
}

// A read-only std::streambuf over memory, so that tinyobjloader parses the
// mapped file without a copy.
struct MemoryBuf : std::streambuf {
    MemoryBuf(const unsigned char *p, std::uint64_t n) {
        char *b = const_cast<char *>(reinterpret_cast<const char *>(p));
        setg(b, b, b + n);
    }
};

void check_finite(const std::vector<float> &v) {
    for (std::size_t i = 0; i < v.size(); ++i)
        if (!std::isfinite(v[i])) throw FormatError("vertex " + std::to_string(i / 3) + " has a non-finite coordinate");
}

}  // namespace

unsigned ply_type_size(const std::string &t) { return type_size(t); }

bool is_role_property(std::string_view name) {
    for (const char *r : {"x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "alpha"})
        if (name == r) return true;
    return false;
}

std::string ply_canonical_type(const std::string &t) {
    static const std::pair<const char *, const char *> kAlias[] = {{"int8", "char"},     {"uint8", "uchar"},   {"int16", "short"},
                                                                   {"uint16", "ushort"}, {"int32", "int"},     {"uint32", "uint"},
                                                                   {"float32", "float"}, {"float64", "double"}};
    for (const auto &[a, c] : kAlias)
        if (t == a || t == c) return c;
    return "";
}

PlyHeader check_ply_header(const unsigned char *data, std::uint64_t size) {
    PlyHeader h;
    const std::uint64_t limit = std::min<std::uint64_t>(size, 1 << 20);
    const std::string text(reinterpret_cast<const char *>(data), static_cast<std::size_t>(limit));
    if (text.compare(0, 3, "ply") != 0 || (text.size() > 3 && text[3] != '\n' && text[3] != '\r'))
        throw FormatError("does not start with 'ply' (not a PLY file)");
    // "end_header" alone on its line (a CR before the LF allowed)
    std::size_t end = 0, nl = std::string::npos;
    for (std::size_t at = text.find("\nend_header"); at != std::string::npos; at = text.find("\nend_header", at + 1)) {
        std::size_t q = at + 11;
        if (q < text.size() && text[q] == '\r') ++q;
        if (q < text.size() && text[q] == '\n') {
            end = at + 1, nl = q;
            break;
        }
    }
    if (nl == std::string::npos) throw FormatError("no 'end_header' line within the first " + std::to_string(limit) + " bytes");
    h.header_bytes = nl + 1;
    for (std::size_t i = 0; i < end; ++i)
        if ((static_cast<unsigned char>(text[i]) < 0x20 && text[i] != '\n' && text[i] != '\r' && text[i] != '\t') ||
            (text[i] == '\r' && text[i + 1] != '\n'))  // (found by fuzzing: Assimp splits lines at a lone CR)
            throw FormatError("the header holds a control byte at offset " + std::to_string(i));
    std::vector<PlyElement> elements;
    std::istringstream in(text.substr(0, static_cast<std::size_t>(end)));
    std::string line;
    std::getline(in, line);  // "ply"
    int lineno = 1;
    while (std::getline(in, line)) {
        ++lineno;
        const std::vector<std::string> w = words(line);
        const std::string where = "header line " + std::to_string(lineno);
        if (w.empty()) continue;
        if (w[0] == "comment" || w[0] == "obj_info") {
            if (h.comments.size() < 64) h.comments.push_back(trim(line.substr(line.find(w[0]) + w[0].size())));
        } else if (w[0] == "format") {
            if (w.size() != 3 || (w[1] != "ascii" && w[1] != "binary_little_endian" && w[1] != "binary_big_endian") || w[2] != "1.0")
                throw FormatError(where + ": format '" + trim(line) + "' (ascii, binary_little_endian or binary_big_endian 1.0)");
            h.format = w[1];
        } else if (w[0] == "element") {
            if (w.size() != 3 || w[2].find_first_not_of("0123456789") != std::string::npos || w[2].size() > 10)
                throw FormatError(where + ": '" + trim(line) + "' is not 'element NAME COUNT'");
            PlyElement e;
            e.name = w[1];
            e.count = std::stoull(w[2]);
            if (e.count > 0x7FFFFFFF)
                throw FormatError(where + ": element '" + e.name + "' declares " + w[2] + " records (at most 2^31-1)");
            elements.push_back(e);
        } else if (w[0] == "property") {
            if (elements.empty()) throw FormatError(where + ": a property before any element");
            PlyElement &e = elements.back();
            PlyProperty p;
            if (w.size() == 5 && w[1] == "list") {
                if (type_size(w[2]) == 0 || type_size(w[3]) == 0 || is_float(w[2]))
                    throw FormatError(where + ": list property '" + w[4] + "' has types '" + w[2] + " " + w[3] + "'");
                p = {w[4], w[3], w[2]};
            } else if (w.size() == 3 && type_size(w[1]) != 0) {
                p = {w[2], w[1], ""};
            } else {
                throw FormatError(where + ": '" + trim(line) + "' is not a property declaration");
            }
            for (const PlyProperty &q : e.properties)
                if (q.name == p.name) throw FormatError(where + ": property '" + p.name + "' declared twice");
            e.properties.push_back(p);
        } else {
            throw FormatError(where + ": unknown keyword '" + w[0] + "'");
        }
    }
    if (h.format.empty()) throw FormatError("no 'format' line in the header");
    // Bounds on the declaration itself (found by fuzzing: a 9 kB header of a
    // hundred property-less elements made Assimp 5.2 allocate 2.3 GB).
    if (elements.size() > 16) throw FormatError(std::to_string(elements.size()) + " elements declared (at most 16 are read)");
    for (const PlyElement &e : elements) {
        if (e.properties.empty()) throw FormatError("element '" + e.name + "' has no properties");
        if (e.properties.size() > 64)
            throw FormatError("element '" + e.name + "' has " + std::to_string(e.properties.size()) + " properties (at most 64)");
    }
    const bool ascii = h.format == "ascii";
    const std::uint64_t body = size - h.header_bytes;
    std::uint64_t need = 0;
    bool have_vertex = false;
    for (const PlyElement &e : elements) {
        std::uint64_t binary_min = 0;  // bytes one record takes at least (ASCII: 2 per value)
        for (const PlyProperty &p : e.properties) binary_min += type_size(p.count_type.empty() ? p.type : p.count_type);
        need += e.count * (ascii ? 2 * e.properties.size() : binary_min);
        if (need > body)
            throw FormatError("element '" + e.name + "' declares " + std::to_string(e.count) + " records: the elements need at least " +
                              std::to_string(need) + " bytes, the file has " + std::to_string(body) + " after the header");
        auto has = [&](const char *n) {
            return std::any_of(e.properties.begin(), e.properties.end(), [&](const PlyProperty &p) { return p.name == n; });
        };
        if (e.name == "vertex") {
            if (have_vertex) throw FormatError("two vertex elements");
            if (!(has("x") && has("y") && has("z"))) throw FormatError("the vertex element has no x, y and z properties");
            for (const PlyProperty &p : e.properties)
                if (!p.count_type.empty()) throw FormatError("the vertex element has a list property ('" + p.name + "')");
            h.vertices = e.count;
            have_vertex = true;
        } else if (e.name == "face") {
            if (!has("vertex_indices") && !has("vertex_index")) throw FormatError("the face element has no vertex_indices list");
            h.faces = e.count;
        } else {
            h.other_elements.push_back(e.name + " " + std::to_string(e.count));
        }
    }
    if (!have_vertex) throw FormatError("no vertex element");
    h.elements = std::move(elements);
    return h;
}

// Decodes the body record by record as the header declares it. Every value
// is read and checked (inside the file, a number of its type, list lengths
// that fit, faces of at least 3 vertices that exist); the vertex element's
// coordinates, colours and other scalar properties and the face element's
// polygons (as fans) go to `out`. Errors name the element and record.
void decode_ply_body(const PlyHeader &h, const unsigned char *data, std::uint64_t size, Mesh &out) {
    const bool ascii = h.format == "ascii", big = h.format == "binary_big_endian";
    std::uint64_t pos = h.header_bytes;
    auto fail = [&](const PlyElement &e, std::uint64_t r, const std::string &what) {
        throw FormatError("element '" + e.name + "' record " + std::to_string(r) + ": " + what);
    };
    // ASCII: the next whitespace-separated token.
    auto token = [&]() -> std::string_view {
        while (pos < size && (data[pos] == ' ' || data[pos] == '\t' || data[pos] == '\r' || data[pos] == '\n')) ++pos;
        const std::uint64_t start = pos;
        while (pos < size && data[pos] != ' ' && data[pos] != '\t' && data[pos] != '\r' && data[pos] != '\n') ++pos;
        return {reinterpret_cast<const char *>(data + start), std::size_t(pos - start)};
    };
    auto is_signed = [](const std::string &t) {
        return t == "char" || t == "int8" || t == "short" || t == "int16" || t == "int" || t == "int32";
    };
    // What each property is and where its values go, decided once per element.
    enum class Role { Skip, Coord, Colour, Extra, Indices };
    struct Kind {
        unsigned size, count_size;
        bool is_signed, count_signed, is_float, list;
        Role role;
        int axis;  // Coord / Colour: 0..2
        VertexProperty *extra;
        double colour_scale;  // Colour: integers in [0, type max], floats in [0, 1]
    };
    // One value of a property: ints exactly, floats as double.
    struct Value {
        std::int64_t i;
        double d;
    };
    auto read_value = [&](const PlyElement &e, std::uint64_t r, unsigned n, bool is_float, bool sgn, const std::string &name) -> Value {
        if (ascii) {
            const std::string_view t = token();
            if (t.empty()) fail(e, r, "the file ends inside it");
            const char *b = t.data() + (t.size() > 1 && t[0] == '+'), *end = t.data() + t.size();
            if (is_float) {
                double d = 0;
                const auto res = std::from_chars(b, end, d);
                if (res.ptr != end || res.ec != std::errc())
                    fail(e, r, "'" + std::string(t.substr(0, 20)) + "' is not a number (" + name + ")");
                return {0, d};
            }
            std::int64_t v = 0;
            const auto res = std::from_chars(b, end, v);
            if (res.ptr != end || res.ec != std::errc())
                fail(e, r, "'" + std::string(t.substr(0, 20)) + "' is not an integer (" + name + ")");
            if (!fits(v, n, sgn)) fail(e, r, std::to_string(v) + " does not fit the type of '" + name + "'");
            return {v, double(v)};
        }
        if (size - pos < n) fail(e, r, "the file ends inside it");
        std::uint64_t u = 0;
        for (unsigned i = 0; i < n; ++i) u |= std::uint64_t(data[pos + (big ? n - 1 - i : i)]) << (8 * i);
        pos += n;
        if (is_float) {
            if (n == 4) {
                float f;
                const auto u32 = static_cast<std::uint32_t>(u);
                std::memcpy(&f, &u32, 4);
                return {0, f};
            }
            double d;
            std::memcpy(&d, &u, 8);
            return {0, d};
        }
        std::int64_t v = static_cast<std::int64_t>(u);
        if (sgn && n < 8 && (u >> (8 * n - 1)) != 0) v = static_cast<std::int64_t>(u | (~std::uint64_t(0) << (8 * n)));
        return {v, double(v)};
    };
    const std::uint64_t nv = h.vertices;
    bool colours = false;
    std::vector<std::uint32_t> polygon;
    for (const PlyElement &e : h.elements) {
        const bool vertex = e.name == "vertex", face = e.name == "face";
        std::vector<Kind> kinds;
        bool fixed = !ascii;
        std::uint64_t record = 0;
        int colour_axes = 0;
        for (const PlyProperty &p : e.properties) {
            const bool list = !p.count_type.empty();
            Kind k{type_size(p.type), list ? type_size(p.count_type) : 0,
                   is_signed(p.type), list && is_signed(p.count_type),
                   is_float(p.type),  list,
                   Role::Skip,        0,
                   nullptr,           1.0};
            if (vertex) {
                static const char *const kCoord[] = {"x", "y", "z"}, *const kColour[] = {"red", "green", "blue"};
                for (int a = 0; a < 3; ++a) {
                    if (p.name == kCoord[a]) k.role = Role::Coord, k.axis = a;
                    if (p.name == kColour[a]) k.role = Role::Colour, k.axis = a, ++colour_axes;
                }
                if (k.role == Role::Colour && !k.is_float)
                    k.colour_scale = double((std::uint64_t(1) << (8 * k.size - (k.is_signed ? 1 : 0))) - 1);
                if (k.role == Role::Skip && !list && !is_role_property(p.name)) {
                    out.properties.push_back({p.name, ply_canonical_type(p.type), {}});
                    k.role = Role::Extra;
                }
            } else if (face && list && (p.name == "vertex_indices" || p.name == "vertex_index") && !k.is_float) {
                k.role = Role::Indices;
            }
            kinds.push_back(k);
            fixed &= !list;
            record += type_size(p.type);
        }
        if (vertex) {
            // (pointers into out.properties, now that it no longer grows)
            std::size_t next = out.properties.size();
            for (auto it = kinds.rbegin(); it != kinds.rend(); ++it)
                if (it->role == Role::Extra) it->extra = &out.properties[--next];
            for (Kind &k : kinds)
                if (k.extra) k.extra->bytes.reserve(std::size_t(e.count * k.size));
            out.vertices.assign(3 * std::size_t(e.count), 0.0f);
            colours = colour_axes == 3;
            if (colours) out.colors.assign(3 * std::size_t(e.count), 0.0f);
        }
        if (fixed && !vertex && !face) {  // binary records of one size, nothing to keep: only to fit
            if (e.count * record > size - pos) fail(e, (size - pos) / record, "the file ends inside it");
            pos += e.count * record;
            continue;
        }
        for (std::uint64_t r = 0; r < e.count; ++r) {
            for (std::size_t j = 0; j < kinds.size(); ++j) {
                const Kind &k = kinds[j];
                const std::string &name = e.properties[j].name;
                std::int64_t n = 1;
                if (k.list) {  // the list length
                    n = read_value(e, r, k.count_size, false, k.count_signed, name).i;
                    const std::uint64_t item = ascii ? 2 : k.size;
                    if (n < 0 || std::uint64_t(n) > (size - pos + 1) / item)
                        fail(e, r, "list '" + name + "' of " + std::to_string(n) + " values, more than the file holds");
                    if (k.role == Role::Indices && n < 3) fail(e, r, "a face of " + std::to_string(n) + " vertices");
                    polygon.clear();
                }
                for (std::int64_t i = 0; i < n; ++i) {
                    const std::uint64_t at = pos;
                    const Value v = read_value(e, r, k.size, k.is_float, k.is_signed, name);
                    switch (k.role) {
                    case Role::Coord: out.vertices[3 * r + std::size_t(k.axis)] = static_cast<float>(v.d); break;
                    case Role::Colour:
                        if (colours)
                            out.colors[3 * r + std::size_t(k.axis)] = static_cast<float>(std::clamp(v.d / k.colour_scale, 0.0, 1.0));
                        break;
                    case Role::Extra:
                        if (ascii) {
                            if (k.is_float) {
                                const float f = static_cast<float>(v.d);
                                const auto *src = k.size == 4 ? reinterpret_cast<const unsigned char *>(&f)
                                                              : reinterpret_cast<const unsigned char *>(&v.d);
                                k.extra->bytes.insert(k.extra->bytes.end(), src, src + k.size);
                            } else {
                                const auto u = static_cast<std::uint64_t>(v.i);  // little-endian host
                                for (unsigned b = 0; b < k.size; ++b) k.extra->bytes.push_back(static_cast<unsigned char>(u >> (8 * b)));
                            }
                        } else {
                            for (unsigned b = 0; b < k.size; ++b) k.extra->bytes.push_back(data[at + (big ? k.size - 1 - b : b)]);
                        }
                        break;
                    case Role::Indices:
                        if (v.i < 0 || std::uint64_t(v.i) >= nv)
                            fail(e, r, "uses vertex " + std::to_string(v.i) + ", outside [0, " + std::to_string(nv) + ")");
                        polygon.push_back(static_cast<std::uint32_t>(v.i));
                        break;
                    case Role::Skip: break;
                    }
                }
                if (k.role == Role::Indices)
                    for (std::size_t q = 2; q < polygon.size(); ++q) {  // a fan: 0 1 2, 0 2 3, ...
                        out.faces.push_back(polygon[0]);
                        out.faces.push_back(polygon[q - 1]);
                        out.faces.push_back(polygon[q]);
                    }
            }
        }
    }
}

Mesh read_ply(const unsigned char *data, std::uint64_t size) {
    const PlyHeader h = check_ply_header(data, size);
    if (h.faces == 0) throw FormatError("no faces (" + std::to_string(h.vertices) + " vertices: a point cloud, not a mesh)");
    Mesh out;
    decode_ply_body(h, data, size, out);
    check_finite(out.vertices);
    if (out.faces.empty()) throw FormatError("no triangles");
    out.metadata.emplace_back("ply format", h.format);
    for (const auto &c : h.comments) out.metadata.emplace_back("comment", c);
    for (const auto &e : h.other_elements) out.metadata.emplace_back("ignored element", e);
    return out;
}

// tinyobjloader reads a number it cannot parse ("nan", "1.0e", "abc") as 0;
// this pass rejects such vertex lines instead, naming the line.
static void check_obj_vertices(const unsigned char *data, std::uint64_t size) {
    const char *p = reinterpret_cast<const char *>(data), *end = p + size;
    std::uint64_t lineno = 0;
    while (p < end) {
        const char *eol = static_cast<const char *>(std::memchr(p, '\n', std::size_t(end - p)));
        if (eol == nullptr) eol = end;
        ++lineno;
        const char *q = p;
        while (q < eol && (*q == ' ' || *q == '\t')) ++q;
        if (eol - q >= 2 && q[0] == 'v' && (q[1] == ' ' || q[1] == '\t')) {
            q += 2;
            for (int c = 0; c < 3; ++c) {
                while (q < eol && (*q == ' ' || *q == '\t')) ++q;
                const char *t = q;
                while (t < eol && *t != ' ' && *t != '\t' && *t != '\r') ++t;
                float x = 0;
                const char *start = (q < t && *q == '+') ? q + 1 : q;
                const auto res = std::from_chars(start, t, x);
                if (q == t || res.ec != std::errc() || res.ptr != t || !std::isfinite(x))
                    throw FormatError("line " + std::to_string(lineno) + ": vertex coordinate '" +
                                      std::string(q, std::size_t(std::min<std::ptrdiff_t>(t - q, 40))) + "' is not a finite number");
                q = t;
            }
        }
        p = eol + 1;
    }
}

Mesh read_obj(const unsigned char *data, std::uint64_t size) {
    check_obj_vertices(data, size);
    MemoryBuf buf(data, size);
    std::istream in(&buf);
    tinyobj::attrib_t attrib;
    std::vector<tinyobj::shape_t> shapes;
    std::vector<tinyobj::material_t> materials;
    std::string warn, err;
    // No material reader: mtllib lines are not followed. Polygons are split
    // into fans; colours are kept only when every vertex has them.
    if (!tinyobj::LoadObj(&attrib, &shapes, &materials, &warn, &err, &in, nullptr, true, false))
        throw FormatError("not read by tinyobjloader: " + trim(err.empty() ? warn : err));
    Mesh out;
    out.vertices.assign(attrib.vertices.begin(), attrib.vertices.end());
    if (out.vertices.empty()) throw FormatError("no vertices ('v' lines)");
    if (out.vertices.size() / 3 > 0x7FFFFFFF) throw FormatError("more than 2^31-1 vertices");
    check_finite(out.vertices);
    const std::uint64_t nv = out.vertices.size() / 3;
    std::uint64_t lines = 0, points = 0;
    for (const auto &s : shapes) {
        lines += s.lines.num_line_vertices.size();
        points += s.points.indices.size();
        std::size_t k = 0;
        for (const unsigned char fv : s.mesh.num_face_vertices) {
            if (fv != 3) throw FormatError("a face of " + std::to_string(fv) + " vertices after triangulation");
            for (unsigned c = 0; c < 3; ++c, ++k) {
                const int v = s.mesh.indices[k].vertex_index;
                if (v < 0 || std::uint64_t(v) >= nv)
                    throw FormatError("face in '" + s.name + "' uses vertex " + std::to_string(std::int64_t(v) + 1) +
                                      " (1-based), outside 1.." + std::to_string(nv));
                out.faces.push_back(static_cast<std::uint32_t>(v));
            }
        }
    }
    if (out.faces.empty()) throw FormatError("no faces ('f' lines): a point cloud, not a mesh");
    if (attrib.colors.size() == out.vertices.size()) {
        out.colors.assign(attrib.colors.begin(), attrib.colors.end());
        for (float &c : out.colors) c = std::isfinite(c) ? std::clamp(c, 0.0f, 1.0f) : 0.0f;
    }
    if (lines) out.metadata.emplace_back("ignored lines", std::to_string(lines));
    if (points) out.metadata.emplace_back("ignored points", std::to_string(points));
    if (!materials.empty() || !attrib.texcoords.empty()) out.metadata.emplace_back("ignored", "texture coordinates and materials");
    return out;
}

namespace {

struct File {
    std::FILE *f;
    explicit File(const std::string &path) : f(std::fopen(path.c_str(), "wb")) {
        if (f == nullptr) throw FormatError(std::string("cannot create: ") + std::strerror(errno));
    }
    ~File() {
        if (f) std::fclose(f);
    }
    void put(const void *p, std::size_t n) {
        if (n && std::fwrite(p, 1, n, f) != n) throw FormatError("write failed");
    }
    void close() {
        const int rc = std::fclose(f);
        f = nullptr;
        if (rc != 0) throw FormatError("write failed");
    }
};

std::string one_line(std::string s) {
    std::replace(s.begin(), s.end(), '\n', ' ');
    std::replace(s.begin(), s.end(), '\r', ' ');
    return s;
}

void check_input(const WriteInput &in) {
    if (in.nb_vertices > 0x7FFFFFFF || in.nb_faces > 0x7FFFFFFF) throw FormatError("too many vertices or faces");
    for (std::uint64_t i = 0; i < 3 * in.nb_faces; ++i)
        if (in.faces[i] >= in.nb_vertices) throw FormatError("a face uses a vertex index out of range");
}

}  // namespace

void write_ply(const std::string &path, const WriteInput &in) {
    check_input(in);
    static_assert(std::endian::native == std::endian::little, "the PLY writer assumes a little-endian host");
    const bool rgba = !in.colors.empty();
    std::string h = "ply\nformat binary_little_endian 1.0\ncomment created by Horizon (RAS+ mm)\n";
    for (const auto &c : in.comments)
        if (c != "created by Horizon (RAS+ mm)") h += "comment " + one_line(c) + "\n";
    h += "element vertex " + std::to_string(in.nb_vertices) + "\nproperty float x\nproperty float y\nproperty float z\n";
    if (rgba) h += "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n";
    std::size_t rec = rgba ? 16 : 12;
    std::vector<unsigned> sizes;
    for (const auto &p : in.properties) {
        const unsigned n = type_size(p.type);
        if (n == 0 || p.type != ply_canonical_type(p.type) || p.data == nullptr)
            throw FormatError("vertex property '" + p.name + "': bad type '" + p.type + "'");
        h += "property " + p.type + " " + p.name + "\n";
        sizes.push_back(n);
        rec += n;
    }
    h += "element face " + std::to_string(in.nb_faces) + "\nproperty list uchar int vertex_indices\nend_header\n";
    File f(path);
    f.put(h.data(), h.size());
    std::vector<unsigned char> chunk;
    chunk.reserve(rec * 65536);
    for (std::uint64_t i = 0; i < in.nb_vertices; ++i) {
        const auto *p = reinterpret_cast<const unsigned char *>(in.vertices + 3 * i);
        chunk.insert(chunk.end(), p, p + 12);
        if (rgba) chunk.insert(chunk.end(), in.colors.begin() + std::ptrdiff_t(4 * i), in.colors.begin() + std::ptrdiff_t(4 * i + 4));
        for (std::size_t k = 0; k < sizes.size(); ++k)
            chunk.insert(chunk.end(), in.properties[k].data + i * sizes[k], in.properties[k].data + (i + 1) * sizes[k]);
        if (chunk.size() >= rec * 65536) f.put(chunk.data(), chunk.size()), chunk.clear();
    }
    for (std::uint64_t i = 0; i < in.nb_faces; ++i) {
        chunk.push_back(3);
        const auto *p = reinterpret_cast<const unsigned char *>(in.faces + 3 * i);
        chunk.insert(chunk.end(), p, p + 12);
        if (chunk.size() >= 13 * 65536) f.put(chunk.data(), chunk.size()), chunk.clear();
    }
    f.put(chunk.data(), chunk.size());
    f.close();
}

void write_obj(const std::string &path, const WriteInput &in) {
    check_input(in);
    File f(path);
    std::string out = "# created by Horizon (RAS+ mm)\n";
    for (const auto &c : in.comments)
        if (c != "created by Horizon (RAS+ mm)") out += "# " + one_line(c) + "\n";
    char buf[160];
    for (std::uint64_t i = 0; i < in.nb_vertices; ++i) {
        const float *v = in.vertices + 3 * i;
        int n = 0;
        if (in.colors.empty())
            n = std::snprintf(buf, sizeof buf, "v %.9g %.9g %.9g\n", v[0], v[1], v[2]);
        else  // the vertex-colour extension (MeshLab, tinyobjloader): "v x y z r g b", colours in [0, 1]
            n = std::snprintf(buf, sizeof buf, "v %.9g %.9g %.9g %.9g %.9g %.9g\n", v[0], v[1], v[2], in.colors[4 * i] / 255.0,
                              in.colors[4 * i + 1] / 255.0, in.colors[4 * i + 2] / 255.0);
        out.append(buf, std::size_t(n));
        if (out.size() > (1 << 20)) f.put(out.data(), out.size()), out.clear();
    }
    for (std::uint64_t i = 0; i < in.nb_faces; ++i) {
        const std::uint32_t *t = in.faces + 3 * i;
        const int n = std::snprintf(buf, sizeof buf, "f %u %u %u\n", t[0] + 1, t[1] + 1, t[2] + 1);
        out.append(buf, std::size_t(n));
        if (out.size() > (1 << 20)) f.put(out.data(), out.size()), out.clear();
    }
    f.put(out.data(), out.size());
    f.close();
}

}  // namespace plyobj
