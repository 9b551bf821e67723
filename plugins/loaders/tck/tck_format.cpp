// MRtrix TCK format. Spec facts: MRtrix3 documentation "Tracks file format"
// and ../shared/formats/FORMATS.md section 1.4 (quirks observed in nibabel's
// and mrtrix3's files).
#include "tck_format.hpp"

#include "parallel.hpp"
#include "tck_scan.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <limits>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>
#include <utility>
#include <vector>

namespace tck {

const char *to_string(DataType t) {
    switch (t) {
    case DataType::Float32LE: return "Float32LE";
    case DataType::Float32BE: return "Float32BE";
    case DataType::Float64LE: return "Float64LE";
    case DataType::Float64BE: return "Float64BE";
    }
    return "?";
}

namespace {

constexpr std::string_view kMagic = "mrtrix tracks";

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
    return s;
}

bool parse_u64(std::string_view s, std::uint64_t &out) {
    if (s.empty() || s.size() > 19) return false;
    std::uint64_t v = 0;
    for (char c : s) {
        if (c < '0' || c > '9') return false;
        v = v * 10 + static_cast<std::uint64_t>(c - '0');
    }
    out = v;
    return true;
}

inline std::uint32_t bswap(std::uint32_t v) { return __builtin_bswap32(v); }
inline std::uint64_t bswap(std::uint64_t v) { return __builtin_bswap64(v); }

// Reads one element of type T stored with the file's byte order.
template <class T, bool Swap>
inline T load(const unsigned char *p) {
    using U = std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>;
    U u;
    std::memcpy(&u, p, sizeof u);
    if constexpr (Swap) u = bswap(u);
    return std::bit_cast<T>(u);
}

constexpr bool kLittle = std::endian::native == std::endian::little;

// Calls f(x, y, z) for every triple of the data section, stopping when f
// returns false. Dispatches once on the data type.
template <class F>
void for_each_triple(const unsigned char *p, std::uint64_t n_triples, DataType t, F &&f) {
    auto run = [&](auto tag, auto swap) {
        using T = decltype(tag);
        constexpr bool S = decltype(swap)::value;
        constexpr std::uint64_t stride = 3 * sizeof(T);
        for (std::uint64_t i = 0; i < n_triples; ++i, p += stride) {
            const T x = load<T, S>(p), y = load<T, S>(p + sizeof(T)), z = load<T, S>(p + 2 * sizeof(T));
            if (!f(i, static_cast<double>(x), static_cast<double>(y), static_cast<double>(z))) return;
        }
    };
    switch (t) {
    case DataType::Float32LE: run(float{}, std::bool_constant<!kLittle>{}); break;
    case DataType::Float32BE: run(float{}, std::bool_constant<kLittle>{}); break;
    case DataType::Float64LE: run(double{}, std::bool_constant<!kLittle>{}); break;
    case DataType::Float64BE: run(double{}, std::bool_constant<kLittle>{}); break;
    }
}

std::uint64_t element_size(DataType t) { return (t == DataType::Float32LE || t == DataType::Float32BE) ? 4 : 8; }

}  // namespace

int probe(const unsigned char *head, std::uint64_t size) {
    if (size < kMagic.size()) return 0;
    if (std::memcmp(head, kMagic.data(), kMagic.size()) != 0) return 0;
    // The rest of the first line may only hold blanks.
    for (std::uint64_t i = kMagic.size(); i < size; ++i) {
        const unsigned char c = head[i];
        if (c == '\n') return 100;
        if (c != ' ' && c != '\t' && c != '\r') return 0;
    }
    return 80;  // magic seen, line not finished within the probe window
}

