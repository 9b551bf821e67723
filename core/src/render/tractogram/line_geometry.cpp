// Streamline geometry on the CPU (line_geometry.hpp).
#include "line_geometry.hpp"

#include "../colour.hpp"

#include <hz/core/render/decimate.hpp>
#include <hz/core/render/renderer.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

namespace hz::core::render {

std::vector<float> tube_radii(const Object &o) {
    const Tractogram &t = o.data.tractogram;
    const std::uint64_t N = t.nb_streamlines();
    std::vector<float> radius(N, float(o.radius_mm));
    for (const auto &x : t.arrays)  // (each streamline's own radius: connectome edges by weight)
        if (x.name == "radius_mm" && x.attach == HZ_ATTACH_STREAMLINE && x.count == N && x.components == 1) {
            const std::vector<double> r = array_values(x);
            for (std::uint64_t i = 0; i < N; ++i) radius[i] = float(std::clamp(r[i], 1e-3, 100.0));
            return radius;
        }
    if (o.clustering && o.clustering->width_by_size) {
        for (const auto &x : t.arrays)
            if (x.name == "cluster_size" && x.attach == HZ_ATTACH_STREAMLINE && x.count == N) {
                std::vector<double> sz = array_values(x);
                std::vector<double> sorted = sz;
                std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
                const double med = sorted.empty() ? 1.0 : std::max(1.0, sorted[sorted.size() / 2]);
                for (std::uint64_t i = 0; i < N; ++i)
                    radius[i] = float(o.radius_mm * std::clamp(std::sqrt(std::max(sz[i], 1.0) / med), 0.35, 3.0));
            }
    }
    return radius;
}

// The colouring of tractogram object `o`, resolved per streamline.
std::shared_ptr<LineData> line_data(const Object &o) {
    auto d = std::make_shared<LineData>();
    const Tractogram &t = o.data.tractogram;
    const std::uint64_t N = t.nb_streamlines();
    d->t = &t;
    const Coloring &c = o.coloring;
    if (c.mode == "direction")
        d->mode = LineData::Mode::Direction;
    else if (c.mode == "cluster")
        d->mode = LineData::Mode::Cluster;
    else if (c.mode == "data")
        d->mode = LineData::Mode::Data;
    else
        d->mode = LineData::Mode::Solid;
    d->solid = rgba8(c.color[0], c.color[1], c.color[2]);
    if (d->mode == LineData::Mode::Data) {
        const DataArray *a = nullptr;
        for (const auto &x : t.arrays)
            if (x.name == c.array && (x.attach == HZ_ATTACH_VERTEX || x.attach == HZ_ATTACH_STREAMLINE)) a = &x;
        if (!a) {
            std::string list;
            for (const auto &x : t.arrays) list += (list.empty() ? "" : ", ") + x.name;
            throw Error(o.name + ": color: no per-point or per-streamline array '" + c.array +
                        "' (arrays: " + (list.empty() ? "none" : list) + ")");
        }
        d->colormap = c.colormap;
        if (a->attach == HZ_ATTACH_VERTEX) {
            d->per_vertex = a;
            if (c.range)
                d->range = *c.range;
            else {
                double lo = INFINITY, hi = -INFINITY;
                const std::size_t stride = dtype_size(a->dtype) * a->components;
                for (std::uint64_t i = 0; i < a->count; ++i) {
                    const double v = value_at(a->bytes.data() + i * stride, a->dtype);
                    if (std::isfinite(v)) lo = std::min(lo, v), hi = std::max(hi, v);
                }
                d->range = !(lo <= hi) ? std::array<double, 2>{0, 1}
                           : lo == hi  ? std::array<double, 2>{lo, lo + 1}
                                       : std::array<double, 2>{lo, hi};
            }
        } else {
            d->per_streamline = array_values(*a);
            d->range = c.range ? *c.range : finite_range(d->per_streamline);
        }
    }
    if (d->mode == LineData::Mode::Cluster) {
        // By a per-streamline "cluster_id" when present (stable while
        // clusters are expanded or hidden), else by position.
        std::vector<double> ids;
        for (const auto &x : t.arrays)
            if (x.name == "cluster_id" && x.attach == HZ_ATTACH_STREAMLINE && x.count == N) ids = array_values(x);
        d->cluster.resize(N);
        for (std::uint64_t s = 0; s < N; ++s) {
            const double key = ids.empty() ? double(s) : ids[s];
            const auto c = cluster_palette(key);
            d->cluster[s] = rgba8(srgb_to_linear(c[0]), srgb_to_linear(c[1]), srgb_to_linear(c[2]));
        }
    }
    if (!c.mark.empty()) {
        for (const auto &x : t.arrays)
            if (x.name == c.mark && x.attach == HZ_ATTACH_VERTEX && x.count == t.nb_stored() && x.components == 1) d->mark = &x;
        if (!d->mark) throw Error(o.name + ": color: no per-point array '" + c.mark + "' to mark points by");
        d->mark_rgba = rgba8(c.mark_color[0], c.mark_color[1], c.mark_color[2]);
    }
    d->radius = tube_radii(o);
    // Highlighted streamlines (a per-streamline "highlight" array, e.g.
    // the clusters selected in the window): their colour mixed towards
    // white by the value, clamped to [0, 1].
    for (const auto &x : t.arrays)
        if (x.name == "highlight" && x.attach == HZ_ATTACH_STREAMLINE && x.count == N) {
            const std::vector<double> h = array_values(x);
            if (std::any_of(h.begin(), h.end(), [](double v) { return v > 0; })) d->highlight.assign(h.begin(), h.end());
        }
    return d;
}

// The colour every vertex of `d` has, if it is one (solid colouring, or
// per-streamline colours that happen to be equal): with baked materials
// it is a constant of the program.
std::optional<std::array<std::uint8_t, 4>> uniform_colour(const LineData &d) {
    if (!d.highlight.empty() || d.mark || d.t->nb_vertices() == 0) return std::nullopt;
    if (d.mode == LineData::Mode::Solid) return d.solid;
    if (d.mode == LineData::Mode::Cluster && !d.cluster.empty() &&
        std::all_of(d.cluster.begin(), d.cluster.end(), [&](const auto &c) { return c == d.cluster[0]; }))
        return d.cluster[0];
    if (d.mode == LineData::Mode::Data && !d.per_streamline.empty() &&
        std::all_of(d.per_streamline.begin(), d.per_streamline.end(),
                    [&](double v) { return v == d.per_streamline[0] || (std::isnan(v) && std::isnan(d.per_streamline[0])); })) {
        const auto m = colormap(d.colormap, (d.per_streamline[0] - d.range[0]) / (d.range[1] - d.range[0]));
        return rgba8(srgb_to_linear(m[0]), srgb_to_linear(m[1]), srgb_to_linear(m[2]));
    }
    return std::nullopt;
}

// rgba8's quantisation of srgb_to_linear(|x|), x in [-1, 1], through a
// table of 4097 entries (the direction colouring of every vertex).
namespace {
const std::array<std::uint8_t, 4097> &direction_table() {
    static const auto table = [] {
        std::array<std::uint8_t, 4097> t{};
        for (int i = 0; i <= 4096; ++i) t[i] = rgba8(srgb_to_linear(i / 4096.0), 0, 0)[0];
        return t;
    }();
    return table;
}
std::uint8_t direction_lut(float x, const std::array<std::uint8_t, 4097> &table = direction_table()) {
    return table[std::size_t(std::min(std::abs(x), 1.0f) * 4096.0f + 0.5f)];  // (lround, without the call)
}

// The colour of streamline s before per-point colouring, and how much it is
// mixed towards white (the highlight).
struct StreamlineColour {
    std::array<std::uint8_t, 4> rgba;
    double highlight;
};
StreamlineColour streamline_colour(const LineData &d, std::uint64_t s) {
    StreamlineColour c{d.solid, d.highlight.empty() ? 0.0 : std::min<double>(d.highlight[s], 1.0) * 0.75};
    if (d.mode == LineData::Mode::Cluster)
        c.rgba = d.cluster[s];
    else if (d.mode == LineData::Mode::Data && !d.per_vertex) {
        const auto m = colormap(d.colormap, (d.per_streamline[s] - d.range[0]) / (d.range[1] - d.range[0]));
        c.rgba = rgba8(srgb_to_linear(m[0]), srgb_to_linear(m[1]), srgb_to_linear(m[2]));
    }
    return c;
}

// The colour of input point i (unit tangent t) of a streamline coloured `sc`;
// `stride`: bytes per value of the per-point array, if there is one.
std::array<std::uint8_t, 4> point_colour(const LineData &d, const StreamlineColour &sc, std::uint64_t i, std::size_t stride, float tx,
                                         float ty, float tz) {
    std::array<std::uint8_t, 4> col = sc.rgba;
    if (d.mark && value_at(d.mark->bytes.data() + i * dtype_size(d.mark->dtype), d.mark->dtype) != 0)
        col = d.mark_rgba;
    else if (d.mode == LineData::Mode::Direction)
        col = {direction_lut(tx), direction_lut(ty), direction_lut(tz), 255};
    else if (d.per_vertex) {
        const double val = value_at(d.per_vertex->bytes.data() + i * stride, d.per_vertex->dtype);
        const auto m = colormap(d.colormap, (val - d.range[0]) / (d.range[1] - d.range[0]));
        col = rgba8(srgb_to_linear(m[0]), srgb_to_linear(m[1]), srgb_to_linear(m[2]));
    }
    if (sc.highlight > 0)
        for (int c = 0; c < 3; ++c) col[c] = std::uint8_t(std::lround(col[c] + (255 - col[c]) * sc.highlight));
    return col;
}

std::size_t per_vertex_stride(const LineData &d) { return d.per_vertex ? dtype_size(d.per_vertex->dtype) * d.per_vertex->components : 0; }

}  // namespace

void build_lines(const LineData &d, const Piece *pieces, std::uint64_t a, std::uint64_t b, double tol, BuiltLines &out) {
    const Tractogram &t = *d.t;
    const float *P = t.positions.data();
    std::vector<std::uint32_t> keep;
    out.verts.clear(), out.firsts.clear(), out.counts.clear(), out.indices.clear();
    out.segments = out.kept = 0;
    {
        std::uint64_t pts = 0;
        for (std::uint64_t k = a; k < b; ++k) pts += pieces ? pieces[k].count : t.size(k);
        out.verts.reserve(pts);
        out.firsts.reserve(b - a), out.counts.reserve(b - a);
    }
    const std::size_t stride = per_vertex_stride(d);
    for (std::uint64_t k = a; k < b; ++k) {
        const std::uint64_t s = pieces ? pieces[k].s : k;
        const std::uint64_t sb = pieces ? t.begin(s) + pieces[k].first : t.begin(s);
        const std::uint64_t e = pieces ? sb + pieces[k].count : t.end(s), n = e - sb;
        if (n < 2) continue;
        decimate(P + sb * 3, n, tol, keep);
        out.firsts.push_back(GLint(out.verts.size()));
        out.counts.push_back(GLsizei(keep.size()));
        out.segments += keep.size() - 1;
        out.kept += keep.size();
        const StreamlineColour sc = streamline_colour(d, s);
        const float radius = d.radius[s];
        for (std::uint32_t ki = 0; ki < keep.size(); ++ki) {
            const std::uint64_t i = sb + keep[ki];
            const std::uint64_t i0 = i > sb ? i - 1 : i, i1 = i + 1 < e ? i + 1 : i;
            float tx = P[i1 * 3] - P[i0 * 3], ty = P[i1 * 3 + 1] - P[i0 * 3 + 1], tz = P[i1 * 3 + 2] - P[i0 * 3 + 2];
            const float len = std::sqrt(tx * tx + ty * ty + tz * tz);
            if (len > 0 && std::isfinite(len))
                tx /= len, ty /= len, tz /= len;
            else
                tx = ty = tz = 0;
            LineVertex v;
            v.pos[0] = P[i * 3], v.pos[1] = P[i * 3 + 1], v.pos[2] = P[i * 3 + 2];
            v.tangent = pack_snorm_2_10_10_10(tx, ty, tz);
            const std::array<std::uint8_t, 4> col = point_colour(d, sc, i, stride, tx, ty, tz);
            std::memcpy(v.rgba, col.data(), 4);
            v.radius = radius;
            out.verts.push_back(v);
        }
    }
    out.indices.clear();
    out.indices.reserve(out.verts.size() + out.counts.size());
    for (std::size_t k = 0; k < out.firsts.size(); ++k) {
        for (GLsizei q = 0; q < out.counts[k]; ++q) out.indices.push_back(std::uint32_t(out.firsts[k] + q));
        out.indices.push_back(kRestart);
    }
}

namespace {
// Chunks of at most max_points input points over [0, n), item k of
// points_of(k) points.
template <class F>
std::vector<LineChunk> partition_by(std::uint64_t n, std::uint64_t max_points, F &&points_of) {
    std::vector<LineChunk> out;
    LineChunk c;
    for (std::uint64_t k = 0; k < n; ++k) {
        const std::uint64_t pts = points_of(k);
        if (c.points > 0 && c.points + pts > max_points) {
            c.b = k;
            out.push_back(std::move(c));
            c = LineChunk{};
            c.a = k;
        }
        c.points += pts;
    }
    c.b = n;
    if (c.b > c.a) out.push_back(std::move(c));
    return out;
}
}  // namespace

// Chunks of at most max_points input points over streamlines [0, n)
// (or over pieces[0..n)).
std::vector<LineChunk> partition(const Tractogram &t, const Piece *pieces, std::uint64_t n, std::uint64_t max_points) {
    return partition_by(n, max_points, [&](std::uint64_t k) -> std::uint64_t { return pieces ? pieces[k].count : t.size(k); });
}
std::vector<LineChunk> partition(const BrickPiece *pieces, std::uint64_t n, std::uint64_t max_points) {
    return partition_by(n, max_points, [&](std::uint64_t k) -> std::uint64_t { return pieces[k].count(); });
}

void slab_crossings(const LineData &d, int axis, double centre, std::uint64_t a, std::uint64_t b, std::vector<LineVertex> &out,
                    const std::atomic<bool> *cancel) {
    const Tractogram &t = *d.t;
    const float *P = t.positions.data();
    const std::size_t stride = per_vertex_stride(d);
    const float c = float(centre);
    for (std::uint64_t s = a; s < b; ++s) {
        if (cancel && (s & 4095) == 0 && cancel->load(std::memory_order_relaxed)) return;
        const std::uint64_t sb = t.begin(s), e = t.end(s);
        if (e - sb < 2) continue;
        // Sides of the plane: below (< c) or not; a point exactly on the
        // plane is on the upper side, so it is counted once.
        bool below = P[sb * 3 + axis] < c;
        for (std::uint64_t i = sb + 1; i < e; ++i) {
            const bool now = P[i * 3 + axis] < c;
            if (now == below) continue;
            below = now;
            const float *p0 = P + (i - 1) * 3, *p1 = P + i * 3;
            const float u0 = p0[axis] - c, u1 = p1[axis] - c;
            const float f = u0 / (u0 - u1);  // (u0 and u1 differ in sign: finite, in [0, 1])
            float tx = p1[0] - p0[0], ty = p1[1] - p0[1], tz = p1[2] - p0[2];
            const float len = std::sqrt(tx * tx + ty * ty + tz * tz);
            if (!(len > 0) || !std::isfinite(len) || !std::isfinite(f)) continue;
            tx /= len, ty /= len, tz /= len;
            LineVertex v;
            for (int k = 0; k < 3; ++k) v.pos[k] = p0[k] + f * (p1[k] - p0[k]);
            v.pos[axis] = c;
            v.tangent = pack_snorm_2_10_10_10(tx, ty, tz);
            const std::array<std::uint8_t, 4> col = point_colour(d, streamline_colour(d, s), f < 0.5f ? i - 1 : i, stride, tx, ty, tz);
            std::memcpy(v.rgba, col.data(), 4);
            v.radius = d.radius[s];
            out.push_back(v);
        }
    }
}

namespace {

// A grid of bricks over bounds b, and how streamlines are cut into its pieces.
struct BrickGrid {
    std::array<int, 3> dim{};
    double edge = 1;
    float inv = 1, lo[3] = {};
    BrickGrid(const Bounds &b, int per_side) {
        double extent = 0;
        for (int i = 0; i < 3; ++i) extent = std::max(extent, b.max[i] - b.min[i]);
        edge = std::max(extent, 1e-3) / std::max(per_side, 1);
        for (int i = 0; i < 3; ++i) dim[i] = std::max(1, int(std::ceil((b.max[i] - b.min[i]) / edge))), lo[i] = float(b.min[i]);
        inv = float(1.0 / edge);
    }
    std::size_t size() const { return std::size_t(dim[0]) * dim[1] * dim[2]; }
    // The brick of point p; `outside` set when p is outside the bounds (a
    // loader's bounds are not trusted: it is counted in the edge's brick).
    std::uint32_t brick_of(const float *p, bool &outside) const {
        int c[3];
        for (int i = 0; i < 3; ++i) {
            const float f = (p[i] - lo[i]) * inv;
            outside |= !(f >= 0.0f && f < float(dim[i]));
            c[i] = std::clamp(int(f), 0, dim[i] - 1);  // (NaN: 0)
        }
        return std::uint32_t((std::size_t(c[2]) * dim[1] + c[1]) * dim[0] + c[0]);
    }
    // Calls f(brick, first, count, outside) for each piece of streamline s
    // of t: outside when one of the piece's points but its last is outside
    // the brick's cell.
    template <class F>
    void cut(const Tractogram &t, std::uint64_t s, F &&f) const {
        const float *P = t.positions.data();
        const std::uint64_t sb = t.begin(s), n = t.end(s) - sb;
        if (n < 2) return;
        std::uint64_t i0 = 0;
        bool out0 = false;
        std::uint32_t k0 = brick_of(P + sb * 3, out0);
        for (std::uint64_t i = 1; i < n; ++i) {
            bool out = false;
            const std::uint32_t k = brick_of(P + (sb + i) * 3, out);
            if (k == k0) {
                out0 |= out;
                continue;
            }
            f(k0, i0, i - i0 + 1, out0);
            i0 = i, k0 = k, out0 = out;
        }
        if (n - i0 >= 2) f(k0, i0, n - i0, out0);
    }
};

// The BrickPieces a run of cnt >= 2 points takes.
std::uint64_t brick_pieces(std::uint64_t cnt) { return (cnt - 2) / (BrickPiece::kMaxPoints - 1) + 1; }

}  // namespace

int brick_side_for(const Tractogram &t, const Bounds &b, int min_side, int max_side, std::uint64_t max_pieces) {
    const std::uint64_t N = t.nb_streamlines();
    if (N == 0 || N > std::numeric_limits<std::uint32_t>::max() || b.empty) return 0;
    const std::uint64_t every = std::max<std::uint64_t>(1, N / 4096);
    for (int side = max_side; side >= std::max(1, min_side); --side) {
        const BrickGrid grid(b, side);
        std::uint64_t pieces = 0, sampled = 0;
        for (std::uint64_t s = every / 2; s < N; s += every, ++sampled)
            grid.cut(t, s, [&](std::uint32_t, std::uint64_t, std::uint64_t cnt, bool) { pieces += brick_pieces(cnt); });
        if (double(pieces) * double(N) / double(std::max<std::uint64_t>(sampled, 1)) <= double(max_pieces)) return side;
    }
    return 0;
}

Bricks bricks_of(const Tractogram &t, const Bounds &b, int per_side, unsigned threads, const std::atomic<bool> &cancel) {
    Bricks out;
    const std::uint64_t N = t.nb_streamlines();
    if (N == 0 || N > std::numeric_limits<std::uint32_t>::max() || b.empty) return out;
    const BrickGrid grid(b, per_side);
    out.dim = grid.dim;
    const double edge = grid.edge;
    const std::size_t nb = grid.size();
    const float *P = t.positions.data();
    const unsigned parts = std::max(1u, std::min<unsigned>(threads, unsigned(std::min<std::uint64_t>(N, 64))));
    // Pass 1: pieces and bounds per brick, per part.
    std::vector<std::vector<std::uint64_t>> count(parts);
    std::vector<std::vector<std::array<float, 6>>> box(parts);
    std::atomic<bool> stopped{false};
    parallel_ranges(parts, 1, [&](std::uint64_t p0, std::uint64_t p1) {
        for (std::uint64_t part = p0; part < p1; ++part) {
            count[part].assign(nb, 0);
            box[part].assign(nb, {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY});
            const std::uint64_t s0 = N * part / parts, s1 = N * (part + 1) / parts;
            for (std::uint64_t s = s0; s < s1; ++s) {
                if ((s & 4095) == 0 && cancel.load(std::memory_order_relaxed)) return stopped.store(true);
                const std::uint64_t sb = t.begin(s);
                if (t.end(s) - sb > BrickPiece::kMaxFirst) return stopped.store(true);  // (a first point BrickPiece cannot hold)
                grid.cut(t, s, [&](std::uint32_t k, std::uint64_t first, std::uint64_t cnt, bool outside) {
                    count[part][k] += brick_pieces(cnt);
                    // (its other points are in the brick's cell, unless
                    // outside: the box is the cell's, grown to its last, or
                    // to all of them)
                    std::array<float, 6> &bx = box[part][k];
                    for (std::uint64_t i = outside ? first : first + cnt - 1; i < first + cnt; ++i) {
                        const float *q = P + (sb + i) * 3;
                        for (int a = 0; a < 3; ++a) bx[a] = std::min(bx[a], q[a]), bx[3 + a] = std::max(bx[3 + a], q[a]);
                    }
                });
            }
        }
    });
    if (stopped) return Bricks{};
    // Where each part's pieces of each brick go: brick by brick, and within
    // a brick part by part (streamline order).
    std::vector<std::vector<std::uint64_t>> at(parts, std::vector<std::uint64_t>(nb));
    out.begin.assign(nb + 1, 0);
    out.box.assign(nb, {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY});
    std::uint64_t total = 0;
    for (std::size_t k = 0; k < nb; ++k) {
        out.begin[k] = total;
        for (unsigned part = 0; part < parts; ++part) {
            at[part][k] = total;
            total += count[part][k];
            for (int a = 0; a < 3; ++a)
                out.box[k][a] = std::min(out.box[k][a], box[part][k][a]),
                out.box[k][3 + a] = std::max(out.box[k][3 + a], box[part][k][3 + a]);
        }
    }
    out.begin[nb] = total;
    for (int z = 0; z < out.dim[2]; ++z)
        for (int y = 0; y < out.dim[1]; ++y)
            for (int x = 0; x < out.dim[0]; ++x) {
                const std::size_t k = (std::size_t(z) * out.dim[1] + y) * out.dim[0] + x;
                if (out.begin[k] == out.begin[k + 1]) continue;
                const int c[3] = {x, y, z};
                for (int a = 0; a < 3; ++a) {
                    out.box[k][a] = std::min(out.box[k][a], float(std::max(b.min[a], b.min[a] + c[a] * edge)));
                    out.box[k][3 + a] = std::max(out.box[k][3 + a], float(std::min(b.max[a], b.min[a] + (c[a] + 1) * edge)));
                }
            }
    count.clear(), box.clear();
    out.pieces.resize(total);
    // Pass 2: the pieces, in place.
    parallel_ranges(parts, 1, [&](std::uint64_t p0, std::uint64_t p1) {
        for (std::uint64_t part = p0; part < p1; ++part) {
            std::vector<std::uint64_t> &a = at[part];
            const std::uint64_t s0 = N * part / parts, s1 = N * (part + 1) / parts;
            for (std::uint64_t s = s0; s < s1; ++s) {
                if ((s & 4095) == 0 && cancel.load(std::memory_order_relaxed)) return stopped.store(true);
                grid.cut(t, s, [&](std::uint32_t k, std::uint64_t first, std::uint64_t cnt, bool) {
                    for (std::uint64_t j = 0; j + 1 < cnt; j += BrickPiece::kMaxPoints - 1)
                        out.pieces[a[k]++] = BrickPiece(s, std::uint32_t(first + j),
                                                        std::uint32_t(std::min<std::uint64_t>(cnt - j, BrickPiece::kMaxPoints)));
                });
            }
        }
    });
    if (stopped) return Bricks{};
    return out;
}

FibreVolume fibre_volume(const LineData &d, const Bounds &b, int grid, double budget_points, unsigned threads,
                         const std::atomic<bool> &cancel) {
    FibreVolume v;
    const Tractogram &t = *d.t;
    const std::uint64_t N = t.nb_streamlines();
    if (N == 0 || b.empty) return v;
    double extent = 0;
    for (int i = 0; i < 3; ++i) extent = std::max(extent, b.max[i] - b.min[i]);
    const double vox = std::max(extent, 1e-3) / std::max(grid, 4);
    // One empty voxel around the data: a ray's linear samples fade to zero
    // inside the grid, and the skip distances have an outside to start from.
    for (int i = 0; i < 3; ++i) {
        v.dim[i] = int((b.max[i] - b.min[i]) / vox) + 3;
        v.origin[i] = float(b.min[i] - vox);
    }
    v.voxel_mm = float(vox);
    const std::size_t nvox = std::size_t(v.dim[0]) * v.dim[1] * v.dim[2];
    // Above the budget every `every`-th segment of every streamline (from an
    // offset its hash picks), weighted `every`: all streamlines stand in
    // every voxel (a subsample of whole streamlines leaves the colours
    // noisier for the same work).
    const std::uint64_t every =
        std::max<std::uint64_t>(1, std::uint64_t(std::ceil(double(t.nb_vertices()) / std::max(1.0, budget_points))));
    const float weight = float(every);
    const float *P = t.positions.data();
    const std::size_t stride = per_vertex_stride(d);
    const float inv = float(1.0 / vox);
    auto voxel_of = [&](float x, float y, float z) -> std::size_t {
        const float f[3] = {(x - v.origin[0]) * inv, (y - v.origin[1]) * inv, (z - v.origin[2]) * inv};
        int c[3];
        for (int i = 0; i < 3; ++i) {
            if (!(f[i] >= 0 && f[i] < v.dim[i])) return SIZE_MAX;
            c[i] = int(f[i]);
        }
        return (std::size_t(c[2]) * v.dim[1] + c[1]) * v.dim[0] + c[0];
    };
    const std::array<std::uint8_t, 4097> &lut = direction_table();
    // Per voxel: length, length x colour (3), length x t t^T (6).
    constexpr int kAcc = 10;
    const unsigned parts = std::max(1u, std::min<unsigned>(threads, unsigned(std::min<std::uint64_t>(N, 64))));
    std::vector<std::vector<float>> acc(parts);
    parallel_ranges(parts, 1, [&](std::uint64_t p0, std::uint64_t p1) {
        for (std::uint64_t part = p0; part < p1; ++part) {
            std::vector<float> &a = acc[part];
            a.assign(nvox * kAcc, 0.0f);
            const std::uint64_t s0 = N * part / parts, s1 = N * (part + 1) / parts;
            for (std::uint64_t s = s0; s < s1; ++s) {
                if ((s & 4095) == 0 && cancel.load(std::memory_order_relaxed)) return;
                const std::uint64_t sb = t.begin(s), e = t.end(s);
                if (e - sb < 2) continue;
                const StreamlineColour sc = streamline_colour(d, s);
                const bool plain_direction = d.mode == LineData::Mode::Direction && !(sc.highlight > 0);
                // The grid is larger than the caches and a streamline wanders
                // through it: consecutive segments in one voxel are summed
                // here first, and the voxel a few segments ahead is
                // prefetched (its sums are read and written next).
                constexpr std::uint64_t kAhead = 8;
                std::size_t cur = SIZE_MAX;
                float sum[kAcc] = {};
                auto flush = [&] {
                    if (cur >= nvox) return;
                    float *o = a.data() + cur * kAcc;
                    for (int c = 0; c < kAcc; ++c) o[c] += sum[c], sum[c] = 0.0f;
                };
                // The voxels of the next kAhead segments taken, each found
                // once: when it is prefetched.
                auto voxel_at = [&](std::uint64_t i) {
                    const float *f = P + i * 3;
                    return voxel_of(0.5f * (f[0] + f[3]), 0.5f * (f[1] + f[4]), 0.5f * (f[2] + f[5]));
                };
                std::size_t ahead[kAhead];
                const std::uint64_t first = sb + (every > 1 ? streamline_hash(s) % every : 0);
                for (std::uint64_t j = 0; j < kAhead; ++j) ahead[j] = first + j * every + 1 < e ? voxel_at(first + j * every) : SIZE_MAX;
                for (std::uint64_t i = first, n = 0; i + 1 < e; i += every, ++n) {
                    const std::size_t k = ahead[n % kAhead];
                    if (const std::uint64_t next = i + kAhead * every; next + 1 < e) {
                        const std::size_t ka = voxel_at(next);
                        ahead[n % kAhead] = ka;
                        if (ka < nvox) __builtin_prefetch(a.data() + ka * kAcc, 1), __builtin_prefetch(a.data() + ka * kAcc + kAcc - 1, 1);
                    }
                    const float *p = P + i * 3, *q = p + 3;
                    float tx = q[0] - p[0], ty = q[1] - p[1], tz = q[2] - p[2];
                    const float len = std::sqrt(tx * tx + ty * ty + tz * tz);
                    if (!(len > 0) || !std::isfinite(len)) continue;
                    if (k >= nvox) continue;
                    if (k != cur) flush(), cur = k;
                    tx /= len, ty /= len, tz /= len;
                    // (the direction colouring without a highlight: its table, inline)
                    const std::array<std::uint8_t, 4> col =
                        plain_direction
                            ? std::array<std::uint8_t, 4>{direction_lut(tx, lut), direction_lut(ty, lut), direction_lut(tz, lut), 255}
                            : point_colour(d, sc, i, stride, tx, ty, tz);
                    const float w = len * weight, wc = w * (1.0f / 255.0f);
                    sum[0] += w;
                    sum[1] += wc * col[0], sum[2] += wc * col[1], sum[3] += wc * col[2];
                    sum[4] += w * tx * tx, sum[5] += w * ty * ty, sum[6] += w * tz * tz;
                    sum[7] += w * tx * ty, sum[8] += w * tx * tz, sum[9] += w * ty * tz;
                }
                flush();
            }
        }
    });
    if (cancel) return v;
    for (unsigned part = 1; part < parts; ++part) {
        for (std::size_t k = 0; k < nvox * kAcc; ++k) acc[0][k] += acc[part][k];
        std::vector<float>().swap(acc[part]);
    }
    const std::vector<float> &a = acc[0];
    v.colour_density.assign(nvox * 4, 0.0f);
    v.direction.assign(nvox * 4, 0);
    v.skip.assign(nvox, 0);
    const double inv_volume = 1.0 / (vox * vox * vox);
    std::vector<std::uint32_t> queue;
    for (std::size_t k = 0; k < nvox; ++k) {
        const float *o = a.data() + k * kAcc;
        std::uint8_t *ts = v.direction.data() + k * 4;
        if (!(o[0] > 0)) {
            ts[0] = ts[1] = ts[2] = 128, ts[3] = 0;
            v.skip[k] = 255;
            continue;
        }
        const float density = float(o[0] * inv_volume);
        for (int c = 0; c < 3; ++c) v.colour_density[k * 4 + c] = o[1 + c] / o[0] * density;
        v.colour_density[k * 4 + 3] = density;
        // The main direction: power iteration on the mean of t t^T, from
        // the axis it is largest along.
        const double m[3][3] = {{o[4], o[7], o[8]}, {o[7], o[5], o[9]}, {o[8], o[9], o[6]}};
        const int big = o[4] >= o[5] && o[4] >= o[6] ? 0 : o[5] >= o[6] ? 1 : 2;
        double e[3] = {0, 0, 0};
        e[big] = 1;
        for (int it = 0; it < 12; ++it) {
            double f[3];
            for (int r = 0; r < 3; ++r) f[r] = m[r][0] * e[0] + m[r][1] * e[1] + m[r][2] * e[2];
            const double n = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
            if (!(n > 0)) break;
            for (int r = 0; r < 3; ++r) e[r] = f[r] / n;
        }
        // One sign for neighbours along a bundle (its largest component
        // positive): the GPU filters directions between voxels.
        const int top = std::abs(e[0]) >= std::abs(e[1]) && std::abs(e[0]) >= std::abs(e[2]) ? 0 : std::abs(e[1]) >= std::abs(e[2]) ? 1 : 2;
        if (e[top] < 0) e[0] = -e[0], e[1] = -e[1], e[2] = -e[2];
        for (int c = 0; c < 3; ++c) ts[c] = std::uint8_t(std::lround(std::clamp(e[c], -1.0, 1.0) * 127.5 + 127.5));
        double lambda = 0;  // e^T M e / trace M
        for (int r = 0; r < 3; ++r) lambda += e[r] * (m[r][0] * e[0] + m[r][1] * e[1] + m[r][2] * e[2]);
        lambda /= std::max(1e-30, m[0][0] + m[1][1] + m[2][2]);
        ts[3] = std::uint8_t(std::lround(std::clamp((lambda - 1.0 / 3.0) * 1.5, 0.0, 1.0) * 255.0));
        v.skip[k] = 0;
        queue.push_back(std::uint32_t(k));
    }
    std::vector<float>().swap(acc[0]);
    // Chebyshev distances to the voxels with streamlines.
    chebyshev_steps(v.dim, v.skip, std::move(queue));
    return v;
}

}  // namespace hz::core::render
