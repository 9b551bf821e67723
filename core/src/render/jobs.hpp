// Timing and threads of the renderer's work (private to the renderer): a
// steady clock, milliseconds since a time point, a background job's time
// logged at -v, the cores to build on.
#pragma once

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <thread>

namespace hz::core::render {

using Clock = std::chrono::steady_clock;

inline double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

// fn()'s result; -v logs "renderer: object K: WHAT (S s)" (a level-of-detail
// job's time, on its own thread).
template <class F>
auto timed_job(std::size_t object, const std::string &what, F &&fn) {
    const auto t0 = Clock::now();
    auto result = fn();
    spdlog::debug("renderer: object {}: {} ({:.2f} s)", object, what, ms_since(t0) / 1000);
    return result;
}

// The threads to build chunks on: one per core, at least one.
inline unsigned cores() { return std::max(1u, std::thread::hardware_concurrency()); }

}  // namespace hz::core::render
