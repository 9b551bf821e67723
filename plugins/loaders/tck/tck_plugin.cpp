// hz.loader/1 adapter for the MRtrix TCK format (tck_format.hpp).
#include "tck_format.hpp"
#include "mapped_file.hpp"
#include "parallel.hpp"

#include <hz/cpp/plugin.hpp>

#include <bit>
#include <cstring>
#include <memory>

namespace {

#if defined(TCK_FIXTURE_LYING_BOUNDS)  // tests/fixtures: the same loader vouching for bounds 1 mm too wide in x (mapped or copied)
constexpr const char *kId = "org.horizon.test.tck-lying-bounds";
#elif defined(TCK_FIXTURE_IGNORES_SIZES)        // tests/fixtures: vouching through `check` whatever its struct_size
constexpr const char *kId = "org.horizon.test.tck-ignores-sizes";
#elif defined(TCK_FIXTURE_IGNORES_GAP)          // tests/fixtures: HZ_EXT_DELIMITED_STREAMLINES offered, the gap written as points
constexpr const char *kId = "org.horizon.test.tck-ignores-gap";
#elif defined(TCK_FIXTURE_UNLISTED_EXTENSIONS)  // tests/fixtures: extension tables served but not listed
constexpr const char *kId = "org.horizon.test.tck-unlisted-extensions";
#elif defined(TCK_FIXTURE_IGNORES_TASK)         // tests/fixtures: never polls its task (a small read need not)
constexpr const char *kId = "org.horizon.test.tck-ignores-task";
#else
constexpr const char *kId = "org.horizon.loader.tck";
#endif
const hz_host *host();

void log(hz_log_level lvl, const std::string &msg) { hz::log(host(), kId, lvl, msg); }

struct Reader {
    std::string path;
    std::unique_ptr<hzio::MappedFile> file;
    tck::Header header;
    tck::Layout layout;
    bool mapped = false;  // locate_positions() answered HZ_OK
};

// Runs a TCK operation, turning format errors into "tck: <path>: <what>".
template <class F>
hz_status run(hz_error *err, const std::string &path, F &&body) {
    return hz::guard(err, [&]() -> hz_status {
        try {
            return body();
        } catch (const tck::Cancelled &) {
            return hz::set_error(err, HZ_E_CANCELLED, "cancelled");
        } catch (const tck::FormatError &e) {
            return hz::set_errorf(err, e.io ? HZ_E_IO : HZ_E_FORMAT, "tck: %s: %s", path.c_str(), e.what());
        } catch (const hzio::IoError &e) {
            return hz::set_errorf(err, HZ_E_IO, "tck: %s: %s", path.c_str(), e.what());
        }
    });
}

// Whether `task` asks the call to stop (never, for the fixture that does
// not poll).
bool stop_asked(const hz_task *task) {
#ifdef TCK_FIXTURE_IGNORES_TASK
    (void)task;
    return false;
#else
    return hz::cancelled(task);
#endif
}

// Polls cancellation and drops the mapped pages already walked (peak
// memory stays near the decoded data).
tck::Tick tick(const hz_task *task, const hzio::MappedFile &file) {
    return [task, &file](std::uint64_t pos) {
        if (pos > (64u << 20)) file.release_before(pos - (32u << 20));
        return stop_asked(task);
    };
}

// Drops the mapped pages of a chunk a parallel pass is done with.
tck::Release release(const hzio::MappedFile &file) {
    return [&file](std::uint64_t begin, std::uint64_t end) { file.release(begin, end); };
}

int32_t HZ_ABI probe(const uint8_t *head, uint64_t size, const char *) { return tck::probe(head, size); }

// The scan's: tick()'s, reporting the share of the file scanned as well.
tck::Tick scan_tick(const hz_task *task, const hzio::MappedFile &file) {
    return [task, &file, inner = tick(task, file)](std::uint64_t pos) {
        if (pos > 0 && file.size() > 0) hz::report(task, std::min(1.0, double(pos) / double(file.size())), "scanning TCK");
        return inner(pos);
    };
}

// Opens and scans the file (every triple: the counts, the delimiters, the
// bounds); with a task (HZ_EXT_OPEN_TASK), reporting and cancellable.
hz_status open_with(const hz_open_request *req, const hz_task *task, hz_reader **out, hz_error *err) {
    if (out != nullptr) *out = nullptr;
    if (req == nullptr || req->path == nullptr || out == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: open: NULL request, path or output");
#ifdef TCK_FIXTURE_CRASH_ON_OPEN  // tests/fixtures: a loader that dies on every file it opens (SIGSEGV)
    *static_cast<volatile int *>(nullptr) = 1;
#endif
    return run(err, req->path, [&]() -> hz_status {
        auto r = std::make_unique<Reader>();
        r->path = req->path;
        r->file = std::make_unique<hzio::MappedFile>(r->path);
        r->header = tck::parse_header(r->file->data(), r->file->size());
        if (hz::cancelled(task)) throw tck::Cancelled{};  // (the fixture too: open-task/1 requires it)
        r->layout = tck::scan(r->file->data(), r->file->size(), r->header, scan_tick(task, *r->file), release(*r->file));
        hz::report(task, 1.0, nullptr);
        for (const auto &w : r->header.warnings) log(HZ_LOG_WARN, r->path + ": " + w);
        if (r->layout.trailing_bytes != 0)
            log(HZ_LOG_WARN, r->path + ": " + std::to_string(r->layout.trailing_bytes) + " bytes after the Inf terminator ignored");
        if (const auto count = tck::declared_count(r->header); count && *count != r->layout.nb_streamlines)
            log(HZ_LOG_WARN, r->path + ": the header says count " + std::to_string(*count) + " but the data hold " +
                                 std::to_string(r->layout.nb_streamlines) +
                                 (r->layout.nb_streamlines == 1 ? " streamline" : " streamlines") + "; reading what the data hold");
        *out = reinterpret_cast<hz_reader *>(r.release());
        return HZ_OK;
    });
}

hz_status HZ_ABI open(const hz_open_request *req, hz_reader **out, hz_error *err) { return open_with(req, nullptr, out, err); }
hz_status HZ_ABI open_task(const hz_open_request *req, const hz_task *task, hz_reader **out, hz_error *err) {
    return open_with(req, task, out, err);
}

Reader *as_reader(hz_reader *r) { return reinterpret_cast<Reader *>(r); }

hz_status HZ_ABI get_info(hz_reader *reader, hz_dataset_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: get_info: NULL");
    const Reader &r = *as_reader(reader);
    if (out->struct_size < sizeof(hz_dataset_info))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: get_info: output struct too small");
    out->kind = HZ_DATA_STREAMLINES;
    std::snprintf(out->format, sizeof out->format, "tck %s", tck::to_string(r.header.datatype));
    out->nb_streamlines = r.layout.nb_streamlines;
    out->nb_vertices = r.layout.nb_vertices;
    static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::memcpy(out->voxel_to_ras, identity, sizeof identity);
    out->source_space = HZ_SPACE_RASMM;  // TCK stores scanner RAS+ mm
    out->nb_arrays = 0;
    return HZ_OK;
}

hz_status HZ_ABI get_array_info(hz_reader *, uint32_t index, hz_array_info *, hz_error *err) {
    return hz::set_errorf(err, HZ_E_NOT_FOUND, "tck: no extra array %u (TCK holds none)", index);
}

hz_status HZ_ABI visit_metadata(hz_reader *reader, hz_metadata_visitor visitor, void *ctx, hz_error *err) {
    if (reader == nullptr || visitor == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: visit_metadata: NULL");
    for (const auto &[k, v] : as_reader(reader)->header.entries) visitor(ctx, k.c_str(), v.c_str());
    return HZ_OK;
}

// The bounds the scan found, as the loader vouches for them.
void vouch(const tck::Layout &L, double *lo, double *hi) {
    for (int d = 0; d < 3; ++d) {
        lo[d] = L.lo[d];
        hi[d] = L.hi[d];
    }
#ifdef TCK_FIXTURE_LYING_BOUNDS
    hi[0] += 1;
#endif
}

// Decodes every streamline into the host's buffers; with `check`
// (HZ_EXT_CHECKED_READ), vouches for what it wrote.
hz_status read_into(hz_reader *reader, const hz_streamlines_dst *dst, hz_positions_check *check, const hz_task *task, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: read_streamlines: NULL");
    Reader &r = *as_reader(reader);
    if ((dst->positions == nullptr && r.layout.nb_vertices > 0) || dst->offsets == nullptr)
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "tck: %s: read_streamlines: NULL destination", r.path.c_str());
    if (dst->positions_capacity < 3 * r.layout.nb_vertices || dst->offsets_capacity < r.layout.nb_streamlines + 1)
        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "tck: %s: destination holds %llu floats / %llu offsets, need %llu / %llu",
                              r.path.c_str(), (unsigned long long)dst->positions_capacity, (unsigned long long)dst->offsets_capacity,
                              (unsigned long long)(3 * r.layout.nb_vertices), (unsigned long long)(r.layout.nb_streamlines + 1));
    return run(err, r.path, [&]() -> hz_status {
        hz::report(task, 0.0, "decoding TCK");
        tck::decode(r.file->data(), r.header, r.layout, dst->positions, dst->offsets, tick(task, *r.file), release(*r.file));
        // Float32LE data are copied as they are, and the scan read every
        // coordinate (finite outside the delimiters) and found their bounds.
#ifndef TCK_FIXTURE_IGNORES_SIZES
        if (check != nullptr && check->struct_size < sizeof(hz_positions_check)) check = nullptr;
#endif
        if (check != nullptr && r.layout.has_bounds) {
            check->vouched = 1;
            vouch(r.layout, check->bounds_min, check->bounds_max);
        }
        hz::report(task, 1.0, nullptr);
        return HZ_OK;
    });
}

hz_status HZ_ABI read_streamlines(hz_reader *reader, const hz_streamlines_dst *dst, const hz_task *task, hz_error *err) {
    return read_into(reader, dst, nullptr, task, err);
}

// HZ_EXT_CHECKED_READ.
hz_status HZ_ABI read_streamlines_checked(hz_reader *reader, const hz_streamlines_dst *dst, hz_positions_check *check, const hz_task *task,
                                          hz_error *err) {
    if (check == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: read_streamlines_checked: NULL check");
    return read_into(reader, dst, check, task, err);
}

// HZ_EXT_MAPPED_POSITIONS. Float32LE positions are already RAS+ mm float32
// in the host's byte order: the host maps them, the NaN delimiter after each
// streamline in place (HZ_EXTENT_DELIMITED), when it accepts that layout.
hz_status HZ_ABI locate_positions(hz_reader *reader, hz_positions_extent *out, hz_error *err) {
    if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_positions_extent))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: locate_positions: bad arguments");
    Reader &r = *as_reader(reader);
    const bool delimited_ok = (out->accepts & HZ_EXTENT_DELIMITED) != 0;
    // (nibabel and DIPY write the data at byte 67: mapped all the same, when the host accepts it.)
    const bool unaligned = r.header.data_offset % 4 != 0;
    if (!delimited_ok || r.header.datatype != tck::DataType::Float32LE || std::endian::native != std::endian::little ||
        (unaligned && (out->accepts & HZ_EXTENT_UNALIGNED) == 0) || r.layout.nb_streamlines == 0 ||
        r.layout.delimiters.size() != r.layout.nb_streamlines)
        return HZ_E_UNSUPPORTED;
    out->path = r.path.c_str();
    out->offset = r.header.data_offset;
    out->flags = HZ_EXTENT_DELIMITED | (unaligned ? hz_extent_flags(HZ_EXTENT_UNALIGNED) : 0u);
    out->crc32 = 0;
    // The scan read every coordinate: the walk rejected any NaN/Inf outside
    // an all-NaN delimiter, and the bounds came with it.
    if ((out->accepts & HZ_EXTENT_CHECKED) != 0 && r.layout.has_bounds) {
        out->flags |= HZ_EXTENT_CHECKED;
        vouch(r.layout, out->bounds_min, out->bounds_max);
    }
    r.mapped = true;
    return HZ_OK;
}

