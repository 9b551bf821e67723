// A progress line on stderr for work that takes more than a moment (reading,
// clustering): "horizon: reading t1m.trk ... 42%  2.3 s", redrawn in place.
#pragma once

#include <hz/core/plugin_host.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

namespace hz::host {

// Off for the whole program (--json anywhere on the command line).
void disable_progress();

// The innermost Progress alive now (the window shows it while it reads).
struct ProgressState {
    bool active = false;
    std::string what;      // "reading t1m.trk"
    double fraction = -1;  // 0..1, or < 0 when the work does not report one
    double seconds = 0;    // since it began
};
ProgressState current_progress();
// Cancels the task of every Progress alive now (a window closed while it
// reads): the plugins doing that work see hz_task::is_cancelled.
void cancel_progress();

class Progress {
public:
    // Shown on stderr only when stderr is a terminal and `enabled` (false
    // with --json), once the work has taken HORIZON_PROGRESS_DELAY seconds
    // (default 1); then redrawn every 0.2 s from a thread of its own.
    // Cleared when the object is destroyed. current_progress() sees it
    // either way.
    Progress(std::string what, bool enabled);
    ~Progress();
    Progress(const Progress &) = delete;
    Progress &operator=(const Progress &) = delete;
    // A task whose reports (hz_task::report) feed the percentage.
    const hz_task *task() { return task_.get(); }

private:
    void loop();
    friend ProgressState current_progress();
    friend void cancel_progress();
    std::string what_;
    std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
    core::Task task_;
    std::atomic<double> fraction_{-1.0};
    std::mutex m_;
    std::condition_variable cv_;
    bool done_ = false, shown_ = false;
    std::thread thread_;
};

}  // namespace hz::host
