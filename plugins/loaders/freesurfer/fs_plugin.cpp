// hz.loader/1: FreeSurfer binary surfaces (lh.white, rh.pial, ...).
// Format (nibabel freesurfer/io.py, FORMATS.md 1.7): big-endian; magic
// FF FF FE; a "created by ..." line and a blank line; int32 vnum, fnum;
// vnum x 3 float32; fnum x 3 int32; an optional volume-info footer. The
// coordinates are surface RAS (tkr-RAS) and are used as stored, as nibabel
// does; the footer (with c_ras) is kept as header entries and written back.
// Also "new format" curv files (lh.curv, lh.thickness, lh.sulc, ...): magic
// FF FF FF, int32 vnum, fnum, values per vertex (1), vnum float32: read as a
// per-vertex overlay without geometry, named after the file (lh.thickness ->
// "thickness"), and written from one. Quad surfaces (FF FF FF / FF FF FD,
// read only) are split into triangles as nibabel does. And annotations
// (lh.aparc.annot, read and written): an overlay of two per-vertex arrays,
// "aparc" (int32 colour-table index, -1 unlabeled) and "aparc rgba" (uint8 x 4, the label's sRGB colour,
// alpha 255 - transparency; unlabeled vertices grey with alpha 0), with the
// table as header entries "label <index>" = "<name> <r> <g> <b> <t>".
#include "fs_format.hpp"
#include "label_table.hpp"
#include "mapped_file.hpp"

#include <hz/cpp/plugin.hpp>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <bit>
#include <cstring>
#include <ctime>
#include <memory>
#include <vector>

namespace {

constexpr const char *kId = "org.horizon.loader.freesurfer";

using fsurf::be32;
using fsurf::FormatError;
using fsurf::looks_like_curv;
using fsurf::parse;
using fsurf::Surface;

struct Reader {
    std::string path;
    std::string array_name;  // curv, annot: named after the file
    std::string rgba_name;   // annot: "<name> rgba"
    Surface s;
    bool annot = false;
    fsurf::Annotation a;
    std::vector<std::pair<std::string, std::string>> annot_meta;
};

bool is_annot_name(const std::string &path) { return path.size() > 6 && path.compare(path.size() - 6, 6, ".annot") == 0; }

// lh.thickness -> "thickness"; a name without a dot is used whole.
std::string overlay_name(const std::string &path) {
    std::string base = path.substr(path.find_last_of('/') + 1);
    const auto dot = base.find('.');
    if (dot != std::string::npos && dot + 1 < base.size()) base = base.substr(dot + 1);
    if (base.size() > 6 && base.compare(base.size() - 6, 6, ".annot") == 0) base.resize(base.size() - 6);
    return base.empty() ? "curv" : base;
}
Reader *as_reader(hz_reader *r) { return reinterpret_cast<Reader *>(r); }

template <class F>
hz_status run(hz_error *err, const std::string &path, F &&body) {
    return hz::format_guard<FormatError, hzio::IoError>(err, "freesurfer", path, body);
}

int32_t HZ_ABI probe(const uint8_t *head, uint64_t size, const char *name) {
    if (size >= 3 && head[0] == 0xFF && head[1] == 0xFF && head[2] == 0xFE) return 90;
    if (looks_like_curv(head, size)) return 80;
    if (size >= 9 && head[0] == 0xFF && head[1] == 0xFF && (head[2] == 0xFF || head[2] == 0xFD)) return 80;  // quad surface
    // Annotations have no magic number: the name, a positive vertex count and vertex 0 first.
    if (name != nullptr && is_annot_name(name) && size >= 8 && static_cast<std::int32_t>(be32(head)) > 0 && be32(head + 4) == 0) return 60;
    return 0;
}

hz_status HZ_ABI open(const hz_open_request *req, hz_reader **out, hz_error *err) {
    if (out != nullptr) *out = nullptr;
    if (req == nullptr || req->path == nullptr || out == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "freesurfer: open: NULL request, path or output");
    return run(err, req->path, [&]() -> hz_status {
        auto r = std::make_unique<Reader>();
        r->path = req->path;
        const hzio::MappedFile m(r->path);
        r->array_name = overlay_name(r->path);
        if (is_annot_name(r->path)) {
            r->annot = true;
            r->a = fsurf::parse_annot(m.data(), m.size());
            r->rgba_name = r->array_name + " rgba";
            if (!r->a.orig_table.empty()) r->annot_meta.emplace_back("orig_table", r->a.orig_table);
            for (const auto &e : r->a.table) r->annot_meta.emplace_back(hzlabel::key(e.index), hzlabel::value(e));
        } else {
            r->s = parse(m.data(), m.size());
        }
        *out = reinterpret_cast<hz_reader *>(r.release());
        return HZ_OK;
    });
}

hz_status HZ_ABI get_info(hz_reader *reader, hz_dataset_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_dataset_info))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "freesurfer: get_info: bad arguments");
    const Surface &s = as_reader(reader)->s;
    out->kind = HZ_DATA_MESH;
    std::snprintf(out->format, sizeof out->format,
                  as_reader(reader)->annot ? "freesurfer annot"
                  : s.curv                 ? "freesurfer curv"
                  : s.quad                 ? "freesurfer quads"
                                           : "freesurfer triangles");
    out->nb_arrays = as_reader(reader)->annot ? 2 : s.curv ? 1 : 0;
    out->nb_vertices = s.vertices.size() / 3;
    out->nb_faces = s.faces.size() / 3;
    static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::memcpy(out->voxel_to_ras, identity, sizeof identity);
    out->source_space = HZ_SPACE_SURFACE_RAS;
    return HZ_OK;
}

