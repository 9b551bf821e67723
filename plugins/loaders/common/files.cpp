#include "files.hpp"

#include "mapped_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

namespace hzio {

namespace fs = std::filesystem;

namespace {

std::string inside(const std::string &input, const fs::path &joined, const std::string &name) {
    std::error_code ec;
    const fs::path in(input);
    const fs::path dir = fs::canonical(in.has_parent_path() ? in.parent_path() : fs::path("."), ec);
    if (ec) throw IoError("cannot resolve the folder of " + input + ": " + ec.message());
    const fs::path target = fs::weakly_canonical(joined.is_absolute() ? joined : fs::absolute(joined, ec), ec);
    if (ec) throw IoError("companion file '" + name + "' cannot be resolved: " + ec.message());
    // Inside the folder: dir is a prefix of target, component by component.
    auto d = dir.begin(), t = target.begin();
    for (; d != dir.end(); ++d, ++t)
        if (t == target.end() || *d != *t) throw IoError("companion file '" + name + "' lies outside the file's folder");
    struct stat st {};
    if (::stat(target.c_str(), &st) != 0) throw IoError("companion file '" + name + "' cannot be opened: " + std::strerror(errno));
    if (!S_ISREG(st.st_mode)) throw IoError("companion file '" + name + "' is not a regular file");
    return target.string();
}

}  // namespace

std::string companion_path(const std::string &input, const std::string &name) {
    if (name.empty()) throw IoError("an empty companion file name");
    const fs::path n(name);
    if (n.is_absolute())
        throw IoError("companion file '" + name + "' is an absolute path: only names relative to the file's folder are read");
    const fs::path in(input);
    return inside(input, (in.has_parent_path() ? in.parent_path() : fs::path(".")) / n, name);
}

std::string contained_file(const std::string &input, const std::string &path) { return inside(input, fs::path(path), path); }

void write_file(const std::string &path, const void *data, std::size_t bytes) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) throw IoError(std::string("cannot create: ") + std::strerror(errno));
    const char *p = static_cast<const char *>(data);
    std::size_t done = 0;
    while (done < bytes) {
        const ssize_t n = ::write(fd, p + done, bytes - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            const int e = n < 0 ? errno : EIO;
            ::close(fd);
            throw IoError(std::string("write failed: ") + std::strerror(e));
        }
        done += std::size_t(n);
    }
    if (::close(fd) != 0) throw IoError(std::string("write failed: ") + std::strerror(errno));
}

}  // namespace hzio
