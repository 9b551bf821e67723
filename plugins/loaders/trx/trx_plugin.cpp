// hz.loader/1 adapter for TRX (trx_format.hpp).
#include "trx_format.hpp"

#include <hz/cpp/plugin.hpp>

#include <algorithm>
#include <cstring>
#include <memory>

namespace {

constexpr const char *kId = "org.horizon.loader.trx";

struct Reader {
    std::string path;
    trx::File file;
    trx::Extent extent;  // locate_positions' answer; its file name is handed out
    bool located = false;
};
Reader *as_reader(hz_reader *r) { return reinterpret_cast<Reader *>(r); }

// std::exception as I/O: the directory form reports file-system errors that way.
template <class F>
hz_status run(hz_error *err, const std::string &path, F &&body) {
    return hz::format_guard<trx::FormatError, std::exception, trx::Cancelled>(err, "trx", path, body);
}

hz_dtype to_hz(trx::DType t) {
    switch (t) {
    case trx::DType::I8: return HZ_DTYPE_I8;
    case trx::DType::I16: return HZ_DTYPE_I16;
    case trx::DType::I32: return HZ_DTYPE_I32;
    case trx::DType::I64: return HZ_DTYPE_I64;
    case trx::DType::U8:
    case trx::DType::Bit: return HZ_DTYPE_U8;
    case trx::DType::U16: return HZ_DTYPE_U16;
    case trx::DType::U32: return HZ_DTYPE_U32;
    case trx::DType::U64: return HZ_DTYPE_U64;
    case trx::DType::F16:
    case trx::DType::F32: return HZ_DTYPE_F32;  // float16 is widened
    case trx::DType::F64: return HZ_DTYPE_F64;
    }
    return HZ_DTYPE_UNKNOWN;
}
bool from_hz(hz_dtype t, trx::DType &out) {
    switch (t) {
    case HZ_DTYPE_I8: out = trx::DType::I8; return true;
    case HZ_DTYPE_I16: out = trx::DType::I16; return true;
    case HZ_DTYPE_I32: out = trx::DType::I32; return true;
    case HZ_DTYPE_I64: out = trx::DType::I64; return true;
    case HZ_DTYPE_U8: out = trx::DType::U8; return true;
    case HZ_DTYPE_U16: out = trx::DType::U16; return true;
    case HZ_DTYPE_U32: out = trx::DType::U32; return true;
    case HZ_DTYPE_U64: out = trx::DType::U64; return true;
    case HZ_DTYPE_F32: out = trx::DType::F32; return true;
    case HZ_DTYPE_F64: out = trx::DType::F64; return true;
    default: return false;
    }
}

int32_t HZ_ABI probe(const uint8_t *head, uint64_t size, const char *) { return trx::probe(head, size); }

hz_status HZ_ABI open(const hz_open_request *req, hz_reader **out, hz_error *err) {
    if (out != nullptr) *out = nullptr;
    if (req == nullptr || req->path == nullptr || out == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: open: NULL request, path or output");
    return run(err, req->path, [&]() -> hz_status {
        auto r = std::make_unique<Reader>();
        r->path = req->path;
        r->file = trx::open(r->path);
        *out = reinterpret_cast<hz_reader *>(r.release());
        return HZ_OK;
    });
}

hz_status HZ_ABI get_info(hz_reader *reader, hz_dataset_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_dataset_info))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: get_info: bad arguments");
    const trx::File &f = as_reader(reader)->file;
    out->kind = HZ_DATA_STREAMLINES;
    std::snprintf(out->format, sizeof out->format, "trx %s %s", f.container_kind.c_str(), trx::dtype_name(f.positions_dtype));
    out->nb_streamlines = f.nb_streamlines;
    out->nb_vertices = f.nb_vertices;
    std::copy(f.voxel_to_rasmm.begin(), f.voxel_to_rasmm.end(), out->voxel_to_ras);
    std::copy(f.dims.begin(), f.dims.end(), out->ref_dims);
    out->source_space = HZ_SPACE_RASMM;
    out->nb_arrays = static_cast<uint32_t>(f.arrays.size());
    return HZ_OK;
}

hz_status HZ_ABI get_array_info(hz_reader *reader, uint32_t index, hz_array_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: get_array_info: NULL");
    const Reader &r = *as_reader(reader);
    if (index >= r.file.arrays.size()) return hz::set_errorf(err, HZ_E_NOT_FOUND, "trx: %s: no extra array %u", r.path.c_str(), index);
    const trx::Array &a = r.file.arrays[index];
    static const hz_attach attach[] = {HZ_ATTACH_VERTEX, HZ_ATTACH_STREAMLINE, HZ_ATTACH_GROUP, HZ_ATTACH_GROUP_DATA};
    out->attach = attach[static_cast<int>(a.kind)];
    out->name = a.name.c_str();
    out->dtype = to_hz(a.dtype);
    out->components = a.cols;
    out->count = a.rows;
    return HZ_OK;
}