hz_status HZ_ABI get_array_info(hz_reader *reader, uint32_t index, hz_array_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "freesurfer: get_array_info: NULL");
    const Reader &r = *as_reader(reader);
    if (r.annot && index < 2) {
        out->attach = HZ_ATTACH_VERTEX;
        out->name = index == 0 ? r.array_name.c_str() : r.rgba_name.c_str();
        out->dtype = index == 0 ? HZ_DTYPE_I32 : HZ_DTYPE_U8;
        out->components = index == 0 ? 1 : 4;
        out->count = r.a.labels.size();
        return HZ_OK;
    }
    if (!r.s.curv || index != 0) return hz::set_errorf(err, HZ_E_NOT_FOUND, "freesurfer: %s: no extra array %u", r.path.c_str(), index);
    out->attach = HZ_ATTACH_VERTEX;
    out->name = r.array_name.c_str();
    out->dtype = HZ_DTYPE_F32;
    out->components = 1;
    out->count = r.s.values.size();
    return HZ_OK;
}

hz_status HZ_ABI read_array(hz_reader *reader, uint32_t index, const hz_array_view *dst, const hz_task *, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "freesurfer: read_array: NULL");
    const Reader &r = *as_reader(reader);
    if (r.annot && index < 2) {
        const std::uint64_t n = r.a.labels.size();
        if (dst->dtype != (index == 0 ? HZ_DTYPE_I32 : HZ_DTYPE_U8) || dst->ndim < 1 || dst->shape[0] != n)
            return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "freesurfer: %s: read_array: destination does not match", r.path.c_str());
        const hzlabel::Colours colour(r.a.table);
        for (std::uint64_t i = 0; i < n; ++i) {
            const std::int32_t l = r.a.labels[i];
            for (std::uint32_t c = 0; c < (index == 0 ? 1u : 4u); ++c) {
                unsigned char *cell = hz::view_cell(*dst, i, c, index == 0 ? 4 : 1);
                if (cell == nullptr)
                    return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "freesurfer: %s: read_array: destination too small", r.path.c_str());
                if (index == 0)
                    std::memcpy(cell, &l, 4);
                else
                    *cell = colour(l)[c];
            }
        }
        return HZ_OK;
    }
    if (!r.s.curv || index != 0) return hz::set_errorf(err, HZ_E_NOT_FOUND, "freesurfer: %s: no extra array %u", r.path.c_str(), index);
    if (dst->dtype != HZ_DTYPE_F32 || dst->ndim < 1 || dst->shape[0] != r.s.values.size())
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "freesurfer: %s: read_array: destination does not match", r.path.c_str());
    for (std::uint64_t i = 0; i < r.s.values.size(); ++i) {
        unsigned char *cell = hz::view_cell(*dst, i, 0, 4);
        if (cell == nullptr)
            return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "freesurfer: %s: read_array: destination too small", r.path.c_str());
        std::memcpy(cell, &r.s.values[i], 4);
    }
    return HZ_OK;
}

hz_status HZ_ABI visit_metadata(hz_reader *reader, hz_metadata_visitor visitor, void *ctx, hz_error *err) {
    if (reader == nullptr || visitor == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "freesurfer: visit_metadata: NULL");
    const Surface &s = as_reader(reader)->s;
    for (const auto &[k, v] : as_reader(reader)->annot_meta) visitor(ctx, k.c_str(), v.c_str());
    if (s.curv || as_reader(reader)->annot) return HZ_OK;
    visitor(ctx, s.quad ? "quad coordinates" : "created", s.created.c_str());
    for (const auto &[k, v] : s.footer) visitor(ctx, k.c_str(), v.c_str());
    return HZ_OK;
}

