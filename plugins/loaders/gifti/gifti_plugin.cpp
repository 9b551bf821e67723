// hz.loader/1 adapter for GIFTI surfaces and overlays (gifti_format.hpp).
#include "gifti_format.hpp"
#include "label_table.hpp"
#include "mapped_file.hpp"

#include <hz/cpp/plugin.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>

namespace {

constexpr const char *kId = "org.horizon.loader.gifti";

struct Reader {
    std::string path;
    gifti::Surface s;
    // The LabelTable in 0..255 components, listed as header entries
    // ("label <key>" = "<name> r g b t").
    std::vector<hzlabel::Entry> labels;
    // For each NIFTI_INTENT_LABEL overlay (when the file has a LabelTable):
    // a derived uint8 x 4 array "<name> rgba", the colour of each vertex's
    // label (unknown keys grey with alpha 0), listed after the overlays.
    std::vector<std::size_t> rgba_of;  // overlay index of each derived array
    std::vector<std::string> rgba_names;
};
Reader *as_reader(hz_reader *r) { return reinterpret_cast<Reader *>(r); }

// How an overlay is presented: int32 labels, float64 as stored, or float32.
hz_dtype dtype_of(const gifti::Overlay &o) { return o.integer ? HZ_DTYPE_I32 : o.values64.empty() ? HZ_DTYPE_F32 : HZ_DTYPE_F64; }

template <class F>
hz_status run(hz_error *err, const std::string &path, F &&body) {
    return hz::format_guard<gifti::FormatError, hzio::IoError>(err, "gifti", path, body);
}

int32_t HZ_ABI probe(const uint8_t *head, uint64_t size, const char *) { return gifti::probe(head, size); }

hz_status HZ_ABI open(const hz_open_request *req, hz_reader **out, hz_error *err) {
    if (out != nullptr) *out = nullptr;
    if (req == nullptr || req->path == nullptr || out == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "gifti: open: NULL request, path or output");
    return run(err, req->path, [&]() -> hz_status {
        auto r = std::make_unique<Reader>();
        r->path = req->path;
        r->s = gifti::read(r->path);
        for (const gifti::Label &l : r->s.labels) {
            hzlabel::Entry e;
            e.index = l.key;
            e.name = l.name;
            e.r = static_cast<std::int32_t>(std::lround(l.red * 255)), e.g = static_cast<std::int32_t>(std::lround(l.green * 255));
            e.b = static_cast<std::int32_t>(std::lround(l.blue * 255)), e.t = 255 - static_cast<std::int32_t>(std::lround(l.alpha * 255));
            e.coloured = l.coloured;
            r->labels.push_back(std::move(e));
        }
        for (std::size_t i = 0; i < r->s.overlays.size() && !r->s.labels.empty(); ++i) {
            const gifti::Overlay &o = r->s.overlays[i];
            if (o.integer && o.components == 1 && o.intent == "NIFTI_INTENT_LABEL") {
                r->rgba_of.push_back(i);
                r->rgba_names.push_back(o.name + " rgba");
            }
        }
        *out = reinterpret_cast<hz_reader *>(r.release());
        return HZ_OK;
    });
}

hz_status HZ_ABI get_info(hz_reader *reader, hz_dataset_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_dataset_info))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "gifti: get_info: bad arguments");
    const gifti::Surface &s = as_reader(reader)->s;
    out->kind = HZ_DATA_MESH;
    std::snprintf(out->format, sizeof out->format, "gifti");
    out->nb_vertices = s.vertices.size() / 3;
    out->nb_faces = s.faces.size() / 3;
    // The POINTSET's CoordinateSystemTransformMatrix (DataSpace ->
    // TransformedSpace), kept so that a writer can restore it; vertices are
    // used as stored (nibabel, Workbench).
    std::copy(s.transform.begin(), s.transform.end(), out->voxel_to_ras);
    out->source_space = HZ_SPACE_RASMM;
    out->nb_arrays = static_cast<uint32_t>(s.overlays.size() + as_reader(reader)->rgba_of.size());
    return HZ_OK;
}

hz_status HZ_ABI get_array_info(hz_reader *reader, uint32_t index, hz_array_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "gifti: get_array_info: NULL");
    const Reader &r = *as_reader(reader);
    if (index >= r.s.overlays.size() && index - r.s.overlays.size() < r.rgba_of.size()) {
        out->attach = HZ_ATTACH_VERTEX;
        out->name = r.rgba_names[index - r.s.overlays.size()].c_str();
        out->dtype = HZ_DTYPE_U8;
        out->components = 4;
        out->count = r.s.rows;
        return HZ_OK;
    }
    if (index >= r.s.overlays.size()) return hz::set_errorf(err, HZ_E_NOT_FOUND, "gifti: %s: no extra array %u", r.path.c_str(), index);
    const gifti::Overlay &o = r.s.overlays[index];
    out->attach = HZ_ATTACH_VERTEX;
    out->name = o.name.c_str();
    out->dtype = dtype_of(o);
    out->components = o.components;
    out->count = r.s.rows;
    return HZ_OK;
}

