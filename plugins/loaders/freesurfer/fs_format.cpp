// FreeSurfer surface and curv parsing (fs_format.hpp).
#include "fs_format.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

namespace fsurf {

std::uint32_t be32(const unsigned char *p) {
    return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
}

// A "new format" curv file: FF FF FF, then vnum, fnum, values per vertex = 1.
bool looks_like_curv(const unsigned char *b, std::uint64_t size) {
    return size >= 15 && b[0] == 0xFF && b[1] == 0xFF && b[2] == 0xFF && be32(b + 11) == 1 && static_cast<std::int32_t>(be32(b + 3)) >= 0;
}

static Surface parse_curv(const unsigned char *b, std::uint64_t size) {
    Surface s;
    s.curv = true;
    const auto vnum = static_cast<std::int32_t>(be32(b + 3));
    const std::uint64_t need = 15 + 4ull * static_cast<std::uint64_t>(vnum);
    if (vnum == 0) throw FormatError("curv file with 0 vertices");
    if (size < need)
        throw FormatError("curv file declares " + std::to_string(vnum) + " values (" + std::to_string(need) + " bytes), the file has " +
                          std::to_string(size));
    s.values.resize(static_cast<std::size_t>(vnum));
    for (std::size_t i = 0; i < s.values.size(); ++i) s.values[i] = std::bit_cast<float>(be32(b + 15 + 4 * i));
    return s;
}

static std::uint32_t be24(const unsigned char *p) { return (std::uint32_t(p[0]) << 16) | (std::uint32_t(p[1]) << 8) | p[2]; }

// Bytes a quad file with the counts in its first 9 bytes needs.
static std::uint64_t quad_bytes(const unsigned char *b) {
    const std::uint64_t per_vertex = b[2] == 0xFF ? 6 : 12;  // int16 x 3 (old) or float32 x 3 (new)
    return 9 + per_vertex * be24(b + 3) + 12ull * be24(b + 6);
}

bool is_quad(const unsigned char *b, std::uint64_t size) {
    if (size < 9 || b[0] != 0xFF || b[1] != 0xFF || (b[2] != 0xFF && b[2] != 0xFD)) return false;
    if (b[2] == 0xFD) return true;
    // FF FF FF is also a curv file's magic: a quad file unless the curv
    // layout (values per vertex = 1 at byte 11) fits and the quad one does not.
    if (!looks_like_curv(b, size)) return true;
    const std::uint64_t curv_need = 15 + 4ull * be32(b + 3);
    return size == quad_bytes(b) && size != curv_need;
}

// FreeSurfer's quad surfaces (nibabel read_geometry): magic FF FF FF (int16
// coordinates in 1/100 mm) or FF FF FD (float32), 3-byte vertex and quad
// counts, the coordinates, then 4 3-byte indices per quad. Each quad is
// split into two triangles by nibabel's (and FreeSurfer's) rule.
static Surface parse_quad(const unsigned char *b, std::uint64_t size) {
    Surface s;
    s.quad = true;
    const bool old = b[2] == 0xFF;
    const std::uint32_t nv = be24(b + 3), nq = be24(b + 6);
    if (nv == 0) throw FormatError("quad surface with 0 vertices");
    if (quad_bytes(b) > size)
        throw FormatError("quad surface of " + std::to_string(nv) + " vertices and " + std::to_string(nq) + " quads needs " +
                          std::to_string(quad_bytes(b)) + " bytes, the file has " + std::to_string(size));
    s.created = old ? "int16, 1/100 mm" : "float32";
    s.vertices.resize(3ull * nv);
    std::uint64_t pos = 9;
    for (std::size_t i = 0; i < s.vertices.size(); ++i) {
        if (old) {
            const auto v = static_cast<std::int16_t>((std::uint16_t(b[pos]) << 8) | b[pos + 1]);
            s.vertices[i] = static_cast<float>(double(v) / 100.0);
            pos += 2;
        } else {
            s.vertices[i] = std::bit_cast<float>(be32(b + pos));
            if (!std::isfinite(s.vertices[i])) throw FormatError("vertex " + std::to_string(i / 3) + " has a non-finite coordinate");
            pos += 4;
        }
    }
    s.faces.resize(6ull * nq);
    for (std::uint32_t q = 0; q < nq; ++q) {
        std::uint32_t v[4];
        for (int k = 0; k < 4; ++k, pos += 3) {
            v[k] = be24(b + pos);
            if (v[k] >= nv)
                throw FormatError("quad " + std::to_string(q) + " uses vertex " + std::to_string(v[k]) + ", outside [0, " +
                                  std::to_string(nv) + ")");
        }
        std::uint32_t *f = s.faces.data() + 6ull * q;
        if (v[0] % 2 == 0)
            f[0] = v[0], f[1] = v[1], f[2] = v[3], f[3] = v[2], f[4] = v[3], f[5] = v[1];
        else
            f[0] = v[0], f[1] = v[1], f[2] = v[2], f[3] = v[0], f[4] = v[2], f[5] = v[3];
    }
    return s;
}

Surface parse(const unsigned char *b, std::uint64_t size) {
    if (size < 3) throw FormatError("file is " + std::to_string(size) + " bytes: no magic number");
    if (is_quad(b, size)) return parse_quad(b, size);
    if (looks_like_curv(b, size)) return parse_curv(b, size);
    if (b[0] != 0xFF || b[1] != 0xFF || b[2] != 0xFE) {
        if (b[0] == 0xFF && b[1] == 0xFF && (b[2] == 0xFF || b[2] == 0xFD))
            throw FormatError("file ends inside the quad surface header (" + std::to_string(size) + " bytes)");
        throw FormatError("magic is not FF FF FE, FF FF FF or FF FF FD (not a FreeSurfer surface or curv file)");
    }
    Surface s;
    std::uint64_t pos = 3;
    const void *nl = std::memchr(b + pos, '\n', static_cast<std::size_t>(std::min<std::uint64_t>(size - pos, 4096)));
    if (nl == nullptr) throw FormatError("no end to the 'created by' line within 4096 bytes");
    const auto end = static_cast<std::uint64_t>(static_cast<const unsigned char *>(nl) - b);
    s.created.assign(reinterpret_cast<const char *>(b + pos), end - pos);
    pos = end + 1;
    if (pos < size && b[pos] == '\n') ++pos;
    if (size - pos < 8) throw FormatError("file ends before the vertex and face counts");
    const auto vnum = static_cast<std::int32_t>(be32(b + pos)), fnum = static_cast<std::int32_t>(be32(b + pos + 4));
    pos += 8;
    if (vnum < 0 || fnum < 0)
        throw FormatError("negative vertex or face count (" + std::to_string(vnum) + ", " + std::to_string(fnum) + ")");
    const std::uint64_t need = 12ull * static_cast<std::uint64_t>(vnum) + 12ull * static_cast<std::uint64_t>(fnum);
    if (need > size - pos)
        throw FormatError(std::to_string(vnum) + " vertices and " + std::to_string(fnum) + " faces need " + std::to_string(need) +
                          " bytes, the file has " + std::to_string(size - pos) + " left");
    s.vertices.resize(3 * static_cast<std::size_t>(vnum));
    for (std::size_t i = 0; i < s.vertices.size(); ++i, pos += 4) {
        s.vertices[i] = std::bit_cast<float>(be32(b + pos));
        if (!std::isfinite(s.vertices[i])) throw FormatError("vertex " + std::to_string(i / 3) + " has a non-finite coordinate");
    }
    s.faces.resize(3 * static_cast<std::size_t>(fnum));
    for (std::size_t i = 0; i < s.faces.size(); ++i, pos += 4) {
        const auto f = static_cast<std::int32_t>(be32(b + pos));
        if (f < 0 || f >= vnum)
            throw FormatError("face " + std::to_string(i / 3) + " uses vertex " + std::to_string(f) + ", outside [0, " +
                              std::to_string(vnum) + ")");
        s.faces[i] = static_cast<std::uint32_t>(f);
    }
    // Optional footer: tag 20 (or 2, 0, 20) then "key = value" lines.
    if (size - pos >= 4) {
        std::uint64_t q = pos;
        std::int32_t tag = static_cast<std::int32_t>(be32(b + q));
        if (tag == 2 && size - q >= 12 && be32(b + q + 4) == 0 && be32(b + q + 8) == 20)
            q += 12;
        else if (tag == 20)
            q += 4;
        else
            q = size;
        std::string text(reinterpret_cast<const char *>(b + q), static_cast<std::size_t>(size - q));
        std::size_t start = 0;
        while (start < text.size()) {
            const auto e = text.find('\n', start);
            const std::string line = text.substr(start, e == std::string::npos ? std::string::npos : e - start);
            start = e == std::string::npos ? text.size() : e + 1;
            const auto eq = line.find('=');
            if (eq == std::string::npos) continue;
            auto trim = [](std::string x) {
                const auto a = x.find_first_not_of(" \t"), z = x.find_last_not_of(" \t\r");
                return a == std::string::npos ? std::string() : x.substr(a, z - a + 1);
            };
            std::string k = trim(line.substr(0, eq)), v = trim(line.substr(eq + 1));
            if (const auto hash = v.find('#'); hash != std::string::npos) v = trim(v.substr(0, hash));
            if (!k.empty() && s.footer.size() < 64) s.footer.emplace_back(k, v);
        }
    }
    return s;
}

Annotation parse_annot(const unsigned char *b, std::uint64_t size) {
    std::uint64_t pos = 0;
    auto need = [&](std::uint64_t n, const char *what) {
        if (n > size - pos)
            throw FormatError(std::string(what) + " needs " + std::to_string(n) + " bytes at byte " + std::to_string(pos) + ", " +
                              std::to_string(size - pos) + " left");
    };
    auto i32 = [&](const char *what) {
        need(4, what);
        const auto v = static_cast<std::int32_t>(be32(b + pos));
        pos += 4;
        return v;
    };
    auto text = [&](const char *what) {
        const std::int32_t n = i32(what);
        if (n < 0) throw FormatError(std::string(what) + " has a negative length (" + std::to_string(n) + ")");
        need(std::uint64_t(n), what);
        std::string s(reinterpret_cast<const char *>(b + pos), std::size_t(n));
        pos += std::uint64_t(n);
        s.erase(std::find(s.begin(), s.end(), '\0'), s.end());  // names are stored with their NUL
        return s;
    };
    Annotation a;
    const std::int32_t vnum = i32("the vertex count");
    if (vnum <= 0) throw FormatError("annotation for " + std::to_string(vnum) + " vertices");
    need(8ull * std::uint64_t(vnum), "the vertex labels");
    std::vector<std::uint32_t> values(std::size_t(vnum), 0);
    for (std::int32_t i = 0; i < vnum; ++i) {
        const auto vno = static_cast<std::int32_t>(be32(b + pos));
        const std::uint32_t value = be32(b + pos + 4);
        pos += 8;
        if (vno < 0 || vno >= vnum)
            throw FormatError("label pair " + std::to_string(i) + " names vertex " + std::to_string(vno) + " of " + std::to_string(vnum));
        values[std::size_t(vno)] = value;
    }
    if (pos == size) throw FormatError("no colour table after the labels");
    if (i32("the colour-table flag") != 1) throw FormatError("the colour-table flag is not 1");
    const std::int32_t n = i32("the colour-table size");
    constexpr std::uint64_t kEntryMin = 24;  // index/length + r g b t, the least an entry takes
    if (n > 0) {                             // old format: entries 0..n-1
        a.orig_table = text("the original table name");
        if (std::uint64_t(n) > (size - pos) / 20)
            throw FormatError("colour table of " + std::to_string(n) + " entries is longer than the file");
        for (std::int32_t i = 0; i < n; ++i) {
            AnnotEntry e;
            e.index = i;
            e.name = text("a label name");
            e.r = i32("a colour"), e.g = i32("a colour"), e.b = i32("a colour"), e.t = i32("a colour");
            a.table.push_back(std::move(e));
        }
    } else if (n == -2) {
        const std::int32_t max_index = i32("the largest label index");
        if (max_index < 0) throw FormatError("negative largest label index");
        a.orig_table = text("the original table name");
        const std::int32_t count = i32("the colour-table entry count");
        if (count < 0 || std::uint64_t(count) > (size - pos) / kEntryMin)
            throw FormatError("colour table of " + std::to_string(count) + " entries is longer than the file");
        for (std::int32_t i = 0; i < count; ++i) {
            AnnotEntry e;
            e.index = i32("a label index");
            if (e.index < 0 || e.index >= max_index)
                throw FormatError("label index " + std::to_string(e.index) + " outside 0.." + std::to_string(max_index - 1));
            e.name = text("a label name");
            e.r = i32("a colour"), e.g = i32("a colour"), e.b = i32("a colour"), e.t = i32("a colour");
            a.table.push_back(std::move(e));
        }
    } else {
        throw FormatError("colour-table version " + std::to_string(-std::int64_t(n)) + " (only the old format and version 2 are defined)");
    }
    for (const auto &e : a.table)
        for (std::int32_t c : {e.r, e.g, e.b, e.t})
            if (c < 0 || c > 255) throw FormatError("label '" + e.name + "' has a colour component outside 0..255");
    // value -> index of the entry with that colour (the first, if colours repeat)
    std::vector<std::pair<std::uint32_t, std::int32_t>> by_value;
    for (const auto &e : a.table) by_value.emplace_back(e.packed(), e.index);
    std::stable_sort(by_value.begin(), by_value.end(), [](const auto &x, const auto &y) { return x.first < y.first; });
    a.labels.resize(values.size());
    for (std::size_t i = 0; i < values.size(); ++i) {
        a.labels[i] = -1;
        if (values[i] == 0) continue;
        const auto it =
            std::lower_bound(by_value.begin(), by_value.end(), values[i], [](const auto &x, std::uint32_t v) { return x.first < v; });
        if (it != by_value.end() && it->first == values[i]) a.labels[i] = it->second;
    }
    return a;
}

}  // namespace fsurf