Header parse_header(const unsigned char *bytes, std::uint64_t size) {
    Header h;
    std::uint64_t pos = 0;
    std::uint64_t line_no = 0;
    bool have_datatype = false, have_file = false, have_end = false;
    while (pos < size) {
        const void *nl = std::memchr(bytes + pos, '\n', size - pos);
        if (nl == nullptr) break;  // an unfinished last line cannot be END
        const std::uint64_t end = static_cast<std::uint64_t>(static_cast<const unsigned char *>(nl) - bytes);
        std::string_view line(reinterpret_cast<const char *>(bytes + pos), end - pos);
        pos = end + 1;
        ++line_no;
        if (line_no == 1) {
            if (trim(line) != kMagic) throw FormatError("first line is not 'mrtrix tracks' (not a TCK file)");
            continue;
        }
        if (line.find('\0') != std::string_view::npos)
            throw FormatError("NUL byte in header line " + std::to_string(line_no) + " before END");
        std::string_view t = trim(line);
        if (t == "END") {
            have_end = true;
            break;
        }
        const auto colon = t.find(':');
        if (colon == std::string_view::npos) {
            // A continuation of the previous value (MRtrix writes multi-line
            // command_history this way); before any key it is an error.
            if (h.entries.empty()) throw FormatError("header line " + std::to_string(line_no) + " has no 'key: value' form");
            h.entries.back().second += "\n";
            h.entries.back().second += t;
            continue;
        }
        std::string key(trim(t.substr(0, colon)));
        std::string value(trim(t.substr(colon + 1)));
        if (key == "datatype") {
            if (value == "Float32LE")
                h.datatype = DataType::Float32LE;
            else if (value == "Float32BE")
                h.datatype = DataType::Float32BE;
            else if (value == "Float64LE")
                h.datatype = DataType::Float64LE;
            else if (value == "Float64BE")
                h.datatype = DataType::Float64BE;
            else
                throw FormatError("datatype '" + value + "' unsupported (Float32/Float64 LE/BE only)");
            have_datatype = true;
        } else if (key == "file") {
            // "file: . OFFSET": data in this file at OFFSET.
            const auto sp = value.find_first_of(" \t");
            std::string_view fname = trim(std::string_view(value).substr(0, sp));
            std::string_view off = sp == std::string::npos ? std::string_view{} : trim(std::string_view(value).substr(sp));
            if (fname != ".") throw FormatError("data in another file ('file: " + value + "') is unsupported");
            if (!parse_u64(off, h.data_offset)) throw FormatError("'file: " + value + "' has no valid byte offset");
            have_file = true;
        }
        h.entries.emplace_back(std::move(key), std::move(value));
    }
    if (line_no == 0) {
        if (size == 0) throw FormatError("empty file");
        if (probe(bytes, size) == 0) throw FormatError("first line is not 'mrtrix tracks' (not a TCK file)");
    }
    if (!have_end) throw FormatError("header has no END line (file truncated?)");
    if (!have_datatype) h.warnings.emplace_back("no datatype field: assuming Float32LE");
    if (!have_file) {
        h.warnings.emplace_back("no file field: data assumed right after END");
        h.data_offset = pos;
    }
    if (h.data_offset < pos)
        throw FormatError("data offset " + std::to_string(h.data_offset) + " points inside the header (ends at byte " +
                          std::to_string(pos) + ")");
    if (h.data_offset > size)
        throw FormatError("data offset " + std::to_string(h.data_offset) + " is past the end of the file (" + std::to_string(size) +
                          " bytes)");
    return h;
}

std::optional<std::uint64_t> declared_count(const Header &h) {
    for (auto it = h.entries.rbegin(); it != h.entries.rend(); ++it) {
        if (it->first != "count") continue;
        std::uint64_t v = 0;
        if (!parse_u64(it->second, v)) return std::nullopt;  // (values are stored trimmed)
        return v;
    }
    return std::nullopt;
}

namespace {

// The validating walk over the data section, one classified triple at a
// time; both scans below drive it. Triple `index` at byte `at` has `nans`
// NaN and `infs` infinite components.
struct Walk {
    Walk(Layout &layout, bool record) : L(layout), record_delimiters(record) {}
    Layout &L;
    bool record_delimiters;
    std::uint64_t in_track = 0;  // points in the open streamline
    bool terminated = false;
    std::string error;

