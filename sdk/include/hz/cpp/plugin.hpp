// Horizon plugin SDK: header-only C++ helpers for plugin authors.
//
// Nothing here crosses the ABI: these helpers live entirely inside the
// plugin and turn C++ idioms (exceptions, std::string) into the C ABI's
// status codes and caller-owned messages.
#ifndef HZ_CPP_PLUGIN_HPP
#define HZ_CPP_PLUGIN_HPP

#include <hz/hz.h>

#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <exception>
#include <new>
#include <stdexcept>
#include <string>

namespace hz {

// An error with a status code. Throw it inside hz::guard; it becomes the
// call's status and message.
class Error : public std::runtime_error {
public:
    Error(hz_status code, const std::string &message) : std::runtime_error(message), code_(code) {}
    hz_status code() const noexcept { return code_; }

private:
    hz_status code_;
};

// Writes `code` and `message` into a caller-owned hz_error (which may be
// NULL), truncating the message to fit. Returns `code`.
inline hz_status set_error(hz_error *err, hz_status code, const char *message) noexcept {
    if (err != nullptr && err->struct_size >= sizeof(hz_error)) {
        err->code = code;
        std::snprintf(err->message, sizeof err->message, "%s", message != nullptr ? message : "");
    }
    return code;
}

// printf-style variant of set_error.
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
inline hz_status
set_errorf(hz_error *err, hz_status code, const char *fmt, ...) noexcept {
    char buf[HZ_ERROR_MESSAGE_SIZE];
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return set_error(err, code, buf);
}

// Runs `body` (returning hz_status) and converts any exception into a status
// and message, so that no exception ever crosses the C ABI:
//   hz::Error -> its code, std::bad_alloc -> HZ_E_OUT_OF_MEMORY,
//   std::exception -> HZ_E_INTERNAL, anything else -> HZ_E_INTERNAL.
template <class F>
hz_status guard(hz_error *err, F &&body) noexcept {
    try {
        return body();
    } catch (const Error &e) {
        return set_error(err, e.code(), e.what());
    } catch (const std::bad_alloc &) {
        return set_error(err, HZ_E_OUT_OF_MEMORY, "out of memory");
    } catch (const std::exception &e) {
        return set_errorf(err, HZ_E_INTERNAL, "internal error: %s", e.what());
    } catch (...) {
        return set_error(err, HZ_E_INTERNAL, "internal error: unknown exception");
    }
}

// An extension table a plugin serves (hz_extensions.h): its id and table.
// Declare one as a static constant and name it in single_plugin's list:
//     constexpr hz::extension kMapped{HZ_EXT_MAPPED_POSITIONS, &kMappedTable};
struct extension {
    const char *id;
    const void *table;
};

// Ready-made extension entries for single_plugin's list, for the
// extensions of hz_extensions.h (list the same ids in the descriptor):
//     hz::single_plugin<kDescriptor, kLoader,
//                       hz::mapped_positions<locate_positions, read_offsets>::ext,
//                       hz::checked_read<read_streamlines_checked>::ext,
//                       hz::delimited_streamlines>
template <auto Locate, auto ReadOffsets>
struct mapped_positions {
    static constexpr hz_ext_mapped_positions table = {
        .struct_size = sizeof(hz_ext_mapped_positions), .reserved0 = 0, .locate_positions = Locate, .read_offsets = ReadOffsets};
    static constexpr extension ext = {HZ_EXT_MAPPED_POSITIONS, &table};
};
template <auto ReadChecked>
struct checked_read {
    static constexpr hz_ext_checked_read table = {
        .struct_size = sizeof(hz_ext_checked_read), .reserved0 = 0, .read_streamlines_checked = ReadChecked};
    static constexpr extension ext = {HZ_EXT_CHECKED_READ, &table};
};
template <auto Open>
struct open_task {
    static constexpr hz_ext_open_task table = {.struct_size = sizeof(hz_ext_open_task), .reserved0 = 0, .open = Open};
    static constexpr extension ext = {HZ_EXT_OPEN_TASK, &table};
};
// Whether a selection given to hz_ext_write_selection.write_selection breaks
// the contract a writer may rely on (entries strictly increasing and below
// nb_streamlines; a NULL selection only with nb_selected 0). O(nb_selected);
// any thread.
inline bool selection_invalid(uint64_t nb_streamlines, const uint64_t *selection, uint64_t nb_selected) noexcept {
    if (nb_selected == 0) return false;
    if (selection == nullptr || nb_selected > nb_streamlines) return true;
    for (uint64_t k = 0; k < nb_selected; ++k)
        if (selection[k] >= nb_streamlines || (k > 0 && selection[k] <= selection[k - 1])) return true;
    return false;
}
// hz_loader.write and hz_ext_write_selection.write_selection from one
// function `Some` of both: hz_status Some(const hz_write_request *req, const
// hz_dataset_view *data, const uint64_t *selection, uint64_t nb_selected,
// hz_error *err), where `selection` NULL means every streamline and is
// otherwise valid (checked here, HZ_E_INVALID_ARGUMENT otherwise; an empty
// selection arrives as a non-NULL pointer with nb_selected 0). `prefix`
// starts its error messages ("tck").
//     .write = hz::selective_writer<write_some, kPrefix>::write,
//     hz::write_selection<hz::selective_writer<write_some, kPrefix>::write_selection>::ext
template <auto Some, const char *Prefix>
struct selective_writer {
    static hz_status HZ_ABI write(const hz_write_request *req, const hz_dataset_view *data, const hz_task *, hz_error *err) noexcept {
        return Some(req, data, nullptr, 0, err);
    }
    static hz_status HZ_ABI write_selection(const hz_write_request *req, const hz_dataset_view *data, const uint64_t *selection,
                                            uint64_t nb_selected, const hz_task *, hz_error *err) noexcept {
        if (data != nullptr && selection_invalid(data->streamlines.nb_streamlines, selection, nb_selected))
            return set_errorf(err, HZ_E_INVALID_ARGUMENT, "%s: %s: the selection is not increasing indices of the %llu streamlines", Prefix,
                              req != nullptr && req->path != nullptr ? req->path : "",
                              static_cast<unsigned long long>(data->streamlines.nb_streamlines));
        static const uint64_t none = 0;
        return Some(req, data, nb_selected ? selection : &none, nb_selected, err);
    }
};
template <auto WriteSelection>
struct write_selection {
    static constexpr hz_ext_write_selection table = {
        .struct_size = sizeof(hz_ext_write_selection), .reserved0 = 0, .write_selection = WriteSelection};
    static constexpr extension ext = {HZ_EXT_WRITE_SELECTION, &table};
};
inline constexpr hz_ext_delimited_streamlines delimited_streamlines_table = {.struct_size = sizeof(hz_ext_delimited_streamlines),
                                                                              .max_gap = 1};
inline constexpr extension delimited_streamlines = {HZ_EXT_DELIMITED_STREAMLINES, &delimited_streamlines_table};

// The entry functions of a library that holds exactly one plugin, with
// descriptor `D`, whose get_interface() answers a request for its own id
// with Lookup(iface) (NULL: not served): what single_plugin and
// hz::loader_plugin (hz/cpp/loader.hpp) share.
// host() returns the hz_host given to init() (NULL before init / after deinit).
template <const hz_plugin_descriptor &D, const void *(*Lookup)(const char *iface) noexcept>
struct one_plugin_entry {
    static const hz_host *host() noexcept { return host_; }
    static bool HZ_ABI init(const hz_host *h, const char *) noexcept {
        host_ = h;
        return true;
    }
    static void HZ_ABI deinit() noexcept { host_ = nullptr; }
    static uint32_t HZ_ABI count() noexcept { return 1; }
    static const hz_plugin_descriptor *HZ_ABI descriptor(uint32_t i) noexcept { return i == 0 ? &D : nullptr; }
    static const void *HZ_ABI get_interface(const char *id, const char *iface) noexcept {
        if (id == nullptr || iface == nullptr || std::strcmp(id, D.id) != 0) return nullptr;
        return Lookup(iface);
    }
    static constexpr hz_plugin_entry entry = {sizeof(hz_plugin_entry), HZ_ABI_VERSION_INIT, init, deinit, count, descriptor, get_interface};

private:
    static inline const hz_host *host_ = nullptr;
};

namespace detail {
// single_plugin's tables: T for D.interfaces[0], each extension's for its id.
template <const hz_plugin_descriptor &D, const auto &T, const extension &...E>
struct single_lookup {
    static const void *get(const char *iface) noexcept {
        if (std::strcmp(iface, D.interfaces[0]) == 0) return static_cast<const void *>(&T);
        const void *found = nullptr;
        ((found == nullptr && std::strcmp(iface, E.id) == 0 ? (void)(found = E.table) : (void)0), ...);
        return found;
    }
};
}  // namespace detail

// The entry functions of a library that holds exactly one plugin, whose
// descriptor `D` lists its core interface first (then the ids of the
// extensions E..., in any order) and whose core table is `T`:
//     HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader>::entry;
//     HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader, kMapped>::entry;
// get_interface() serves T for D.interfaces[0] and each extension's table
// for its id; an extension missing from D.interfaces is a bug `horizon
// validate` reports (the host never asks for it).
// host() returns the hz_host given to init() (NULL before init / after deinit).
template <const hz_plugin_descriptor &D, const auto &T, const extension &...E>
struct single_plugin : one_plugin_entry<D, &detail::single_lookup<D, T, E...>::get> {};

// Logs through the host of a single_plugin (no-op without one). [thread-safe]
inline void log(const hz_host *host, const char *plugin_id, hz_log_level level, const std::string &msg) noexcept {
    if (host != nullptr && host->log != nullptr) host->log(host, plugin_id, level, msg.c_str());
}

// Never thrown; the default "cancelled" type of format_guard.
struct no_cancel {};

// Runs a loader operation on `path` inside hz::guard, mapping the plugin's
// own exception types: FormatErr -> HZ_E_FORMAT, IoErr -> HZ_E_IO (message
// "<prefix>: <path>: <what>"), CancelT -> HZ_E_CANCELLED.
template <class FormatErr, class IoErr, class CancelT = no_cancel, class F>
hz_status format_guard(hz_error *err, const char *prefix, const std::string &path, F &&body) noexcept {
    return guard(err, [&]() -> hz_status {
        try {
            return body();
        } catch (const CancelT &) {
            return set_error(err, HZ_E_CANCELLED, "cancelled");
        } catch (const FormatErr &e) {
            return set_errorf(err, HZ_E_FORMAT, "%s: %s: %s", prefix, path.c_str(), e.what());
        } catch (const IoErr &e) {
            return set_errorf(err, HZ_E_IO, "%s: %s: %s", prefix, path.c_str(), e.what());
        }
    });
}

// Address of element (row, col) of a 2-D view of `elem_size`-byte elements,
// or NULL when it does not lie wholly inside [data, data + capacity_bytes).
inline unsigned char *view_cell(const hz_array_view &v, uint64_t row, uint64_t col, std::size_t elem_size) noexcept {
    const int64_t off = static_cast<int64_t>(row) * v.stride_bytes[0] + static_cast<int64_t>(col) * v.stride_bytes[1];
    if (off < 0 || static_cast<uint64_t>(off) + elem_size > v.capacity_bytes) return nullptr;
    return static_cast<unsigned char *>(v.data) + off;
}

// Bytes of one value of `d` (0 for HZ_DTYPE_UNKNOWN).
inline std::size_t dtype_size(hz_dtype d) noexcept {
    switch (d) {
    case HZ_DTYPE_U8:
    case HZ_DTYPE_I8: return 1;
    case HZ_DTYPE_U16:
    case HZ_DTYPE_I16:
    case HZ_DTYPE_F16: return 2;
    case HZ_DTYPE_U32:
    case HZ_DTYPE_I32:
    case HZ_DTYPE_F32: return 4;
    case HZ_DTYPE_U64:
    case HZ_DTYPE_I64:
    case HZ_DTYPE_F64: return 8;
    case HZ_DTYPE_RGB8: return 3;
    case HZ_DTYPE_RGBA8: return 4;
    default: return 0;
    }
}

// 1.7-1.9 (kept for source compatibility): where read_streamlines() could
// vouch for the positions it wrote. Since 1.10 the host never asks there
// (hz_streamlines_dst.check is always NULL): this returns NULL, and a loader
// vouches through hz.ext.checked-read/1 (hz::checked_read). [calling thread]
[[deprecated("always NULL since ABI 1.10: vouch through hz.ext.checked-read/1 (hz::checked_read)")]] inline hz_positions_check *
positions_check(const hz_streamlines_dst *) noexcept {
    return nullptr;
}

// Convenience for polling a possibly-NULL task.
inline bool cancelled(const hz_task *task) noexcept {
    return task != nullptr && task->is_cancelled != nullptr && task->is_cancelled(task);
}
inline void report(const hz_task *task, double fraction, const char *msg = nullptr) noexcept {
    if (task != nullptr && task->report != nullptr) task->report(task, fraction, msg);
}

}  // namespace hz

#endif  // HZ_CPP_PLUGIN_HPP
