#include "progress.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace hz::host {

namespace {
std::atomic<bool> g_enabled{true};
std::mutex g_alive_mutex;
std::vector<Progress *> g_alive;  // in the order they began
}  // namespace

void disable_progress() { g_enabled = false; }

ProgressState current_progress() {
    std::lock_guard<std::mutex> lock(g_alive_mutex);
    if (g_alive.empty()) return {};
    const Progress *p = g_alive.back();
    return {true, p->what_, p->fraction_.load(), std::chrono::duration<double>(std::chrono::steady_clock::now() - p->start_).count()};
}

void cancel_progress() {
    std::lock_guard<std::mutex> lock(g_alive_mutex);
    for (Progress *p : g_alive) p->task_.cancel();
}

Progress::Progress(std::string what, bool enabled) : what_(std::move(what)) {
    task_.on_progress = [this](double f, const char *) { fraction_ = f; };
    {
        std::lock_guard<std::mutex> lock(g_alive_mutex);
        g_alive.push_back(this);
    }
    if (!enabled || !g_enabled || ::isatty(STDERR_FILENO) != 1) return;
    thread_ = std::thread([this] { loop(); });
}

Progress::~Progress() {
    {
        std::lock_guard<std::mutex> lock(g_alive_mutex);
        std::erase(g_alive, this);
    }
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
        if (f >= 0 && f <= 1)
            std::fprintf(stderr, "\rhorizon: %s ... %3.0f%%  %.1f s\033[K", what_.c_str(), f * 100, s);
        else
            std::fprintf(stderr, "\rhorizon: %s ... %.1f s\033[K", what_.c_str(), s);
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
