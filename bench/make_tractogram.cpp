// hz-make-tractogram: writes a realistic synthetic whole-brain tractogram as
// an MRtrix TCK file, streamed (memory stays at a few MB whatever the size),
// for the scale tests and benchmarks (1M-10M streamlines, 2-21 GB).
//
//   hz-make-tractogram OUT.tck --streamlines N [--seed S] [--bundles B] [--threads T]
//
// What "realistic" means here, in the figures of whole-brain probabilistic
// tractography (e.g. MRtrix3 iFOD2 with 0.5-1 mm steps):
// - streamlines of 100-400 points each, steps of 0.5-0.8 mm (a few outside
//   0.5-1 mm where the point count is clamped), about 60-280 mm long;
// - they follow a few hundred long bundles: smooth cubic curves between two
//   points near the surface of a brain-sized ellipsoid (semi-axes 65, 85,
//   60 mm, RAS+), arching through the interior (association, commissural and
//   projection-like paths), so that streamlines overlap, cross and fan out;
// - each streamline lies in its bundle's cross-section (Gaussian, 1.5-5 mm,
//   fanning out towards the ends) and wanders from the core by a smooth
//   deviation of about a millimetre, plus a little step-to-step noise
//   (0.05 mm), so that no two streamlines are the same polyline;
// - bundle sizes follow a heavy-tailed law (a few large bundles, many small).
// Deterministic for a given seed, whatever the thread count.
#include <hz/core/phantom.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

