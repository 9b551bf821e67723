// What a C++ loader written against ABI 1.7-1.9 used and 1.10 replaced, in
// one place (tests/abi/check_source.py compiles it against today's headers:
// each name must compile, with a deprecation warning naming its
// replacement). Not a plugin: never linked.
#include <hz/cpp/plugin.hpp>
#include <hz/hz.h>

hz_status read_like_1_9(const hz_streamlines_dst *dst) {
    if (dst->flags & HZ_STREAMLINES_OFFSETS_ONLY) return HZ_OK;  // offsets only: the host mapped the positions
    if (hz_positions_check *check = hz::positions_check(dst)) check->vouched = 1;
    return HZ_OK;
}

const hz_loader_caps kCaps = HZ_LOADER_CAN_READ | HZ_LOADER_CAN_WRITE | HZ_LOADER_WRITES_GAP;
