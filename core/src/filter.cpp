#include <hz/core/filter.hpp>
#include <hz/core/io.hpp>

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <mutex>
#include <sstream>
#include <thread>

namespace hz::core {

namespace detail {  // filter_simd.cpp
std::uint64_t first_in_sphere(const float *xyz, std::uint64_t n, float cx, float cy, float cz, float r);
std::uint64_t first_in_box(const float *xyz, std::uint64_t n, const float *lo, const float *hi);
}  // namespace detail

namespace {

// std::round (halves away from zero) without its library call: x minus its
// truncation is exact below 2^23, beyond which every float is an integer.
inline float round_half_away(float x) {
    if (!(std::abs(x) < 0x1p23f)) return x;
    const float t = float(std::int32_t(x)), f = x - t;
    return f >= 0.5f ? t + 1 : f <= -0.5f ? t - 1 : t;
}

// The numbers of "a,b,c": exactly `n` finite ones, or Error naming `spec`.
std::vector<double> numbers(const std::string &text, std::size_t n, const std::string &spec, const char *form) {
    std::vector<double> v;
    std::size_t pos = 0;
    while (pos <= text.size()) {
        const std::size_t comma = std::min(text.find(',', pos), text.size());
        const std::string item = text.substr(pos, comma - pos);
        char *end = nullptr;
        errno = 0;
        const double x = std::strtod(item.c_str(), &end);
        if (item.empty() || end != item.c_str() + item.size() || errno == ERANGE || !std::isfinite(x))
            throw Error("ROI '" + spec + "': '" + item + "' is not a number (expected " + form + ")");
        v.push_back(x);
        pos = comma + 1;
    }
    if (v.size() != n) throw Error("ROI '" + spec + "': " + std::to_string(v.size()) + " numbers, expected " + form);
    return v;
}

// The inverse of a row-major affine (its 3x3 part must be invertible).
Affine affine_inverse(const Affine &a, const std::string &what) {
    const double m00 = a[0], m01 = a[1], m02 = a[2], m10 = a[4], m11 = a[5], m12 = a[6], m20 = a[8], m21 = a[9], m22 = a[10];
    const double c00 = m11 * m22 - m12 * m21, c01 = m02 * m21 - m01 * m22, c02 = m01 * m12 - m02 * m11;
    const double c10 = m12 * m20 - m10 * m22, c11 = m00 * m22 - m02 * m20, c12 = m02 * m10 - m00 * m12;
    const double c20 = m10 * m21 - m11 * m20, c21 = m01 * m20 - m00 * m21, c22 = m00 * m11 - m01 * m10;
    const double det = m00 * c00 + m01 * c10 + m02 * c20;
    if (!std::isfinite(det) || std::abs(det) < 1e-12) throw Error(what + ": the voxel-to-RAS affine is singular");
    const double inv[9] = {c00 / det, c01 / det, c02 / det, c10 / det, c11 / det, c12 / det, c20 / det, c21 / det, c22 / det};
    Affine r = kIdentity;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) r[i * 4 + j] = inv[i * 3 + j];
        r[i * 4 + 3] = -(inv[i * 3] * a[3] + inv[i * 3 + 1] * a[7] + inv[i * 3 + 2] * a[11]);
    }
    return r;
}

std::string fmt(double x) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.9g", x);
    return buf;
}

// Whether a vertex of streamline vertices [b, e) at p lies in r, whose
// bounds are `rb` (a mask's vertices outside them need no lookup).
bool any_in(const Roi &r, const Bounds &rb, const float *p, std::uint64_t b, std::uint64_t e) {
    switch (r.shape) {
    case Roi::Shape::Sphere:
        return detail::first_in_sphere(p + b * 3, e - b, float(r.center[0]), float(r.center[1]), float(r.center[2]), float(r.radius)) <
               e - b;
    case Roi::Shape::Box: {
        const float lo[3] = {float(r.lo[0]), float(r.lo[1]), float(r.lo[2])}, hi[3] = {float(r.hi[0]), float(r.hi[1]), float(r.hi[2])};
        return detail::first_in_box(p + b * 3, e - b, lo, hi) < e - b;
    }
    case Roi::Shape::Mask: {
        const float lo[3] = {float(rb.min[0]), float(rb.min[1]), float(rb.min[2])},
                    hi[3] = {float(rb.max[0]), float(rb.max[1]), float(rb.max[2])};
        for (std::uint64_t v = b; v < e;) {
            v += detail::first_in_box(p + v * 3, e - v, lo, hi);  // (the next vertex within the bounds)
            if (v < e && r.contains(p + v * 3)) return true;
            ++v;
        }
        return false;
    }
    }
    return false;
}