hz_status HZ_ABI read_mesh(hz_reader *reader, const hz_mesh_dst *dst, const hz_task *task, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "freesurfer: read_mesh: NULL");
    const Reader &r = *as_reader(reader);
    if (hz::cancelled(task)) return hz::set_error(err, HZ_E_CANCELLED, "cancelled");
    if (dst->vertices_capacity < r.s.vertices.size() || dst->faces_capacity < r.s.faces.size())
        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "freesurfer: %s: destination too small", r.path.c_str());
    if (!r.s.vertices.empty()) std::memcpy(dst->vertices, r.s.vertices.data(), r.s.vertices.size() * 4);
    if (!r.s.faces.empty()) std::memcpy(dst->faces, r.s.faces.data(), r.s.faces.size() * 4);
    return HZ_OK;
}

void HZ_ABI close(hz_reader *reader) { delete as_reader(reader); }

// Big-endian output, as every FreeSurfer file.
void put_be32(std::vector<unsigned char> &out, std::uint32_t v) {
    for (int sh = 24; sh >= 0; sh -= 8) out.push_back(static_cast<unsigned char>(v >> sh));
}

void save(const char *path, const std::vector<unsigned char> &bytes) {
    std::FILE *f = std::fopen(path, "wb");
    if (f == nullptr) throw FormatError(std::string("cannot create: ") + std::strerror(errno));
    const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
    if ((std::fclose(f) != 0) || !ok) throw FormatError("write failed");
}

const char *const kCurvExtensions[] = {"curv", "thickness", "sulc", "area"};

// One per-vertex, one-component float array as a curv file.
hz_status write_curv(const hz_write_request *req, const hz_dataset_view *data) {
    const hz_named_array *pick = nullptr;
    for (uint32_t i = 0; i < data->nb_arrays; ++i) {
        const hz_named_array &a = data->arrays[i];
        const bool fits = a.attach == HZ_ATTACH_VERTEX && a.components == 1 && (a.dtype == HZ_DTYPE_F32 || a.dtype == HZ_DTYPE_F64) &&
                          (data->mesh_nb_vertices == 0 || a.count == data->mesh_nb_vertices);
        if (fits && pick == nullptr)
            pick = &a;
        else if (req->on_dropped)
            req->on_dropped(req->ctx,
                            ("array '" + std::string(a.name ? a.name : "") + "' (a curv file holds one per-vertex value)").c_str());
    }
    if (pick == nullptr) throw FormatError("a curv file needs a per-vertex array of one float value per vertex; this data has none");
    if (pick->count == 0 || pick->count > 0x7FFFFFFF) throw FormatError("curv files hold 1 to 2^31-1 values");
    if (data->mesh_nb_vertices > 0 && req->on_dropped) req->on_dropped(req->ctx, "the surface geometry (a curv file holds values only)");
    if (pick->dtype == HZ_DTYPE_F64 && req->on_dropped)
        req->on_dropped(req->ctx, ("the float64 precision of array '" + std::string(pick->name ? pick->name : "") +
                                   "' (curv values are float32: rounded)")
                                      .c_str());
    std::vector<unsigned char> out = {0xFF, 0xFF, 0xFF};
    auto put = [&](std::uint32_t v) { put_be32(out, v); };
    put(static_cast<std::uint32_t>(pick->count));
    put(static_cast<std::uint32_t>(data->mesh_nb_faces));
    put(1);
    for (std::uint64_t i = 0; i < pick->count; ++i) {
        const float v = pick->dtype == HZ_DTYPE_F32 ? static_cast<const float *>(pick->data)[i]
                                                    : static_cast<float>(static_cast<const double *>(pick->data)[i]);
        put(std::bit_cast<std::uint32_t>(v));
    }
    save(req->path, out);
    return HZ_OK;
}

