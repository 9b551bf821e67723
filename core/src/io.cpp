#include <hz/core/io.hpp>
#include <hz/core/plugin_guard.hpp>
#include <hz/core/filter.hpp>

#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <libdeflate.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <fstream>
#include <mutex>
#include <random>

namespace hz::core {

namespace {

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

// RAII for a reader.
struct ReaderGuard {
    const hz_loader *l;
    hz_reader *r = nullptr;
    ~ReaderGuard() {
        if (r != nullptr) l->close(r);
    }
};

hz_error make_error() {
    hz_error e{};
    e.struct_size = sizeof e;
    return e;
}

// Formats a plugin failure; plugins name the file themselves, but make sure.
std::string failure(const hz_error &e, hz_status st, const fs::path &path, const char *what) {
    std::string msg = e.message[0] ? e.message : (std::string(what) + " failed with status " + std::to_string(st));
    if (msg.find(path.string()) == std::string::npos) msg = path.string() + ": " + msg;
    return msg;
}

std::vector<unsigned char> read_head(const fs::path &path, std::size_t n) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(path.string() + ": cannot open: " + std::strerror(errno));
    std::vector<unsigned char> buf(n);
    in.read(reinterpret_cast<char *>(buf.data()), static_cast<std::streamsize>(n));
    buf.resize(static_cast<std::size_t>(in.gcount()));
    return buf;
}

// The bounds a loader vouched for (HZ_EXTENT_CHECKED, hz_positions_check):
// finite, ordered.
Bounds vouched_bounds(const double (&lo)[3], const double (&hi)[3], const fs::path &path, const std::string &loader) {
    Bounds b;
    b.empty = false;
    for (int d = 0; d < 3; ++d) {
        b.min[d] = lo[d];
        b.max[d] = hi[d];
        if (!(std::isfinite(b.min[d]) && std::isfinite(b.max[d]) && b.min[d] <= b.max[d]))
            throw Error(path.string() + ": loader " + loader + " vouched for invalid bounds");
    }
    return b;
}

// With HZ_VERIFY_PLUGIN_CLAIMS (Debug and sanitizer builds), a loader's
// vouched bounds are checked all the same: the host's own pass must find
// every coordinate finite and the same bounds.
void verify_claim([[maybe_unused]] const Tractogram &t, [[maybe_unused]] const Bounds &vouched, [[maybe_unused]] const fs::path &path,
                  [[maybe_unused]] const std::string &loader) {
#ifdef HZ_VERIFY_PLUGIN_CLAIMS
    check_reported_bounds(t, vouched, path, loader);
#endif
}

// Zero-copy positions (HZ_EXT_MAPPED_POSITIONS): maps `nb_vertices` x 3
// float32 at ext.offset of ext.path copy-on-write (the data model may edit
// them; the file never changes), verifies the zip CRC when the loader gave
// one and the finiteness of every coordinate, and returns the bounds. The
// checksum and the scan share one pass over the pages, split over the cores.
// With HZ_EXTENT_DELIMITED, nb_vertices counts the delimiters, and the
// caller checks them and computes the bounds (Tractogram::validate), or
// takes the loader's word for them (HZ_EXTENT_CHECKED).
Buffer<float> map_positions(const hz_positions_extent &ext, std::uint64_t nb_vertices, const fs::path &path, Bounds &bounds) {
    const std::string where = path.string();
    const std::string file = ext.path ? ext.path : "";
    if (file.empty()) throw Error(where + ": loader located the positions in no file");
    const bool delimited = (ext.flags & HZ_EXTENT_DELIMITED) != 0;
    const std::uint64_t bytes = nb_vertices * 12;
    const bool unaligned = ext.offset % 4 != 0;
    if (unaligned && (ext.flags & HZ_EXTENT_UNALIGNED) == 0)
        throw Error(where + ": loader located the positions at a misaligned offset without HZ_EXTENT_UNALIGNED");
    const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw Error(where + ": cannot open " + file + ": " + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || std::uint64_t(st.st_size) < ext.offset ||
        std::uint64_t(st.st_size) - ext.offset < bytes) {
        ::close(fd);
        throw Error(where + ": the positions extend past the end of " + file);
    }
    const std::uint64_t page = static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
    const std::uint64_t start = ext.offset / page * page, len = ext.offset - start + bytes;
    // Mapped read-only, then made writable: a write copies only its page.
    // Extents the host reads at once (to check a CRC) are populated in one
    // call (a populate of a writable private mapping would copy every page);
    // delimited ones fault in as they are used, on every thread reading them.
    void *base = ::mmap(nullptr, len, PROT_READ, MAP_PRIVATE | (delimited ? 0 : MAP_POPULATE), fd, static_cast<off_t>(start));
    const int map_errno = errno;
    ::close(fd);
    if (base == MAP_FAILED) throw Error(where + ": cannot map " + file + ": " + std::strerror(map_errno));
    if (::mprotect(base, len, PROT_READ | PROT_WRITE) != 0) {
        const int e = errno;
        ::munmap(base, len);
        throw Error(where + ": cannot map " + file + " copy-on-write: " + std::strerror(e));
    }
    std::shared_ptr<void> owner(base, [len](void *q) { ::munmap(q, len); });
    unsigned char *first = static_cast<unsigned char *>(base) + (ext.offset - start);
    Buffer<float> mapped;
    if (unaligned) {
        // float32 may not be read at this address (a TCK written by nibabel
        // has its data at byte 67): the floats are copied to aligned memory
        // on their first use, by whoever needs them, on every core, each
        // mapped page dropped once copied. Until then the mapping is the
        // only copy, and a loader that vouched for the extent's content
        // (HZ_EXTENT_CHECKED) spares the host from reading it at all.
        mapped = Buffer<float>::deferred(3 * nb_vertices, [first, bytes, owner](float *dst) {
            auto *out = reinterpret_cast<unsigned char *>(dst);
            const std::uint64_t page = static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
            parallel_ranges(bytes, 64u << 20, [&](std::uint64_t b, std::uint64_t e) {
                constexpr std::uint64_t kChunk = 8u << 20;
                for (std::uint64_t s = b; s < e; s += kChunk) {
                    const std::uint64_t n = std::min(e, s + kChunk) - s;
                    std::memcpy(out + s, first + s, n);
                    // (The whole pages of the chunk: the file keeps them cached.)
                    const auto lo = (reinterpret_cast<std::uintptr_t>(first + s) + page - 1) / page * page;
                    const auto hi = reinterpret_cast<std::uintptr_t>(first + s + n) / page * page;
                    if (hi > lo) ::madvise(reinterpret_cast<void *>(lo), hi - lo, MADV_DONTNEED);
                }
            });
        });
    } else {
        mapped = Buffer<float>(reinterpret_cast<float *>(first), 3 * nb_vertices, std::move(owner));
    }
    if (delimited) return mapped;
    const float *xyz = mapped.data();

    const bool check_crc = (ext.flags & HZ_EXTENT_HAS_CRC32) != 0;
    struct Part {
        std::uint64_t begin, end;
        uLong crc;
        Bounds b;
    };
    std::vector<Part> parts;
    std::mutex mu;
    parallel_ranges(nb_vertices, 1u << 20, [&](std::uint64_t b, std::uint64_t e) {
        Part part{b, e, 0, {}};
        constexpr std::uint64_t kBlock = 16384;  // points: 192 KiB, checksummed then scanned while in cache
        for (std::uint64_t s = b; s < e; s += kBlock) {
            const std::uint64_t n = std::min(e, s + kBlock) - s;
            // libdeflate's CRC-32 uses carry-less multiplication: about 10x zlib's here.
            if (check_crc) part.crc = libdeflate_crc32(static_cast<std::uint32_t>(part.crc), xyz + 3 * s, n * 12);
            merge_bounds(part.b, finite_bounds(xyz + 3 * s, n, where, s));
        }
        std::lock_guard lock(mu);
        parts.push_back(part);
    });
    std::sort(parts.begin(), parts.end(), [](const Part &a, const Part &b) { return a.begin < b.begin; });
    uLong crc = 0;  // (zlib combines the per-thread checksums)
    bounds = Bounds{};
    for (const auto &p : parts) {
        crc = crc32_combine(crc, p.crc, static_cast<z_off_t>((p.end - p.begin) * 12));
        merge_bounds(bounds, p.b);
    }
    if (check_crc && crc != ext.crc32) throw Error(where + ": the positions fail their zip CRC-32 check (the archive is corrupt)");
    return mapped;
}

// Reads extra array `i` of an open reader into the data model.
DataArray read_extra_array(const hz_loader &l, hz_reader *r, uint32_t i, const fs::path &path, const hz_task *task) {
    hz_error err = make_error();
    hz_array_info ai{};
    ai.struct_size = sizeof ai;
    hz_status st = l.get_array_info(r, i, &ai, &err);
    if (st != HZ_OK) throw Error(failure(err, st, path, "get_array_info"));
    DataArray a;
    a.name = ai.name ? ai.name : "";
    a.attach = ai.attach;
    a.dtype = ai.dtype;
    a.components = ai.components;
    a.count = ai.count;
    const std::size_t es = dtype_size(ai.dtype);
    if (es == 0 || ai.components == 0) throw Error(path.string() + ": array '" + a.name + "' has an invalid type");
    a.bytes = Buffer<std::byte>(ai.count * ai.components * es);
    hz_array_view v{};
    v.struct_size = sizeof v;
    v.dtype = ai.dtype;
    v.data = a.bytes.data();
    v.capacity_bytes = a.bytes.size();
    v.ndim = 2;
    v.shape[0] = ai.count;
    v.shape[1] = ai.components;
    v.stride_bytes[0] = static_cast<int64_t>(ai.components * es);
    v.stride_bytes[1] = static_cast<int64_t>(es);
    st = l.read_array ? l.read_array(r, i, &v, task, &err) : HZ_E_UNSUPPORTED;
    if (st != HZ_OK) throw Error(failure(err, st, path, "read_array"));
    return a;
}

}  // namespace