bool boxes_overlap(const std::array<float, 6> &b, const Bounds &r) {
    return !(b[3] < r.min[0] || b[0] > r.max[0] || b[4] < r.min[1] || b[1] > r.max[1] || b[5] < r.min[2] || b[2] > r.max[2]);
}

}  // namespace

bool Roi::contains(const float *p) const {
    switch (shape) {
    case Shape::Sphere: {
        // tckedit: (pos - p).squaredNorm() <= radius^2, in float32.
        const float dx = float(center[0]) - p[0], dy = float(center[1]) - p[1], dz = float(center[2]) - p[2];
        const float r = float(radius);
        return dx * dx + dy * dy + dz * dz <= r * r;
    }
    case Shape::Box:  // (bounds rounded to float32, as the vector loop has them)
        return p[0] >= float(lo[0]) && p[0] <= float(hi[0]) && p[1] >= float(lo[1]) && p[1] <= float(hi[1]) && p[2] >= float(lo[2]) &&
               p[2] <= float(hi[2]);
    case Shape::Mask: {
        // tckedit's arithmetic: the RAS -> voxel affine in float32, each
        // coordinate ((m0 x + m1 y) + m2 z) + t, rounded half away from zero.
        const std::array<float, 12> &m = r2v;
        float v[3];
        for (int i = 0; i < 3; ++i) v[i] = round_half_away((m[i * 4] * p[0] + m[i * 4 + 1] * p[1]) + m[i * 4 + 2] * p[2] + m[i * 4 + 3]);
        if (!(v[0] >= 0 && v[1] >= 0 && v[2] >= 0 && v[0] < float(dims[0]) && v[1] < float(dims[1]) && v[2] < float(dims[2]))) return false;
        return (*mask)[(std::uint64_t(v[2]) * dims[1] + std::uint64_t(v[1])) * dims[0] + std::uint64_t(v[0])] != 0;
    }
    }
    return false;
}

Bounds Roi::bounds() const {
    Bounds b;
    b.empty = false;
    switch (shape) {
    case Shape::Sphere:
        for (int i = 0; i < 3; ++i) b.min[i] = center[i] - radius * 1.0001 - 1e-4, b.max[i] = center[i] + radius * 1.0001 + 1e-4;
        break;
    case Shape::Box: b.min = lo, b.max = hi; break;
    case Shape::Mask: b = mask_bounds; break;
    }
    return b;
}

std::string Roi::spec() const {
    switch (shape) {
    case Shape::Sphere: return "sphere:" + fmt(center[0]) + "," + fmt(center[1]) + "," + fmt(center[2]) + "," + fmt(radius);
    case Shape::Box:
        return "box:" + fmt(lo[0]) + "," + fmt(lo[1]) + "," + fmt(lo[2]) + "," + fmt(hi[0]) + "," + fmt(hi[1]) + "," + fmt(hi[2]);
    case Shape::Mask: return file;
    }
    return {};
}

