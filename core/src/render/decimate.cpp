// Polyline decimation (see decimate.hpp).
#include <hz/core/render/decimate.hpp>

#include <array>

namespace hz::core::render {

void decimate(const float *p, std::uint64_t n, double tol, std::vector<std::uint32_t> &keep) {
    keep.clear();
    if (n == 0) return;
    keep.push_back(0);
    if (n == 1) return;
    if (!(tol > 0)) {
        for (std::uint64_t i = 1; i < n; ++i) keep.push_back(std::uint32_t(i));
        return;
    }
    const double tol2 = tol * tol;
    // The window's points relative to the segment's first point `a`, in
    // double, converted once per window (not once per test): x[i], y[i],
    // z[i] and the squared length r2[i] of point a + i.
    constexpr std::uint32_t W = kDecimateWindow + 1;
    std::array<double, W> x, y, z, r2;
    std::uint64_t a = 0, filled = 1;  // points a .. a + filled - 1 are converted
    x[0] = y[0] = z[0] = r2[0] = 0;
    for (std::uint64_t j = 2; j < n; ++j) {
        // Can a..j be one segment? The distance from a point q (relative to
        // a) to the segment from 0 to d is |q| before it (q.d <= 0), |q - d|
        // past it (q.d >= d.d), else sqrt(|q|^2 - (q.d)^2 / d.d): compared
        // with tol without a division.
        bool ok = j - a <= kDecimateWindow;
        if (ok) {
            const std::uint64_t last = j - a;
            for (; filled <= last; ++filled) {
                const float *q = p + (a + filled) * 3;
                x[filled] = double(q[0]) - double(p[a * 3]);
                y[filled] = double(q[1]) - double(p[a * 3 + 1]);
                z[filled] = double(q[2]) - double(p[a * 3 + 2]);
                r2[filled] = x[filled] * x[filled] + y[filled] * y[filled] + z[filled] * z[filled];
            }
            const double dx = x[last], dy = y[last], dz = z[last], dd = r2[last];
            const double lim = tol2 * dd;
            int bad = 0;
            for (std::uint64_t m = 1; m < last; ++m) {
                const double dot = x[m] * dx + y[m] * dy + z[m] * dz;
                const double ex = x[m] - dx, ey = y[m] - dy, ez = z[m] - dz;
                const bool before = dot <= 0, past = dot >= dd;
                const double e_end = before ? r2[m] : ex * ex + ey * ey + ez * ez;
                bad |= (before || past) ? e_end > tol2 : r2[m] * dd - dot * dot > lim;
            }
            ok = !bad;
        }
        if (!ok) {
            a = j - 1;
            keep.push_back(std::uint32_t(a));
            // The new window starts at a: its first point is the origin.
            x[0] = y[0] = z[0] = r2[0] = 0;
            filled = 1;
        }
    }
    keep.push_back(std::uint32_t(n - 1));
}

}  // namespace hz::core::render