// An annotation from a per-vertex int32 label array (an annotation's, or a
// GIFTI label array's) and the label table in the header entries ("label
// <index>" = "<name> r g b t"), written as nibabel's write_annot writes it:
// colour table version 2, every vertex listed in order, value 0 for -1.
hz_status write_annot(const hz_write_request *req, const hz_dataset_view *data) {
    const hz_named_array *pick = nullptr;
    for (uint32_t i = 0; i < data->nb_arrays; ++i) {
        const hz_named_array &a = data->arrays[i];
        const std::string name = a.name ? a.name : "";
        const bool fits = a.attach == HZ_ATTACH_VERTEX && a.components == 1 && a.dtype == HZ_DTYPE_I32 &&
                          (data->mesh_nb_vertices == 0 || a.count == data->mesh_nb_vertices);
        if (fits && pick == nullptr) {
            pick = &a;
            continue;
        }
        // The label colours ("<labels> rgba") are the colour table's.
        const bool colours = pick != nullptr && pick->name != nullptr && name == std::string(pick->name) + " rgba";
        if (!colours && req->on_dropped)
            req->on_dropped(req->ctx, ("array '" + name + "' (an annotation holds one label per vertex)").c_str());
    }
    if (pick == nullptr) throw FormatError("an annotation needs a per-vertex int32 label array; this data has none");
    if (pick->count == 0 || pick->count > 0x7FFFFFFF) throw FormatError("annotations hold 1 to 2^31-1 vertices");
    std::vector<hzlabel::Entry> table;
    std::string orig_table = "NOFILE";
    for (uint32_t i = 0; i < data->nb_metadata; ++i) {
        const char *k = data->metadata[i].key, *v = data->metadata[i].value;
        if (k == nullptr || v == nullptr) continue;
        if (auto e = hzlabel::parse(k, v))
            table.push_back(std::move(*e));
        else if (std::string(k) == "orig_table")
            orig_table = v;
    }
    if (table.empty())
        throw FormatError("an annotation needs a colour table (header entries 'label <index>' = '<name> r g b t'); this data has none");
    hzlabel::assign_colours(table);  // (labels without a colour: one no other label has)
    // index -> packed colour, the value stored per vertex
    std::vector<std::pair<std::int32_t, std::uint32_t>> packed;
    for (const auto &e : table) {
        if (e.index < 0) throw FormatError("label index " + std::to_string(e.index) + " is negative (annotation indices are 0 or more)");
        packed.emplace_back(e.index, e.packed());
    }
    std::sort(packed.begin(), packed.end());
    for (std::size_t i = 1; i < packed.size(); ++i)
        if (packed[i].first == packed[i - 1].first) throw FormatError("the colour table lists a label index twice");
    // An annotation stores each vertex's label as its colour: two labels of one colour would merge.
    {
        std::vector<std::pair<std::uint32_t, std::int32_t>> by_colour;
        for (const auto &[index, colour] : packed) by_colour.emplace_back(colour, index);
        std::sort(by_colour.begin(), by_colour.end());
        for (std::size_t i = 1; i < by_colour.size(); ++i)
            if (by_colour[i].first == by_colour[i - 1].first)
                throw FormatError("labels " + std::to_string(by_colour[i - 1].second) + " and " + std::to_string(by_colour[i].second) +
                                  " have the same colour (an annotation identifies labels by their colour)");
    }
    const std::int32_t max_index = packed.back().first;
    const auto *labels = static_cast<const std::int32_t *>(pick->data);
    std::vector<unsigned char> out;
    auto put = [&](std::uint32_t v) { put_be32(out, v); };
    auto put_text = [&](const std::string &t) {
        put(static_cast<std::uint32_t>(t.size() + 1));
        out.insert(out.end(), t.begin(), t.end());
        out.push_back(0);
    };
    out.reserve(8 * pick->count + 64 * table.size() + 64);
    put(static_cast<std::uint32_t>(pick->count));
    for (std::uint64_t i = 0; i < pick->count; ++i) {
        const std::int32_t l = labels[i];
        std::uint32_t value = 0;
        if (l != -1) {
            const auto it = std::lower_bound(packed.begin(), packed.end(), std::pair{l, 0u});
            if (it == packed.end() || it->first != l)
                throw FormatError("vertex " + std::to_string(i) + " has label " + std::to_string(l) +
                                  ", which the colour table does not define");
            value = it->second;
        }
        put(static_cast<std::uint32_t>(i));
        put(value);
    }
    put(1);                                          // a colour table follows
    put(static_cast<std::uint32_t>(-2));             // version 2
    put(static_cast<std::uint32_t>(max_index + 1));  // largest index + 1
    put_text(orig_table);
    put(static_cast<std::uint32_t>(table.size()));
    for (const auto &e : table) {
        put(static_cast<std::uint32_t>(e.index));
        put_text(e.name);
        const auto c = e.rgb();  // (a label without a colour: the assigned one, also in the packed vertex values)
        put(std::uint32_t(c[0])), put(std::uint32_t(c[1])), put(std::uint32_t(c[2])), put(std::uint32_t(e.coloured ? e.t : 0));
    }
    if (data->mesh_nb_vertices > 0 && req->on_dropped) req->on_dropped(req->ctx, "the surface geometry (an annotation holds labels only)");
    save(req->path, out);
    return HZ_OK;
}