namespace {

// The RAS+ bounds outside which a mask holds no point: the corners of its set
// voxels' index box, each widened by half a voxel (what rounds onto it),
// through voxel -> RAS, padded past the float32 rounding of contains().
Bounds set_voxel_bounds(const Roi &r) {
    std::array<std::uint64_t, 3> a{r.dims[0], r.dims[1], r.dims[2]}, z{0, 0, 0};
    for (std::uint64_t k = 0; k < r.dims[2]; ++k)
        for (std::uint64_t j = 0; j < r.dims[1]; ++j)
            for (std::uint64_t i = 0; i < r.dims[0]; ++i)
                if ((*r.mask)[(k * r.dims[1] + j) * r.dims[0] + i]) {
                    a = {std::min(a[0], i), std::min(a[1], j), std::min(a[2], k)};
                    z = {std::max(z[0], i), std::max(z[1], j), std::max(z[2], k)};
                }
    const Affine inv = affine_inverse(r.ras_to_voxel, r.file);
    Bounds b;
    for (int c = 0; c < 8; ++c) {
        const double v[3] = {(c & 1 ? double(z[0]) + 0.5 : double(a[0]) - 0.5), (c & 2 ? double(z[1]) + 0.5 : double(a[1]) - 0.5),
                             (c & 4 ? double(z[2]) + 0.5 : double(a[2]) - 0.5)};
        for (int i = 0; i < 3; ++i) {
            const double x = inv[i * 4] * v[0] + inv[i * 4 + 1] * v[1] + inv[i * 4 + 2] * v[2] + inv[i * 4 + 3];
            const double pad = 1e-3 * (1 + std::abs(x));
            if (b.empty || x - pad < b.min[i]) b.min[i] = x - pad;
            if (b.empty || x + pad > b.max[i]) b.max[i] = x + pad;
        }
        b.empty = false;
    }
    return b;
}

}  // namespace

Roi mask_roi(const Volume &v, const std::string &file, bool include) {
    if (v.dims.size() < 3 || v.dims[0] == 0 || v.dims[1] == 0 || v.dims[2] == 0) throw Error("ROI mask " + file + ": not a 3D volume");
    Roi r;
    r.shape = Roi::Shape::Mask;
    r.include = include;
    r.file = file;
    r.dims = {v.dims[0], v.dims[1], v.dims[2]};
    r.ras_to_voxel = affine_inverse(v.voxel_to_ras, "ROI mask " + file);
    for (int i = 0; i < 12; ++i) r.r2v[i] = float(r.ras_to_voxel[i]);
    const std::uint64_t n = r.dims[0] * r.dims[1] * r.dims[2];
    const std::size_t es = dtype_size(v.dtype);
    if (es == 0 || v.voxels.size() < n * es) throw Error("ROI mask " + file + ": unsupported voxel type");
    auto bits = std::make_shared<std::vector<std::uint8_t>>(n);
    const double slope = v.scale_slope == 0 ? 1.0 : v.scale_slope;
    std::uint64_t set = 0;
    const std::byte *data = v.voxels.data();
    for (std::uint64_t i = 0; i < n; ++i) {
        const double x = value_at(data + i * es, v.dtype) * slope + v.scale_inter;
        (*bits)[i] = x != 0 && !std::isnan(x);
        set += (*bits)[i];
    }
    if (set == 0) throw Error("ROI mask " + file + ": no voxel is set (the mask is empty)");
    r.mask = std::move(bits);
    r.mask_bounds = set_voxel_bounds(r);
    return r;
}

Roi parse_roi(const Registry &reg, const std::string &spec, bool include) {
    Roi r;
    r.include = include;
    if (spec.rfind("sphere:", 0) == 0) {
        const auto v = numbers(spec.substr(7), 4, spec, "sphere:X,Y,Z,R in mm");
        r.shape = Roi::Shape::Sphere;
        r.center = {v[0], v[1], v[2]};
        r.radius = v[3];
        if (!(r.radius > 0)) throw Error("ROI '" + spec + "': the radius must be > 0");
        return r;
    }
    if (spec.rfind("box:", 0) == 0) {
        const auto v = numbers(spec.substr(4), 6, spec, "box:X0,Y0,Z0,X1,Y1,Z1 in mm");
        r.shape = Roi::Shape::Box;
        for (int i = 0; i < 3; ++i) {
            r.lo[i] = std::min(v[i], v[i + 3]), r.hi[i] = std::max(v[i], v[i + 3]);
            if (!(r.hi[i] > r.lo[i])) throw Error("ROI '" + spec + "': the box is flat along axis " + "xyz"[i]);
        }
        return r;
    }
    if (spec.empty()) throw Error("ROI '': expected sphere:X,Y,Z,R, box:X0,Y0,Z0,X1,Y1,Z1 or a mask file");
    std::error_code ec;
    if (!fs::exists(spec, ec))
        throw Error("ROI '" + spec + "': no such file (expected sphere:X,Y,Z,R, box:X0,Y0,Z0,X1,Y1,Z1 or a mask volume)");
    const Dataset ds = read_dataset(reg, spec);
    if (ds.kind != HZ_DATA_VOLUME) throw Error("ROI mask " + spec + ": a " + std::string(kind_name(ds.kind)) + " file, not a volume");
    return mask_roi(ds.volume, spec, include);
}