void check_reported_bounds(const Tractogram &t, const Bounds &reported, const fs::path &path, const std::string &loader) {
    const Bounds b = t.validate(path.string());
    if (b.empty != reported.empty || (!b.empty && (b.min != reported.min || b.max != reported.max)))
        throw Error(path.string() + ": loader " + loader + " vouched for bounds its positions do not have");
}

hz_array_view volume_view(const Volume &v) {
    // Contiguous, x fastest; axes beyond the view's 4 merged into the last.
    hz_array_view a{};
    a.struct_size = sizeof a;
    a.dtype = v.dtype;
    a.data = const_cast<std::byte *>(v.voxels.data());
    a.capacity_bytes = v.voxels.size();
    std::vector<std::uint64_t> dims = v.dims;
    while (dims.size() > 4) {
        const auto last = dims.back();
        dims.pop_back();
        dims.back() *= last;
    }
    a.ndim = static_cast<uint32_t>(dims.size());
    std::int64_t stride = static_cast<std::int64_t>(dtype_size(v.dtype));
    for (std::size_t i = 0; i < dims.size(); ++i) {
        a.shape[i] = dims[i];
        a.stride_bytes[i] = stride;
        stride *= static_cast<std::int64_t>(dims[i]);
    }
    return a;
}

std::string matching_extension(const hz_loader &loader, const fs::path &path) {
    const std::string name = lower(path.filename().string());
    std::string best;
    for (const char *const *e = loader.extensions; e != nullptr && *e != nullptr; ++e) {
        const std::string ext = std::string(".") + *e;
        if (name.size() > ext.size() && name.compare(name.size() - ext.size(), ext.size(), ext) == 0 && ext.size() - 1 > best.size())
            best = *e;
    }
    return best;
}

