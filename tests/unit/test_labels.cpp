// Label volumes (core/render/labels.hpp): FreeSurferColorLUT-format tables,
// the labels read from a volume, the slices' texture, and the surface nets:
// closed and outward (every edge once each way, Euler's characteristic of
// a sphere and of a torus), the volume they enclose against the voxels',
// every vertex within a voxel of the region's boundary, mirrored affines.
#include <hz/core/render/labels.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <map>
#include <set>

using namespace hz::core;
using namespace hz::core::render;

namespace {

// An int16 volume X x Y x Z with voxel (i, j, k)'s label f(i, j, k).
template <class F>
Volume label_volume(std::uint64_t X, std::uint64_t Y, std::uint64_t Z, const Affine &a, F f) {
    Volume v;
    v.dtype = HZ_DTYPE_I16;
    v.dims = {X, Y, Z};
    v.voxel_to_ras = a;
    v.voxels = Buffer<std::byte>(X * Y * Z * 2);
    for (std::uint64_t k = 0; k < Z; ++k)
        for (std::uint64_t j = 0; j < Y; ++j)
            for (std::uint64_t i = 0; i < X; ++i) {
                const auto l = std::int16_t(f(double(i), double(j), double(k)));
                std::memcpy(v.voxels.data() + ((k * Y + j) * X + i) * 2, &l, 2);
            }
    return v;
}

struct Topology {
    bool closed = true;  // every directed edge once, its reverse once
    std::int64_t euler = 0;
    double volume = 0;  // enclosed, by the divergence theorem (positive: faces outward)
};

Topology topology(const Mesh &m) {
    Topology t;
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
    std::set<std::uint32_t> used;
    const float *V = m.vertices.data();
    for (std::uint64_t f = 0; f < m.nb_faces(); ++f) {
        const std::uint32_t *F = m.faces.data() + 3 * f;
        for (int e = 0; e < 3; ++e) ++directed[{F[e], F[(e + 1) % 3]}], used.insert(F[e]);
        const float *a = V + 3 * F[0], *b = V + 3 * F[1], *c = V + 3 * F[2];
        t.volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0;
    }
    for (const auto &[e, n] : directed) {
        const auto back = directed.find({e.second, e.first});
        if (n != 1 || back == directed.end() || back->second != 1) t.closed = false;
    }
    t.euler = std::int64_t(used.size()) - std::int64_t(directed.size() / 2) + std::int64_t(m.nb_faces());
    return t;
}

const float *array_of(const Mesh &m, const std::string &name) {
    for (const auto &a : m.arrays)
        if (a.name == name) return reinterpret_cast<const float *>(a.bytes.data());
    return nullptr;
}

}  // namespace

TEST_CASE("label tables: FreeSurferColorLUT lines, comments, and each malformed line named", "[labels]") {
    const LabelTable t = parse_label_table(
        "#No. Label Name:   R   G   B   A\n\n0   Unknown  0 0 0 0\n17  Left-Hippocampus  220 216 20 0  # a comment\n1000 ctx-lh-unknown 25 "
        "5 25\n",
        "lut.txt");
    REQUIRE(t.size() == 3);
    CHECK(t.at(17).name == "Left-Hippocampus");
    CHECK(t.at(17).rgb == std::array<std::uint8_t, 3>{220, 216, 20});
    CHECK(t.at(1000).rgb == std::array<std::uint8_t, 3>{25, 5, 25});
    CHECK(label_name(t, 17) == "Left-Hippocampus");
    CHECK(label_name(t, 18) == "18");
    CHECK(label_colour(t, 17) == std::array<std::uint8_t, 3>{220, 216, 20});
    const std::pair<const char *, const char *> bad[] = {
        {"1 a 2 3\n", "lut.txt: line 1: expected INDEX NAME R G B [A], not 4 fields"},
        {"# x\n2 a 1 2 256 0\n", "lut.txt: line 2: R G B must be whole numbers in 0..255, not '256'"},
        {"2 a 1 2 3.5\n", "R G B must be whole numbers in 0..255, not '3.5'"},
        {"2.5 a 1 2 3\n", "the index '2.5' is not a whole number below 2^24"},
        {"2 a 1 2 3 0\n3 b 1 1 1 0\n2 c 0 0 0 0\n", "lut.txt: line 3: label 2 is listed twice"},
        {"2 a 1 2 3 -1\n", "A must be a whole number"},
        {"# nothing\n", "lut.txt: no label"},
    };
    for (const auto &[text, msg] : bad) {
        INFO(text);
        CHECK_THROWS_WITH(parse_label_table(text, "lut.txt"), Catch::Contains(msg));
    }
}

