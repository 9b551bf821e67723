// libFuzzer target: PLY (Horizon's header checks and decoder) and OBJ (vertex checks,
// then tinyobjloader) from memory, as the plugin parses its mapped file.
// Inputs starting "ply" go to the PLY reader, all others to the OBJ reader.
#include "plyobj_format.hpp"

#include <cstdint>
#include <cstring>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    try {
        const bool ply = size >= 4 && std::memcmp(data, "ply", 3) == 0;
        const plyobj::Mesh m = ply ? plyobj::read_ply(data, size) : plyobj::read_obj(data, size);
        const std::size_t nv = m.vertices.size() / 3;
        for (std::uint32_t f : m.faces)
            if (f >= nv) __builtin_trap();  // faces are checked
        if (!m.colors.empty() && m.colors.size() != m.vertices.size()) __builtin_trap();
    } catch (const plyobj::FormatError &) {}
    return 0;
}
