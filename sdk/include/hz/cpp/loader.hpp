// Horizon plugin SDK: a loader written as a C++ class (header-only).
//
// hz::loader<L>::table is the hz_loader table (hz_loader.h) of a class L that
// describes a format in plain C++: it opens a file into a Reader, describes
// it, and fills dense buffers. The adapter does what every C entry point must
// and every loader would otherwise write again:
//   - NULL-pointer and struct_size checks on every argument;
//   - capacities checked against the file's description before anything is
//     written (HZ_E_BUFFER_TOO_SMALL), array destinations of any strides;
//   - one-line error messages that start with L::prefix and name the file;
//   - no exception across the ABI: L::FormatError becomes HZ_E_FORMAT,
//     L::IoError HZ_E_IO, L::Cancelled (if any) HZ_E_CANCELLED, anything
//     else HZ_E_INTERNAL (hz::format_guard);
//   - slots L does not fill are NULL, and `caps` follows from what it does;
//   - the extensions of hz_extensions.h L supports (below), their tables,
//     and the descriptor's interfaces list that names them
//     (loader<L>::interfaces), served by hz::loader_plugin<D, L>::entry.
// Nothing here crosses the ABI; C authors keep writing the table by hand.
//
// L provides these static members ([opt]: may be left out):
//   static constexpr const char *prefix;                // "plyobj"
//   static constexpr hz_data_kind kinds;                // what it reads and writes
//   static constexpr uint32_t probe_bytes;
//   static constexpr const char *const *extensions;     // NULL-terminated, as hz_loader.extensions
//   using FormatError = ...; using IoError = ...;       // exception types; [opt] using Cancelled = ...;
//   static int32_t probe(const uint8_t *head, uint64_t size, const char *name_hint) noexcept;   // pure
//   struct Reader;                                      // one open file
//   [opt] static std::unique_ptr<Reader> open(const std::string &path, const hz_task *task);
//   [opt] static void info(const Reader &, hz_dataset_info &out);   // with open: kind, counts, format, ...,
//                                                                   // nb_arrays (out is zero-filled)
//   [opt] static void array_info(const Reader &, uint32_t index, hz_array_info &out);   // out.name owned by
//                                                                   // the Reader (valid until close)
//   [opt] static void read_array(const Reader &, uint32_t index, void *dense, const hz_task *);
//                                // count x components values of out.dtype, C order
//   [opt] static void metadata(const Reader &, hz_metadata_visitor visit, void *ctx);
//   [opt] static void read_streamlines(Reader &, float *positions, uint64_t *offsets, const hz_task *);
//   [opt] static void read_mesh(Reader &, float *vertices, uint32_t *faces, const hz_task *);
//   [opt] static void read_volume(Reader &, const hz_array_view &dst, const hz_task *);   // dims checked
//   [opt] static void write(const hz_write_request &req, const hz_dataset_view &data, const hz_task *);
//                                // data.kind is one of `kinds`; req.path is where to write
// Extensions (hz_extensions.h), each offered when L has what it needs:
//   HZ_EXT_OPEN_TASK              whenever L reads: open() gets the host's task (may be NULL)
//   HZ_EXT_CHECKED_READ           [opt] static bool read_streamlines_checked(Reader &, float *positions,
//                                     uint64_t *offsets, double lo[3], double hi[3], const hz_task *);
//                                 read_streamlines() that returns true when it vouches that every
//                                 coordinate it wrote is finite and lo/hi are exactly their bounds
//                                 (false: the host checks them itself). With it, read_streamlines may
//                                 be left out.
//   HZ_EXT_MAPPED_POSITIONS       [opt] static bool locate_positions(Reader &, hz_positions_extent &out);
//                                 [opt] static void read_offsets(Reader &, uint64_t *offsets, const hz_task *);
//                                 both or neither; locate_positions returns false when the positions are
//                                 not stored as the host holds them (or not in a layout out.accepts
//                                 lists); read_offsets writes nb_streamlines + 1 offsets (room checked,
//                                 called only after a locate_positions that returned true).
//   HZ_EXT_DELIMITED_STREAMLINES  [opt] static constexpr uint32_t max_gap = 1;   // write() takes
//                                 views whose streamlines end `gap` vertices before the next offset
//                                 (a larger gap is refused here, HZ_E_INVALID_ARGUMENT)
//   HZ_EXT_WRITE_SELECTION        [opt] static void write_selection(const hz_write_request &,
//                                     const hz_dataset_view &, const uint64_t *selection,
//                                     uint64_t nb_selected, const hz_task *);
//                                 selection NULL: every streamline; else strictly increasing indices
//                                 below nb_streamlines (checked here). Without L::write, the table's
//                                 write() calls it with NULL.
// A single-plugin library then needs only its descriptor:
//     const hz_plugin_descriptor kDescriptor = {..., .interfaces = hz::loader<Trk>::interfaces};
//     HZ_DECLARE_PLUGIN_ENTRY = hz::loader_plugin<kDescriptor, Trk>::entry;
// Every function is called with the loader's threading rules (hz_loader.h):
// one thread at a time per reader.
#ifndef HZ_CPP_LOADER_HPP
#define HZ_CPP_LOADER_HPP

