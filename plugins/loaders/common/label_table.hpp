// A label table (FreeSurfer annotation colour table, GIFTI LabelTable) as
// header entries, the form every loader that reads or writes labels shares:
//
//   key   "label <index>"            e.g. "label 3"
//   value "<name> <r> <g> <b> <t>"   e.g. "cuneus 220 180 140 0"
//         "<name> - - - -"           a label without a colour (a GIFTI Label
//                                    with no Red/Green/Blue/Alpha, as nibabel
//                                    writes one it was given no colour for)
//
// r, g, b are 0..255 sRGB, t is FreeSurfer's transparency (255 - alpha).
// The name may contain spaces: the last four fields are the numbers.
// A label without a colour is drawn, and written to formats that need one
// (FreeSurfer annotations), in a colour generated from its index (hues
// spaced by the golden ratio, opaque), unless another label of the table
// has that colour (assign_colours()).
// Header-only, no SDK types.
#pragma once

#include <algorithm>
#include <cmath>
#include <array>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace hzlabel {

// The colour a label without one is given: hue (index x golden ratio) mod 1
// at saturation 0.6 and value 0.9, 0..255 sRGB.
inline std::array<std::int32_t, 3> generated_rgb(std::int32_t index) {
    double h = std::fmod(static_cast<double>(index) * 0.618033988749895, 1.0);
    if (h < 0) h += 1.0;
    const double v = 0.9, s = 0.6, c = v * s, h6 = h * 6.0, x = c * (1.0 - std::fabs(std::fmod(h6, 2.0) - 1.0)), m = v - c;
    double r = 0, g = 0, b = 0;
    switch (static_cast<int>(h6)) {
    case 0: r = c, g = x; break;
    case 1: r = x, g = c; break;
    case 2: g = c, b = x; break;
    case 3: g = x, b = c; break;
    case 4: r = x, b = c; break;
    default: r = c, b = x; break;
    }
    auto q = [&](double u) { return static_cast<std::int32_t>(std::lround((u + m) * 255.0)); };
    return {q(r), q(g), q(b)};
}

struct Entry {
    std::int32_t index = 0;
    std::string name;
    std::int32_t r = 0, g = 0, b = 0, t = 0;
    bool coloured = true;   // false: no colour given (r, g, b, t unused until assign_colours())
    bool assigned = false;  // (not coloured) r, g, b hold the colour assign_colours() chose
    std::array<std::int32_t, 3> rgb() const { return coloured || assigned ? std::array<std::int32_t, 3>{r, g, b} : generated_rgb(index); }
    std::uint8_t alpha() const { return coloured ? static_cast<std::uint8_t>(255 - t) : 255; }
    // FreeSurfer's per-vertex annotation value: r + g*256 + b*65536.
    std::uint32_t packed() const { return pack(rgb()); }
    static std::uint32_t pack(const std::array<std::int32_t, 3> &c) {
        return std::uint32_t(c[0]) + std::uint32_t(c[1]) * 256u + std::uint32_t(c[2]) * 65536u;
    }
};

// Gives every label without a colour one that no other label of the table
// has: its generated colour, or else the generated colour of index + k P
// for the smallest k >= 1 that is free (P a large prime, so the hues probed
// spread over the circle). An annotation identifies labels by colour, so a
// generated colour equal to another label's would merge the two. Labels in
// table order; deterministic. Labels given the same colour by the data are
// left as they are (a FreeSurfer writer rejects them).
inline void assign_colours(std::vector<Entry> &table) {
    std::vector<std::uint32_t> used;
    for (const Entry &e : table)
        if (e.coloured || e.assigned) used.push_back(e.packed());
    std::sort(used.begin(), used.end());
    for (Entry &e : table) {
        if (e.coloured || e.assigned) continue;
        constexpr std::int64_t kStep = 1000003;
        auto taken = [&](const std::array<std::int32_t, 3> &x) { return std::binary_search(used.begin(), used.end(), Entry::pack(x)); };
        std::array<std::int32_t, 3> c = generated_rgb(e.index);
        for (std::int64_t k = 1; taken(c) && k <= 256; ++k)
            c = generated_rgb(static_cast<std::int32_t>((std::int64_t(e.index) + k * kStep) % 2147483647));
        // The generated hues are a few hundred distinct colours: a table with
        // more labels without one than that takes the next free 24-bit
        // colour after the generated one (found within table.size() steps).
        for (std::uint32_t v = Entry::pack(c); taken(c);) {
            v = (v + 1) & 0xFFFFFFu;
            c = {std::int32_t(v & 0xFF), std::int32_t(v >> 8 & 0xFF), std::int32_t(v >> 16)};
        }
        e.r = c[0], e.g = c[1], e.b = c[2];
        e.assigned = true;
        used.insert(std::upper_bound(used.begin(), used.end(), Entry::pack(c)), Entry::pack(c));
    }
}