std::string read_small_file(const fs::path &file, std::uint64_t max_bytes, const std::string &what) {
    const std::string name = file.string();
    // O_NONBLOCK: opening a FIFO with no writer must not wait for one.
    const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) throw Error(name + ": cannot open the " + what + ": " + std::strerror(errno));
    struct Closer {
        int fd;
        ~Closer() { ::close(fd); }
    } closer{fd};
    struct stat st {};
    if (::fstat(fd, &st) != 0) throw Error(name + ": cannot read the " + what + ": " + std::strerror(errno));
    if (!S_ISREG(st.st_mode)) throw Error(name + ": the " + what + " is not a regular file");
    const auto too_large = [&] {
        const bool mib = max_bytes >= (1u << 20);
        return Error(name + ": " + what + " larger than " + std::to_string(mib ? max_bytes >> 20 : max_bytes) + (mib ? " MiB" : " bytes"));
    };
    if (std::uint64_t(st.st_size) > max_bytes) throw too_large();
    std::string text(std::size_t(st.st_size), '\0');
    std::size_t got = 0;
    for (;;) {
        if (got == text.size()) {
            if (text.size() > max_bytes) throw too_large();
            text.resize(std::min<std::uint64_t>(max_bytes + 1, text.size() + 65536));
        }
        const ssize_t r = ::read(fd, text.data() + got, text.size() - got);
        if (r < 0 && errno == EINTR) continue;
        if (r < 0) throw Error(name + ": cannot read the " + what + ": " + std::strerror(errno));
        if (r == 0) break;
        got += std::size_t(r);
    }
    if (got > max_bytes) throw too_large();
    text.resize(got);
    return text;
}

const LoadedPlugin &loader_for_read(const Registry &reg, const fs::path &path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw Error(path.string() + ": no such file");
    if (fs::is_directory(path, ec)) {
        // Directory formats (TRX) are claimed by extension only.
    } else if (!fs::is_regular_file(path, ec)) {
        throw Error(path.string() + ": not a regular file");
    }
    const auto loaders = reg.of_kind(HZ_KIND_LOADER);
    const LoadedPlugin *by_ext = nullptr;
    std::size_t best_len = 0;
    std::uint32_t probe_bytes = 0;
    for (const auto *p : loaders) {
        const hz_loader *l = p->loader();
        if (!(l->caps & HZ_LOADER_CAN_READ)) continue;
        probe_bytes = std::max(probe_bytes, std::min<std::uint32_t>(l->probe_bytes, 65536));
        const std::string ext = matching_extension(*l, path);
        if (!ext.empty() && ext.size() > best_len) {
            by_ext = p;
            best_len = ext.size();
        }
    }
    std::vector<unsigned char> head;
    if (!fs::is_directory(path, ec)) head = read_head(path, std::max<std::uint32_t>(probe_bytes, 16));
    const std::string hint = path.filename().string();
    // Each loader's probe() guarded (plugin_guard.hpp): one that crashes or
    // does not return within the plugin timeout is named, and not asked again;
    // the others still are (a file with no known extension asks them all).
    auto score = [&](const LoadedPlugin *p) {
        const hz_loader *l = p->loader();
        if (l->probe == nullptr || p->faulted()) return 0;
        PluginCallSite site;
        site.plugin = p->info.file.c_str();
        site.call = "probe";
        site.timeout_s = plugin_call_timeout();
        int32_t s = 0;
        bool threw = false;
        std::string thrown = "not a std::exception";
        if (!guarded_call(site, [&] {
                try {
                    s = l->probe(head.data(), head.size(), hint.c_str());
                } catch (const std::exception &e) {
                    threw = true, thrown = e.what();
                } catch (...) {
                    threw = true;
                }
            })) {
            p->module->mark_faulted();
            spdlog::warn("{}: the plugin {} ({}) {}: not asked again; move it out of the plugin folders or report it to its author",
                         path.string(), p->info.id, p->info.file, fault_text(site));
            return 0;
        }
        if (threw) throw Error(p->escaped("probe", path.string(), thrown.c_str()));
        return int(s);
    };
    if (by_ext != nullptr && score(by_ext) >= 50) return *by_ext;
    const LoadedPlugin *best = nullptr;
    int best_score = 49;
    for (const auto *p : loaders) {
        if (p == by_ext || !(p->loader()->caps & HZ_LOADER_CAN_READ)) continue;
        const int s = score(p);
        if (s > best_score) {
            best = p;
            best_score = s;
        }
    }
    if (best != nullptr) return *best;
    // Let the extension's loader explain what is wrong with the file.
    if (by_ext != nullptr) return *by_ext;
    throw Error(path.string() + ": no loader recognises this file (" + std::to_string(loaders.size()) +
                " loaders tried; see `horizon plugins`)");
}

