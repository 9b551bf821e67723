// libFuzzer target: the TCK parser, scanner and decoder on arbitrary bytes.
#include "tck_format.hpp"

#include <cstdint>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    try {
        const tck::Header h = tck::parse_header(data, size);
        const tck::Layout l = tck::scan(data, size, h);
        // Allocation bounded by the file: every vertex takes >= 12 bytes.
        if (l.nb_vertices > size) __builtin_trap();
        std::vector<float> pos(3 * l.nb_vertices);
        std::vector<std::uint64_t> off(l.nb_streamlines + 1);
        tck::decode(data, h, l, pos.data(), off.data());
    } catch (const tck::FormatError &) {
    }
    tck::probe(data, size);
    return 0;
}
