// The TRK format code on its own: the parallel chunked decode against one
// sequential chunk, the first error in file order, and the vector transform.
#include "trk_format.hpp"
#include "trk_transform.hpp"

#include <catch2/catch.hpp>

#include "simd_targets.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

std::string slurp(const std::string &p) {
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), {});
}

}  // namespace

TEST_CASE(
    "trk: at every SIMD target, the parallel chunked decode equals one sequential chunk, and the first bad point in file order is named") {
    hz::test::for_each_simd_target([&](const char *) {
        // About 40 MB of records: three chunks of 16 MiB, with one scalar column
        // and one property so records are not plain points.
        std::vector<float> pos, scal, prop;
        std::vector<std::uint64_t> off{0};
        for (int s = 0; off.back() < 3'200'000; ++s) {
            const std::uint64_t n = 1 + (static_cast<std::uint64_t>(s) * 7919) % 300;
            for (std::uint64_t i = 0; i < n; ++i) {
                for (int c = 0; c < 3; ++c) pos.push_back(static_cast<float>((s * 13 + i * 3 + c) % 1999) * 0.05f - 50.0f);
                scal.push_back(static_cast<float>(i));
            }
            prop.push_back(static_cast<float>(s));
            off.push_back(off.back() + n);
        }
        const std::uint64_t N = off.size() - 1, V = off.back();
        trk::WriteSpec spec;
        spec.vox_to_ras = {-2, 0, 0, 90, 0, 2, 0, -126, 0, 0, 2, -72, 0, 0, 0, 1};  // LAS, 2 mm
        spec.dims = {91, 109, 91};
        spec.scalars = {{"index", 1}};
        spec.properties = {{"id", 1}};
        spec.scalar_data = scal.data();
        spec.property_data = prop.data();
        const std::string path =
            (std::filesystem::temp_directory_path() / ("hz_unit_trk_chunks_" + std::to_string(::getpid()) + ".trk")).string();
        trk::write(path, pos.data(), V, off.data(), N, spec);
        std::string file = slurp(path);
        std::filesystem::remove(path);

        auto decode = [](const std::string &f, bool one_chunk) {
            const auto *b = reinterpret_cast<const unsigned char *>(f.data());
            const trk::Header h = trk::parse_header(b, f.size());
            trk::Layout l = trk::scan(b, f.size(), h);
            if (one_chunk) l.chunks = {l.chunks.front(), l.chunks.back()};
            std::vector<float> p(3 * l.nb_vertices), sc(l.nb_vertices), pr(l.nb_streamlines);
            std::vector<std::uint64_t> o(l.nb_streamlines + 1);
            trk::decode(b, f.size(), h, l, p.data(), o.data(), sc.data(), pr.data());
            return std::make_tuple(l.chunks.size(), p, o, sc, pr);
        };
        const auto [chunks, p, o, sc, pr] = decode(file, false);
        const auto [chunks1, p1, o1, sc1, pr1] = decode(file, true);
        CHECK(chunks >= 4);  // at least three chunks and the end marker
        CHECK(chunks1 == 2);
        CHECK(o == off);
        CHECK(o1 == off);
        CHECK(p == p1);
        CHECK(sc == scal);
        CHECK(pr == prop);
        for (std::size_t i = 0; i < pos.size(); i += 9973) CHECK(std::fabs(p[i] - pos[i]) < 1e-4f);

        // Non-finite values in the third and the second chunk: the second's is reported.
        auto poison = [&](std::uint64_t streamline) {
            // Record layout: count, then per point x y z + 1 scalar, then 1 property.
            std::uint64_t at = 1000;
            for (std::uint64_t s = 0; s < streamline; ++s) at += 4 + (off[s + 1] - off[s]) * 16 + 4;
            const float nan = NAN;
            std::memcpy(file.data() + at + 4 + 16 + 4, &nan, 4);  // point 1, y
        };
        const std::uint64_t late = N * 9 / 10, early = N / 2;
        poison(late);
        poison(early);
        CHECK_THROWS_WITH(decode(file, false), Catch::Contains("streamline " + std::to_string(early) + " point 1 has a non-finite"));
    });
}

