// libFuzzer target: the TRK header parser, record scanner and decoder.
#include "trk_format.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size) {
    try {
        const trk::Header h = trk::parse_header(data, size);
        // The walk in many chains (from guessed record starts) must give the
        // single walk's result and first error.
        std::string many_error;
        trk::Layout many;
        try {
            many = trk::scan(data, size, h, {}, trk::ScanPlan{7, 1});
        } catch (const trk::FormatError &e) {
            many_error = e.what();
        }
        trk::Layout l;
        try {
            l = trk::scan(data, size, h, {}, trk::ScanPlan{1, 1});
        } catch (const trk::FormatError &e) {
            if (many_error != e.what()) __builtin_trap();
            throw;
        }
        if (!many_error.empty() || many.nb_streamlines != l.nb_streamlines || many.nb_vertices != l.nb_vertices ||
            many.chunks.back().byte != l.chunks.back().byte)
            __builtin_trap();
        if (l.nb_vertices > size) __builtin_trap();
        std::vector<float> pos(3 * l.nb_vertices), sc(l.nb_vertices * h.n_scalars), pr(l.nb_streamlines * h.n_properties);
        std::vector<std::uint64_t> off(l.nb_streamlines + 1);
        trk::Box box;
        trk::decode(data, size, h, l, pos.data(), off.data(), sc.data(), pr.data(), {}, {}, &box);
        // The bounds the loader vouches for (ABI 1.7): exactly the decoded points'.
        for (int d = 0; d < 3; ++d) {
            float lo = HUGE_VALF, hi = -HUGE_VALF;
            for (std::uint64_t v = 0; v < l.nb_vertices; ++v) {
                lo = std::min(lo, pos[3 * v + d]);
                hi = std::max(hi, pos[3 * v + d]);
            }
            if (box.lo[d] != lo || box.hi[d] != hi) __builtin_trap();
        }
    } catch (const trk::FormatError &) {}
    trk::probe(data, size);
    return 0;
}
