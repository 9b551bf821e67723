// BUAN profiles: numpy vectors, DIPY's assignment map (buan.hpp).
#include <hz/core/render/buan.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>

namespace hz::core::render {

namespace {

// A Python literal's value for `key` in the .npy header dict ("'descr': '<f8', ...").
std::string header_value(const std::string &h, const std::string &key) {
    const std::size_t k = h.find("'" + key + "'");
    if (k == std::string::npos) return {};
    std::size_t v = h.find(':', k);
    if (v == std::string::npos) return {};
    ++v;
    while (v < h.size() && h[v] == ' ') ++v;
    if (v >= h.size()) return {};
    if (h[v] == '\'') {
        const std::size_t e = h.find('\'', v + 1);
        return e == std::string::npos ? std::string() : h.substr(v, e - v + 1);
    }
    if (h[v] == '(') {
        const std::size_t e = h.find(')', v);
        return e == std::string::npos ? std::string() : h.substr(v, e - v + 1);
    }
    const std::size_t e = h.find_first_of(",}", v);
    return h.substr(v, e == std::string::npos ? std::string::npos : e - v);
}

// DIPY's set_number_of_points (float32 arithmetic, as DIPY computes on
// float32 streamlines): n points evenly spaced along the polyline's length.
void resample(const float *p, std::uint64_t m, std::uint32_t n, float *out) {
    if (m == 1) {
        for (std::uint32_t i = 0; i < n; ++i) std::memcpy(out + 3 * i, p, 12);
        return;
    }
    std::vector<float> arc(m, 0.0f);
    for (std::uint64_t i = 1; i < m; ++i) {
        float s = 0;
        for (int d = 0; d < 3; ++d) s += (p[3 * i + d] - p[3 * (i - 1) + d]) * (p[3 * i + d] - p[3 * (i - 1) + d]);
        arc[i] = arc[i - 1] + std::sqrt(s);
    }
    const float step = arc[m - 1] / float(n - 1);
    float next = 0;
    std::uint64_t i = 0, j = 0;
    while (next < arc[m - 1] && i < n) {
        if (next == arc[j]) {
            std::memcpy(out + 3 * i, p + 3 * j, 12);
            next += step, ++i, ++j;
        } else if (next < arc[j]) {
            const float ratio = 1.0f - ((arc[j] - next) / (arc[j] - arc[j - 1]));
            for (int d = 0; d < 3; ++d) out[3 * i + d] = p[3 * (j - 1) + d] + ratio * (p[3 * j + d] - p[3 * (j - 1) + d]);
            next += step, ++i;
        } else {
            ++j;
        }
    }
    std::memcpy(out + 3 * (n - 1), p + 3 * (m - 1), 12);
}

}  // namespace

std::vector<double> read_npy_vector(const std::filesystem::path &path) {
    const std::string what = path.string();
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(what + ": cannot open");
    char magic[8];
    if (!in.read(magic, 8) || std::memcmp(magic, "\x93NUMPY", 6) != 0) throw Error(what + ": not a .npy file (numpy's format)");
    const int major = static_cast<unsigned char>(magic[6]);
    if (major < 1 || major > 3) throw Error(what + ": .npy format version " + std::to_string(major) + ", not 1 to 3");
    std::uint32_t hlen = 0;
    unsigned char b[4] = {};
    if (!in.read(reinterpret_cast<char *>(b), major == 1 ? 2 : 4)) throw Error(what + ": truncated header");
    hlen = major == 1 ? std::uint32_t(b[0] | b[1] << 8) : std::uint32_t(b[0] | b[1] << 8 | b[2] << 16 | std::uint32_t(b[3]) << 24);
    if (hlen > 65536) throw Error(what + ": a header of " + std::to_string(hlen) + " bytes: not a .npy file");
    std::string h(hlen, '\0');
    if (!in.read(h.data(), hlen)) throw Error(what + ": truncated header");
    const std::string descr = header_value(h, "descr"), fortran = header_value(h, "fortran_order"), shape = header_value(h, "shape");
    if (descr.size() < 5 || shape.empty()) throw Error(what + ": a header without 'descr' or 'shape'");
    const char order = descr[1], kind = descr[2];
    const int size = std::atoi(descr.substr(3, descr.size() - 4).c_str());
    const bool ok_kind =
        (kind == 'f' && (size == 4 || size == 8)) || ((kind == 'i' || kind == 'u') && (size == 1 || size == 2 || size == 4 || size == 8));
    if (!ok_kind || (order != '<' && order != '>' && order != '|' && order != '='))
        throw Error(what + ": values of type " + descr + ": expected numbers (float64, float32 or integers)");
    (void)fortran;  // (one vector: the same in either order)
    // The shape: (n,), (n, 1) or (1, n).
    std::vector<std::uint64_t> dims;
    for (std::size_t p = 1; p < shape.size();) {
        while (p < shape.size() && (shape[p] == ' ' || shape[p] == ',')) ++p;
        if (p >= shape.size() || shape[p] == ')') break;
        char *end = nullptr;
        const unsigned long long v = std::strtoull(shape.c_str() + p, &end, 10);
        if (end == shape.c_str() + p) throw Error(what + ": a shape of " + shape + ": not numbers");
        dims.push_back(v);
        p = std::size_t(end - shape.c_str());
    }
    std::uint64_t count = 1, larger = 0;
    for (std::uint64_t d : dims) count *= std::max<std::uint64_t>(d, 1), larger += d > 1;
    if (dims.empty() || larger > 1 || count == 0 || std::find(dims.begin(), dims.end(), 0) != dims.end()) {
        std::string s;
        for (std::uint64_t d : dims) s += (s.empty() ? "" : " x ") + std::to_string(d);
        throw Error(what + ": holds " + (s.empty() ? std::string("one value (a scalar)") : s + " values") +
                    ": one vector, one value a segment");
    }
    if (count > (1u << 20)) throw Error(what + ": " + std::to_string(count) + " values: more than 2^20 segments");
    std::vector<unsigned char> raw(count * std::size_t(size));
    if (!in.read(reinterpret_cast<char *>(raw.data()), std::streamsize(raw.size())))
        throw Error(what + ": truncated: " + std::to_string(count) + " values of " + std::to_string(size) + " bytes expected");
    const bool big = order == '>';
    std::vector<double> out(count);
    for (std::uint64_t i = 0; i < count; ++i) {
        unsigned char v[8];
        for (int k = 0; k < size; ++k) v[k] = raw[i * std::size_t(size) + std::size_t(big ? size - 1 - k : k)];
        std::uint64_t bits = 0;
        for (int k = size - 1; k >= 0; --k) bits = bits << 8 | v[k];
        if (kind == 'f' && size == 8) {
            double d;
            std::memcpy(&d, &bits, 8);
            out[i] = d;
        } else if (kind == 'f') {
            const std::uint32_t u = std::uint32_t(bits);
            float f;
            std::memcpy(&f, &u, 4);
            out[i] = f;
        } else if (kind == 'u') {
            out[i] = double(bits);
        } else {
            const int shift = 64 - 8 * size;
            out[i] = double(std::int64_t(bits << shift) >> shift);
        }
    }
    return out;
}

std::vector<std::uint32_t> buan_segments(const Tractogram &t, std::uint32_t n) {
    if (n < 1 || n > 100000) throw Error("BUAN: " + std::to_string(n) + " segments: 1 to 100000");
    const std::uint64_t N = t.nb_streamlines();
    const float *P = t.positions.data();
    // Resampled streamlines, then QuickBundles (average pointwise distance to
    // the nearer of the streamline and its reverse, joins below 85 mm,
    // running-mean centroids in float32).
    const std::uint32_t m = std::max<std::uint32_t>(n, 2);  // (1 segment: the points of 2, the first taken)
    std::vector<std::vector<float>> centroids;
    std::vector<std::uint64_t> sizes;
    std::vector<float> f(3 * std::size_t(m)), flipped(f.size());
    // The average pointwise distance of centroid c to the streamline
    // (`rev`: read backwards).
    auto distance = [&](const std::vector<float> &c, const std::vector<float> &g) {
        double sum = 0;
        for (std::uint32_t i = 0; i < m; ++i) {
            double dd = 0;
            for (int d = 0; d < 3; ++d) dd += double(c[3 * i + d] - g[3 * i + d]) * double(c[3 * i + d] - g[3 * i + d]);
            sum += std::sqrt(dd);
        }
        return sum / m;
    };
    for (std::uint64_t s = 0; s < N; ++s) {
        const std::uint64_t b = t.begin(s), e = t.end(s);
        if (e == b) continue;
        resample(P + 3 * b, e - b, m, f.data());
        for (std::uint32_t i = 0; i < m; ++i) std::memcpy(&flipped[3 * i], &f[3 * (m - 1 - i)], 12);
        // (as DIPY's QuickBundles: each centroid's nearer of the streamline
        // and its reverse, which then joins it)
        double best = std::numeric_limits<double>::infinity();
        std::size_t at = 0;
        bool flip = false;
        for (std::size_t c = 0; c < centroids.size(); ++c) {
            const double direct = distance(centroids[c], f), reverse = distance(centroids[c], flipped);
            const double dist = std::min(direct, reverse);
            if (dist < best) best = dist, at = c, flip = reverse < direct;
        }
        if (centroids.empty() || !(best < 85.0)) {
            centroids.push_back(f);
            sizes.push_back(1);
            continue;
        }
        const std::vector<float> &g = flip ? flipped : f;
        const std::uint64_t k = ++sizes[at];
        for (std::size_t i = 0; i < g.size(); ++i) centroids[at][i] = (float(k - 1) * centroids[at][i] + g[i]) / float(k);
    }
    // Each point: the nearest centroid point, over the centroids laid end to end.
    std::vector<std::uint32_t> out;
    out.reserve(t.nb_vertices());
    for (std::uint64_t s = 0; s < N; ++s)
        for (std::uint64_t i = t.begin(s); i < t.end(s); ++i) {
            double best = std::numeric_limits<double>::infinity();
            std::uint32_t at = 0;
            for (std::size_t c = 0; c < centroids.size(); ++c)
                for (std::uint32_t j = 0; j < n; ++j) {
                    double dd = 0;
                    for (int d = 0; d < 3; ++d) dd += std::pow(double(P[3 * i + d]) - double(centroids[c][3 * j + d]), 2);
                    if (dd < best) best = dd, at = std::uint32_t(c * n + j);
                }
            out.push_back(at);
        }
    return out;
}

}  // namespace hz::core::render
