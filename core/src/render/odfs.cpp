// ODF glyphs (odfs.hpp).
#include <hz/core/render/odfs.hpp>
#include <hz/core/render/peaks.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <numbers>
#include <utility>

namespace hz::core::render {

namespace {

// The associated Legendre function P_n^m(x), m >= 0, with the
// Condon-Shortley phase (-1)^m (as scipy.special.lpmv and sph_harm): the
// standard recurrence in n from P_m^m.
double legendre(int n, int m, double x) {
    const double s = std::sqrt(std::max(0.0, (1 - x) * (1 + x)));
    double pmm = 1;
    for (int i = 1; i <= m; ++i) pmm *= -(2.0 * i - 1) * s;
    if (n == m) return pmm;
    double p1 = x * (2.0 * m + 1) * pmm;  // P_{m+1}^m
    if (n == m + 1) return p1;
    double p0 = pmm;
    for (int l = m + 2; l <= n; ++l) {
        const double p = ((2.0 * l - 1) * x * p1 - (l + m - 1.0) * p0) / (l - m);
        p0 = p1, p1 = p;
    }
    return p1;
}

// K_n^m = sqrt((2n + 1) / (4 pi) (n - m)! / (n + m)!), m >= 0.
double norm(int n, int m) {
    double r = 1;
    for (int k = n - m + 1; k <= n + m; ++k) r /= k;
    return std::sqrt((2.0 * n + 1) / (4 * std::numbers::pi) * r);
}

}  // namespace

double real_sh(const std::string &basis, bool legacy, int n, int m, double theta, double phi) {
    const int M = std::abs(m);
    // Y_n^M = K P_n^M(cos theta) e^{i M phi}: its real and imaginary parts.
    const double kp = norm(n, M) * legendre(n, M, std::cos(theta));
    const double re = kp * std::cos(M * phi), im = kp * std::sin(M * phi);
    const double root2 = std::numbers::sqrt2;
    if (basis == "descoteaux07") {
        if (m == 0) return re;
        if (m > 0) return root2 * im;
        // m < 0: Re(Y_n^m), where Y_n^{-M} = (-1)^M conj(Y_n^M); DIPY's legacy form takes Y_n^M.
        return root2 * (legacy || M % 2 == 0 ? re : -re);
    }
    if (basis == "tournier07") {
        const double v = m == 0 ? re : m < 0 ? im : re;
        return legacy || m == 0 ? v : root2 * v;
    }
    throw Error("SH basis '" + basis + "' is neither descoteaux07 nor tournier07");
}

SphereMesh icosphere(int subdivisions) {
    if (subdivisions < 0 || subdivisions > 7) throw Error("sphere subdivisions " + std::to_string(subdivisions) + " outside 0 to 7");
    const double t = (1 + std::sqrt(5.0)) / 2;
    std::vector<double> v = {-1, t,  0,  1, t, 0,  -1, -t, 0,  1, -t, 0, 0,  -1, t,  0,  1, t,
                             0,  -1, -t, 0, 1, -t, t,  0,  -1, t, 0,  1, -t, 0,  -1, -t, 0, 1};
    std::vector<std::uint32_t> f = {0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4,  11, 10, 2,  10, 7, 6, 7, 1, 8,
                                    3, 9,  4, 3, 4, 2, 3, 2, 6, 3, 6, 8,  3, 8,  9,  4, 9, 5, 2, 4,  11, 6,  2,  10, 8,  6, 7, 9, 8, 1};
    const auto unit = [&](std::size_t i) {
        const double n = std::sqrt(v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
        for (int k = 0; k < 3; ++k) v[3 * i + std::size_t(k)] /= n;
    };
    for (std::size_t i = 0; i < 12; ++i) unit(i);
    for (int s = 0; s < subdivisions; ++s) {
        std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
        const auto middle = [&](std::uint32_t a, std::uint32_t b) {
            const auto key = std::minmax(a, b);
            if (auto it = mid.find(key); it != mid.end()) return it->second;
            const std::uint32_t i = std::uint32_t(v.size() / 3);
            for (int k = 0; k < 3; ++k) v.push_back((v[3 * a + std::uint32_t(k)] + v[3 * b + std::uint32_t(k)]) / 2);
            unit(i);
            mid.emplace(key, i);
            return i;
        };
        std::vector<std::uint32_t> g;
        g.reserve(f.size() * 4);
        for (std::size_t k = 0; k < f.size(); k += 3) {
            const std::uint32_t a = f[k], b = f[k + 1], c = f[k + 2];
            const std::uint32_t ab = middle(a, b), bc = middle(b, c), ca = middle(c, a);
            g.insert(g.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
        }
        f = std::move(g);
    }
    SphereMesh out;
    out.vertices = std::move(v);
    out.faces = std::move(f);
    return out;
}

std::vector<double> sh_matrix(const std::vector<double> &xyz, int order, const std::string &basis, bool legacy) {
    const std::uint64_t C = sh_coefficients(order), V = xyz.size() / 3;
    std::vector<double> B(V * C);
    for (std::uint64_t i = 0; i < V; ++i) {
        const double x = xyz[3 * i], y = xyz[3 * i + 1], z = xyz[3 * i + 2];
        const double r = std::sqrt(x * x + y * y + z * z);
        const double theta = r > 0 ? std::acos(std::clamp(z / r, -1.0, 1.0)) : 0, phi = std::atan2(y, x);
        std::uint64_t j = 0;
        for (int n = 0; n <= order; n += 2)
            for (int m = -n; m <= n; ++m) B[i * C + j++] = real_sh(basis, legacy, n, m, theta, phi);
    }
    return B;
}

OdfField make_odf_field(const Volume &v, const OdfOptions &o, const std::string &what) {
    if (o.basis != "descoteaux07" && o.basis != "tournier07")
        throw Error(what + ": SH basis '" + o.basis + "' is neither descoteaux07 nor tournier07 (MRtrix3's: tournier07, not legacy)");
    if (o.sphere < 0 || o.sphere > 5) throw Error(what + ": glyph sphere subdivisions must be 0 to 5");
    if (!(o.scale > 0 && o.scale <= 100)) throw Error(what + ": ODF scale " + std::to_string(o.scale) + " is outside (0, 100]");
    if (o.normalise != "minmax" && o.normalise != "max" && o.normalise != "none")
        throw Error(what + ": ODF normalisation '" + o.normalise + "' is none of minmax, max, none");
    GlyphVolume g = glyph_volume(v, what, "ODFs need SH coefficients");
    int order = -1;
    for (int L = 0; L <= 16; L += 2)
        if (sh_coefficients(L) == g.volume.dims[3]) order = L;
    if (order < 0)
        throw Error(what + ": " + std::to_string(g.volume.dims[3]) +
                    " values a voxel: not the coefficients of an even-order SH series (1, 6, 15, 28, 45, 66, 91, ... up to order 16)");
    OdfField f;
    f.volume = std::move(g.volume);
    f.voxel_mm = g.voxel_mm;
    f.options = o;
    f.order = order;
    return f;
}

namespace {
// Voxel `vox`'s SH series (scaled) into c (its size: the 4th dimension);
// false for an empty one (all zero, or a value not finite).
bool series_at(const Volume &v, std::uint64_t vox, std::vector<double> &c) {
    const std::uint64_t nvox = v.dims[0] * v.dims[1] * v.dims[2];
    const std::size_t es = dtype_size(v.dtype);
    const double slope = v.scale_slope == 0 ? 1.0 : v.scale_slope;
    bool any = false, finite = true;
    for (std::uint64_t j = 0; j < c.size(); ++j) {
        c[j] = value_at(v.voxels.data() + (vox + nvox * j) * es, v.dtype) * slope + v.scale_inter;
        any = any || c[j] != 0;
        finite = finite && std::isfinite(c[j]);
    }
    return any && finite;
}
}  // namespace

OdfField coarser_odf_field(const OdfField &f) {
    const Volume &v = f.volume;
    const std::uint64_t X = v.dims[0], Y = v.dims[1], Z = v.dims[2], C = v.dims[3];
    const std::uint64_t k[3] = {X > 1 ? 2u : 1u, Y > 1 ? 2u : 1u, Z > 1 ? 2u : 1u};
    const std::uint64_t X2 = (X + k[0] - 1) / k[0], Y2 = (Y + k[1] - 1) / k[1], Z2 = (Z + k[2] - 1) / k[2], n2 = X2 * Y2 * Z2;
    std::vector<double> sum(n2 * C, 0.0), c(C);
    std::vector<std::uint32_t> count(n2, 0);
    for (std::uint64_t z = 0; z < Z; ++z)
        for (std::uint64_t y = 0; y < Y; ++y)
            for (std::uint64_t x = 0; x < X; ++x) {
                if (!series_at(v, x + X * (y + Y * z), c)) continue;
                const std::uint64_t o = x / k[0] + X2 * (y / k[1] + Y2 * (z / k[2]));
                ++count[o];
                for (std::uint64_t j = 0; j < C; ++j) sum[o + n2 * j] += c[j];
            }
    std::vector<float> mean(n2 * C, 0.f);
    for (std::uint64_t o = 0; o < n2; ++o)
        if (count[o])
            for (std::uint64_t j = 0; j < C; ++j) mean[o + n2 * j] = float(sum[o + n2 * j] / count[o]);
    Volume w;
    w.dtype = HZ_DTYPE_F32;
    w.dims = {X2, Y2, Z2, C};
    w.voxels = Buffer<std::byte>::copy_of({reinterpret_cast<const std::byte *>(mean.data()), mean.size() * sizeof(float)});
    // Coarse voxel i is at fine voxel k i + (k - 1) / 2: each column of the
    // affine times k, the origin moved to the first block's centre.
    w.voxel_to_ras = v.voxel_to_ras;
    for (int r = 0; r < 3; ++r)
        for (int a = 0; a < 3; ++a) {
            w.voxel_to_ras[std::size_t(r * 4 + 3)] += v.voxel_to_ras[std::size_t(r * 4 + a)] * double(k[a] - 1) / 2;
            w.voxel_to_ras[std::size_t(r * 4 + a)] = v.voxel_to_ras[std::size_t(r * 4 + a)] * double(k[a]);
        }
    return make_odf_field(w, f.options, "ODFs (coarser)");
}

Mesh odf_glyphs(const OdfField &f, std::optional<double> x, std::optional<double> y, std::optional<double> z, int subdivisions) {
    const Volume &v = f.volume;
    const SphereMesh sphere = icosphere(subdivisions);
    const std::uint64_t V = sphere.nb_vertices(), C = v.dims[3], X = v.dims[0], Y = v.dims[1];
    const std::vector<double> B = sh_matrix(sphere.vertices, f.order, f.options.basis, f.options.legacy);
    const auto &a = v.voxel_to_ras;
    const std::vector<std::uint64_t> shown = slice_voxels(v.dims, a, x, y, z, false);
    // Each shown voxel's values on the sphere, and its radii (before the scale).
    std::vector<std::uint64_t> kept;
    std::vector<float> radii;
    std::vector<double> c(C), sf(V);
    double largest = 0;
    for (const std::uint64_t vox : shown) {
        if (!series_at(v, vox, c)) continue;
        double lo = 1e300, hi = -1e300;
        for (std::uint64_t i = 0; i < V; ++i) {
            double s = 0;
            for (std::uint64_t j = 0; j < C; ++j) s += B[i * C + j] * c[j];
            sf[i] = s, lo = std::min(lo, s), hi = std::max(hi, s);
        }
        const std::string &mode = f.options.normalise;
        if (mode == "minmax" ? !(hi > lo) : !(hi > 0)) continue;
        kept.push_back(vox);
        for (std::uint64_t i = 0; i < V; ++i)
            radii.push_back(float(mode == "minmax" ? (sf[i] - lo) / (hi - lo)
                                  : mode == "max"  ? std::max(sf[i], 0.0) / hi
                                                   : std::max(sf[i], 0.0)));
        if (mode == "none") largest = std::max(largest, hi);
    }
    const double reach = 0.5 * f.voxel_mm * f.options.scale / (f.options.normalise == "none" && largest > 0 ? largest : 1.0);
    std::vector<std::array<double, 3>> centres(kept.size());
    for (std::size_t g = 0; g < kept.size(); ++g) {
        const std::uint64_t vox = kept[g];
        const double ijk[3] = {double(vox % X), double(vox / X % Y), double(vox / X / Y)};
        for (int r = 0; r < 3; ++r)
            centres[g][std::size_t(r)] = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
    }
    return sphere_glyphs(sphere, kept.size(), "direction", [&](std::size_t g, std::uint64_t i, float *xyz, float *rgb) {
        const double rad = reach * radii[g * V + i];
        for (std::size_t k = 0; k < 3; ++k) {
            const double u = sphere.vertices[3 * i + k];
            xyz[k] = float(centres[g][k] + rad * u);
            rgb[k] = float(std::abs(u));
        }
    });
}

Mesh sphere_glyphs(const SphereMesh &sphere, std::size_t count, const std::string &colours,
                   const std::function<void(std::size_t g, std::uint64_t i, float *xyz, float *rgb)> &place) {
    const std::uint64_t V = sphere.nb_vertices(), F = sphere.faces.size();
    Mesh m;
    m.vertices = Buffer<float>(count * V * 3);
    m.faces = Buffer<std::uint32_t>(count * F);
    std::vector<float> colour(colours.empty() ? 3 : count * V * 3);  // (no colours: one scratch colour)
    for (std::size_t g = 0; g < count; ++g) {
        for (std::uint64_t i = 0; i < V; ++i) place(g, i, &m.vertices[(g * V + i) * 3], &colour[colours.empty() ? 0 : (g * V + i) * 3]);
        for (std::size_t k = 0; k < F; ++k) m.faces[g * F + k] = std::uint32_t(g * V + sphere.faces[k]);
    }
    if (colours.empty()) return m;
    DataArray d;
    d.name = colours;
    d.attach = HZ_ATTACH_VERTEX;
    d.dtype = HZ_DTYPE_F32;
    d.components = 3;
    d.count = count * V;
    d.bytes = Buffer<std::byte>(colour.size() * 4);
    if (!colour.empty()) std::memcpy(d.bytes.data(), colour.data(), colour.size() * 4);
    m.arrays.push_back(std::move(d));
    return m;
}

Bounds grown_grid_box(const Volume &grid, double grow) {
    Bounds b = grid_box(grid.dims, grid.voxel_to_ras);
    for (int k = 0; k < 3; ++k) b.min[k] -= grow, b.max[k] += grow;
    return b;
}

Bounds odf_bounds(const OdfField &f) { return grown_grid_box(f.volume, 0.5 * f.voxel_mm * f.options.scale); }

}  // namespace hz::core::render
