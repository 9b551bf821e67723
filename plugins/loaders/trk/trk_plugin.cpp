// hz.loader/1 adapter for TrackVis TRK (trk_format.hpp).
#include "mapped_file.hpp"
#include "trk_format.hpp"

#include <hz/cpp/plugin.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

namespace {

constexpr const char *kId = "org.horizon.loader.trk";
const hz_host *host();

void log(hz_log_level lvl, const std::string &msg) { hz::log(host(), kId, lvl, msg); }

struct Reader {
    std::string path;
    std::unique_ptr<hzio::MappedFile> file;
    trk::Header header;
    trk::Layout layout;
    // Scalars and properties, decoded on first use (plugin-owned until close).
    bool extras_decoded = false;
    std::vector<float> scalars, properties;
};
Reader *as_reader(hz_reader *r) { return reinterpret_cast<Reader *>(r); }

template <class F>
hz_status run(hz_error *err, const std::string &path, F &&body) {
    return hz::format_guard<trk::FormatError, hzio::IoError, trk::Cancelled>(err, "trk", path, body);
}

// The decode's: polls cancellation and reports the fraction of `total`
// vertices decoded.
trk::Tick tick(const hz_task *task, std::uint64_t total) {
    return [task, total](std::uint64_t done) {
        if (done > 0 && total > 0) hz::report(task, std::min(1.0, double(done) / double(total)));
        return hz::cancelled(task);
    };
}

// Drops the mapped pages of a decoded chunk.
trk::Release release(const hzio::MappedFile &file) {
    return [&file](std::uint64_t begin, std::uint64_t end) { file.release(begin, end); };
}

int32_t HZ_ABI probe(const uint8_t *head, uint64_t size, const char *) { return trk::probe(head, size); }

// Opens and scans the file (every record: the counts and the chunk plan);
// with a task (HZ_EXT_OPEN_TASK), reporting the share scanned and cancellable.
hz_status open_with(const hz_open_request *req, const hz_task *task, hz_reader **out, hz_error *err) {
    if (out != nullptr) *out = nullptr;
    if (req == nullptr || req->path == nullptr || out == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trk: open: NULL request, path or output");
    return run(err, req->path, [&]() -> hz_status {
        auto r = std::make_unique<Reader>();
        r->path = req->path;
        r->file = std::make_unique<hzio::MappedFile>(r->path);
        r->header = trk::parse_header(r->file->data(), r->file->size());
        if (hz::cancelled(task)) throw trk::Cancelled{};
        const std::uint64_t size = r->file->size();
        r->layout = trk::scan(r->file->data(), size, r->header, [task, size](std::uint64_t pos) {
            if (pos > 0 && size > 0) hz::report(task, std::min(1.0, double(pos) / double(size)), "scanning TRK");
            return hz::cancelled(task);
        });
        hz::report(task, 1.0, nullptr);
        for (const auto &w : r->header.warnings) log(HZ_LOG_WARN, r->path + ": " + w);
        *out = reinterpret_cast<hz_reader *>(r.release());
        return HZ_OK;
    });
}

hz_status HZ_ABI open(const hz_open_request *req, hz_reader **out, hz_error *err) { return open_with(req, nullptr, out, err); }
hz_status HZ_ABI open_task(const hz_open_request *req, const hz_task *task, hz_reader **out, hz_error *err) {
    return open_with(req, task, out, err);
}

// Extra arrays: one per scalar column group (per vertex), then one per
// property column group (per streamline).
std::size_t nb_arrays(const Reader &r) { return r.header.scalars.size() + r.header.properties.size(); }

hz_status HZ_ABI get_info(hz_reader *reader, hz_dataset_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_dataset_info))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trk: get_info: bad arguments");
    const Reader &r = *as_reader(reader);
    out->kind = HZ_DATA_STREAMLINES;
    std::snprintf(out->format, sizeof out->format, "trk v%d %s%s", r.header.version, r.header.voxel_order.c_str(),
                  r.header.swap ? " swapped" : "");
    out->nb_streamlines = r.layout.nb_streamlines;
    out->nb_vertices = r.layout.nb_vertices;
    std::copy(r.header.vox_to_ras.begin(), r.header.vox_to_ras.end(), out->voxel_to_ras);
    for (int i = 0; i < 3; ++i) out->ref_dims[i] = static_cast<uint64_t>(r.header.dim[i]);
    out->source_space = HZ_SPACE_VOXMM;
    out->nb_arrays = static_cast<uint32_t>(nb_arrays(r));
    return HZ_OK;
}

