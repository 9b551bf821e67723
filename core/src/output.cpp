// Putting an output in place: the last step of every write (io.hpp).
#include <hz/core/io.hpp>
#include <hz/core/plugin_guard.hpp>

#include "plugin_internal.hpp"

#include <random>

#include <fcntl.h>
#include <signal.h>
#include <ucontext.h>
#include <stdio.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cerrno>
#include <cstring>
#include <string>

namespace hz::core {

namespace {

// Temporaries being written, removed by the termination handler (a fixed
// table: the handler may only call async-signal-safe functions).
constexpr int kSlots = 16;
constexpr std::size_t kPathMax = 4096;
char g_paths[kSlots][kPathMax];
// Each temporary's folder and name (set with its path, read by the handler).
char g_dirs[kSlots][kPathMax];
char g_names[kSlots][256];
std::atomic<bool> g_used[kSlots];     // the slot holds a temporary, whole (the handlers read it)
std::atomic<bool> g_claimed[kSlots];  // the slot is taken (set first, then filled, then g_used)

// Removes temporary `i` and the files a writer made beside it from its name
// (NAME.XXXXXX: libzip writes a TRX to a temporary of its own next to the
// path it was given, then renames it; SIGINT in between left it). Only
// async-signal-safe calls: open, getdents64, unlinkat, close.
void remove_temporary(int i) {
    ::unlink(g_paths[i]);
    const int dir = ::open(g_dirs[i], O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dir < 0) return;
    const std::size_t n = std::strlen(g_names[i]);
    alignas(8) char buf[4096];
    for (;;) {
        const long got = ::syscall(SYS_getdents64, dir, buf, sizeof buf);
        if (got <= 0) break;
        for (long off = 0; off < got;) {
            struct Entry {
                std::uint64_t ino;
                std::int64_t off;
                unsigned short reclen;
                unsigned char type;
                char name[1];
            };
            const auto *e = reinterpret_cast<const Entry *>(buf + off);
            if (std::strncmp(e->name, g_names[i], n) == 0 && e->name[n] == '.') ::unlinkat(dir, e->name, 0);
            off += e->reclen;
        }
    }
    ::close(dir);
}

void on_termination(int sig) {
    for (int i = 0; i < kSlots; ++i)
        if (g_used[i].load()) remove_temporary(i);
    ::signal(sig, SIG_DFL);
    ::raise(sig);
}

std::string errno_message(int e) { return std::strerror(e); }

void write_all(const char *s) { detail::write_stderr(s); }

// The file mapped at `addr`, from /proc/self/maps (async-signal-safe: only
// open, read and close). False if none.
bool mapped_file_at(std::uintptr_t addr, char *out, std::size_t cap) {
    const int fd = ::open("/proc/self/maps", O_RDONLY | O_CLOEXEC);
    if (fd < 0) return false;
    char buf[8192], line[4096 + 256];
    std::size_t len = 0;
    bool found = false;
    for (;;) {
        const ssize_t r = ::read(fd, buf, sizeof buf);
        if (r <= 0) break;
        for (ssize_t i = 0; i < r && !found; ++i) {
            if (buf[i] != '\n') {
                if (len + 1 < sizeof line) line[len++] = buf[i];
                continue;
            }
            line[len] = '\0';
            len = 0;
            // "start-end perms offset dev inode   path"
            std::uintptr_t lo = 0, hi = 0;
            const char *p = line;
            auto hex = [&](std::uintptr_t &v) {
                for (; *p; ++p) {
                    const char c = *p;
                    const int d = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
                    if (d < 0) break;
                    v = v * 16 + std::uintptr_t(d);
                }
            };
            hex(lo);
            if (*p == '-') ++p;
            hex(hi);
            if (addr < lo || addr >= hi) continue;
            const char *path = std::strchr(line, '/');
            if (path == nullptr) break;
            std::size_t k = 0;
            for (; path[k] && k + 1 < cap; ++k) out[k] = path[k];
            out[k] = '\0';
            found = true;
        }
        if (found) break;
    }
    ::close(fd);
    return found;
}

// A mapped input that shrank under us (truncated, replaced in place): the
// kernel raises SIGBUS on the pages past its new end. One line naming the
// file instead of a silent death.
void on_crash(int sig, siginfo_t *, void *ctx);

// Set by the first thread that reports a fault: threads that fault at the
// same moment (a parallel decode reading past a truncated file's end) wait
// for that one to end the process instead of printing a second line.
std::atomic<bool> g_fault_reported{false};
void wait_for_the_first_report() {
    if (!g_fault_reported.exchange(true)) return;
    for (;;) ::pause();
}

void on_sigbus(int sig, siginfo_t *info, void *ctx) {
    wait_for_the_first_report();
    char name[4096];
    for (int i = 0; i < kSlots; ++i)
        if (g_used[i].load()) remove_temporary(i);
    if (info != nullptr && mapped_file_at(reinterpret_cast<std::uintptr_t>(info->si_addr), name, sizeof name)) {
        write_all("horizon: error: ");
        write_all(name);
        write_all(": the file was truncated or changed while it was being read\n");
        ::_exit(1);
    }
    on_crash(sig, info, ctx);  // not a mapped file: a crash, as before
}

// A crash: where the faulting instruction lies (/proc/self/maps), named on
// stderr when it is a plugin's code, then the default action (the process
// dies of the signal as before).
void on_crash(int sig, siginfo_t *, void *ctx) {
    // A plugin's call: returns into its guard where it may, else is named
    // with the call (and, at exit, ends the process with the command's status).
    const bool named = sig != SIGBUS && plugin_fault(sig, ctx);
    if (sig != SIGBUS) wait_for_the_first_report();  // (on_sigbus has)
    char name[4096];
    const std::uintptr_t pc = detail::fault_pc(ctx);
    const char *what = sig == SIGSEGV ? "SIGSEGV" : sig == SIGILL ? "SIGILL" : sig == SIGFPE ? "SIGFPE" : "SIGBUS";
    if (!named && pc && mapped_file_at(pc, name, sizeof name)) {
        const std::size_t n = std::strlen(name);
        const bool plugin = n > 3 && std::strcmp(name + n - 3, ".so") == 0 && std::strstr(name, "/libc.so") == nullptr &&
                            std::strstr(name, "/x86_64-linux-gnu/") == nullptr && std::strstr(name, "/aarch64-linux-gnu/") == nullptr;
        if (plugin) {
            write_all("horizon: error: the plugin ");
            write_all(name);
            write_all(" crashed (");
            write_all(what);
            write_all("); move it out of the plugin folders or report it to its author\n");
        }
    }
    for (int i = 0; i < kSlots; ++i)
        if (g_used[i].load()) remove_temporary(i);
    ::signal(sig, SIG_DFL);
    ::raise(sig);
}

// fsync of a file or directory; errno on failure, 0 on success.
int sync_path(const fs::path &p, bool directory) {
    const int fd = ::open(p.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
    if (fd < 0) return errno;
    int e = 0;
    if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) e = errno;  // (EINVAL: a file system without fsync)
    ::close(fd);
    return e;
}

}  // namespace

void install_termination_cleanup() {
    struct sigaction sa {};
    sa.sa_handler = on_termination;
    sigemptyset(&sa.sa_mask);
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
        struct sigaction old {};
        if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN) continue;  // (nohup)
        ::sigaction(sig, &sa, nullptr);
    }
    // Past a file size limit (ulimit -f) a write fails with EFBIG, reported
    // like any other write error, instead of a silent SIGXFSZ.
    ::signal(SIGXFSZ, SIG_IGN);
    struct sigaction bus {};
    bus.sa_sigaction = on_sigbus;
    bus.sa_flags = SA_SIGINFO;
    sigemptyset(&bus.sa_mask);
    ::sigaction(SIGBUS, &bus, nullptr);
    // Crashes in a plugin after its trial (a later call) name the plugin,
    // and a guarded call's return into its guard (plugin_guard.hpp).
    // (Not where a sanitizer or debugger already handles them.)
    install_plugin_guard();
    for (int sig : {SIGSEGV, SIGILL, SIGFPE}) {
        struct sigaction old {};
        if (::sigaction(sig, nullptr, &old) != 0 || old.sa_handler != SIG_DFL) continue;
        // (not reset on delivery: a fault in a plugin's guarded call returns
        // into its guard, and the next one must be caught too; on_crash
        // resets it before dying of the signal)
        struct sigaction crash {};
        crash.sa_sigaction = on_crash;
        crash.sa_flags = SA_SIGINFO | SA_ONSTACK;
        sigemptyset(&crash.sa_mask);
        ::sigaction(sig, &crash, nullptr);
    }
}

