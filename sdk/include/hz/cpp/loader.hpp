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
//   - slots L does not fill are NULL, and `caps` follows from what it does.
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
// Every function is called with the loader's threading rules (hz_loader.h):
// one thread at a time per reader.
#ifndef HZ_CPP_LOADER_HPP
#define HZ_CPP_LOADER_HPP

#include <hz/cpp/plugin.hpp>

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
    };
    static Open *as(hz_reader *r) noexcept { return reinterpret_cast<Open *>(r); }

    static constexpr bool reads = requires(const std::string &p, const hz_task *t) { L::open(p, t); };
    static constexpr bool has_arrays = requires(const typename L::Reader &r, hz_array_info &a) { L::array_info(r, 0u, a); };
    static constexpr bool has_metadata = requires(const typename L::Reader &r) { L::metadata(r, hz_metadata_visitor{}, nullptr); };
    static constexpr bool has_streamlines = requires(typename L::Reader &r) { L::read_streamlines(r, nullptr, nullptr, nullptr); };
    static constexpr bool has_mesh = requires(typename L::Reader &r) { L::read_mesh(r, nullptr, nullptr, nullptr); };
    static constexpr bool has_volume = requires(typename L::Reader &r, const hz_array_view &v) { L::read_volume(r, v, nullptr); };
    static constexpr bool writes = requires(const hz_write_request &q, const hz_dataset_view &d) { L::write(q, d, nullptr); };

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
            L::read_streamlines(*r.impl, dst->positions, dst->offsets, task);
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

    static hz_status HZ_ABI write(const hz_write_request *req, const hz_dataset_view *data, const hz_task *task, hz_error *err) noexcept {
        if (req == nullptr || req->path == nullptr || data == nullptr) return bad(err, "write: NULL request or data");
        if ((data->kind & L::kinds) == 0 || (data->kind & (data->kind - 1)) != 0)
            return set_errorf(err, HZ_E_UNSUPPORTED, "%s: %s: cannot hold this kind of data", L::prefix, req->path);
        return run(err, req->path, [&]() -> hz_status {
            L::write(*req, *data, task);
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
        if constexpr (has_streamlines) t.read_streamlines = read_streamlines;
        if constexpr (has_arrays) t.read_array = read_array;
        if constexpr (has_volume) t.read_volume = read_volume;
        if constexpr (has_mesh) t.read_mesh = read_mesh;
        if constexpr (writes) t.write = write;
        return t;
    }
    static constexpr hz_loader table = make_table();
};

}  // namespace hz

#endif  // HZ_CPP_LOADER_HPP