// HZ_EXT_MAPPED_POSITIONS: offsets into the mapped span, delimiters included.
hz_status HZ_ABI read_offsets(hz_reader *reader, uint64_t *offsets, uint64_t capacity, const hz_task *task, hz_error *err) {
    if (reader == nullptr || offsets == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: read_offsets: NULL");
    Reader &r = *as_reader(reader);
    if (!r.mapped) return hz::set_errorf(err, HZ_E_BAD_STATE, "tck: %s: read_offsets before locate_positions", r.path.c_str());
    if (capacity < r.layout.nb_streamlines + 1)
        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "tck: %s: destination holds %llu offsets, need %llu", r.path.c_str(),
                              (unsigned long long)capacity, (unsigned long long)(r.layout.nb_streamlines + 1));
    if (stop_asked(task)) return hz::set_error(err, HZ_E_CANCELLED, "cancelled");
    const auto &D = r.layout.delimiters;
    hzio::prefault_write(offsets, (r.layout.nb_streamlines + 1) * sizeof(std::uint64_t));  // (one call, not a fault a page)
    offsets[0] = 0;
    for (std::uint64_t k = 0; k < r.layout.nb_streamlines; ++k) offsets[k + 1] = D[k] + 1;
    return HZ_OK;
}

void HZ_ABI close(hz_reader *reader) { delete as_reader(reader); }

