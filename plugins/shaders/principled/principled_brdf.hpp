// The principled BRDF of the paper (Burley 2012, "Physically-Based Shading at
// Disney", BRDF Explorer semantics) under the canonical contract of
// ../shared/brdf/README.md: guards that keep it finite and non-negative over
// the whole input domain. CPU reference in double precision; the GLSL in
// principled_plugin.cpp is the same function.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace principled {

using V3 = std::array<double, 3>;

struct Params {
    V3 base_color{0.8, 0.8, 0.8};  // linear RGB
    double subsurface = 0, metallic = 0, specular = 0.5, specular_tint = 0, roughness = 0.5, anisotropic = 0, sheen = 0, sheen_tint = 0.5,
           clearcoat = 0, clearcoat_gloss = 1;
    // Cheaper or costlier variants of single terms (0 = the paper's model),
    // for the speed-accuracy chart: diffuse 1 = Lambert instead of Burley;
    // fresnel 1 = exact dielectric Fresnel (eta from F0) instead of Schlick;
    // visibility 1 = height-correlated Smith instead of separable.
    int diffuse = 0, fresnel = 0, visibility = 0;
};

namespace detail {
constexpr double kPi = 3.14159265358979323846;
inline double dot(const V3 &a, const V3 &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline V3 sub(const V3 &a, const V3 &b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline V3 scale(const V3 &a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
inline V3 cross(const V3 &a, const V3 &b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
inline bool finite3(const V3 &a) { return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]); }
// Scale-safe normalisation: divide by the largest component before squaring.
inline bool normalize(V3 &a) {
    if (!finite3(a)) return false;
    const double m = std::max({std::fabs(a[0]), std::fabs(a[1]), std::fabs(a[2])});
    if (!(m > 0)) return false;
    a = scale(a, 1.0 / m);
    const double len = std::sqrt(dot(a, a));
    a = scale(a, 1.0 / len);
    return true;
}
inline double clamp01(double x) { return std::isfinite(x) ? std::clamp(x, 0.0, 1.0) : 0.0; }
inline double mix(double a, double b, double t) { return a * (1 - t) + b * t; }
// Schlick weight (1 - u)^5 with u clamped to [0, 1].
inline double schlick(double u) {
    const double m = std::clamp(1.0 - u, 0.0, 1.0);
    const double m2 = m * m;
    return m2 * m2 * m;
}
}  // namespace detail

// Tangent frame of the contract: X' = X orthogonalised against N; if X is
// (nearly) parallel to N, Y's; if both are degenerate, Duff et al. 2017's
// branchless basis. Y' = N x X'.
inline void frame(const V3 &n, const V3 &x, const V3 &y, V3 &tx, V3 &ty) {
    using namespace detail;
    auto perp = [&](const V3 &v, V3 &out) {
        if (!finite3(v)) return false;
        const double m = std::max({std::fabs(v[0]), std::fabs(v[1]), std::fabs(v[2])});
        if (!(m > 0)) return false;
        const V3 s = scale(v, 1.0 / m);
        const V3 p = sub(s, scale(n, dot(s, n)));
        if (!(std::sqrt(dot(p, p)) > 1e-6 * std::sqrt(dot(s, s)))) return false;
        out = p;
        return normalize(out);
    };
    V3 p;
    if (perp(x, p)) {
        tx = p;
    } else if (perp(y, p)) {
        tx = cross(p, n);
        normalize(tx);
    } else {  // Duff, Burgess, Christensen, Hery, Kensler, Liani, Villemin 2017
        const double sign = std::copysign(1.0, n[2]);
        const double a = -1.0 / (sign + n[2]);
        const double b = n[0] * n[1] * a;
        tx = {1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]};
    }
    ty = cross(n, tx);
}

// f_r in sr^-1 (cosine not included); 0 below either horizon or for
// degenerate directions. Parameters are clamped to [0, 1].
inline V3 eval(const Params &in, V3 n, V3 l, V3 v, const V3 &x_hint, const V3 &y_hint) {
    using namespace detail;
    const V3 zero{0, 0, 0};
    if (!normalize(n) || !normalize(l) || !normalize(v)) return zero;
    const double NoL = dot(n, l), NoV = dot(n, v);
    if (!(NoL > 0) || !(NoV > 0)) return zero;
    Params p = in;
    for (double *q : {&p.subsurface, &p.metallic, &p.specular, &p.specular_tint, &p.roughness, &p.anisotropic, &p.sheen, &p.sheen_tint,
                      &p.clearcoat, &p.clearcoat_gloss})
        *q = clamp01(*q);
    V3 C;
    for (int i = 0; i < 3; ++i) C[i] = clamp01(in.base_color[i]);

    V3 h = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    if (!normalize(h)) return zero;  // l = -v is only reachable at the horizon
    const double NoH = dot(n, h), LoH = dot(l, h);
    V3 X, Y;
    frame(n, x_hint, y_hint, X, Y);

    const double FL = schlick(NoL), FV = schlick(NoV), FH = schlick(LoH);
    const double lum = 0.3 * C[0] + 0.6 * C[1] + 0.1 * C[2];
    const V3 Ctint = lum > 0 ? scale(C, 1.0 / lum) : V3{1, 1, 1};

    // Burley 2012 diffuse, with its Hanrahan-Krueger-inspired subsurface lobe.
    const double Fd90 = 0.5 + 2.0 * p.roughness * LoH * LoH;
    const double Fd = in.diffuse == 1 ? 1.0 : mix(1.0, Fd90, FL) * mix(1.0, Fd90, FV);
    const double Fss90 = p.roughness * LoH * LoH;
    const double Fss = mix(1.0, Fss90, FL) * mix(1.0, Fss90, FV);
    const double ss = 1.25 * (Fss * (1.0 / std::max(NoL + NoV, 1e-30) - 0.5) + 0.5);

    // Anisotropic GGX (Walter et al. 2007; Burley 2012's aspect mapping).
    const double aspect = std::sqrt(1.0 - 0.9 * p.anisotropic);
    const double r2 = p.roughness * p.roughness;
    const double ax = std::max(0.001, r2 / aspect), ay = std::max(0.001, r2 * aspect);
    const double HoX = dot(h, X), HoY = dot(h, Y);
    const double dden = (HoX / ax) * (HoX / ax) + (HoY / ay) * (HoY / ay) + NoH * NoH;
    const double Ds = 1.0 / (kPi * ax * ay * dden * dden);
    // Separable Smith GGX visibility, G1(w) / (2 n.w).
    auto vis = [&](const V3 &w, double NoW) {
        const double wx = dot(w, X) * ax, wy = dot(w, Y) * ay;
        return 1.0 / (NoW + std::sqrt(wx * wx + wy * wy + NoW * NoW));
    };
    double Gs = vis(l, NoL) * vis(v, NoV);
    if (in.visibility == 1) {  // height-correlated Smith (Heitz 2014): G2 / (4 n.l n.v)
        auto root = [&](const V3 &w, double NoW) {
            const double wx = dot(w, X) * ax, wy = dot(w, Y) * ay;
            return std::sqrt(wx * wx + wy * wy + NoW * NoW);
        };
        Gs = 0.5 / (NoL * root(v, NoV) + NoV * root(l, NoL));
    }

    // Clearcoat: GTR1 (Burley 2012), Smith G with alpha 0.25, F0 = 0.04.
    const double ac = std::max(0.001, mix(0.1, 0.001, p.clearcoat_gloss));
    const double a2 = ac * ac;
    const V3 nxh = cross(n, h);
    const double sin2 = dot(nxh, nxh);
    const double t = a2 - 1.0;
    const double ratio = t == 0 ? 1.0 : t / std::log1p(t);  // (a^2 - 1) / ln(a^2), stable near a = 1
    const double Dr = ratio / (kPi * (sin2 + a2 * NoH * NoH));
    auto visg = [](double c, double a) { return 1.0 / (c + std::sqrt(a * a + c * c - a * a * c * c)); };
    const double Gr = visg(NoL, 0.25) * visg(NoV, 0.25);
    const double Fr = mix(0.04, 1.0, FH);

    V3 f;
    for (int i = 0; i < 3; ++i) {
        const double Cspec0 = mix(0.08 * p.specular * mix(1.0, Ctint[i], p.specular_tint), C[i], p.metallic);
        double Fs = mix(Cspec0, 1.0, FH);
        if (in.fresnel == 1) {  // exact unpolarised dielectric Fresnel with the index F0 implies
            const double r0 = std::sqrt(std::clamp(Cspec0, 0.0, 0.999));
            const double eta = (1 + r0) / (1 - r0), c = std::clamp(LoH, 0.0, 1.0);
            const double s2 = (1 - c * c) / (eta * eta), ct = std::sqrt(std::max(0.0, 1 - s2));
            const double rs = (c - eta * ct) / (c + eta * ct), rp = (eta * c - ct) / (eta * c + ct);
            Fs = s2 >= 1 ? 1.0 : 0.5 * (rs * rs + rp * rp);
        }
        const double Csheen = mix(1.0, Ctint[i], p.sheen_tint);
        const double diffuse = (1.0 / kPi) * mix(Fd, ss, p.subsurface) * C[i] + FH * p.sheen * Csheen;
        f[i] = diffuse * (1.0 - p.metallic) + Ds * Gs * Fs + 0.25 * p.clearcoat * Dr * Fr * Gr;
    }
    return f;
}

}  // namespace principled
