// TrackVis TRK v1/v2 (TrackVis file format documentation; nibabel trk.py for
// the voxmm -> RAS+ mm convention and the name encoding of scalar columns).
#include "trk_format.hpp"

#include "parallel.hpp"
#include "trk_transform.hpp"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <atomic>
#include <limits>
#include <thread>

namespace trk {

namespace {

constexpr std::uint64_t kHeaderSize = 1000;

inline std::uint32_t bswap(std::uint32_t v) { return __builtin_bswap32(v); }
inline std::uint16_t bswap(std::uint16_t v) { return __builtin_bswap16(v); }

template <class T>
T load(const unsigned char *p, bool swap) {
    using U = std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint16_t>;
    U u;
    std::memcpy(&u, p, sizeof u);
    if (swap) u = bswap(u);
    return std::bit_cast<T>(u);
}
template <class T>
void store(unsigned char *p, T v) {  // little-endian file output
    using U = std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint16_t>;
    U u = std::bit_cast<U>(v);
    if constexpr (std::endian::native == std::endian::big) u = bswap(u);
    std::memcpy(p, &u, sizeof u);
}
constexpr bool kBigHost = std::endian::native == std::endian::big;

Mat4 identity() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }

Mat4 mul(const Mat4 &a, const Mat4 &b) {
    Mat4 c{};
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double s = 0;
            for (int k = 0; k < 4; ++k) s += a[4 * i + k] * b[4 * k + j];
            c[4 * i + j] = s;
        }
    return c;
}

// Orientation of each voxel axis: (RAS axis, +1/-1), nibabel's "ornt".
struct Ornt {
    int axis[3];
    int flip[3];
};

Ornt ornt_from_codes(const std::string &codes) {
    static const char *labels[3] = {"LR", "PA", "IS"};
    Ornt o{};
    bool used[3] = {false, false, false};
    for (int i = 0; i < 3; ++i) {
        const char c = codes[static_cast<std::size_t>(i)];
        int found = -1;
        for (int j = 0; j < 3; ++j)
            if (c == labels[j][0] || c == labels[j][1]) found = j;
        if (found < 0 || used[found]) throw FormatError("voxel_order '" + codes + "' is not a permutation of L/R, P/A, I/S");
        used[found] = true;
        o.axis[i] = found;
        o.flip[i] = c == labels[found][0] ? -1 : 1;
    }
    return o;
}

// nibabel's inv_ornt_aff(ornt_transform(from, to), dims).
Mat4 reorient(const Ornt &from, const Ornt &to, const std::int16_t dims[3]) {
    int axis[3], flip[3];
    for (int e = 0; e < 3; ++e)
        for (int s = 0; s < 3; ++s)
            if (to.axis[e] == from.axis[s]) {
                axis[s] = e;
                flip[s] = from.flip[s] == to.flip[e] ? 1 : -1;
            }
    Mat4 undo_reorder{};
    for (int i = 0; i < 3; ++i) undo_reorder[4 * i + axis[i]] = 1;
    undo_reorder[15] = 1;
    Mat4 undo_flip = identity();
    for (int i = 0; i < 3; ++i) {
        const double c = -(double(dims[i]) - 1) / 2.0;
        undo_flip[4 * i + i] = flip[i];
        undo_flip[4 * i + 3] = flip[i] * c - c;
    }
    return mul(undo_flip, undo_reorder);
}

std::vector<Column> decode_names(const unsigned char *p, std::uint32_t total, const char *what, const char *rest) {
    std::vector<Column> cols;
    std::uint32_t used = 0;
    for (int k = 0; k < 10; ++k) {
        const char *s = reinterpret_cast<const char *>(p + 20 * k);
        std::string field(s, 20);
        while (!field.empty() && field.back() == '\0') field.pop_back();
        if (field.empty()) continue;
        const auto nul = field.find('\0');
        Column c;
        c.name = field.substr(0, nul);
        if (nul != std::string::npos) {
            const std::string num = field.substr(nul + 1);
            if (num.empty() || num.size() > 3 || !std::all_of(num.begin(), num.end(), ::isdigit))
                throw FormatError(std::string(what) + " name " + std::to_string(k) +
                                  " has bytes after its NUL that are not a column count");
            c.count = static_cast<std::uint32_t>(std::stoi(num));
        }
        if (c.count == 0) continue;
        used += c.count;
        cols.push_back(c);
    }
    if (used > total)
        throw FormatError(std::string(what) + " names describe " + std::to_string(used) + " columns but the header declares " +
                          std::to_string(total));
    if (used < total) cols.push_back({rest, total - used});
    return cols;
}

}  // namespace