// write() of all the streamlines, or (hz.ext.write-selection/1) of `selection` only.
hz_status write_some(const hz_write_request *req, const hz_dataset_view *data, const std::uint64_t *selection, std::uint64_t nb_selected,
                     hz_error *err) {
    if (req == nullptr || req->path == nullptr || data == nullptr)
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "tck: write: NULL request or data");
    if (data->kind != HZ_DATA_STREAMLINES) return hz::set_errorf(err, HZ_E_UNSUPPORTED, "tck: %s: TCK holds streamlines only", req->path);
    const hz_streamlines_view &s = data->streamlines;
    if (s.offsets == nullptr || (s.nb_vertices > 0 && s.positions == nullptr))
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "tck: %s: streamline view without data", req->path);
    for (uint32_t i = 0; i < data->nb_arrays; ++i) {
        const hz_named_array &a = data->arrays[i];
        if (req->on_dropped == nullptr) break;
        const std::string what = std::string(a.attach == HZ_ATTACH_STREAMLINE ? "per-streamline" : "per-vertex") + " array '" +
                                 (a.name ? a.name : "") + "' (TCK stores positions only)";
        req->on_dropped(req->ctx, what.c_str());
    }
    if (s.gap > 1)
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "tck: %s: streamlines with gap %u (0 or 1 expected)", req->path, s.gap);
#ifdef TCK_FIXTURE_IGNORES_GAP
    const std::uint32_t gap = 0;  // (offers HZ_EXT_DELIMITED_STREAMLINES, then writes the delimiters as points)
