// hz.loader/1 adapter for TrackVis TRK (trk_format.hpp).
#include "mapped_file.hpp"
#include "trk_format.hpp"

#include <hz/cpp/loader.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

namespace {

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

const char *const kExtensions[] = {"trk", nullptr};
void log(hz_log_level lvl, const std::string &msg);

// The format, as hz::loader<Trk> (hz/cpp/loader.hpp) wants it: the adapter
// checks every argument and capacity, turns the exceptions into statuses,
// and serves the extensions this class supports (open with a task, checked
// reads, delimited streamlines, selections).
struct Trk {
    static constexpr const char *prefix = "trk";
    static constexpr hz_data_kind kinds = HZ_DATA_STREAMLINES;
    static constexpr uint32_t probe_bytes = 1000;
    static constexpr const char *const *extensions = kExtensions;
    static constexpr uint32_t max_gap = 1;  // (a mapped TCK's delimiters are skipped when written)
    using FormatError = trk::FormatError;
    using IoError = hzio::IoError;
    using Cancelled = trk::Cancelled;

    static int32_t probe(const uint8_t *head, uint64_t size, const char *) noexcept { return trk::probe(head, size); }

    struct Reader {
        std::unique_ptr<hzio::MappedFile> file;
        trk::Header header;
        trk::Layout layout;
        // Scalars and properties, decoded on first use (or with the
        // positions), plugin-owned until close.
        mutable bool extras_decoded = false;
        mutable std::vector<float> scalars, properties;
    };

    // The decode's: polls cancellation and reports the fraction of `total`
    // vertices decoded.
    static trk::Tick tick(const hz_task *task, std::uint64_t total) {
        return [task, total](std::uint64_t done) {
            if (done > 0 && total > 0) hz::report(task, std::min(1.0, double(done) / double(total)));
            return hz::cancelled(task);
        };
    }
    // Drops the mapped pages of a decoded chunk.
    static trk::Release release(const hzio::MappedFile &file) {
        return [&file](std::uint64_t begin, std::uint64_t end) { file.release(begin, end); };
    }

    // Opens and scans the file (every record: the counts and the chunk
    // plan), reporting the share scanned; cancellable.
    static std::unique_ptr<Reader> open(const std::string &path, const hz_task *task) {
        auto r = std::make_unique<Reader>();
        r->file = std::make_unique<hzio::MappedFile>(path);
        r->header = trk::parse_header(r->file->data(), r->file->size());
        if (hz::cancelled(task)) throw trk::Cancelled{};
        const std::uint64_t size = r->file->size();
        r->layout = trk::scan(r->file->data(), size, r->header, [task, size](std::uint64_t pos) {
            if (pos > 0 && size > 0) hz::report(task, std::min(1.0, double(pos) / double(size)), "scanning TRK");
            return hz::cancelled(task);
        });
        hz::report(task, 1.0, nullptr);
        for (const auto &w : r->header.warnings) log(HZ_LOG_WARN, path + ": " + w);
        return r;
    }

    static void info(const Reader &r, hz_dataset_info &out) {
        out.kind = HZ_DATA_STREAMLINES;
        std::snprintf(out.format, sizeof out.format, "trk v%d %s%s", r.header.version, r.header.voxel_order.c_str(),
                      r.header.swap ? " swapped" : "");
        out.nb_streamlines = r.layout.nb_streamlines;
        out.nb_vertices = r.layout.nb_vertices;
        std::copy(r.header.vox_to_ras.begin(), r.header.vox_to_ras.end(), out.voxel_to_ras);
        for (int i = 0; i < 3; ++i) out.ref_dims[i] = static_cast<uint64_t>(r.header.dim[i]);
        out.source_space = HZ_SPACE_VOXMM;
        // Extra arrays: one per scalar column group (per vertex), then one
        // per property column group (per streamline).
        out.nb_arrays = static_cast<uint32_t>(r.header.scalars.size() + r.header.properties.size());
    }

    static void array_info(const Reader &r, uint32_t index, hz_array_info &out) {
        const bool scalar = index < r.header.scalars.size();
        const trk::Column &c = scalar ? r.header.scalars[index] : r.header.properties[index - r.header.scalars.size()];
        out.attach = scalar ? HZ_ATTACH_VERTEX : HZ_ATTACH_STREAMLINE;
        out.name = c.name.c_str();
        out.dtype = HZ_DTYPE_F32;
        out.components = c.count;
        out.count = scalar ? r.layout.nb_vertices : r.layout.nb_streamlines;
    }

    static void metadata(const Reader &r, hz_metadata_visitor visit, void *ctx) {
        const trk::Header &h = r.header;
        char buf[128];
        visit(ctx, "version", std::to_string(h.version).c_str());
        std::snprintf(buf, sizeof buf, "%d %d %d", h.dim[0], h.dim[1], h.dim[2]);
        visit(ctx, "dimensions", buf);
        std::snprintf(buf, sizeof buf, "%g %g %g", h.voxel_size[0], h.voxel_size[1], h.voxel_size[2]);
        visit(ctx, "voxel_sizes", buf);
        visit(ctx, "voxel_order", h.voxel_order.c_str());
        visit(ctx, "n_count", std::to_string(h.n_count).c_str());
        visit(ctx, "byte_order", h.swap ? "swapped" : "native");
    }

