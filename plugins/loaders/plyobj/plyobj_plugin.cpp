// hz.loader/1: PLY and Wavefront OBJ triangle meshes (plyobj_format.hpp).
// Neither format says what space its coordinates are in; Horizon reads and
// writes them as RAS+ mm, as FreeSurfer's mris_convert, Surf Ice and the
// other neuroimaging tools that export these formats do. Vertex colours are
// the per-vertex array "color" (float RGB in [0, 1], as glTF's COLOR_0).
#include "mapped_file.hpp"
#include "plyobj_format.hpp"

#include <hz/cpp/loader.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <utility>

namespace {

constexpr const char *kId = "org.horizon.loader.plyobj";

struct MeshReader {
    bool ply = true;
    plyobj::Mesh m;
};

bool ends_with(const char *name, const char *ext) {
    if (name == nullptr) return false;
    const std::size_t n = std::strlen(name), e = std::strlen(ext);
    if (n < e) return false;
    for (std::size_t i = 0; i < e; ++i)
        if (std::tolower(static_cast<unsigned char>(name[n - e + i])) != ext[i]) return false;
    return true;
}

bool is_ply(const uint8_t *h, uint64_t n) { return n >= 4 && std::memcmp(h, "ply", 3) == 0 && (h[3] == '\n' || h[3] == '\r'); }

int32_t mesh_probe(const uint8_t *h, uint64_t n, const char *name) noexcept {
    if (is_ply(h, n)) return 95;
    // OBJ has no magic number: the name, and text whose first statement is an OBJ one.
    if (!ends_with(name, ".obj")) return 0;
    for (uint64_t i = 0; i < n; ++i)
        if (h[i] == 0) return 0;  // binary, e.g. a COFF object file
    return 60;
}

std::unique_ptr<MeshReader> mesh_open(const std::string &path, const hz_task *) {
    auto r = std::make_unique<MeshReader>();
    const hzio::MappedFile f(path);
    // A .ply name is read as PLY (so a wrong magic says so), anything else by its content.
    r->ply = is_ply(f.data(), f.size()) || ends_with(path.c_str(), ".ply");
    r->m = r->ply ? plyobj::read_ply(f.data(), f.size()) : plyobj::read_obj(f.data(), f.size());
    return r;
}

void mesh_info(const MeshReader &r, hz_dataset_info &out) {
    out.kind = HZ_DATA_MESH;
    std::snprintf(out.format, sizeof out.format, r.ply ? "ply" : "obj");
    out.nb_vertices = r.m.vertices.size() / 3;
    out.nb_faces = r.m.faces.size() / 3;
    static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::memcpy(out.voxel_to_ras, identity, sizeof identity);
    out.source_space = HZ_SPACE_RASMM;
    out.nb_arrays = (r.m.colors.empty() ? 0 : 1) + static_cast<uint32_t>(r.m.properties.size());
}

// Arrays: "color" first when the file has colours, then the PLY vertex properties.
// Canonical PLY scalar types and the dtypes they read into (both directions).
constexpr std::pair<const char *, hz_dtype> kPlyTypes[] = {
    {"char", HZ_DTYPE_I8}, {"uchar", HZ_DTYPE_U8}, {"short", HZ_DTYPE_I16}, {"ushort", HZ_DTYPE_U16},
    {"int", HZ_DTYPE_I32}, {"uint", HZ_DTYPE_U32}, {"float", HZ_DTYPE_F32}, {"double", HZ_DTYPE_F64},
};
hz_dtype dtype_of(const std::string &ply_type) {
    for (const auto &[name, dtype] : kPlyTypes)
        if (ply_type == name) return dtype;
    return HZ_DTYPE_F64;  // (not reached: the decoder keeps canonical names only)
}
const char *ply_type_of(hz_dtype dtype) {
    for (const auto &[name, d] : kPlyTypes)
        if (d == dtype) return name;
    return nullptr;
}
const plyobj::VertexProperty *property_at(const MeshReader &r, uint32_t index) {
    if (!r.m.colors.empty()) {
        if (index == 0) return nullptr;
        --index;
    }
    return index < r.m.properties.size() ? &r.m.properties[index] : nullptr;
}
void mesh_array_info(const MeshReader &r, uint32_t index, hz_array_info &out) {
    out.attach = HZ_ATTACH_VERTEX;
    if (const plyobj::VertexProperty *p = property_at(r, index)) {
        out.name = p->name.c_str();
        out.dtype = dtype_of(p->type);
        out.components = 1;
        out.count = r.m.vertices.size() / 3;
        return;
    }
    out.name = "color";
    out.dtype = HZ_DTYPE_F32;
    out.components = 3;
    out.count = r.m.colors.size() / 3;
}

void mesh_read_array(const MeshReader &r, uint32_t index, void *dense, const hz_task *) {
    if (const plyobj::VertexProperty *p = property_at(r, index))
        std::memcpy(dense, p->bytes.data(), r.m.vertices.size() / 3 * plyobj::ply_type_size(p->type));
    else
        std::memcpy(dense, r.m.colors.data(), r.m.colors.size() * sizeof(float));
}

void mesh_metadata(const MeshReader &r, hz_metadata_visitor visit, void *ctx) {
    for (const auto &[k, v] : r.m.metadata) visit(ctx, k.c_str(), v.c_str());
}

void mesh_read(MeshReader &r, float *vertices, uint32_t *faces, const hz_task *) {
    std::memcpy(vertices, r.m.vertices.data(), r.m.vertices.size() * 4);
    std::memcpy(faces, r.m.faces.data(), r.m.faces.size() * 4);
}

// Vertex colours from the data: "color" (float RGB or RGBA in [0, 1], from
// glTF, PLY or OBJ), else a uint8 RGBA array (an annotation's or a label
// GIFTI's "<labels> rgba"). PLY also keeps per-vertex scalar arrays as
// vertex properties; every other array is reported as dropped.
void mesh_write(const hz_write_request &request, const hz_dataset_view &view, const hz_task *) {
    const hz_write_request *req = &request;
    const hz_dataset_view *data = &view;
    {
        const std::string ext = req->extension ? req->extension : "ply";
        const std::uint64_t nv = data->mesh_nb_vertices;
        if (nv == 0 || data->mesh_nb_faces == 0)
            throw plyobj::FormatError("no surface to write (" + std::to_string(nv) + " vertices, " + std::to_string(data->mesh_nb_faces) +
                                      " faces)");
        plyobj::WriteInput in;
        in.vertices = data->mesh_vertices, in.nb_vertices = nv, in.faces = data->mesh_faces, in.nb_faces = data->mesh_nb_faces;
        const hz_named_array *colour = nullptr;
        for (uint32_t i = 0; i < data->nb_arrays; ++i) {
            const hz_named_array &a = data->arrays[i];
            const bool per_vertex = a.attach == HZ_ATTACH_VERTEX && a.count == nv;
            const bool is_float_colour = per_vertex && a.name != nullptr && std::string(a.name) == "color" && a.dtype == HZ_DTYPE_F32 &&
                                         (a.components == 3 || a.components == 4);
            const bool is_rgba8 = per_vertex && a.dtype == HZ_DTYPE_U8 && a.components == 4;
            if (is_float_colour && (colour == nullptr || colour->dtype != HZ_DTYPE_F32))
                colour = &a;
            else if (is_rgba8 && colour == nullptr)
                colour = &a;
        }
        // PLY: every other per-vertex scalar array whose name is a PLY word
        // (and not one of the properties written for geometry and colour)
        // becomes a vertex property of its type.
        auto ply_word = [](const char *name) {
            if (name == nullptr || *name == 0 || std::strlen(name) > 128) return false;
            for (const char *c = name; *c; ++c)
                if (static_cast<unsigned char>(*c) <= 0x20 || static_cast<unsigned char>(*c) >= 0x7f) return false;
            return !plyobj::is_role_property(name);
        };
        std::vector<const hz_named_array *> kept = {colour};
        for (uint32_t i = 0; i < data->nb_arrays && ext != "obj"; ++i) {
            const hz_named_array &a = data->arrays[i];
            if (&a == colour || a.attach != HZ_ATTACH_VERTEX || a.count != nv || a.components != 1 || ply_type_of(a.dtype) == nullptr ||
                a.data == nullptr || !ply_word(a.name))
                continue;
            if (std::any_of(in.properties.begin(), in.properties.end(), [&](const auto &p) { return p.name == a.name; })) continue;
            in.properties.push_back({a.name, ply_type_of(a.dtype), static_cast<const unsigned char *>(a.data)});
            kept.push_back(&a);
        }
        for (uint32_t i = 0; i < data->nb_arrays && req->on_dropped; ++i)
            if (std::find(kept.begin(), kept.end(), &data->arrays[i]) == kept.end())
                req->on_dropped(req->ctx, ("array '" + std::string(data->arrays[i].name ? data->arrays[i].name : "") + "' (" + ext +
                                           (ext == "obj" ? " keeps geometry and vertex colours only)"
                                                         : " keeps geometry, vertex colours and per-vertex scalars of 8-64 bits)"))
                                              .c_str());
        if (colour != nullptr) {
            in.colors.resize(4 * nv);
            for (std::uint64_t i = 0; i < nv; ++i)
                for (std::uint32_t c = 0; c < 4; ++c) {
                    if (colour->dtype == HZ_DTYPE_U8) {
                        in.colors[4 * i + c] = static_cast<const std::uint8_t *>(colour->data)[4 * i + c];
                    } else {
                        const float x =
                            c < colour->components ? static_cast<const float *>(colour->data)[colour->components * i + c] : 1.0f;
                        in.colors[4 * i + c] =
                            static_cast<std::uint8_t>(std::lround(std::clamp(std::isfinite(x) ? x : 0.0f, 0.0f, 1.0f) * 255));
                    }
                }
        }
        for (uint32_t i = 0; i < data->nb_metadata; ++i)
            if (data->metadata[i].key && data->metadata[i].value && std::string(data->metadata[i].key) == "comment")
                in.comments.emplace_back(data->metadata[i].value);
        if (ext == "obj")
            plyobj::write_obj(req->path, in);
        else
            plyobj::write_ply(req->path, in);
    }
}

const char *const kExtensions[] = {"ply", "obj", nullptr};

// The format as the SDK's C++ loader adapter takes it (hz/cpp/loader.hpp).
struct PlyObj {
    static constexpr const char *prefix = "plyobj";
    static constexpr hz_data_kind kinds = HZ_DATA_MESH;
    static constexpr uint32_t probe_bytes = 4096;
    static constexpr const char *const *extensions = kExtensions;
    using FormatError = plyobj::FormatError;
    using IoError = hzio::IoError;
    using Reader = MeshReader;
    static constexpr auto probe = mesh_probe;
    static constexpr auto open = mesh_open;
    static constexpr auto info = mesh_info;
    static constexpr auto array_info = mesh_array_info;
    static constexpr auto read_array = mesh_read_array;
    static constexpr auto metadata = mesh_metadata;
    static constexpr auto read_mesh = mesh_read;
    static constexpr auto write = mesh_write;
};
constexpr const hz_loader &kLoader = hz::loader<PlyObj>::table;
const char *const kInterfaces[] = {HZ_INTERFACE_LOADER, nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "PLY and OBJ",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description =
        "PLY (ASCII and binary, with scalar vertex properties) and Wavefront OBJ (tinyobjloader) triangle meshes with vertex colours, RAS+ "
        "mm",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader>::entry;