TemporaryFile::TemporaryFile(const fs::path &path) : path_(path) {
    const std::string s = path.string();
    const std::string dir = path.has_parent_path() ? path.parent_path().string() : std::string(".");
    const std::string name = path.filename().string();
    if (s.size() >= kPathMax || dir.size() >= kPathMax || name.size() >= sizeof g_names[0]) return;
    for (int i = 0; i < kSlots; ++i) {
        bool expected = false;
        if (!g_claimed[i].compare_exchange_strong(expected, true)) continue;
        std::memcpy(g_paths[i], s.c_str(), s.size() + 1);
        std::memcpy(g_dirs[i], dir.c_str(), dir.size() + 1);
        std::memcpy(g_names[i], name.c_str(), name.size() + 1);
        g_used[i].store(true);  // (the handler reads the slot once it is whole)
        slot_ = i;
        return;
    }
}

TemporaryFile::~TemporaryFile() {
    if (!published_) {
        std::error_code ec;
        fs::remove_all(path_, ec);
        // (and what a writer made beside it from its name: remove_temporary)
        const std::string prefix = path_.filename().string() + ".";
        const fs::path dir = path_.has_parent_path() ? path_.parent_path() : fs::path(".");
        for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
            if (it->path().filename().string().rfind(prefix, 0) == 0) fs::remove_all(it->path(), ec);
    }
    if (slot_ >= 0) g_used[slot_].store(false), g_claimed[slot_].store(false);
}

