// Colour and value helpers of the renderer (colour.hpp), and the public
// colour maps and cluster palette (renderer.hpp).
#include "colour.hpp"

#include <hz/core/render/renderer.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

namespace hz::core::render {

double srgb_to_linear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

std::uint32_t pack_snorm_2_10_10_10(float x, float y, float z) {
    auto q = [](float v) {
        v = std::isfinite(v) ? std::clamp(v, -1.0f, 1.0f) : 0.0f;
        return static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(v * 511.0f))) & 0x3FFu;
    };
    return q(x) | (q(y) << 10) | (q(z) << 20);
}

std::array<std::uint8_t, 4> rgba8(double r, double g, double b, double a) {
    auto q = [](double v) { return static_cast<std::uint8_t>(std::lround(std::clamp(std::isfinite(v) ? v : 0.0, 0.0, 1.0) * 255.0)); };
    return {q(r), q(g), q(b), q(a)};
}

// `count` values of type `dtype`, `stride` bytes apart, as doubles.
std::vector<double> values_of(const std::byte *data, hz_dtype dtype, std::uint64_t count, std::size_t stride) {
    std::vector<double> out(count);
    for (std::uint64_t i = 0; i < count; ++i) out[i] = value_at(data + i * stride, dtype);
    return out;
}

// Values of a named array as doubles (any dtype, first component).
std::vector<double> array_values(const DataArray &a) {
    return values_of(a.bytes.data(), a.dtype, a.count, dtype_size(a.dtype) * a.components);
}

std::array<double, 2> finite_range(const std::vector<double> &v) {
    double lo = INFINITY, hi = -INFINITY;
    for (double x : v)
        if (std::isfinite(x)) lo = std::min(lo, x), hi = std::max(hi, x);
    if (!(lo <= hi)) return {0, 1};
    if (lo == hi) hi = lo + 1;
    return {lo, hi};
}

namespace {

struct Stop {
    double t, r, g, b;
};
const std::map<std::string, std::vector<Stop>> &colormap_stops() {
    // sRGB values of published colormaps at a few positions (matplotlib's
    // viridis and inferno, Moreland's cool-warm); linear interpolation between.
    static const std::map<std::string, std::vector<Stop>> m = {
        {"viridis",
         {{0.0, 0.267004, 0.004874, 0.329415},
          {0.125, 0.282623, 0.140926, 0.457517},
          {0.25, 0.253935, 0.265254, 0.529983},
          {0.375, 0.206756, 0.371758, 0.553117},
          {0.5, 0.163625, 0.471133, 0.558148},
          {0.625, 0.127568, 0.566949, 0.550556},
          {0.75, 0.134692, 0.658636, 0.517649},
          {0.875, 0.477504, 0.821444, 0.318195},
          {1.0, 0.993248, 0.906157, 0.143936}}},
        {"inferno",
         {{0.0, 0.001462, 0.000466, 0.013866},
          {0.25, 0.341500, 0.062325, 0.429425},
          {0.5, 0.735683, 0.215906, 0.330245},
          {0.75, 0.978422, 0.557937, 0.034931},
          {1.0, 0.988362, 0.998364, 0.644924}}},
        {"coolwarm", {{0.0, 0.2298, 0.2987, 0.7537}, {0.5, 0.8654, 0.8654, 0.8654}, {1.0, 0.7057, 0.0156, 0.1502}}},
        {"gray", {{0.0, 0, 0, 0}, {1.0, 1, 1, 1}}},
        {"hot", {{0.0, 0, 0, 0}, {1.0 / 3, 1, 0, 0}, {2.0 / 3, 1, 1, 0}, {1.0, 1, 1, 1}}},
    };
    return m;
}

}  // namespace

std::array<double, 3> cluster_palette(double id) {
    // Golden-ratio steps around the hue circle: neighbours in id order are far apart.
    const double hue = std::fmod(id * 0.618033988749895, 1.0);
    const double h6 = hue * 6, x = 1 - std::abs(std::fmod(h6, 2.0) - 1);
    double r = 0, g = 0, b = 0;
    switch (int(h6)) {
    case 0: r = 1, g = x; break;
    case 1: r = x, g = 1; break;
    case 2: g = 1, b = x; break;
    case 3: g = x, b = 1; break;
    case 4: r = x, b = 1; break;
    default: r = 1, b = x; break;
    }
    return {0.25 + 0.7 * r, 0.25 + 0.7 * g, 0.25 + 0.7 * b};
}

std::array<float, 3> colormap(const std::string &name, double t) {
    const auto &all = colormap_stops();
    auto it = all.find(name);
    const auto &stops = it == all.end() ? all.at("viridis") : it->second;
    t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0;
    for (std::size_t i = 1; i < stops.size(); ++i)
        if (t <= stops[i].t) {
            const Stop &a = stops[i - 1], &b = stops[i];
            const double u = (t - a.t) / (b.t - a.t);
            return {float(a.r + u * (b.r - a.r)), float(a.g + u * (b.g - a.g)), float(a.b + u * (b.b - a.b))};
        }
    return {float(stops.back().r), float(stops.back().g), float(stops.back().b)};
}

}  // namespace hz::core::render
