// hz.loader/1 adapter for TRX (trx_format.hpp).
#include "trx_format.hpp"

#include <hz/cpp/loader.hpp>

#include <algorithm>
#include <cstring>
#include <memory>

namespace {

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

const char *const kExtensions[] = {"trx", nullptr};

// The format, as hz::loader<Trx> (hz/cpp/loader.hpp) wants it: the adapter
// checks every argument and capacity, turns the exceptions into statuses
// (std::exception as I/O: the directory form reports file-system errors
// that way), and serves the extensions this class supports (stored
// positions mapped in place; a mapped TCK, and the streamlines kept of any
// tractogram, written without a copy).
struct Trx {
    static constexpr const char *prefix = "trx";
    static constexpr hz_data_kind kinds = HZ_DATA_STREAMLINES;
    static constexpr uint32_t probe_bytes = 4096;
    static constexpr const char *const *extensions = kExtensions;
    static constexpr uint32_t max_gap = 1;
    using FormatError = trx::FormatError;
    using IoError = std::exception;
    using Cancelled = trx::Cancelled;

    static int32_t probe(const uint8_t *head, uint64_t size, const char *) noexcept { return trx::probe(head, size); }

    struct Reader {
        trx::File file;
        trx::Extent extent;  // locate_positions' answer; its file name is handed out
    };

    static std::unique_ptr<Reader> open(const std::string &path, const hz_task *task) {
        auto r = std::make_unique<Reader>();
        r->file = trx::open(path);
        hz::report(task, 1.0);
        return r;
    }

    static void info(const Reader &r, hz_dataset_info &out) {
        const trx::File &f = r.file;
        out.kind = HZ_DATA_STREAMLINES;
        std::snprintf(out.format, sizeof out.format, "trx %s %s", f.container_kind.c_str(), trx::dtype_name(f.positions_dtype));
        out.nb_streamlines = f.nb_streamlines;
        out.nb_vertices = f.nb_vertices;
        std::copy(f.voxel_to_rasmm.begin(), f.voxel_to_rasmm.end(), out.voxel_to_ras);
        std::copy(f.dims.begin(), f.dims.end(), out.ref_dims);
        out.source_space = HZ_SPACE_RASMM;
        out.nb_arrays = static_cast<uint32_t>(f.arrays.size());
    }

    static void array_info(const Reader &r, uint32_t index, hz_array_info &out) {
        const trx::Array &a = r.file.arrays[index];
        static const hz_attach attach[] = {HZ_ATTACH_VERTEX, HZ_ATTACH_STREAMLINE, HZ_ATTACH_GROUP, HZ_ATTACH_GROUP_DATA};
        out.attach = attach[static_cast<int>(a.kind)];
        out.name = a.name.c_str();
        out.dtype = to_hz(a.dtype);
        out.components = a.cols;
        out.count = a.rows;
    }

    static void metadata(const Reader &r, hz_metadata_visitor visit, void *ctx) {
        for (const auto &[k, v] : r.file.header_extra) visit(ctx, k.c_str(), v.c_str());
    }

    static void read_streamlines(Reader &r, float *positions, uint64_t *offsets, const hz_task *task) {
        trx::read_streamlines(r.file, positions, offsets, [task] { return hz::cancelled(task); });
        hz::report(task, 1.0);
    }

    // Array `index` as described (float16 widened to float32), dense.
    static void read_array(const Reader &r, uint32_t index, void *dense, const hz_task *) {
        const trx::Array &a = r.file.arrays[index];
        if (a.dtype != trx::DType::F16) {
            trx::read_array(r.file, a, dense);
            return;
        }
        std::vector<std::uint16_t> raw(a.rows * a.cols);
        trx::read_array(r.file, a, raw.data());
        float *out = static_cast<float *>(dense);
        for (std::size_t k = 0; k < raw.size(); ++k) out[k] = trx::half_to_float(raw[k]);
    }

    // A stored (uncompressed) float32 positions entry, or a directory's
    // positions file, is mapped by the host as it is.
    static bool locate_positions(Reader &r, hz_positions_extent &out) {
        r.extent = trx::Extent{};
        if (!trx::locate_positions(r.file, r.extent)) return false;
        out.path = r.extent.file.c_str();
        out.offset = r.extent.offset;
        out.flags = r.extent.has_crc ? HZ_EXTENT_HAS_CRC32 : 0;
        out.crc32 = r.extent.crc;
        return true;
    }
    // The offsets alone (those of the plain layout).
    static void read_offsets(Reader &r, uint64_t *offsets, const hz_task *task) {
        trx::read_streamlines(r.file, nullptr, offsets, [task] { return hz::cancelled(task); });
    }

    // Writes every streamline (selection NULL) or the selected ones, with
    // the arrays TRX can hold; what it cannot is reported.
    static void write_selection(const hz_write_request &req, const hz_dataset_view &data, const std::uint64_t *selection,
                                std::uint64_t nb_selected, const hz_task *) {
        const hz_streamlines_view &s = data.streamlines;
        const std::uint64_t nb_written = selection != nullptr ? nb_selected : s.nb_streamlines;  // (the dps rows)
        std::vector<trx::WriteArray> arrays;
        std::vector<std::vector<std::uint32_t>> narrowed;  // uint64 groups stored as uint32
        narrowed.reserve(data.nb_arrays);
        for (uint32_t i = 0; i < data.nb_arrays; ++i) {
            const hz_named_array &a = data.arrays[i];
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
                if (req.on_dropped) req.on_dropped(req.ctx, ("array '" + name + "' (not representable in TRX)").c_str());
                continue;
            }
            arrays.push_back(w);
        }
        std::array<double, 16> aff;
        std::copy(data.voxel_to_ras, data.voxel_to_ras + 16, aff.begin());
        if (aff[15] == 0) aff = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        std::array<std::uint64_t, 3> dims;
        std::copy(data.ref_dims, data.ref_dims + 3, dims.begin());
        std::vector<std::pair<std::string, std::string>> extra;
        for (uint32_t i = 0; i < data.nb_metadata; ++i)
            if (data.metadata[i].key && data.metadata[i].value) {
                const std::string k = data.metadata[i].key;
                // TRX's own keys, and TCK's structural ones (meaningless once read).
                if (k == "NB_STREAMLINES" || k == "NB_VERTICES" || k == "VOXEL_TO_RASMM" || k == "DIMENSIONS" || k == "file" ||
                    k == "datatype" || k == "count")
                    continue;
                auto it = std::find_if(extra.begin(), extra.end(), [&](const auto &e) { return e.first == k; });
                if (it != extra.end()) {  // repeated keys are joined by newlines
                    it->second.push_back('\n');
                    it->second.append(data.metadata[i].value);
                } else {
                    extra.emplace_back(k, data.metadata[i].value);
                }
            }
        trx::write(req.path, s.positions, s.nb_vertices, s.offsets, s.nb_streamlines, aff, dims, arrays, extra, s.gap, selection,
                   nb_selected);
    }
};

const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = "org.horizon.loader.trx",
    .name = "TRX",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "TRX tractograms: zip (stored/deflated) and directory forms, dpv/dps/groups/dpg; writes stored zips",
    .license = "MIT",
    .interfaces = hz::loader<Trx>::interfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::loader_plugin<kDescriptor, Trx>::entry;