std::string axcodes(const Mat4 &a) {
    // Columns of the 3x3 part, normalised; greedily assign the largest
    // remaining component (nibabel's io_orientation for non-degenerate affines).
    double m[3][3];
    for (int j = 0; j < 3; ++j) {
        double n = 0;
        for (int i = 0; i < 3; ++i) n += a[4 * i + j] * a[4 * i + j];
        n = std::sqrt(n);
        for (int i = 0; i < 3; ++i) m[i][j] = n > 0 ? a[4 * i + j] / n : 0;
    }
    static const char *labels[3] = {"LR", "PA", "IS"};
    std::string codes = "???";
    bool row_used[3] = {false, false, false}, col_used[3] = {false, false, false};
    for (int step = 0; step < 3; ++step) {
        int bi = -1, bj = -1;
        double best = -1;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                if (!row_used[i] && !col_used[j] && std::fabs(m[i][j]) > best) best = std::fabs(m[i][j]), bi = i, bj = j;
        row_used[bi] = col_used[bj] = true;
        codes[static_cast<std::size_t>(bj)] = labels[bi][m[bi][bj] >= 0 ? 1 : 0];
    }
    return codes;
}

int probe(const unsigned char *head, std::uint64_t size) {
    if (size < 6 || std::memcmp(head, "TRACK", 5) != 0) return 0;
    if (size >= kHeaderSize) {
        const auto hs = load<std::int32_t>(head + 996, false);
        const auto hs_swapped = load<std::int32_t>(head + 996, true);
        return hs == 1000 || hs_swapped == 1000 ? 100 : 10;
    }
    return 60;  // magic only: the probe window ends before hdr_size
}