    // Returns false when the walk ends (terminator or error).
    bool triple(int nans, int infs, std::uint64_t index, std::uint64_t at, std::uint64_t triple_bytes) {
        if (nans == 0 && infs == 0) {
            ++in_track;
            return true;
        }
        if (nans == 3) {  // end of a streamline (possibly empty)
            if (record_delimiters) L.delimiters.push_back(index);
            ++L.nb_streamlines;
            L.nb_vertices += in_track;
            in_track = 0;
            return true;
        }
        if (infs == 3) {
            if (in_track != 0) {
                error = "last streamline is not closed by a NaN triple before the Inf terminator (byte " + std::to_string(at) + ")";
                return false;
            }
            terminated = true;
            L.end_offset = at + triple_bytes;
            return false;
        }
        error = "partial NaN/Inf triple at byte " + std::to_string(at) + " (only all-NaN ends a streamline and all-Inf ends the file)";
        return false;
    }

    // Throws what the walk found wrong; fills the trailing bytes.
    void finish(std::uint64_t size, std::uint64_t avail, std::uint64_t triple_bytes) const {
        if (!error.empty()) throw FormatError(error);
        if (!terminated) {
            if (avail % triple_bytes != 0)
                throw FormatError("data ends inside a point (file truncated at byte " + std::to_string(size) + ")");
            throw FormatError("no 'Inf Inf Inf' terminator (file truncated?)");
        }
        L.trailing_bytes = size - L.end_offset;
    }
};

// Float32LE, the common case, in one pass over the data. Chunks of a
// million triples are classified in parallel by detail::scan_chunk (SIMD
// through Highway): the index of every triple with a NaN or Inf component
// is kept with its NaN and Inf counts (8 bytes per such 12-byte triple at
// most), and every other float is folded into the chunk's bounds. Those
// triples then go through the walk in file order, the runs between them
// counting as plain points; the walk records the delimiters, so decode()
// copies the runs between them, and the chunks' bounds up to the
// terminator are the file's.

void scan_f32le(const unsigned char *data, std::uint64_t n_triples, const Header &h, const Tick &cancelled, const Release &release,
                Walk &w) {
    constexpr std::uint64_t kChunk = 1u << 20;
    const std::size_t nchunks = static_cast<std::size_t>((n_triples + kChunk - 1) / kChunk);
    std::vector<std::vector<std::uint64_t>> specials(nchunks);
    struct Box {
        float lo[3], hi[3];
    };
    std::vector<Box> boxes(nchunks);
    std::atomic<std::uint64_t> scanned{0};  // chunks done: the position `cancelled` is given
    const bool done = hzio::parallel_chunks(
        nchunks,
        [&](std::size_t c) {
            const std::uint64_t b = c * kChunk, e = std::min(n_triples, b + kChunk);
            Box &box = boxes[c];
            std::fill(box.lo, box.lo + 3, HUGE_VALF);
            std::fill(box.hi, box.hi + 3, -HUGE_VALF);
            detail::scan_chunk(data, b, e, specials[c], box.lo, box.hi);
            if (release) release(h.data_offset + 12 * b, h.data_offset + 12 * e);
            scanned.fetch_add(1, std::memory_order_relaxed);
        },
        [&] { return cancelled && cancelled(h.data_offset + 12 * std::min(n_triples, scanned.load(std::memory_order_relaxed) * kChunk)); });
    if (!done) throw Cancelled{};
    // The delimiters are among the flagged triples: room for all of them at
    // once, rather than a growing vector that copies itself into fresh
    // memory again and again (8 MB at a million streamlines).
    std::size_t flagged = 0;
    for (const auto &chunk : specials) flagged += chunk.size();
    w.L.delimiters.reserve(flagged);
    hzio::prefault_write(w.L.delimiters.data(), flagged * sizeof(std::uint64_t));
    std::uint64_t next = 0;          // first triple not yet walked
    std::uint64_t stop = n_triples;  // the triple that ended the walk (the terminator)
    for (auto &chunk : specials) {
        for (const std::uint64_t packed : chunk) {
            const std::uint64_t i = packed >> 4;
            const int nans = static_cast<int>(packed >> 2 & 3), infs = static_cast<int>(packed & 3);
            w.in_track += i - next;
            next = i + 1;
            if (!w.triple(nans, infs, i, h.data_offset + i * 12, 12)) {
                stop = i;
                break;
            }
        }
        if (stop != n_triples) break;
        std::vector<std::uint64_t>().swap(chunk);
    }
    if (stop == n_triples) w.in_track += n_triples - next;
    if (!w.error.empty() || !w.terminated) return;  // (finish() reports it)
    // The bounds of the chunks before the terminator's, and of that chunk up
    // to the terminator (points after it are not data; usually there are
    // none, and the chunk's box stands).
    float lo[3] = {HUGE_VALF, HUGE_VALF, HUGE_VALF}, hi[3] = {-HUGE_VALF, -HUGE_VALF, -HUGE_VALF};
    const std::size_t last = static_cast<std::size_t>(stop / kChunk);
    for (std::size_t c = 0; c < last; ++c)
        for (int d = 0; d < 3; ++d) {
            lo[d] = std::min(lo[d], boxes[c].lo[d]);
            hi[d] = std::max(hi[d], boxes[c].hi[d]);
        }
    if (stop + 1 == n_triples) {
        for (int d = 0; d < 3; ++d) {
            lo[d] = std::min(lo[d], boxes[last].lo[d]);
            hi[d] = std::max(hi[d], boxes[last].hi[d]);
        }
    } else {  // (that chunk again, up to the terminator)
        std::vector<std::uint64_t> again;
        detail::scan_chunk(data, last * kChunk, stop, again, lo, hi);
    }
    Layout &L = w.L;
    L.has_bounds = lo[0] <= hi[0];
    for (int d = 0; d < 3 && L.has_bounds; ++d) {
        L.lo[d] = lo[d];
        L.hi[d] = hi[d];
    }
}

}  // namespace

