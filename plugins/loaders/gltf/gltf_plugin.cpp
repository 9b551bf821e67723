// hz.loader/1: glTF 2.0 meshes (.gltf with embedded or external buffers,
// binary .glb) through tinygltf, with their PBR metallic-roughness factors.
//
// Coordinates. glTF is metres, +Y up, +Z the asset's front, +X its left
// (right-handed). Horizon is RAS+ millimetres. The reader maps a glTF point
// (x, y, z) to RAS (-1000 x, 1000 z, 1000 y) after applying the node
// transforms of the default scene; the writer applies the inverse, so files
// open upright and life-size in other glTF viewers and round-trip exactly
// up to float32 rounding.
//
// What is read: every triangle primitive (mode 4) of every mesh instanced by
// the scene's nodes, merged into one mesh; COLOR_0 as the per-vertex array
// "color" (RGB, float); the first primitive's material factors as header
// entries (material.baseColorFactor, material.metallicFactor, ...), which
// `horizon render` uses for the principled model. Textures are not decoded.
// A file without triangles whose primitives are lines (mode 1, segments
// chained where one starts at the vertex the last ended on) or line strips
// (mode 3) is read as streamlines, COLOR_0 likewise as "color". Points,
// skins and morph targets are reported, not drawn.
//
// What is written: a mesh as one triangle primitive; streamlines as one
// line primitive (mode 1, each streamline's segments in order), COLOR_0
// from a per-vertex "color" array or else each point's direction colour
// (|tangent| as RGB, as tractography viewers colour streamlines): what a
// browser's glTF viewer (three.js) shows of a tractogram.
#include <hz/cpp/loader.hpp>

#include <tiny_gltf.h>

#include "files.hpp"
#include "mapped_file.hpp"

#include <array>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <sys/stat.h>
#include <vector>

namespace {

constexpr const char *kId = "org.horizon.loader.gltf";

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
struct IoError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

using M4 = std::array<double, 16>;  // column-major, as glTF
constexpr M4 kI = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

M4 mul(const M4 &a, const M4 &b) {
    M4 r{};
    for (int c = 0; c < 4; ++c)
        for (int rr = 0; rr < 4; ++rr) {
            double s = 0;
            for (int k = 0; k < 4; ++k) s += a[k * 4 + rr] * b[c * 4 + k];
            r[c * 4 + rr] = s;
        }
    return r;
}

M4 node_matrix(const tinygltf::Node &n) {
    if (n.matrix.size() == 16) {
        M4 m;
        std::copy(n.matrix.begin(), n.matrix.end(), m.begin());
        return m;
    }
    M4 t = kI, r = kI, s = kI;
    if (n.translation.size() == 3) t[12] = n.translation[0], t[13] = n.translation[1], t[14] = n.translation[2];
    if (n.rotation.size() == 4) {
        const double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
        r = {1 - 2 * (y * y + z * z),
             2 * (x * y + z * w),
             2 * (x * z - y * w),
             0,
             2 * (x * y - z * w),
             1 - 2 * (x * x + z * z),
             2 * (y * z + x * w),
             0,
             2 * (x * z + y * w),
             2 * (y * z - x * w),
             1 - 2 * (x * x + y * y),
             0,
             0,
             0,
             0,
             1};
    }
    if (n.scale.size() == 3) s[0] = n.scale[0], s[5] = n.scale[1], s[10] = n.scale[2];
    return mul(t, mul(r, s));
}

// Reads element `i`, component `c` of an accessor as double, bounds-checked.
struct AccessorReader {
    const unsigned char *base = nullptr;
    std::size_t stride = 0, comp_size = 0, count = 0;
    int ncomp = 0, ctype = 0;
    bool normalized = false;
    AccessorReader(const tinygltf::Model &m, int index, const char *what) {
        if (index < 0 || index >= int(m.accessors.size())) throw FormatError(std::string(what) + ": accessor index out of range");
        const tinygltf::Accessor &a = m.accessors[index];
        if (a.sparse.isSparse) throw FormatError(std::string(what) + ": sparse accessors are not supported");
        if (a.bufferView < 0 || a.bufferView >= int(m.bufferViews.size()))
            throw FormatError(std::string(what) + ": accessor without a valid buffer view");
        const tinygltf::BufferView &bv = m.bufferViews[a.bufferView];
        if (bv.buffer < 0 || bv.buffer >= int(m.buffers.size()))
            throw FormatError(std::string(what) + ": buffer view without a valid buffer");
        const auto &buf = m.buffers[bv.buffer].data;
        ncomp = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type));
        comp_size = std::size_t(tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(a.componentType)));
        if (ncomp <= 0 || comp_size == 0 || comp_size > 8) throw FormatError(std::string(what) + ": bad accessor type");
        ctype = a.componentType;
        normalized = a.normalized;
        count = a.count;
        const int s = a.ByteStride(bv);
        if (s <= 0) throw FormatError(std::string(what) + ": bad byte stride");
        stride = std::size_t(s);
        const std::size_t elem = comp_size * std::size_t(ncomp);
        if (bv.byteOffset > buf.size() || bv.byteLength > buf.size() - bv.byteOffset)
            throw FormatError(std::string(what) + ": buffer view outside its buffer");
        if (count > 0) {
            if (a.byteOffset > bv.byteLength) throw FormatError(std::string(what) + ": accessor offset outside its buffer view");
            const std::size_t avail = bv.byteLength - a.byteOffset;
            if (elem > avail || (count - 1) > (avail - elem) / stride)
                throw FormatError(std::string(what) + ": " + std::to_string(count) + " elements do not fit in the buffer view");
        }
        base = buf.data() + bv.byteOffset + a.byteOffset;
    }
    double get(std::size_t i, int c) const {
        const unsigned char *p = base + i * stride + std::size_t(c) * comp_size;
        switch (ctype) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: {
            float f;
            std::memcpy(&f, p, 4);
            return f;
        }
        case TINYGLTF_COMPONENT_TYPE_DOUBLE: {
            double d;
            std::memcpy(&d, p, 8);
            return d;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
        case TINYGLTF_COMPONENT_TYPE_BYTE: return normalized ? std::max(-1.0, int8_t(p[0]) / 127.0) : int8_t(p[0]);
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
            uint16_t v;
            std::memcpy(&v, p, 2);
            return normalized ? v / 65535.0 : v;
        }
        case TINYGLTF_COMPONENT_TYPE_SHORT: {
            int16_t v;
            std::memcpy(&v, p, 2);
            return normalized ? std::max(-1.0, v / 32767.0) : v;
        }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
            uint32_t v;
            std::memcpy(&v, p, 4);
            return v;
        }
        case TINYGLTF_COMPONENT_TYPE_INT: {
            int32_t v;
            std::memcpy(&v, p, 4);
            return v;
        }
        default: return 0;
        }
    }
};