Header parse_header(const unsigned char *b, std::uint64_t size) {
    if (size < kHeaderSize) throw FormatError("file is " + std::to_string(size) + " bytes, shorter than the 1000-byte TrackVis header");
    if (std::memcmp(b, "TRACK", 5) != 0) throw FormatError("no 'TRACK' magic at offset 0 (not a TrackVis file)");
    Header h;
    const auto hs = load<std::int32_t>(b + 996, false);
    if (hs == 1000)
        h.swap = false;
    else if (load<std::int32_t>(b + 996, true) == 1000)
        h.swap = true;
    else
        throw FormatError("hdr_size at offset 996 is " + std::to_string(hs) + ", expected 1000 (truncated or not TrackVis)");
    const bool sw = h.swap;
    for (int i = 0; i < 3; ++i) {
        h.dim[i] = load<std::int16_t>(b + 6 + 2 * i, sw);
        h.voxel_size[i] = load<float>(b + 12 + 4 * i, sw);
        if (!(std::isfinite(h.voxel_size[i]) && h.voxel_size[i] > 0))
            throw FormatError("voxel_size[" + std::to_string(i) + "] = " + std::to_string(h.voxel_size[i]) + " is not a positive number");
        if (h.dim[i] < 0) throw FormatError("dim[" + std::to_string(i) + "] = " + std::to_string(h.dim[i]) + " is negative");
    }
    const auto ns = load<std::int16_t>(b + 36, sw), np = load<std::int16_t>(b + 238, sw);
    if (ns < 0 || np < 0) throw FormatError("negative n_scalars or n_properties");
    h.n_scalars = static_cast<std::uint32_t>(ns);
    h.n_properties = static_cast<std::uint32_t>(np);
    h.scalars = decode_names(b + 38, h.n_scalars, "scalar", "scalars");
    h.properties = decode_names(b + 240, h.n_properties, "property", "properties");
    h.version = load<std::int32_t>(b + 992, sw);
    h.vox_to_ras = identity();
    if (h.version == 2 || h.version == 3) {
        if (h.version == 3) h.warnings.emplace_back("version 3 read as version 2");
        Mat4 m;
        for (int i = 0; i < 16; ++i) m[static_cast<std::size_t>(i)] = load<float>(b + 440 + 4 * i, sw);
        for (double v : m)
            if (!std::isfinite(v)) throw FormatError("vox_to_ras holds a non-finite value");
        if (m[15] != 0) {  // [3][3] == 0: not recorded
            // A singular matrix would collapse every point (nibabel refuses it too).
            const double det =
                m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) + m[2] * (m[4] * m[9] - m[5] * m[8]);
            if (!(std::abs(det) > 1e-12))
                throw FormatError("vox_to_ras is singular (its 3x3 part has determinant " + std::to_string(det) + ")");
            h.vox_to_ras = m;
        }
    } else if (h.version != 1) {
        throw FormatError("version " + std::to_string(h.version) + " is not 1 or 2");
    }
    std::string order(reinterpret_cast<const char *>(b + 948), 4);
    order.erase(std::find(order.begin(), order.end(), '\0'), order.end());
    std::transform(order.begin(), order.end(), order.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
    while (!order.empty() && order.back() == ' ') order.pop_back();
    if (order.empty()) order = "LPS";  // TrackVis's default
    if (order.size() != 3) throw FormatError("voxel_order '" + order + "' is not three letters");
    h.voxel_order = order;
    h.n_count = load<std::int32_t>(b + 988, sw);
    if (h.n_count < 0) throw FormatError("n_count = " + std::to_string(h.n_count) + " is negative");

    // voxmm -> RAS+ mm: scale to voxels, shift the corner origin to voxel
    // centres, reorient voxel_order onto the affine's orientation, apply it.
    Mat4 a = identity();
    for (int i = 0; i < 3; ++i) a[4 * i + i] = 1.0 / h.voxel_size[i];
    Mat4 offset = identity();
    for (int i = 0; i < 3; ++i) offset[4 * i + 3] = -0.5;
    a = mul(offset, a);
    const Ornt header_ornt = ornt_from_codes(order);
    const Ornt affine_ornt = ornt_from_codes(axcodes(h.vox_to_ras));
    a = mul(reorient(header_ornt, affine_ornt, h.dim), a);
    h.to_rasmm = mul(h.vox_to_ras, a);
    return h;
}

// ---- The record walk ----
//
// A TRK file is a chain of records (a point count, the points, the
// properties), and where a record starts is known only from the one before
// it. Walked from the header alone, the chain costs a dependent cache miss
// and, every few records, a page fault per streamline: 0.14 s of a 0.5 s
// load of 1M streamlines (1.2 GB). So the walk runs as several chains at
// once: chain 0 from the header, every other one from a guessed record
// start in its share of the file (the first 4-byte position from which
// kPlausible records in a row are well-formed). One thread advances its
// chains in turn, one record each, so their cache misses overlap, and the
// chains are split over two threads. Each chain records the starts of its
// first kPrefix records; the chain before it, on reaching them, either meets
// it at one (a position determines every record after it, so from there
// the later chain's walk is the true one) or passes them all and goes on
// itself (the guess was wrong: only time is lost). The assembly follows the
// true path through the chains, so the result and the first error are
// exactly those of the single walk.

