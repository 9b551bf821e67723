#include "shell_proxy.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <mutex>

namespace hz::core::render {

std::uint64_t streamline_hash(std::uint64_t s) {
    std::uint64_t z = (s + 1) * 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

void chebyshev_steps(const std::array<int, 3> &dim, std::vector<std::uint8_t> &d, std::vector<std::uint32_t> queue) {
    // (the queue holds distance 0, then 1, ... in order)
    const std::size_t sy = std::size_t(dim[0]), sz = sy * dim[1];
    for (std::size_t q = 0; q < queue.size(); ++q) {
        const std::size_t k = queue[q];
        const int x = int(k % sy), y = int(k / sy % dim[1]), z = int(k / sz);
        const std::uint8_t dk = d[k];
        if (dk >= 254) continue;
        for (int dz = -1; dz <= 1; ++dz)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int X = x + dx, Y = y + dy, Z = z + dz;
                    if (X < 0 || Y < 0 || Z < 0 || X >= dim[0] || Y >= dim[1] || Z >= dim[2]) continue;
                    const std::size_t n = std::size_t(Z) * sz + std::size_t(Y) * sy + std::size_t(X);
                    if (d[n] != 255) continue;
                    d[n] = std::uint8_t(dk + 1);
                    queue.push_back(std::uint32_t(n));
                }
    }
}

namespace {

std::uint32_t clamp_count(std::uint64_t n) { return std::uint32_t(std::min<std::uint64_t>(n, 0xFFFFFFFFu)); }

struct Grid {
    std::array<int, 3> dim{};
    std::array<double, 3> origin{};
    double inv_vox = 1;
    std::vector<std::uint8_t> v;
    std::size_t at(int x, int y, int z) const { return (std::size_t(z) * dim[1] + y) * dim[0] + x; }
    // The voxel of point p; SIZE_MAX when outside (or not finite).
    std::size_t voxel(const float *p) const {
        int c[3];
        for (int i = 0; i < 3; ++i) {
            const double f = (double(p[i]) - origin[i]) * inv_vox;
            if (!(f >= 0 && f < dim[i])) return std::numeric_limits<std::size_t>::max();
            c[i] = int(f);
        }
        return at(c[0], c[1], c[2]);
    }
};

// One pass of a separable max (dilate) or min (erode) filter of radius r
// along axis `ax`.
void filter_axis(Grid &g, int ax, int r, bool dilate) {
    const std::array<int, 3> d = g.dim;
    std::vector<std::uint8_t> out(g.v.size());
    const int n = d[ax];
    std::vector<std::uint8_t> line(n);
    const int a1 = ax == 0 ? 1 : 0, a2 = ax == 2 ? 1 : 2;
    for (int j = 0; j < d[a2]; ++j)
        for (int i = 0; i < d[a1]; ++i) {
            auto idx = [&](int k) {
                int c[3];
                c[ax] = k, c[a1] = i, c[a2] = j;
                return g.at(c[0], c[1], c[2]);
            };
            for (int k = 0; k < n; ++k) line[k] = g.v[idx(k)];
            for (int k = 0; k < n; ++k) {
                std::uint8_t m = dilate ? 0 : 1;
                for (int q = std::max(0, k - r); q <= std::min(n - 1, k + r); ++q) m = dilate ? std::max(m, line[q]) : std::min(m, line[q]);
                out[idx(k)] = m;
            }
        }
    g.v.swap(out);
}

}  // namespace

std::vector<Piece> uniform_proxy(const Tractogram &t, double budget_points) {
    std::vector<Piece> out;
    const std::uint64_t N = t.nb_streamlines();
    const double keep = std::min(1.0, std::max(1.0, budget_points) / std::max<double>(1.0, double(t.nb_vertices())));
    const std::uint64_t cut = keep >= 1.0 ? std::numeric_limits<std::uint64_t>::max() : std::uint64_t(keep * 18446744073709551615.0);
    std::vector<std::pair<std::uint64_t, std::uint64_t>> order;  // (hash, s): any prefix is uniform too
    for (std::uint64_t s = 0; s < N; ++s)
        if (const std::uint64_t h = streamline_hash(s); h < cut) order.emplace_back(h, s);
    std::sort(order.begin(), order.end());
    for (const auto &[h, s] : order) out.push_back({s, 0, clamp_count(t.size(s))});
    if (out.empty() && N) out.push_back({0, 0, clamp_count(t.size(0))});
    return out;
}

std::vector<Piece> shell_proxy(const Tractogram &t, const Bounds &b, double budget_points, const std::atomic<bool> &cancel, bool all_cores,
                               int grid, int shell_voxels) {
    const std::uint64_t N = t.nb_streamlines();
    // On every core (someone waits for it), or on this thread alone (a
    // window's first frames need the other core).
    auto run_ranges = [&](std::uint64_t n, const std::function<void(std::uint64_t, std::uint64_t)> &fn) {
        if (all_cores)
            parallel_ranges(n, 4096, fn);
        else if (n)
            fn(0, n);
    };
    if (N == 0 || b.empty) return {};
    const float *P = t.positions.data();
    const int close_r = 2, pad = close_r + 1;
    Grid g;
    double extent = 0;
    for (int i = 0; i < 3; ++i) extent = std::max(extent, b.max[i] - b.min[i]);
    const double vox = std::max(extent, 1e-3) / std::max(grid, 8);
    g.inv_vox = 1.0 / vox;
    for (int i = 0; i < 3; ++i) {
        g.dim[i] = int((b.max[i] - b.min[i]) / vox) + 1 + 2 * pad;
        g.origin[i] = b.min[i] - pad * vox;
    }
    const std::size_t nvox = std::size_t(g.dim[0]) * g.dim[1] * g.dim[2];
    g.v.assign(nvox, 0);

    // 1. Occupancy, one grid per thread, merged.
    std::mutex merge;
    run_ranges(N, [&](std::uint64_t a, std::uint64_t e) {
        std::vector<std::uint8_t> mine(nvox, 0);
        for (std::uint64_t s = a; s < e; ++s) {
            if ((s & 4095) == 0 && cancel.load(std::memory_order_relaxed)) return;
            for (std::uint64_t i = t.begin(s); i < t.end(s); ++i)
                if (const std::size_t k = g.voxel(P + i * 3); k < nvox) mine[k] = 1;
        }
        std::lock_guard<std::mutex> lock(merge);
        for (std::size_t k = 0; k < nvox; ++k) g.v[k] |= mine[k];
    });
    if (cancel) return {};
    // Closing: fills the gaps between neighbouring streamlines.
    for (int ax = 0; ax < 3; ++ax) filter_axis(g, ax, close_r, true);
    for (int ax = 0; ax < 3; ++ax) filter_axis(g, ax, close_r, false);

    // 2. The outside (empty voxels reached from the border, 6-connected),
    // then each voxel's depth from it (26-connected steps, capped at 255).
    std::vector<std::uint8_t> depth(nvox, 255);
    std::vector<std::uint32_t> queue;
    auto push_outside = [&](int x, int y, int z) {
        const std::size_t k = g.at(x, y, z);
        if (g.v[k] || depth[k] == 0) return;
        depth[k] = 0;
        queue.push_back(std::uint32_t(k));
    };
    for (int z = 0; z < g.dim[2]; ++z)
        for (int y = 0; y < g.dim[1]; ++y)
            for (int x = 0; x < g.dim[0]; ++x)
                if (x == 0 || y == 0 || z == 0 || x == g.dim[0] - 1 || y == g.dim[1] - 1 || z == g.dim[2] - 1) push_outside(x, y, z);
    const std::size_t sy = std::size_t(g.dim[0]), sz = sy * g.dim[1];
    for (std::size_t q = 0; q < queue.size(); ++q) {
        const std::size_t k = queue[q];
        const int x = int(k % sy), y = int(k / sy % g.dim[1]), z = int(k / sz);
        if (x > 0) push_outside(x - 1, y, z);
        if (x + 1 < g.dim[0]) push_outside(x + 1, y, z);
        if (y > 0) push_outside(x, y - 1, z);
        if (y + 1 < g.dim[1]) push_outside(x, y + 1, z);
        if (z > 0) push_outside(x, y, z - 1);
        if (z + 1 < g.dim[2]) push_outside(x, y, z + 1);
    }
    // Breadth-first from the whole outside at once.
    chebyshev_steps(g.dim, depth, std::move(queue));
    auto depth_at = [&](std::uint64_t i) -> std::uint8_t {
        const std::size_t k = g.voxel(P + i * 3);
        return k < nvox ? depth[k] : 0;
    };

    // 3. Per streamline: its smallest depth and its points in the shell.
    std::vector<std::uint8_t> min_depth(N, 255);
    std::vector<std::uint32_t> in_shell(N, 0);
    run_ranges(N, [&](std::uint64_t a, std::uint64_t e) {
        for (std::uint64_t s = a; s < e; ++s) {
            if ((s & 4095) == 0 && cancel.load(std::memory_order_relaxed)) return;
            std::uint8_t m = 255;
            std::uint64_t c = 0;
            for (std::uint64_t i = t.begin(s); i < t.end(s); ++i) {
                const std::uint8_t d = depth_at(i);
                m = std::min(m, d);
                c += d <= shell_voxels;
            }
            min_depth[s] = m, in_shell[s] = clamp_count(c);
        }
    });
    if (cancel) return {};

    // Layers by smallest depth, outermost first, until the budget is met;
    // within the last layer, a uniform choice (by hash).
    std::array<double, 256> layer_points{};
    for (std::uint64_t s = 0; s < N; ++s) layer_points[min_depth[s]] += in_shell[s];
    double taken = 0;
    int last = 0;
    for (; last < 256; ++last) {
        if (taken + layer_points[last] >= budget_points) break;
        taken += layer_points[last];
    }
    std::vector<std::uint8_t> chosen(N, 0);
    for (std::uint64_t s = 0; s < N; ++s) chosen[s] = min_depth[s] < last;
    if (last < 256) {
        std::vector<std::pair<std::uint64_t, std::uint64_t>> layer;  // (hash, s)
        for (std::uint64_t s = 0; s < N; ++s)
            if (min_depth[s] == last && in_shell[s] >= 2) layer.emplace_back(streamline_hash(s), s);
        std::sort(layer.begin(), layer.end());
        for (const auto &[h, s] : layer) {
            if (taken >= budget_points) break;
            chosen[s] = 1;
            taken += in_shell[s];
        }
    }
    std::vector<std::uint32_t>().swap(in_shell);
    // In the order they were chosen (outermost layer first, by hash within a
    // layer): any prefix is the shell of a smaller budget.
    std::vector<std::pair<std::uint64_t, std::uint64_t>> order;  // ((depth, hash), s)
    for (std::uint64_t s = 0; s < N; ++s)
        if (chosen[s]) order.emplace_back((std::uint64_t(min_depth[s]) << 56) | (streamline_hash(s) >> 8), s);
    std::sort(order.begin(), order.end());
    std::vector<std::uint8_t>().swap(min_depth);

    // 4. The chosen streamlines' runs of at least two points in the shell.
    std::vector<Piece> out;
    for (std::size_t o = 0; o < order.size(); ++o) {
        const std::uint64_t s = order[o].second;
        if ((o & 4095) == 0 && cancel.load(std::memory_order_relaxed)) return {};
        const std::uint64_t sb = t.begin(s), se = t.end(s);
        std::uint64_t run = sb;
        for (std::uint64_t i = sb; i <= se; ++i) {
            const bool in = i < se && depth_at(i) <= shell_voxels;
            if (in) continue;
            if (i - run >= 2) out.push_back({s, clamp_count(run - sb), clamp_count(i - run)});
            run = i + 1;
        }
    }
    return out;
}

}  // namespace hz::core::render
