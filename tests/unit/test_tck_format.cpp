// The TCK format code on its own (no plugin, no host).
#include "tck_format.hpp"

#include <catch2/catch.hpp>

#include "simd_targets.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

std::string f32le(std::initializer_list<float> v) {
    std::string s;
    for (float f : v) {
        uint32_t u = std::bit_cast<uint32_t>(f);
        for (int i = 0; i < 4; ++i) s.push_back(static_cast<char>((u >> (8 * i)) & 0xff));
    }
    return s;
}
std::string f64be(std::initializer_list<double> v) {
    std::string s;
    for (double f : v) {
        uint64_t u = std::bit_cast<uint64_t>(f);
        for (int i = 7; i >= 0; --i) s.push_back(static_cast<char>((u >> (8 * i)) & 0xff));
    }
    return s;
}
const float NaN = std::numeric_limits<float>::quiet_NaN();
const float Inf = std::numeric_limits<float>::infinity();

struct Parsed {
    tck::Header h;
    tck::Layout l;
    std::vector<float> pos;
    std::vector<uint64_t> off;
};
Parsed parse(const std::string &file) {
    const auto *b = reinterpret_cast<const unsigned char *>(file.data());
    Parsed p;
    p.h = tck::parse_header(b, file.size());
    p.l = tck::scan(b, file.size(), p.h);
    p.pos.resize(3 * p.l.nb_vertices);
    p.off.resize(p.l.nb_streamlines + 1);
    tck::decode(b, p.h, p.l, p.pos.data(), p.off.data());
    return p;
}
std::string header(const std::string &datatype, std::size_t offset_pad = 0) {
    std::string h = "mrtrix tracks    \ncount: 2\ndatatype: " + datatype + "\n";
    const std::size_t off = h.size() + std::string("file: . 000\nEND\n").size() + offset_pad;
    h += "file: . " + std::to_string(off) + "\nEND\n";
    h.resize(off, '\0');
    return h;
}

// The Float32LE scan's bounds are the decoded points' bounds.
void check_bounds(const Parsed &p) {
    REQUIRE(p.l.has_bounds == !p.pos.empty());
    for (std::size_t d = 0; d < 3 && !p.pos.empty(); ++d) {
        float lo = p.pos[d], hi = p.pos[d];
        for (std::size_t i = d; i < p.pos.size(); i += 3) lo = std::min(lo, p.pos[i]), hi = std::max(hi, p.pos[i]);
        CHECK(p.l.lo[d] == lo);
        CHECK(p.l.hi[d] == hi);
    }
}

}  // namespace

TEST_CASE("tck: Float32LE with an empty streamline and trailing spaces in the magic line") {
    const std::string file =
        header("Float32LE") + f32le({1, 2, 3, 4, 5, 6, NaN, NaN, NaN, NaN, NaN, NaN, 7, 8, 9, NaN, NaN, NaN, Inf, Inf, Inf});
    const Parsed p = parse(file);
    REQUIRE(p.l.nb_streamlines == 3);
    REQUIRE(p.l.nb_vertices == 3);
    CHECK(p.off == std::vector<uint64_t>{0, 2, 2, 3});
    CHECK(p.pos == std::vector<float>{1, 2, 3, 4, 5, 6, 7, 8, 9});
}

TEST_CASE("tck: Float64BE is decoded to float32") {
    const double dnan = std::nan(""), dinf = INFINITY;
    const std::string file = header("Float64BE", 5) + f64be({0.5, -1.25, 100.125, dnan, dnan, dnan, dinf, dinf, dinf});
    const Parsed p = parse(file);
    CHECK(p.h.datatype == tck::DataType::Float64BE);
    CHECK(p.pos == std::vector<float>{0.5f, -1.25f, 100.125f});
}

