// Whole-file reads and writes with or without gzip (gzip.hpp).
#include "gzip.hpp"

#include "mapped_file.hpp"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace hzio {

std::vector<unsigned char> gunzip(const std::string &path, std::uint64_t limit) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::exists(path, ec) && !fs::is_regular_file(path, ec)) throw IoError("not a regular file");  // (a FIFO would block)
    gzFile g = gzopen(path.c_str(), "rb");
    if (g == nullptr) throw IoError(std::string("cannot open: ") + std::strerror(errno));
    gzbuffer(g, 1 << 17);
    auto fail = [&] {
        int code = 0;
        const std::string m = gzerror(g, &code);
        gzclose(g);
        throw CorruptData("corrupt gzip stream: " + m);
    };
    std::vector<unsigned char> out;
    while (out.size() < limit) {
        const std::size_t want = static_cast<std::size_t>(std::min<std::uint64_t>(limit - out.size(), 1 << 24));
        const std::size_t at = out.size();
        out.resize(at + want);
        const int got = gzread(g, out.data() + at, static_cast<unsigned>(want));
        if (got < 0) fail();
        out.resize(at + static_cast<std::size_t>(got));
        if (got == 0) break;
    }
    // A damaged stream is an error even when the bytes we need are all
    // there: check up to 1 MiB past them for the end of the stream.
    if (out.size() == limit) {
        std::vector<unsigned char> rest(1 << 20);
        if (gzread(g, rest.data(), static_cast<unsigned>(rest.size())) < 0) fail();
    }
    if (out.size() < limit) {
        int code = 0;
        gzerror(g, &code);
        if (code != Z_OK && code != Z_STREAM_END) fail();
    }
    gzclose(g);
    return out;
}

void write_parts(const std::string &path, bool gz, const std::vector<std::pair<const void *, std::uint64_t>> &parts) {
    bool ok = true;
    if (gz) {
        gzFile g = gzopen(path.c_str(), "wb6");
        if (g == nullptr) throw IoError(std::string("cannot create: ") + std::strerror(errno));
        for (const auto &[data, bytes] : parts) {
            const auto *p = static_cast<const unsigned char *>(data);
            for (std::uint64_t done = 0; ok && done < bytes;) {
                const unsigned chunk = static_cast<unsigned>(std::min<std::uint64_t>(bytes - done, 1 << 26));
                ok = gzwrite(g, p + done, chunk) == static_cast<int>(chunk);
                done += chunk;
            }
        }
        ok = gzclose(g) == Z_OK && ok;
    } else {
        std::FILE *f = std::fopen(path.c_str(), "wb");
        if (f == nullptr) throw IoError(std::string("cannot create: ") + std::strerror(errno));
        for (const auto &[data, bytes] : parts) ok = ok && (bytes == 0 || std::fwrite(data, 1, bytes, f) == bytes);
        ok = std::fclose(f) == 0 && ok;
    }
    if (!ok) throw IoError(std::string("write failed: ") + std::strerror(errno));
}

}  // namespace hzio