hz_status HZ_ABI visit_metadata(hz_reader *reader, hz_metadata_visitor visitor, void *ctx, hz_error *err) {
    if (reader == nullptr || visitor == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "gifti: visit_metadata: NULL");
    const gifti::Surface &s = as_reader(reader)->s;
    for (const auto &[k, v] : s.metadata) visitor(ctx, k.c_str(), v.c_str());
    for (const hzlabel::Entry &e : as_reader(reader)->labels) visitor(ctx, hzlabel::key(e.index).c_str(), hzlabel::value(e).c_str());
    if (!s.data_space.empty()) visitor(ctx, "DataSpace", s.data_space.c_str());
    if (!s.transformed_space.empty()) visitor(ctx, "TransformedSpace", s.transformed_space.c_str());
    return HZ_OK;
}

hz_status HZ_ABI read_mesh(hz_reader *reader, const hz_mesh_dst *dst, const hz_task *task, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "gifti: read_mesh: NULL");
    const Reader &r = *as_reader(reader);
    if (hz::cancelled(task)) return hz::set_error(err, HZ_E_CANCELLED, "cancelled");
    if (dst->vertices_capacity < r.s.vertices.size() || dst->faces_capacity < r.s.faces.size())
        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "gifti: %s: destination too small", r.path.c_str());
    if (!r.s.vertices.empty()) std::memcpy(dst->vertices, r.s.vertices.data(), r.s.vertices.size() * 4);
    if (!r.s.faces.empty()) std::memcpy(dst->faces, r.s.faces.data(), r.s.faces.size() * 4);
    return HZ_OK;
}

hz_status HZ_ABI read_array(hz_reader *reader, uint32_t index, const hz_array_view *dst, const hz_task *, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "gifti: read_array: NULL");
    const Reader &r = *as_reader(reader);
    const std::uint64_t rows = r.s.rows;
    if (index >= r.s.overlays.size() && index - r.s.overlays.size() < r.rgba_of.size()) {
        if (dst->dtype != HZ_DTYPE_U8 || dst->ndim < 1 || dst->shape[0] != rows)
            return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "gifti: %s: read_array: destination does not match", r.path.c_str());
        const gifti::Overlay &o = r.s.overlays[r.rgba_of[index - r.s.overlays.size()]];
        const hzlabel::Colours colour(r.labels);
        for (std::uint64_t i = 0; i < rows; ++i) {
            const std::array<std::uint8_t, 4> rgba = colour(o.labels[i]);
            for (std::uint32_t c = 0; c < 4; ++c) {
                unsigned char *cell = hz::view_cell(*dst, i, c, 1);
                if (cell == nullptr)
                    return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "gifti: %s: read_array: destination too small", r.path.c_str());
                *cell = rgba[c];
            }
        }
        return HZ_OK;
    }
    if (index >= r.s.overlays.size()) return hz::set_errorf(err, HZ_E_NOT_FOUND, "gifti: %s: no extra array %u", r.path.c_str(), index);
    const gifti::Overlay &o = r.s.overlays[index];
    if (dst->ndim != 2 || dst->shape[0] != rows || dst->shape[1] != o.components || dst->dtype != dtype_of(o))
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "gifti: %s: read_array: destination does not match", r.path.c_str());
    const std::size_t width = o.values64.empty() ? 4 : 8;
    for (std::uint64_t i = 0; i < rows; ++i)
        for (std::uint32_t c = 0; c < o.components; ++c) {
            unsigned char *cell = hz::view_cell(*dst, i, c, width);
            if (cell == nullptr)
                return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "gifti: %s: read_array: destination too small", r.path.c_str());
            const std::size_t k = i * o.components + c;
            const void *src = o.integer    ? static_cast<const void *>(&o.labels[k])
                              : width == 8 ? static_cast<const void *>(&o.values64[k])
                                           : static_cast<const void *>(&o.values[k]);
            std::memcpy(cell, src, width);
        }
    return HZ_OK;
}

void HZ_ABI close(hz_reader *reader) { delete as_reader(reader); }