TEST_CASE("tck: negative NaN delimiters and -Inf terminator are accepted") {
    const float nnan = -NaN, ninf = -Inf;
    const Parsed p = parse(header("Float32LE") + f32le({1, 1, 1, nnan, nnan, nnan, ninf, ninf, ninf}));
    CHECK(p.l.nb_streamlines == 1);
}

TEST_CASE("tck: header quirks") {
    SECTION("repeated keys, ':' in values, empty values are kept in order") {
        std::string h = "mrtrix tracks\ncommand_history: a: b\ncommand_history: c\nroi: \ndatatype: Float32LE\nfile: . 200\nEND\n";
        h.resize(200, '\0');
        const Parsed p = parse(h + f32le({Inf, Inf, Inf}));
        REQUIRE(p.h.entries.size() == 5);
        CHECK(p.h.entries[0].second == "a: b");
        CHECK(p.h.entries[2].first == "roi");
        CHECK(p.h.entries[2].second.empty());
        CHECK(p.l.nb_streamlines == 0);
    }
    SECTION("missing datatype and file fields are tolerated with warnings") {
        const Parsed p = parse("mrtrix tracks\nEND\n" + f32le({1, 2, 3, NaN, NaN, NaN, Inf, Inf, Inf}));
        CHECK(p.h.warnings.size() == 2);
        CHECK(p.l.nb_vertices == 1);
    }
    SECTION("count is informative only") {
        std::string h = "mrtrix tracks\ncount: 615000\ndatatype: Float32LE\nfile: . 80\nEND\n";
        h.resize(80, '\0');
        CHECK(parse(h + f32le({1, 2, 3, NaN, NaN, NaN, Inf, Inf, Inf})).l.nb_streamlines == 1);
    }
}

TEST_CASE("tck: malformed files are rejected with a reason") {
    auto rejects = [](const std::string &file, const std::string &needle) {
        try {
            parse(file);
            FAIL("accepted: " << needle);
        } catch (const tck::FormatError &e) {
            CHECK_THAT(e.what(), Catch::Contains(needle));
        }
    };
    rejects("mrtrix trucks\nEND\n", "not a TCK file");
    rejects("mrtrix tracks\ndatatype: Float32LE\n", "no END line");
    rejects("mrtrix tracks\ndatatype: Int32LE\nEND\n", "Int32LE");
    rejects("mrtrix tracks\nfile: other.dat 100\nEND\n", "another file");
    rejects("mrtrix tracks\nfile: . 999999\nEND\n", "past the end");
    rejects("mrtrix tracks\nfile: . 1\nEND\n", "inside the header");
    rejects("mrtrix tracks\nno colon here\nEND\n", "key: value");
    rejects(header("Float32LE") + f32le({1, 2, 3, NaN, 2, 3, NaN, NaN, NaN, Inf, Inf, Inf}), "partial NaN");
    rejects(header("Float32LE") + f32le({1, 2, Inf, NaN, NaN, NaN, Inf, Inf, Inf}), "partial NaN/Inf");
    rejects(header("Float32LE") + f32le({1, 2, 3, NaN, NaN, NaN}), "no 'Inf Inf Inf' terminator");
    rejects(header("Float32LE") + f32le({1, 2, 3, Inf, Inf, Inf}), "not closed by a NaN");
    rejects((header("Float32LE") + f32le({1, 2, 3, NaN, NaN, NaN})).substr(0, header("Float32LE").size() + 17), "truncated");
    rejects("", "empty file");
}

TEST_CASE("tck: every truncation of a valid file is rejected, never accepted as shorter data") {
    const std::string file = header("Float32LE") + f32le({1, 2, 3, 4, 5, 6, NaN, NaN, NaN, 7, 8, 9, NaN, NaN, NaN, Inf, Inf, Inf});
    for (std::size_t cut = 0; cut < file.size(); ++cut) {
        INFO("cut at " << cut);
        CHECK_THROWS_AS(parse(file.substr(0, cut)), tck::FormatError);
    }
    CHECK(parse(file).l.nb_streamlines == 2);
}