#include <hz/cpp/plugin.hpp>

#include <array>
#include <concepts>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

namespace hz {

namespace detail {
template <class L>
concept has_cancelled = requires { typename L::Cancelled; };
template <class L>
struct cancel_type {
    using type = no_cancel;
};
template <class L>
    requires has_cancelled<L>
struct cancel_type<L> {
    using type = typename L::Cancelled;
};
}  // namespace detail

template <class L>
class loader {
    // What a reader is to the host: the file, its description (capacities
    // are checked against it), its arrays, and L's own Reader.
    struct Open {
        std::string path;
        hz_dataset_info info{};
        std::vector<hz_array_info> arrays;
        std::unique_ptr<typename L::Reader> impl;
        bool located = false;  // locate_positions() answered HZ_OK
    };
    static Open *as(hz_reader *r) noexcept { return reinterpret_cast<Open *>(r); }

    static constexpr bool reads = requires(const std::string &p, const hz_task *t) { L::open(p, t); };
    static constexpr bool has_arrays = requires(const typename L::Reader &r, hz_array_info &a) { L::array_info(r, 0u, a); };
    static constexpr bool has_metadata = requires(const typename L::Reader &r) { L::metadata(r, hz_metadata_visitor{}, nullptr); };
    static constexpr bool has_streamlines = requires(typename L::Reader &r) { L::read_streamlines(r, nullptr, nullptr, nullptr); };
    static constexpr bool has_mesh = requires(typename L::Reader &r) { L::read_mesh(r, nullptr, nullptr, nullptr); };
    static constexpr bool has_volume = requires(typename L::Reader &r, const hz_array_view &v) { L::read_volume(r, v, nullptr); };
    static constexpr bool has_write = requires(const hz_write_request &q, const hz_dataset_view &d) { L::write(q, d, nullptr); };
    static constexpr bool has_checked = requires(typename L::Reader &r, double *b) {
        { L::read_streamlines_checked(r, nullptr, nullptr, b, b, nullptr) } -> std::convertible_to<bool>;
    };
    static constexpr bool has_mapped = requires(typename L::Reader &r, hz_positions_extent &e) {
        { L::locate_positions(r, e) } -> std::convertible_to<bool>;
        L::read_offsets(r, nullptr, nullptr);
    };
    static constexpr bool has_gap = requires { requires L::max_gap >= 1u; };
    static constexpr bool has_selection = requires(const hz_write_request &q, const hz_dataset_view &d) {
        L::write_selection(q, d, nullptr, uint64_t{0}, nullptr);
    };
    static constexpr bool writes = has_write || has_selection;
    static constexpr uint32_t gap_taken() noexcept {
        if constexpr (has_gap) return L::max_gap;
        return 0;
    }

