// Label volumes: lookup tables, the slices' texture, surface nets.
#include <hz/core/io.hpp>
#include <hz/core/render/labels.hpp>

#include "label_table.hpp"  // (plugins/loaders/common: the generated colours)

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <span>
#include <sstream>

namespace hz::core::render {

namespace {

constexpr std::uint64_t kMaxTableBytes = 16ull << 20;
constexpr std::size_t kMaxLabels = 65536;
constexpr double kMaxLabel = 16777216.0;                // 2^24: exact in the texture's float
constexpr std::uint64_t kMaxTriangles = 40'000'000ull;  // about 1.4 GB of mesh: beyond it the labels are noise

bool whole(const std::string &s, double &out) {
    char *end = nullptr;
    out = std::strtod(s.c_str(), &end);
    return !s.empty() && end == s.c_str() + s.size() && std::isfinite(out) && out == std::floor(out);
}

}  // namespace

LabelTable parse_label_table(std::string_view text, const std::string &what) {
    LabelTable t;
    std::istringstream in{std::string(text)};
    std::string line;
    for (std::size_t number = 1; std::getline(in, line); ++number) {
        if (const std::size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
        std::istringstream fields(line);
        std::vector<std::string> f;
        for (std::string w; fields >> w;) f.push_back(w);
        if (f.empty()) continue;
        const std::string at = what + ": line " + std::to_string(number) + ": ";
        if (f.size() < 5 || f.size() > 6)
            throw Error(at + "expected INDEX NAME R G B [A], not " + std::to_string(f.size()) + (f.size() == 1 ? " field" : " fields"));
        double index = 0;
        if (!whole(f[0], index) || std::abs(index) >= kMaxLabel)
            throw Error(at + "the index '" + f[0] + "' is not a whole number below 2^24");
        LabelEntry e;
        e.name = f[1];
        for (std::size_t k = 0; k < 3; ++k) {
            double c = 0;
            if (!whole(f[2 + k], c) || c < 0 || c > 255) throw Error(at + "R G B must be whole numbers in 0..255, not '" + f[2 + k] + "'");
            e.rgb[k] = std::uint8_t(c);
        }
        double a = 0;
        if (f.size() == 6 && (!whole(f[5], a) || a < 0 || a > 255)) throw Error(at + "A must be a whole number in 0..255");
        if (!t.emplace(std::int64_t(index), std::move(e)).second) throw Error(at + "label " + f[0] + " is listed twice");
        if (t.size() > kMaxLabels) throw Error(what + ": more than " + std::to_string(kMaxLabels) + " labels");
    }
    if (t.empty()) throw Error(what + ": no label (lines of INDEX NAME R G B A)");
    return t;
}

LabelTable read_label_table(const std::filesystem::path &path) {
    const std::string what = path.string();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) throw Error(what + ": no such file");
    const std::uint64_t size = std::filesystem::file_size(path, ec);
    if (ec) throw Error(what + ": cannot read: " + ec.message());
    if (size > kMaxTableBytes) throw Error(what + ": larger than 16 MiB: not a colour lookup table");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(what + ": cannot open");
    std::string text(size, '\0');
    in.read(text.data(), std::streamsize(size));
    if (std::size_t(in.gcount()) != size) throw Error(what + ": read error");
    if (text.find('\0') != std::string::npos) throw Error(what + ": binary data: not a colour lookup table");
    return parse_label_table(text, what);
}

std::array<std::uint8_t, 3> label_colour(const LabelTable &table, std::int64_t label) {
    if (auto it = table.find(label); it != table.end()) return it->second.rgb;
    // (the colour the loaders give a GIFTI or FreeSurfer label without one)
    const auto c = hzlabel::generated_rgb(std::int32_t(label));
    return {std::uint8_t(c[0]), std::uint8_t(c[1]), std::uint8_t(c[2])};
}

std::string label_name(const LabelTable &table, std::int64_t label) {
    if (auto it = table.find(label); it != table.end()) return it->second.name;
    return std::to_string(label);
}

bool LabelField::shown(std::int64_t label) const {
    if (label == 0) return false;
    return options.only.empty() || std::find(options.only.begin(), options.only.end(), label) != options.only.end();
}

LabelField make_label_field(const Volume &v, const LabelOptions &opt, const std::string &what) {
    std::size_t dims = v.dims.size();
    while (dims > 3 && v.dims[dims - 1] == 1) --dims;
    if (dims != 3) throw Error(what + ": a label volume is 3D, not " + std::to_string(v.dims.size()) + " dimensions");
    const std::size_t es = dtype_size(v.dtype);
    const std::uint64_t X = v.dims[0], Y = v.dims[1], Z = v.dims[2], n = X * Y * Z;
    if (es == 0 || v.dtype == HZ_DTYPE_RGB8 || v.dtype == HZ_DTYPE_RGBA8 || v.voxels.size() < n * es)
        throw Error(what + ": a label volume holds numbers, one a voxel");
    if (!(opt.fill >= 0 && opt.fill <= 1)) throw Error(what + ": fill is an opacity in 0..1");
    if (opt.smoothing < 0 || opt.smoothing > 100) throw Error(what + ": smoothing is 0 to 100 iterations");
    if (!opt.outline && opt.fill == 0 && !opt.surfaces) throw Error(what + ": no outline, no fill and no surfaces: nothing to draw");
    LabelField f;
    f.dims = {X, Y, Z};
    f.voxel_to_ras = v.voxel_to_ras;
    f.options = opt;
    f.labels.resize(n);
    const double slope = v.scale_slope == 0 ? 1.0 : v.scale_slope;
    for (std::uint64_t k = 0; k < n; ++k) {
        const double l = value_at(v.voxels.data() + k * es, v.dtype) * slope + v.scale_inter;
        if (!(std::abs(l) < kMaxLabel) || l != std::floor(l))
            throw Error(what + ": voxel (" + std::to_string(k % X) + ", " + std::to_string(k / X % Y) + ", " + std::to_string(k / X / Y) +
                        ") holds " + std::to_string(l) + ": not a label (a whole number below 2^24)");
        f.labels[k] = std::int32_t(l);
    }
    std::vector<std::int32_t> sorted(f.labels);
    std::sort(sorted.begin(), sorted.end());
    sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
    if (sorted.size() > kMaxLabels)
        throw Error(what + ": " + std::to_string(sorted.size()) + " distinct values: more than " + std::to_string(kMaxLabels) +
                    " labels (not a label volume?)");
    f.present.assign(sorted.begin(), sorted.end());
    for (std::int64_t l : opt.only)
        if (!std::binary_search(f.present.begin(), f.present.end(), l))
            throw Error(what + ": label " + std::to_string(l) + " (" + label_name(opt.table, l) + ") is not in the volume");
    return f;
}

std::vector<float> label_texture(const LabelField &f) {
    const std::size_t n = f.labels.size();
    std::vector<float> out(n * 4, 0.0f);
    std::map<std::int32_t, std::array<float, 4>> cache;
    for (std::int64_t l : f.present)
        if (f.shown(l)) {
            const auto c = label_colour(f.options.table, l);
            cache[std::int32_t(l)] = {c[0] / 255.0f, c[1] / 255.0f, c[2] / 255.0f, float(l)};
        }
    std::int32_t last = 0;
    const std::array<float, 4> none{0, 0, 0, 0};
    const std::array<float, 4> *colour = &none;
    for (std::size_t i = 0; i < n; ++i) {
        const std::int32_t l = f.labels[i];
        if (l != last) {
            auto it = cache.find(l);
            colour = it == cache.end() ? &none : &it->second;
            last = l;
        }
        if (l == 0) colour = &none;
        std::memcpy(&out[i * 4], colour->data(), 16);
    }
    return out;
}

namespace {

struct Box {
    std::array<std::int64_t, 3> lo{INT64_MAX, INT64_MAX, INT64_MAX}, hi{INT64_MIN, INT64_MIN, INT64_MIN};
};

// One label's surface net, appended to (xyz, faces) in voxel coordinates.
void surface_net(const LabelField &f, std::int32_t label, const Box &b, int smoothing, std::vector<float> &xyz,
                 std::vector<std::uint32_t> &faces, std::uint64_t &triangles) {
    const std::int64_t X = std::int64_t(f.dims[0]), Y = std::int64_t(f.dims[1]), Z = std::int64_t(f.dims[2]);
    auto inside = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
        return i >= 0 && j >= 0 && k >= 0 && i < X && j < Y && k < Z && f.labels[std::size_t((k * Y + j) * X + i)] == label;
    };
    // Cells: min corner c in [lo - 1, hi] on each axis.
    const std::array<std::int64_t, 3> o{b.lo[0] - 1, b.lo[1] - 1, b.lo[2] - 1};
    const std::array<std::int64_t, 3> n{b.hi[0] - b.lo[0] + 2, b.hi[1] - b.lo[1] + 2, b.hi[2] - b.lo[2] + 2};
    std::vector<std::int32_t> cell_vertex(std::size_t(n[0] * n[1] * n[2]), -1);
    auto cell_at = [&](std::int64_t i, std::int64_t j, std::int64_t k) -> std::int32_t & {
        return cell_vertex[std::size_t(((k - o[2]) * n[1] + (j - o[1])) * n[0] + (i - o[0]))];
    };
    std::vector<std::array<double, 3>> pos, cell_min;
    static constexpr int kEdges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3}, {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    for (std::int64_t k = o[2]; k < o[2] + n[2]; ++k)
        for (std::int64_t j = o[1]; j < o[1] + n[1]; ++j)
            for (std::int64_t i = o[0]; i < o[0] + n[0]; ++i) {
                bool in[8];
                int count = 0;
                for (int c = 0; c < 8; ++c) count += (in[c] = inside(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1)));
                if (count == 0 || count == 8) continue;
                std::array<double, 3> p{0, 0, 0};
                int crossings = 0;
                for (const auto &e : kEdges)
                    if (in[e[0]] != in[e[1]]) {
                        for (int a = 0; a < 3; ++a) p[std::size_t(a)] += 0.5 * (((e[0] >> a) & 1) + ((e[1] >> a) & 1));
                        ++crossings;
                    }
                for (int a = 0; a < 3; ++a) p[std::size_t(a)] /= crossings;
                cell_at(i, j, k) = std::int32_t(pos.size());
                pos.push_back({double(i) + p[0], double(j) + p[1], double(k) + p[2]});
                cell_min.push_back({double(i), double(j), double(k)});
            }
    // Quads across each voxel edge (p, p + e_a) of which one end is inside.
    std::vector<std::array<std::int32_t, 4>> quads;
    for (std::int64_t k = o[2]; k < o[2] + n[2]; ++k)
        for (std::int64_t j = o[1]; j < o[1] + n[1]; ++j)
            for (std::int64_t i = o[0]; i < o[0] + n[0]; ++i) {
                const std::array<std::int64_t, 3> p{i, j, k};
                const bool here = inside(i, j, k);
                for (int a = 0; a < 3; ++a) {
                    std::array<std::int64_t, 3> q = p;
                    ++q[std::size_t(a)];
                    if (here == inside(q[0], q[1], q[2])) continue;
                    const int bb = (a + 1) % 3, cc = (a + 2) % 3;
                    if (p[std::size_t(bb)] <= o[std::size_t(bb)] || p[std::size_t(cc)] <= o[std::size_t(cc)])
                        continue;  // (never: both ends outside)
                    std::array<std::int64_t, 3> c1 = p, c2 = p, c3 = p;
                    --c1[std::size_t(bb)];
                    --c2[std::size_t(bb)], --c2[std::size_t(cc)];
                    --c3[std::size_t(cc)];
                    // (c0, c1, c2, c3) turn counter-clockwise about +a: the
                    // outward normal is +a where p is the inside end.
                    std::array<std::int32_t, 4> quad{cell_at(p[0], p[1], p[2]), cell_at(c1[0], c1[1], c1[2]), cell_at(c2[0], c2[1], c2[2]),
                                                     cell_at(c3[0], c3[1], c3[2])};
                    if (!here) std::swap(quad[1], quad[3]);
                    quads.push_back(quad);
                }
            }
    triangles += 2 * quads.size();
    if (triangles > kMaxTriangles)
        throw Error("label surfaces: more than " + std::to_string(kMaxTriangles / 1000000) +
                    " million triangles: the volume's labels are too fragmented to mesh (show it as slices)");
    // Constrained smoothing: each vertex to its neighbours' mean, within its cell.
    if (smoothing > 0 && !pos.empty()) {
        std::vector<std::vector<std::int32_t>> next(pos.size());
        for (const auto &q : quads)
            for (int e = 0; e < 4; ++e) {
                const std::int32_t u = q[std::size_t(e)], w = q[std::size_t((e + 1) % 4)];
                next[std::size_t(u)].push_back(w), next[std::size_t(w)].push_back(u);
            }
        for (auto &l : next) {
            std::sort(l.begin(), l.end());
            l.erase(std::unique(l.begin(), l.end()), l.end());
        }
        // Taubin's two steps a pass (shrink by lambda, inflate by mu): a
        // sphere keeps its volume, where plain averaging shrinks it (-12 % for
        // a radius of 8 voxels after 10 passes).
        std::vector<std::array<double, 3>> moved(pos.size());
        for (int it = 0; it < 2 * smoothing; ++it) {
            const double step = it % 2 == 0 ? 0.5 : -0.53;
            for (std::size_t v = 0; v < pos.size(); ++v) {
                std::array<double, 3> m{0, 0, 0};
                for (std::int32_t w : next[v])
                    for (int a = 0; a < 3; ++a) m[std::size_t(a)] += pos[std::size_t(w)][std::size_t(a)];
                for (int a = 0; a < 3; ++a) {
                    const double lo = cell_min[v][std::size_t(a)], p = pos[v][std::size_t(a)];
                    moved[v][std::size_t(a)] =
                        next[v].empty() ? p : std::clamp(p + step * (m[std::size_t(a)] / double(next[v].size()) - p), lo, lo + 1.0);
                }
            }
            pos.swap(moved);
        }
    }
    const auto base = std::uint32_t(xyz.size() / 3);
    for (const auto &p : pos)
        for (int a = 0; a < 3; ++a) xyz.push_back(float(p[std::size_t(a)]));
    auto dist2 = [&](std::int32_t u, std::int32_t w) {
        double s = 0;
        for (int a = 0; a < 3; ++a) s += std::pow(pos[std::size_t(u)][std::size_t(a)] - pos[std::size_t(w)][std::size_t(a)], 2);
        return s;
    };
    for (const auto &q : quads) {
        // Split along the shorter diagonal (keeps the triangles' winding).
        const std::uint32_t v[4] = {base + std::uint32_t(q[0]), base + std::uint32_t(q[1]), base + std::uint32_t(q[2]),
                                    base + std::uint32_t(q[3])};
        if (dist2(q[0], q[2]) <= dist2(q[1], q[3]))
            faces.insert(faces.end(), {v[0], v[1], v[2], v[0], v[2], v[3]});
        else
            faces.insert(faces.end(), {v[0], v[1], v[3], v[1], v[2], v[3]});
    }
}

}  // namespace

