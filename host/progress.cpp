#include "progress.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>

namespace hz::host {

namespace {
std::atomic<bool> g_enabled{true};
}

void disable_progress() { g_enabled = false; }

Progress::Progress(std::string what, bool enabled) : what_(std::move(what)) {
    if (!enabled || !g_enabled || ::isatty(STDERR_FILENO) != 1) return;
    task_.on_progress = [this](double f, const char *) { fraction_ = f; };
    thread_ = std::thread([this] { loop(); });
}

Progress::~Progress() {
    if (!thread_.joinable()) return;
    {
        std::lock_guard<std::mutex> lock(m_);
        done_ = true;
    }
    cv_.notify_all();
    thread_.join();
}

void Progress::loop() {
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    double delay = 1.0;
    if (const char *d = std::getenv("HORIZON_PROGRESS_DELAY")) delay = std::atof(d);
    std::unique_lock<std::mutex> lock(m_);
    if (cv_.wait_for(lock, std::chrono::duration<double>(delay), [this] { return done_; })) return;
    for (;;) {
        const double s = std::chrono::duration<double>(Clock::now() - t0).count();
        const double f = fraction_;
        if (f >= 0 && f <= 1) std::fprintf(stderr, "\rhorizon: %s ... %3.0f%%  %.1f s\033[K", what_.c_str(), f * 100, s);
        else std::fprintf(stderr, "\rhorizon: %s ... %.1f s\033[K", what_.c_str(), s);
        std::fflush(stderr);
        shown_ = true;
        if (cv_.wait_for(lock, std::chrono::milliseconds(200), [this] { return done_; })) break;
    }
    if (shown_) {
        std::fprintf(stderr, "\r\033[K");  // the line goes away: what follows is the result
        std::fflush(stderr);
    }
}

}  // namespace hz::host