    template <class F>
    static hz_status run(hz_error *err, const std::string &path, F &&body) noexcept {
        return format_guard<typename L::FormatError, typename L::IoError, typename detail::cancel_type<L>::type>(err, L::prefix, path,
                                                                                                                 body);
    }
    static hz_status bad(hz_error *err, const char *what) noexcept {
        return set_errorf(err, HZ_E_INVALID_ARGUMENT, "%s: %s", L::prefix, what);
    }
    static hz_status too_small(hz_error *err, const Open &r, const char *call) noexcept {
        return set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "%s: %s: %s: destination too small", L::prefix, r.path.c_str(), call);
    }

public:
    static int32_t HZ_ABI probe(const uint8_t *head, uint64_t size, const char *name) noexcept {
        return head == nullptr && size > 0 ? 0 : L::probe(head, size, name);
    }

    // open(), and open() with a task (offer it as hz::open_task<loader<L>::open_task>).
    static hz_status HZ_ABI open_task(const hz_open_request *req, const hz_task *task, hz_reader **out, hz_error *err) noexcept {
        if (out != nullptr) *out = nullptr;
        if (req == nullptr || req->path == nullptr || out == nullptr) return bad(err, "open: NULL request, path or output");
        if (cancelled(task)) return set_error(err, HZ_E_CANCELLED, "cancelled");
        return run(err, req->path, [&]() -> hz_status {
            auto r = std::make_unique<Open>();
            r->path = req->path;
            r->impl = L::open(r->path, task);
            r->info.struct_size = sizeof r->info;
            L::info(*r->impl, r->info);
            r->info.struct_size = sizeof r->info;
            if constexpr (has_arrays) {
                for (uint32_t i = 0; i < r->info.nb_arrays; ++i) {
                    hz_array_info a{};
                    a.struct_size = sizeof a;
                    L::array_info(*r->impl, i, a);
                    a.struct_size = sizeof a;
                    r->arrays.push_back(a);
                }
            } else {
                r->info.nb_arrays = 0;
            }
            *out = reinterpret_cast<hz_reader *>(r.release());
            return HZ_OK;
        });
    }
    static hz_status HZ_ABI open(const hz_open_request *req, hz_reader **out, hz_error *err) noexcept {
        return open_task(req, nullptr, out, err);
    }

