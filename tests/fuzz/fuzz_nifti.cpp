// libFuzzer target: NIfTI-1/2 headers and voxel access (single .nii files
// and, when the input is gzip, .nii.gz), through a file in /dev/shm.
#include "nifti_format.hpp"

#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <unistd.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    const bool gz = size >= 2 && data[0] == 0x1f && data[1] == 0x8b;
    static const std::string base = "/dev/shm/hz_fuzz_nifti_" + std::to_string(::getpid());
    const std::string path = base + (gz ? ".nii.gz" : ".nii");
    if (std::FILE *f = std::fopen(path.c_str(), "wb")) {
        std::fwrite(data, 1, size, f);
        std::fclose(f);
    }
    try {
        const nifti::Image img = nifti::Image::open(path);
        const auto &h = img.header();
        const std::uint64_t bytes = h.nb_voxels * nifti::dtype_size(h.dtype);
        if (!gz && bytes > size) __builtin_trap();  // the size check must hold for plain files
        volatile unsigned char sink = 0;
        for (std::uint64_t i = 0; i < bytes; i += 4096) sink = sink ^ img.data()[i];
        if (bytes) sink = sink ^ img.data()[bytes - 1];
    } catch (const std::runtime_error &) {}
    return 0;
}