std::string FilterSpec::describe() const {
    std::string s;
    auto add = [&](const std::string &x) { s += (s.empty() ? "" : "; ") + x; };
    for (const Roi &r : rois) add(std::string(r.include ? "include " : "exclude ") + r.spec());
    if (min_length > 0) add("min_length " + fmt(min_length));
    if (max_length < std::numeric_limits<double>::infinity()) add("max_length " + fmt(max_length));
    if (ends_only) add("ends_only");
    if (invert) add("invert");
    return s.empty() ? "all" : s;
}

float streamline_length(const Tractogram &t, std::uint64_t s) {
    const std::uint64_t b = t.begin(s), e = t.end(s);
    if (e <= b) return std::numeric_limits<float>::quiet_NaN();
    const float *p = t.positions.data();
    float len = 0;
    // The segments' lengths 64 at a time (independent: the compiler
    // vectorises them), then summed in order, as tckedit adds them.
    float seg[64];
    for (std::uint64_t v = b + 1; v < e; v += 64) {
        const std::uint64_t m = std::min<std::uint64_t>(64, e - v);
        const float *q = p + v * 3;
        for (std::uint64_t j = 0; j < m; ++j) {
            const float dx = q[j * 3] - q[j * 3 - 3], dy = q[j * 3 + 1] - q[j * 3 - 2], dz = q[j * 3 + 2] - q[j * 3 - 1];
            seg[j] = std::sqrt(dx * dx + dy * dy + dz * dz);
        }
        for (std::uint64_t j = 0; j < m; ++j) len += seg[j];
    }
    return len;
}

StreamlineBoxes StreamlineBoxes::of(const Tractogram &t) {
    StreamlineBoxes out;
    const std::uint64_t n = t.nb_streamlines();
    out.box.resize(n);
    const float *p = t.positions.data();
    parallel_ranges(n, 4096, [&](std::uint64_t from, std::uint64_t to) {
        for (std::uint64_t s = from; s < to; ++s) {
            std::array<float, 6> b{1, 1, 1, 0, 0, 0};
            const std::uint64_t e = t.end(s);
            if (std::uint64_t v = t.begin(s); v < e) {
                b = {p[v * 3], p[v * 3 + 1], p[v * 3 + 2], p[v * 3], p[v * 3 + 1], p[v * 3 + 2]};
                for (++v; v < e; ++v)
                    for (int i = 0; i < 3; ++i) b[i] = std::min(b[i], p[v * 3 + i]), b[i + 3] = std::max(b[i + 3], p[v * 3 + i]);
            }
            out.box[s] = b;
        }
    });
    return out;
}