hz_status HZ_ABI write(const hz_write_request *req, const hz_dataset_view *data, const hz_task *, hz_error *err) {
    if (req == nullptr || req->path == nullptr || data == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "freesurfer: write: NULL request or data");
    if (data->kind != HZ_DATA_MESH) return hz::set_errorf(err, HZ_E_UNSUPPORTED, "freesurfer: %s: holds surfaces only", req->path);
    return run(err, req->path, [&]() -> hz_status {
        const std::string ext = req->extension ? req->extension : "";
        if (ext == "annot") return write_annot(req, data);
        if (std::find(std::begin(kCurvExtensions), std::end(kCurvExtensions), ext) != std::end(kCurvExtensions))
            return write_curv(req, data);
        if (data->mesh_nb_vertices == 0 && data->nb_arrays > 0)
            throw FormatError("no surface geometry to write (per-vertex values go in a curv file: lh.curv, lh.thickness, ...)");
        if (data->mesh_nb_vertices > 0x7FFFFFFF || data->mesh_nb_faces > 0x7FFFFFFF) throw FormatError("too many vertices or faces");
        for (uint32_t i = 0; i < data->nb_arrays && req->on_dropped; ++i)
            req->on_dropped(req->ctx, ("array '" + std::string(data->arrays[i].name ? data->arrays[i].name : "") +
                                       "' (a FreeSurfer surface holds geometry only; overlays go in curv files)")
                                          .c_str());
        static const char *footer_keys[] = {"valid", "filename", "volume", "voxelsize", "xras", "yras", "zras", "cras"};
        std::string footer;
        for (uint32_t i = 0; i < data->nb_metadata; ++i) {
            const std::string k = data->metadata[i].key ? data->metadata[i].key : "";
            if (std::find(std::begin(footer_keys), std::end(footer_keys), k) != std::end(footer_keys))
                footer += (k.size() < 6 ? k + std::string(6 - k.size(), ' ') : k) + " = " + data->metadata[i].value + "\n";
        }
        std::vector<unsigned char> out = {0xFF, 0xFF, 0xFE};
        const std::time_t now = std::time(nullptr);
        char stamp[64];
        std::strftime(stamp, sizeof stamp, "%a %b %d %H:%M:%S %Y", std::localtime(&now));
        const std::string created = std::string("created by horizon on ") + stamp + "\n\n";
        out.insert(out.end(), created.begin(), created.end());
        auto put = [&](std::uint32_t v) { put_be32(out, v); };
        put(static_cast<std::uint32_t>(data->mesh_nb_vertices));
        put(static_cast<std::uint32_t>(data->mesh_nb_faces));
        for (std::uint64_t i = 0; i < 3 * data->mesh_nb_vertices; ++i) put(std::bit_cast<std::uint32_t>(data->mesh_vertices[i]));
        for (std::uint64_t i = 0; i < 3 * data->mesh_nb_faces; ++i) {
            if (data->mesh_faces[i] >= data->mesh_nb_vertices) throw FormatError("a face uses a vertex index out of range");
            put(data->mesh_faces[i]);
        }
        if (!footer.empty()) {
            put(2), put(0), put(20);
            out.insert(out.end(), footer.begin(), footer.end());
        }
        save(req->path, out);
        return HZ_OK;
    });
}

const char *const kExtensions[] = {"white", "pial", "inflated",  "sphere", "orig", "smoothwm", "midthickness",
                                   "surf",  "curv", "thickness", "sulc",   "area", "annot",    nullptr};
const hz_loader kLoader = {
    .struct_size = sizeof(hz_loader),
    .data_kinds = HZ_DATA_MESH,
    .caps = HZ_LOADER_CAN_READ | HZ_LOADER_CAN_WRITE,
    .probe_bytes = 15,
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
    .name = "FreeSurfer surface",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description =
        "FreeSurfer binary surfaces (lh.white, rh.pial, ...; triangle files with the volume-info footer, quad files read), curv overlays "
        "(lh.curv, lh.thickness, ...) and annotations (lh.aparc.annot)",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader>::entry;