Mesh mask_surface(const Volume &v, double above, int smoothing, const std::string &what) {
    if (v.dims.size() < 3) throw Error(what + ": a surface is made from a 3D volume");
    const std::size_t es = dtype_size(v.dtype);
    const std::uint64_t X = v.dims[0], Y = v.dims[1], Z = v.dims[2], n = X * Y * Z;
    if (es == 0 || v.dtype == HZ_DTYPE_RGB8 || v.dtype == HZ_DTYPE_RGBA8 || v.voxels.size() < n * es)
        throw Error(what + ": a surface is made from a volume of numbers, one a voxel");
    if (smoothing < 0 || smoothing > 100) throw Error(what + ": smoothing is 0 to 100 iterations");
    LabelField f;
    f.dims = {X, Y, Z};
    f.voxel_to_ras = v.voxel_to_ras;
    f.options.surfaces = true;
    f.options.smoothing = smoothing;
    f.labels.resize(n);
    const double slope = v.scale_slope == 0 ? 1.0 : v.scale_slope;
    bool any = false;
    for (std::uint64_t k = 0; k < n; ++k) {
        f.labels[k] = value_at(v.voxels.data() + k * es, v.dtype) * slope + v.scale_inter > above ? 1 : 0;
        any = any || f.labels[k];
    }
    if (!any) throw Error(what + ": no voxel above " + std::to_string(above) + ": no surface");
    f.present = {0, 1};
    return label_surfaces(f);
}