StreamlineGrid StreamlineGrid::of(const Tractogram &t, double cell_mm, unsigned threads, const std::atomic<bool> *cancel) {
    StreamlineGrid g;
    const std::uint64_t N = t.nb_streamlines();
    if (N >= (std::uint64_t(1) << 32)) throw Error("filter: more than 2^32 streamlines for the spatial index");
    g.nb_streamlines = N;
    g.cell = cell_mm;
    const float *p = t.positions.data();
    g.bounds = t.nb_stored() ? bounds_of(p, t.nb_stored()) : Bounds{};
    if (g.bounds.empty) {
        g.start.assign(2, 0);
        g.n = {1, 1, 1};
        return g;
    }
    // Bounded memory: the entries a sample of streamlines gives at this
    // cell size, scaled to all of them; above the budget (13 entries per
    // streamline, at least 48M and at most 128M: 192-512 MB) the cells
    // grow until the estimate fits.
    {
        const std::uint64_t stride = std::max<std::uint64_t>(1, N / 20000);
        const double budget = std::clamp(13.0 * double(N), 48e6, 128e6);
        const float slo[3] = {float(g.bounds.min[0]), float(g.bounds.min[1]), float(g.bounds.min[2])};
        for (int round = 0; round < 6; ++round) {
            std::uint64_t sampled = 0, entries = 0;
            for (std::uint64_t s = 0; s < N; s += stride, ++sampled) {
                std::int64_t prev[3] = {-1, -1, -1};
                for (std::uint64_t v = t.begin(s); v < t.end(s); ++v) {
                    std::int64_t c[3];
                    for (int i = 0; i < 3; ++i) c[i] = std::int64_t((p[v * 3 + i] - slo[i]) / float(cell_mm));
                    if (c[0] != prev[0] || c[1] != prev[1] || c[2] != prev[2]) ++entries, std::copy(c, c + 3, prev);
                }
            }
            const double estimate = double(entries) * double(N) / double(std::max<std::uint64_t>(sampled, 1));
            if (estimate <= budget) break;
            cell_mm *= std::min(4.0, estimate / budget);
        }
        g.cell = cell_mm;
    }
    for (int i = 0; i < 3; ++i) g.n[i] = std::uint64_t(std::floor((g.bounds.max[i] - g.bounds.min[i]) / cell_mm)) + 1;
    const std::uint64_t cells = g.n[0] * g.n[1] * g.n[2];
    const float lo[3] = {float(g.bounds.min[0]), float(g.bounds.min[1]), float(g.bounds.min[2])};
    const float inv = float(1.0 / cell_mm);
    const std::uint64_t nx = g.n[0], ny = g.n[1], nz = g.n[2];
    auto cell_of = [&](const float *q) {
        const auto c = [&](int i, std::uint64_t m) {
            return std::min<std::uint64_t>(m - 1, std::uint64_t(std::max(0.0f, (q[i] - lo[i]) * inv)));
        };
        return (c(2, nz) * ny + c(1, ny)) * nx + c(0, nx);
    };
    // A counting sort on every core: parts of streamlines count their
    // entries per cell, then write them where the counts put them.
    const std::uint64_t hw = threads ? threads : std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
    const std::uint64_t grain = std::max<std::uint64_t>(1024, (N + hw - 1) / hw);
    const std::uint64_t parts = (N + grain - 1) / grain;
    std::vector<std::vector<std::uint64_t>> count(parts, std::vector<std::uint64_t>(cells, 0));
    std::atomic<bool> stop{false};
    auto walk = [&](std::uint64_t from, std::uint64_t to, auto &&emit) {
        for (std::uint64_t s = from; s < to; ++s) {
            if ((s & 4095) == 0 && cancel && cancel->load(std::memory_order_relaxed)) {
                stop = true;
                return;
            }
            std::uint64_t prev = ~std::uint64_t(0);
            for (std::uint64_t v = t.begin(s); v < t.end(s); ++v) {
                const std::uint64_t c = cell_of(p + v * 3);
                if (c != prev) emit(c, s), prev = c;
            }
        }
    };
    // (parallel_ranges makes one part per `grain` streamlines; with one
    // thread asked for, the parts run one after the other here.)
    auto run_parts = [&](const std::function<void(std::uint64_t, std::uint64_t)> &fn) {
        if (threads == 1)
            for (std::uint64_t from = 0; from < N; from += grain) fn(from, std::min(N, from + grain));
        else
            parallel_ranges(N, grain, fn);
    };
    run_parts([&](std::uint64_t from, std::uint64_t to) {
        std::vector<std::uint64_t> &mine = count[from / grain];
        walk(from, to, [&](std::uint64_t c, std::uint64_t) { ++mine[c]; });
    });
    if (stop) return StreamlineGrid{};
    g.start.assign(cells + 1, 0);
    std::uint64_t total = 0;
    for (std::uint64_t c = 0; c < cells; ++c) {
        g.start[c] = total;
        for (std::uint64_t k = 0; k < parts; ++k) {
            const std::uint64_t n = count[k][c];
            count[k][c] = total;  // (now: where part k writes in cell c)
            total += n;
        }
    }
    g.start[cells] = total;
    g.ids.resize(total);
    run_parts([&](std::uint64_t from, std::uint64_t to) {
        std::vector<std::uint64_t> &at = count[from / grain];
        walk(from, to, [&](std::uint64_t c, std::uint64_t s) { g.ids[at[c]++] = std::uint32_t(s); });
    });
    if (stop) return StreamlineGrid{};
    spdlog::debug("streamline grid: {} streamlines, {:.1f} mm cells ({} x {} x {}), {} entries ({:.0f} MB)", N, g.cell, g.n[0], g.n[1],
                  g.n[2], g.ids.size(), double(g.ids.size()) * 4 / 1048576.0);
    return g;
}