struct Surface {
    std::vector<float> vertices;  // RAS mm
    std::vector<std::uint32_t> faces;
    std::vector<float> colors;  // RGB per vertex, or empty
    std::vector<std::pair<std::string, std::string>> meta;
    // Streamlines (a file of lines and no triangles): the vertices above,
    // one streamline per offsets range.
    bool streamlines = false;
    std::vector<std::uint64_t> offsets;
};

bool skip_images(tinygltf::Image *, const int, std::string *, std::string *, int, int, const unsigned char *, int, void *) { return true; }

// External buffers and images (uri): only regular files inside the glTF's
// folder (hzio::contained_file); a uri with ../, an absolute one, a link out
// of the folder or a FIFO is an error, never read. user_data: the glTF path.
bool uri_exists(const std::string &path, void *) {
    struct stat st {};
    return ::lstat(path.c_str(), &st) == 0;  // (uri_read then says why a file is refused)
}
std::string uri_expand(const std::string &path, void *) { return path; }  // (no ~ or $VAR expansion)
bool uri_read(std::vector<unsigned char> *out, std::string *err, const std::string &path, void *gltf) {
    try {
        const std::string p = hzio::contained_file(*static_cast<const std::string *>(gltf), path);
        hzio::MappedFile m(p);
        out->assign(m.data(), m.data() + m.size());
        return true;
    } catch (const std::exception &e) {
        if (err) *err += e.what() + std::string("\n");
        return false;
    }
}
bool uri_write(std::string *err, const std::string &, const std::vector<unsigned char> &, void *) {
    if (err) *err += "external files are not written\n";
    return false;
}