const LoadedPlugin &loader_for_write(const Registry &reg, const fs::path &path, hz_data_kind kind) {
    const LoadedPlugin *best = nullptr;
    std::size_t best_len = 0;
    bool best_holds = false;
    for (const auto *p : reg.of_kind(HZ_KIND_LOADER)) {
        const hz_loader *l = p->loader();
        if (!(l->caps & HZ_LOADER_CAN_WRITE) || l->write == nullptr) continue;
        const std::string ext = matching_extension(*l, path);
        if (ext.empty()) continue;
        const bool holds = kind != 0 && (l->data_kinds & kind);
        if ((holds && !best_holds) || (holds == best_holds && ext.size() > best_len)) {
            best = p;
            best_len = ext.size();
            best_holds = holds;
        }
    }
    if (best == nullptr)
        throw Error(path.string() + ": no writer for extension '" + path.extension().string() + "' (see `horizon plugins`)");
    return *best;
}

void make_resident(const void *p, std::size_t bytes) {
#ifdef MADV_POPULATE_READ
    const std::uint64_t page = static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
    const std::uintptr_t b = reinterpret_cast<std::uintptr_t>(p) / page * page;
    const std::uintptr_t e = reinterpret_cast<std::uintptr_t>(p) + bytes;
    if (bytes == 0 || e <= b) return;
    const std::uint64_t pages = (e - b + page - 1) / page;
    parallel_ranges(pages, 4096, [&](std::uint64_t lo, std::uint64_t hi) {
        (void)::madvise(reinterpret_cast<void *>(b + lo * page), (hi - lo) * page, MADV_POPULATE_READ);
    });
#else
    (void)p;
    (void)bytes;
#endif
}

namespace {
Dataset read_dataset_unguarded(const Registry &reg, const fs::path &path, const hz_task *task, const ReadLimits &limits);
}

Dataset read_dataset(const Registry &reg, const fs::path &path, const hz_task *task, const ReadLimits &limits) {
    try {
        return read_dataset_unguarded(reg, path, task, limits);
    } catch (const std::bad_alloc &) {
        throw Error(path.string() + ": out of memory while reading it (the data do not fit in this machine's memory)");
    }
}