void StreamlineGrid::mark(const Bounds &r, std::vector<std::uint64_t> &bits) const {
    if (bounds.empty || r.empty) return;
    std::uint64_t a[3], z[3];
    for (int i = 0; i < 3; ++i) {
        // (Widened past the float32 rounding of the vertices' cells.)
        const double pad_lo = 1e-3 * (1 + std::abs(r.min[i])), pad_hi = 1e-3 * (1 + std::abs(r.max[i]));
        if (r.max[i] + pad_hi < bounds.min[i] || r.min[i] - pad_lo > bounds.max[i]) return;
        const double lo = std::max(0.0, std::floor((r.min[i] - pad_lo - bounds.min[i]) / cell));
        const double hi = std::floor((r.max[i] + pad_hi - bounds.min[i]) / cell);
        a[i] = std::min<std::uint64_t>(n[i] - 1, std::uint64_t(lo));
        z[i] = std::min<std::uint64_t>(n[i] - 1, std::uint64_t(std::max(0.0, hi)));
    }
    for (std::uint64_t k = a[2]; k <= z[2]; ++k)
        for (std::uint64_t j = a[1]; j <= z[1]; ++j)
            for (std::uint64_t i = a[0]; i <= z[0]; ++i) {
                const std::uint64_t c = (k * n[1] + j) * n[0] + i;
                for (std::uint64_t e = start[c]; e < start[c + 1]; ++e) bits[ids[e] >> 6] |= std::uint64_t(1) << (ids[e] & 63);
            }
}