// Appends the streamlines of a line (mode 1) or line-strip (mode 3)
// primitive, transformed by `world` into RAS mm: a strip is one streamline
// (its vertices in index order); segments (a, b) of lines are chained while
// each starts at the vertex the one before ended on.
void read_lines(const tinygltf::Model &m, const tinygltf::Primitive &prim, const M4 &world, Surface &out, bool &has_color) {
    auto pos_it = prim.attributes.find("POSITION");
    if (pos_it == prim.attributes.end()) throw FormatError("a primitive without POSITION");
    AccessorReader pos(m, pos_it->second, "POSITION");
    if (pos.ncomp != 3) throw FormatError("POSITION is not VEC3");
    std::unique_ptr<AccessorReader> col;
    if (auto c = prim.attributes.find("COLOR_0"); c != prim.attributes.end()) {
        col = std::make_unique<AccessorReader>(m, c->second, "COLOR_0");
        if (col->count != pos.count || col->ncomp < 3) throw FormatError("COLOR_0 does not match POSITION");
    }
    std::vector<std::size_t> order;  // the primitive's vertex sequence
    if (prim.indices >= 0) {
        AccessorReader idx(m, prim.indices, "indices");
        if (idx.ncomp != 1) throw FormatError("line indices are not scalars");
        order.reserve(idx.count);
        for (std::size_t i = 0; i < idx.count; ++i) {
            const double k = idx.get(i, 0);
            if (!(k >= 0) || k >= double(pos.count)) throw FormatError("a line index is out of range (" + std::to_string(k) + ")");
            order.push_back(std::size_t(k));
        }
    } else {
        for (std::size_t i = 0; i < pos.count; ++i) order.push_back(i);
    }
    if (prim.mode == TINYGLTF_MODE_LINE && order.size() % 2 != 0) throw FormatError("line indices are not pairs");
    if (col && !has_color) out.colors.assign(out.vertices.size(), 1.0f);
    auto put = [&](std::size_t i) {
        const double x = pos.get(i, 0), y = pos.get(i, 1), z = pos.get(i, 2);
        const double wx = world[0] * x + world[4] * y + world[8] * z + world[12];
        const double wy = world[1] * x + world[5] * y + world[9] * z + world[13];
        const double wz = world[2] * x + world[6] * y + world[10] * z + world[14];
        const float r = float(-1000.0 * wx), a = float(1000.0 * wz), u = float(1000.0 * wy);
        if (!std::isfinite(r) || !std::isfinite(a) || !std::isfinite(u)) throw FormatError("non-finite vertex coordinate (in RAS mm)");
        out.vertices.push_back(r);
        out.vertices.push_back(a);
        out.vertices.push_back(u);
        if (col)
            for (int c = 0; c < 3; ++c) out.colors.push_back(float(col->get(i, c)));
        else if (has_color)
            out.colors.insert(out.colors.end(), 3, 1.0f);
    };
    auto end_streamline = [&] {
        if (out.vertices.size() / 3 > out.offsets.back()) out.offsets.push_back(out.vertices.size() / 3);
    };
    // Horizon's own: the streamlines' offsets into POSITION (an accessor
    // named by the primitive's extras), which keep empty and one-point
    // streamlines that segments cannot hold.
    if (prim.extras.IsObject() && prim.extras.Has("horizon_offsets") && prim.extras.Get("horizon_offsets").IsInt()) {
        AccessorReader offs(m, prim.extras.Get("horizon_offsets").GetNumberAsInt(), "extras.horizon_offsets");
        if (offs.ncomp != 1 || offs.count < 1) throw FormatError("extras.horizon_offsets is not a list of offsets");
        double before = 0;
        for (std::size_t k = 0; k < offs.count; ++k) {
            const double o = offs.get(k, 0);
            if (!(o >= before) || o > double(pos.count) || (k == 0 && o != 0) || (k + 1 == offs.count && o != double(pos.count)))
                throw FormatError("extras.horizon_offsets are not increasing offsets from 0 to the vertex count");
            before = o;
        }
        const std::uint64_t base = out.vertices.size() / 3;
        for (std::size_t i = 0; i < pos.count; ++i) put(i);
        for (std::size_t k = 1; k < offs.count; ++k) out.offsets.push_back(base + std::uint64_t(offs.get(k, 0)));
    } else if (prim.mode == TINYGLTF_MODE_LINE_STRIP) {
        for (std::size_t i : order) put(i);
        end_streamline();
    } else {
        std::size_t last = SIZE_MAX;
        for (std::size_t k = 0; k < order.size(); k += 2) {
            if (order[k] != last) {
                end_streamline();
                put(order[k]);
            }
            put(order[k + 1]);
            last = order[k + 1];
        }
        end_streamline();
    }
    has_color = has_color || col != nullptr;
}

