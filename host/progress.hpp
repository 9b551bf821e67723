// A progress line on stderr for work that takes more than a moment (reading,
// clustering): "horizon: reading t1m.trk ... 42%  2.3 s", redrawn in place.
#pragma once

#include <hz/core/plugin_host.hpp>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

namespace hz::host {

// Off for the whole program (--json anywhere on the command line).
void disable_progress();

class Progress {
public:
    // Shown only when stderr is a terminal and `enabled` (false with --json),
    // once the work has taken HORIZON_PROGRESS_DELAY seconds (default 1);
    // then redrawn every 0.2 s from a thread of its own. Cleared when the
    // object is destroyed.
    Progress(std::string what, bool enabled);
    ~Progress();
    Progress(const Progress &) = delete;
    Progress &operator=(const Progress &) = delete;
    // A task whose reports (hz_task::report) feed the percentage.
    const hz_task *task() { return task_.get(); }

private:
    void loop();
    std::string what_;
    core::Task task_;
    std::atomic<double> fraction_{-1.0};
    std::mutex m_;
    std::condition_variable cv_;
    bool done_ = false, shown_ = false;
    std::thread thread_;
};

}  // namespace hz::host
