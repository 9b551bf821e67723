// Running work in a child process (run_in_child, and the registry's trial
// loads): fork, a pipe, a deadline, and how the child ended.
#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
#include <hz/core/plugin_guard.hpp>
#include <hz/core/plugin_host.hpp>

#include "plugin_internal.hpp"

#include <boost/dll/shared_library.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <array>
#include <dlfcn.h>
#include <elf.h>
#include <link.h>
#include <set>
#include <optional>
#include <string_view>
#include <sys/stat.h>
#include <tuple>
#include <fcntl.h>
#include <fstream>
#include <map>
#include <mutex>
#include <poll.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstddef>
#include <cstdio>

namespace hz::core {

// --------------------------------------------------------------- children

std::string ChildResult::describe() const {
    if (timed_out) return "hung (killed after the time limit)";
    if (signal != 0) {
        const char *name = sigabbrev_np(signal);
        return std::string("crashed (signal SIG") + (name ? name : std::to_string(signal).c_str()) + ")";
    }
    if (exited && exit_code != 0) return "exited with status " + std::to_string(exit_code);
    return "ok";
}

namespace detail {

void write_all(int fd, const std::string &s) {
    const char *p = s.data();
    std::size_t left = s.size();
    while (left > 0) {
        const ssize_t w = ::write(fd, p, left);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) break;
        p += w;
        left -= static_cast<std::size_t>(w);
    }
}

// Forks a child that runs body(fd), fd being the write end of a pipe whose
// read end is returned with the pid. In the child, stdout goes to stderr
// (the parent's stdout stays clean for JSON output) and a crash dies of
// the real signal (sanitizer runtimes would turn it into an exit status),
// so the parent can name it; it exits 0, or 3 when body throws.
std::pair<pid_t, int> spawn(const std::function<void(int)> &body) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) throw Error(std::string("pipe: ") + std::strerror(errno));
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t pid = ::fork();
    if (pid < 0) {
        const int e = errno;
        ::close(fds[0]);
        ::close(fds[1]);
        throw Error(std::string("fork: ") + std::strerror(e));
    }
    if (pid == 0) {
        ::close(fds[0]);
        for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL}) std::signal(sig, SIG_DFL);
        disable_plugin_guard();  // (no watchdog, no recovery: the parent watches and names)
        ::dup2(2, 1);
        int code = 0;
        try {
            body(fds[1]);
        } catch (...) {
            code = 3;
        }
        std::fflush(nullptr);
        ::_exit(code);
    }
    ::close(fds[1]);
    return {pid, fds[0]};
}

// Reads what the child writes to `fd` into `buf` until EOF (returns 0), the
// deadline (kills the child, sets r.timed_out, returns -1), or, with
// `until_newline`, a complete line in buf (returns 1).
int read_child(pid_t pid, int fd, std::chrono::steady_clock::time_point deadline, std::string &buf, bool until_newline, ChildResult &r) {
    char chunk[65536];
    for (;;) {
        if (until_newline && buf.find('\n') != std::string::npos) return 1;
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
        if (left <= 0) {
            r.timed_out = true;
            ::kill(pid, SIGKILL);
            return -1;
        }
        pollfd pfd{fd, POLLIN, 0};
        const int pr = ::poll(&pfd, 1, static_cast<int>(std::min<long long>(left, 1000)));
        if (pr < 0 && errno == EINTR) continue;
        if (pr == 0) continue;
        const ssize_t n = ::read(fd, chunk, sizeof chunk);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return 0;  // EOF: the child is done or died
        buf.append(chunk, static_cast<std::size_t>(n));
    }
}

// Waits for the child (its pipe closed, or it was killed) and records how it
// ended; one still running at the deadline is killed.
void reap(pid_t pid, std::chrono::steady_clock::time_point deadline, ChildResult &r) {
    int status = 0;
    if (!r.timed_out) {
        // Woken the moment it exits (a pidfd polls readable then, Linux 5.3;
        // elsewhere, short sleeps).
        const int pidfd = static_cast<int>(::syscall(SYS_pidfd_open, pid, 0));
        for (;;) {
            const pid_t w = ::waitpid(pid, &status, WNOHANG);
            if (w == pid) break;
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
            if (left <= 0) {
                r.timed_out = true;
                ::kill(pid, SIGKILL);
                ::waitpid(pid, &status, 0);
                break;
            }
            if (pidfd >= 0) {
                pollfd pfd{pidfd, POLLIN, 0};
                (void)::poll(&pfd, 1, static_cast<int>(std::min<long long>(left, 1000)));
            } else {
                ::usleep(200);
            }
        }
        if (pidfd >= 0) ::close(pidfd);
    } else {
        ::waitpid(pid, &status, 0);
    }
    if (!r.timed_out) {
        if (WIFEXITED(status)) {
            r.exited = true;
            r.exit_code = WEXITSTATUS(status);
        } else if (WIFSIGNALED(status)) {
            r.signal = WTERMSIG(status);
        }
    }
}

}  // namespace detail

using namespace detail;

ChildResult run_in_child(const std::function<std::string()> &fn, double timeout_s) {
    ChildResult r;
    const auto [pid, fd] = spawn([&](int out) {
        const pid_t self = ::getpid();
        std::string s = fn();
        if (::getpid() != self) ::_exit(0);  // a process `fn` forked reports nothing
        write_all(out, s);
    });
    const auto deadline = std::chrono::steady_clock::now() +
                          std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(timeout_s));
    read_child(pid, fd, deadline, r.output, false, r);
    ::close(fd);
    reap(pid, deadline, r);
    return r;
}

}  // namespace hz::core