namespace {

constexpr std::uint64_t kChunkBytes = 16u << 20;
constexpr std::size_t kPrefix = 1024, kPlausible = 16;

enum class Fault : std::uint8_t { None, CutOff, Negative, TooLong };

struct Walker {
    const unsigned char *b;
    std::uint64_t size, point_bytes, prop_bytes;
    bool swap;
    // The record at `pos` (< size): advances pos past it and returns its
    // point count in n, or the fault.
    Fault step(std::uint64_t &pos, std::int32_t &n) const {
        if (size - pos < 4) return Fault::CutOff;
        n = load<std::int32_t>(b + pos, swap);
        if (n < 0) return Fault::Negative;
        const std::uint64_t left = size - pos - 4;
        if (static_cast<std::uint64_t>(n) > left / point_bytes || std::uint64_t(n) * point_bytes + prop_bytes > left) return Fault::TooLong;
        pos += 4 + std::uint64_t(n) * point_bytes + prop_bytes;
        return Fault::None;
    }
    std::string message(Fault f, std::uint64_t s, std::uint64_t pos, std::int32_t n) const {
        const std::string who = "streamline " + std::to_string(s);
        if (f == Fault::CutOff) return who + ": point count cut off at byte " + std::to_string(pos);
        if (f == Fault::Negative) return who + " declares " + std::to_string(n) + " points";
        return who + " declares " + std::to_string(n) + " points but only " + std::to_string(size - pos - 4) +
               " bytes remain (file truncated?)";
    }
};

struct Hop {
    std::uint64_t pos, s, v;  // a record start, and the records and points before it in its chain
};

struct Chain {
    enum State : std::uint8_t { Walking, Ended, Failed, Joined };
    // Its first record: kUnplaced until its thread has found one, 0 when there
    // is none (read by the chain before it, maybe on the other thread).
    static constexpr std::uint64_t kUnplaced = UINT64_MAX;
    std::atomic<std::uint64_t> start{kUnplaced};
    std::uint64_t pos = 0, s = 0, v = 0;  // s, v: records and points walked from `start`
    State state = Walking;
    Fault fault = Fault::None;
    std::int32_t fault_n = 0;
    std::vector<Hop> prefix;               // its first kPrefix record starts
    std::atomic<bool> prefix_done{false};  // (published to the chain before it, maybe on the other thread)
    std::vector<Chunk> chunks;             // chain-relative starts of runs of about kChunkBytes
    std::size_t target = 0;                // the chain this one is to meet
    std::size_t next_hop = 0;              // the first of the target's prefix not yet passed
    std::size_t join_at = 0;               // Joined: where, in the target's prefix
    // Stops, publishing its prefix.
    void stop(State st) {
        state = st;
        prefix_done.store(true, std::memory_order_release);
    }
};

}  // namespace