Layout scan(const unsigned char *bytes, std::uint64_t size, const Header &h, const Tick &cancelled, const Release &release) {
    const std::uint64_t es = element_size(h.datatype);
    const std::uint64_t avail = size - h.data_offset;
    const std::uint64_t n_triples = avail / (3 * es);
    Layout L;
    const bool f32le = h.datatype == DataType::Float32LE && kLittle;
    Walk w(L, f32le);
    if (f32le) {
        scan_f32le(bytes + h.data_offset, n_triples, h, cancelled, release, w);
    } else {
        for_each_triple(bytes + h.data_offset, n_triples, h.datatype, [&](std::uint64_t i, double x, double y, double z) {
            if ((i & 0xFFFFF) == 0 && cancelled && cancelled(h.data_offset + i * 3 * es)) throw Cancelled{};
            const int nans = std::isnan(x) + std::isnan(y) + std::isnan(z);
            const int infs = std::isinf(x) + std::isinf(y) + std::isinf(z);
            return w.triple(nans, infs, i, h.data_offset + i * 3 * es, 3 * es);
        });
    }
    w.finish(size, avail, 3 * es);
    return L;
}

void decode(const unsigned char *bytes, const Header &h, const Layout &L, float *positions, std::uint64_t *offsets, const Tick &cancelled,
            const Release &release) {
    const std::uint64_t es = element_size(h.datatype);
    const std::uint64_t n_triples = (L.end_offset - h.data_offset) / (3 * es);
    std::uint64_t v = 0, s = 0;
    offsets[0] = 0;
    if (L.delimiters.size() == L.nb_streamlines && L.nb_streamlines > 0 && h.datatype == DataType::Float32LE && kLittle) {
        // The runs between the delimiters found by scan(), copied as they
        // are, in parallel chunks of whole streamlines (about 12 MiB each).
        // Streamline k starts at triple delimiters[k-1] + 1, which is vertex
        // delimiters[k-1] + 1 - k: every earlier delimiter is one triple.
        const unsigned char *data = bytes + h.data_offset;
        const std::vector<std::uint64_t> &D = L.delimiters;
        std::vector<std::uint64_t> first{0};  // first streamline of each chunk
        for (std::uint64_t k = 0, start = 0; k < L.nb_streamlines; ++k)
            if (D[k] - start >= (1u << 20)) {
                first.push_back(k + 1);
                start = D[k] + 1;
            }
        if (first.back() != L.nb_streamlines) first.push_back(L.nb_streamlines);
        const bool done = hzio::parallel_chunks(
            first.size() - 1,
            [&](std::size_t c) {
                const std::uint64_t k0 = first[c], k1 = first[c + 1];
                std::uint64_t start = k0 == 0 ? 0 : D[k0 - 1] + 1;
                const std::uint64_t chunk_begin = start;
                const std::uint64_t v0 = start - k0, v1 = D[k1 - 1] - (k1 - 1);  // this chunk's vertices
                hzio::prefault_write(positions + 3 * v0, 12 * (v1 - v0));
                for (std::uint64_t k = k0; k < k1; ++k) {
                    const std::uint64_t n = D[k] - start;
                    if (n) std::memcpy(positions + 3 * (start - k), data + 12 * start, 12 * n);
                    offsets[k + 1] = D[k] - k;
                    start = D[k] + 1;
                }
                if (release) release(h.data_offset + 12 * chunk_begin, h.data_offset + 12 * start);
            },
            [&] { return cancelled && cancelled(0); });
        if (!done) throw Cancelled{};
        if (offsets[L.nb_streamlines] != L.nb_vertices) throw FormatError("file changed while reading");
        return;
    }
    for_each_triple(bytes + h.data_offset, n_triples, h.datatype, [&](std::uint64_t i, double x, double y, double z) {
        if ((i & 0xFFFFF) == 0 && cancelled && cancelled(h.data_offset + i * 3 * es)) throw Cancelled{};
        if (std::isnan(x)) {
            offsets[++s] = v;
            return true;
        }
        if (std::isinf(x)) return false;
        float *p = positions + 3 * v++;
        p[0] = static_cast<float>(x);
        p[1] = static_cast<float>(y);
        p[2] = static_cast<float>(z);
        return true;
    });
    if (s != L.nb_streamlines || v != L.nb_vertices) throw FormatError("file changed while reading");
}

