// Putting an output in place: the last step of every write (io.hpp).
#include <hz/core/io.hpp>

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
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
std::atomic<bool> g_used[kSlots];

void on_termination(int sig) {
    for (int i = 0; i < kSlots; ++i)
        if (g_used[i].load()) ::unlink(g_paths[i]);
    ::signal(sig, SIG_DFL);
    ::raise(sig);
}

std::string errno_message(int e) { return std::strerror(e); }

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
}

TemporaryFile::TemporaryFile(const fs::path &path) : path_(path) {
    const std::string s = path.string();
    if (s.size() >= kPathMax) return;
    for (int i = 0; i < kSlots; ++i) {
        bool expected = false;
        if (g_used[i].load() || !g_used[i].compare_exchange_strong(expected, true)) continue;
        std::memcpy(g_paths[i], s.c_str(), s.size() + 1);
        slot_ = i;
        return;
    }
}

TemporaryFile::~TemporaryFile() {
    if (!published_) {
        std::error_code ec;
        fs::remove_all(path_, ec);
    }
    if (slot_ >= 0) g_used[slot_].store(false);
}

void check_output_target(const fs::path &path) {
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0) return;  // (absent: fine)
    if (S_ISDIR(st.st_mode)) throw Error(path.string() + ": is a directory");
    if (!S_ISREG(st.st_mode) && !S_ISLNK(st.st_mode))
        throw Error(path.string() + ": exists and is not a regular file (a device, FIFO or socket); refusing to replace it");
}

void remove_stale_temporaries(const fs::path &path) {
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    const std::string prefix = "." + path.filename().string() + ".tmp-";
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

}  // namespace hz::core