TEST_CASE(
    "trk: at every SIMD target, the vector transform of scalar-free points equals the scalar formula bit for bit, and non-finite input is "
    "flagged") {
    hz::test::for_each_simd_target([&](const char *) {
        // An oblique affine with a translation, every length 0..40 (vector body
        // and scalar tail), points at an offset of one float (unaligned vectors).
        const double A[16] = {0.9, -0.31, 0.2, -90.25, 0.27, 1.1, -0.05, 126.5, -0.12, 0.08, 2.03, -72.125, 0, 0, 0, 1};
        std::vector<float> in(1 + 3 * 40), out(3 * 40 + 1);
        for (std::size_t i = 0; i < in.size(); ++i) in[i] = static_cast<float>(std::sin(double(i) * 12.9898) * 180.0);
        for (std::uint64_t n = 0; n <= 40; ++n) {
            std::fill(out.begin(), out.end(), -1.0f);
            float lo[3] = {HUGE_VALF, HUGE_VALF, HUGE_VALF}, hi[3] = {-HUGE_VALF, -HUGE_VALF, -HUGE_VALF};
            REQUIRE(trk::detail::transform_points(in.data() + 1, n, A, out.data(), lo, hi));
            float want_lo[3] = {HUGE_VALF, HUGE_VALF, HUGE_VALF}, want_hi[3] = {-HUGE_VALF, -HUGE_VALF, -HUGE_VALF};
            for (std::uint64_t i = 0; i < n; ++i)
                for (int r = 0; r < 3; ++r) {
                    const float *p = in.data() + 1 + 3 * i;
                    const float want = static_cast<float>(A[4 * r] * double(p[0]) + A[4 * r + 1] * double(p[1]) +
                                                          A[4 * r + 2] * double(p[2]) + A[4 * r + 3]);
                    REQUIRE(std::memcmp(&out[3 * i + r], &want, 4) == 0);
                    want_lo[r] = std::min(want_lo[r], want);
                    want_hi[r] = std::max(want_hi[r], want);
                }
            REQUIRE(out[3 * n] == -1.0f);  // nothing written past the n points
            for (int r = 0; r < 3; ++r) {  // the bounds of what it wrote
                REQUIRE(lo[r] == want_lo[r]);
                REQUIRE(hi[r] == want_hi[r]);
            }
        }
        // The bounds with the extreme point at every position (vector lanes and
        // tail), and merged with the bounds passed in.
        for (std::uint64_t at = 0; at < 40; ++at)
            for (const float big : {1e6f, -1e6f}) {
                std::vector<float> v(in.begin() + 1, in.end());
                v[3 * at] = v[3 * at + 1] = v[3 * at + 2] = big;
                float lo[3] = {HUGE_VALF, HUGE_VALF, HUGE_VALF}, hi[3] = {-HUGE_VALF, -HUGE_VALF, -HUGE_VALF};
                REQUIRE(trk::detail::transform_points(v.data(), 40, A, out.data(), lo, hi));
                for (int r = 0; r < 3; ++r) {
                    const float e = out[3 * at + r];
                    REQUIRE((e == lo[r] || e == hi[r]));
                    float mn = HUGE_VALF, mx = -HUGE_VALF;
                    for (int i = 0; i < 40; ++i) {
                        mn = std::min(mn, out[3 * i + r]);
                        mx = std::max(mx, out[3 * i + r]);
                    }
                    REQUIRE((lo[r] == mn && hi[r] == mx));
                }
                float lo2[3] = {-1e30f, -1e30f, -1e30f}, hi2[3] = {1e30f, 1e30f, 1e30f};
                REQUIRE(trk::detail::transform_points(v.data(), 40, A, out.data(), lo2, hi2));
                for (int r = 0; r < 3; ++r) REQUIRE((lo2[r] == -1e30f && hi2[r] == 1e30f));
            }
        for (const float bad : {NAN, INFINITY, -INFINITY})
            for (std::uint64_t at : {0, 3 * 17 + 2, 3 * 39 + 1}) {  // in the vector body and in the tail
                std::vector<float> v(in.begin() + 1, in.end());
                v[at] = bad;
                float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
                REQUIRE_FALSE(trk::detail::transform_points(v.data(), 40, A, out.data(), lo, hi));
            }
    });
}

