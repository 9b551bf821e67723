// Connectomes (connectome.hpp).
#include <hz/core/io.hpp>
#include <hz/core/render/connectome.hpp>
#include <hz/core/render/odfs.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <sstream>

namespace hz::core::render {

namespace {

constexpr std::size_t kMaxNodes = 65536;

// The lines of a text file, each split at whitespace and commas; blank
// lines and `#` comments dropped, with their line numbers.
struct Row {
    std::size_t line;
    std::vector<std::string> fields;
};
std::vector<Row> rows_of(const std::filesystem::path &file, const std::string &what) {
    const std::string text = read_small_file(file, 64u << 20, what);
    std::vector<Row> out;
    std::size_t line = 0, pos = 0;
    while (pos <= text.size()) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string::npos) end = text.size();
        std::string l = text.substr(pos, end - pos);
        ++line;
        pos = end + 1;
        if (const auto hash = l.find('#'); hash != std::string::npos) l.resize(hash);
        Row r{line, {}};
        std::string field;
        for (char c : l) {
            if (c == ' ' || c == '\t' || c == ',' || c == '\r') {
                if (!field.empty()) r.fields.push_back(std::move(field)), field.clear();
            } else {
                field += c;
            }
        }
        if (!field.empty()) r.fields.push_back(std::move(field));
        if (!r.fields.empty()) out.push_back(std::move(r));
        if (end == text.size()) break;
    }
    return out;
}

double number(const std::string &s, const std::filesystem::path &file, const Row &r, std::size_t column) {
    double v = 0;
    const char *b = s.data(), *e = s.data() + s.size();
    if (*b == '+') ++b;
    const auto [p, ec] = std::from_chars(b, e, v);
    if (ec != std::errc() || p != e || !std::isfinite(v))
        throw Error(file.string() + ": line " + std::to_string(r.line) + ", column " + std::to_string(column + 1) + ": '" + s +
                    "' is not a finite number");
    return v;
}

void read_matrix(Connectome &c, const std::filesystem::path &edge_file, const std::string &nodes_name);

}  // namespace

Connectome read_connectome(const std::filesystem::path &node_file, const std::filesystem::path &edge_file) {
    Connectome c;
    const std::vector<Row> nodes = rows_of(node_file, "node file");
    if (nodes.empty()) throw Error(node_file.string() + ": no nodes (a line of x y z [colour size label] each)");
    if (nodes.size() > kMaxNodes) throw Error(node_file.string() + ": more than " + std::to_string(kMaxNodes) + " nodes");
    // (a first row that is not numbers: a CSV header)
    std::size_t first = 0;
    if (!nodes[0].fields.empty()) {
        double v;
        const std::string &s = nodes[0].fields[0];
        if (std::from_chars(s.data(), s.data() + s.size(), v).ec != std::errc()) first = 1;
    }
    for (std::size_t k = first; k < nodes.size(); ++k) {
        const Row &r = nodes[k];
        if (r.fields.size() < 3)
            throw Error(node_file.string() + ": line " + std::to_string(r.line) + ": " + std::to_string(r.fields.size()) +
                        " values, a node needs x y z (then colour, size, label)");
        c.xyz.push_back({number(r.fields[0], node_file, r, 0), number(r.fields[1], node_file, r, 1), number(r.fields[2], node_file, r, 2)});
        c.colour.push_back(r.fields.size() > 3 ? number(r.fields[3], node_file, r, 3) : 1.0);
        c.size.push_back(r.fields.size() > 4 ? number(r.fields[4], node_file, r, 4) : 1.0);
        if (c.size.back() < 0)
            throw Error(node_file.string() + ": line " + std::to_string(r.line) + ": a node's size is negative (" + r.fields[4] + ")");
        std::string label;
        for (std::size_t f = 5; f < r.fields.size(); ++f) label += (f > 5 ? " " : "") + r.fields[f];
        c.labels.push_back(label == "-" ? "" : label);
    }
    if (c.xyz.empty()) throw Error(node_file.string() + ": no nodes (a line of x y z [colour size label] each)");
    read_matrix(c, edge_file, node_file.filename().string());
    return c;
}

