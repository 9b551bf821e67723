// The MRtrix TCK format (tck_format.hpp) as hz::loader<tck::Loader> wants it
// (hz/cpp/loader.hpp): the adapter checks every argument and capacity, turns
// the exceptions into statuses, and serves the extensions this class
// supports: open with a task, checked reads (the scan's bounds vouched for),
// positions mapped in place with their NaN delimiters, writes of delimited
// streamlines and of selections. tck_plugin.cpp is the plugin; the test
// fixtures that misbehave at the ABI wrap the same class.
//
// Included by one source of each plugin, which defines tck::log_warning.
#pragma once

#include "mapped_file.hpp"
#include "parallel.hpp"
#include "tck_format.hpp"

#include <hz/cpp/loader.hpp>

#include <algorithm>
#include <bit>
#include <cstdio>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace tck {

// A warning about `path`'s content, through the host's log (defined by the
// plugin's source, which holds the host).
void log_warning(const std::string &message);

inline const char *const kExtensions[] = {"tck", nullptr};

struct Loader {
    static constexpr const char *prefix = "tck";
    static constexpr hz_data_kind kinds = HZ_DATA_STREAMLINES;
    static constexpr uint32_t probe_bytes = 64;
    static constexpr const char *const *extensions = kExtensions;
    static constexpr uint32_t max_gap = 1;  // (a mapped TCK's delimiters are skipped when written)
    using FormatError = tck::FormatError;
    using IoError = hzio::IoError;
    using Cancelled = tck::Cancelled;

    static int32_t probe(const uint8_t *head, uint64_t size, const char *) noexcept { return tck::probe(head, size); }

    struct Reader {
        std::string path;
        std::unique_ptr<hzio::MappedFile> file;
        Header header;
        Layout layout;
    };

    // Polls cancellation and drops the mapped pages already walked (peak
    // memory stays near the decoded data).
    static Tick tick(const hz_task *task, const hzio::MappedFile &file) {
        return [task, &file](std::uint64_t pos) {
            if (pos > (64u << 20)) file.release_before(pos - (32u << 20));
            return hz::cancelled(task);
        };
    }
    // Drops the mapped pages of a chunk a parallel pass is done with.
    static Release release(const hzio::MappedFile &file) {
        return [&file](std::uint64_t begin, std::uint64_t end) { file.release(begin, end); };
    }

    // Opens and scans the file (every triple: the counts, the delimiters,
    // the bounds), reporting the share scanned; cancellable.
    static std::unique_ptr<Reader> open(const std::string &path, const hz_task *task) {
        auto r = std::make_unique<Reader>();
        r->path = path;
        r->file = std::make_unique<hzio::MappedFile>(path);
        r->header = parse_header(r->file->data(), r->file->size());
        if (hz::cancelled(task)) throw Cancelled{};
        const hzio::MappedFile &file = *r->file;
        Tick scan_tick = [task, &file, inner = tick(task, file)](std::uint64_t pos) {
            if (pos > 0 && file.size() > 0) hz::report(task, std::min(1.0, double(pos) / double(file.size())), "scanning TCK");
            return inner(pos);
        };
        r->layout = scan(file.data(), file.size(), r->header, scan_tick, release(file));
        hz::report(task, 1.0, nullptr);
        for (const auto &w : r->header.warnings) log_warning(path + ": " + w);
        if (r->layout.trailing_bytes != 0)
            log_warning(path + ": " + std::to_string(r->layout.trailing_bytes) + " bytes after the Inf terminator ignored");
        if (const auto count = declared_count(r->header); count && *count != r->layout.nb_streamlines)
            log_warning(path + ": the header says count " + std::to_string(*count) + " but the data hold " +
                        std::to_string(r->layout.nb_streamlines) + (r->layout.nb_streamlines == 1 ? " streamline" : " streamlines") +
                        "; reading what the data hold");
        return r;
    }

    static void info(const Reader &r, hz_dataset_info &out) {
        out.kind = HZ_DATA_STREAMLINES;
        std::snprintf(out.format, sizeof out.format, "tck %s", to_string(r.header.datatype));
        out.nb_streamlines = r.layout.nb_streamlines;
        out.nb_vertices = r.layout.nb_vertices;
        static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        std::copy(identity, identity + 16, out.voxel_to_ras);
        out.source_space = HZ_SPACE_RASMM;  // TCK stores scanner RAS+ mm
        out.nb_arrays = 0;                  // (TCK holds positions only)
    }

    static void metadata(const Reader &r, hz_metadata_visitor visit, void *ctx) {
        for (const auto &[k, v] : r.header.entries) visit(ctx, k.c_str(), v.c_str());
    }