TEST_CASE("label colours: a table's, else distinct and the same every time", "[labels]") {
    std::set<std::array<std::uint8_t, 3>> seen;
    for (std::int64_t l = 1; l <= 64; ++l) {
        const auto c = label_colour({}, l);
        CHECK(c == label_colour({}, l));
        seen.insert(c);
        CHECK(std::max({c[0], c[1], c[2]}) >= 200);  // (bright: value 0.95)
    }
    CHECK(seen.size() == 64);
}

TEST_CASE("label fields: whole numbers only, labels present, the texture's colours and labels", "[labels]") {
    const Affine I = kIdentity;
    Volume v = label_volume(4, 3, 2, I, [](double i, double j, double) { return i == 1 && j == 0 ? 17 : i == 3 ? 5 : 0; });
    LabelOptions opt;
    opt.table = parse_label_table("17 Left-Hippocampus 220 216 20 0\n", "lut");
    const LabelField f = make_label_field(v, opt, "aseg.nii");
    CHECK(f.present == std::vector<std::int64_t>{0, 5, 17});
    const std::vector<float> tex = label_texture(f);
    REQUIRE(tex.size() == 4 * 24);
    CHECK(tex[4 * 1 + 0] == Approx(220 / 255.0));
    CHECK(tex[4 * 1 + 3] == 17.0f);
    CHECK(tex[4 * 3 + 3] == 5.0f);
    CHECK(tex[4 * 0 + 3] == 0.0f);  // (the background: not shown)
    opt.only = {5};
    const LabelField g = make_label_field(v, opt, "aseg.nii");
    CHECK(label_texture(g)[4 * 1 + 3] == 0.0f);  // (17: not among those shown)
    CHECK(label_texture(g)[4 * 3 + 3] == 5.0f);
    opt.only = {4};
    CHECK_THROWS_WITH(make_label_field(v, opt, "aseg.nii"), "aseg.nii: label 4 (4) is not in the volume");
    opt.only.clear();
    // A float volume with a fraction; colour voxels; a 4D series.
    Volume fl;
    fl.dims = {2, 1, 1};
    fl.voxels = Buffer<std::byte>(8);
    const float vals[2] = {1.0f, 2.5f};
    std::memcpy(fl.voxels.data(), vals, 8);
    CHECK_THROWS_WITH(make_label_field(fl, opt, "x.nii"), Catch::StartsWith("x.nii: voxel (1, 0, 0) holds 2.5"));
    fl.dims = {1, 1, 1, 2};
    CHECK_THROWS_WITH(make_label_field(fl, opt, "x.nii"), "x.nii: a label volume is 3D, not 4 dimensions");
    fl.dims = {2, 1, 1, 1};  // (trailing dimensions of 1: 3D)
    CHECK_THROWS_WITH(make_label_field(fl, opt, "x.nii"), Catch::Contains("holds 2.5"));
    opt.fill = 1.5;
    CHECK_THROWS_WITH(make_label_field(v, opt, "a"), "a: fill is an opacity in 0..1");
}