Layout scan(const unsigned char *b, std::uint64_t size, const Header &h, const Tick &cancelled, ScanPlan plan) {
    const Walker w{b, size, 4ull * (3 + h.n_scalars), 4ull * h.n_properties, h.swap};
    const std::uint64_t want = h.n_count > 0 ? static_cast<std::uint64_t>(h.n_count) : UINT64_MAX;
    // Chains and threads: one of each below 64 MiB of records.
    const unsigned threads = std::max(1u, plan.threads ? plan.threads : std::min(2u, std::max(1u, std::thread::hardware_concurrency())));
    unsigned K = plan.chains ? plan.chains : (size - kHeaderSize < (64u << 20) ? 1u : 8u * threads);
    K = static_cast<unsigned>(std::min<std::uint64_t>(K, std::max<std::uint64_t>(1, (size - kHeaderSize) / 4)));
    const unsigned T = std::min(threads, K);
    std::vector<Chain> chains(K);
    for (unsigned i = 0; i < K; ++i) chains[i].target = i + 1;
    std::atomic<bool> stop{false};

    // The chains of thread t: [K t / T, K (t + 1) / T).
    auto run = [&](unsigned t) {
        const unsigned c0 = K * t / T, c1 = K * (t + 1) / T;
        for (unsigned i = c0; i < c1; ++i) {
            Chain &ch = chains[i];
            std::uint64_t g = kHeaderSize + (size - kHeaderSize) / K * i / 4 * 4;
            if (i > 0) {  // the first plausible record start at or after g (within 1 MiB)
                const std::uint64_t limit = std::min(size, g + (1u << 20));
                bool found = false;
                for (; g < limit && !found; g += 4) {
                    std::uint64_t pos = g;
                    std::int32_t n = 0;
                    std::size_t k = 0;
                    while (k < kPlausible && pos < size && w.step(pos, n) == Fault::None) ++k;
                    found = k == kPlausible || pos == size;
                }
                if (!found) {  // no chain here: the one before passes it at once
                    ch.stop(Chain::Ended);
                    ch.start.store(0, std::memory_order_release);
                    continue;
                }
                g -= 4;
            }
            ch.pos = g;
            ch.chunks.push_back({0, g, 0});
            ch.prefix.reserve(kPrefix);
            ch.start.store(g, std::memory_order_release);
        }
        std::uint64_t rounds = 0;
        for (bool active = true; active && !stop.load(std::memory_order_relaxed);) {
            active = false;
            bool moved = false;
            for (unsigned i = c0; i < c1; ++i) {
                Chain &ch = chains[i];
                if (ch.state != Chain::Walking) continue;
                active = true;
                // Meeting the chain after it.
                bool wait = false;
                while (ch.target < K) {
                    Chain &nx = chains[ch.target];
                    if (ch.pos < nx.start.load(std::memory_order_acquire)) break;  // (or not placed yet)
                    if (!nx.prefix_done.load(std::memory_order_acquire)) {         // its prefix is not known yet: wait
                        wait = true;
                        break;
                    }
                    while (ch.next_hop < nx.prefix.size() && nx.prefix[ch.next_hop].pos < ch.pos) ++ch.next_hop;
                    if (ch.next_hop < nx.prefix.size() && nx.prefix[ch.next_hop].pos == ch.pos) {
                        ch.join_at = ch.next_hop;
                        ch.stop(Chain::Joined);
                        break;
                    }
                    if (ch.next_hop < nx.prefix.size()) break;  // not there yet
                    ++ch.target;                                // passed them all: that chain's guess was wrong; aim at the next one
                    ch.next_hop = 0;
                }
                if (ch.state == Chain::Joined || wait) continue;
                moved = true;
                if (ch.pos == size) {
                    ch.stop(Chain::Ended);
                    continue;
                }
                if (ch.prefix.size() < kPrefix) {
                    ch.prefix.push_back({ch.pos, ch.s, ch.v});
                    if (ch.prefix.size() == kPrefix) ch.prefix_done.store(true, std::memory_order_release);
                }
                if (ch.pos - ch.chunks.back().byte >= kChunkBytes) ch.chunks.push_back({ch.s, ch.pos, ch.v});
                std::int32_t n = 0;
                const std::uint64_t at = ch.pos;
                const Fault f = w.step(ch.pos, n);
                if (f != Fault::None) {
                    ch.fault = f;
                    ch.fault_n = n;
                    ch.pos = at;
                    ch.stop(Chain::Failed);
                    continue;
                }
                ++ch.s;
                ch.v += static_cast<std::uint64_t>(n);
            }
            // (Every chain moves one record a round: chain c0's share of its
            // stretch is the whole scan's, given to `cancelled` as a file position.)
            if (t == 0 && (++rounds & 0x3FFF) == 0 && cancelled &&
                cancelled(std::min<std::uint64_t>(size, kHeaderSize + (chains[c0].pos - std::min(chains[c0].pos, kHeaderSize)) * K)))
                stop.store(true, std::memory_order_relaxed);
            if (active && !moved) std::this_thread::yield();
        }
    };
    {
        std::vector<std::thread> pool;
        for (unsigned t = 1; t < T; ++t) pool.emplace_back(run, t);
        run(0);
        for (auto &th : pool) th.join();
    }
    if (stop.load()) throw Cancelled{};

    // The true path: chain 0, and from each Joined chain on into its target.
    Layout l;
    l.chunks.push_back({0, kHeaderSize, 0});
    std::size_t c = 0;
    std::uint64_t rs = 0, rv = 0, entry = kHeaderSize;  // where the path enters chain c (chain-relative counts)
    std::uint64_t abs_s = 0, abs_v = 0;                 // the same, counted from the header
    for (;;) {
        const Chain &ch = chains[c];
        const std::uint64_t off_s = abs_s - rs, off_v = abs_v - rv;  // (modulo 2^64: chain-relative + off = absolute)
        if (entry != l.chunks.back().byte) l.chunks.push_back({abs_s, entry, abs_v});
        for (const Chunk &k : ch.chunks)
            if (k.byte > entry) l.chunks.push_back({k.streamline + off_s, k.byte, k.vertex + off_v});
        abs_s = ch.s + off_s;
        abs_v = ch.v + off_v;
        if (ch.state != Chain::Joined) break;
        const Hop &hp = chains[ch.target].prefix[ch.join_at];
        rs = hp.s;
        rv = hp.v;
        entry = hp.pos;
        c = ch.target;
    }
    const Chain &last = chains[c];
    const bool failed = last.state == Chain::Failed;
    if (want != UINT64_MAX && (abs_s > want || (failed && abs_s >= want))) {
        // The walk stops after n_count records: cut there (from the last run start before it).
        while (l.chunks.back().streamline > want) l.chunks.pop_back();
        Chunk k = l.chunks.back();
        while (k.streamline < want) {
            std::int32_t n = 0;
            if (w.step(k.byte, n) != Fault::None) throw FormatError("file changed while reading");
            ++k.streamline;
            k.vertex += static_cast<std::uint64_t>(n);
        }
        if (l.chunks.back().streamline == want) l.chunks.pop_back();
        l.chunks.push_back(k);
        l.nb_streamlines = k.streamline;
        l.nb_vertices = k.vertex;
        return l;
    }
    if (failed) throw FormatError(w.message(last.fault, abs_s, last.pos, last.fault_n));
    if (want != UINT64_MAX && abs_s < want)
        throw FormatError("header n_count is " + std::to_string(h.n_count) + " but the file holds " + std::to_string(abs_s) +
                          " streamlines (truncated?)");
    if (l.chunks.back().byte == last.pos) l.chunks.pop_back();
    l.chunks.push_back({abs_s, last.pos, abs_v});
    l.nb_streamlines = abs_s;
    l.nb_vertices = abs_v;
    return l;
}

