// The glass model's CPU reference (paper section 2.1, Eq. 14, Figs. 3 and 8):
// exact unpolarised dielectric Fresnel, Beer-Lambert absorption along the
// refracted path through a slab, and a GGX reflection lobe for lights.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace glass {

// Exact unpolarised Fresnel reflectance for a ray arriving at cos_i from a
// medium into one with relative index eta = n_t / n_i; total internal
// reflection gives 1. cos_i is clamped to [0, 1].
inline double fresnel_dielectric(double cos_i, double eta) {
    if (!std::isfinite(cos_i) || !std::isfinite(eta) || eta <= 0) return 1.0;
    const double c = std::clamp(cos_i, 0.0, 1.0);
    const double s2 = (1.0 - c * c) / (eta * eta);
    if (s2 >= 1.0) return 1.0;
    const double ct = std::sqrt(1.0 - s2);
    const double rs = (c - eta * ct) / (c + eta * ct);
    const double rp = (eta * c - ct) / (eta * c + ct);
    return std::clamp(0.5 * (rs * rs + rp * rp), 0.0, 1.0);
}

// Schlick's approximation F0 + (1 - F0)(1 - cos_i)^5.
inline double fresnel_schlick(double f0, double cos_i) {
    const double c = std::clamp(std::isfinite(cos_i) ? cos_i : 0.0, 0.0, 1.0);
    const double m = 1.0 - c, m2 = m * m;
    return std::clamp(f0, 0.0, 1.0) + (1.0 - std::clamp(f0, 0.0, 1.0)) * m2 * m2 * m;
}

// Beer-Lambert transmittance exp(-alpha l c) (paper Eq. 14), every factor
// clamped >= 0.
inline double beer_lambert(double alpha, double length, double concentration) {
    auto nn = [](double x) { return std::isfinite(x) ? std::max(x, 0.0) : 0.0; };
    return std::exp(-nn(alpha) * nn(length) * nn(concentration));
}

// Path length through a slab of thickness d entered at cos_i: d / cos(theta_t).
inline double slab_path_length(double d, double cos_i, double eta) {
    const double c = std::clamp(cos_i, 0.0, 1.0);
    const double s2 = (1.0 - c * c) / (eta * eta);
    const double ct = std::sqrt(std::max(1.0 - s2, 0.0));
    return ct > 1e-3 ? d / ct : d / 1e-3;
}

using V3 = std::array<double, 3>;

// GGX reflection lobe of a smooth dielectric (white), for point and
// directional lights: D G F / (4 n.l n.v), F exact (or Schlick with
// f0 = ((eta - 1) / (eta + 1))^2).
inline V3 reflection_brdf(double ior, double roughness, bool schlick, V3 n, V3 l, V3 v) {
    auto norm = [](V3 &a) {
        double m = std::max({std::abs(a[0]), std::abs(a[1]), std::abs(a[2])});
        if (!(m > 0) || !std::isfinite(m)) return false;
        for (auto &x : a) x /= m;
        const double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        for (auto &x : a) x /= len;
        return true;
    };
    auto dot = [](const V3 &a, const V3 &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
    if (!norm(n) || !norm(l) || !norm(v)) return {0, 0, 0};
    const double NoL = dot(n, l), NoV = dot(n, v);
    if (!(NoL > 0) || !(NoV > 0)) return {0, 0, 0};
    V3 h = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    if (!norm(h)) return {0, 0, 0};
    const double NoH = dot(n, h), VoH = std::clamp(dot(v, h), 0.0, 1.0);
    const double r = std::clamp(std::isfinite(roughness) ? roughness : 0.0, 0.0, 1.0);
    const double a = std::max(0.001, r * r), aa = a * a;
    const V3 nxh = {n[1] * h[2] - n[2] * h[1], n[2] * h[0] - n[0] * h[2], n[0] * h[1] - n[1] * h[0]};
    const double dd = dot(nxh, nxh) + aa * NoH * NoH;
    const double D = aa / (M_PI * dd * dd);
    const double vl = 1.0 / (NoL + std::sqrt(aa * (1.0 - NoL * NoL) + NoL * NoL));
    const double vv = 1.0 / (NoV + std::sqrt(aa * (1.0 - NoV * NoV) + NoV * NoV));
    const double eta = std::clamp(std::isfinite(ior) ? ior : 1.5, 1.0, 3.0);
    const double f0 = ((eta - 1) / (eta + 1)) * ((eta - 1) / (eta + 1));
    const double F = schlick ? fresnel_schlick(f0, VoH) : fresnel_dielectric(VoH, eta);
    const double f = D * vl * vv * F;
    return {f, f, f};
}

}  // namespace glass