hz_status HZ_ABI visit_metadata(hz_reader *reader, hz_metadata_visitor visitor, void *ctx, hz_error *err) {
    if (reader == nullptr || visitor == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: visit_metadata: NULL");
    for (const auto &[k, v] : as_reader(reader)->file.header_extra) visitor(ctx, k.c_str(), v.c_str());
    return HZ_OK;
}

hz_status HZ_ABI read_streamlines(hz_reader *reader, const hz_streamlines_dst *dst, const hz_task *task, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: read_streamlines: NULL");
    Reader &r = *as_reader(reader);
    const trx::File &f = r.file;
    if (dst->positions_capacity < 3 * f.nb_vertices || dst->offsets_capacity < f.nb_streamlines + 1)
        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "trx: %s: destination too small", r.path.c_str());
    if ((dst->positions == nullptr && f.nb_vertices > 0) || dst->offsets == nullptr)
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "trx: %s: NULL destination", r.path.c_str());
    return run(err, r.path, [&]() -> hz_status {
        trx::read_streamlines(f, dst->positions, dst->offsets, [task] { return hz::cancelled(task); });
        hz::report(task, 1.0);
        return HZ_OK;
    });
}

hz_status HZ_ABI read_array(hz_reader *reader, uint32_t index, const hz_array_view *dst, const hz_task *, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: read_array: NULL");
    Reader &r = *as_reader(reader);
    if (index >= r.file.arrays.size()) return hz::set_errorf(err, HZ_E_NOT_FOUND, "trx: %s: no extra array %u", r.path.c_str(), index);
    const trx::Array &a = r.file.arrays[index];
    return run(err, r.path, [&]() -> hz_status {
        const std::size_t es_in = trx::dtype_size(a.dtype), es_out = a.dtype == trx::DType::F16 ? 4 : es_in;
        if (dst->dtype != to_hz(a.dtype) || dst->ndim != 2 || dst->shape[0] != a.rows || dst->shape[1] != a.cols)
            throw trx::FormatError("read_array: destination shape or dtype does not match '" + a.name + "'");
        std::vector<unsigned char> raw(a.rows * a.cols * es_in);
        trx::read_array(r.file, a, raw.data());
        for (std::uint64_t i = 0; i < a.rows; ++i)
            for (std::uint32_t c = 0; c < a.cols; ++c) {
                unsigned char *cell = hz::view_cell(*dst, i, c, es_out);
                if (cell == nullptr)
                    return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "trx: %s: read_array: destination too small", r.path.c_str());
                const unsigned char *src = raw.data() + (i * a.cols + c) * es_in;
                if (a.dtype == trx::DType::F16) {
                    std::uint16_t hbits;
                    std::memcpy(&hbits, src, 2);
                    const float v = trx::half_to_float(hbits);
                    std::memcpy(cell, &v, 4);
                } else {
                    std::memcpy(cell, src, es_in);
                }
            }
        return HZ_OK;
    });
}

void HZ_ABI close(hz_reader *reader) { delete as_reader(reader); }

// HZ_EXT_MAPPED_POSITIONS: a stored (uncompressed) float32 positions entry,
// or a directory's positions file, is mapped by the host as it is.
hz_status HZ_ABI locate_positions(hz_reader *reader, hz_positions_extent *out, hz_error *err) {
    if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_positions_extent))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: locate_positions: bad arguments");
    Reader &r = *as_reader(reader);
    return run(err, r.path, [&]() -> hz_status {
        r.extent = trx::Extent{};
        r.located = false;
        if (!trx::locate_positions(r.file, r.extent)) return HZ_E_UNSUPPORTED;
        out->path = r.extent.file.c_str();
        out->offset = r.extent.offset;
        out->flags = r.extent.has_crc ? HZ_EXTENT_HAS_CRC32 : 0;
        out->crc32 = r.extent.crc;
        r.located = true;
        return HZ_OK;
    });
}

// HZ_EXT_MAPPED_POSITIONS: the offsets alone (those of the plain layout).
hz_status HZ_ABI read_offsets(hz_reader *reader, uint64_t *offsets, uint64_t capacity, const hz_task *task, hz_error *err) {
    if (reader == nullptr || offsets == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: read_offsets: NULL");
    Reader &r = *as_reader(reader);
    if (!r.located) return hz::set_errorf(err, HZ_E_BAD_STATE, "trx: %s: read_offsets before locate_positions", r.path.c_str());
    if (capacity < r.file.nb_streamlines + 1)
        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "trx: %s: destination too small", r.path.c_str());
    return run(err, r.path, [&]() -> hz_status {
        trx::read_streamlines(r.file, nullptr, offsets, [task] { return hz::cancelled(task); });
        return HZ_OK;
    });
}