void check_output_target(const fs::path &path) {
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0) return;  // (absent: fine)
    if (S_ISDIR(st.st_mode)) throw Error(path.string() + ": is a directory");
    if (!S_ISREG(st.st_mode) && !S_ISLNK(st.st_mode))
        throw Error(path.string() + ": exists and is not a regular file (a device, FIFO or socket); refusing to replace it");
}

namespace {
// ".NAME.tmp-", NAME cut so that the prefix and "PID-RANDOM" (at most 10 +
// 1 + 6 bytes) fit NAME_MAX.
std::string temporary_prefix(const fs::path &path) {
    constexpr std::size_t kNameMax = 255, kTail = 5 + 10 + 1 + 6;  // ".tmp-" PID "-" RANDOM
    std::string name = path.filename().string();
    if (name.size() > kNameMax - 1 - kTail) {
        std::size_t n = kNameMax - 1 - kTail;
        while (n > 0 && (static_cast<unsigned char>(name[n]) & 0xC0) == 0x80) --n;  // (not inside a UTF-8 character)
        name.resize(n);
    }
    std::string prefix = ".";  // (appended piecewise: GCC 12 warns falsely on a + chain here)
    prefix += name;
    prefix += ".tmp-";
    return prefix;
}
}  // namespace

fs::path temporary_path(const fs::path &path) {
    static std::random_device rd;
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    std::string name = temporary_prefix(path);
    name += std::to_string(::getpid());
    name += '-';
    name += std::to_string(rd() % 1000000);
    return dir / name;
}

