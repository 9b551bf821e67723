// hz.loader/1 for GIFTI surfaces and overlays (gifti_format.hpp), through the
// SDK's C++ loader adapter (hz/cpp/loader.hpp).
#include "gifti_format.hpp"
#include "label_table.hpp"
#include "mapped_file.hpp"

#include <hz/cpp/loader.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>

namespace {

constexpr const char *kId = "org.horizon.loader.gifti";
const char *const kExtensions[] = {"gii", nullptr};

struct Gifti {
    static constexpr const char *prefix = "gifti";
    static constexpr hz_data_kind kinds = HZ_DATA_MESH;
    static constexpr uint32_t probe_bytes = 4096;
    static constexpr const char *const *extensions = kExtensions;
    using FormatError = gifti::FormatError;
    using IoError = hzio::IoError;

    struct Reader {
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

    // How an overlay is presented: int32 labels, float64 as stored, or float32.
    static hz_dtype dtype_of(const gifti::Overlay &o) {
        return o.integer ? HZ_DTYPE_I32 : o.values64.empty() ? HZ_DTYPE_F32 : HZ_DTYPE_F64;
    }

    static int32_t probe(const uint8_t *head, uint64_t size, const char *) noexcept { return gifti::probe(head, size); }

    static std::unique_ptr<Reader> open(const std::string &path, const hz_task *) {
        auto r = std::make_unique<Reader>();
        r->s = gifti::read(path);
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
        return r;
    }

    static void info(const Reader &r, hz_dataset_info &out) {
        const gifti::Surface &s = r.s;
        out.kind = HZ_DATA_MESH;
        std::snprintf(out.format, sizeof out.format, "gifti");
        out.nb_vertices = s.vertices.size() / 3;
        out.nb_faces = s.faces.size() / 3;
        // The POINTSET's CoordinateSystemTransformMatrix (DataSpace ->
        // TransformedSpace), kept so that a writer can restore it; vertices are
        // used as stored (nibabel, Workbench).
        std::copy(s.transform.begin(), s.transform.end(), out.voxel_to_ras);
        out.source_space = HZ_SPACE_RASMM;
        out.nb_arrays = static_cast<uint32_t>(s.overlays.size() + r.rgba_of.size());
    }

    // Arrays: the overlays, then the derived label colours.
    static void array_info(const Reader &r, uint32_t index, hz_array_info &out) {
        out.attach = HZ_ATTACH_VERTEX;
        out.count = r.s.rows;
        if (index >= r.s.overlays.size()) {
            out.name = r.rgba_names[index - r.s.overlays.size()].c_str();
            out.dtype = HZ_DTYPE_U8;
            out.components = 4;
            return;
        }
        const gifti::Overlay &o = r.s.overlays[index];
        out.name = o.name.c_str();
        out.dtype = dtype_of(o);
        out.components = o.components;
    }

    static void read_array(const Reader &r, uint32_t index, void *dense, const hz_task *) {
        const std::uint64_t rows = r.s.rows;
        if (index >= r.s.overlays.size()) {
            const gifti::Overlay &o = r.s.overlays[r.rgba_of[index - r.s.overlays.size()]];
            const hzlabel::Colours colour(r.labels);
            auto *out = static_cast<std::uint8_t *>(dense);
            for (std::uint64_t i = 0; i < rows; ++i) {
                const std::array<std::uint8_t, 4> rgba = colour(o.labels[i]);
                std::memcpy(out + 4 * i, rgba.data(), 4);
            }
            return;
        }
        const gifti::Overlay &o = r.s.overlays[index];
        const std::uint64_t n = rows * o.components;
        const void *src = o.integer            ? static_cast<const void *>(o.labels.data())
                          : o.values64.empty() ? static_cast<const void *>(o.values.data())
                                               : static_cast<const void *>(o.values64.data());
        std::memcpy(dense, src, n * (o.values64.empty() ? 4 : 8));
    }

    static void metadata(const Reader &r, hz_metadata_visitor visit, void *ctx) {
        const gifti::Surface &s = r.s;
        for (const auto &[k, v] : s.metadata) visit(ctx, k.c_str(), v.c_str());
        for (const hzlabel::Entry &e : r.labels) visit(ctx, hzlabel::key(e.index).c_str(), hzlabel::value(e).c_str());
        if (!s.data_space.empty()) visit(ctx, "DataSpace", s.data_space.c_str());
        if (!s.transformed_space.empty()) visit(ctx, "TransformedSpace", s.transformed_space.c_str());
    }

    static void read_mesh(Reader &r, float *vertices, uint32_t *faces, const hz_task *) {
        if (!r.s.vertices.empty()) std::memcpy(vertices, r.s.vertices.data(), r.s.vertices.size() * 4);
        if (!r.s.faces.empty()) std::memcpy(faces, r.s.faces.data(), r.s.faces.size() * 4);
    }

    static void write(const hz_write_request &request, const hz_dataset_view &view, const hz_task *) {
        const hz_write_request *req = &request;
        const hz_dataset_view *data = &view;
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
    }
};
constexpr const hz_loader &kLoader = hz::loader<Gifti>::table;

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
