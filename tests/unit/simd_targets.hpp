// Runs a test body once per SIMD target: Highway's code (the TCK scan, the
// TRK transform, the clustering kernels) dispatches to the best target the
// CPU runs, AVX-512 on this project's machines, while most users' CPUs take
// AVX2 or SSE4. libhwy holds the choice for the whole process (the test and
// the plugins it loads alike), so forcing a target here reaches them all.
#pragma once

#include <hwy/targets.h>

#include <catch2/catch.hpp>

#include <cstdint>
#include <vector>

namespace hz::test {

// Every target Highway compiled (HWY_TARGETS) that this CPU runs, best first.
inline std::vector<std::int64_t> simd_targets() { return hwy::SupportedAndGeneratedTargets(); }

// body(name) with each of simd_targets() forced in turn; the normal choice is
// restored afterwards, also when the body throws (a failed REQUIRE).
template <class Body>
void for_each_simd_target(Body &&body) {
    struct Restore {
        ~Restore() { hwy::SetSupportedTargetsForTest(0); }
    } restore;
    for (const std::int64_t target : simd_targets()) {
        hwy::SetSupportedTargetsForTest(target);
        const char *name = hwy::TargetName(target);
        INFO("SIMD target " << name);
        body(name);
    }
}

}  // namespace hz::test