    // Decodes every streamline. Float32LE data are copied as they are, and
    // the scan read every coordinate (finite outside the delimiters) and
    // found their bounds: vouched for. (Other datatypes: the host checks.)
    static bool read_streamlines_checked(Reader &r, float *positions, uint64_t *offsets, double lo[3], double hi[3], const hz_task *task) {
        hz::report(task, 0.0, "decoding TCK");
        decode(r.file->data(), r.header, r.layout, positions, offsets, tick(task, *r.file), release(*r.file));
        hz::report(task, 1.0, nullptr);
        for (int d = 0; d < 3; ++d) lo[d] = r.layout.lo[d], hi[d] = r.layout.hi[d];
        return r.layout.has_bounds;
    }

    // HZ_EXT_MAPPED_POSITIONS. Float32LE positions are already RAS+ mm
    // float32 in the host's byte order: the host maps them, the NaN
    // delimiter after each streamline in place (HZ_EXTENT_DELIMITED), when
    // it accepts that layout. nibabel and DIPY write the data at byte 67:
    // mapped all the same (HZ_EXTENT_UNALIGNED), when the host accepts it.
    static bool locate_positions(Reader &r, hz_positions_extent &out) {
        const bool unaligned = r.header.data_offset % 4 != 0;
        if ((out.accepts & HZ_EXTENT_DELIMITED) == 0 || r.header.datatype != DataType::Float32LE ||
            std::endian::native != std::endian::little || (unaligned && (out.accepts & HZ_EXTENT_UNALIGNED) == 0) ||
            r.layout.nb_streamlines == 0 || r.layout.delimiters.size() != r.layout.nb_streamlines)
            return false;
        out.path = r.path.c_str();
        out.offset = r.header.data_offset;
        out.flags = HZ_EXTENT_DELIMITED | (unaligned ? hz_extent_flags(HZ_EXTENT_UNALIGNED) : 0u);
        out.crc32 = 0;
        // The scan read every coordinate: the walk rejected any NaN/Inf
        // outside an all-NaN delimiter, and the bounds came with it.
        if ((out.accepts & HZ_EXTENT_CHECKED) != 0 && r.layout.has_bounds) {
            out.flags |= HZ_EXTENT_CHECKED;
            for (int d = 0; d < 3; ++d) out.bounds_min[d] = r.layout.lo[d], out.bounds_max[d] = r.layout.hi[d];
        }
        return true;
    }
    // The offsets into the mapped span, delimiters included.
    static void read_offsets(Reader &r, uint64_t *offsets, const hz_task *) {
        const auto &D = r.layout.delimiters;
        hzio::prefault_write(offsets, (r.layout.nb_streamlines + 1) * sizeof(std::uint64_t));  // (one call, not a fault a page)
        offsets[0] = 0;
        for (std::uint64_t k = 0; k < r.layout.nb_streamlines; ++k) offsets[k + 1] = D[k] + 1;
    }

    // Writes every streamline (selection NULL) or the selected ones, with
    // the metadata given; extra arrays are reported as dropped (TCK stores
    // positions only). Gap vertices (a mapped TCK's delimiters) are skipped.
    static void write_selection(const hz_write_request &req, const hz_dataset_view &data, const std::uint64_t *selection,
                                std::uint64_t nb_selected, const hz_task *) {
        const hz_streamlines_view &s = data.streamlines;
        if (s.offsets == nullptr || (s.nb_vertices > 0 && s.positions == nullptr)) throw FormatError("streamline view without data");
        for (uint32_t i = 0; i < data.nb_arrays && req.on_dropped != nullptr; ++i) {
            const hz_named_array &a = data.arrays[i];
            const std::string what = std::string(a.attach == HZ_ATTACH_STREAMLINE ? "per-streamline" : "per-vertex") + " array '" +
                                     (a.name ? a.name : "") + "' (TCK stores positions only)";
            req.on_dropped(req.ctx, what.c_str());
        }
        std::vector<std::pair<std::string, std::string>> meta;
        for (uint32_t i = 0; i < data.nb_metadata; ++i)
            if (data.metadata[i].key != nullptr && data.metadata[i].value != nullptr)
                meta.emplace_back(data.metadata[i].key, data.metadata[i].value);
        try {
            write(req.path, s.positions, s.nb_vertices, s.offsets, s.nb_streamlines, meta, s.gap, selection, nb_selected);
        } catch (const FormatError &e) {
            if (e.io) throw hzio::IoError(e.what());  // (the system's failure, not the data's: HZ_E_IO)
            throw;
        }
    }
};

}  // namespace tck
