// libFuzzer target: the TCK parser, scanner and decoder on arbitrary bytes.
#include "tck_format.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    try {
        const tck::Header h = tck::parse_header(data, size);
        const tck::Layout l = tck::scan(data, size, h);
        (void)tck::declared_count(h);  // (the count warned about when it disagrees with the data; under the sanitizers)
        // Allocation bounded by the file: every vertex takes >= 12 bytes.
        if (l.nb_vertices > size) __builtin_trap();
        std::vector<float> pos(3 * l.nb_vertices);
        std::vector<std::uint64_t> off(l.nb_streamlines + 1);
        tck::decode(data, h, l, pos.data(), off.data());
        // What a mapped read (ABI 1.5 delimited extent) hands the host: every
        // streamline's points, each followed by an all-NaN delimiter triple,
        // the same points decode() copied.
        if (h.datatype == tck::DataType::Float32LE && l.delimiters.size() == l.nb_streamlines) {
            std::uint64_t start = 0;
            for (std::uint64_t k = 0; k < l.nb_streamlines; ++k) {
                const std::uint64_t d = l.delimiters[k];
                if (d < start || off[k + 1] - off[k] != d - start) __builtin_trap();
                float t[3];
                std::memcpy(t, data + h.data_offset + 12 * d, 12);
                if (!(std::isnan(t[0]) && std::isnan(t[1]) && std::isnan(t[2]))) __builtin_trap();
                if (d > start && std::memcmp(data + h.data_offset + 12 * start, pos.data() + 3 * off[k], 12 * (d - start)) != 0)
                    __builtin_trap();
                start = d + 1;
            }
            if (start != l.nb_vertices + l.nb_streamlines) __builtin_trap();
        }
        // The bounds the scan vouches for (ABI 1.6): exactly the decoded points'.
        if (l.has_bounds != (h.datatype == tck::DataType::Float32LE && l.nb_vertices > 0)) __builtin_trap();
        for (int d = 0; d < 3 && l.has_bounds; ++d) {
            float lo = pos[d], hi = pos[d];
            for (std::uint64_t i = d; i < pos.size(); i += 3) {
                if (!std::isfinite(pos[i])) __builtin_trap();
                lo = std::min(lo, pos[i]);
                hi = std::max(hi, pos[i]);
            }
            if (l.lo[d] != lo || l.hi[d] != hi) __builtin_trap();
        }
    } catch (const tck::FormatError &) {}
    tck::probe(data, size);
    return 0;
}
