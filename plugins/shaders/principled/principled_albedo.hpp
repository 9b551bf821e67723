// Directional albedo E(v) = integral over the hemisphere of f_r(l, v) n.l dl
// of the principled BRDF (the CPU reference in principled_brdf.hpp), by
// deterministic quadrature: stratified samples from three densities (cosine,
// the anisotropic GGX normal distribution, the clearcoat GTR1 distribution)
// combined with the balance heuristic, i.e. samples of their equal mixture.
// Each density's samples are the cell centres of an S x S grid in its own
// warped coordinates, so the sharp lobes of roughness 0 are integrated where
// they are, not searched for.
#pragma once

#include "principled_brdf.hpp"

namespace principled {

inline V3 albedo(const Params &p, V3 n, V3 v, const V3 &x_hint, const V3 &y_hint, int S = 512) {
    using namespace detail;
    if (!normalize(n) || !normalize(v) || !(dot(n, v) > 0)) return {0, 0, 0};
    V3 X, Y;
    frame(n, x_hint, y_hint, X, Y);
    const double r = clamp01(p.roughness), an = clamp01(p.anisotropic);
    const double aspect = std::sqrt(1.0 - 0.9 * an);
    const double ax = std::max(0.001, r * r / aspect), ay = std::max(0.001, r * r * aspect);
    const double ac = std::max(0.001, mix(0.1, 0.001, clamp01(p.clearcoat_gloss))), ac2 = ac * ac;
    auto world = [&](double a, double b, double c) {
        return V3{a * X[0] + b * Y[0] + c * n[0], a * X[1] + b * Y[1] + c * n[1], a * X[2] + b * Y[2] + c * n[2]};
    };
    auto reflect = [&](const V3 &h) {
        const double d = 2 * dot(v, h);
        return V3{d * h[0] - v[0], d * h[1] - v[1], d * h[2] - v[2]};
    };
    // Densities of l under each strategy.
    auto pdf_cos = [&](const V3 &l) { return std::max(dot(n, l), 0.0) / M_PI; };
    auto half = [&](const V3 &l, V3 &h) {
        h = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
        return normalize(h);
    };
    auto pdf_ggx = [&](const V3 &l) {
        V3 h;
        if (!half(l, h)) return 0.0;
        const double hx = dot(h, X), hy = dot(h, Y), hn = dot(h, n);
        if (hn <= 0) return 0.0;
        const double d = (hx / ax) * (hx / ax) + (hy / ay) * (hy / ay) + hn * hn;
        const double D = 1.0 / (M_PI * ax * ay * d * d);
        return D * hn / (4.0 * std::abs(dot(v, h)));
    };
    auto pdf_gtr1 = [&](const V3 &l) {
        V3 h;
        if (!half(l, h)) return 0.0;
        const double hn = dot(h, n);
        if (hn <= 0) return 0.0;
        const V3 c = cross(n, h);
        const double t = ac2 - 1.0;
        const double ratio = std::abs(t) < 1e-12 ? 1.0 : t / std::log(ac2);
        const double D = ratio / (M_PI * (dot(c, c) + ac2 * hn * hn));
        return D * hn / (4.0 * std::abs(dot(v, h)));
    };
    V3 sum = {0, 0, 0};
    for (int s = 0; s < 3; ++s)
        for (int i = 0; i < S; ++i)
            for (int j = 0; j < S; ++j) {
                const double u1 = (i + 0.5) / S, u2 = (j + 0.5) / S;
                const double phi = 2 * M_PI * u2;
                V3 l;
                if (s == 0) {  // cosine
                    const double rr = std::sqrt(u1);
                    l = world(rr * std::cos(phi), rr * std::sin(phi), std::sqrt(std::max(0.0, 1 - u1)));
                } else if (s == 1) {  // GGX slopes: D(h) n.h
                    const double q = std::sqrt(u1 / (1 - u1));
                    V3 h = world(-ax * q * std::cos(phi), -ay * q * std::sin(phi), 1.0);
                    normalize(h);
                    l = reflect(h);
                } else {  // GTR1: D(h) n.h
                    const double ct = std::sqrt(std::max(0.0, (1 - std::pow(ac2, 1 - u1)) / (1 - ac2)));
                    const double st = std::sqrt(std::max(0.0, 1 - ct * ct));
                    V3 h = world(st * std::cos(phi), st * std::sin(phi), ct);
                    l = reflect(h);
                }
                const double nl = dot(n, l);
                if (!(nl > 0)) continue;
                const double pm = pdf_cos(l) + pdf_ggx(l) + pdf_gtr1(l);
                if (!(pm > 0)) continue;
                const V3 f = eval(p, n, l, v, x_hint, y_hint);
                for (int k = 0; k < 3; ++k) sum[k] += f[k] * nl / pm;
            }
    const double norm = 1.0 / (double(S) * S);
    return {sum[0] * norm, sum[1] * norm, sum[2] * norm};
}

}  // namespace principled