    static hz_status HZ_ABI get_info(hz_reader *reader, hz_dataset_info *out, hz_error *err) noexcept {
        if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_dataset_info)) return bad(err, "get_info: bad arguments");
        const uint32_t size = out->struct_size;
        std::memcpy(out, &as(reader)->info, sizeof(hz_dataset_info));
        out->struct_size = size;
        return HZ_OK;
    }

    static hz_status HZ_ABI get_array_info(hz_reader *reader, uint32_t index, hz_array_info *out, hz_error *err) noexcept {
        if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_array_info)) return bad(err, "get_array_info: bad arguments");
        const Open &r = *as(reader);
        if (index >= r.arrays.size())
            return set_errorf(err, HZ_E_NOT_FOUND, "%s: %s: no extra array %u", L::prefix, r.path.c_str(), index);
        const uint32_t size = out->struct_size;
        std::memcpy(out, &r.arrays[index], sizeof(hz_array_info));
        out->struct_size = size;
        return HZ_OK;
    }

    // Values land in the host's view as they are (dtype as described), in
    // one pass when the view is dense, else value by value within bounds.
    static hz_status HZ_ABI read_array(hz_reader *reader, uint32_t index, const hz_array_view *dst, const hz_task *task,
                                       hz_error *err) noexcept {
        if (reader == nullptr || dst == nullptr) return bad(err, "read_array: NULL");
        Open &r = *as(reader);
        if (index >= r.arrays.size())
            return set_errorf(err, HZ_E_NOT_FOUND, "%s: %s: no extra array %u", L::prefix, r.path.c_str(), index);
        const hz_array_info &a = r.arrays[index];
        const std::size_t es = dtype_size(a.dtype);
        const uint32_t comps = a.components ? a.components : 1;
        if (dst->dtype != a.dtype || dst->ndim < 1 || dst->shape[0] != a.count ||
            (comps > 1 && (dst->ndim < 2 || dst->shape[1] != comps)))
            return set_errorf(err, HZ_E_INVALID_ARGUMENT, "%s: %s: read_array: the destination is not %llu x %u of the array's type",
                              L::prefix, r.path.c_str(), (unsigned long long)a.count, comps);
        if (a.count == 0) return HZ_OK;
        if (dst->data == nullptr) return bad(err, "read_array: NULL destination");
        return run(err, r.path, [&]() -> hz_status {
            const uint64_t bytes = a.count * comps * es;
            const bool dense = dst->stride_bytes[0] == int64_t(comps * es) && (comps == 1 || dst->stride_bytes[1] == int64_t(es));
            if (dense) {
                if (dst->capacity_bytes < bytes) return too_small(err, r, "read_array");
                L::read_array(*r.impl, index, dst->data, task);
                return HZ_OK;
            }
            std::vector<unsigned char> tmp(bytes);
            L::read_array(*r.impl, index, tmp.data(), task);
            for (uint64_t i = 0; i < a.count; ++i)
                for (uint32_t c = 0; c < comps; ++c) {
                    unsigned char *cell = view_cell(*dst, i, c, es);
                    if (cell == nullptr) return too_small(err, r, "read_array");
                    std::memcpy(cell, tmp.data() + (i * comps + c) * es, es);
                }
            return HZ_OK;
        });
    }

    static hz_status HZ_ABI visit_metadata(hz_reader *reader, hz_metadata_visitor visitor, void *ctx, hz_error *err) noexcept {
        if (reader == nullptr || visitor == nullptr) return bad(err, "visit_metadata: NULL");
        Open &r = *as(reader);
        return run(err, r.path, [&]() -> hz_status {
            L::metadata(*r.impl, visitor, ctx);
            return HZ_OK;
        });
    }

    static hz_status HZ_ABI read_streamlines(hz_reader *reader, const hz_streamlines_dst *dst, const hz_task *task, hz_error *err) noexcept {
        if (reader == nullptr || dst == nullptr) return bad(err, "read_streamlines: NULL");
        Open &r = *as(reader);
        if (r.info.kind != HZ_DATA_STREAMLINES)
            return set_errorf(err, HZ_E_UNSUPPORTED, "%s: %s: holds no streamlines", L::prefix, r.path.c_str());
        if ((dst->positions == nullptr && r.info.nb_vertices > 0) || dst->offsets == nullptr)
            return bad(err, "read_streamlines: NULL destination");
        if (dst->positions_capacity < 3 * r.info.nb_vertices || dst->offsets_capacity < r.info.nb_streamlines + 1)
            return too_small(err, r, "read_streamlines");
        if (cancelled(task)) return set_error(err, HZ_E_CANCELLED, "cancelled");
        return run(err, r.path, [&]() -> hz_status {
            if constexpr (has_streamlines) {
                L::read_streamlines(*r.impl, dst->positions, dst->offsets, task);
            } else {
                double lo[3], hi[3];
                (void)L::read_streamlines_checked(*r.impl, dst->positions, dst->offsets, lo, hi, task);
            }
            return HZ_OK;
        });
    }

    // HZ_EXT_CHECKED_READ: read_streamlines() and the loader's vouch, into
    // `check` only where its struct_size has room.
    static hz_status HZ_ABI read_streamlines_checked(hz_reader *reader, const hz_streamlines_dst *dst, hz_positions_check *check,
                                                     const hz_task *task, hz_error *err) noexcept {
        if (reader == nullptr || dst == nullptr || check == nullptr) return bad(err, "read_streamlines_checked: NULL");
        Open &r = *as(reader);
        if (r.info.kind != HZ_DATA_STREAMLINES)
            return set_errorf(err, HZ_E_UNSUPPORTED, "%s: %s: holds no streamlines", L::prefix, r.path.c_str());
        if ((dst->positions == nullptr && r.info.nb_vertices > 0) || dst->offsets == nullptr)
            return bad(err, "read_streamlines_checked: NULL destination");
        if (dst->positions_capacity < 3 * r.info.nb_vertices || dst->offsets_capacity < r.info.nb_streamlines + 1)
            return too_small(err, r, "read_streamlines_checked");
        if (cancelled(task)) return set_error(err, HZ_E_CANCELLED, "cancelled");
        return run(err, r.path, [&]() -> hz_status {
            double lo[3], hi[3];
            const bool vouched = L::read_streamlines_checked(*r.impl, dst->positions, dst->offsets, lo, hi, task);
            if (vouched && check->struct_size >= sizeof(hz_positions_check)) {
                check->vouched = 1;
                for (int d = 0; d < 3; ++d) check->bounds_min[d] = lo[d], check->bounds_max[d] = hi[d];
            }
            return HZ_OK;
        });
    }

    // HZ_EXT_MAPPED_POSITIONS.
    static hz_status HZ_ABI locate_positions(hz_reader *reader, hz_positions_extent *out, hz_error *err) noexcept {
        if (reader == nullptr || out == nullptr || out->struct_size < sizeof(hz_positions_extent))
            return bad(err, "locate_positions: bad arguments");
        Open &r = *as(reader);
        if (r.info.kind != HZ_DATA_STREAMLINES) return HZ_E_UNSUPPORTED;
        hz_status st = HZ_E_UNSUPPORTED;
        const hz_status ran = run(err, r.path, [&]() -> hz_status {
            hz_positions_extent e = *out;
            // (a layout the host did not list is not one it can map: the
            // host reads with read_streamlines() instead)
            if (L::locate_positions(*r.impl, e) && (e.flags & ~(out->accepts | hz_extent_flags(HZ_EXTENT_HAS_CRC32))) == 0) {
                e.struct_size = out->struct_size, e.accepts = out->accepts;
                *out = e;
                r.located = true, st = HZ_OK;
            }
            return HZ_OK;
        });
        return ran != HZ_OK ? ran : st;
    }
    static hz_status HZ_ABI read_offsets(hz_reader *reader, uint64_t *offsets, uint64_t capacity, const hz_task *task,
                                         hz_error *err) noexcept {
        if (reader == nullptr || offsets == nullptr) return bad(err, "read_offsets: NULL");
        Open &r = *as(reader);
        if (!r.located)
            return set_errorf(err, HZ_E_BAD_STATE, "%s: %s: read_offsets before locate_positions", L::prefix, r.path.c_str());
        if (capacity < r.info.nb_streamlines + 1) return too_small(err, r, "read_offsets");
        if (cancelled(task)) return set_error(err, HZ_E_CANCELLED, "cancelled");
        return run(err, r.path, [&]() -> hz_status {
            L::read_offsets(*r.impl, offsets, task);
            return HZ_OK;
        });
    }

    static hz_status HZ_ABI read_mesh(hz_reader *reader, const hz_mesh_dst *dst, const hz_task *task, hz_error *err) noexcept {
        if (reader == nullptr || dst == nullptr) return bad(err, "read_mesh: NULL");
        Open &r = *as(reader);
        if (r.info.kind != HZ_DATA_MESH) return set_errorf(err, HZ_E_UNSUPPORTED, "%s: %s: holds no mesh", L::prefix, r.path.c_str());
        if ((dst->vertices == nullptr && r.info.nb_vertices > 0) || (dst->faces == nullptr && r.info.nb_faces > 0))
            return bad(err, "read_mesh: NULL destination");
        if (dst->vertices_capacity < 3 * r.info.nb_vertices || dst->faces_capacity < 3 * r.info.nb_faces)
            return too_small(err, r, "read_mesh");
        if (cancelled(task)) return set_error(err, HZ_E_CANCELLED, "cancelled");
        return run(err, r.path, [&]() -> hz_status {
            L::read_mesh(*r.impl, dst->vertices, dst->faces, task);
            return HZ_OK;
        });
    }

    static hz_status HZ_ABI read_volume(hz_reader *reader, const hz_array_view *dst, const hz_task *task, hz_error *err) noexcept {
        if (reader == nullptr || dst == nullptr) return bad(err, "read_volume: NULL");
        Open &r = *as(reader);
        if (r.info.kind != HZ_DATA_VOLUME && r.info.kind != HZ_DATA_IMAGE)
            return set_errorf(err, HZ_E_UNSUPPORTED, "%s: %s: holds no volume", L::prefix, r.path.c_str());
        if (dst->data == nullptr) return bad(err, "read_volume: NULL destination");
        if (cancelled(task)) return set_error(err, HZ_E_CANCELLED, "cancelled");
        return run(err, r.path, [&]() -> hz_status {
            L::read_volume(*r.impl, *dst, task);
            return HZ_OK;
        });
    }

    static void HZ_ABI close(hz_reader *reader) noexcept { delete as(reader); }

    // What every write checks: the request, the kind, a gap L takes.
    static hz_status write_checks(const hz_write_request *req, const hz_dataset_view *data, hz_error *err) noexcept {
        if (req == nullptr || req->path == nullptr || data == nullptr) return bad(err, "write: NULL request or data");
        if ((data->kind & L::kinds) == 0 || (data->kind & (data->kind - 1)) != 0)
            return set_errorf(err, HZ_E_UNSUPPORTED, "%s: %s: cannot hold this kind of data", L::prefix, req->path);
        if (data->kind == HZ_DATA_STREAMLINES && data->streamlines.gap > gap_taken())
            return set_errorf(err, HZ_E_INVALID_ARGUMENT, "%s: %s: streamlines with gap %u (at most %u expected)", L::prefix, req->path,
                              data->streamlines.gap, gap_taken());
        return HZ_OK;
    }

    static hz_status HZ_ABI write(const hz_write_request *req, const hz_dataset_view *data, const hz_task *task, hz_error *err) noexcept {
        if (const hz_status st = write_checks(req, data, err); st != HZ_OK) return st;
        return run(err, req->path, [&]() -> hz_status {
            if constexpr (has_write)
                L::write(*req, *data, task);
            else
                L::write_selection(*req, *data, nullptr, 0, task);
            return HZ_OK;
        });
    }

    // HZ_EXT_WRITE_SELECTION: the selection checked (selection_invalid).
    static hz_status HZ_ABI write_selection(const hz_write_request *req, const hz_dataset_view *data, const uint64_t *selection,
                                            uint64_t nb_selected, const hz_task *task, hz_error *err) noexcept {
        if (const hz_status st = write_checks(req, data, err); st != HZ_OK) return st;
        if (selection_invalid(data->streamlines.nb_streamlines, selection, nb_selected))
            return set_errorf(err, HZ_E_INVALID_ARGUMENT, "%s: %s: the selection is not increasing indices of the %llu streamlines",
                              L::prefix, req->path, static_cast<unsigned long long>(data->streamlines.nb_streamlines));
        static const uint64_t none = 0;
        return run(err, req->path, [&]() -> hz_status {
            L::write_selection(*req, *data, nb_selected ? selection : &none, nb_selected, task);
            return HZ_OK;
        });
    }

    // The table: every slot L fills, NULL for the rest. (Each entry point
    // is instantiated only when its slot is filled.)
    static constexpr hz_loader make_table() noexcept {
        hz_loader t{};
        t.struct_size = sizeof(hz_loader);
        t.data_kinds = L::kinds;
        t.caps = (reads ? hz_loader_caps(HZ_LOADER_CAN_READ) : 0u) | (writes ? hz_loader_caps(HZ_LOADER_CAN_WRITE) : 0u);
        t.probe_bytes = L::probe_bytes;
        t.extensions = L::extensions;
        t.probe = probe;
        if constexpr (reads) {
            t.open = open;
            t.get_info = get_info;
            t.get_array_info = get_array_info;
            t.close = close;
        }
        if constexpr (has_metadata) t.visit_metadata = visit_metadata;
        if constexpr (has_streamlines || has_checked) t.read_streamlines = read_streamlines;
        if constexpr (has_arrays) t.read_array = read_array;
        if constexpr (has_volume) t.read_volume = read_volume;
        if constexpr (has_mesh) t.read_mesh = read_mesh;
        if constexpr (writes) t.write = write;
        return t;
    }
    static constexpr hz_loader table = make_table();

    // The extension tables L supports, and the descriptor's interfaces:
    // HZ_INTERFACE_LOADER, then their ids, NULL-terminated.
    static constexpr hz_ext_open_task open_task_table = {.struct_size = sizeof(hz_ext_open_task), .reserved0 = 0, .open = open_task};
    static constexpr hz_ext_checked_read checked_read_table = {
        .struct_size = sizeof(hz_ext_checked_read), .reserved0 = 0, .read_streamlines_checked = read_streamlines_checked};
    static constexpr hz_ext_mapped_positions mapped_positions_table = {
        .struct_size = sizeof(hz_ext_mapped_positions), .reserved0 = 0, .locate_positions = locate_positions, .read_offsets = read_offsets};
    static constexpr hz_ext_delimited_streamlines delimited_table = {.struct_size = sizeof(hz_ext_delimited_streamlines),
                                                                     .max_gap = gap_taken()};
    static constexpr hz_ext_write_selection write_selection_table = {
        .struct_size = sizeof(hz_ext_write_selection), .reserved0 = 0, .write_selection = write_selection};

    // The table of extension `id` (NULL: not one L supports). [any thread]
    static const void *extension(const char *id) noexcept {
        if (id == nullptr) return nullptr;
        if constexpr (reads)
            if (std::strcmp(id, HZ_EXT_OPEN_TASK) == 0) return &open_task_table;
        if constexpr (has_checked)
            if (std::strcmp(id, HZ_EXT_CHECKED_READ) == 0) return &checked_read_table;
        if constexpr (has_mapped)
            if (std::strcmp(id, HZ_EXT_MAPPED_POSITIONS) == 0) return &mapped_positions_table;
        if constexpr (has_gap)
            if (std::strcmp(id, HZ_EXT_DELIMITED_STREAMLINES) == 0) return &delimited_table;
        if constexpr (has_selection)
            if (std::strcmp(id, HZ_EXT_WRITE_SELECTION) == 0) return &write_selection_table;
        return nullptr;
    }

