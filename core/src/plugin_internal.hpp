// Private to the plugin host's sources (plugin_host.cpp, plugin_module.cpp,
// plugin_child.cpp, plugin_guard.cpp, output.cpp): the child-process plumbing the registry's trial loads
// share with run_in_child(), and the core interface id of a plugin kind.
#pragma once

#include <hz/core/plugin_host.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <sys/types.h>
#include <utility>

namespace hz::core::detail {

// Writes all of `s` to `fd`, retrying short writes.
void write_all(int fd, const std::string &s);
// Writes the C string `s` to stderr (async-signal-safe: write only; the
// signal handlers' one lines).
void write_stderr(const char *s);
// The faulting instruction's address in a signal handler's ucontext (0 where unknown).
std::uintptr_t fault_pc(void *ucontext);
// Forks a child that runs `body` with the write end of a pipe whose read
// end is returned with the pid. In the child, stdout goes to stderr and a
// crash dies of the real signal; it exits 0, or 3 when body throws.
std::pair<pid_t, int> spawn(const std::function<void(int)> &body);
// Reads the child's pipe into `buf` until it closes (returns 0), the
// deadline (kills the child, sets r.timed_out, returns -1), or, with
// `until_newline`, a complete line in buf (returns 1).
int read_child(pid_t pid, int fd, std::chrono::steady_clock::time_point deadline, std::string &buf, bool until_newline, ChildResult &r);
// Waits for the child and records how it ended; one still running at the
// deadline is killed.
void reap(pid_t pid, std::chrono::steady_clock::time_point deadline, ChildResult &r);
// The core interface id of kind `k` ("hz.loader/1", ...), or NULL.
const char *core_interface(hz_plugin_kind k);

}  // namespace hz::core::detail