// write() of all the streamlines, or (hz.ext.write-selection/1) of `selection` only.
hz_status write_some(const hz_write_request *req, const hz_dataset_view *data, const std::uint64_t *selection, std::uint64_t nb_selected,
                     hz_error *err) {
    if (req == nullptr || req->path == nullptr || data == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "trx: write: NULL request or data");
    if (data->kind != HZ_DATA_STREAMLINES) return hz::set_errorf(err, HZ_E_UNSUPPORTED, "trx: %s: TRX holds streamlines only", req->path);
    return run(err, req->path, [&]() -> hz_status {
        const hz_streamlines_view &s = data->streamlines;
        const std::uint64_t nb_written = selection != nullptr ? nb_selected : s.nb_streamlines;  // (the dps rows)
        std::vector<trx::WriteArray> arrays;
        std::vector<std::vector<std::uint32_t>> narrowed;  // uint64 groups stored as uint32
        narrowed.reserve(data->nb_arrays);
        for (uint32_t i = 0; i < data->nb_arrays; ++i) {
            const hz_named_array &a = data->arrays[i];
            const std::string name = a.name ? a.name : "";
            trx::WriteArray w{trx::Kind::Dpv, name, trx::DType::F32, a.components, a.count, a.data};
            bool ok = !name.empty() && name.find('.') == std::string::npos && from_hz(a.dtype, w.dtype);
            switch (a.attach) {
            case HZ_ATTACH_VERTEX: ok = ok && a.count == s.nb_vertices && name.find('/') == std::string::npos; break;
            case HZ_ATTACH_STREAMLINE:
                w.kind = trx::Kind::Dps;
                ok = ok && a.count == nb_written && name.find('/') == std::string::npos;
                break;
            case HZ_ATTACH_GROUP:
                w.kind = trx::Kind::Group;
                ok = ok && a.components == 1 && name.find('/') == std::string::npos && (a.dtype == HZ_DTYPE_U32 || a.dtype == HZ_DTYPE_U64);
                if (ok && a.dtype == HZ_DTYPE_U64) {
                    const auto *p = static_cast<const std::uint64_t *>(a.data);
                    auto &v = narrowed.emplace_back(a.count);
                    for (std::uint64_t k = 0; k < a.count; ++k) v[k] = static_cast<std::uint32_t>(p[k]);
                    w.data = v.data();
                    w.dtype = trx::DType::U32;
                }
                break;
            case HZ_ATTACH_GROUP_DATA:
                w.kind = trx::Kind::Dpg;
                ok = ok && a.count == 1 && std::count(name.begin(), name.end(), '/') == 1;
                break;
            default: ok = false;
            }
            if (!ok) {
                if (req->on_dropped) req->on_dropped(req->ctx, ("array '" + name + "' (not representable in TRX)").c_str());
                continue;
            }
            arrays.push_back(w);
        }
        std::array<double, 16> aff;
        std::copy(data->voxel_to_ras, data->voxel_to_ras + 16, aff.begin());
        if (aff[15] == 0) aff = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        std::array<std::uint64_t, 3> dims;
        std::copy(data->ref_dims, data->ref_dims + 3, dims.begin());
        std::vector<std::pair<std::string, std::string>> extra;
        for (uint32_t i = 0; i < data->nb_metadata; ++i)
            if (data->metadata[i].key && data->metadata[i].value) {
                const std::string k = data->metadata[i].key;
                // TRX's own keys, and TCK's structural ones (meaningless once read).
                if (k == "NB_STREAMLINES" || k == "NB_VERTICES" || k == "VOXEL_TO_RASMM" || k == "DIMENSIONS" || k == "file" ||
                    k == "datatype" || k == "count")
                    continue;
                auto it = std::find_if(extra.begin(), extra.end(), [&](const auto &e) { return e.first == k; });
                if (it != extra.end()) {  // repeated keys are joined by newlines
                    it->second.push_back('\n');
                    it->second.append(data->metadata[i].value);
                } else {
                    extra.emplace_back(k, data->metadata[i].value);
                }
            }
        trx::write(req->path, s.positions, s.nb_vertices, s.offsets, s.nb_streamlines, aff, dims, arrays, extra, s.gap, selection,
                   nb_selected);
        return HZ_OK;
    });
}

constexpr char kPrefix[] = "trx";
using Writer = hz::selective_writer<write_some, kPrefix>;

const char *const kExtensions[] = {"trx", nullptr};
const hz_loader kLoader = {
    .struct_size = sizeof(hz_loader),
    .data_kinds = HZ_DATA_STREAMLINES,
    .caps = HZ_LOADER_CAN_READ | HZ_LOADER_CAN_WRITE,
    .probe_bytes = 4096,
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

// Extensions (hz_extensions.h): stored positions mapped in place; a mapped
// TCK, and the streamlines kept of any tractogram, written without a copy.
using Mapped = hz::mapped_positions<locate_positions, read_offsets>;
using WriteSelection = hz::write_selection<Writer::write_selection>;

const char *const kInterfaces[] = {HZ_INTERFACE_LOADER, HZ_EXT_MAPPED_POSITIONS, HZ_EXT_DELIMITED_STREAMLINES, HZ_EXT_WRITE_SELECTION,
                                   nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "TRX",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "TRX tractograms: zip (stored/deflated) and directory forms, dpv/dps/groups/dpg; writes stored zips",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader, Mapped::ext, hz::delimited_streamlines, WriteSelection::ext>::entry;