void remove_stale_temporaries(const fs::path &path) {
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    const std::string prefix = temporary_prefix(path);
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        if (name.rfind(prefix, 0) != 0) continue;
        // .NAME.tmp-PID-RANDOM, or .NAME.tmp-PID: stale when PID is gone.
        const std::string rest = name.substr(prefix.size());
        char *endp = nullptr;
        const long pid = std::strtol(rest.c_str(), &endp, 10);
        if (pid <= 0 || endp == rest.c_str() || (*endp != '\0' && *endp != '-')) continue;
        if (pid == ::getpid() || ::kill(pid_t(pid), 0) == 0 || errno == EPERM) continue;  // (alive)
        std::error_code e2;
        fs::remove_all(it->path(), e2);
    }
}

void publish(TemporaryFile &tmp, const fs::path &path, bool force) {
    if (int e = sync_path(tmp.path(), fs::is_directory(tmp.path())); e != 0)
        throw Error(path.string() + ": cannot write: " + errno_message(e));
    check_output_target(path);
    if (force) {
        if (::rename(tmp.path().c_str(), path.c_str()) != 0)
            throw Error(path.string() + ": cannot rename the temporary file into place: " + errno_message(errno));
    } else if (::renameat2(AT_FDCWD, tmp.path().c_str(), AT_FDCWD, path.c_str(), RENAME_NOREPLACE) != 0) {
        // Atomic: of two writers of the same new output, one gets EEXIST.
        int e = errno;
        if (e == EINVAL || e == ENOSYS) {  // a file system without RENAME_NOREPLACE: link() is as atomic
            e = ::link(tmp.path().c_str(), path.c_str()) == 0 ? 0 : errno;
            if (e == 0) ::unlink(tmp.path().c_str());
        }
        if (e == EEXIST) throw Error(path.string() + ": already exists (use --force to replace it)");
        if (e != 0) throw Error(path.string() + ": cannot rename the temporary file into place: " + errno_message(e));
    }
    tmp.published();
    // The rename itself, durable (as git does for its objects).
    if (int e = sync_path(path.has_parent_path() ? path.parent_path() : fs::path("."), true); e != 0)
        throw Error(path.string() + ": written, but its directory could not be synced: " + errno_message(e));
}

void publish_together(const std::vector<std::pair<TemporaryFile *, fs::path>> &files, bool force) {
    struct Aside {
        fs::path file, aside;
    };
    std::vector<Aside> asides;
    std::vector<fs::path> placed;
    const auto undo = [&] {
        for (const fs::path &p : placed) ::unlink(p.c_str());
        for (const Aside &a : asides) ::rename(a.aside.c_str(), a.file.c_str());
    };
    try {
        for (const auto &[tmp, path] : files) {
            struct stat st {};
            if (force && ::lstat(path.c_str(), &st) == 0) {
                check_output_target(path);
                fs::path aside = temporary_path(path);
                const std::string name = aside.filename().string();
                aside.replace_filename(name.substr(0, name.rfind(".tmp-")) + ".old-" + name.substr(name.rfind(".tmp-") + 5));
                if (::rename(path.c_str(), aside.c_str()) != 0)
                    throw Error(path.string() + ": cannot move the file it replaces aside: " + errno_message(errno));
                asides.push_back({path, aside});
            }
            publish(*tmp, path, force);
            placed.push_back(path);
        }
    } catch (...) {
        undo();
        throw;
    }
    for (const Aside &a : asides) ::unlink(a.aside.c_str());
}

namespace detail {
void write_stderr(const char *s) {
    std::size_t n = std::strlen(s);
    while (n > 0) {
        const ssize_t w = ::write(STDERR_FILENO, s, n);
        if (w <= 0) return;
        s += w, n -= std::size_t(w);
    }
}
}  // namespace detail

}  // namespace hz::core