hz_status HZ_ABI get_array_info(hz_reader *reader, uint32_t index, hz_array_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trk: get_array_info: NULL");
    const Reader &r = *as_reader(reader);
    if (index >= nb_arrays(r)) return hz::set_errorf(err, HZ_E_NOT_FOUND, "trk: %s: no extra array %u", r.path.c_str(), index);
    const bool scalar = index < r.header.scalars.size();
    const trk::Column &c = scalar ? r.header.scalars[index] : r.header.properties[index - r.header.scalars.size()];
    out->attach = scalar ? HZ_ATTACH_VERTEX : HZ_ATTACH_STREAMLINE;
    out->name = c.name.c_str();
    out->dtype = HZ_DTYPE_F32;
    out->components = c.count;
    out->count = scalar ? r.layout.nb_vertices : r.layout.nb_streamlines;
    return HZ_OK;
}

hz_status HZ_ABI visit_metadata(hz_reader *reader, hz_metadata_visitor visitor, void *ctx, hz_error *err) {
    if (reader == nullptr || visitor == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trk: visit_metadata: NULL");
    const trk::Header &h = as_reader(reader)->header;
    char buf[128];
    visitor(ctx, "version", std::to_string(h.version).c_str());
    std::snprintf(buf, sizeof buf, "%d %d %d", h.dim[0], h.dim[1], h.dim[2]);
    visitor(ctx, "dimensions", buf);
    std::snprintf(buf, sizeof buf, "%g %g %g", h.voxel_size[0], h.voxel_size[1], h.voxel_size[2]);
    visitor(ctx, "voxel_sizes", buf);
    visitor(ctx, "voxel_order", h.voxel_order.c_str());
    visitor(ctx, "n_count", std::to_string(h.n_count).c_str());
    visitor(ctx, "byte_order", h.swap ? "swapped" : "native");
    return HZ_OK;
}

// Decodes every streamline into the host's buffers; with `check`
// (HZ_EXT_CHECKED_READ), vouches for what it wrote.
hz_status read_into(hz_reader *reader, const hz_streamlines_dst *dst, hz_positions_check *check, const hz_task *task, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trk: read_streamlines: NULL");
    Reader &r = *as_reader(reader);
    if (dst->positions_capacity < 3 * r.layout.nb_vertices || dst->offsets_capacity < r.layout.nb_streamlines + 1)
        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "trk: %s: destination too small", r.path.c_str());
    if ((dst->positions == nullptr && r.layout.nb_vertices > 0) || dst->offsets == nullptr)
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "trk: %s: NULL destination", r.path.c_str());
    return run(err, r.path, [&]() -> hz_status {
        if (hz::cancelled(task)) throw trk::Cancelled{};
        // Scalars and properties come along in the same pass.
        r.scalars.resize(r.layout.nb_vertices * r.header.n_scalars);
        r.properties.resize(r.layout.nb_streamlines * r.header.n_properties);
        trk::Box box;
        trk::decode(r.file->data(), r.file->size(), r.header, r.layout, dst->positions, dst->offsets,
                    r.scalars.empty() ? nullptr : r.scalars.data(), r.properties.empty() ? nullptr : r.properties.data(),
                    tick(task, r.layout.nb_vertices), release(*r.file), &box);
        r.extras_decoded = true;
        // decode() rejected every non-finite input coordinate and found the
        // bounds of what it wrote; the host need not read the copy again
        // unless a transformed coordinate overflowed float32 (then it reports it).
        if (check != nullptr && check->struct_size < sizeof(hz_positions_check)) check = nullptr;
        bool finite = r.layout.nb_vertices > 0;
        for (int d = 0; d < 3; ++d) finite = finite && std::isfinite(box.lo[d]) && std::isfinite(box.hi[d]) && box.lo[d] <= box.hi[d];
        if (check != nullptr && finite) {
            check->vouched = 1;
            for (int d = 0; d < 3; ++d) {
                check->bounds_min[d] = box.lo[d];
                check->bounds_max[d] = box.hi[d];
            }
        }
        hz::report(task, 1.0);
        return HZ_OK;
    });
}

