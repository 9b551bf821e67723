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

#include <hz/cpp/loader.hpp>

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

bool is_annot_name(const std::string &path) { return path.size() > 6 && path.compare(path.size() - 6, 6, ".annot") == 0; }

// lh.thickness -> "thickness"; a name without a dot is used whole.
std::string overlay_name(const std::string &path) {
    std::string base = path.substr(path.find_last_of('/') + 1);
    const auto dot = base.find('.');
    if (dot != std::string::npos && dot + 1 < base.size()) base = base.substr(dot + 1);
    if (base.size() > 6 && base.compare(base.size() - 6, 6, ".annot") == 0) base.resize(base.size() - 6);
    return base.empty() ? "curv" : base;
}

struct FsReader {
    std::string array_name;  // curv, annot: named after the file
    std::string rgba_name;   // annot: "<name> rgba"
    Surface s;
    bool annot = false;
    fsurf::Annotation a;
    std::vector<std::pair<std::string, std::string>> annot_meta;
};

int32_t fs_probe(const uint8_t *head, uint64_t size, const char *name) noexcept {
    if (size >= 3 && head[0] == 0xFF && head[1] == 0xFF && head[2] == 0xFE) return 90;
    if (looks_like_curv(head, size)) return 80;
    if (size >= 9 && head[0] == 0xFF && head[1] == 0xFF && (head[2] == 0xFF || head[2] == 0xFD)) return 80;  // quad surface
    // Annotations have no magic number: the name, a positive vertex count and vertex 0 first.
    if (name != nullptr && is_annot_name(name) && size >= 8 && static_cast<std::int32_t>(be32(head)) > 0 && be32(head + 4) == 0) return 60;
    return 0;
}

std::unique_ptr<FsReader> fs_open(const std::string &path, const hz_task *) {
    auto r = std::make_unique<FsReader>();
    const hzio::MappedFile m(path);
    r->array_name = overlay_name(path);
    if (is_annot_name(path)) {
        r->annot = true;
        r->a = fsurf::parse_annot(m.data(), m.size());
        r->rgba_name = r->array_name + " rgba";
        if (!r->a.orig_table.empty()) r->annot_meta.emplace_back("orig_table", r->a.orig_table);
        for (const auto &e : r->a.table) r->annot_meta.emplace_back(hzlabel::key(e.index), hzlabel::value(e));
    } else {
        r->s = parse(m.data(), m.size());
    }
    return r;
}

void fs_info(const FsReader &r, hz_dataset_info &out) {
    const Surface &s = r.s;
    out.kind = HZ_DATA_MESH;
    std::snprintf(out.format, sizeof out.format,
                  r.annot  ? "freesurfer annot"
                  : s.curv ? "freesurfer curv"
                  : s.quad ? "freesurfer quads"
                           : "freesurfer triangles");
    out.nb_arrays = r.annot ? 2 : s.curv ? 1 : 0;
    out.nb_vertices = s.vertices.size() / 3;
    out.nb_faces = s.faces.size() / 3;
    static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::memcpy(out.voxel_to_ras, identity, sizeof identity);
    out.source_space = HZ_SPACE_SURFACE_RAS;
}

// Arrays: an annotation's labels and their colours; a curv file's values.
void fs_array_info(const FsReader &r, uint32_t index, hz_array_info &out) {
    out.attach = HZ_ATTACH_VERTEX;
    if (r.annot) {
        out.name = index == 0 ? r.array_name.c_str() : r.rgba_name.c_str();
        out.dtype = index == 0 ? HZ_DTYPE_I32 : HZ_DTYPE_U8;
        out.components = index == 0 ? 1 : 4;
        out.count = r.a.labels.size();
        return;
    }
    out.name = r.array_name.c_str();
    out.dtype = HZ_DTYPE_F32;
    out.components = 1;
    out.count = r.s.values.size();
}

void fs_read_array(const FsReader &r, uint32_t index, void *dense, const hz_task *) {
    if (!r.annot) {
        std::memcpy(dense, r.s.values.data(), r.s.values.size() * sizeof(float));
    } else if (index == 0) {
        std::memcpy(dense, r.a.labels.data(), r.a.labels.size() * sizeof(std::int32_t));
    } else {
        const hzlabel::Colours colour(r.a.table);
        auto *out = static_cast<std::uint8_t *>(dense);
        for (std::size_t i = 0; i < r.a.labels.size(); ++i) std::memcpy(out + 4 * i, colour(r.a.labels[i]).data(), 4);
    }
}

void fs_metadata(const FsReader &r, hz_metadata_visitor visit, void *ctx) {
    const Surface &s = r.s;
    for (const auto &[k, v] : r.annot_meta) visit(ctx, k.c_str(), v.c_str());
    if (s.curv || r.annot) return;
    visit(ctx, s.quad ? "quad coordinates" : "created", s.created.c_str());
    for (const auto &[k, v] : s.footer) visit(ctx, k.c_str(), v.c_str());
}

void fs_read_mesh(FsReader &r, float *vertices, uint32_t *faces, const hz_task *) {
    if (!r.s.vertices.empty()) std::memcpy(vertices, r.s.vertices.data(), r.s.vertices.size() * 4);
    if (!r.s.faces.empty()) std::memcpy(faces, r.s.faces.data(), r.s.faces.size() * 4);
}

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

void fs_write(const hz_write_request &request, const hz_dataset_view &view, const hz_task *) {
    const hz_write_request *req = &request;
    const hz_dataset_view *data = &view;
    {
        const std::string ext = req->extension ? req->extension : "";
        if (ext == "annot") {
            write_annot(req, data);
            return;
        }
        if (std::find(std::begin(kCurvExtensions), std::end(kCurvExtensions), ext) != std::end(kCurvExtensions)) {
            write_curv(req, data);
            return;
        }
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
    }
}

const char *const kExtensions[] = {"white", "pial", "inflated",  "sphere", "orig", "smoothwm", "midthickness",
                                   "surf",  "curv", "thickness", "sulc",   "area", "annot",    nullptr};

// The format as the SDK's C++ loader adapter takes it (hz/cpp/loader.hpp).
struct FreeSurfer {
    static constexpr const char *prefix = "freesurfer";
    static constexpr hz_data_kind kinds = HZ_DATA_MESH;
    static constexpr uint32_t probe_bytes = 15;
    static constexpr const char *const *extensions = kExtensions;
    using FormatError = fsurf::FormatError;
    using IoError = hzio::IoError;
    using Reader = FsReader;
    static constexpr auto probe = fs_probe;
    static constexpr auto open = fs_open;
    static constexpr auto info = fs_info;
    static constexpr auto array_info = fs_array_info;
    static constexpr auto read_array = fs_read_array;
    static constexpr auto metadata = fs_metadata;
    static constexpr auto read_mesh = fs_read_mesh;
    static constexpr auto write = fs_write;
};
constexpr const hz_loader &kLoader = hz::loader<FreeSurfer>::table;
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