Surface parse(const std::string &path) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) throw IoError("cannot open: " + std::string(std::strerror(errno)));
    if (!S_ISREG(st.st_mode)) throw IoError("not a regular file");
    if (st.st_size < 12) throw FormatError("file is " + std::to_string(st.st_size) + " bytes: too short for glTF");
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(skip_images, nullptr);
    tinygltf::FsCallbacks fs{uri_exists, uri_expand, uri_read, uri_write, const_cast<std::string *>(&path)};
    loader.SetFsCallbacks(fs);
    tinygltf::Model m;
    std::string err, warn;
    std::FILE *f = std::fopen(path.c_str(), "rb");
    if (!f) throw IoError("cannot open: " + std::string(std::strerror(errno)));
    char magic[4] = {};
    const bool binary = std::fread(magic, 1, 4, f) == 4 && std::memcmp(magic, "glTF", 4) == 0;
    std::fclose(f);
    bool ok = false;
    try {
        ok = binary ? loader.LoadBinaryFromFile(&m, &err, &warn, path) : loader.LoadASCIIFromFile(&m, &err, &warn, path);
    } catch (const std::exception &e) {
        throw FormatError(std::string("not valid glTF: ") + e.what());
    }
    if (!ok) {
        std::string one = err.substr(0, err.find('\n'));
        throw FormatError(one.empty() ? "not valid glTF" : one);
    }
    Surface s;
    bool has_color = false;
    std::size_t skipped = 0;
    // Lines and strips: their streamlines, kept aside while triangles may
    // still come (a file with triangles is a mesh).
    Surface lines;
    lines.offsets = {0};
    bool lines_color = false;
    std::size_t line_primitives = 0;
    int first_material = -1;
    // Instancing multiplies what a file stores: a node listed twice as a
    // child at every level of a 60-deep chain would be visited 2^60 times.
    // Bound the visits and the vertices produced, so a small file cannot
    // ask for unbounded time or memory.
    constexpr std::size_t kMaxInstances = 1u << 16, kMaxVertices = std::size_t(1) << 27;
    std::size_t instances = 0;
    std::function<void(int, const M4 &, int)> visit = [&](int ni, const M4 &parent, int depth) {
        if (ni < 0 || ni >= int(m.nodes.size())) throw FormatError("node index out of range");
        if (depth > 64) throw FormatError("node hierarchy deeper than 64 (a cycle?)");
        if (++instances > kMaxInstances)
            throw FormatError("the scene instances more than " + std::to_string(kMaxInstances) + " nodes (a node shared by many parents?)");
        const tinygltf::Node &n = m.nodes[ni];
        const M4 world = mul(parent, node_matrix(n));
        if (n.mesh >= 0) {
            if (n.mesh >= int(m.meshes.size())) throw FormatError("mesh index out of range");
            for (const auto &prim : m.meshes[n.mesh].primitives) {
                if (prim.mode == TINYGLTF_MODE_LINE || prim.mode == TINYGLTF_MODE_LINE_STRIP) {
                    read_lines(m, prim, world, lines, lines_color);
                    ++line_primitives;
                    if (lines.vertices.size() / 3 > kMaxVertices)
                        throw FormatError("the scene's instances add up to more than " + std::to_string(kMaxVertices) + " vertices");
                    continue;
                }
                if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1) {
                    ++skipped;
                    continue;
                }
                auto pos_it = prim.attributes.find("POSITION");
                if (pos_it == prim.attributes.end()) throw FormatError("a primitive without POSITION");
                AccessorReader pos(m, pos_it->second, "POSITION");
                if (pos.ncomp != 3) throw FormatError("POSITION is not VEC3");
                const std::size_t v0 = s.vertices.size() / 3;
                if (v0 + pos.count > kMaxVertices)
                    throw FormatError("the scene's instances add up to more than " + std::to_string(kMaxVertices) + " vertices");
                for (std::size_t i = 0; i < pos.count; ++i) {
                    const double x = pos.get(i, 0), y = pos.get(i, 1), z = pos.get(i, 2);
                    const double wx = world[0] * x + world[4] * y + world[8] * z + world[12];
                    const double wy = world[1] * x + world[5] * y + world[9] * z + world[13];
                    const double wz = world[2] * x + world[6] * y + world[10] * z + world[14];
                    const float r = float(-1000.0 * wx), a = float(1000.0 * wz), u = float(1000.0 * wy);
                    if (!std::isfinite(r) || !std::isfinite(a) || !std::isfinite(u))
                        throw FormatError("non-finite vertex coordinate (in RAS mm)");
                    s.vertices.push_back(r);
                    s.vertices.push_back(a);
                    s.vertices.push_back(u);
                }
                auto col_it = prim.attributes.find("COLOR_0");
                if (col_it != prim.attributes.end()) {
                    AccessorReader col(m, col_it->second, "COLOR_0");
                    if (col.count != pos.count || col.ncomp < 3) throw FormatError("COLOR_0 does not match POSITION");
                    if (!has_color) s.colors.assign(v0 * 3, 1.0f);
                    has_color = true;
                    for (std::size_t i = 0; i < col.count; ++i)
                        for (int c = 0; c < 3; ++c) s.colors.push_back(float(col.get(i, c)));
                } else if (has_color) {
                    s.colors.insert(s.colors.end(), pos.count * 3, 1.0f);
                }
                if (prim.indices >= 0) {
                    AccessorReader idx(m, prim.indices, "indices");
                    if (idx.ncomp != 1 || idx.count % 3 != 0) throw FormatError("triangle indices are not a multiple of 3 scalars");
                    for (std::size_t i = 0; i < idx.count; ++i) {
                        const double k = idx.get(i, 0);
                        if (!(k >= 0) || k >= double(pos.count))
                            throw FormatError("a face index is out of range (" + std::to_string(k) + ")");
                        s.faces.push_back(std::uint32_t(v0 + std::size_t(k)));
                    }
                } else {
                    if (pos.count % 3 != 0) throw FormatError("non-indexed triangles: vertex count not a multiple of 3");
                    for (std::size_t i = 0; i < pos.count; ++i) s.faces.push_back(std::uint32_t(v0 + i));
                }
                if (first_material < 0) first_material = prim.material;
            }
        }
        for (int c : n.children) visit(c, world, depth + 1);
    };
    std::vector<int> roots;
    if (m.defaultScene >= 0 && m.defaultScene < int(m.scenes.size()))
        roots = m.scenes[m.defaultScene].nodes;
    else if (!m.scenes.empty())
        roots = m.scenes[0].nodes;
    else
        for (int i = 0; i < int(m.nodes.size()); ++i) roots.push_back(i);
    for (int r : roots) visit(r, kI, 0);
    if (s.faces.empty() && skipped == 0 && roots.empty() && !m.meshes.empty())
        throw FormatError("meshes but no scene nodes instancing them");
    if (s.vertices.empty() && line_primitives > 0) {
        lines.streamlines = true;
        if (!m.asset.generator.empty()) lines.meta.emplace_back("generator", m.asset.generator);
        if (skipped) lines.meta.emplace_back("skipped_primitives", std::to_string(skipped) + " primitives neither lines nor triangles");
        return lines;
    }
    skipped += line_primitives;
    if (skipped) s.meta.emplace_back("skipped_primitives", std::to_string(skipped) + " non-triangle primitives");
    if (first_material >= 0 && first_material < int(m.materials.size())) {
        const auto &mat = m.materials[first_material];
        const auto &pbr = mat.pbrMetallicRoughness;
        std::string bc;
        for (double x : pbr.baseColorFactor) bc += (bc.empty() ? "" : " ") + std::to_string(x);
        if (!mat.name.empty()) s.meta.emplace_back("material.name", mat.name);
        s.meta.emplace_back("material.baseColorFactor", bc.empty() ? "1 1 1 1" : bc);
        s.meta.emplace_back("material.metallicFactor", std::to_string(pbr.metallicFactor));
        s.meta.emplace_back("material.roughnessFactor", std::to_string(pbr.roughnessFactor));
    }
    if (!m.asset.generator.empty()) s.meta.emplace_back("generator", m.asset.generator);
    return s;
}

}  // namespace

