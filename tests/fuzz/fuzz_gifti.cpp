// libFuzzer target: GIFTI XML, decoders (base64, zlib, ASCII) and checks,
// through a file in /dev/shm.
#include "gifti_format.hpp"

#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    static const std::string path = "/dev/shm/hz_fuzz_gifti_" + std::to_string(::getpid()) + ".gii";
    if (std::FILE *f = std::fopen(path.c_str(), "wb")) {
        std::fwrite(data, 1, size, f);
        std::fclose(f);
    }
    try {
        const gifti::Surface s = gifti::read(path);
        for (std::uint32_t f : s.faces)
            if (f >= s.vertices.size() / 3) __builtin_trap();  // faces are checked
    } catch (const std::runtime_error &) {}
    return 0;
}