namespace {

// One chunk of records; Swap: the file's byte order is not the host's.
template <bool Swap>
void decode_chunk(const unsigned char *b, const Header &h, const Chunk &from, const Chunk &to, float *positions, std::uint64_t *offsets,
                  float *scalars, float *properties, Box &box) {
    const Mat4 &A = h.to_rasmm;
    const std::uint32_t ns = h.n_scalars, np = h.n_properties;
    const std::uint64_t point_bytes = 4ull * (3 + ns);
    std::uint64_t pos = from.byte, v = from.vertex;
    for (std::uint64_t s = from.streamline; s < to.streamline; ++s) {
        const auto n = static_cast<std::uint64_t>(load<std::int32_t>(b + pos, Swap));
        pos += 4;
        const unsigned char *rec = b + pos;
        if (positions) {
            // Branch-free over the streamline (vectorisable); locate a bad value only on failure.
            unsigned bad = 0;
            float *out = positions + 3 * v;
            if (!Swap && ns == 0) {  // contiguous xyz triples: the vector kernel, same values
                bad = !detail::transform_points(reinterpret_cast<const float *>(rec), n, A.data(), out, box.lo, box.hi);
            } else
                for (std::uint64_t i = 0; i < n; ++i) {
                    const unsigned char *p = rec + i * point_bytes;
                    const float x = load<float>(p, Swap), y = load<float>(p + 4, Swap), z = load<float>(p + 8, Swap);
                    bad |= unsigned(!(std::fabs(x) <= 3.4028235e38f)) | unsigned(!(std::fabs(y) <= 3.4028235e38f)) |
                           unsigned(!(std::fabs(z) <= 3.4028235e38f));
                    for (int r = 0; r < 3; ++r) {
                        const float o = static_cast<float>(A[4 * r] * x + A[4 * r + 1] * y + A[4 * r + 2] * z + A[4 * r + 3]);
                        out[3 * i + r] = o;
                        box.lo[r] = std::min(box.lo[r], o);
                        box.hi[r] = std::max(box.hi[r], o);
                    }
                }
            if (bad)
                for (std::uint64_t i = 0; i < n; ++i)
                    for (int c = 0; c < 3; ++c)
                        if (!std::isfinite(load<float>(rec + i * point_bytes + 4 * c, Swap)))
                            throw FormatError("streamline " + std::to_string(s) + " point " + std::to_string(i) +
                                              " has a non-finite coordinate");
        }
        if (scalars)
            for (std::uint64_t i = 0; i < n; ++i)
                for (std::uint32_t k = 0; k < ns; ++k) scalars[(v + i) * ns + k] = load<float>(rec + i * point_bytes + 12 + 4 * k, Swap);
        pos += n * point_bytes;
        v += n;
        for (std::uint32_t k = 0; k < np; ++k, pos += 4)
            if (properties) properties[s * np + k] = load<float>(b + pos, Swap);
        if (offsets) offsets[s + 1] = v;
    }
}

}  // namespace