namespace {
Dataset read_dataset_unguarded(const Registry &reg, const fs::path &path, const hz_task *task, const ReadLimits &limits) {
    const LoadedPlugin &p = loader_for_read(reg, path);
    const hz_loader *l = p.loader();
    if (l->open == nullptr || l->get_info == nullptr) throw Error(path.string() + ": loader " + p.info.id + " cannot read");
    hz_error err = make_error();
    ReaderGuard g{l};
    hz_open_request req{};
    req.struct_size = sizeof req;
    const std::string spath = path.string();
    req.path = spath.c_str();
    // A loader whose open() reads the whole file takes the task there too
    // (HZ_EXT_OPEN_TASK): progress and cancel from the first byte.
    const auto *with_task = p.extension<hz_ext_open_task>(HZ_EXT_OPEN_TASK);
    hz_status st = p.call("open", spath, [&] {
        return with_task != nullptr && with_task->open != nullptr ? with_task->open(&req, task, &g.r, &err) : l->open(&req, &g.r, &err);
    });
    if (st != HZ_OK || g.r == nullptr) throw Error(failure(err, st, path, "open"));
    // The next phase (allocation, then the decode, which reports its own
    // fraction) starts with an unknown fraction, not the scan's 100 %.
    if (task != nullptr && task->report != nullptr) task->report(task, -1.0, nullptr);
    hz_dataset_info info{};
    info.struct_size = sizeof info;
    st = p.call("get_info", spath, [&] { return l->get_info(g.r, &info, &err); });
    if (st != HZ_OK) throw Error(failure(err, st, path, "get_info"));

    Dataset ds;
    ds.kind = info.kind;
    ds.format.assign(info.format, strnlen(info.format, sizeof info.format));
    ds.loader_id = p.info.id;
    ds.source_space = info.source_space;
    if (l->visit_metadata != nullptr) {
        l->visit_metadata(
            g.r,
            [](void *ctx, const char *k, const char *v) { static_cast<Dataset *>(ctx)->metadata.emplace_back(k ? k : "", v ? v : ""); },
            &ds, &err);
    }

    if (info.kind == HZ_DATA_STREAMLINES) {
        if (l->read_streamlines == nullptr) throw Error(path.string() + ": loader " + p.info.id + " has no read_streamlines");
        Tractogram &t = ds.tractogram;
        std::copy(std::begin(info.voxel_to_ras), std::end(info.voxel_to_ras), t.reference.begin());
        std::copy(std::begin(info.ref_dims), std::end(info.ref_dims), t.reference_dims.begin());
        // Zero-copy when the loader can say where float32 RAS+ mm positions
        // lie (HZ_EXT_MAPPED_POSITIONS).
        const auto *located = p.extension<hz_ext_mapped_positions>(HZ_EXT_MAPPED_POSITIONS);
        if (located != nullptr && (located->locate_positions == nullptr || located->read_offsets == nullptr)) located = nullptr;
        const auto *checked = p.extension<hz_ext_checked_read>(HZ_EXT_CHECKED_READ);
        if (checked != nullptr && checked->read_streamlines_checked == nullptr) checked = nullptr;
        hz_positions_extent ext{};
        ext.struct_size = sizeof ext;
        ext.accepts = HZ_EXTENT_DELIMITED | HZ_EXTENT_CHECKED | HZ_EXTENT_UNALIGNED;
        bool mapped = false;
        if (located != nullptr && info.nb_vertices > 0) {
            st = located->locate_positions(g.r, &ext, &err);
            if (st == HZ_OK)
                mapped = true;
            else if (st != HZ_E_UNSUPPORTED)
                throw Error(failure(err, st, path, "locate_positions"));
            err = make_error();
            if (mapped && (ext.flags & ~(HZ_EXTENT_HAS_CRC32 | HZ_EXTENT_DELIMITED | HZ_EXTENT_CHECKED | HZ_EXTENT_UNALIGNED)) != 0)
                throw Error(path.string() + ": loader located the positions with a layout flag the host does not know");
        }
        const bool delimited = mapped && (ext.flags & HZ_EXTENT_DELIMITED) != 0;
        // (A delimited extent holds one more vertex per streamline.)
        const std::uint64_t stored = info.nb_vertices + (delimited ? info.nb_streamlines : 0);
        // Loaders validate declared sizes against the file before reporting them.
        t.offsets = Buffer<std::uint64_t>(info.nb_streamlines + 1);
        hz_streamlines_dst dst{};
        dst.struct_size = sizeof dst;
        hz_positions_check check{};
        check.struct_size = sizeof check;
        if (!mapped) {
            {
                const std::size_t n = 3 * info.nb_vertices;
                if (n) {
                    std::shared_ptr<void> block;
                    try {
                        block = allocate_spillable(n * sizeof(float));
                    } catch (const Error &e) {
                        throw Error(path.string() + ": its decoded positions: " + e.what());
                    }
                    float *p = static_cast<float *>(block.get());
                    t.positions = Buffer<float>(p, n, std::move(block));
                }
            }
            dst.positions = t.positions.data();
            dst.positions_capacity = t.positions.size();
        }
        dst.offsets = t.offsets.data();
        dst.offsets_capacity = t.offsets.size();
        if (mapped) {  // (the positions are mapped: only the offsets are read)
            st = p.call("read_offsets", spath, [&] { return located->read_offsets(g.r, t.offsets.data(), t.offsets.size(), task, &err); });
            if (st != HZ_OK) throw Error(failure(err, st, path, "read_offsets"));
        } else if (checked != nullptr) {  // (the loader may vouch for what it wrote)
            st =
                p.call("read_streamlines_checked", spath, [&] { return checked->read_streamlines_checked(g.r, &dst, &check, task, &err); });
            if (st != HZ_OK) throw Error(failure(err, st, path, "read_streamlines_checked"));
        } else {
            st = p.call("read_streamlines", spath, [&] { return l->read_streamlines(g.r, &dst, task, &err); });
            if (st != HZ_OK) throw Error(failure(err, st, path, "read_streamlines"));
        }
        if (delimited) {
            t.positions = map_positions(ext, stored, path, ds.bounds);
            t.gap = 1;
            ds.mapped = true;
            ds.unaligned = ext.offset % 4 != 0;
            if ((ext.flags & HZ_EXTENT_CHECKED) != 0) {
                // The loader read every coordinate while opening the file and
                // vouches for them (the ABI contract; `horizon validate`
                // checks it): the extent stays unread until it is used.
                t.validate_offsets(path.string());
                ds.bounds = vouched_bounds(ext.bounds_min, ext.bounds_max, path, p.info.id);
                verify_claim(t, ds.bounds, path, p.info.id);
            } else {  // the delimiters and coordinates are checked with the offsets
                ds.bounds = t.validate(path.string());
            }
        } else if (mapped) {  // the coordinates are checked as they are mapped
            t.positions = map_positions(ext, info.nb_vertices, path, ds.bounds);
            ds.mapped = true;
            ds.unaligned = ext.offset % 4 != 0;
            t.validate_offsets(path.string());
        } else if (check.vouched != 0 && info.nb_vertices > 0) {
            // The loader looked at every coordinate as it decoded them and
            // vouches for them: the copy is not read again here.
            t.validate_offsets(path.string());
            ds.bounds = vouched_bounds(check.bounds_min, check.bounds_max, path, p.info.id);
            verify_claim(t, ds.bounds, path, p.info.id);
        } else {
            ds.bounds = t.validate(path.string());
        }
        for (uint32_t i = 0; i < info.nb_arrays; ++i) t.arrays.push_back(read_extra_array(*l, g.r, i, path, task));
        // Per-vertex data index the streamlines' vertices: no delimiters between them.
        if (t.gap != 0 && std::any_of(t.arrays.begin(), t.arrays.end(), [](const DataArray &a) { return a.attach == HZ_ATTACH_VERTEX; })) {
            t = t.compacted();
            ds.mapped = false;
            ds.unaligned = false;
        }
    } else if (info.kind == HZ_DATA_VOLUME || info.kind == HZ_DATA_IMAGE) {
        if (l->read_volume == nullptr) throw Error(path.string() + ": loader " + p.info.id + " has no read_volume");
        Volume &v = ds.volume;
        v.dtype = info.dtype;
        const std::size_t es = dtype_size(info.dtype);
        if (es == 0 || info.ndim < 1 || info.ndim > 7) throw Error(path.string() + ": loader reports an invalid volume layout");
        v.dims.assign(info.dims, info.dims + info.ndim);
        // Loaders check sizes against the file before reporting them, but a
        // compressed image or volume may unpack to anything (a 0.8 MB PNG of
        // 16384 x 16384): its size is bounded before it is allocated.
        std::uint64_t n = 1;
        std::string shape;
        for (auto d : v.dims) {
            if (d != 0 && n > std::numeric_limits<std::uint64_t>::max() / es / d) throw Error(path.string() + ": its dimensions overflow");
            n *= d;
            shape += (shape.empty() ? "" : "x") + std::to_string(d);
        }
        if (info.kind == HZ_DATA_IMAGE && limits.max_pixels != 0 && v.dims.size() == 3 && v.dims[1] * v.dims[2] > limits.max_pixels)
            throw Error(path.string() + ": " + limits.what + " of " + std::to_string(v.dims[1]) + "x" + std::to_string(v.dims[2]) +
                        " pixels, more than the " + std::to_string(limits.max_pixels) + " it may have: downsample it");
        if (const std::size_t available = memory_available(); n * es > available)
            throw Error(path.string() + ": its " + shape + " values need " + gb(double(n * es)) + " of memory, and " +
                        gb(double(available)) + " are available");
        v.voxels = Buffer<std::byte>(n * es);
        v.scale_slope = info.scale_slope;
        v.scale_inter = info.scale_inter;
        std::copy(std::begin(info.voxel_to_ras), std::end(info.voxel_to_ras), v.voxel_to_ras.begin());
        hz_array_view dst = volume_view(v);
        st = p.call("read_volume", spath, [&] { return l->read_volume(g.r, &dst, task, &err); });
        if (st != HZ_OK) throw Error(failure(err, st, path, "read_volume"));
    } else if (info.kind == HZ_DATA_MESH) {
        if (l->read_mesh == nullptr) throw Error(path.string() + ": loader " + p.info.id + " has no read_mesh");
        Mesh &m = ds.mesh;
        m.vertices = Buffer<float>(3 * info.nb_vertices);
        m.faces = Buffer<std::uint32_t>(3 * info.nb_faces);
        hz_mesh_dst dst{};
        dst.struct_size = sizeof dst;
        dst.vertices = m.vertices.data();
        dst.vertices_capacity = m.vertices.size();
        dst.faces = m.faces.data();
        dst.faces_capacity = m.faces.size();
        st = p.call("read_mesh", spath, [&] { return l->read_mesh(g.r, &dst, task, &err); });
        if (st != HZ_OK) throw Error(failure(err, st, path, "read_mesh"));
        for (std::size_t i = 0; i < m.faces.size(); ++i)
            if (m.faces[i] >= m.nb_vertices())
                throw Error(path.string() + ": triangle " + std::to_string(i / 3) + " uses a vertex out of range");
        std::copy(std::begin(info.voxel_to_ras), std::end(info.voxel_to_ras), m.transform.begin());
        for (uint32_t i = 0; i < info.nb_arrays; ++i) m.arrays.push_back(read_extra_array(*l, g.r, i, path, task));
    } else {
        throw Error(path.string() + ": " + kind_name(info.kind) + " data is not supported by this build of the host yet");
    }
    return ds;
}
}  // namespace