std::vector<std::uint64_t> filter_streamlines(const Tractogram &t, const FilterSpec &f, const StreamlineBoxes *boxes,
                                              const std::vector<std::uint64_t> *subset, const StreamlineGrid *grid) {
    const std::uint64_t n = subset ? subset->size() : t.nb_streamlines();
    std::vector<const Roi *> inc, exc;
    std::vector<Bounds> inc_b, exc_b;
    for (const Roi &r : f.rois) {
        (r.include ? inc : exc).push_back(&r);
        (r.include ? inc_b : exc_b).push_back(r.bounds());
    }
    const bool lengths = f.min_length > 0 || f.max_length < std::numeric_limits<double>::infinity();
    const float *p = t.positions.data();
    // Lengths are compared in float32, as tckedit does.
    const float min_len = float(f.min_length), max_len = float(f.max_length);
    // Whether non-empty streamline s meets the criteria (before invert);
    // without `check_exc`, the exclude regions are known to be far from it.
    auto keep_pass = [&](std::uint64_t s, bool check_exc) -> bool {
        const std::uint64_t b = t.begin(s), e = t.end(s);
        bool pass = true;
        const std::array<float, 6> *box = boxes ? &boxes->box[s] : nullptr;
        if (f.ends_only) {
            const float *ends[2] = {p + b * 3, p + (e - 1) * 3};
            for (const Roi *r : inc) pass = pass && (r->contains(ends[0]) || r->contains(ends[1]));
            for (const Roi *r : exc) pass = pass && (!check_exc || (!r->contains(ends[0]) && !r->contains(ends[1])));
        } else {
            // Each region over the whole run (in cache after the first); a
            // streamline whose box misses a region's bounds has no vertex
            // in it.
            for (std::size_t k = 0; pass && k < inc.size(); ++k)
                pass = (box == nullptr || boxes_overlap(*box, inc_b[k])) && any_in(*inc[k], inc_b[k], p, b, e);
            for (std::size_t k = 0; pass && check_exc && k < exc.size(); ++k)
                pass = (box != nullptr && !boxes_overlap(*box, exc_b[k])) || !any_in(*exc[k], exc_b[k], p, b, e);
        }
        // (The length last: most streamlines fail the regions first.)
        if (pass && lengths) {
            const float len = streamline_length(t, s);
            pass = len <= max_len && len >= min_len;
        }
        return pass;
    };
    // (An empty streamline has no length: tckedit drops it even with -inverse.)
    auto keep = [&](std::uint64_t s) { return t.end(s) > t.begin(s) && keep_pass(s, true) != f.invert; };
    if (grid && !subset && grid->nb_streamlines == t.nb_streamlines() && !f.rois.empty()) {
        // Candidates from the grid: a streamline must be listed near every
        // include region (none: every streamline is); one listed near no
        // exclude region needs no vertex test for them.
        const std::uint64_t N = t.nb_streamlines(), words = (N + 63) / 64;
        std::vector<std::uint64_t> cand(words, inc.empty() ? ~std::uint64_t(0) : 0), near_exc(words, 0), one(words);
        for (std::size_t k = 0; k < inc.size(); ++k) {
            std::vector<std::uint64_t> &bits = k == 0 ? cand : one;
            if (k) std::fill(one.begin(), one.end(), 0);
            grid->mark(inc_b[k], bits);
            if (k)
                for (std::uint64_t w = 0; w < words; ++w) cand[w] &= one[w];
        }
        for (std::size_t k = 0; k < exc.size(); ++k) grid->mark(exc_b[k], near_exc);
        std::mutex m;
        std::vector<std::pair<std::uint64_t, std::vector<std::uint64_t>>> parts;
        parallel_ranges(words, 256, [&](std::uint64_t from, std::uint64_t to) {
            std::vector<std::uint64_t> mine;
            for (std::uint64_t w = from; w < to; ++w) {
                std::uint64_t bits = f.invert ? ~std::uint64_t(0) : cand[w];
                if (w == words - 1 && N % 64) bits &= (std::uint64_t(1) << (N % 64)) - 1;
                for (; bits; bits &= bits - 1) {
                    const std::uint64_t s = w * 64 + std::uint64_t(__builtin_ctzll(bits));
                    if (t.end(s) <= t.begin(s)) continue;
                    // (With invert, a streamline no include region is near fails them.)
                    const bool pass = (cand[w] >> (s & 63) & 1) && keep_pass(s, (near_exc[w] >> (s & 63) & 1) != 0);
                    if (pass != f.invert) mine.push_back(s);
                }
            }
            std::lock_guard<std::mutex> lock(m);
            parts.emplace_back(from, std::move(mine));
        });
        std::sort(parts.begin(), parts.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
        std::vector<std::uint64_t> out;
        for (const auto &pp : parts) out.insert(out.end(), pp.second.begin(), pp.second.end());
        return out;
    }
    std::mutex m;
    std::vector<std::pair<std::uint64_t, std::vector<std::uint64_t>>> parts;
    parallel_ranges(n, 2048, [&](std::uint64_t from, std::uint64_t to) {
        std::vector<std::uint64_t> mine;
        for (std::uint64_t i = from; i < to; ++i) {
            const std::uint64_t s = subset ? (*subset)[i] : i;
            if (t.end(s) > t.begin(s) && keep(s)) mine.push_back(s);
        }
        std::lock_guard<std::mutex> lock(m);
        parts.emplace_back(from, std::move(mine));
    });
    std::sort(parts.begin(), parts.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
    std::vector<std::uint64_t> out;
    std::size_t total = 0;
    for (const auto &pp : parts) total += pp.second.size();
    out.reserve(total);
    for (const auto &pp : parts) out.insert(out.end(), pp.second.begin(), pp.second.end());
    return out;
}

std::vector<DataArray> arrays_of_selection(const Tractogram &t, const std::vector<std::uint64_t> &ids, bool gather_vertex_arrays) {
    std::vector<DataArray> out_arrays;
    const std::uint64_t N = t.nb_streamlines();
    std::vector<std::int64_t> renumber;  // old index -> new, -1 when dropped (for groups)
    std::vector<std::string> kept_groups;
    for (const DataArray &a : t.arrays) {
        const std::size_t row = std::size_t(a.components) * dtype_size(a.dtype);
        if (a.attach == HZ_ATTACH_STREAMLINE && a.count == N) {
            DataArray c{a.name, a.attach, a.dtype, a.components, ids.size(), Buffer<std::byte>(ids.size() * row)};
            for (std::size_t i = 0; i < ids.size(); ++i) std::memcpy(c.bytes.data() + i * row, a.bytes.data() + ids[i] * row, row);
            out_arrays.push_back(std::move(c));
        } else if (a.attach == HZ_ATTACH_VERTEX && t.gap == 0 && a.count == t.nb_vertices() && !gather_vertex_arrays) {
            DataArray c{a.name, a.attach, a.dtype, a.components, a.count, a.bytes.shared()};
            out_arrays.push_back(std::move(c));
        } else if (a.attach == HZ_ATTACH_VERTEX && t.gap == 0 && a.count == t.nb_vertices()) {
            std::uint64_t nv = 0;
            for (std::uint64_t s : ids) nv += t.size(s);
            DataArray c{a.name, a.attach, a.dtype, a.components, nv, Buffer<std::byte>(nv * row)};
            std::uint64_t w = 0;
            for (std::uint64_t s : ids) {
                std::memcpy(c.bytes.data() + w * row, a.bytes.data() + t.begin(s) * row, t.size(s) * row);
                w += t.size(s);
            }
            out_arrays.push_back(std::move(c));
        } else if (a.attach == HZ_ATTACH_GROUP && a.components == 1 && (a.dtype == HZ_DTYPE_U32 || a.dtype == HZ_DTYPE_U64)) {
            if (renumber.empty()) {
                renumber.assign(N, -1);
                for (std::size_t i = 0; i < ids.size(); ++i) renumber[ids[i]] = std::int64_t(i);
            }
            std::vector<std::uint32_t> members;
            for (std::uint64_t k = 0; k < a.count; ++k) {
                std::uint64_t s;
                if (a.dtype == HZ_DTYPE_U32) {
                    std::uint32_t x;
                    std::memcpy(&x, a.bytes.data() + k * 4, 4);
                    s = x;
                } else {
                    std::memcpy(&s, a.bytes.data() + k * 8, 8);
                }
                if (s < N && renumber[s] >= 0) members.push_back(std::uint32_t(renumber[s]));
            }
            if (members.empty()) continue;
            DataArray c{a.name, a.attach, HZ_DTYPE_U32, 1, members.size(), Buffer<std::byte>(members.size() * 4)};
            std::memcpy(c.bytes.data(), members.data(), members.size() * 4);
            out_arrays.push_back(std::move(c));
            kept_groups.push_back(a.name);
        }
    }
    for (const DataArray &a : t.arrays)
        if (a.attach == HZ_ATTACH_GROUP_DATA) {
            const std::string group = a.name.substr(0, a.name.find('/'));
            if (std::find(kept_groups.begin(), kept_groups.end(), group) == kept_groups.end()) continue;
            DataArray c{a.name, a.attach, a.dtype, a.components, a.count, Buffer<std::byte>::copy_of(a.bytes.span())};
            out_arrays.push_back(std::move(c));
        }
    return out_arrays;
}

Tractogram subset_with_arrays(const Tractogram &t, const std::vector<std::uint64_t> &ids, bool spill, const std::atomic<bool> *cancel) {
    Tractogram out = select_streamlines(t, ids, spill, cancel);
    if (cancel != nullptr && cancel->load()) return out;
    out.arrays = arrays_of_selection(t, ids, /*gather_vertex_arrays=*/true);
    return out;
}

}  // namespace hz::core