Mesh label_surfaces(const LabelField &f) {
    const std::uint64_t X = f.dims[0], Y = f.dims[1];
    std::map<std::int32_t, Box> boxes;
    for (std::int64_t l : f.present)
        if (f.shown(l)) boxes[std::int32_t(l)];
    for (std::size_t i = 0; i < f.labels.size(); ++i) {
        auto it = boxes.find(f.labels[i]);
        if (it == boxes.end()) continue;
        const std::array<std::int64_t, 3> p{std::int64_t(i % X), std::int64_t(i / X % Y), std::int64_t(i / X / Y)};
        for (std::size_t a = 0; a < 3; ++a)
            it->second.lo[a] = std::min(it->second.lo[a], p[a]), it->second.hi[a] = std::max(it->second.hi[a], p[a]);
    }
    std::vector<float> xyz;
    std::vector<std::uint32_t> faces;
    std::vector<float> label_of;
    std::vector<std::uint8_t> rgb;
    std::uint64_t triangles = 0;
    for (const auto &[label, box] : boxes) {
        const std::size_t before = xyz.size() / 3;
        surface_net(f, label, box, f.options.smoothing, xyz, faces, triangles);
        const std::size_t added = xyz.size() / 3 - before;
        const auto c = label_colour(f.options.table, label);
        label_of.insert(label_of.end(), added, float(label));
        for (std::size_t k = 0; k < added; ++k) rgb.insert(rgb.end(), c.begin(), c.end());
    }
    // Voxel -> RAS+ mm; a mirroring affine turns the winding back.
    const auto &A = f.voxel_to_ras;
    const double det = A[0] * (A[5] * A[10] - A[6] * A[9]) - A[1] * (A[4] * A[10] - A[6] * A[8]) + A[2] * (A[4] * A[9] - A[5] * A[8]);
    for (std::size_t v = 0; v < xyz.size(); v += 3) {
        const double i = xyz[v], j = xyz[v + 1], k = xyz[v + 2];
        for (int r = 0; r < 3; ++r) xyz[v + std::size_t(r)] = float(A[4 * r] * i + A[4 * r + 1] * j + A[4 * r + 2] * k + A[4 * r + 3]);
    }
    if (det < 0)
        for (std::size_t t = 0; t < faces.size(); t += 3) std::swap(faces[t + 1], faces[t + 2]);
    Mesh m;
    m.vertices = Buffer<float>::copy_of(xyz);
    m.faces = Buffer<std::uint32_t>::copy_of(faces);
    m.arrays.push_back(f32_array("label", HZ_ATTACH_VERTEX, label_of));
    DataArray colours;
    colours.name = "rgb";
    colours.dtype = HZ_DTYPE_U8;
    colours.components = 3;
    colours.count = rgb.size() / 3;
    colours.bytes = Buffer<std::byte>::copy_of(std::as_bytes(std::span<const std::uint8_t>(rgb)));
    m.arrays.push_back(std::move(colours));
    return m;
}

}  // namespace hz::core::render