private:
    static constexpr std::array<const char *, 7> make_interfaces() noexcept {
        std::array<const char *, 7> a{};
        std::size_t n = 0;
        a[n++] = HZ_INTERFACE_LOADER;
        if (reads) a[n++] = HZ_EXT_OPEN_TASK;
        if (has_checked) a[n++] = HZ_EXT_CHECKED_READ;
        if (has_mapped) a[n++] = HZ_EXT_MAPPED_POSITIONS;
        if (has_gap) a[n++] = HZ_EXT_DELIMITED_STREAMLINES;
        if (has_selection) a[n++] = HZ_EXT_WRITE_SELECTION;
        return a;
    }
    static constexpr std::array<const char *, 7> interfaces_ = make_interfaces();

public:
    // For hz_plugin_descriptor.interfaces: static storage, NULL-terminated.
    static constexpr const char *const *interfaces = interfaces_.data();
};

// The entry functions of a library holding one loader written as class L,
// whose descriptor D has .interfaces = hz::loader<L>::interfaces:
//     HZ_DECLARE_PLUGIN_ENTRY = hz::loader_plugin<kDescriptor, Trk>::entry;
// get_interface() serves loader<L>::table and the extensions L supports.
// host() returns the hz_host given to init() (NULL before init / after deinit).
namespace detail {
template <class L>
const void *loader_lookup(const char *iface) noexcept {
    if (std::strcmp(iface, HZ_INTERFACE_LOADER) == 0) return &loader<L>::table;
    return loader<L>::extension(iface);
}
}  // namespace detail

template <const hz_plugin_descriptor &D, class L>
struct loader_plugin : one_plugin_entry<D, &detail::loader_lookup<L>> {};

}  // namespace hz

#endif  // HZ_CPP_LOADER_HPP
