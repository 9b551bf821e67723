// hz.loader/1: PLY and Wavefront OBJ triangle meshes (plyobj_format.hpp).
// Neither format says what space its coordinates are in; Horizon reads and
// writes them as RAS+ mm, as FreeSurfer's mris_convert, Surf Ice and the
// other neuroimaging tools that export these formats do. Vertex colours are
// the per-vertex array "color" (float RGB in [0, 1], as glTF's COLOR_0).
#include "mapped_file.hpp"
#include "plyobj_format.hpp"

#include <hz/cpp/plugin.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <utility>

namespace {

constexpr const char *kId = "org.horizon.loader.plyobj";

struct Reader {
    std::string path;
    bool ply = true;
    plyobj::Mesh m;
};
Reader *as_reader(hz_reader *r) { return reinterpret_cast<Reader *>(r); }

template <class F>
hz_status run(hz_error *err, const std::string &path, F &&body) {
    return hz::format_guard<plyobj::FormatError, hzio::IoError>(err, "plyobj", path, body);
}

bool ends_with(const char *name, const char *ext) {
    if (name == nullptr) return false;
    const std::size_t n = std::strlen(name), e = std::strlen(ext);
    if (n < e) return false;
    for (std::size_t i = 0; i < e; ++i)
        if (std::tolower(static_cast<unsigned char>(name[n - e + i])) != ext[i]) return false;
    return true;
}

bool is_ply(const uint8_t *h, uint64_t n) { return n >= 4 && std::memcmp(h, "ply", 3) == 0 && (h[3] == '\n' || h[3] == '\r'); }

int32_t HZ_ABI probe(const uint8_t *h, uint64_t n, const char *name) {
    if (is_ply(h, n)) return 95;
    // OBJ has no magic number: the name, and text whose first statement is an OBJ one.
    if (!ends_with(name, ".obj")) return 0;
    for (uint64_t i = 0; i < n; ++i)
        if (h[i] == 0) return 0;  // binary, e.g. a COFF object file
    return 60;
}

hz_status HZ_ABI open(const hz_open_request *req, hz_reader **out, hz_error *err) {
    if (out != nullptr) *out = nullptr;
    if (req == nullptr || req->path == nullptr || out == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "plyobj: open: NULL request, path or output");
    return run(err, req->path, [&]() -> hz_status {
        auto r = std::make_unique<Reader>();
        r->path = req->path;
        const hzio::MappedFile f(r->path);
        // A .ply name is read as PLY (so a wrong magic says so), anything else by its content.
        r->ply = is_ply(f.data(), f.size()) || ends_with(req->path, ".ply");
        r->m = r->ply ? plyobj::read_ply(f.data(), f.size()) : plyobj::read_obj(f.data(), f.size());
        *out = reinterpret_cast<hz_reader *>(r.release());
        return HZ_OK;
    });
}

hz_status HZ_ABI get_info(hz_reader *reader, hz_dataset_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_dataset_info))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "plyobj: get_info: bad arguments");
    const Reader &r = *as_reader(reader);
    out->kind = HZ_DATA_MESH;
    std::snprintf(out->format, sizeof out->format, r.ply ? "ply" : "obj");
    out->nb_vertices = r.m.vertices.size() / 3;
    out->nb_faces = r.m.faces.size() / 3;
    static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::memcpy(out->voxel_to_ras, identity, sizeof identity);
    out->source_space = HZ_SPACE_RASMM;
    out->nb_arrays = (r.m.colors.empty() ? 0 : 1) + static_cast<uint32_t>(r.m.properties.size());
    return HZ_OK;
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
const plyobj::VertexProperty *property_at(const Reader &r, uint32_t index) {
    if (!r.m.colors.empty()) {
        if (index == 0) return nullptr;
        --index;
    }
    return index < r.m.properties.size() ? &r.m.properties[index] : nullptr;
}
bool valid_array(const Reader &r, uint32_t index) { return (index == 0 && !r.m.colors.empty()) || property_at(r, index) != nullptr; }

hz_status HZ_ABI get_array_info(hz_reader *reader, uint32_t index, hz_array_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "plyobj: get_array_info: NULL");
    const Reader &r = *as_reader(reader);
    if (!valid_array(r, index)) return hz::set_errorf(err, HZ_E_NOT_FOUND, "plyobj: %s: no extra array %u", r.path.c_str(), index);
    if (const plyobj::VertexProperty *p = property_at(r, index)) {
        out->attach = HZ_ATTACH_VERTEX;
        out->name = p->name.c_str();
        out->dtype = dtype_of(p->type);
        out->components = 1;
        out->count = r.m.vertices.size() / 3;
        return HZ_OK;
    }
    out->attach = HZ_ATTACH_VERTEX;
    out->name = "color";
    out->dtype = HZ_DTYPE_F32;
    out->components = 3;
    out->count = r.m.colors.size() / 3;
    return HZ_OK;
}