#ifdef HZ_GLTF_FUZZ
// For tests/fuzz/fuzz_gltf.cpp: the parser without the ABI around it; returns
// the vertex count, or -1 when the file was rejected (as the plugin would).
long long hz_gltf_fuzz_parse(const std::string &path) {
    try {
        const Surface s = parse(path);
        for (std::uint32_t f : s.faces)
            if (f >= s.vertices.size() / 3) __builtin_trap();  // faces are checked
        return static_cast<long long>(s.vertices.size() / 3);
    } catch (const FormatError &) {
    } catch (const IoError &) {}
    return -1;
}
#endif

namespace {

struct GltfReader {
    Surface s;
};

int32_t gltf_probe(const uint8_t *h, uint64_t n, const char *) noexcept {
    if (n >= 4 && std::memcmp(h, "glTF", 4) == 0) return 100;
    // JSON glTF: an object with "asset" near the start.
    std::string head(reinterpret_cast<const char *>(h), std::size_t(std::min<uint64_t>(n, 4096)));
    const auto p = head.find_first_not_of(" \t\r\n\xEF\xBB\xBF");
    if (p != std::string::npos && head[p] == '{' && head.find("\"asset\"") != std::string::npos) return 80;
    return 0;
}

std::unique_ptr<GltfReader> gltf_open(const std::string &path, const hz_task *) {
    auto r = std::make_unique<GltfReader>();
    r->s = parse(path.c_str());
    return r;
}

void gltf_info(const GltfReader &r, hz_dataset_info &out) {
    out.kind = r.s.streamlines ? HZ_DATA_STREAMLINES : HZ_DATA_MESH;
    std::snprintf(out.format, sizeof out.format, r.s.streamlines ? "gltf 2.0 lines" : "gltf 2.0");
    out.nb_vertices = r.s.vertices.size() / 3;
    out.nb_faces = r.s.faces.size() / 3;
    if (r.s.streamlines) out.nb_streamlines = r.s.offsets.size() - 1;
    const double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::memcpy(out.voxel_to_ras, id, sizeof id);
    out.source_space = HZ_SPACE_RASMM;
    out.nb_arrays = r.s.colors.empty() ? 0 : 1;
}

// The one array: COLOR_0 as "color", float RGB.
void gltf_array_info(const GltfReader &r, uint32_t, hz_array_info &out) {
    out.attach = HZ_ATTACH_VERTEX;
    out.name = "color";
    out.dtype = HZ_DTYPE_F32;
    out.components = 3;
    out.count = r.s.colors.size() / 3;
}

void gltf_read_array(const GltfReader &r, uint32_t, void *dense, const hz_task *) {
    std::memcpy(dense, r.s.colors.data(), r.s.colors.size() * sizeof(float));
}

void gltf_metadata(const GltfReader &r, hz_metadata_visitor visit, void *ctx) {
    for (const auto &[k, v] : r.s.meta) visit(ctx, k.c_str(), v.c_str());
}

void gltf_read_streamlines(GltfReader &r, float *positions, uint64_t *offsets, const hz_task *) {
    if (!r.s.vertices.empty()) std::memcpy(positions, r.s.vertices.data(), r.s.vertices.size() * 4);
    std::memcpy(offsets, r.s.offsets.data(), r.s.offsets.size() * sizeof(uint64_t));
}

void gltf_read_mesh(GltfReader &r, float *vertices, uint32_t *faces, const hz_task *) {
    if (!r.s.vertices.empty()) std::memcpy(vertices, r.s.vertices.data(), r.s.vertices.size() * 4);
    if (!r.s.faces.empty()) std::memcpy(faces, r.s.faces.data(), r.s.faces.size() * 4);
}

// Direction colours of streamlines (|the tangent| as RGB, central
// differences inside, one-sided at the ends; grey for a single point).
std::vector<float> direction_colours(const float *p, const uint64_t *offsets, std::uint64_t ns) {
    std::vector<float> c(offsets[ns] * 3, 0.5f);
    for (std::uint64_t s = 0; s < ns; ++s) {
        const std::uint64_t b = offsets[s], e = offsets[s + 1];
        if (e - b < 2) continue;
        for (std::uint64_t v = b; v < e; ++v) {
            const std::uint64_t i = v == b ? b : v - 1, j = v + 1 == e ? v : v + 1;
            double d[3], n = 0;
            for (int k = 0; k < 3; ++k) d[k] = double(p[j * 3 + k]) - double(p[i * 3 + k]), n += d[k] * d[k];
            n = std::sqrt(n);
            if (n > 0)
                for (int k = 0; k < 3; ++k) c[v * 3 + k] = float(std::abs(d[k]) / n);
        }
    }
    return c;
}

void gltf_write(const hz_write_request &request, const hz_dataset_view &view, const hz_task *) {
    const hz_write_request *req = &request;
    const hz_dataset_view *data = &view;
    {
        const bool lines = data->kind == HZ_DATA_STREAMLINES;
        const hz_streamlines_view &sv = data->streamlines;
        const std::uint64_t nv = lines ? sv.nb_vertices : data->mesh_nb_vertices, nf = lines ? 0 : data->mesh_nb_faces;
        if (nv > 0xFFFFFFFFu || nf * 3 > 0xFFFFFFFFu) throw FormatError("too many vertices or faces");
        const float *vertices = lines ? sv.positions : data->mesh_vertices;
        const float *colors = nullptr;
        for (uint32_t i = 0; i < data->nb_arrays; ++i) {
            const hz_named_array &a = data->arrays[i];
            const std::string name = a.name ? a.name : "";
            if (name == "color" && a.attach == HZ_ATTACH_VERTEX && a.dtype == HZ_DTYPE_F32 && a.components == 3 && a.count == nv)
                colors = static_cast<const float *>(a.data);
            else if (req->on_dropped)
                req->on_dropped(req->ctx, ("array '" + name + "' (glTF keeps geometry and COLOR_0 only)").c_str());
        }
        // Streamlines: segment indices, each streamline's in order; colours
        // of their directions where none are given.
        std::vector<std::uint32_t> segments;
        std::vector<float> own_colours;
        if (lines) {
            if (sv.offsets == nullptr || (nv > 0 && sv.positions == nullptr)) throw FormatError("streamlines without data");
            for (std::uint64_t s = 0; s < sv.nb_streamlines; ++s) {
                if (sv.offsets[s] > sv.offsets[s + 1] || sv.offsets[s + 1] > nv) throw FormatError("streamline offsets out of order");
                for (std::uint64_t v = sv.offsets[s]; v + 1 < sv.offsets[s + 1]; ++v)
                    segments.push_back(std::uint32_t(v)), segments.push_back(std::uint32_t(v + 1));
            }
            if (colors == nullptr)
                own_colours = direction_colours(sv.positions, sv.offsets, sv.nb_streamlines), colors = own_colours.data();
        }
        tinygltf::Model m;
        m.asset.version = "2.0";
        m.asset.generator = "Horizon";
        tinygltf::Buffer buf;
        auto append = [&](const void *p, std::size_t n) {
            const std::size_t off = buf.data.size();
            buf.data.resize(off + n);
            if (n) std::memcpy(buf.data.data() + off, p, n);
            while (buf.data.size() % 4) buf.data.push_back(0);
            return off;
        };
        std::vector<float> pos(nv * 3);
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (std::uint64_t i = 0; i < nv; ++i) {
            const float R = vertices[i * 3], A = vertices[i * 3 + 1], S = vertices[i * 3 + 2];
            const float g[3] = {float(-double(R) / 1000.0), float(double(S) / 1000.0), float(double(A) / 1000.0)};
            for (int c = 0; c < 3; ++c) {
                pos[i * 3 + c] = g[c];
                lo[c] = std::min(lo[c], g[c]), hi[c] = std::max(hi[c], g[c]);
            }
        }
        for (std::uint64_t i = 0; i < nf * 3; ++i)
            if (data->mesh_faces[i] >= nv) throw FormatError("a face uses a vertex index out of range");
        auto add_view = [&](std::size_t off, std::size_t len, int target) {
            tinygltf::BufferView v;
            v.buffer = 0, v.byteOffset = off, v.byteLength = len, v.target = target;
            m.bufferViews.push_back(v);
            return int(m.bufferViews.size() - 1);
        };
        auto add_accessor = [&](int view, int ctype, int type, std::size_t count) {
            tinygltf::Accessor a;
            a.bufferView = view, a.componentType = ctype, a.type = type, a.count = count;
            m.accessors.push_back(a);
            return int(m.accessors.size() - 1);
        };
        tinygltf::Primitive prim;
        prim.mode = lines ? TINYGLTF_MODE_LINE : TINYGLTF_MODE_TRIANGLES;
        const int pa = add_accessor(add_view(append(pos.data(), pos.size() * 4), pos.size() * 4, TINYGLTF_TARGET_ARRAY_BUFFER),
                                    TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
        if (nv) {
            m.accessors[pa].minValues = {lo[0], lo[1], lo[2]};
            m.accessors[pa].maxValues = {hi[0], hi[1], hi[2]};
        }
        prim.attributes["POSITION"] = pa;
        if (colors)
            prim.attributes["COLOR_0"] = add_accessor(add_view(append(colors, nv * 12), nv * 12, TINYGLTF_TARGET_ARRAY_BUFFER),
                                                      TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, nv);
        if (lines) {
            // (the offsets, for a reader that knows them: empty and
            // one-point streamlines have no segment)
            std::vector<std::uint32_t> offs(sv.offsets, sv.offsets + sv.nb_streamlines + 1);
            const int oa = add_accessor(add_view(append(offs.data(), offs.size() * 4), offs.size() * 4, 0),
                                        TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, offs.size());
            tinygltf::Value::Object extras;
            extras["horizon_offsets"] = tinygltf::Value(oa);
            prim.extras = tinygltf::Value(extras);
        }
        if (lines)
            prim.indices = add_accessor(
                add_view(append(segments.data(), segments.size() * 4), segments.size() * 4, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER),
                TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, segments.size());
        else
            prim.indices = add_accessor(add_view(append(data->mesh_faces, nf * 12), nf * 12, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER),
                                        TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, nf * 3);
        // Material factors carried in the header (from a glTF read), else defaults.
        tinygltf::Material mat;
        mat.pbrMetallicRoughness.baseColorFactor = {1, 1, 1, 1};
        mat.pbrMetallicRoughness.metallicFactor = 0.0;
        mat.pbrMetallicRoughness.roughnessFactor = 0.5;
        mat.doubleSided = true;
        for (uint32_t i = 0; i < data->nb_metadata; ++i) {
            const std::string k = data->metadata[i].key ? data->metadata[i].key : "",
                              v = data->metadata[i].value ? data->metadata[i].value : "";
            if (k == "material.baseColorFactor") {
                std::vector<double> f;
                char *end = nullptr;
                for (const char *p = v.c_str(); *p;) {
                    const double x = std::strtod(p, &end);
                    if (end == p) break;
                    f.push_back(x);
                    p = end;
                }
                if (f.size() == 4) mat.pbrMetallicRoughness.baseColorFactor = f;
            } else if (k == "material.metallicFactor")
                mat.pbrMetallicRoughness.metallicFactor = std::atof(v.c_str());
            else if (k == "material.roughnessFactor")
                mat.pbrMetallicRoughness.roughnessFactor = std::atof(v.c_str());
            else if (k == "material.name")
                mat.name = v;
        }
        m.materials.push_back(mat);
        prim.material = 0;
        buf.uri = "";
        m.buffers.push_back(std::move(buf));
        tinygltf::Mesh mesh;
        mesh.primitives.push_back(prim);
        m.meshes.push_back(mesh);
        tinygltf::Node node;
        node.mesh = 0;
        m.nodes.push_back(node);
        tinygltf::Scene scene;
        scene.nodes = {0};
        m.scenes.push_back(scene);
        m.defaultScene = 0;
        const std::string ext = req->extension ? req->extension : "gltf";
        tinygltf::TinyGLTF w;
        std::ostringstream os;  // (tinygltf's file writer does not check its stream: a full disk went unnoticed)
        if (!w.WriteGltfSceneToStream(&m, os, ext != "glb", ext == "glb") || !os) throw IoError("write failed");
        const std::string bytes = std::move(os).str();
        try {
            hzio::write_file(req->path, bytes.data(), bytes.size());
        } catch (const hzio::IoError &e) {
            throw IoError(e.what());
        }
    }
}

const char *const kExtensions[] = {"gltf", "glb", nullptr};

// The format as the SDK's C++ loader adapter takes it (hz/cpp/loader.hpp).
struct Gltf {
    static constexpr const char *prefix = "gltf";
    static constexpr hz_data_kind kinds = HZ_DATA_MESH | HZ_DATA_STREAMLINES;
    static constexpr uint32_t probe_bytes = 4096;
    static constexpr const char *const *extensions = kExtensions;
    using FormatError = ::FormatError;
    using IoError = ::IoError;
    using Reader = GltfReader;
    static constexpr auto probe = gltf_probe;
    static constexpr auto open = gltf_open;
    static constexpr auto info = gltf_info;
    static constexpr auto array_info = gltf_array_info;
    static constexpr auto read_array = gltf_read_array;
    static constexpr auto metadata = gltf_metadata;
    static constexpr auto read_mesh = gltf_read_mesh;
    static constexpr auto read_streamlines = gltf_read_streamlines;
    static constexpr auto write = gltf_write;
};
constexpr const hz_loader &kLoader = hz::loader<Gltf>::table;
const char *const kInterfaces[] = {HZ_INTERFACE_LOADER, nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "glTF 2.0",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "glTF 2.0 triangle meshes (.gltf, .glb) with vertex colours and PBR factors, metres Y-up <-> RAS+ mm",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader>::entry;
