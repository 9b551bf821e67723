// libFuzzer target: FreeSurfer triangle surfaces, curv files and
// annotations, parsed from memory as the plugin parses its memory-mapped
// file (every input goes through both parsers: annotations have no magic).
#include "fs_format.hpp"

#include <algorithm>
#include <cstdint>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    try {
        const fsurf::Surface s = fsurf::parse(data, size);
        for (std::uint32_t f : s.faces)
            if (f >= s.vertices.size() / 3) __builtin_trap();                                   // faces are checked
        if (s.curv && (s.values.empty() || 15 + 4 * s.values.size() > size)) __builtin_trap();  // sizes are checked
    } catch (const fsurf::FormatError &) {}
    try {
        const fsurf::Annotation a = fsurf::parse_annot(data, size);
        if (4 + 8 * a.labels.size() > size) __builtin_trap();  // counts are checked
        for (std::int32_t l : a.labels) {
            if (l < -1) __builtin_trap();
            if (l >= 0 && std::none_of(a.table.begin(), a.table.end(), [l](const fsurf::AnnotEntry &e) { return e.index == l; }))
                __builtin_trap();  // a label always names a table entry
        }
    } catch (const fsurf::FormatError &) {}
    return 0;
}