TEST_CASE("tck: write then read round-trips, offset stable when the header grows") {
    const auto dir = std::filesystem::temp_directory_path() / ("hz_unit_tck_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::vector<float> pos = {1.5f, -2.25f, 3e5f, 4, 5, 6, 7, 8, 9};
    const std::vector<uint64_t> off = {0, 2, 2, 3};
    for (std::size_t meta_len : {0, 10, 75, 76, 77, 900}) {
        const auto path = (dir / "rt.tck").string();
        tck::write(path, pos.data(), 3, off.data(), 3, {{"comment", std::string(meta_len, 'x')}});
        std::ifstream in(path, std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)), {});
        const Parsed p = parse(bytes);
        CHECK(p.pos == pos);
        CHECK(p.off == off);
        CHECK(p.h.entries.front().second.size() == meta_len);
    }
    std::filesystem::remove_all(dir);
}

TEST_CASE("tck: probe") {
    auto score = [](const std::string &s) { return tck::probe(reinterpret_cast<const unsigned char *>(s.data()), s.size()); };
    CHECK(score("mrtrix tracks\n") == 100);
    CHECK(score("mrtrix tracks    \r\n") == 100);
    CHECK(score("mrtrix tracks") == 80);
    CHECK(score("mrtrix tracksX\n") == 0);
    CHECK(score("mrtrix image\n") == 0);
    CHECK(score("") == 0);
}

TEST_CASE("tck: at every SIMD target, the Float32LE block scan agrees with the generic walk on long streamlines") {
    hz::test::for_each_simd_target([&](const char *) {
        // Streamlines of 0..70 points put delimiters at every position inside the
        // 16-triple blocks; the same data as Float64BE takes the generic walk.
        std::vector<float> xs;
        std::vector<double> xd;
        std::vector<std::uint64_t> lengths;
        for (int s = 0; s < 60; ++s) {
            const int n = (s * 37) % 71;
            lengths.push_back(static_cast<std::uint64_t>(n));
            for (int i = 0; i < 3 * n; ++i) {
                const float v = static_cast<float>(s * 1000 + i) * 0.25f - 300.0f;
                xs.push_back(v), xd.push_back(v);
            }
            for (int k = 0; k < 3; ++k) xs.push_back(NaN), xd.push_back(NaN);
        }
        for (int k = 0; k < 3; ++k) xs.push_back(Inf), xd.push_back(Inf);
        std::string f32, f64;
        for (float f : xs) f32 += f32le({f});
        for (double d : xd) f64 += f64be({d});
        const Parsed a = parse(header("Float32LE") + f32), b = parse(header("Float64BE") + f64);
        REQUIRE(a.l.nb_streamlines == 60);
        CHECK(a.l.nb_vertices == b.l.nb_vertices);
        CHECK(a.off == b.off);
        CHECK(a.pos == b.pos);
        for (std::size_t s = 0; s < lengths.size(); ++s) CHECK(a.off[s + 1] - a.off[s] == lengths[s]);
        check_bounds(a);
        CHECK_FALSE(b.l.has_bounds);  // (only the Float32LE scan finds them)
        // The extremes in every position of a block, data at any byte alignment,
        // and points after the terminator (not data) left out of the bounds.
        for (std::size_t pad : {0, 1, 2, 3})
            for (std::size_t at = 0; at < 48; at += 5) {
                std::vector<float> v = xs;
                std::size_t i = 3 * 16 * 7 + at;
                while (std::isnan(v[i])) ++i;
                v[i] = i % 2 ? 1e30f : -1e30f;
                for (float f : {7e30f, -7e30f, 1.0f}) v.push_back(f);
                std::string file = header("Float32LE", pad);
                for (float f : v) file += f32le({f});
                const Parsed c = parse(file);
                check_bounds(c);
                CHECK(std::max(c.l.hi[i % 3], -c.l.lo[i % 3]) == 1e30f);
            }
        // A partial NaN or an early Inf deep inside a long streamline is still found, with its byte offset.
        for (std::size_t at : {std::size_t(17 * 3 + 1), std::size_t(40 * 3 + 2), std::size_t(1000)}) {
            std::vector<float> bad = xs;
            while (std::isnan(bad[at]) || std::isinf(bad[at])) ++at;
            bad[at] = at % 2 ? NaN : Inf;
            std::string file = header("Float32LE");
            for (float f : bad) file += f32le({f});
            try {
                parse(file);
                FAIL("accepted a partial NaN/Inf triple at value " << at);
            } catch (const tck::FormatError &e) {
                const std::size_t byte = header("Float32LE").size() + 12 * (at / 3);
                CHECK_THAT(e.what(), Catch::Contains("partial NaN/Inf triple at byte " + std::to_string(byte)));
            }
        }
    });
}

