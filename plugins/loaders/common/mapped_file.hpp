// Read-only memory mapping of a whole file, shared by the loader plugins
// (a static library linked into each; no SDK types).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace hzio {

// An operating-system failure (open, stat, map), message without the path.
struct IoError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

class MappedFile {
public:
    explicit MappedFile(const std::string &path);  // throws IoError
    ~MappedFile();
    MappedFile(const MappedFile &) = delete;
    MappedFile &operator=(const MappedFile &) = delete;
    const unsigned char *data() const { return data_; }
    std::uint64_t size() const { return size_; }
    // Drops the mapped pages of [0, end) from this process (they stay in the
    // page cache and fault back in on access): keeps peak memory near the
    // decoded data when a file is walked front to back.
    void release_before(std::uint64_t end) const;
    // The same for the whole pages inside [begin, end) (a decoded chunk).
    void release(std::uint64_t begin, std::uint64_t end) const;

private:
    const unsigned char *data_ = nullptr;
    std::uint64_t size_ = 0;
};

}  // namespace hzio