#else
    const std::uint32_t gap = s.gap;  // (HZ_EXT_DELIMITED_STREAMLINES: a mapped TCK's delimiters are skipped)
#endif
    return run(err, req->path, [&]() -> hz_status {
        std::vector<std::pair<std::string, std::string>> meta;
        for (uint32_t i = 0; i < data->nb_metadata; ++i)
            if (data->metadata[i].key != nullptr && data->metadata[i].value != nullptr)
                meta.emplace_back(data->metadata[i].key, data->metadata[i].value);
        tck::write(req->path, s.positions, s.nb_vertices, s.offsets, s.nb_streamlines, meta, gap, selection, nb_selected);
        return HZ_OK;
    });
}

constexpr char kPrefix[] = "tck";
using Writer = hz::selective_writer<write_some, kPrefix>;

const char *const kExtensions[] = {"tck", nullptr};

const hz_loader kLoader = {
    .struct_size = sizeof(hz_loader),
    .data_kinds = HZ_DATA_STREAMLINES,
    .caps = HZ_LOADER_CAN_READ | HZ_LOADER_CAN_WRITE,
    .probe_bytes = 64,
    .extensions = kExtensions,
    .probe = probe,
    .open = open,
    .get_info = get_info,
    .get_array_info = get_array_info,
    .visit_metadata = visit_metadata,
    .read_streamlines = read_streamlines,
    .read_array = nullptr,  // TCK has no extra arrays
    .read_volume = nullptr,
    .read_mesh = nullptr,
    .close = close,
    .write = Writer::write,
    .locate_positions = nullptr,  // (1.4-1.9, kept for source compatibility; the extensions below read in place)
};

// Extensions (hz_extensions.h): the host maps Float32LE positions in place,
// takes the scan's word for them, and writes a mapped TCK as it is.
using Mapped = hz::mapped_positions<locate_positions, read_offsets>;
using Checked = hz::checked_read<read_streamlines_checked>;
using OpenTask = hz::open_task<open_task>;
using WriteSelection = hz::write_selection<Writer::write_selection>;
#ifndef TCK_FIXTURE_UNLISTED_EXTENSIONS
const char *const kInterfaces[] = {HZ_INTERFACE_LOADER,
                                   HZ_EXT_MAPPED_POSITIONS,
                                   HZ_EXT_CHECKED_READ,
                                   HZ_EXT_DELIMITED_STREAMLINES,
                                   HZ_EXT_OPEN_TASK,
                                   HZ_EXT_WRITE_SELECTION,
                                   nullptr};
#else
const char *const kInterfaces[] = {HZ_INTERFACE_LOADER, nullptr};
#endif

const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "MRtrix TCK",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "MRtrix3 .tck streamlines: Float32/Float64, both byte orders, read and write",
    .license = "MIT",
    .interfaces = kInterfaces,
};

using Plugin =
    hz::single_plugin<kDescriptor, kLoader, Mapped::ext, Checked::ext, hz::delimited_streamlines, OpenTask::ext, WriteSelection::ext>;
const hz_host *host() { return Plugin::host(); }

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = Plugin::entry;