TEST_CASE("trk: the record walk in many chains gives exactly the single walk's layout and first error") {
    // Files of a few thousand records (0-39 points; exact zeros among the
    // coordinates, so that guessed chains can walk runs of zeros as empty
    // records and be wrong), with and without scalars and properties, then
    // spoiled: n_count 0, short of the records, past them; trailing bytes;
    // truncation; a negative or huge count. Every plan of chains and threads
    // must give the single walk's streamlines, points and error, and every
    // run start it gives must be a true record start.
    std::uint64_t seed = 12345;
    auto rnd = [&]() {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        return static_cast<std::uint32_t>(seed >> 33);
    };
    for (const auto &[ns, np] : {std::pair{0, 0}, std::pair{2, 0}, std::pair{0, 1}, std::pair{1, 2}}) {
        trk::WriteSpec spec;
        spec.vox_to_ras = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        spec.dims = {100, 100, 100};
        std::vector<float> one_pos = {1, 2, 3}, one_s(static_cast<std::size_t>(ns), 0.0f), one_p(static_cast<std::size_t>(np), 0.0f);
        std::vector<std::uint64_t> one_off = {0, 1};
        if (ns) spec.scalars = {{"s", static_cast<std::uint32_t>(ns)}};
        if (np) spec.properties = {{"p", static_cast<std::uint32_t>(np)}};
        spec.scalar_data = one_s.data();
        spec.property_data = one_p.data();
        const std::string path =
            (std::filesystem::temp_directory_path() / ("hz_unit_trk_chains_" + std::to_string(::getpid()) + ".trk")).string();
        trk::write(path, one_pos.data(), 1, one_off.data(), 1, spec);
        const std::string header = slurp(path).substr(0, 1000);
        std::filesystem::remove(path);
        // Records, and where each starts (with the records and points before it).
        std::string body;
        std::vector<trk::Chunk> starts;
        std::uint64_t V = 0;
        const std::uint64_t N = 3000 + rnd() % 2000;
        for (std::uint64_t s = 0; s < N; ++s) {
            starts.push_back({s, 1000 + body.size(), V});
            const std::int32_t n = rnd() % 4 == 0 ? 0 : static_cast<std::int32_t>(rnd() % 40);
            body.append(reinterpret_cast<const char *>(&n), 4);
            for (std::int32_t i = 0; i < n * (3 + ns) + np; ++i) {
                const float v = rnd() % 3 == 0 ? 0.0f : static_cast<float>(rnd() % 20000) * 0.01f - 100.0f;
                body.append(reinterpret_cast<const char *>(&v), 4);
            }
            V += static_cast<std::uint64_t>(n);
        }
        starts.push_back({N, 1000 + body.size(), V});
        auto with_count = [&](std::int32_t count, const std::string &b) {
            std::string f = header + b;
            std::memcpy(f.data() + 988, &count, 4);
            return f;
        };
        std::vector<std::pair<std::string, std::string>> files = {
            {"exact n_count", with_count(static_cast<std::int32_t>(N), body)},
            {"n_count 0", with_count(0, body)},
            {"n_count short", with_count(static_cast<std::int32_t>(N / 2), body)},
            {"n_count past the records", with_count(static_cast<std::int32_t>(N + 5), body)},
            {"trailing bytes, n_count 0", with_count(0, body + std::string(4097, '\x7f'))},
            {"trailing bytes, exact n_count", with_count(static_cast<std::int32_t>(N), body + std::string(4097, '\x7f'))},
        };
        for (int k = 0; k < 4; ++k) {
            const std::size_t cut = 1 + rnd() % (body.size() - 1);
            files.push_back({"truncated at " + std::to_string(cut), with_count(0, body.substr(0, cut))});
            const std::uint64_t r = rnd() % N;
            std::string bad = body;
            const std::int32_t v = k % 2 ? -7 : 1 << 30;
            std::memcpy(bad.data() + (starts[r].byte - 1000), &v, 4);
            files.push_back({"count " + std::to_string(v) + " at record " + std::to_string(r), with_count(0, bad)});
            files.push_back({"count " + std::to_string(v) + " at record " + std::to_string(r) + " past n_count " + std::to_string(r),
                             with_count(static_cast<std::int32_t>(std::max<std::uint64_t>(r, 1)), bad)});
        }
        for (const auto &[what, f] : files) {
            INFO(what << " (scalars " << ns << ", properties " << np << ")");
            const auto *b = reinterpret_cast<const unsigned char *>(f.data());
            const trk::Header h = trk::parse_header(b, f.size());
            auto walk = [&](trk::ScanPlan plan, trk::Layout &l) -> std::string {
                try {
                    l = trk::scan(b, f.size(), h, {}, plan);
                    return "";
                } catch (const trk::FormatError &e) {
                    return e.what();
                }
            };
            // The single walk, spelled out here as the format defines it.
            std::string want_error;
            std::uint64_t want_n = 0, want_v = 0, pos = 1000;
            const std::uint64_t point_bytes = 4u * (3 + ns), limit = h.n_count > 0 ? std::uint64_t(h.n_count) : UINT64_MAX;
            while (want_n < limit && pos != f.size()) {
                const std::string who = "streamline " + std::to_string(want_n);
                if (f.size() - pos < 4) {
                    want_error = who + ": point count cut off at byte " + std::to_string(pos);
                    break;
                }
                std::int32_t n;
                std::memcpy(&n, f.data() + pos, 4);
                const std::uint64_t left = f.size() - pos - 4;
                if (n < 0 || std::uint64_t(n) * point_bytes + 4u * np > left) {
                    want_error = who + " declares " + std::to_string(n) + " points" +
                                 (n < 0 ? "" : " but only " + std::to_string(left) + " bytes remain (file truncated?)");
                    break;
                }
                pos += 4 + std::uint64_t(n) * point_bytes + 4u * np;
                ++want_n;
                want_v += std::uint64_t(n);
            }
            if (want_error.empty() && limit != UINT64_MAX && want_n < limit)
                want_error = "header n_count is " + std::to_string(h.n_count) + " but the file holds " + std::to_string(want_n) +
                             " streamlines (truncated?)";
            trk::Layout ref;
            const std::string ref_error = walk({1, 1}, ref);
            REQUIRE(ref_error == want_error);
            if (ref_error.empty()) {
                REQUIRE(ref.nb_streamlines == want_n);
                REQUIRE(ref.nb_vertices == want_v);
                REQUIRE(ref.chunks.back().byte == pos);
            }
            for (const trk::ScanPlan plan : {trk::ScanPlan{2, 1}, trk::ScanPlan{3, 2}, trk::ScanPlan{8, 2}, trk::ScanPlan{16, 2},
                                             trk::ScanPlan{61, 2}, trk::ScanPlan{200, 1}}) {
                INFO(plan.chains << " chains on " << plan.threads << " threads");
                trk::Layout l;
                const std::string error = walk(plan, l);
                REQUIRE(error == ref_error);
                if (!error.empty()) continue;
                REQUIRE(l.nb_streamlines == ref.nb_streamlines);
                REQUIRE(l.nb_vertices == ref.nb_vertices);
                REQUIRE(l.chunks.front().byte == 1000);
                REQUIRE(l.chunks.back().streamline == l.nb_streamlines);
                REQUIRE(l.chunks.back().vertex == l.nb_vertices);
                REQUIRE(l.chunks.back().byte == ref.chunks.back().byte);
                for (std::size_t c = 0; c < l.chunks.size(); ++c) {
                    const trk::Chunk &k = l.chunks[c];
                    if (c > 0) REQUIRE(k.byte > l.chunks[c - 1].byte);
                    REQUIRE(k.streamline < starts.size());
                    REQUIRE(k.byte == starts[k.streamline].byte);
                    REQUIRE(k.vertex == starts[k.streamline].vertex);
                }
            }
        }
    }
}
