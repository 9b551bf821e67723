// Chunked parallel work for the plugins (std::thread; no SDK
// types). Loaders split a file into runs of whole records during their scan
// and decode the runs concurrently into the host's buffers.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <thread>
#include <vector>

#include <sys/mman.h>

// Compiles a function for AVX-512 and AVX2 as well as the baseline, the
// variant chosen when the library loads (GCC target_clones; the compiler
// vectorises plain loops, no intrinsics). Empty elsewhere.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define HZIO_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define HZIO_SIMD_CLONES
#endif

namespace hzio {

// Maps the whole pages of [p, p + bytes) for writing now, in one call
// (MADV_POPULATE_WRITE, Linux 5.14), instead of one page fault per page as
// a decoder (or the clustering plugin's resampling) first writes them: a
// chunk's output is about 12-16 MiB, 3-4 thousand pages. Nothing is written. Where the kernel cannot, the pages
// fault in as before.
inline void prefault_write(void *p, std::size_t bytes) noexcept {
#ifdef MADV_POPULATE_WRITE
    const std::uintptr_t page = 4096, a = reinterpret_cast<std::uintptr_t>(p);
    const std::uintptr_t b = (a + page - 1) & ~(page - 1), e = (a + bytes) & ~(page - 1);
    if (e > b) (void)madvise(reinterpret_cast<void *>(b), e - b, MADV_POPULATE_WRITE);
#else
    (void)p;
    (void)bytes;
#endif
}

// v.resize(n) (new elements value-initialised) for a large array, with its
// whole new pages mapped first in one call (prefault_write) rather than
// faulted in one by one as the initialisation reaches them (the clustering's
// per-streamline records and member lists: tens of MB at a million
// streamlines, fresh in every process).
template <class Vec>
void resize_prefaulted(Vec &v, std::size_t n) {
    v.reserve(n);
    if (n > v.size()) prefault_write(v.data() + v.size(), (n - v.size()) * sizeof(typename Vec::value_type));
    v.resize(n);
}

// Runs body(c) for every chunk c in [0, n) on up to min(n, cores, 8)
// threads, the calling thread being one of them; chunks are taken in order
// from a shared counter. `poll` (may be empty) runs on the calling thread
// only (the ABI's cancellation query is calling-thread only), before each of
// its chunks; when it returns true no further chunk starts and the function
// returns false once the running ones finish.
//
// If bodies throw, every chunk before the lowest failing one still runs,
// later ones are skipped, and that chunk's exception is rethrown: the error
// reported is the first in file order, as a sequential decode would report.
inline bool parallel_chunks(std::size_t n, const std::function<void(std::size_t)> &body, const std::function<bool()> &poll) {
    const std::size_t threads = std::max<std::size_t>(1, std::min<std::size_t>({n, std::thread::hardware_concurrency(), 8}));
    std::atomic<std::size_t> next{0};
    std::atomic<std::size_t> first_failed{n};
    std::atomic<bool> cancelled{false};
    std::vector<std::exception_ptr> errors(n);
    auto work = [&](bool caller) {
        for (;;) {
            if (caller && poll && poll()) cancelled = true;
            if (cancelled) return;
            const std::size_t c = next.fetch_add(1);
            if (c >= n || c > first_failed.load()) return;
            try {
                body(c);
            } catch (...) {
                errors[c] = std::current_exception();
                std::size_t f = first_failed.load();
                while (c < f && !first_failed.compare_exchange_weak(f, c)) {}
            }
        }
    };
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work, false);
    work(true);
    for (auto &t : pool) t.join();
    if (first_failed < n) std::rethrow_exception(errors[first_failed]);
    return !cancelled;
}

}  // namespace hzio