hz_status HZ_ABI read_array(hz_reader *reader, uint32_t index, const hz_array_view *dst, const hz_task *, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "plyobj: read_array: NULL");
    const Reader &r = *as_reader(reader);
    if (!valid_array(r, index)) return hz::set_errorf(err, HZ_E_NOT_FOUND, "plyobj: %s: no extra array %u", r.path.c_str(), index);
    if (const plyobj::VertexProperty *p = property_at(r, index)) {
        const std::uint64_t n = r.m.vertices.size() / 3;
        const unsigned size = plyobj::ply_type_size(p->type);
        if (dst->dtype != dtype_of(p->type) || dst->ndim < 1 || dst->shape[0] != n)
            return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "plyobj: %s: read_array: destination does not match", r.path.c_str());
        for (std::uint64_t i = 0; i < n; ++i) {
            unsigned char *cell = hz::view_cell(*dst, i, 0, size);
            if (cell == nullptr)
                return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "plyobj: %s: read_array: destination too small", r.path.c_str());
            std::memcpy(cell, p->bytes.data() + i * size, size);
        }
        return HZ_OK;
    }
    const std::uint64_t n = r.m.colors.size() / 3;
    if (dst->dtype != HZ_DTYPE_F32 || dst->ndim < 1 || dst->shape[0] != n)
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "plyobj: %s: read_array: destination does not match", r.path.c_str());
    for (std::uint64_t i = 0; i < n; ++i)
        for (std::uint32_t c = 0; c < 3; ++c) {
            unsigned char *cell = hz::view_cell(*dst, i, c, 4);
            if (cell == nullptr)
                return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "plyobj: %s: read_array: destination too small", r.path.c_str());
            std::memcpy(cell, &r.m.colors[3 * i + c], 4);
        }
    return HZ_OK;
}

hz_status HZ_ABI visit_metadata(hz_reader *reader, hz_metadata_visitor visitor, void *ctx, hz_error *err) {
    if (reader == nullptr || visitor == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "plyobj: visit_metadata: NULL");
    for (const auto &[k, v] : as_reader(reader)->m.metadata) visitor(ctx, k.c_str(), v.c_str());
    return HZ_OK;
}

hz_status HZ_ABI read_mesh(hz_reader *reader, const hz_mesh_dst *dst, const hz_task *task, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "plyobj: read_mesh: NULL");
    const Reader &r = *as_reader(reader);
    if (hz::cancelled(task)) return hz::set_error(err, HZ_E_CANCELLED, "cancelled");
    if (dst->vertices_capacity < r.m.vertices.size() || dst->faces_capacity < r.m.faces.size())
        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "plyobj: %s: destination too small", r.path.c_str());
    std::memcpy(dst->vertices, r.m.vertices.data(), r.m.vertices.size() * 4);
    std::memcpy(dst->faces, r.m.faces.data(), r.m.faces.size() * 4);
    return HZ_OK;
}

void HZ_ABI close(hz_reader *reader) { delete as_reader(reader); }

// Vertex colours from the data: "color" (float RGB or RGBA in [0, 1], from
// glTF, PLY or OBJ), else a uint8 RGBA array (an annotation's or a label
// GIFTI's "<labels> rgba"). PLY also keeps per-vertex scalar arrays as
// vertex properties; every other array is reported as dropped.
hz_status HZ_ABI write(const hz_write_request *req, const hz_dataset_view *data, const hz_task *, hz_error *err) {
    if (req == nullptr || req->path == nullptr || data == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "plyobj: write: NULL request or data");
    if (data->kind != HZ_DATA_MESH) return hz::set_errorf(err, HZ_E_UNSUPPORTED, "plyobj: %s: holds meshes only", req->path);
    return run(err, req->path, [&]() -> hz_status {
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
        return HZ_OK;
    });
}

const char *const kExtensions[] = {"ply", "obj", nullptr};
const hz_loader kLoader = {
    .struct_size = sizeof(hz_loader),
    .data_kinds = HZ_DATA_MESH,
    .caps = HZ_LOADER_CAN_READ | HZ_LOADER_CAN_WRITE,
    .probe_bytes = 4096,
    .extensions = kExtensions,
    .probe = probe,
    .open = open,
    .get_info = get_info,
    .get_array_info = get_array_info,
    .visit_metadata = visit_metadata,
    .read_streamlines = nullptr,
    .read_array = read_array,
    .read_volume = nullptr,
    .read_mesh = read_mesh,
    .close = close,
    .write = write,
};
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