hz_status HZ_ABI write(const hz_write_request *req, const hz_dataset_view *data, const hz_task *, hz_error *err) {
    if (req == nullptr || req->path == nullptr || data == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "gifti: write: NULL request or data");
    if (data->kind != HZ_DATA_MESH) return hz::set_errorf(err, HZ_E_UNSUPPORTED, "gifti: %s: GIFTI holds surfaces only", req->path);
    return run(err, req->path, [&]() -> hz_status {
        gifti::Surface s;
        s.vertices.assign(data->mesh_vertices, data->mesh_vertices + 3 * data->mesh_nb_vertices);
        s.faces.assign(data->mesh_faces, data->mesh_faces + 3 * data->mesh_nb_faces);
        for (std::uint32_t f : s.faces)
            if (f >= data->mesh_nb_vertices) throw gifti::FormatError("a triangle uses a vertex index out of range");
        std::copy(data->voxel_to_ras, data->voxel_to_ras + 16, s.transform.begin());
        if (s.transform[15] == 0) s.transform = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        for (uint32_t i = 0; i < data->nb_metadata; ++i) {
            const std::string k = data->metadata[i].key ? data->metadata[i].key : "";
            const std::string v = data->metadata[i].value ? data->metadata[i].value : "";
            if (k == "DataSpace")
                s.data_space = v;
            else if (k == "TransformedSpace")
                s.transformed_space = v;
            else if (auto e = hzlabel::parse(k, v)) {
                // a label table entry (an annotation's, or a GIFTI LabelTable's) goes in the LabelTable
                s.labels.push_back({e->index, e->name, e->r / 255.0, e->g / 255.0, e->b / 255.0, e->alpha() / 255.0, e->coloured});
            } else
                s.metadata.emplace_back(k, v);
        }
        // No geometry: an overlay-only file, its rows set by the first per-vertex array.
        s.rows = data->mesh_nb_vertices;
        if (s.rows == 0)
            for (uint32_t i = 0; i < data->nb_arrays && s.rows == 0; ++i)
                if (data->arrays[i].attach == HZ_ATTACH_VERTEX) s.rows = data->arrays[i].count;
        for (uint32_t i = 0; i < data->nb_arrays; ++i) {
            const hz_named_array &a = data->arrays[i];
            const std::string name = a.name ? a.name : "";
            if (a.attach != HZ_ATTACH_VERTEX || a.count != s.rows) {
                if (req->on_dropped) req->on_dropped(req->ctx, ("array '" + name + "' (GIFTI overlays are per vertex)").c_str());
                continue;
            }
            gifti::Overlay o;
            o.name = name;
            o.components = a.components;
            const std::uint64_t n = a.count * a.components;
            if (a.dtype == HZ_DTYPE_F32) {
                const auto *p = static_cast<const float *>(a.data);
                o.values.assign(p, p + n);
            } else if (a.dtype == HZ_DTYPE_F64) {  // kept as float64 (NIFTI_TYPE_FLOAT64), not narrowed
                const auto *p = static_cast<const double *>(a.data);
                o.values64.assign(p, p + n);
            } else if (a.dtype == HZ_DTYPE_I32) {
                o.integer = true;
                const auto *p = static_cast<const std::int32_t *>(a.data);
                o.labels.assign(p, p + n);
            } else {
                // The colours of a label array ("<labels> rgba", as annotations
                // and label GIFTIs are read) are kept by the LabelTable.
                const bool label_colours = !s.labels.empty() && a.dtype == HZ_DTYPE_U8 && a.components == 4 && name.size() > 5 &&
                                           name.compare(name.size() - 5, 5, " rgba") == 0 && [&] {
                                               const std::string base = name.substr(0, name.size() - 5);
                                               for (uint32_t j = 0; j < data->nb_arrays; ++j)
                                                   if (data->arrays[j].dtype == HZ_DTYPE_I32 && data->arrays[j].components == 1 &&
                                                       data->arrays[j].name != nullptr && base == data->arrays[j].name)
                                                       return true;
                                               return false;
                                           }();
                if (!label_colours && req->on_dropped)
                    req->on_dropped(req->ctx, ("array '" + name + "' (type not stored in GIFTI)").c_str());
                continue;
            }
            s.overlays.push_back(std::move(o));
        }
        if (s.vertices.empty() && s.overlays.empty()) throw gifti::FormatError("nothing to write: no surface and no per-vertex array");
        gifti::write(req->path, s, true);
        return HZ_OK;
    });
}

const char *const kExtensions[] = {"gii", nullptr};
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
    .name = "GIFTI",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "GIFTI surfaces and per-vertex overlays (ASCII, Base64, GZipBase64, external; both endians; row/column major)",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader>::entry;