TEST_CASE("label surfaces: a sphere closed, outward, its volume and radius the voxels'", "[labels]") {
    const double R = 8.0;
    for (const bool mirrored : {false, true}) {
        // 1.5 x 2 x 1 mm voxels turned about z by 30 degrees (mirrored in x).
        const double c = std::cos(0.5236), s = std::sin(0.5236), sx = mirrored ? -1.5 : 1.5;
        const Affine A{c * sx, -s * 2.0, 0, 10, s * sx, c * 2.0, 0, -20, 0, 0, 1.0, 5, 0, 0, 0, 1};
        const Volume v =
            label_volume(24, 24, 24, A, [&](double i, double j, double k) { return std::hypot(i - 11.5, j - 12, k - 11) <= R ? 3 : 0; });
        std::uint64_t inside = 0;
        for (std::uint64_t x = 0; x < 24 * 24 * 24; ++x) inside += reinterpret_cast<const std::int16_t *>(v.voxels.data())[x] == 3;
        const double det = std::abs(sx * 2.0 * 1.0);
        for (const int smoothing : {0, 10}) {
            INFO("mirrored " << mirrored << ", smoothing " << smoothing);
            LabelOptions opt;
            opt.surfaces = true;
            opt.smoothing = smoothing;
            const Mesh m = label_surfaces(make_label_field(v, opt, "sphere"));
            REQUIRE(m.nb_faces() > 500);
            const Topology t = topology(m);
            CHECK(t.closed);
            CHECK(t.euler == 2);
            CHECK(t.volume > 0);  // (outward)
            CHECK(t.volume == Approx(double(inside) * det).epsilon(0.04));
            // Each vertex (back in voxels) within a voxel of the boundary.
            const float *V = m.vertices.data();
            const float *label = array_of(m, "label");
            REQUIRE(label);
            for (std::uint64_t i = 0; i < m.nb_vertices(); ++i) {
                const double x = V[3 * i] - 10, y = V[3 * i + 1] + 20, z = V[3 * i + 2] - 5;
                const double vi = (c * x + s * y) / sx, vj = (-s * x + c * y) / 2.0, vk = z / 1.0;
                const double r = std::hypot(vi - 11.5, vj - 12, vk - 11);
                CHECK(r > R - 1.0);
                CHECK(r < R + 1.0);
                CHECK(label[i] == 3.0f);
            }
        }
    }
}

TEST_CASE("mask surfaces: the voxels above a value, of a float volume", "[labels]") {
    Volume v;
    v.dims = {20, 20, 20};
    v.voxels = Buffer<std::byte>(20 * 20 * 20 * 4);
    std::uint64_t above = 0;
    for (std::uint64_t k = 0; k < 20 * 20 * 20; ++k) {
        const float r = float(std::hypot(double(k % 20) - 9.5, double(k / 20 % 20) - 9.5, double(k / 400) - 9.5));
        const float val = 100.0f - 10.0f * r;  // (above 30: within 7 voxels)
        std::memcpy(v.voxels.data() + 4 * k, &val, 4);
        above += val > 30.0f;
    }
    const Mesh m = mask_surface(v, 30.0, 20, "t1.nii");
    const Topology t = topology(m);
    CHECK(t.closed);
    CHECK(t.euler == 2);
    CHECK(t.volume == Approx(double(above)).epsilon(0.05));
    CHECK_THROWS_WITH(mask_surface(v, 100.0, 20, "t1.nii"), "t1.nii: no voxel above 100.000000: no surface");
}

TEST_CASE("label surfaces: a torus has a hole, two labels two surfaces of their colours", "[labels]") {
    const Volume v = label_volume(40, 40, 16, kIdentity, [](double i, double j, double k) {
        const double ring = std::hypot(i - 20, j - 20) - 11;
        if (std::hypot(ring, k - 8) <= 4) return 7;
        return std::hypot(i - 20, j - 20, (k - 8) * 3) <= 3.5 ? 9 : 0;  // (a bead in the hole)
    });
    LabelOptions opt;
    opt.table = parse_label_table("7 Ring 10 20 30\n", "lut");
    opt.surfaces = true;
    const Mesh m = label_surfaces(make_label_field(v, opt, "torus"));
    const Topology t = topology(m);
    CHECK(t.closed);
    CHECK(t.euler == 0 + 2);  // (a torus, 0, and a sphere, 2)
    const float *label = array_of(m, "label");
    const DataArray *rgb = nullptr;
    for (const auto &a : m.arrays)
        if (a.name == "rgb") rgb = &a;
    REQUIRE(rgb);
    REQUIRE(rgb->components == 3);
    std::set<float> labels;
    for (std::uint64_t i = 0; i < m.nb_vertices(); ++i) {
        labels.insert(label[i]);
        const auto *c = reinterpret_cast<const std::uint8_t *>(rgb->bytes.data()) + 3 * i;
        const auto want = label_colour(opt.table, std::int64_t(label[i]));
        CHECK((c[0] == want[0] && c[1] == want[1] && c[2] == want[2]));
    }
    CHECK(labels == std::set<float>{7.0f, 9.0f});
    // Only the ring: a torus alone.
    opt.only = {7};
    CHECK(topology(label_surfaces(make_label_field(v, opt, "torus"))).euler == 0);
}
