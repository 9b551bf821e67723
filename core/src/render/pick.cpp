#include <hz/core/render/pick.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <utility>
#include <vector>

namespace hz::core::render {

namespace {

struct Clip {
    double x, y, z, w;
};

Clip project(const std::array<double, 16> &m, const float *p) {
    const double x = p[0], y = p[1], z = p[2];
    return {m[0] * x + m[4] * y + m[8] * z + m[12], m[1] * x + m[5] * y + m[9] * z + m[13], m[2] * x + m[6] * y + m[10] * z + m[14],
            m[3] * x + m[7] * y + m[11] * z + m[15]};
}

Clip lerp(const Clip &a, const Clip &b, double t) {
    return {a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t, a.z + (b.z - a.z) * t, a.w + (b.w - a.w) * t};
}

}  // namespace

std::optional<PickHit> pick_streamline(const Tractogram &t, std::span<const float> radius_mm, const View &v, int width, int height,
                                       double x, double y, double tolerance_px, const std::vector<std::uint64_t> *subset) {
    if (width <= 0 || height <= 0 || !std::isfinite(x) || !std::isfinite(y)) return std::nullopt;
    tolerance_px = std::max(tolerance_px, 0.0);
    const std::array<double, 16> m = view_projection(v, width, height);
    // Pixels per mm at a depth of 1 mm (the perspective's focal length).
    const double focal = 0.5 * height / std::tan(0.5 * v.fov_deg * 3.14159265358979323846 / 180.0);
    // For a perspective projection clip w is the depth along the view axis.
    const double near = v.near_mm;
    struct Best {
        std::optional<PickHit> on_tube, beside;  // the point on a tube (nearest the eye); within the tolerance (closest axis)
        double beside_gap = std::numeric_limits<double>::infinity();
    };
    const float *P = t.positions.data();
    const std::uint64_t n = subset ? subset->size() : t.nb_streamlines();
    std::mutex mu;
    Best best;
    parallel_ranges(n, 4096, [&](std::uint64_t from, std::uint64_t to) {
        Best mine;
        auto segment = [&](std::uint64_t s, double r, Clip a, Clip b) {
            if (a.w < near && b.w < near) return;  // behind the near plane
            if (a.w < near)
                a = lerp(a, b, (near - a.w) / (b.w - a.w));
            else if (b.w < near)
                b = lerp(b, a, (near - b.w) / (a.w - b.w));
            const double ax = (a.x / a.w * 0.5 + 0.5) * width, ay = (0.5 - a.y / a.w * 0.5) * height;
            const double bx = (b.x / b.w * 0.5 + 0.5) * width, by = (0.5 - b.y / b.w * 0.5) * height;
            const double dx = bx - ax, dy = by - ay, len2 = dx * dx + dy * dy;
            const double u = len2 > 0 ? std::clamp(((x - ax) * dx + (y - ay) * dy) / len2, 0.0, 1.0) : 0.0;
            const double px = ax + u * dx - x, py = ay + u * dy - y, dist = std::sqrt(px * px + py * py);
            const double depth = 1.0 / ((1.0 - u) / a.w + u / b.w);  // 1/w is linear on screen
            const double r_px = r * focal / depth;
            if (dist <= r_px) {
                if (!mine.on_tube || depth < mine.on_tube->depth_mm) mine.on_tube = PickHit{s, dist, depth};
            } else if (dist <= r_px + tolerance_px && dist - r_px < mine.beside_gap) {
                mine.beside_gap = dist - r_px;
                mine.beside = PickHit{s, dist, depth};
            }
        };
        for (std::uint64_t k = from; k < to; ++k) {
            const std::uint64_t s = subset ? (*subset)[k] : k;
            const std::uint64_t b = t.begin(s), e = t.end(s);
            if (b == e) continue;
            const double r = radius_mm.empty() ? 0.0 : double(radius_mm[s]);
            Clip prev = project(m, P + 3 * b);
            if (e - b == 1) segment(s, r, prev, prev);
            for (std::uint64_t i = b + 1; i < e; ++i) {
                const Clip cur = project(m, P + 3 * i);
                segment(s, r, prev, cur);
                prev = cur;
            }
        }
        // The parts' answers merged: the same answer as one pass (ties: the
        // lower streamline index, as one pass in order keeps the first).
        std::lock_guard<std::mutex> lock(mu);
        if (mine.on_tube && (!best.on_tube || mine.on_tube->depth_mm < best.on_tube->depth_mm ||
                             (mine.on_tube->depth_mm == best.on_tube->depth_mm && mine.on_tube->streamline < best.on_tube->streamline)))
            best.on_tube = mine.on_tube;
        if (mine.beside && (mine.beside_gap < best.beside_gap ||
                            (mine.beside_gap == best.beside_gap && mine.beside->streamline < best.beside->streamline)))
            best.beside = mine.beside, best.beside_gap = mine.beside_gap;
    });
    return best.on_tube ? best.on_tube : best.beside;
}

namespace {

// Whether segments ab and cd of the plane meet (touching counts).
bool segments_meet(double ax, double ay, double bx, double by, double cx, double cy, double dx, double dy) {
    auto orient = [](double px, double py, double qx, double qy, double rx, double ry) {
        const double v = (qx - px) * (ry - py) - (qy - py) * (rx - px);
        return (v > 0) - (v < 0);
    };
    auto on = [](double px, double py, double qx, double qy, double rx, double ry) {  // r on pq, given collinear
        return std::min(px, qx) <= rx && rx <= std::max(px, qx) && std::min(py, qy) <= ry && ry <= std::max(py, qy);
    };
    const int o1 = orient(ax, ay, bx, by, cx, cy), o2 = orient(ax, ay, bx, by, dx, dy);
    const int o3 = orient(cx, cy, dx, dy, ax, ay), o4 = orient(cx, cy, dx, dy, bx, by);
    if (o1 != o2 && o3 != o4) return true;
    return (o1 == 0 && on(ax, ay, bx, by, cx, cy)) || (o2 == 0 && on(ax, ay, bx, by, dx, dy)) || (o3 == 0 && on(cx, cy, dx, dy, ax, ay)) ||
           (o4 == 0 && on(cx, cy, dx, dy, bx, by));
}

}  // namespace

std::vector<std::uint64_t> streamlines_crossing(const Tractogram &t, const View &v, int width, int height,
                                                std::span<const std::array<double, 2>> stroke) {
    std::vector<std::uint64_t> out;
    if (width <= 0 || height <= 0 || stroke.size() < 2) return out;
    const std::array<double, 16> m = view_projection(v, width, height);
    const double near = v.near_mm;
    double lo[2] = {stroke[0][0], stroke[0][1]}, hi[2] = {lo[0], lo[1]};
    for (const auto &q : stroke)
        for (int i = 0; i < 2; ++i) lo[i] = std::min(lo[i], q[i]), hi[i] = std::max(hi[i], q[i]);
    const float *P = t.positions.data();
    std::mutex mu;
    std::vector<std::pair<std::uint64_t, std::vector<std::uint64_t>>> parts;
    parallel_ranges(t.nb_streamlines(), 1024, [&](std::uint64_t from, std::uint64_t to) {
        std::vector<std::uint64_t> mine;
        auto crosses = [&](Clip a, Clip b) {
            if (a.w < near && b.w < near) return false;
            if (a.w < near)
                a = lerp(a, b, (near - a.w) / (b.w - a.w));
            else if (b.w < near)
                b = lerp(b, a, (near - b.w) / (a.w - b.w));
            const double ax = (a.x / a.w * 0.5 + 0.5) * width, ay = (0.5 - a.y / a.w * 0.5) * height;
            const double bx = (b.x / b.w * 0.5 + 0.5) * width, by = (0.5 - b.y / b.w * 0.5) * height;
            if (std::max(ax, bx) < lo[0] || std::min(ax, bx) > hi[0] || std::max(ay, by) < lo[1] || std::min(ay, by) > hi[1]) return false;
            for (std::size_t k = 1; k < stroke.size(); ++k)
                if (segments_meet(ax, ay, bx, by, stroke[k - 1][0], stroke[k - 1][1], stroke[k][0], stroke[k][1])) return true;
            return false;
        };
        for (std::uint64_t s = from; s < to; ++s) {
            const std::uint64_t b = t.begin(s), e = t.end(s);
            if (b == e) continue;
            Clip prev = project(m, P + 3 * b);
            bool hit = e - b == 1 && crosses(prev, prev);
            for (std::uint64_t i = b + 1; i < e && !hit; ++i) {
                const Clip cur = project(m, P + 3 * i);
                hit = crosses(prev, cur);
                prev = cur;
            }
            if (hit) mine.push_back(s);
        }
        std::lock_guard<std::mutex> lock(mu);
        parts.emplace_back(from, std::move(mine));
    });
    std::sort(parts.begin(), parts.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
    for (auto &pp : parts) out.insert(out.end(), pp.second.begin(), pp.second.end());
    return out;
}

std::optional<double> ray_mesh(const Mesh &m, const std::array<double, 3> &o, const std::array<double, 3> &d) {
    const float *V = m.vertices.data();
    const std::uint32_t *F = m.faces.data();
    const std::uint64_t nv = m.nb_vertices();
    std::mutex mu;
    double best = std::numeric_limits<double>::infinity();
    parallel_ranges(m.nb_faces(), 8192, [&](std::uint64_t from, std::uint64_t to) {
        double mine = std::numeric_limits<double>::infinity();
        for (std::uint64_t f = from; f < to; ++f) {
            const std::uint32_t ia = F[f * 3], ib = F[f * 3 + 1], ic = F[f * 3 + 2];
            if (ia >= nv || ib >= nv || ic >= nv) continue;
            // Moller-Trumbore, in double.
            double a[3], e1[3], e2[3];
            for (int i = 0; i < 3; ++i) a[i] = V[ia * 3 + i], e1[i] = V[ib * 3 + i] - a[i], e2[i] = V[ic * 3 + i] - a[i];
            const double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
            const double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
            if (std::abs(det) < 1e-12) continue;
            const double inv = 1.0 / det, tv[3] = {o[0] - a[0], o[1] - a[1], o[2] - a[2]};
            const double u = (tv[0] * p[0] + tv[1] * p[1] + tv[2] * p[2]) * inv;
            if (u < 0 || u > 1) continue;
            const double q[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2], tv[0] * e1[1] - tv[1] * e1[0]};
            const double w = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv;
            if (w < 0 || u + w > 1) continue;
            const double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
            if (t > 0 && t < mine) mine = t;
        }
        std::lock_guard<std::mutex> lock(mu);
        best = std::min(best, mine);
    });
    if (!std::isfinite(best)) return std::nullopt;
    return best;
}

}  // namespace hz::core::render