    // Decodes every streamline (scalars and properties come along in the
    // same pass). decode() rejected every non-finite input coordinate and
    // found the bounds of what it wrote: vouched for, unless a transformed
    // coordinate overflowed float32 (the host then reports it).
    static bool read_streamlines_checked(Reader &r, float *positions, uint64_t *offsets, double lo[3], double hi[3], const hz_task *task) {
        r.scalars.resize(r.layout.nb_vertices * r.header.n_scalars);
        r.properties.resize(r.layout.nb_streamlines * r.header.n_properties);
        trk::Box box;
        trk::decode(r.file->data(), r.file->size(), r.header, r.layout, positions, offsets, r.scalars.empty() ? nullptr : r.scalars.data(),
                    r.properties.empty() ? nullptr : r.properties.data(), tick(task, r.layout.nb_vertices), release(*r.file), &box);
        r.extras_decoded = true;
        hz::report(task, 1.0);
        bool finite = r.layout.nb_vertices > 0;
        for (int d = 0; d < 3; ++d) {
            finite = finite && std::isfinite(box.lo[d]) && std::isfinite(box.hi[d]) && box.lo[d] <= box.hi[d];
            lo[d] = box.lo[d], hi[d] = box.hi[d];
        }
        return finite;
    }

    // Array `index`, float32 rows x its columns, dense.
    static void read_array(const Reader &r, uint32_t index, void *dense, const hz_task *task) {
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
        float *out = static_cast<float *>(dense);
        for (std::uint64_t i = 0; i < rows; ++i) std::memcpy(out + i * comps, &src[i * width + first], comps * sizeof(float));
    }

    // Writes every streamline (selection NULL) or the selected ones: per-
    // vertex arrays become scalars, per-streamline ones properties,
    // interleaved column by column; what does not fit is reported.
    static void write_selection(const hz_write_request &req, const hz_dataset_view &data, const std::uint64_t *selection,
                                std::uint64_t nb_selected, const hz_task *) {
        const hz_streamlines_view &s = data.streamlines;
        trk::WriteSpec spec;
        spec.gap = s.gap;
        spec.selection = selection;
        spec.nb_selected = nb_selected;
        const std::uint64_t nb_written = selection != nullptr ? nb_selected : s.nb_streamlines;  // (the property rows)
        std::copy(data.voxel_to_ras, data.voxel_to_ras + 16, spec.vox_to_ras.begin());
        if (spec.vox_to_ras[15] == 0) spec.vox_to_ras = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        std::copy(data.ref_dims, data.ref_dims + 3, spec.dims.begin());
        std::vector<std::vector<float>> sc, pr;
        for (uint32_t i = 0; i < data.nb_arrays; ++i) {
            const hz_named_array &a = data.arrays[i];
            const std::string name = a.name ? a.name : "";
            const bool vertex = a.attach == HZ_ATTACH_VERTEX && a.count == s.nb_vertices;
            const bool streamline = a.attach == HZ_ATTACH_STREAMLINE && a.count == nb_written;
            auto &cols = vertex ? spec.scalars : spec.properties;
            std::vector<float> f;
            const bool fits = (vertex || streamline) && cols.size() < 10 && !name.empty() &&
                              name.size() + (a.components > 1 ? 1 + std::to_string(a.components).size() : 0) <= 20 &&
                              name.find('\0') == std::string::npos && to_float_columns(a, f);
            if (!fits) {
                if (req.on_dropped)
                    req.on_dropped(req.ctx,
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
        for (uint32_t i = 0; i < data.nb_metadata && req.on_dropped; ++i) {
            const std::string k = data.metadata[i].key ? data.metadata[i].key : "";
            // TRK's own fields, and TCK's structural keys (meaningless once read, as the TRX writer treats them).
            static const char *own[] = {"version",    "dimensions", "voxel_sizes", "voxel_order", "n_count",
                                        "byte_order", "count",      "datatype",    "file"};
            if (std::find(std::begin(own), std::end(own), k) == std::end(own))
                req.on_dropped(req.ctx, ("header entry '" + k + "'").c_str());
        }
        const std::uint64_t empty = trk::write(req.path, s.positions, s.nb_vertices, s.offsets, s.nb_streamlines, spec);
        if (empty > 0 && req.on_dropped)
            req.on_dropped(req.ctx, (std::to_string(empty) + " streamline" + (empty == 1 ? "" : "s") +
                                     " without points (TRK readers cannot read them)")
                                        .c_str());
    }
};

const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = "org.horizon.loader.trk",
    .name = "TrackVis TRK",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "TrackVis .trk v1/v2, both byte orders, scalars and properties; read and write in RAS+ mm",
    .license = "MIT",
    .interfaces = hz::loader<Trk>::interfaces,
};

using Plugin = hz::loader_plugin<kDescriptor, Trk>;
void log(hz_log_level lvl, const std::string &msg) { hz::log(Plugin::host(), kDescriptor.id, lvl, msg); }

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = Plugin::entry;