void decode(const unsigned char *b, std::uint64_t, const Header &h, const Layout &l, float *positions, std::uint64_t *offsets,
            float *scalars, float *properties, const Tick &cancelled, const Release &release, Box *box) {
    if (offsets) offsets[0] = 0;
    if (l.chunks.size() < 2) return;
    std::vector<Box> boxes(l.chunks.size() - 1);  // each chunk's, merged in the end
    std::atomic<std::uint64_t> decoded{0};        // vertices, for the progress `cancelled` is given
    const bool done = hzio::parallel_chunks(
        l.chunks.size() - 1,
        [&](std::size_t c) {
            const Chunk &from = l.chunks[c], &to = l.chunks[c + 1];
            if (positions) hzio::prefault_write(positions + 3 * from.vertex, 12 * (to.vertex - from.vertex));
            if (h.swap)
                decode_chunk<true>(b, h, from, to, positions, offsets, scalars, properties, boxes[c]);
            else
                decode_chunk<false>(b, h, from, to, positions, offsets, scalars, properties, boxes[c]);
            if (release) release(from.byte, to.byte);
            decoded += to.vertex - from.vertex;
        },
        [&] { return cancelled && cancelled(decoded.load()); });
    if (!done) throw Cancelled{};
    if (box != nullptr && positions != nullptr)
        for (const Box &c : boxes) box->merge(c);
}