hz_status HZ_ABI read_streamlines(hz_reader *reader, const hz_streamlines_dst *dst, const hz_task *task, hz_error *err) {
    return read_into(reader, dst, nullptr, task, err);
}

// HZ_EXT_CHECKED_READ.
hz_status HZ_ABI read_streamlines_checked(hz_reader *reader, const hz_streamlines_dst *dst, hz_positions_check *check, const hz_task *task,
                                          hz_error *err) {
    if (check == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trk: read_streamlines_checked: NULL check");
    return read_into(reader, dst, check, task, err);
}

hz_status HZ_ABI read_array(hz_reader *reader, uint32_t index, const hz_array_view *dst, const hz_task *task, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trk: read_array: NULL");
    Reader &r = *as_reader(reader);
    if (index >= nb_arrays(r)) return hz::set_errorf(err, HZ_E_NOT_FOUND, "trk: %s: no extra array %u", r.path.c_str(), index);
    return run(err, r.path, [&]() -> hz_status {
        if (!r.extras_decoded) {
            r.scalars.resize(r.layout.nb_vertices * r.header.n_scalars);
            r.properties.resize(r.layout.nb_streamlines * r.header.n_properties);
            trk::decode(r.file->data(), r.file->size(), r.header, r.layout, nullptr, nullptr,
                        r.scalars.empty() ? nullptr : r.scalars.data(), r.properties.empty() ? nullptr : r.properties.data(),
                        tick(task, r.layout.nb_vertices), release(*r.file));
            r.extras_decoded = true;
        }
        const bool scalar = index < r.header.scalars.size();
        const auto &cols = scalar ? r.header.scalars : r.header.properties;
        const std::size_t which = scalar ? index : index - r.header.scalars.size();
        std::uint32_t first = 0;
        for (std::size_t k = 0; k < which; ++k) first += cols[k].count;
        const std::uint32_t width = scalar ? r.header.n_scalars : r.header.n_properties, comps = cols[which].count;
        const std::uint64_t rows = scalar ? r.layout.nb_vertices : r.layout.nb_streamlines;
        const std::vector<float> &src = scalar ? r.scalars : r.properties;
        if (dst->dtype != HZ_DTYPE_F32 || dst->ndim != 2 || dst->shape[0] != rows || dst->shape[1] != comps)
            throw trk::FormatError("read_array: destination must be float32 [" + std::to_string(rows) + ", " + std::to_string(comps) + "]");
        for (std::uint64_t i = 0; i < rows; ++i)
            for (std::uint32_t c = 0; c < comps; ++c) {
                unsigned char *cell = hz::view_cell(*dst, i, c, 4);
                if (cell == nullptr)
                    return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "trk: %s: read_array: destination too small", r.path.c_str());
                std::memcpy(cell, &src[i * width + first + c], 4);
            }
        return HZ_OK;
    });
}

void HZ_ABI close(hz_reader *reader) { delete as_reader(reader); }

