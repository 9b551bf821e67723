#include <hz/core/data.hpp>
#include <hz/cpp/plugin.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <mutex>
#include <new>
#include <string>
#include <system_error>
#include <thread>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/statvfs.h>
#include <unistd.h>

namespace hz::core {

namespace {

// Gives a large block's pages back to the kernel on several cores, then
// frees it. Unmapping 1.2 GB of written pages is the kernel's work page by
// page (0.06-0.07 s here, a sixth of loading a 1.2 GB TRK file); munmap does
// it on one core, while MADV_DONTNEED on disjoint parts runs on as many as
// call it (0.033 s on two). Only whole pages inside [p, p + bytes) are
// dropped: the allocator's own header before p is left alone. Never throws:
// without a thread it all runs on the caller's.
void release_in_parallel(void *p, std::size_t bytes) noexcept {
    const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
    const std::uintptr_t b = (reinterpret_cast<std::uintptr_t>(p) + page - 1) / page * page,
                         e = (reinterpret_cast<std::uintptr_t>(p) + bytes) / page * page;
    if (e <= b) return;
    auto drop = [&](std::uint64_t lo, std::uint64_t hi) {  // (in pages from b)
        (void)::madvise(reinterpret_cast<void *>(b + lo * page), (hi - lo) * page, MADV_DONTNEED);
    };
    try {
        parallel_ranges((e - b) / page, (std::uint64_t(16) << 20) / page, drop);
    } catch (...) {  // (only when even the thread list cannot be allocated)
        drop(0, (e - b) / page);
    }
}

constexpr std::size_t kParallelRelease = std::size_t(64) << 20;

}  // namespace

std::size_t memory_available() {
    if (const char *m = std::getenv("HORIZON_MEMORY_AVAILABLE_MB"); m && *m) return std::size_t(std::strtoull(m, nullptr, 10)) << 20;
    std::ifstream in("/proc/meminfo");
    for (std::string line; std::getline(in, line);)
        if (line.rfind("MemAvailable:", 0) == 0) return std::size_t(std::strtoull(line.c_str() + 13, nullptr, 10)) << 10;
    return std::numeric_limits<std::size_t>::max();
}

// (MB below a tenth of a GB, which would read "0.0 GB")
std::string gb(double bytes) { return bytes < 1e8 ? fmt::format("{:.0f} MB", bytes / 1e6) : fmt::format("{:.1f} GB", bytes / 1e9); }

std::shared_ptr<void> allocate_uninitialised(std::size_t bytes) {
    // (Transparent huge pages and populated anonymous mappings were measured
    // for 1 GB decodes here: no faster, and huge pages much slower when the
    // kernel had to compact memory for them.)
    const std::size_t size = (bytes + 63) / 64 * 64;
    void *p = std::aligned_alloc(64, size);
    if (p == nullptr) throw std::bad_alloc();
    if (size < kParallelRelease) return std::shared_ptr<void>(p, [](void *q) { std::free(q); });
    return std::shared_ptr<void>(p, [size](void *q) {
        release_in_parallel(q, size);
        std::free(q);
    });
}

std::shared_ptr<void> allocate_spillable(std::size_t bytes) {
    std::size_t from = kSpillBytes;
    if (const char *m = std::getenv("HORIZON_SPILL_MIN_BYTES"); m && *m) from = std::strtoull(m, nullptr, 10);  // (tests)
    if (bytes == 0 || bytes < from) return allocate_uninitialised(bytes);
    const char *env = std::getenv("HORIZON_SPILL_DIR");
    const std::string dir = env && *env ? env : "/var/tmp";
    // Where no temporary file holds it, anonymous memory, if there is that
    // much to be had: a block larger than the memory available would be
    // swapped, or the process killed by the kernel later, half-way through
    // its work; it is refused now instead, saying what to do.
    auto in_memory = [&](const std::string &why) {
        if (const std::size_t available = memory_available(); bytes > available)
            throw Error(fmt::format("{} to hold: {}, and {} of memory are available (HORIZON_SPILL_DIR=DIR names a folder with room)",
                                    gb(double(bytes)), why, gb(double(available))));
        return allocate_uninitialised(bytes);
    };
    if (dir == "off") return in_memory("no temporary file (HORIZON_SPILL_DIR=off)");
    const int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
    if (fd < 0) return in_memory(fmt::format("no temporary file in {} ({})", dir, std::strerror(errno)));
    // The blocks are reserved now (a full disk is found here, not as a
    // SIGBUS on a later write into the mapping).
    if (const int rc = ::posix_fallocate(fd, 0, off_t(bytes)); rc != 0) {
        struct statvfs fs {};
        const double free_bytes = ::fstatvfs(fd, &fs) == 0 ? double(fs.f_bavail) * double(fs.f_frsize) : 0.0;
        ::close(fd);
        return in_memory(fmt::format("{} has {} free ({})", dir, gb(free_bytes), std::strerror(rc)));
    }
    // Not populated here: the decode's threads fault the pages in as they
    // write them, in parallel (MAP_POPULATE did it on one thread first:
    // a 1M-streamline TRK, 2.1 GB of positions, opened in 1.9-4.5 s with
    // it and 0.9-1.0 s without, alternating runs).
    void *p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    const int map_errno = errno;
    ::close(fd);  // (the mapping keeps the file; unlinked, it goes with it)
    if (p == MAP_FAILED) return in_memory(fmt::format("a temporary file in {} cannot be mapped ({})", dir, std::strerror(map_errno)));
    spdlog::debug("{} MB decoded into a temporary file in {}", bytes >> 20, dir);
    return std::shared_ptr<void>(p, [bytes](void *q) { ::munmap(q, bytes); });
}

void parallel_ranges(std::uint64_t n, std::uint64_t grain, const std::function<void(std::uint64_t, std::uint64_t)> &fn) {
    const std::uint64_t hw = std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
    const std::uint64_t parts = std::max<std::uint64_t>(1, std::min(hw, n / std::max<std::uint64_t>(grain, 1)));
    if (parts <= 1) {
        if (n) fn(0, n);
        return;
    }
    std::vector<std::exception_ptr> errors(parts);
    std::vector<std::thread> threads;
    auto run = [&](std::uint64_t k) {
        try {
            fn(n * k / parts, n * (k + 1) / parts);
        } catch (...) {
            errors[k] = std::current_exception();
        }
    };
    threads.reserve(parts - 1);
    for (std::uint64_t k = 1; k < parts; ++k) {
        try {
            threads.emplace_back(run, k);
        } catch (const std::system_error &) {  // no thread to be had: this one runs that range too
            run(k);
        }
    }
    run(0);
    for (auto &t : threads) t.join();
    for (auto &e : errors)
        if (e) std::rethrow_exception(e);
}

void merge_bounds(Bounds &a, const Bounds &b) {
    if (b.empty) return;
    if (a.empty) {
        a = b;
        return;
    }
    for (int d = 0; d < 3; ++d) {
        a.min[d] = std::min(a.min[d], b.min[d]);
        a.max[d] = std::max(a.max[d], b.max[d]);
    }
}

namespace {

// The kernel of finite_bounds: 16 points (48 floats) per step into 48
// running minima/maxima (lane k holds coordinate k % 3) and one "not finite"
// flag, branch-free, so the compiler vectorises it at any width: SSE2 by
// default, AVX2 or AVX-512 in the clones picked at load time (GCC's
// target_clones; no intrinsics). Returns false when a value is not finite.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#endif
bool minmax48(const float *q, std::uint64_t steps, float *mn, float *mx) {
    unsigned bad = 0;
    for (std::uint64_t i = 0; i < steps; ++i, q += 48)
        for (int k = 0; k < 48; ++k) {
            const float v = q[k];
            bad |= !(std::fabs(v) <= 3.4028235e38f);
            mn[k] = v < mn[k] ? v : mn[k];
            mx[k] = v > mx[k] ? v : mx[k];
        }
    return bad == 0;
}

// minmax48 for data that holds NaN delimiters: running minima/maxima that a
// NaN never changes (lanes start at +/-inf), and the count of values that
// are not finite.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#endif
std::uint64_t
minmax48_count(const float *q, std::uint64_t steps, float *mn, float *mx) {
    std::uint32_t bad[48] = {};
    for (std::uint64_t i = 0; i < steps; ++i, q += 48)
        for (int k = 0; k < 48; ++k) {
            const float v = q[k];
            bad[k] += !(std::fabs(v) <= 3.4028235e38f);
            mn[k] = v < mn[k] ? v : mn[k];
            mx[k] = v > mx[k] ? v : mx[k];
        }
    std::uint64_t n = 0;
    for (int k = 0; k < 48; ++k) n += bad[k];
    return n;
}

// Points [0, n) into the 48 lanes of minmax48_count (started at +/-inf),
// the tail one point at a time; returns the count of values not finite.
std::uint64_t minmax_nan(const float *xyz, std::uint64_t n, float *mn, float *mx) {
    const std::uint64_t whole = n / 16 * 16;
    std::uint64_t bad = minmax48_count(xyz, whole / 16, mn, mx);
    for (std::uint64_t i = whole; i < n; ++i)
        for (int d = 0; d < 3; ++d) {
            const float v = xyz[3 * i + d];
            bad += !std::isfinite(v);
            mn[d] = v < mn[d] ? v : mn[d];
            mx[d] = v > mx[d] ? v : mx[d];
        }
    return bad;
}

// The 48 lanes of minmax48_count folded into bounds (empty when no lane saw
// a number).
Bounds fold48_nan(const float *mn, const float *mx) {
    Bounds b;
    for (int d = 0; d < 3; ++d) {
        b.min[d] = HUGE_VAL;
        b.max[d] = -HUGE_VAL;
        for (int k = d; k < 48; k += 3) {
            b.min[d] = std::min(b.min[d], double(mn[k]));
            b.max[d] = std::max(b.max[d], double(mx[k]));
        }
    }
    b.empty = !(b.min[0] <= b.max[0]);
    if (b.empty) b = Bounds{};
    return b;
}

// The points [whole, n) folded into the 48 lanes, then the lanes into bounds.
Bounds fold48(const float *xyz, std::uint64_t n, std::uint64_t whole, float *mn, float *mx) {
    for (std::uint64_t i = whole; i < n; ++i)
        for (int d = 0; d < 3; ++d) {
            mn[d] = std::min(mn[d], xyz[3 * i + d]);
            mx[d] = std::max(mx[d], xyz[3 * i + d]);
        }
    Bounds b;
    b.empty = false;
    for (int d = 0; d < 3; ++d) {
        b.min[d] = b.max[d] = xyz[d];
        for (int k = d; k < 48; k += 3) {
            b.min[d] = std::min(b.min[d], double(mn[k]));
            b.max[d] = std::max(b.max[d], double(mx[k]));
        }
    }
    return b;
}

// One thread's share of finite_bounds, in blocks of 1024 points (a fault
// is then located within its block only).
Bounds finite_bounds_serial(const float *xyz, std::uint64_t n, std::uint64_t first_vertex, const std::string &what) {
    if (n == 0) return {};
    float mn[48], mx[48];
    for (int k = 0; k < 48; ++k) mn[k] = mx[k] = xyz[k % 3];
    auto locate = [&](std::uint64_t s, std::uint64_t e) {
        for (std::uint64_t i = 3 * s; i < 3 * e; ++i)
            if (!std::isfinite(xyz[i])) throw Error(what + ": non-finite coordinate at vertex " + std::to_string(first_vertex + i / 3));
    };
    constexpr std::uint64_t kBlock = 1024;  // points, a multiple of 16
    const std::uint64_t whole = n / 16 * 16;
    for (std::uint64_t s = 0; s < whole; s += kBlock) {
        const std::uint64_t e = std::min(whole, s + kBlock);
        if (!minmax48(xyz + 3 * s, (e - s) / 16, mn, mx)) locate(s, e);
    }
    locate(whole, n);
    return fold48(xyz, n, whole, mn, mx);
}

}  // namespace

Bounds delimited_bounds(const float *xyz, std::uint64_t n, const std::uint64_t *offsets, std::uint64_t N, const std::string &what) {
    if (N == 0 || offsets[0] != 0) throw Error(what + ": offsets must start at 0");
    for (std::uint64_t s = 0; s < N; ++s)
        if (offsets[s + 1] <= offsets[s])
            throw Error(what + ": streamline " + std::to_string(s) + " has no delimiter (offsets must increase)");
    if (offsets[N] != n) throw Error(what + ": final offset " + std::to_string(offsets[N]) + " != " + std::to_string(n) + " vertices");
    // Streamlines [s0, s1) per thread: their vertices must hold exactly
    // 3 (s1 - s0) values that are not finite, all in the delimiters. Both
    // are checked a block of streamlines at a time, while it is in cache.
    auto part = [&](std::uint64_t s0, std::uint64_t s1) {
        float mn[48], mx[48];
        for (int k = 0; k < 48; ++k) mn[k] = HUGE_VALF, mx[k] = -HUGE_VALF;
        std::uint64_t bad = 0;
        bool delimiters_nan = true;
        constexpr std::uint64_t kBlock = 256;  // streamlines
        for (std::uint64_t c0 = s0; c0 < s1; c0 += kBlock) {
            const std::uint64_t c1 = std::min(s1, c0 + kBlock);
            bad += minmax_nan(xyz + 3 * offsets[c0], offsets[c1] - offsets[c0], mn, mx);
            for (std::uint64_t s = c0; s < c1; ++s) {
                const float *q = xyz + 3 * (offsets[s + 1] - 1);
                delimiters_nan &= std::isnan(q[0]) & std::isnan(q[1]) & std::isnan(q[2]);
            }
        }
        if (bad != 3 * (s1 - s0) || !delimiters_nan)
            for (std::uint64_t s = s0; s < s1; ++s) {  // (the first fault, for the message)
                const float *q = xyz + 3 * (offsets[s + 1] - 1);
                if (!(std::isnan(q[0]) && std::isnan(q[1]) && std::isnan(q[2])))
                    throw Error(what + ": the delimiter after streamline " + std::to_string(s) + " is not a NaN triple");
                for (std::uint64_t i = 3 * offsets[s]; i < 3 * (offsets[s + 1] - 1); ++i)
                    if (!std::isfinite(xyz[i]))
                        throw Error(what + ": non-finite coordinate in streamline " + std::to_string(s) + " at point " +
                                    std::to_string(i / 3 - offsets[s]));
            }
        return fold48_nan(mn, mx);
    };
    constexpr std::uint64_t kGrain = 1u << 14;  // streamlines per thread at least
    std::vector<Bounds> parts;
    std::mutex mu;
    parallel_ranges(N, kGrain, [&](std::uint64_t s0, std::uint64_t s1) {
        const Bounds r = part(s0, s1);
        std::lock_guard lock(mu);
        parts.push_back(r);
    });
    Bounds all;
    for (const auto &r : parts) merge_bounds(all, r);
    return all;
}

Bounds finite_bounds(const float *xyz, std::uint64_t n, const std::string &what, std::uint64_t first_vertex) {
    constexpr std::uint64_t kGrain = 1u << 20;                                    // points per thread at least
    if (n < 2 * kGrain) return finite_bounds_serial(xyz, n, first_vertex, what);  // (no threads, no allocation)
    std::vector<Bounds> parts;
    std::mutex mu;
    parallel_ranges(n, kGrain, [&](std::uint64_t b, std::uint64_t e) {
        const Bounds r = finite_bounds_serial(xyz + 3 * b, e - b, first_vertex + b, what);
        std::lock_guard lock(mu);
        parts.push_back(r);
    });
    Bounds all;
    for (const auto &r : parts) merge_bounds(all, r);
    return all;
}

std::size_t dtype_size(hz_dtype t) { return hz::dtype_size(t); }  // (the SDK's helper: one table for both sides)

const char *dtype_name(hz_dtype t) {
    switch (t) {
    case HZ_DTYPE_U8: return "uint8";
    case HZ_DTYPE_I8: return "int8";
    case HZ_DTYPE_U16: return "uint16";
    case HZ_DTYPE_I16: return "int16";
    case HZ_DTYPE_U32: return "uint32";
    case HZ_DTYPE_I32: return "int32";
    case HZ_DTYPE_U64: return "uint64";
    case HZ_DTYPE_I64: return "int64";
    case HZ_DTYPE_F16: return "float16";
    case HZ_DTYPE_F32: return "float32";
    case HZ_DTYPE_F64: return "float64";
    case HZ_DTYPE_RGB8: return "rgb8";
    case HZ_DTYPE_RGBA8: return "rgba8";
    default: return "unknown";
    }
}

DataArray f32_array(std::string name, hz_attach attach, const std::vector<float> &values) {
    DataArray a;
    a.name = std::move(name);
    a.attach = attach;
    a.dtype = HZ_DTYPE_F32;
    a.count = values.size();
    a.bytes = Buffer<std::byte>(values.size() * 4);
    if (!values.empty()) std::memcpy(a.bytes.data(), values.data(), values.size() * 4);
    return a;
}

Tractogram select_streamlines(const Tractogram &t, const std::vector<std::uint64_t> &ids, bool spill, const std::atomic<bool> *cancel) {
    Tractogram out;
    out.offsets = Buffer<std::uint64_t>(ids.size() + 1);
    std::uint64_t nv = 0;
    for (std::size_t i = 0; i < ids.size(); ++i) {
        out.offsets[i] = nv;
        nv += t.size(ids[i]);
    }
    out.offsets[ids.size()] = nv;
    if (nv > 0) {
        std::shared_ptr<void> block = spill ? allocate_spillable(nv * 3 * sizeof(float)) : allocate_uninitialised(nv * 3 * sizeof(float));
        float *at = static_cast<float *>(block.get());  // (before the move below: argument order is unspecified)
        out.positions = Buffer<float>(at, nv * 3, std::move(block));
    }
    // The copy on every core: a whole-brain selection is hundreds of MB,
    // and the first writes to fresh pages (the kernel's faults) are half of
    // the cost.
    const float *src = t.positions.data();
    float *dst = out.positions.data();
    parallel_ranges(ids.size(), 4096, [&](std::uint64_t from, std::uint64_t to) {
        for (std::uint64_t i = from; i < to; ++i) {
            if (cancel != nullptr && (i & 1023) == 0 && cancel->load(std::memory_order_relaxed)) return;
            std::memcpy(dst + out.offsets[i] * 3, src + t.begin(ids[i]) * 3, t.size(ids[i]) * 3 * sizeof(float));
        }
    });
    out.reference = t.reference;
    out.reference_dims = t.reference_dims;
    return out;
}

double value_at(const std::byte *p, hz_dtype dtype) {
    switch (dtype) {
    case HZ_DTYPE_U8: return *reinterpret_cast<const std::uint8_t *>(p);
    case HZ_DTYPE_I8: return *reinterpret_cast<const std::int8_t *>(p);
    case HZ_DTYPE_U16: {
        std::uint16_t x;
        std::memcpy(&x, p, 2);
        return x;
    }
    case HZ_DTYPE_I16: {
        std::int16_t x;
        std::memcpy(&x, p, 2);
        return x;
    }
    case HZ_DTYPE_U32: {
        std::uint32_t x;
        std::memcpy(&x, p, 4);
        return x;
    }
    case HZ_DTYPE_I32: {
        std::int32_t x;
        std::memcpy(&x, p, 4);
        return x;
    }
    case HZ_DTYPE_U64: {
        std::uint64_t x;
        std::memcpy(&x, p, 8);
        return double(x);
    }
    case HZ_DTYPE_I64: {
        std::int64_t x;
        std::memcpy(&x, p, 8);
        return double(x);
    }
    case HZ_DTYPE_F32: {
        float x;
        std::memcpy(&x, p, 4);
        return x;
    }
    case HZ_DTYPE_F64: {
        double x;
        std::memcpy(&x, p, 8);
        return x;
    }
    default: return std::nan("");
    }
}

const char *kind_name(hz_data_kind k) {
    switch (k) {
    case HZ_DATA_STREAMLINES: return "streamlines";
    case HZ_DATA_VOLUME: return "volume";
    case HZ_DATA_MESH: return "mesh";
    case HZ_DATA_IMAGE: return "image";
    default: return "unknown";
    }
}

const char *space_name(hz_space s) {
    switch (s) {
    case HZ_SPACE_RASMM: return "rasmm";
    case HZ_SPACE_VOXMM: return "voxmm";
    case HZ_SPACE_VOXEL: return "voxel";
    case HZ_SPACE_SURFACE_RAS: return "surface-ras";
    default: return "unknown";
    }
}

Tractogram Tractogram::shared() const {
    Tractogram out;
    out.positions = positions.shared();
    out.offsets = offsets.shared();
    out.gap = gap;
    out.reference = reference;
    out.reference_dims = reference_dims;
    for (const auto &a : arrays) {
        DataArray c;
        c.name = a.name, c.attach = a.attach, c.dtype = a.dtype, c.components = a.components, c.count = a.count;
        c.bytes = a.bytes.shared();
        out.arrays.push_back(std::move(c));
    }
    return out;
}

Tractogram Tractogram::compacted() const {
    Tractogram out = shared();
    if (gap == 0) return out;
    out.gap = 0;
    const std::uint64_t N = nb_streamlines();
    out.positions = Buffer<float>(3 * nb_vertices());
    out.offsets = Buffer<std::uint64_t>(N + 1);
    // Streamline s moves back by s * gap vertices: copied in parallel runs.
    for (std::uint64_t s = 0; s <= N; ++s) out.offsets[s] = offsets[s] - s * gap;
    parallel_ranges(N, 1u << 14, [&](std::uint64_t s0, std::uint64_t s1) {
        for (std::uint64_t s = s0; s < s1; ++s)
            std::memcpy(out.positions.data() + 3 * out.offsets[s], positions.data() + 3 * begin(s), 12 * size(s));
    });
    return out;
}

hz_streamlines_view Tractogram::view() const {
    hz_streamlines_view v{};
    v.struct_size = sizeof v;
    v.gap = gap;
    v.positions = positions.data();
    v.nb_vertices = nb_stored();
    v.offsets = offsets.data();
    v.nb_streamlines = nb_streamlines();
    return v;
}

Bounds Tractogram::validate(const std::string &what) const {
    if (gap == 1) return delimited_bounds(positions.data(), nb_stored(), offsets.data(), nb_streamlines(), what);
    validate_offsets(what);
    return finite_bounds(positions.data(), nb_vertices(), what);
}

void Tractogram::validate_offsets(const std::string &what) const {
    if (positions.size() % 3 != 0) throw Error(what + ": positions are not xyz triples");
    if (offsets.empty() || offsets[0] != 0) throw Error(what + ": offsets must start at 0");
    for (std::size_t i = 1; i < offsets.size(); ++i)
        if (offsets[i] < offsets[i - 1] + gap)
            throw Error(what + (gap ? ": offsets leave no delimiter after streamline " : ": offsets decrease at streamline ") +
                        std::to_string(i - 1));
    if (offsets[offsets.size() - 1] != nb_stored())
        throw Error(what + ": final offset " + std::to_string(offsets[offsets.size() - 1]) + " != " + std::to_string(nb_stored()) +
                    " vertices");
}

bool is_overlay(const Dataset &ds) { return overlay_vertices(ds) > 0; }

std::uint64_t overlay_vertices(const Dataset &ds) {
    if (ds.kind != HZ_DATA_MESH || ds.mesh.nb_vertices() != 0 || ds.mesh.nb_faces() != 0 || ds.mesh.arrays.empty()) return 0;
    const std::uint64_t n = ds.mesh.arrays.front().count;
    for (const auto &a : ds.mesh.arrays)
        if (a.attach != HZ_ATTACH_VERTEX || a.count != n) return 0;
    return n;
}

std::vector<std::string> attach_overlay(Mesh &mesh, const Dataset &overlay, const std::string &what) {
    const std::uint64_t n = overlay_vertices(overlay);
    if (n == 0) throw Error(what + ": not a per-vertex overlay (a curv file or an overlay-only GIFTI)");
    if (n != mesh.nb_vertices())
        throw Error(what + ": has values for " + std::to_string(n) + " vertices, the surface has " + std::to_string(mesh.nb_vertices()));
    std::vector<std::string> names;
    for (const auto &a : overlay.mesh.arrays) {
        DataArray copy;
        copy.attach = a.attach, copy.dtype = a.dtype, copy.components = a.components, copy.count = a.count;
        copy.bytes = Buffer<std::byte>(a.bytes.size());
        if (a.bytes.size()) std::memcpy(copy.bytes.data(), a.bytes.data(), a.bytes.size());
        auto taken = [&](const std::string &nm) {
            return std::any_of(mesh.arrays.begin(), mesh.arrays.end(), [&](const DataArray &x) { return x.name == nm; });
        };
        copy.name = a.name;
        for (int k = 2; taken(copy.name); ++k) copy.name = a.name + " (" + std::to_string(k) + ")";
        names.push_back(copy.name);
        mesh.arrays.push_back(std::move(copy));
    }
    return names;
}

Bounds bounds_of(const float *xyz, std::uint64_t n) {
    if (n == 0) return {};
    // The delimited kernel, its count ignored: NaN (a mapped TCK's
    // delimiters) never enters the bounds.
    float mn[48], mx[48];
    for (int k = 0; k < 48; ++k) mn[k] = HUGE_VALF, mx[k] = -HUGE_VALF;
    minmax_nan(xyz, n, mn, mx);
    return fold48_nan(mn, mx);
}

}  // namespace hz::core