std::uint64_t write(const std::string &path, const float *positions, std::uint64_t nb_vertices, const std::uint64_t *offsets,
                    std::uint64_t nb_streamlines, const WriteSpec &spec) {
    const std::uint64_t *selection = spec.selection;
    if (selection != nullptr) nb_streamlines = spec.nb_selected;  // (the streamlines written, k; each from source s)
    if (nb_streamlines > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max()))
        throw FormatError("TRK holds at most 2^31-1 streamlines");
    unsigned char hdr[kHeaderSize] = {};
    std::memcpy(hdr, "TRACK", 6);
    const Mat4 &A = spec.vox_to_ras;
    float vs[3];
    for (int j = 0; j < 3; ++j) {
        double n = 0;
        for (int i = 0; i < 3; ++i) n += A[4 * i + j] * A[4 * i + j];
        vs[j] = static_cast<float>(std::sqrt(n));
        if (!(vs[j] > 0)) throw FormatError("the reference affine is singular: no voxel size");
        const std::uint64_t d = std::max<std::uint64_t>(spec.dims[static_cast<std::size_t>(j)], 1);
        if (d > 32767) throw FormatError("reference dimension " + std::to_string(d) + " does not fit TRK's int16");
        store<std::int16_t>(hdr + 6 + 2 * j, static_cast<std::int16_t>(d));
        store<float>(hdr + 12 + 4 * j, vs[j]);
    }
    auto names = [&](const std::vector<Column> &cols, unsigned char *at, const char *what) {
        std::uint32_t total = 0;
        if (cols.size() > 10) throw FormatError(std::string("TRK holds at most 10 ") + what + " names");
        for (std::size_t k = 0; k < cols.size(); ++k) {
            std::string enc = cols[k].name;
            if (cols[k].count > 1) {
                enc.push_back('\0');
                enc.append(std::to_string(cols[k].count));
            }
            if (enc.size() > 20) throw FormatError(std::string(what) + " name '" + cols[k].name + "' is too long for TRK (20 bytes)");
            std::memcpy(at + 20 * k, enc.data(), enc.size());
            total += cols[k].count;
        }
        return total;
    };
    const std::uint32_t ns = names(spec.scalars, hdr + 38, "scalar"), np = names(spec.properties, hdr + 240, "property");
    if (ns > 32767 || np > 32767) throw FormatError("too many scalar or property columns");
    store<std::int16_t>(hdr + 36, static_cast<std::int16_t>(ns));
    store<std::int16_t>(hdr + 238, static_cast<std::int16_t>(np));
    for (int i = 0; i < 16; ++i) store<float>(hdr + 440 + 4 * i, static_cast<float>(A[static_cast<std::size_t>(i)]));
    const std::string order = axcodes(A);
    std::memcpy(hdr + 948, order.data(), 3);
    // With properties, a record of 0 points is more than nibabel can read
    // ("number of values should match n_elements"): such streamlines are
    // left out. Without, it is kept (valid TRK, as nibabel writes it).
    std::uint64_t empty = 0;
    if (!spec.properties.empty())
        for (std::uint64_t k = 0; k < nb_streamlines; ++k) {
            const std::uint64_t s = selection != nullptr ? selection[k] : k;
            empty += offsets[s + 1] - spec.gap <= offsets[s];
        }
    store<std::int32_t>(hdr + 988, static_cast<std::int32_t>(nb_streamlines - empty));
    store<std::int32_t>(hdr + 992, 2);
    store<std::int32_t>(hdr + 996, 1000);

    // RAS+ mm -> voxmm: inverse of the reader's transform with F = I
    // (voxel_order is the affine's own orientation).
    Mat4 inv{};
    {
        // Inverse of the affine by its 3x3 block.
        const double *m = A.data();
        const double a = m[0], bb = m[1], c = m[2], d = m[4], e = m[5], f = m[6], g = m[8], hh = m[9], k = m[10];
        const double det = a * (e * k - f * hh) - bb * (d * k - f * g) + c * (d * hh - e * g);
        if (!(std::fabs(det) > 0) || !std::isfinite(det)) throw FormatError("the reference affine is singular");
        const double R[9] = {(e * k - f * hh) / det, (c * hh - bb * k) / det, (bb * f - c * e) / det,
                             (f * g - d * k) / det,  (a * k - c * g) / det,   (c * d - a * f) / det,
                             (d * hh - e * g) / det, (bb * g - a * hh) / det, (a * e - bb * d) / det};
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) inv[4 * i + j] = R[3 * i + j];
            inv[4 * i + 3] = -(R[3 * i] * m[3] + R[3 * i + 1] * m[7] + R[3 * i + 2] * m[11]);
        }
        inv[15] = 1;
    }
    std::FILE *fp = std::fopen(path.c_str(), "wb");
    if (fp == nullptr) throw FormatError(std::string("cannot create: ") + std::strerror(errno));
    bool ok = std::fwrite(hdr, 1, sizeof hdr, fp) == sizeof hdr;
    // Records go through a 1 MiB buffer, written out whenever the next
    // field group (a count, a point, the properties) would not fit.
    std::vector<unsigned char> buf(1 << 20);
    std::size_t used = 0;
    auto room = [&](std::size_t bytes) {
        if (used + bytes > buf.size()) {
            ok = ok && std::fwrite(buf.data(), 1, used, fp) == used;
            used = 0;
        }
    };
    auto put = [&](auto v) {
        store(buf.data() + used, v);
        used += 4;
    };
    for (std::uint64_t k = 0; k < nb_streamlines && ok; ++k) {
        const std::uint64_t s = selection != nullptr ? selection[k] : k;
        const std::uint64_t end = offsets[s + 1] - spec.gap, n = end - offsets[s];
        if (n > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max())) {
            std::fclose(fp);
            throw FormatError("streamline " + std::to_string(s) + " has too many points for TRK");
        }
        if (n == 0 && empty > 0) continue;
        room(4);
        put(static_cast<std::int32_t>(n));
        for (std::uint64_t v = offsets[s]; v < end; ++v) {
            room(4 * (3 + std::size_t(ns)));
            const float *p = positions + 3 * v;
            if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
                std::fclose(fp);
                throw FormatError("streamline " + std::to_string(s) + " has a non-finite coordinate");
            }
            for (int r = 0; r < 3; ++r) {
                const double vox = inv[4 * r] * p[0] + inv[4 * r + 1] * p[1] + inv[4 * r + 2] * p[2] + inv[4 * r + 3];
                put(static_cast<float>((vox + 0.5) * vs[r]));
            }
            for (std::uint32_t k = 0; k < ns; ++k) put(spec.scalar_data[v * ns + k]);
        }
        room(4 * std::size_t(np));
        for (std::uint32_t c = 0; c < np; ++c) put(spec.property_data[k * np + c]);
    }
    if (ok && used != 0) ok = std::fwrite(buf.data(), 1, used, fp) == used;
    (void)nb_vertices;
    (void)kBigHost;
    if (std::fclose(fp) != 0) ok = false;
    if (!ok) throw FormatError(std::string("write failed: ") + std::strerror(errno));
    return empty;
}

}  // namespace trk