void write_dataset(const Registry &reg, const Dataset &ds, const fs::path &path, bool force, std::vector<std::string> *dropped,
                   const fs::path &protect, const hz_task *task, const std::vector<std::uint64_t> *selection) {
    std::error_code ec;
    if (selection != nullptr) {
        const std::uint64_t N = ds.kind == HZ_DATA_STREAMLINES ? ds.tractogram.nb_streamlines() : 0;
        if (ds.kind != HZ_DATA_STREAMLINES) throw Error(path.string() + ": a selection of streamlines to write from data without any");
        for (std::size_t k = 0; k < selection->size(); ++k)
            if ((*selection)[k] >= N || (k > 0 && (*selection)[k] <= (*selection)[k - 1]))
                throw Error(path.string() + ": the streamlines to write are not an increasing selection of the " + std::to_string(N));
    }
    if (!protect.empty() && fs::exists(path, ec) && fs::equivalent(path, protect, ec))
        throw Error(path.string() + ": refusing to overwrite the input file");
    check_output_target(path);
    if (fs::exists(path, ec) && !force) throw Error(path.string() + ": already exists (use --force to replace it)");
    const LoadedPlugin &p = loader_for_write(reg, path, ds.kind);
    const hz_loader *l = p.loader();
    if (!(l->data_kinds & ds.kind)) throw Error(path.string() + ": " + p.info.name + " cannot hold " + kind_name(ds.kind) + " data");
    // A selection goes to a writer that offers hz.ext.write-selection/1 with
    // the whole tractogram (its streamlines and per-vertex arrays read where
    // they lie). For another writer, or a mapped TCK's delimiters that it
    // cannot take as they are, the selected streamlines are copied first (into a
    // temporary file beyond kSpillBytes: bounded memory whatever is written).
    const hz_ext_write_selection *selective = nullptr;
    if (selection != nullptr) {
        selective = p.extension<hz_ext_write_selection>(HZ_EXT_WRITE_SELECTION);
        const bool vertex_arrays = std::any_of(ds.tractogram.arrays.begin(), ds.tractogram.arrays.end(),
                                               [](const DataArray &a) { return a.attach == HZ_ATTACH_VERTEX; });
        if (selective == nullptr || selective->write_selection == nullptr ||
            (ds.tractogram.gap != 0 && (vertex_arrays || !p.takes_gap()))) {
            Dataset copy;
            copy.kind = ds.kind;
            copy.format = ds.format;
            copy.loader_id = ds.loader_id;
            copy.source_space = ds.source_space;
            copy.metadata = ds.metadata;
            try {
                copy.tractogram = subset_with_arrays(ds.tractogram, *selection, /*spill=*/true);
            } catch (const Error &e) {  // (a copy that fits nowhere: named by the file it was for)
                throw Error(path.string() + ": the streamlines to write, copied first for " + p.info.name + ": " + e.what());
            }
            write_dataset(reg, copy, path, force, dropped, protect, task);
            return;
        }
    }

    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!fs::is_directory(dir, ec)) throw Error(path.string() + ": directory " + dir.string() + " does not exist");
    remove_stale_temporaries(path);
    TemporaryFile tmp_file(temporary_path(path));
    const fs::path &tmp = tmp_file.path();

    std::vector<hz_metadata_entry> meta;
    for (const auto &[k, v] : ds.metadata) meta.push_back({k.c_str(), v.c_str()});
    std::vector<hz_named_array> arrays;
    const std::vector<DataArray> selected_arrays =
        selective != nullptr ? arrays_of_selection(ds.tractogram, *selection, /*gather_vertex_arrays=*/false) : std::vector<DataArray>{};
    const std::vector<DataArray> &src_arrays = ds.kind == HZ_DATA_MESH ? ds.mesh.arrays
                                               : selective != nullptr  ? selected_arrays
                                                                       : ds.tractogram.arrays;
    for (const auto &a : src_arrays) {
        hz_named_array na{};
        na.struct_size = sizeof na;
        na.attach = a.attach;
        na.name = a.name.c_str();
        na.dtype = a.dtype;
        na.components = a.components;
        na.count = a.count;
        na.data = a.bytes.data();
        arrays.push_back(na);
    }
    hz_dataset_view view{};
    view.struct_size = sizeof view;
    view.kind = ds.kind;
    if (ds.kind == HZ_DATA_VOLUME || ds.kind == HZ_DATA_IMAGE) {
        view.voxels = volume_view(ds.volume);
        std::copy(ds.volume.voxel_to_ras.begin(), ds.volume.voxel_to_ras.end(), view.voxel_to_ras);
        view.volume_ndim = static_cast<uint32_t>(std::min<std::size_t>(ds.volume.dims.size(), 8));
        std::copy_n(ds.volume.dims.begin(), view.volume_ndim, view.volume_dims);
        view.scale_slope = ds.volume.scale_slope;
        view.scale_inter = ds.volume.scale_inter;
    }
    if (ds.kind == HZ_DATA_MESH) {
        view.mesh_vertices = ds.mesh.vertices.data();
        view.mesh_nb_vertices = ds.mesh.nb_vertices();
        view.mesh_faces = ds.mesh.faces.data();
        view.mesh_nb_faces = ds.mesh.nb_faces();
        std::copy(ds.mesh.transform.begin(), ds.mesh.transform.end(), view.voxel_to_ras);
    }
    // A mapped TCK keeps its delimiters (gap 1) for a writer that takes them
    // (HZ_EXT_DELIMITED_STREAMLINES) and when no per-vertex array is indexed
    // around them; other writers get a copy without them.
    const bool pass_gap = ds.kind == HZ_DATA_STREAMLINES && p.takes_gap() &&
                          std::none_of(ds.tractogram.arrays.begin(), ds.tractogram.arrays.end(),
                                       [](const DataArray &a) { return a.attach == HZ_ATTACH_VERTEX; });
    const Tractogram compact = ds.kind != HZ_DATA_STREAMLINES ? Tractogram{}
                               : pass_gap                     ? ds.tractogram.shared()
                                                              : ds.tractogram.compacted();
    if (ds.kind == HZ_DATA_STREAMLINES) {
        view.streamlines = compact.view();
        std::copy(ds.tractogram.reference.begin(), ds.tractogram.reference.end(), view.voxel_to_ras);
        std::copy(ds.tractogram.reference_dims.begin(), ds.tractogram.reference_dims.end(), view.ref_dims);
    }
    view.nb_arrays = static_cast<uint32_t>(arrays.size());
    view.arrays = arrays.data();
    view.nb_metadata = static_cast<uint32_t>(meta.size());
    view.metadata = meta.data();

    const std::string stmp = tmp.string();
    const std::string sfinal = path.string();
    const std::string ext = matching_extension(*l, path);
    // Companion files of multi-file formats: (temporary, final) pairs.
    struct Companions {
        fs::path dir;
        std::vector<std::pair<fs::path, fs::path>> files;
        std::vector<std::unique_ptr<TemporaryFile>> temps;  // removed unless published
    } companions{dir, {}, {}};
    hz_write_request req{};
    req.struct_size = sizeof req;
    req.path = stmp.c_str();
    req.extension = ext.c_str();
    req.on_dropped = [](void *ctx, const char *what) {
        if (ctx != nullptr && what != nullptr) static_cast<std::vector<std::string> *>(ctx)->emplace_back(what);
    };
    std::vector<std::string> local_dropped;
    req.ctx = dropped != nullptr ? dropped : &local_dropped;
    req.final_path = sfinal.c_str();
    req.add_companion = [](void *ctx, const char *temp, const char *final) -> hz_status {
        if (ctx == nullptr || temp == nullptr || final == nullptr) return HZ_E_INVALID_ARGUMENT;
        auto *c = static_cast<Companions *>(ctx);
        std::error_code e;
        const fs::path t(temp), f(final);
        // Both must lie in the target's directory: a plugin cannot rename files elsewhere.
        if (!fs::equivalent(t.has_parent_path() ? t.parent_path() : fs::path("."), c->dir, e) ||
            !fs::equivalent(f.has_parent_path() ? f.parent_path() : fs::path("."), c->dir, e) || !f.has_filename())
            return HZ_E_INVALID_ARGUMENT;
        try {
            c->temps.push_back(std::make_unique<TemporaryFile>(t));
            c->files.emplace_back(t, f);
        } catch (...) {
            return HZ_E_OUT_OF_MEMORY;
        }
        return HZ_OK;
    };
    req.companion_ctx = &companions;
    hz_error err = make_error();
    const hz_status st = p.call(selective != nullptr ? "write_selection" : "write", path.string(), [&] {
        return selective != nullptr ? selective->write_selection(&req, &view, selection->data(), selection->size(), task, &err)
                                    : l->write(&req, &view, task, &err);
    });
    if (st != HZ_OK) {
        std::string msg = err.message[0] ? err.message : ("write failed with status " + std::to_string(st));
        // Report the user's target, not our temporary name.
        for (auto pos = msg.find(stmp); pos != std::string::npos; pos = msg.find(stmp)) msg.replace(pos, stmp.size(), path.string());
        if (msg.find(path.string()) == std::string::npos) msg = path.string() + ": " + msg;
        throw Error(msg);
    }
    // Companions first, so the main file never appears without them.
    for (const auto &[t, f] : companions.files) {
        if (!fs::exists(t, ec)) {
            throw Error(path.string() + ": the writer reported a companion file it did not write (" + f.string() + ")");
        }
        if (fs::exists(f, ec) && (!protect.empty() && fs::equivalent(f, protect, ec))) {
            throw Error(f.string() + ": refusing to overwrite the input file");
        }
        if (fs::exists(f, ec) && !force) {
            throw Error(f.string() + ": already exists (use --force to replace it)");
        }
        check_output_target(f);
    }
    // (the companions and the main file as a unit: all in place, or none)
    std::vector<std::pair<TemporaryFile *, fs::path>> unit;
    for (std::size_t i = 0; i < companions.files.size(); ++i) unit.emplace_back(companions.temps[i].get(), companions.files[i].second);
    unit.emplace_back(&tmp_file, path);
    publish_together(unit, force);
}