TEST_CASE("tck: at every SIMD target, the parallel Float32LE scan and copy span chunks like one sequential walk") {
    hz::test::for_each_simd_target([&](const char *) {
        // 3.2 million triples: four scan chunks of 2^20 triples, several copy
        // chunks, streamlines crossing every chunk boundary. The same data as
        // Float64BE takes the sequential generic walk.
        std::vector<float> xs;
        std::vector<std::uint64_t> lengths;
        std::uint64_t triples = 0;
        for (int s = 0; triples < 3'200'000; ++s) {
            const std::uint64_t n = s % 997 == 0 ? 0 : 1 + (static_cast<std::uint64_t>(s) * 7919) % 4000;
            lengths.push_back(n);
            for (std::uint64_t i = 0; i < 3 * n; ++i) xs.push_back(static_cast<float>((s * 31 + i) % 20011) * 0.01f - 100.0f);
            for (int k = 0; k < 3; ++k) xs.push_back(NaN);
            triples += n + 1;
        }
        for (int k = 0; k < 3; ++k) xs.push_back(Inf);
        auto encode = [](const std::vector<float> &v, bool f64) {
            std::string out = header(f64 ? "Float64BE" : "Float32LE");
            out.reserve(out.size() + v.size() * (f64 ? 8 : 4));
            for (float f : v) out += f64 ? f64be({f}) : f32le({f});
            return out;
        };
        const Parsed a = parse(encode(xs, false)), b = parse(encode(xs, true));
        REQUIRE(a.l.nb_streamlines == lengths.size());
        CHECK(a.l.nb_vertices == b.l.nb_vertices);
        CHECK(a.off == b.off);
        CHECK(a.pos == b.pos);
        for (std::size_t s = 0; s < lengths.size(); s += 101) CHECK(a.off[s + 1] - a.off[s] == lengths[s]);
        check_bounds(a);
        // Points after the terminator, in its chunk and the next, are not data.
        {
            std::vector<float> v = xs;
            for (std::size_t k = 0; k < 3 * (1u << 20); ++k) v.push_back(k % 2 ? 5e3f : -5e3f);
            const Parsed c = parse(encode(v, false));
            CHECK(c.l.nb_vertices == a.l.nb_vertices);
            CHECK(c.l.trailing_bytes == 12 * (1u << 20));
            check_bounds(c);
        }
        // Two faults in different chunks: the first in file order is reported.
        std::vector<float> bad = xs;
        const std::size_t late = 3 * 3'000'000, early = 3 * 1'500'000 + 1;
        for (std::size_t at : {late, early}) {
            std::size_t i = at;
            while (std::isnan(bad[i]) || std::isinf(bad[i])) ++i;
            bad[i] = NaN;
            if (at == early) {
                const std::size_t byte = header("Float32LE").size() + 12 * (i / 3);
                CHECK_THROWS_WITH(parse(encode(bad, false)), Catch::Contains("partial NaN/Inf triple at byte " + std::to_string(byte)));
            }
        }
    });
}
