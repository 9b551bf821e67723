// libFuzzer target: TRX archives (zip parsing by libzip, our validation and
// reads). Inputs go through a file in /dev/shm, as the loader opens paths.
#include "trx_format.hpp"

#include <cstdint>
#include <stdexcept>
#include <cstdio>
#include <string>
#include <unistd.h>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    static const std::string path = "/dev/shm/hz_fuzz_trx_" + std::to_string(::getpid()) + ".trx";
    if (std::FILE *f = std::fopen(path.c_str(), "wb")) {
        std::fwrite(data, 1, size, f);
        std::fclose(f);
    }
    try {
        const trx::File t = trx::open(path);
        if (t.nb_vertices > size || t.nb_streamlines > size) {
            // Sizes were checked against the entries, which libzip bounds by
            // the archive; a deflated entry may legitimately expand, so only
            // read when it stays small.
            if (t.nb_vertices > (1u << 22) || t.nb_streamlines > (1u << 22)) return 0;
        }
        std::vector<float> pos(3 * t.nb_vertices);
        std::vector<std::uint64_t> off(t.nb_streamlines + 1);
        trx::read_streamlines(t, pos.data(), off.data(), {});
        for (const auto &a : t.arrays) {
            if (a.rows * a.cols > (1u << 22)) continue;
            std::vector<unsigned char> buf(a.rows * a.cols * trx::dtype_size(a.dtype));
            trx::read_array(t, a, buf.data());
        }
    } catch (const trx::FormatError &) {
    } catch (const std::runtime_error &) {  // I/O of the scratch file
    }
    return 0;
}