void write_text_atomic(const fs::path &path, const std::string &text, bool force) {
    std::error_code ec;
    if (path == "-") {  // standard output
        std::fwrite(text.data(), 1, text.size(), stdout);
        if (std::fflush(stdout) != 0 || std::ferror(stdout))
            throw Error(std::string("standard output: write failed: ") + std::strerror(errno));
        return;
    }
    check_output_target(path);
    if (fs::exists(path, ec) && !force) throw Error(path.string() + ": already exists (use --force to replace it)");
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!fs::is_directory(dir, ec)) throw Error(path.string() + ": directory " + dir.string() + " does not exist");
    remove_stale_temporaries(path);
    TemporaryFile tmp(temporary_path(path));
    {
        const int fd = ::open(tmp.path().c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
        if (fd < 0) throw Error(path.string() + ": cannot create a temporary file: " + std::strerror(errno));
        std::size_t done = 0;
        while (done < text.size()) {
            const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) {
                const int e = n < 0 ? errno : EIO;
                ::close(fd);
                throw Error(path.string() + ": write failed: " + std::strerror(e));
            }
            done += std::size_t(n);
        }
        if (::close(fd) != 0) throw Error(path.string() + ": write failed: " + std::strerror(errno));
    }
    publish(tmp, path, force);
}

}  // namespace hz::core
