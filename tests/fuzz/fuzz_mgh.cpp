// libFuzzer target: MGH headers, footers and voxel access (.mgh files and,
// when the input is gzip, .mgz), through a file in /dev/shm.
#include "gzip.hpp"
#include "mgh_format.hpp"

#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    const bool gz = size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
    static const std::string base = "/dev/shm/hz_fuzz_mgh_" + std::to_string(::getpid());
    const std::string path = base + (gz ? ".mgz" : ".mgh");
    if (std::FILE *f = std::fopen(path.c_str(), "wb")) {
        std::fwrite(data, 1, size, f);
        std::fclose(f);
    }
    try {
        const mgh::Volume v = mgh::Volume::open(path);
        const mgh::Header &h = v.header();
        if (!gz && mgh::kDataOffset + h.data_bytes > size) __builtin_trap();  // the size check must hold for plain files
        volatile unsigned char sink = 0;
        for (std::uint64_t i = 0; i < h.data_bytes; i += 4096) sink = sink ^ v.voxels()[i];
        if (h.data_bytes) sink = sink ^ v.voxels()[h.data_bytes - 1];
        volatile double a = h.affine()[3];
        (void)a;
    } catch (const std::runtime_error &) {}
    return 0;
}