// Converts one extra array to float32 columns for the TRK body.
bool to_float_columns(const hz_named_array &a, std::vector<float> &out) {
    const std::uint64_t n = a.count * a.components;
    out.resize(n);
    auto conv = [&](auto tag) {
        using T = decltype(tag);
        const T *p = static_cast<const T *>(a.data);
        for (std::uint64_t i = 0; i < n; ++i) out[i] = static_cast<float>(p[i]);
    };
    switch (a.dtype) {
    case HZ_DTYPE_F32: conv(float{}); return true;
    case HZ_DTYPE_F64: conv(double{}); return true;
    case HZ_DTYPE_U8: conv(std::uint8_t{}); return true;
    case HZ_DTYPE_I8: conv(std::int8_t{}); return true;
    case HZ_DTYPE_U16: conv(std::uint16_t{}); return true;
    case HZ_DTYPE_I16: conv(std::int16_t{}); return true;
    case HZ_DTYPE_U32: conv(std::uint32_t{}); return true;
    case HZ_DTYPE_I32: conv(std::int32_t{}); return true;
    case HZ_DTYPE_I64: conv(std::int64_t{}); return true;
    case HZ_DTYPE_U64: conv(std::uint64_t{}); return true;
    default: return false;
    }
}

// write() of all the streamlines, or (hz.ext.write-selection/1) of `selection` only.
hz_status write_some(const hz_write_request *req, const hz_dataset_view *data, const std::uint64_t *selection, std::uint64_t nb_selected,
                     hz_error *err) {
    if (req == nullptr || req->path == nullptr || data == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trk: write: NULL request or data");
    if (data->kind != HZ_DATA_STREAMLINES) return hz::set_errorf(err, HZ_E_UNSUPPORTED, "trk: %s: TRK holds streamlines only", req->path);
    if (data->streamlines.gap > 1)
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "trk: %s: streamlines with gap %u (0 or 1 expected)", req->path,
                              data->streamlines.gap);
    return run(err, req->path, [&]() -> hz_status {
        const hz_streamlines_view &s = data->streamlines;
        trk::WriteSpec spec;
        spec.gap = s.gap;  // (HZ_EXT_DELIMITED_STREAMLINES: a mapped TCK's delimiters are skipped)
        spec.selection = selection;
        spec.nb_selected = nb_selected;
        const std::uint64_t nb_written = selection != nullptr ? nb_selected : s.nb_streamlines;  // (the property rows)
        std::copy(data->voxel_to_ras, data->voxel_to_ras + 16, spec.vox_to_ras.begin());
        if (spec.vox_to_ras[15] == 0) spec.vox_to_ras = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        std::copy(data->ref_dims, data->ref_dims + 3, spec.dims.begin());
        // Per-vertex arrays become scalars, per-streamline ones properties,
        // interleaved column by column; what does not fit is reported.
        std::vector<std::vector<float>> sc, pr;
        for (uint32_t i = 0; i < data->nb_arrays; ++i) {
            const hz_named_array &a = data->arrays[i];
            const std::string name = a.name ? a.name : "";
            const bool vertex = a.attach == HZ_ATTACH_VERTEX && a.count == s.nb_vertices;
            const bool streamline = a.attach == HZ_ATTACH_STREAMLINE && a.count == nb_written;
            auto &cols = vertex ? spec.scalars : spec.properties;
            std::vector<float> f;
            const bool fits = (vertex || streamline) && cols.size() < 10 && !name.empty() &&
                              name.size() + (a.components > 1 ? 1 + std::to_string(a.components).size() : 0) <= 20 &&
                              name.find('\0') == std::string::npos && to_float_columns(a, f);
            if (!fits) {
                if (req->on_dropped)
                    req->on_dropped(req->ctx,
                                    ("array '" + name + "' (TRK holds at most 10 float32 scalars/properties named in 20 bytes)").c_str());
                continue;
            }
            cols.push_back({name, a.components});
            (vertex ? sc : pr).push_back(std::move(f));
        }
        auto interleave = [](const std::vector<trk::Column> &cols, const std::vector<std::vector<float>> &data, std::uint64_t rows) {
            std::uint32_t width = 0;
            for (const auto &c : cols) width += c.count;
            std::vector<float> out(rows * width);
            std::uint32_t first = 0;
            for (std::size_t k = 0; k < cols.size(); ++k) {
                for (std::uint64_t r = 0; r < rows; ++r)
                    for (std::uint32_t c = 0; c < cols[k].count; ++c) out[r * width + first + c] = data[k][r * cols[k].count + c];
                first += cols[k].count;
            }
            return out;
        };
        const std::vector<float> scal = interleave(spec.scalars, sc, s.nb_vertices);
        const std::vector<float> prop = interleave(spec.properties, pr, nb_written);
        spec.scalar_data = scal.data();
        spec.property_data = prop.data();
        for (uint32_t i = 0; i < data->nb_metadata && req->on_dropped; ++i) {
            const std::string k = data->metadata[i].key ? data->metadata[i].key : "";
            // TRK's own fields, and TCK's structural keys (meaningless once read, as the TRX writer treats them).
            static const char *own[] = {"version",    "dimensions", "voxel_sizes", "voxel_order", "n_count",
                                        "byte_order", "count",      "datatype",    "file"};
            if (std::find(std::begin(own), std::end(own), k) == std::end(own))
                req->on_dropped(req->ctx, ("header entry '" + k + "'").c_str());
        }
        const std::uint64_t empty = trk::write(req->path, s.positions, s.nb_vertices, s.offsets, s.nb_streamlines, spec);
        if (empty > 0 && req->on_dropped)
            req->on_dropped(req->ctx, (std::to_string(empty) + " streamline" + (empty == 1 ? "" : "s") +
                                       " without points (TRK readers cannot read them)")
                                          .c_str());
        return HZ_OK;
    });
}

