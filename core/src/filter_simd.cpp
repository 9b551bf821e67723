// The inner loops of streamline selection (filter.cpp): the first vertex of
// a run that lies in a sphere or a box. Highway compiles this file once per
// SIMD target and the entry points below dispatch to the best one the CPU
// supports. The arithmetic is element-wise float32 with the scalar code's
// order, ((dx*dx + dy*dy) + dz*dz) <= r*r, and the file is compiled with
// -ffp-contract=off, so every target answers what the scalar test (and
// tckedit) answers, bit for bit.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "filter_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <cstdint>

HWY_BEFORE_NAMESPACE();
namespace hz::core::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

std::uint64_t FirstInSphere(const float *HWY_RESTRICT xyz, std::uint64_t n, float cx, float cy, float cz, float r) {
    const hn::ScalableTag<float> d;
    const std::uint64_t L = hn::Lanes(d);
    const auto vx = hn::Set(d, cx), vy = hn::Set(d, cy), vz = hn::Set(d, cz), r2 = hn::Set(d, r * r);
    std::uint64_t i = 0;
    for (; i + L <= n; i += L) {
        hn::Vec<decltype(d)> x, y, z;
        hn::LoadInterleaved3(d, xyz + 3 * i, x, y, z);
        const auto dx = hn::Sub(vx, x), dy = hn::Sub(vy, y), dz = hn::Sub(vz, z);
        const auto s = hn::Add(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy)), hn::Mul(dz, dz));
        const intptr_t k = hn::FindFirstTrue(d, hn::Le(s, r2));
        if (k >= 0) return i + std::uint64_t(k);
    }
    const float rr = r * r;
    for (; i < n; ++i) {
        const float dx = cx - xyz[3 * i], dy = cy - xyz[3 * i + 1], dz = cz - xyz[3 * i + 2];
        if (dx * dx + dy * dy + dz * dz <= rr) return i;
    }
    return n;
}

std::uint64_t FirstInBox(const float *HWY_RESTRICT xyz, std::uint64_t n, const float *lo, const float *hi) {
    const hn::ScalableTag<float> d;
    const std::uint64_t L = hn::Lanes(d);
    const auto x0 = hn::Set(d, lo[0]), y0 = hn::Set(d, lo[1]), z0 = hn::Set(d, lo[2]);
    const auto x1 = hn::Set(d, hi[0]), y1 = hn::Set(d, hi[1]), z1 = hn::Set(d, hi[2]);
    std::uint64_t i = 0;
    for (; i + L <= n; i += L) {
        hn::Vec<decltype(d)> x, y, z;
        hn::LoadInterleaved3(d, xyz + 3 * i, x, y, z);
        const auto in = hn::And(hn::And(hn::And(hn::Ge(x, x0), hn::Le(x, x1)), hn::And(hn::Ge(y, y0), hn::Le(y, y1))),
                                hn::And(hn::Ge(z, z0), hn::Le(z, z1)));
        const intptr_t k = hn::FindFirstTrue(d, in);
        if (k >= 0) return i + std::uint64_t(k);
    }
    for (; i < n; ++i) {
        const float *p = xyz + 3 * i;
        if (p[0] >= lo[0] && p[0] <= hi[0] && p[1] >= lo[1] && p[1] <= hi[1] && p[2] >= lo[2] && p[2] <= hi[2]) return i;
    }
    return n;
}

}  // namespace HWY_NAMESPACE
}  // namespace hz::core::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace hz::core::detail {
HWY_EXPORT(FirstInSphere);
HWY_EXPORT(FirstInBox);

// The index in [0, n) of the first of the n xyz triples at `xyz` inside the
// sphere (|p - c|^2 <= r^2 in float32), or n.
std::uint64_t first_in_sphere(const float *xyz, std::uint64_t n, float cx, float cy, float cz, float r) {
    return HWY_DYNAMIC_DISPATCH(FirstInSphere)(xyz, n, cx, cy, cz, r);
}
// The same for the box [lo, hi] (inclusive).
std::uint64_t first_in_box(const float *xyz, std::uint64_t n, const float *lo, const float *hi) {
    return HWY_DYNAMIC_DISPATCH(FirstInBox)(xyz, n, lo, hi);
}
}  // namespace hz::core::detail
#endif