void write(const std::string &path, const float *positions, std::uint64_t nb_vertices, const std::uint64_t *offsets,
           std::uint64_t nb_streamlines, const std::vector<std::pair<std::string, std::string>> &metadata, std::uint32_t gap,
           const std::uint64_t *selection, std::uint64_t nb_selected) {
    const std::uint64_t nb_written = selection != nullptr ? nb_selected : nb_streamlines;
    std::string head = "mrtrix tracks\n";
    for (const auto &[k, v] : metadata) {
        if (k == "datatype" || k == "file" || k == "count") continue;
        if (k.empty() || k.find_first_of(":\n\r") != std::string::npos || k == "END") continue;  // not a key
        // Multi-line values become repeated keys, the MRtrix convention.
        std::size_t start = 0;
        do {
            const std::size_t nl = v.find('\n', start);
            std::string line = v.substr(start, nl == std::string::npos ? std::string::npos : nl - start);
            std::erase(line, '\r');
            head += k + ": " + line + "\n";
            start = nl == std::string::npos ? v.size() + 1 : nl + 1;
        } while (start <= v.size());
    }
    head += "datatype: Float32LE\ncount: " + std::to_string(nb_written) + "\n";
    // The offset is part of the header it points past: grow it until stable.
    // Like MRtrix's writer, the data start on a multiple of 4 bytes, so a
    // reader can map the floats in place.
    std::uint64_t offset = head.size() + 20;
    for (;;) {
        offset = (offset + 3) / 4 * 4;
        const std::string tail = "file: . " + std::to_string(offset) + "\nEND\n";
        if (head.size() + tail.size() <= offset) {
            head += tail;
            break;
        }
        offset = head.size() + tail.size();
    }
    head.resize(offset, '\0');

    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) throw FormatError(std::string("cannot create: ") + std::strerror(errno), true);
    struct Closer {
        int fd;
        ~Closer() {
            if (fd >= 0) ::close(fd);
        }
    } closer{fd};
    // Gathered writes straight from the caller's positions (little-endian
    // machines): each streamline's run, then a shared delimiter triple; up
    // to IOV_MAX pieces per call, no copy in between.
    static const float delimiter[3] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::quiet_NaN(),
                                       std::numeric_limits<float>::quiet_NaN()};
    static const float terminator[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                                        std::numeric_limits<float>::infinity()};
    std::vector<iovec> iov;
    iov.reserve(1024);
    std::vector<float> swapped;  // (big-endian machines: a byte-swapped copy of the pending runs)
    // Writeback started every kKick bytes (sync_file_range, asynchronous):
    // the disk writes while later runs are copied, and the fsync the host
    // does before publishing the file finds most of it written.
    constexpr std::uint64_t kKick = 32u << 20;
    std::uint64_t written = 0, kicked = 0;
    auto flush = [&] {
        std::size_t k = 0;
        while (k < iov.size()) {
            const int cnt = int(std::min<std::size_t>(iov.size() - k, 1024));
            const ssize_t w = ::writev(fd, iov.data() + k, cnt);
            if (w < 0) {
                if (errno == EINTR) continue;
                throw FormatError(std::string("write failed: ") + std::strerror(errno), true);
            }
            written += std::uint64_t(w);
            if (written - kicked >= kKick) {
                (void)::sync_file_range(fd, off_t(kicked), off_t(written - kicked), SYNC_FILE_RANGE_WRITE);  // (a hint: errors ignored)
                kicked = written;
            }
            // Advance past what was written (a short write resumes mid-piece).
            std::size_t left = std::size_t(w);
            while (k < iov.size() && left >= iov[k].iov_len) left -= iov[k++].iov_len;
            if (left) {
                iov[k].iov_base = static_cast<char *>(iov[k].iov_base) + left;
                iov[k].iov_len -= left;
            }
        }
        iov.clear();
        swapped.clear();
    };
    auto add = [&](const void *p, std::size_t bytes) {
        if (bytes == 0) return;
        if constexpr (!kLittle) {
            const float *q = static_cast<const float *>(p);
            std::size_t at = swapped.size();
            if (swapped.capacity() < at + bytes / 4) {  // (no reallocation under pending iovecs)
                flush();
                swapped.reserve(std::max<std::size_t>(bytes / 4, 1 << 20));
                at = 0;
            }
            for (std::size_t i = 0; i < bytes / 4; ++i) swapped.push_back(std::bit_cast<float>(bswap(std::bit_cast<std::uint32_t>(q[i]))));
            p = swapped.data() + at;
        }
        iov.push_back({const_cast<void *>(p), bytes});
        if (iov.size() == 1024) flush();
    };
    add(head.data(), head.size());
    for (std::uint64_t k = 0; k < nb_written; ++k) {
        const std::uint64_t s = selection != nullptr ? selection[k] : k;
        const float *run = positions + 3 * offsets[s];
        const std::uint64_t n = 3 * (offsets[s + 1] - gap - offsets[s]);
        // Exponent bits all set: Inf or NaN (a test the compiler vectorises).
        std::uint32_t bad = 0;
        for (std::uint64_t i = 0; i < n; ++i) bad |= (std::bit_cast<std::uint32_t>(run[i]) & 0x7f800000u) == 0x7f800000u;
        if (bad) throw FormatError("streamline " + std::to_string(s) + " has a non-finite coordinate (TCK uses NaN/Inf as delimiters)");
        add(run, n * sizeof(float));
        add(delimiter, sizeof delimiter);
    }
    add(terminator, sizeof terminator);
    flush();
    (void)nb_vertices;
    if (::close(std::exchange(closer.fd, -1)) != 0) throw FormatError(std::string("write failed: ") + std::strerror(errno), true);
}

}  // namespace tck
