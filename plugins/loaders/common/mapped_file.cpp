#include "mapped_file.hpp"

#include <cerrno>
#include <algorithm>
#include <cstring>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace hzio {

MappedFile::MappedFile(const std::string &path) {
    // (O_NONBLOCK: opening a FIFO must not wait for a writer; it is then refused)
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) throw IoError(std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        ::close(fd);
        throw IoError("not a regular file");
    }
    size_ = static_cast<std::uint64_t>(st.st_size);
    if (size_ > 0) {
        void *p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
        if (p == MAP_FAILED) {
            const int e = errno;
            ::close(fd);
            throw IoError(std::string("cannot map: ") + std::strerror(e));
        }
        ::madvise(p, size_, MADV_SEQUENTIAL);
        data_ = static_cast<const unsigned char *>(p);
    }
    ::close(fd);
}

void MappedFile::release_before(std::uint64_t end) const { release(0, end); }

void MappedFile::release(std::uint64_t begin, std::uint64_t end) const {
    if (data_ == nullptr) return;
    const std::uint64_t page = static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
    const std::uint64_t b = (begin + page - 1) / page * page, e = std::min(end, size_) / page * page;
    if (e > b) ::madvise(const_cast<unsigned char *>(data_) + b, e - b, MADV_DONTNEED);
}

MappedFile::~MappedFile() {
    if (data_ != nullptr) ::munmap(const_cast<unsigned char *>(data_), size_);
}

}  // namespace hzio
