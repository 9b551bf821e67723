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
    // sRGB values of published colormaps, linearly interpolated between:
    // matplotlib's viridis and inferno (van der Walt and Smith, CC0) and
    // Moreland's cool-warm, each at 33 even positions of matplotlib's
    // 256-entry tables (within 1.7/255 of them between; until 2026-11 these
    // were 5-9 stops, the middle of viridis 58/255 off), and its "hot" at
    // the ends of its linear pieces (exact).
    static const std::map<std::string, std::vector<Stop>> m = {
        {"viridis",
         {{0, 0.267004, 0.004874, 0.329415},       {0.03125, 0.276987, 0.050151, 0.375542}, {0.0625, 0.282302, 0.094624, 0.417024},
          {0.09375, 0.282902, 0.135449, 0.453035}, {0.125, 0.278919, 0.174879, 0.482972},   {0.15625, 0.270788, 0.213324, 0.506643},
          {0.1875, 0.259266, 0.250672, 0.524378},  {0.21875, 0.245374, 0.286704, 0.536971}, {0.25, 0.230223, 0.321297, 0.545488},
          {0.28125, 0.214836, 0.354470, 0.551027}, {0.3125, 0.199995, 0.386377, 0.554533},  {0.34375, 0.186132, 0.417256, 0.556682},
          {0.375, 0.173302, 0.447386, 0.557850},   {0.40625, 0.161265, 0.477036, 0.558125}, {0.4375, 0.149668, 0.506440, 0.557329},
          {0.46875, 0.138415, 0.535767, 0.555090}, {0.5, 0.128148, 0.565107, 0.550893},     {0.53125, 0.120875, 0.594465, 0.544158},
          {0.5625, 0.120325, 0.623765, 0.534308},  {0.59375, 0.130961, 0.652859, 0.520817}, {0.625, 0.155378, 0.681539, 0.503240},
          {0.65625, 0.192974, 0.709556, 0.481231}, {0.6875, 0.241467, 0.736626, 0.454543},  {0.71875, 0.298636, 0.762445, 0.423019},
          {0.75, 0.362859, 0.786695, 0.386589},    {0.78125, 0.432985, 0.809056, 0.345271}, {0.8125, 0.508094, 0.829231, 0.299221},
          {0.84375, 0.587266, 0.846982, 0.248871}, {0.875, 0.669358, 0.862217, 0.195444},   {0.90625, 0.752867, 0.875089, 0.142650},
          {0.9375, 0.835913, 0.886110, 0.102462},  {0.96875, 0.916550, 0.896130, 0.100822}, {1, 0.993248, 0.906157, 0.143936}}},
        {"inferno",
         {{0, 0.001462, 0.000466, 0.013866},       {0.03125, 0.013922, 0.011169, 0.071599}, {0.0625, 0.041966, 0.028000, 0.140584},
          {0.09375, 0.081463, 0.043195, 0.214399}, {0.125, 0.128488, 0.047323, 0.289642},   {0.15625, 0.182345, 0.040497, 0.353899},
          {0.1875, 0.237010, 0.036581, 0.395612},  {0.21875, 0.289354, 0.045270, 0.418193}, {0.25, 0.339929, 0.061759, 0.429200},
          {0.28125, 0.389702, 0.080270, 0.433066}, {0.3125, 0.439263, 0.098629, 0.431733},  {0.34375, 0.488879, 0.116421, 0.425894},
          {0.375, 0.538581, 0.133906, 0.415702},   {0.40625, 0.588210, 0.151641, 0.401141}, {0.4375, 0.637450, 0.170368, 0.382220},
          {0.46875, 0.685842, 0.190956, 0.359081}, {0.5, 0.732796, 0.214332, 0.332053},     {0.53125, 0.777617, 0.241383, 0.301650},
          {0.5625, 0.819548, 0.272810, 0.268507},  {0.59375, 0.857837, 0.309010, 0.233294}, {0.625, 0.891827, 0.349998, 0.196523},
          {0.65625, 0.921026, 0.395441, 0.158394}, {0.6875, 0.945122, 0.444778, 0.118766},  {0.71875, 0.963952, 0.497371, 0.077607},
          {0.75, 0.977424, 0.552622, 0.038020},    {0.78125, 0.985454, 0.610025, 0.024506}, {0.8125, 0.987932, 0.669158, 0.059628},
          {0.84375, 0.984742, 0.729624, 0.122151}, {0.875, 0.975924, 0.790939, 0.197307},   {0.90625, 0.962340, 0.852188, 0.286715},
          {0.9375, 0.948615, 0.910906, 0.396250},  {0.96875, 0.951827, 0.960753, 0.524708}, {1, 0.988362, 0.998364, 0.644924}}},
        {"coolwarm",
         {{0, 0.229806, 0.298718, 0.753683},       {0.03125, 0.266238, 0.353091, 0.801450}, {0.0625, 0.303878, 0.406526, 0.844924},
          {0.09375, 0.342818, 0.458741, 0.883671}, {0.125, 0.383029, 0.509393, 0.917313},   {0.15625, 0.424385, 0.558110, 0.945525},
          {0.1875, 0.466680, 0.604511, 0.968042},  {0.21875, 0.509643, 0.648215, 0.984658}, {0.25, 0.552953, 0.688849, 0.995231},
          {0.28125, 0.596252, 0.726053, 0.999680}, {0.3125, 0.639155, 0.759490, 0.997987},  {0.34375, 0.681257, 0.788841, 0.990193},
          {0.375, 0.722145, 0.813816, 0.976403},   {0.40625, 0.761403, 0.834156, 0.956775}, {0.4375, 0.798616, 0.849630, 0.931523},
          {0.46875, 0.833378, 0.860045, 0.900911}, {0.5, 0.865410, 0.864730, 0.865118},     {0.53125, 0.897598, 0.848778, 0.820823},
          {0.5625, 0.923942, 0.827233, 0.774465},  {0.59375, 0.944288, 0.800785, 0.726707}, {0.625, 0.958679, 0.769636, 0.677992},
          {0.65625, 0.967162, 0.734013, 0.628748}, {0.6875, 0.969799, 0.694159, 0.579383},  {0.71875, 0.966667, 0.650326, 0.530280},
          {0.75, 0.957873, 0.602760, 0.481798},    {0.78125, 0.943546, 0.551679, 0.434271}, {0.8125, 0.923846, 0.497245, 0.388000},
          {0.84375, 0.898964, 0.439502, 0.343259}, {0.875, 0.869122, 0.378256, 0.300295},   {0.90625, 0.834573, 0.312809, 0.259325},
          {0.9375, 0.795602, 0.241192, 0.220543},  {0.96875, 0.752521, 0.157027, 0.184125}, {1, 0.705673, 0.015556, 0.150233}}},
        {"gray", {{0.0, 0, 0, 0}, {1.0, 1, 1, 1}}},
        {"hot", {{0.0, 0.0416, 0, 0}, {0.365079, 1, 0, 0}, {0.746032, 1, 1, 0}, {1.0, 1, 1, 1}}},
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
