// Non-PBR and simple reflectance models (CPU references):
// Lambert (1760) f = albedo / pi; classic Blinn-Phong (Blinn 1977), a
// radiance factor with the cosine included; the normalised Blinn-Phong BRDF
// kd/pi + ks (s + 8) / (8 pi) (n.h)^s (Akenine-Moller et al., RTR).
// Illuminated lines (Stalling, Zoeckler, Hege 1997) and Mallo et al. 2005's
// cylinder-averaged diffuse, both from the tangent T alone.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace classic {

using V3 = std::array<double, 3>;
constexpr double kPi = 3.14159265358979323846;

inline double dot(const V3 &a, const V3 &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
// Scale-safe normalisation; false for zero or non-finite vectors.
inline bool normalize(V3 &a) {
    if (!std::isfinite(a[0]) || !std::isfinite(a[1]) || !std::isfinite(a[2])) return false;
    const double m = std::max({std::fabs(a[0]), std::fabs(a[1]), std::fabs(a[2])});
    if (!(m > 0)) return false;
    for (double &x : a) x /= m;
    const double len = std::sqrt(dot(a, a));
    for (double &x : a) x /= len;
    return true;
}
inline double nonneg(double x) { return std::isfinite(x) && x > 0 ? x : 0.0; }

inline V3 lambert(const V3 &albedo, V3 n, V3 l, V3 v) {
    if (!normalize(n) || !normalize(l) || !normalize(v) || !(dot(n, l) > 0) || !(dot(n, v) > 0)) return {0, 0, 0};
    return {nonneg(albedo[0]) / kPi, nonneg(albedo[1]) / kPi, nonneg(albedo[2]) / kPi};
}

// n.h for the Blinn-Phong highlight; 0 when l + v vanishes.
inline double n_dot_h(const V3 &n, const V3 &l, const V3 &v) {
    V3 h{l[0] + v[0], l[1] + v[1], l[2] + v[2]};
    return normalize(h) ? std::max(dot(n, h), 0.0) : 0.0;
}

inline V3 blinn_phong(const V3 &kd, const V3 &ks, const V3 &ka, double s, V3 n, V3 l, V3 v) {
    V3 out{nonneg(ka[0]), nonneg(ka[1]), nonneg(ka[2])};
    if (!normalize(n) || !normalize(l) || !normalize(v)) return out;
    const double NoL = dot(n, l), NoV = dot(n, v);
    const double spec = NoL > 0 && NoV > 0 ? std::pow(n_dot_h(n, l, v), std::max(s, 1.0)) : 0.0;
    for (int i = 0; i < 3; ++i) out[i] += nonneg(kd[i]) * std::max(NoL, 0.0) + nonneg(ks[i]) * spec;
    return out;
}

inline V3 blinn_phong_brdf(const V3 &kd, const V3 &ks, double s, V3 n, V3 l, V3 v) {
    if (!normalize(n) || !normalize(l) || !normalize(v) || !(dot(n, l) > 0) || !(dot(n, v) > 0)) return {0, 0, 0};
    s = std::max(s, 1.0);
    const double spec = (s + 8.0) / (8.0 * kPi) * std::pow(n_dot_h(n, l, v), s);
    return {nonneg(kd[0]) / kPi + nonneg(ks[0]) * spec, nonneg(kd[1]) / kPi + nonneg(ks[1]) * spec,
            nonneg(kd[2]) / kPi + nonneg(ks[2]) * spec};
}

// Stalling et al. 1997: L.N = sqrt(1 - (L.T)^2), V.R = L.N sqrt(1 - (V.T)^2) - (L.T)(V.T).
inline V3 line_stalling(const V3 &kd, const V3 &ks, const V3 &ka, double shininess, double p_diffuse, V3 t, V3 l, V3 v) {
    V3 out{nonneg(ka[0]), nonneg(ka[1]), nonneg(ka[2])};
    if (!normalize(t) || !normalize(l) || !normalize(v)) return out;
    const double LoT = std::clamp(dot(l, t), -1.0, 1.0), VoT = std::clamp(dot(v, t), -1.0, 1.0);
    const double LoN = std::sqrt(std::max(0.0, 1.0 - LoT * LoT));
    const double VoR = LoN * std::sqrt(std::max(0.0, 1.0 - VoT * VoT)) - LoT * VoT;
    const double diff = std::pow(LoN, std::max(p_diffuse, 1e-6));
    const double spec = std::pow(std::max(VoR, 0.0), std::max(shininess, 1.0));
    for (int i = 0; i < 3; ++i) out[i] += nonneg(kd[i]) * diff + nonneg(ks[i]) * spec;
    return out;
}

// Mallo, Peikert, Sigg, Sadlo 2005: the Lambert term averaged over the
// visible half of a thin cylinder around T, weighted by projected width.
inline V3 line_mallo_diffuse(const V3 &kd, V3 t, V3 l, V3 v) {
    if (!normalize(t) || !normalize(l) || !normalize(v)) return {0, 0, 0};
    const double LoT = std::clamp(dot(l, t), -1.0, 1.0), VoT = std::clamp(dot(v, t), -1.0, 1.0);
    const double sinL = std::sqrt(std::max(0.0, 1.0 - LoT * LoT));
    V3 lp{l[0] - LoT * t[0], l[1] - LoT * t[1], l[2] - LoT * t[2]};
    V3 vp{v[0] - VoT * t[0], v[1] - VoT * t[1], v[2] - VoT * t[2]};
    double factor;
    if (!normalize(vp) || std::sqrt(std::max(0.0, 1.0 - VoT * VoT)) < 1e-12) {
        factor = sinL / kPi;  // V along T: every normal of the ring is seen alike
    } else if (!normalize(lp) || sinL < 1e-300) {
        factor = 0;
    } else {
        const double a = std::acos(std::clamp(dot(lp, vp), -1.0, 1.0));
        factor = sinL * (std::sin(a) + (kPi - a) * std::cos(a)) / 4.0;
    }
    factor = std::max(factor, 0.0);
    return {nonneg(kd[0]) * factor, nonneg(kd[1]) * factor, nonneg(kd[2]) * factor};
}

}  // namespace classic
