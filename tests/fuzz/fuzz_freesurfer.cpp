// libFuzzer target: FreeSurfer triangle surfaces and curv files, parsed from
// memory as the plugin parses its memory-mapped file.
#include "fs_format.hpp"

#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    try {
        const fsurf::Surface s = fsurf::parse(data, size);
        for (std::uint32_t f : s.faces)
            if (f >= s.vertices.size() / 3) __builtin_trap();  // faces are checked
        if (s.curv && (s.values.empty() || 15 + 4 * s.values.size() > size)) __builtin_trap();  // sizes are checked
    } catch (const fsurf::FormatError &) {
    }
    return 0;
}
