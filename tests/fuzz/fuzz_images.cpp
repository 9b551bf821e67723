// libFuzzer target: the images backend (OpenImageIO) as the plugin uses it:
// header, then, for images small enough for a fuzzer, every pixel. The
// first input byte picks the file extension OpenImageIO sees.
#include "backend.h"

#include <hz/hz_types.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <unistd.h>
#include <vector>

extern "C" const hzimg_backend *hzimg_backend_v1();

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    if (size < 1) return 0;
    static const char *const kExt[] = {"png", "jpg", "exr", "hdr", "tif"};
    const std::string path = "/dev/shm/hz_fuzz_images_" + std::to_string(::getpid()) + "." + kExt[data[0] % 5];
    if (std::FILE *f = std::fopen(path.c_str(), "wb")) {
        std::fwrite(data + 1, 1, size - 1, f);
        std::fclose(f);
    }
    const hzimg_backend *b = hzimg_backend_v1();
    hzimg_info info{};
    char err[512];
    if (b->info(path.c_str(), &info, err, sizeof err) != 0) return 0;
    if (info.width == 0 || info.height == 0 || info.channels == 0) __builtin_trap();  // info() rejects these
    const std::uint64_t n = info.width * info.height * info.channels;
    if (n > (1u << 22)) return 0;  // larger images are fine, but too slow for a fuzzer
    const std::size_t es = info.dtype == HZ_DTYPE_U8 ? 1 : info.dtype == HZ_DTYPE_U16 ? 2 : 4;
    std::vector<unsigned char> px(n * es);
    b->read(path.c_str(), info.dtype, px.data(), px.size(), err, sizeof err);
    return 0;
}