constexpr char kPrefix[] = "trk";
using Writer = hz::selective_writer<write_some, kPrefix>;

const char *const kExtensions[] = {"trk", nullptr};
const hz_loader kLoader = {
    .struct_size = sizeof(hz_loader),
    .data_kinds = HZ_DATA_STREAMLINES,
    .caps = HZ_LOADER_CAN_READ | HZ_LOADER_CAN_WRITE,
    .probe_bytes = 1000,
    .extensions = kExtensions,
    .probe = probe,
    .open = open,
    .get_info = get_info,
    .get_array_info = get_array_info,
    .visit_metadata = visit_metadata,
    .read_streamlines = read_streamlines,
    .read_array = read_array,
    .read_volume = nullptr,
    .read_mesh = nullptr,
    .close = close,
    .write = Writer::write,
    .locate_positions = nullptr,  // (1.4-1.9, kept for source compatibility; the extensions below read in place)
};

// Extensions (hz_extensions.h): the decode vouches for what it wrote; a
// mapped TCK is written without a copy.
using Checked = hz::checked_read<read_streamlines_checked>;
using OpenTask = hz::open_task<open_task>;
using WriteSelection = hz::write_selection<Writer::write_selection>;

const char *const kInterfaces[] = {HZ_INTERFACE_LOADER, HZ_EXT_CHECKED_READ,    HZ_EXT_DELIMITED_STREAMLINES,
                                   HZ_EXT_OPEN_TASK,    HZ_EXT_WRITE_SELECTION, nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "TrackVis TRK",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "TrackVis .trk v1/v2, both byte orders, scalars and properties; read and write in RAS+ mm",
    .license = "MIT",
    .interfaces = kInterfaces,
};

using Plugin = hz::single_plugin<kDescriptor, kLoader, Checked::ext, hz::delimited_streamlines, OpenTask::ext, WriteSelection::ext>;
const hz_host *host() { return Plugin::host(); }

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = Plugin::entry;