Connectome connectome_of_labels(const Volume &v, const std::string &what, const std::filesystem::path &edge_file) {
    std::size_t dims = v.dims.size();
    while (dims > 3 && v.dims[dims - 1] == 1) --dims;
    if (dims != 3) throw Error(what + ": a parcellation is a 3D volume of labels, not " + std::to_string(v.dims.size()) + " dimensions");
    const std::size_t es = dtype_size(v.dtype);
    const std::uint64_t X = v.dims[0], Y = v.dims[1], n = v.dims[0] * v.dims[1] * v.dims[2];
    if (es == 0 || v.dtype == HZ_DTYPE_RGB8 || v.dtype == HZ_DTYPE_RGBA8 || v.voxels.size() < n * es)
        throw Error(what + ": a parcellation holds numbers (labels)");
    struct Sum {
        double x = 0, y = 0, z = 0;
        std::uint64_t count = 0;
    };
    std::map<std::int64_t, Sum> sums;
    const auto &a = v.voxel_to_ras;
    for (std::uint64_t k = 0; k < n; ++k) {
        const double l = value_at(v.voxels.data() + k * es, v.dtype) * (v.scale_slope == 0 ? 1.0 : v.scale_slope) + v.scale_inter;
        if (!(l > 0)) continue;  // (0 and below: background)
        if (l != std::floor(l) || l > 1e15) throw Error(what + ": label " + std::to_string(l) + " is not a whole number");
        Sum &s = sums[std::int64_t(l)];
        if (sums.size() > kMaxNodes) throw Error(what + ": more than " + std::to_string(kMaxNodes) + " labels");
        s.x += double(k % X), s.y += double(k / X % Y), s.z += double(k / X / Y), ++s.count;
    }
    if (sums.empty()) throw Error(what + ": no label above 0: no nodes");
    Connectome c;
    for (const auto &[label, s] : sums) {
        const double ijk[3] = {s.x / double(s.count), s.y / double(s.count), s.z / double(s.count)};
        std::array<double, 3> p;
        for (int r = 0; r < 3; ++r) p[std::size_t(r)] = a[4 * r] * ijk[0] + a[4 * r + 1] * ijk[1] + a[4 * r + 2] * ijk[2] + a[4 * r + 3];
        c.xyz.push_back(p);
        c.colour.push_back(double(label));
        c.size.push_back(1.0);
        c.labels.push_back(std::to_string(label));
    }
    read_matrix(c, edge_file, std::filesystem::path(what).filename().string());
    return c;
}

namespace {
void read_matrix(Connectome &c, const std::filesystem::path &edge_file, const std::string &nodes_name) {
    if (edge_file.empty()) return;
    const std::vector<Row> edges = rows_of(edge_file, "edge file");
    const std::size_t N = c.nodes();
    if (edges.size() != N)
        throw Error(edge_file.string() + ": " + std::to_string(edges.size()) + " rows, the node file " + nodes_name + " has " +
                    std::to_string(N) + " nodes (an N x N matrix)");
    c.weights.reserve(N * N);
    for (const Row &r : edges) {
        if (r.fields.size() != N)
            throw Error(edge_file.string() + ": line " + std::to_string(r.line) + ": " + std::to_string(r.fields.size()) +
                        " values, the node file has " + std::to_string(N) + " nodes");
        for (std::size_t k = 0; k < N; ++k) c.weights.push_back(number(r.fields[k], edge_file, r, k));
    }
}
}  // namespace

namespace {
void check(const ConnectomeOptions &o) {
    if (!(o.threshold >= 0 && std::isfinite(o.threshold))) throw Error("connectome: threshold must be >= 0");
    if (!(o.node_scale > 0 && o.node_scale <= 100)) throw Error("connectome: node_scale must be in (0, 100]");
    if (!(o.edge_radius > 0 && o.edge_radius <= 100)) throw Error("connectome: edge_radius must be in (0, 100] mm");
}
}  // namespace

Mesh connectome_nodes(const Connectome &c, const ConnectomeOptions &o) {
    check(o);
    const SphereMesh sphere = icosphere(3);
    Mesh m = sphere_glyphs(sphere, c.nodes(), "", [&](std::size_t g, std::uint64_t i, float *xyz, float *) {
        const double r = c.size[g] * o.node_scale;
        for (std::size_t k = 0; k < 3; ++k) xyz[k] = float(c.xyz[g][k] + r * sphere.vertices[3 * i + k]);
    });
    // (colours from the values, through a colormap)
    std::vector<float> value(c.nodes() * sphere.nb_vertices());
    for (std::size_t g = 0; g < c.nodes(); ++g)
        std::fill(value.begin() + std::ptrdiff_t(g * sphere.nb_vertices()), value.begin() + std::ptrdiff_t((g + 1) * sphere.nb_vertices()),
                  float(c.colour[g]));
    m.arrays.push_back(f32_array("node_value", HZ_ATTACH_VERTEX, value));
    return m;
}

Tractogram connectome_edges(const Connectome &c, const ConnectomeOptions &o) {
    check(o);
    const std::size_t N = c.nodes();
    std::vector<float> pos, weight;
    double largest = 0;
    for (std::size_t i = 0; i < N && !c.weights.empty(); ++i)
        for (std::size_t j = i + 1; j < N; ++j) {
            const double a = c.weights[i * N + j], b = c.weights[j * N + i];
            const double w = std::abs(a) >= std::abs(b) ? a : b;
            if (!(std::abs(w) > o.threshold)) continue;
            for (std::size_t k = 0; k < 3; ++k) pos.push_back(float(c.xyz[i][k]));
            for (std::size_t k = 0; k < 3; ++k) pos.push_back(float(c.xyz[j][k]));
            weight.push_back(float(w));
            largest = std::max(largest, std::abs(w));
        }
    std::vector<float> radius(weight.size());
    for (std::size_t e = 0; e < weight.size(); ++e) radius[e] = float(o.edge_radius * std::abs(weight[e]) / largest);
    Tractogram t;
    t.positions = Buffer<float>::copy_of(pos);
    t.offsets = Buffer<std::uint64_t>(weight.size() + 1);
    for (std::size_t e = 0; e <= weight.size(); ++e) t.offsets[e] = 2 * e;
    t.arrays.push_back(f32_array("weight", HZ_ATTACH_STREAMLINE, weight));
    t.arrays.push_back(f32_array("radius_mm", HZ_ATTACH_STREAMLINE, radius));
    return t;
}

}  // namespace hz::core::render