namespace {

using V3 = std::array<double, 3>;
V3 add(V3 a, V3 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
V3 sub(V3 a, V3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
V3 mul(V3 a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dot(V3 a, V3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
V3 cross(V3 a, V3 b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
V3 normalize(V3 a) {
    const double n = std::sqrt(dot(a, a));
    return n > 0 ? mul(a, 1 / n) : V3{1, 0, 0};
}

using Rng = hz::core::SplitMix64;

const V3 kSemi = {65, 85, 60};  // brain-sized ellipsoid, RAS+ mm

V3 on_shell(Rng &r, double depth) {
    const double z = r.uniform(-1, 1), phi = r.uniform(0, 2 * M_PI), s = std::sqrt(1 - z * z);
    return {kSemi[0] * depth * s * std::cos(phi), kSemi[1] * depth * s * std::sin(phi), kSemi[2] * depth * z};
}

struct Bundle {
    std::array<V3, 4> c;  // cubic Bezier control points
    double length = 0, radius = 2;
    V3 at(double t) const {
        const double u = 1 - t;
        return add(add(mul(c[0], u * u * u), mul(c[1], 3 * u * u * t)), add(mul(c[2], 3 * u * t * t), mul(c[3], t * t * t)));
    }
    double arc(double t0 = 0, double t1 = 1, int n = 128) const {
        double len = 0;
        V3 prev = at(t0);
        for (int i = 1; i <= n; ++i) {
            const V3 p = at(t0 + (t1 - t0) * i / n);
            len += std::sqrt(dot(sub(p, prev), sub(p, prev)));
            prev = p;
        }
        return len;
    }
};

Bundle make_bundle(Rng &r) {
    for (;;) {
        Bundle b;
        const V3 a = on_shell(r, r.uniform(0.7, 0.95)), e = on_shell(r, r.uniform(0.7, 0.95));
        // Control points pulled towards the interior: paths arch through the white matter.
        for (int k = 1; k <= 2; ++k) {
            const V3 mid = add(mul(a, 1 - k / 3.0), mul(e, k / 3.0));
            const double pull = r.uniform(0.2, 0.8);
            b.c[k] = add(mul(mid, pull), {r.normal() * 12, r.normal() * 12, r.normal() * 10});
        }
        b.c[0] = a, b.c[3] = e;
        b.length = b.arc();
        b.radius = r.uniform(1.5, 5.0);
        if (b.length >= 100 && b.length <= 280) return b;
    }
}

struct Options {
    std::string out;
    std::uint64_t n = 0, seed = 1;
    int bundles = 400, threads = 0;
};

// Streamline `s` of the file, appended to `pos` (xyz float32 triples).
void make_streamline(const std::vector<Bundle> &bundles, const std::vector<double> &cdf, std::uint64_t seed, std::uint64_t s,
                     std::vector<float> &pos) {
    Rng r{(seed * 0x2545F4914F6CDD1Dull) ^ (s * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull)};
    const double u = r.uniform(0, 1);
    const Bundle &b = bundles[std::min<std::size_t>(std::lower_bound(cdf.begin(), cdf.end(), u) - cdf.begin(), bundles.size() - 1)];
    // Trimmed ends; points and step from the length (100-400 points, 0.5-1 mm).
    const double t0 = r.uniform(0, 0.08), t1 = r.uniform(0.92, 1.0);
    const double len = b.arc(t0, t1, 32);  // (the curve's speed varies along t)
    const double step = r.uniform(0.5, 0.8);
    const int n = std::clamp(int(len / step) + 1, 100, 400);
    // Cross-section offset (fanning towards the ends) and a smooth wander.
    const double ox = r.normal() * b.radius, oy = r.normal() * b.radius;
    const double fan = r.uniform(1.0, 2.5);
    double ph[4], fr[4], am[4];
    for (int k = 0; k < 4; ++k) ph[k] = r.uniform(0, 2 * M_PI), fr[k] = r.uniform(1.0, 4.0), am[k] = r.uniform(0.2, 0.9);
    const bool reverse = r.next() & 1;
    V3 prev_t = normalize(sub(b.at(t0 + 1e-3), b.at(t0)));
    V3 side = normalize(cross(prev_t, std::abs(prev_t[2]) < 0.9 ? V3{0, 0, 1} : V3{1, 0, 0}));
    const std::size_t base = pos.size();
    pos.resize(base + std::size_t(n) * 3);
    for (int i = 0; i < n; ++i) {
        const double w = double(i) / (n - 1), t = t0 + (t1 - t0) * w;
        const V3 c = b.at(t);
        const V3 tan = normalize(sub(b.at(std::min(t + 1e-3, 1.0)), b.at(std::max(t - 1e-3, 0.0))));
        // Parallel transport of the cross-section frame along the core.
        side = normalize(sub(side, mul(tan, dot(side, tan))));
        const V3 up = cross(tan, side);
        const double spread = 1 + (fan - 1) * std::pow(std::abs(2 * w - 1), 3);
        const double wx = am[0] * std::sin(fr[0] * 2 * M_PI * w + ph[0]) + am[1] * std::sin(fr[1] * 2 * M_PI * w + ph[1]);
        const double wy = am[2] * std::sin(fr[2] * 2 * M_PI * w + ph[2]) + am[3] * std::sin(fr[3] * 2 * M_PI * w + ph[3]);
        const double jx = r.normal() * 0.05, jy = r.normal() * 0.05;
        const V3 p = add(c, add(mul(side, ox * spread + wx + jx), mul(up, oy * spread + wy + jy)));
        const std::size_t j = base + std::size_t(reverse ? n - 1 - i : i) * 3;
        pos[j] = float(p[0]), pos[j + 1] = float(p[1]), pos[j + 2] = float(p[2]);
        prev_t = tan;
    }
}

int fail(const std::string &msg) {
    std::fprintf(stderr, "hz-make-tractogram: %s\n", msg.c_str());
    return 1;
}

}  // namespace

int main(int argc, char **argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) std::exit(fail(a + " needs a value"));
            return argv[++i];
        };
        if (a == "--streamlines")
            o.n = std::strtoull(value().c_str(), nullptr, 10);
        else if (a == "--seed")
            o.seed = std::strtoull(value().c_str(), nullptr, 10);
        else if (a == "--bundles")
            o.bundles = std::atoi(value().c_str());
        else if (a == "--threads")
            o.threads = std::atoi(value().c_str());
        else if (a == "-h" || a == "--help") {
            std::printf("usage: hz-make-tractogram OUT.tck --streamlines N [--seed S] [--bundles B] [--threads T]\n");
            return 0;
        } else if (!a.empty() && a[0] == '-')
            return fail("unknown option " + a);
        else
            o.out = a;
    }
    if (o.out.empty() || o.n == 0) return fail("usage: hz-make-tractogram OUT.tck --streamlines N [--seed S] [--bundles B]");
    if (o.bundles < 1) return fail("--bundles must be at least 1");
    const int threads = o.threads > 0 ? o.threads : std::max(1u, std::thread::hardware_concurrency());

    Rng r{o.seed * 7919 + 1};
    std::vector<Bundle> bundles;
    std::vector<double> cdf;
    double total = 0;
    for (int k = 0; k < o.bundles; ++k) {
        bundles.push_back(make_bundle(r));
        total += std::pow(r.uniform(0.02, 1.0), 2.0);  // heavy-tailed bundle sizes
        cdf.push_back(total);
    }
    for (double &c : cdf) c /= total;

    const std::string tmp = o.out + ".part";
    std::FILE *f = std::fopen(tmp.c_str(), "wb");
    if (!f) return fail(o.out + ": cannot create: " + std::strerror(errno));
    std::string head = "mrtrix tracks\ndatatype: Float32LE\ncount: " + std::to_string(o.n) + "\ngenerator: hz-make-tractogram seed " +
                       std::to_string(o.seed) + "\nfile: . ";
    std::size_t offset = head.size() + 16;
    offset = (offset + 3) / 4 * 4;
    head += std::to_string(offset);
    head += "\nEND\n";
    head.resize(offset, '\0');
    std::fwrite(head.data(), 1, head.size(), f);

    const std::uint64_t block = 16384;
    std::vector<std::vector<float>> bufs(threads);
    std::uint64_t points = 0;
    for (std::uint64_t s0 = 0; s0 < o.n; s0 += block * threads) {
        std::vector<std::thread> pool;
        for (int t = 0; t < threads; ++t)
            pool.emplace_back([&, t] {
                auto &pos = bufs[t];
                pos.clear();
                const std::uint64_t a = s0 + t * block, e = std::min(o.n, a + block);
                for (std::uint64_t s = a; s < e; ++s) {
                    make_streamline(bundles, cdf, o.seed, s, pos);
                    pos.insert(pos.end(), {NAN, NAN, NAN});
                }
            });
        for (auto &th : pool) th.join();
        for (int t = 0; t < threads; ++t) {
            points += bufs[t].size() / 3;
            if (!bufs[t].empty() && std::fwrite(bufs[t].data(), 4, bufs[t].size(), f) != bufs[t].size()) {
                std::fclose(f);
                std::remove(tmp.c_str());
                return fail(o.out + ": write failed: " + std::strerror(errno));
            }
        }
        if (o.n >= 1000000 && (s0 / (block * threads)) % 16 == 0)
            std::fprintf(stderr, "\rhz-make-tractogram: %llu / %llu streamlines", (unsigned long long)std::min(o.n, s0 + block * threads),
                         (unsigned long long)o.n);
    }
    const float end[3] = {INFINITY, INFINITY, INFINITY};
    std::fwrite(end, 4, 3, f);
    if (std::fflush(f) != 0 || std::ferror(f) || std::fclose(f) != 0) {
        std::remove(tmp.c_str());
        return fail(o.out + ": write failed: " + std::strerror(errno));
    }
    if (std::rename(tmp.c_str(), o.out.c_str()) != 0) {
        std::remove(tmp.c_str());
        return fail(o.out + ": cannot rename into place: " + std::strerror(errno));
    }
    if (o.n >= 1000000) std::fprintf(stderr, "\n");
    std::printf("%s: %llu streamlines, %llu points (%.1f per streamline)\n", o.out.c_str(), (unsigned long long)o.n,
                (unsigned long long)(points - o.n), double(points - o.n) / double(o.n));
    return 0;
}