// The RGBA colour of each label index, for the "<labels> rgba" arrays that
// annotations and label GIFTIs are read with: an index the table does not
// define (and -1, unlabeled) is grey with alpha 0. The first entry wins
// when an index is listed twice.
class Colours {
public:
    explicit Colours(std::vector<Entry> table) {
        assign_colours(table);
        for (const Entry &e : table) {
            const auto c = e.rgb();
            by_index_.push_back({e.index, {std::uint8_t(c[0]), std::uint8_t(c[1]), std::uint8_t(c[2]), e.alpha()}});
        }
        std::stable_sort(by_index_.begin(), by_index_.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
    }
    std::array<std::uint8_t, 4> operator()(std::int32_t index) const {
        const auto it =
            std::lower_bound(by_index_.begin(), by_index_.end(), index, [](const auto &a, std::int32_t k) { return a.first < k; });
        return it != by_index_.end() && it->first == index ? it->second : std::array<std::uint8_t, 4>{128, 128, 128, 0};
    }

private:
    std::vector<std::pair<std::int32_t, std::array<std::uint8_t, 4>>> by_index_;
};

inline std::string key(std::int32_t index) { return "label " + std::to_string(index); }

inline std::string value(const Entry &e) {
    if (!e.coloured) return e.name + " - - - -";
    return e.name + " " + std::to_string(e.r) + " " + std::to_string(e.g) + " " + std::to_string(e.b) + " " + std::to_string(e.t);
}

// Parses one header entry; nullopt when `k` is not "label <int32>" or the
// value does not end in four integers in 0..255 or in four dashes.
inline std::optional<Entry> parse(std::string_view k, std::string_view v) {
    constexpr std::string_view prefix = "label ";
    if (k.substr(0, prefix.size()) != prefix || k.size() == prefix.size() || k.size() > prefix.size() + 11) return std::nullopt;
    const std::string num(k.substr(prefix.size()));
    char *end = nullptr;
    const long long index = std::strtoll(num.c_str(), &end, 10);
    if (*end != '\0' || index < INT32_MIN || index > INT32_MAX) return std::nullopt;
    Entry e;
    e.index = static_cast<std::int32_t>(index);
    constexpr std::string_view dashes = " - - - -";
    if (v.size() >= dashes.size() && v.substr(v.size() - dashes.size()) == dashes) {
        e.coloured = false;
        std::size_t stop = v.size() - dashes.size();
        while (stop > 0 && v[stop - 1] == ' ') --stop;
        e.name = std::string(v.substr(0, stop));
        return e;
    }
    std::int32_t *fields[4] = {&e.t, &e.b, &e.g, &e.r};
    std::size_t stop = v.size();
    for (std::int32_t *f : fields) {
        while (stop > 0 && v[stop - 1] == ' ') --stop;
        std::size_t start = stop;
        while (start > 0 && v[start - 1] >= '0' && v[start - 1] <= '9') --start;
        if (start == stop || stop - start > 3) return std::nullopt;
        const int x = std::atoi(std::string(v.substr(start, stop - start)).c_str());
        if (x > 255) return std::nullopt;
        *f = x;
        stop = start;
    }
    while (stop > 0 && v[stop - 1] == ' ') --stop;
    e.name = std::string(v.substr(0, stop));
    return e;
}

// Collects the label entries among header entries (pairs of key, value).
template <class Pairs>
std::vector<Entry> collect(const Pairs &pairs) {
    std::vector<Entry> out;
    for (const auto &[k, v] : pairs)
        if (auto e = parse(k, v)) out.push_back(std::move(*e));
    return out;
}

}  // namespace hzlabel
