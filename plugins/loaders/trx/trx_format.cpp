// TRX: the container (libzip for zips, plain files for the directory form)
// and the validation rules of ../shared/formats/FORMATS.md section 1.5.
#include "trx_format.hpp"

#include "mapped_file.hpp"

#include <nlohmann/json.hpp>
#include <zip.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

namespace trx {

namespace fs = std::filesystem;

std::size_t dtype_size(DType t) {
    switch (t) {
    case DType::I8:
    case DType::U8:
    case DType::Bit: return 1;
    case DType::I16:
    case DType::U16:
    case DType::F16: return 2;
    case DType::I32:
    case DType::U32:
    case DType::F32: return 4;
    case DType::I64:
    case DType::U64:
    case DType::F64: return 8;
    }
    return 0;
}
const char *dtype_name(DType t) {
    static const char *n[] = {"int8",   "int16",  "int32",   "int64",   "uint8",   "uint16",
                              "uint32", "uint64", "float16", "float32", "float64", "bit"};
    return n[static_cast<int>(t)];
}

float half_to_float(std::uint16_t h) {  // IEEE binary16, subnormals and Inf/NaN included
    const std::uint32_t sign = (h & 0x8000u) << 16;
    std::uint32_t exp = (h >> 10) & 0x1F, man = h & 0x3FF;
    std::uint32_t bits;
    if (exp == 0) {
        if (man == 0) {
            bits = sign;
        } else {  // subnormal: normalise
            int e = -1;
            do {
                ++e;
                man <<= 1;
            } while ((man & 0x400) == 0);
            bits = sign | ((127 - 15 - e) << 23) | ((man & 0x3FF) << 13);
        }
    } else if (exp == 31) {
        bits = sign | 0x7F800000u | (man << 13);
    } else {
        bits = sign | ((exp + 127 - 15) << 23) | (man << 13);
    }
    return std::bit_cast<float>(bits);
}

// ---------------------------------------------------------------- container

class Container {
public:
    virtual ~Container() = default;
    virtual std::vector<Entry> entries() const = 0;
    // Reads exactly entry.bytes bytes into out; throws on short/corrupt data.
    virtual void read(const Entry &e, void *out) const = 0;
    // Where the entry's bytes lie as stored, when they lie in a file as is.
    virtual bool locate(const Entry &e, Extent &out) const = 0;
};

File::File() = default;
File::File(File &&) noexcept = default;
File &File::operator=(File &&) noexcept = default;
File::~File() = default;

namespace {

class ZipContainer : public Container {
public:
    explicit ZipContainer(const std::string &path) : path_(path) {
        int code = 0;
        za_ = zip_open(path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &code);
        if (za_ == nullptr) {
            zip_error_t e;
            zip_error_init_with_code(&e, code);
            std::string msg = std::string("not a readable zip archive: ") + zip_error_strerror(&e);
            zip_error_fini(&e);
            throw FormatError(msg);
        }
        const zip_int64_t n = zip_get_num_entries(za_, 0);
        for (zip_int64_t i = 0; i < n; ++i) {
            zip_stat_t st;
            zip_stat_init(&st);
            if (zip_stat_index(za_, static_cast<zip_uint64_t>(i), 0, &st) != 0 || !(st.valid & ZIP_STAT_NAME) ||
                !(st.valid & ZIP_STAT_SIZE))
                throw FormatError("zip entry " + std::to_string(i) + " cannot be read");
            index_[st.name] = static_cast<zip_uint64_t>(i);
            list_.push_back({st.name, st.size});
        }
    }
    ~ZipContainer() override {
        if (za_) zip_discard(za_);
    }
    std::vector<Entry> entries() const override { return list_; }
    void read(const Entry &e, void *out) const override {
        zip_file_t *zf = zip_fopen_index(za_, index_.at(e.path), 0);
        if (zf == nullptr) throw FormatError("cannot open zip entry '" + e.path + "': " + zip_strerror(za_));
        auto *dst = static_cast<unsigned char *>(out);
        std::uint64_t done = 0;
        while (done < e.bytes) {
            const zip_int64_t got = zip_fread(zf, dst + done, std::min<std::uint64_t>(e.bytes - done, 1u << 30));
            if (got < 0) {
                const std::string m = zip_file_strerror(zf);
                zip_fclose(zf);
                throw FormatError("zip entry '" + e.path + "' is corrupt: " + m);
            }
            if (got == 0) break;
            done += static_cast<std::uint64_t>(got);
        }
        // One more read reaches the end of the stream, where libzip checks the CRC.
        unsigned char probe_byte;
        const zip_int64_t tail = zip_fread(zf, &probe_byte, 1);
        const std::string m = tail < 0 ? zip_file_strerror(zf) : "";
        zip_fclose(zf);
        if (tail < 0) throw FormatError("zip entry '" + e.path + "' is corrupt: " + m);
        if (done != e.bytes || tail > 0) throw FormatError("zip entry '" + e.path + "' does not hold its declared size");
    }

    bool locate(const Entry &e, Extent &out) const override {
        zip_stat_t st;
        zip_stat_init(&st);
        const zip_uint64_t idx = index_.at(e.path);
        if (zip_stat_index(za_, idx, 0, &st) != 0) return false;
        const zip_uint64_t need = ZIP_STAT_COMP_METHOD | ZIP_STAT_ENCRYPTION_METHOD | ZIP_STAT_CRC | ZIP_STAT_COMP_SIZE;
        if ((st.valid & need) != need || st.comp_method != ZIP_CM_STORE || st.encryption_method != ZIP_EM_NONE || st.comp_size != e.bytes)
            return false;
        const hzio::MappedFile m(path_);
        std::uint64_t offset = 0;
        if (!stored_data_offset(m.data(), m.size(), e.path, e.bytes, offset) || offset % 4 != 0) return false;
        out.file = path_;
        out.offset = offset;
        out.has_crc = true;
        out.crc = st.crc;
        return true;
    }

private:
    // libzip does not say where an entry's data starts; the central directory
    // does (ZIP APPNOTE 4.3.12, 4.3.16, 4.4.7 and the Zip64 records 4.3.14/15
    // and extra field 4.5.3). libzip has already checked the archive's
    // consistency (ZIP_CHECKCONS); anything unexpected here only means the
    // entry is read through libzip instead.
    static std::uint64_t le(const unsigned char *p, int n) {
        std::uint64_t v = 0;
        for (int i = n - 1; i >= 0; --i) v = (v << 8) | p[i];
        return v;
    }
    static bool stored_data_offset(const unsigned char *z, std::uint64_t size, const std::string &name, std::uint64_t bytes,
                                   std::uint64_t &data_offset) {
        if (size < 22) return false;
        std::uint64_t eocd = size - 22;
        const std::uint64_t lowest = size > 22 + 65535 ? size - 22 - 65535 : 0;
        while (le(z + eocd, 4) != 0x06054b50) {
            if (eocd == lowest) return false;
            --eocd;
        }
        std::uint64_t entries = le(z + eocd + 10, 2), cd_size = le(z + eocd + 12, 4), cd_offset = le(z + eocd + 16, 4);
        if ((entries == 0xFFFF || cd_size == 0xFFFFFFFF || cd_offset == 0xFFFFFFFF) && eocd >= 20 && le(z + eocd - 20, 4) == 0x07064b50) {
            const std::uint64_t rec = le(z + eocd - 20 + 8, 8);
            if (rec > size || size - rec < 56 || le(z + rec, 4) != 0x06064b50) return false;
            entries = le(z + rec + 32, 8), cd_size = le(z + rec + 40, 8), cd_offset = le(z + rec + 48, 8);
        }
        if (cd_offset > size || cd_size > size - cd_offset) return false;
        std::uint64_t p = cd_offset;
        const std::uint64_t end = cd_offset + cd_size;
        for (std::uint64_t i = 0; i < entries; ++i) {
            if (end - p < 46 || le(z + p, 4) != 0x02014b50) return false;
            const std::uint64_t method = le(z + p + 10, 2), name_len = le(z + p + 28, 2), extra_len = le(z + p + 30, 2),
                                comment_len = le(z + p + 32, 2);
            std::uint64_t comp = le(z + p + 20, 4), raw = le(z + p + 24, 4), local = le(z + p + 42, 4);
            if (end - p - 46 < name_len + extra_len + comment_len) return false;
            if (name_len == name.size() && std::memcmp(z + p + 46, name.data(), name_len) == 0) {
                // Zip64 extended information: the 8-byte values present, in this order, for fields saturated above.
                for (std::uint64_t q = p + 46 + name_len; q + 4 <= p + 46 + name_len + extra_len;) {
                    const std::uint64_t id = le(z + q, 2), len = le(z + q + 2, 2);
                    if (q + 4 + len > p + 46 + name_len + extra_len) return false;
                    if (id == 0x0001) {
                        std::uint64_t r = q + 4;
                        for (std::uint64_t *f : {&raw, &comp, &local})
                            if (*f == 0xFFFFFFFF) {
                                if (r + 8 > q + 4 + len) return false;
                                *f = le(z + r, 8);
                                r += 8;
                            }
                    }
                    q += 4 + len;
                }
                if (method != 0 || comp != bytes || raw != bytes || local > size || size - local < 30 || le(z + local, 4) != 0x04034b50)
                    return false;
                const std::uint64_t start = local + 30 + le(z + local + 26, 2) + le(z + local + 28, 2);
                if (start > size || size - start < bytes) return false;
                data_offset = start;
                return true;
            }
            p += 46 + name_len + extra_len + comment_len;
        }
        return false;
    }

    std::string path_;
    zip_t *za_ = nullptr;
    std::map<std::string, zip_uint64_t> index_;
    std::vector<Entry> list_;
};

class DirContainer : public Container {
public:
    explicit DirContainer(const fs::path &root) : root_(root) {
        std::error_code ec;
        for (auto it = fs::recursive_directory_iterator(root, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
            if (!it->is_regular_file(ec)) continue;
            list_.push_back({fs::relative(it->path(), root).generic_string(), static_cast<std::uint64_t>(it->file_size(ec))});
        }
        if (ec) throw FormatError("cannot list the directory: " + ec.message());
    }
    std::vector<Entry> entries() const override { return list_; }
    void read(const Entry &e, void *out) const override {
        hzio::MappedFile m((root_ / e.path).string());
        if (m.size() != e.bytes) throw FormatError("'" + e.path + "' changed size while reading");
        if (e.bytes) std::memcpy(out, m.data(), e.bytes);
    }
    bool locate(const Entry &e, Extent &out) const override {
        std::error_code ec;
        const fs::path file = root_ / e.path;
        if (fs::file_size(file, ec) != e.bytes || ec) return false;
        out.file = file.string();
        out.offset = 0;
        out.has_crc = false;
        return true;
    }

private:
    fs::path root_;
    std::vector<Entry> list_;
};

bool parse_dtype(const std::string &s, DType &t) {
    static const std::pair<const char *, DType> map[] = {{"int8", DType::I8},     {"int16", DType::I16},   {"int32", DType::I32},
                                                         {"int64", DType::I64},   {"uint8", DType::U8},    {"uint16", DType::U16},
                                                         {"uint32", DType::U32},  {"uint64", DType::U64},  {"float16", DType::F16},
                                                         {"float32", DType::F32}, {"float64", DType::F64}, {"bit", DType::Bit}};
    for (const auto &[n, d] : map)
        if (s == n) {
            t = d;
            return true;
        }
    return false;
}

// "name[.N].dtype" -> base, columns, dtype.
void split_name(const std::string &file, std::string &base, std::uint32_t &cols, DType &t) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    for (;;) {
        const auto dot = file.find('.', start);
        parts.push_back(file.substr(start, dot == std::string::npos ? std::string::npos : dot - start));
        if (dot == std::string::npos) break;
        start = dot + 1;
    }
    if (parts.size() < 2 || parts.size() > 3 || parts[0].empty())
        throw FormatError("entry name '" + file + "' is not name[.columns].dtype");
    if (!parse_dtype(parts.back(), t)) throw FormatError("entry '" + file + "' has unknown dtype '" + parts.back() + "'");
    base = parts[0];
    cols = 1;
    if (parts.size() == 3) {
        const std::string &c = parts[1];
        if (c.empty() || c.size() > 6 || !std::all_of(c.begin(), c.end(), ::isdigit) || std::stoul(c) == 0)
            throw FormatError("entry '" + file + "' has an invalid column count '" + c + "'");
        cols = static_cast<std::uint32_t>(std::stoul(c));
    }
}

std::uint64_t json_count(const nlohmann::json &h, const char *key) {
    if (!h.contains(key)) throw FormatError(std::string("header.json lacks ") + key);
    const auto &v = h[key];
    if (v.is_number_unsigned()) return v.get<std::uint64_t>();
    if (v.is_number_integer()) {
        const auto i = v.get<std::int64_t>();
        if (i < 0) throw FormatError(std::string("header.json ") + key + " = " + std::to_string(i) + " is negative");
        return static_cast<std::uint64_t>(i);
    }
    throw FormatError(std::string("header.json ") + key + " is not an integer");
}

}  // namespace

int probe(const unsigned char *head, std::uint64_t size) {
    if (size < 30 || std::memcmp(head, "PK\x03\x04", 4) != 0) return 0;
    const std::uint16_t name_len = static_cast<std::uint16_t>(head[26] | (head[27] << 8));
    if (30 + std::uint64_t(name_len) > size) return 30;
    const std::string name(reinterpret_cast<const char *>(head + 30), name_len);
    for (const char *p : {"header.json", "positions.", "offsets.", "dpv/", "dps/", "groups/", "dpg/"})
        if (name.rfind(p, 0) == 0) return 95;
    return 20;  // a zip, not obviously a TRX
}

File open(const std::string &path) {
    File f;
    std::error_code ec;
    if (fs::is_directory(path, ec)) {
        f.container = std::make_unique<DirContainer>(path);
        f.container_kind = "directory";
    } else {
        f.container = std::make_unique<ZipContainer>(path);
        f.container_kind = "zip";
    }
    const auto entries = f.container->entries();
    const Entry *header = nullptr;
    struct Named {
        Entry e;
        std::string dir, file;
    };
    std::vector<Named> named;
    for (const auto &e : entries) {
        const std::string &p = e.path;
        if (p.empty() || p[0] == '/' || p.find('\\') != std::string::npos || p.find("..") != std::string::npos)
            throw FormatError("entry name '" + p + "' is absolute or escapes the archive");
        if (p.back() == '/') continue;  // directory entry
        if (p == "header.json") {
            header = &e;
            continue;
        }
        if (p.size() > 5 && p.compare(p.size() - 5, 5, ".json") == 0) continue;  // side-cars (e.g. dps/algo.json)
        const auto slash = p.rfind('/');
        named.push_back({e, slash == std::string::npos ? "" : p.substr(0, slash), slash == std::string::npos ? p : p.substr(slash + 1)});
    }
    if (header == nullptr) throw FormatError("no header.json");
    if (header->bytes > (16u << 20)) throw FormatError("header.json is larger than 16 MiB");
    std::string text(header->bytes, '\0');
    f.container->read(*header, text.data());
    const nlohmann::json h = nlohmann::json::parse(text, nullptr, false);
    if (h.is_discarded() || !h.is_object()) throw FormatError("header.json is not a JSON object");
    f.nb_streamlines = json_count(h, "NB_STREAMLINES");
    f.nb_vertices = json_count(h, "NB_VERTICES");
    f.voxel_to_rasmm = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    if (h.contains("VOXEL_TO_RASMM")) {
        const auto &m = h["VOXEL_TO_RASMM"];
        if (!m.is_array() || m.size() != 4) throw FormatError("VOXEL_TO_RASMM is not a 4x4 list");
        for (int i = 0; i < 4; ++i) {
            if (!m[i].is_array() || m[i].size() != 4) throw FormatError("VOXEL_TO_RASMM is not a 4x4 list");
            for (int j = 0; j < 4; ++j) {
                if (!m[i][j].is_number()) throw FormatError("VOXEL_TO_RASMM holds a non-number");
                f.voxel_to_rasmm[4 * i + j] = m[i][j].get<double>();
            }
        }
    }
    if (h.contains("DIMENSIONS")) {
        const auto &d = h["DIMENSIONS"];
        if (!d.is_array() || d.size() != 3) throw FormatError("DIMENSIONS is not a list of 3");
        for (int i = 0; i < 3; ++i) {
            if (!d[i].is_number_integer() || d[i].get<std::int64_t>() < 0) throw FormatError("DIMENSIONS holds a non-integer");
            f.dims[i] = d[i].get<std::uint64_t>();
        }
    }
    for (auto it = h.begin(); it != h.end(); ++it)
        if (it.key() != "NB_STREAMLINES" && it.key() != "NB_VERTICES" && it.key() != "VOXEL_TO_RASMM" && it.key() != "DIMENSIONS")
            f.header_extra.emplace_back(it.key(), it.value().is_string() ? it.value().get<std::string>() : it.value().dump());

    const std::uint64_t N = f.nb_streamlines, V = f.nb_vertices;
    bool have_offsets = false;
    std::map<std::string, bool> groups;
    for (const auto &n : named) {
        std::string base;
        std::uint32_t cols;
        DType t;
        split_name(n.file, base, cols, t);
        const std::uint64_t es = dtype_size(t);
        auto need_rows = [&](std::uint64_t rows, const char *what) {
            if (rows != 0 && cols > std::numeric_limits<std::uint64_t>::max() / es / rows)
                throw FormatError("'" + n.e.path + "' declares an absurd size");
            if (n.e.bytes != rows * cols * es)
                throw FormatError("'" + n.e.path + "' holds " + std::to_string(n.e.bytes) + " bytes, " + what + " needs " +
                                  std::to_string(rows * cols * es));
        };
        if (n.dir.empty()) {
            if (base == "positions") {
                if (f.has_positions) throw FormatError("more than one positions entry");
                if (cols != 3) throw FormatError("positions must have 3 columns ('" + n.e.path + "')");
                if (t != DType::F16 && t != DType::F32 && t != DType::F64)
                    throw FormatError("positions must be float16/32/64, not " + std::string(dtype_name(t)));
                if (n.e.bytes % (3 * es) != 0) throw FormatError("'" + n.e.path + "' size is not a whole number of points");
                need_rows(V, "NB_VERTICES");
                f.positions = n.e;
                f.positions_dtype = t;
                f.has_positions = true;
            } else if (base == "offsets") {
                if (have_offsets) throw FormatError("more than one offsets entry");
                if (cols != 1) throw FormatError("offsets must have 1 column ('" + n.e.path + "')");
                if (t != DType::U32 && t != DType::U64)
                    throw FormatError("offsets must be uint32 or uint64, not " + std::string(dtype_name(t)));
                if (n.e.bytes == (N + 1) * es)
                    f.has_sentinel = true;
                else if (n.e.bytes == N * es)
                    f.has_sentinel = false;
                else
                    throw FormatError("'" + n.e.path + "' holds " + std::to_string(n.e.bytes / es) + " offsets for NB_STREAMLINES " +
                                      std::to_string(N));
                f.offsets = n.e;
                f.offsets_dtype = t;
                have_offsets = true;
            } else {
                throw FormatError("unknown top-level entry '" + n.e.path + "'");
            }
            continue;
        }
        Array a{Kind::Dpv, base, t, cols, 0, n.e};
        if (n.dir == "dpv") {
            a.rows = V;
            need_rows(V, "NB_VERTICES");
        } else if (n.dir == "dps") {
            a.kind = Kind::Dps;
            a.rows = N;
            need_rows(N, "NB_STREAMLINES");
        } else if (n.dir == "groups") {
            a.kind = Kind::Group;
            if (t != DType::U32) throw FormatError("group '" + base + "' must be uint32, not " + std::string(dtype_name(t)));
            if (cols != 1) throw FormatError("group '" + base + "' must have 1 column");
            a.rows = n.e.bytes / 4;
            if (n.e.bytes % 4) throw FormatError("group '" + base + "' size is not a multiple of 4");
            groups[base] = true;
        } else if (n.dir.rfind("dpg/", 0) == 0 && n.dir.find('/', 4) == std::string::npos && n.dir.size() > 4) {
            a.kind = Kind::Dpg;
            a.name = n.dir.substr(4) + "/" + base;
            a.rows = 1;
            need_rows(1, "a group's data");
        } else {
            throw FormatError("unknown entry '" + n.e.path + "'");
        }
        f.arrays.push_back(a);
    }
    for (const auto &a : f.arrays)
        if (a.kind == Kind::Dpg && !groups.count(a.name.substr(0, a.name.find('/'))))
            throw FormatError("dpg '" + a.name + "' has no matching group");
    if (!f.has_positions || !have_offsets) {
        if (N == 0 && V == 0 && !f.has_positions && !have_offsets) return f;  // header-only empty TRX
        throw FormatError(!f.has_positions ? "no positions entry" : "no offsets entry");
    }
    return f;
}

void read_streamlines(const File &f, float *positions, std::uint64_t *offsets, const std::function<bool()> &cancelled) {
    const std::uint64_t N = f.nb_streamlines, V = f.nb_vertices;
    offsets[0] = 0;
    if (!f.has_positions) return;
    if (cancelled && cancelled()) throw Cancelled{};
    // Offsets first (small): validate before touching the positions.
    {
        const std::uint64_t n = f.has_sentinel ? N + 1 : N;
        if (f.offsets_dtype == DType::U64) {
            f.container->read(f.offsets, offsets);
        } else {
            std::vector<std::uint32_t> tmp(n);
            f.container->read(f.offsets, tmp.data());
            std::copy(tmp.begin(), tmp.end(), offsets);
        }
        if constexpr (std::endian::native == std::endian::big) throw FormatError("big-endian hosts are not supported");
        if (!f.has_sentinel) offsets[N] = V;
        if (N > 0 && offsets[0] != 0) throw FormatError("offsets[0] = " + std::to_string(offsets[0]) + ", expected 0");
        for (std::uint64_t i = 1; i <= N; ++i)
            if (offsets[i] < offsets[i - 1]) throw FormatError("offsets decrease at streamline " + std::to_string(i - 1));
        if (offsets[N] != V) throw FormatError("final offset " + std::to_string(offsets[N]) + " != NB_VERTICES " + std::to_string(V));
    }
    if (cancelled && cancelled()) throw Cancelled{};
    if (positions == nullptr) return;  // offsets only: the host mapped the positions
    if (f.positions_dtype == DType::F32) {
        f.container->read(f.positions, positions);  // straight into the host's buffer
    } else if (f.positions_dtype == DType::F16) {
        std::vector<std::uint16_t> tmp(3 * V);
        f.container->read(f.positions, tmp.data());
        for (std::uint64_t i = 0; i < 3 * V; ++i) positions[i] = half_to_float(tmp[i]);
    } else {
        std::vector<double> tmp(3 * V);
        f.container->read(f.positions, tmp.data());
        for (std::uint64_t i = 0; i < 3 * V; ++i) positions[i] = static_cast<float>(tmp[i]);
    }
    for (std::uint64_t b = 0; b < 3 * V; b += 4096) {  // branch-free blocks; locate only on failure
        const std::uint64_t e = std::min<std::uint64_t>(3 * V, b + 4096);
        unsigned bad = 0;
        for (std::uint64_t i = b; i < e; ++i) bad |= !(std::fabs(positions[i]) <= 3.4028235e38f);
        if (bad)
            for (std::uint64_t i = b; i < e; ++i)
                if (!std::isfinite(positions[i])) throw FormatError("positions hold a non-finite value at vertex " + std::to_string(i / 3));
    }
}

bool locate_positions(const File &f, Extent &out) {
    if (!f.has_positions || f.positions_dtype != DType::F32 || f.nb_vertices == 0) return false;
    if constexpr (std::endian::native == std::endian::big) return false;
    return f.container->locate(f.positions, out);
}

void read_array(const File &f, const Array &a, void *out) {
    f.container->read(a.entry, out);
    if (a.kind == Kind::Group) {
        const auto *g = static_cast<const std::uint32_t *>(out);
        for (std::uint64_t i = 0; i < a.rows; ++i)
            if (g[i] >= f.nb_streamlines)
                throw FormatError("group '" + a.name + "' holds streamline " + std::to_string(g[i]) + " >= NB_STREAMLINES " +
                                  std::to_string(f.nb_streamlines));
    }
}

namespace {

// A libzip source yielding, for each streamline written (k = 0..N-1, the
// stored streamline s = sel[k], or k without a selection), the rows
// [off[s], off[s+1] - gap) of `base` (row_bytes each: 12 for positions): one
// run of bytes per streamline, read where they lie (no copy of the whole
// array). The positions without a mapped TCK's delimiters, or the kept
// streamlines' positions and per-vertex rows.
class RunSource {
public:
    RunSource(const void *base, std::size_t row_bytes, const std::uint64_t *off, const std::uint64_t *sel, std::uint64_t N,
              std::uint32_t gap, std::uint64_t bytes)
        : p_(static_cast<const unsigned char *>(base)), row_(row_bytes), off_(off), sel_(sel), N_(N), gap_(gap), bytes_(bytes) {
        zip_error_init(&error_);
    }
    ~RunSource() { zip_error_fini(&error_); }

    static zip_int64_t callback(void *ud, void *data, zip_uint64_t len, zip_source_cmd_t cmd) {
        auto *g = static_cast<RunSource *>(ud);
        switch (cmd) {
        case ZIP_SOURCE_OPEN:
            g->k_ = 0;
            g->b_ = 0;
            return 0;
        case ZIP_SOURCE_READ: {
            auto *out = static_cast<unsigned char *>(data);
            zip_uint64_t done = 0;
            while (done < len && g->k_ < g->N_) {
                const std::uint64_t s = g->sel_ != nullptr ? g->sel_[g->k_] : g->k_;
                const std::uint64_t run = g->row_ * (g->off_[s + 1] - g->gap_ - g->off_[s]);
                const std::uint64_t take = std::min<std::uint64_t>(len - done, run - g->b_);
                std::memcpy(out + done, g->p_ + g->row_ * g->off_[s] + g->b_, take);
                done += take;
                g->b_ += take;
                if (g->b_ == run) ++g->k_, g->b_ = 0;
            }
            return static_cast<zip_int64_t>(done);
        }
        case ZIP_SOURCE_CLOSE: return 0;
        case ZIP_SOURCE_STAT: {
            auto *st = static_cast<zip_stat_t *>(data);
            zip_stat_init(st);
            st->size = g->bytes_;
            st->valid |= ZIP_STAT_SIZE;
            return sizeof(*st);
        }
        case ZIP_SOURCE_ERROR: return zip_error_to_data(&g->error_, data, len);
        case ZIP_SOURCE_FREE: delete g; return 0;
        case ZIP_SOURCE_SUPPORTS:
            return zip_source_make_command_bitmap(ZIP_SOURCE_OPEN, ZIP_SOURCE_READ, ZIP_SOURCE_CLOSE, ZIP_SOURCE_STAT, ZIP_SOURCE_ERROR,
                                                  ZIP_SOURCE_FREE, -1);
        default: zip_error_set(&g->error_, ZIP_ER_OPNOTSUPP, 0); return -1;
        }
    }

private:
    const unsigned char *p_;
    std::size_t row_;
    const std::uint64_t *off_, *sel_;
    std::uint64_t N_;
    std::uint32_t gap_;
    std::uint64_t bytes_;
    std::uint64_t k_ = 0, b_ = 0;  // the streamline being read, and the bytes of it already given
    zip_error_t error_;
};

}  // namespace

void write(const std::string &path, const float *positions, std::uint64_t V_stored, const std::uint64_t *offsets, std::uint64_t N_stored,
           const std::array<double, 16> &aff, const std::array<std::uint64_t, 3> &dims, const std::vector<WriteArray> &arrays,
           const std::vector<std::pair<std::string, std::string>> &header_extra, std::uint32_t gap, const std::uint64_t *selection,
           std::uint64_t nb_selected) {
    if (gap > 1) throw FormatError("streamlines with gap " + std::to_string(gap) + " (0 or 1 expected)");
    for (const auto &a : arrays)
        if (gap != 0 && a.kind == Kind::Dpv) throw FormatError("per-vertex array '" + a.name + "' with delimited streamlines");
    const std::uint64_t N = selection != nullptr ? nb_selected : N_stored;  // the streamlines written
    auto source = [&](std::uint64_t k) { return selection != nullptr ? selection[k] : k; };
    std::uint64_t V = 0;  // the vertices written
    for (std::uint64_t k = 0; k < N; ++k) {
        const std::uint64_t s = source(k);
        for (std::uint64_t i = 3 * offsets[s]; i < 3 * (offsets[s + 1] - gap); ++i)
            if (!std::isfinite(positions[i])) throw FormatError("non-finite coordinate at vertex " + std::to_string(i / 3 - s * gap));
        V += offsets[s + 1] - gap - offsets[s];
    }
    (void)V_stored;
    const std::uint64_t *stored = offsets;  // (into positions, gaps included)
    std::vector<std::uint64_t> written;     // with a gap or a selection: the offsets as written
    const bool runs = gap != 0 || selection != nullptr;
    if (runs) {
        written.resize(N + 1);
        written[0] = 0;
        for (std::uint64_t k = 0; k < N; ++k) written[k + 1] = written[k] + (offsets[source(k) + 1] - gap - offsets[source(k)]);
        offsets = written.data();
    }
    nlohmann::json h = nlohmann::json::object();
    for (const auto &[k, v] : header_extra) {  // other formats' header entries, as extra keys (allowed by the spec)
        const nlohmann::json parsed = nlohmann::json::parse(v, nullptr, false);
        h[k] = !parsed.is_discarded() && (parsed.is_object() || parsed.is_array()) ? parsed : nlohmann::json(v);
    }
    h["NB_STREAMLINES"] = N;
    h["NB_VERTICES"] = V;
    h["DIMENSIONS"] = {dims[0], dims[1], dims[2]};
    h["VOXEL_TO_RASMM"] = nlohmann::json::array();
    for (int i = 0; i < 4; ++i) h["VOXEL_TO_RASMM"].push_back({aff[4 * i], aff[4 * i + 1], aff[4 * i + 2], aff[4 * i + 3]});
    const std::string header = h.dump();
    int code = 0;
    zip_t *za = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &code);
    if (za == nullptr) throw FormatError("cannot create the zip archive");
    auto add_source = [&](const std::string &name, zip_source_t *src) {
        if (src == nullptr) throw FormatError(std::string("zip: ") + zip_strerror(za));
        const zip_int64_t idx = zip_file_add(za, name.c_str(), src, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE);
        if (idx < 0) {
            zip_source_free(src);
            throw FormatError(std::string("zip: ") + zip_strerror(za));
        }
        zip_set_file_compression(za, static_cast<zip_uint64_t>(idx), ZIP_CM_STORE, 0);  // stored: readers can map it
    };
    auto add = [&](const std::string &name, const void *data, std::uint64_t bytes) {
        add_source(name, zip_source_buffer(za, data, bytes, 0));
    };
    // Rows per vertex (positions, dpv) of the streamlines written, where they lie.
    auto add_runs = [&](const std::string &name, const void *data, std::size_t row_bytes, std::uint32_t g) {
        auto *r = new RunSource(data, row_bytes, stored, selection, N, g, row_bytes * V);
        zip_source_t *src = zip_source_function(za, &RunSource::callback, r);
        if (src == nullptr) delete r;  // (otherwise the source owns it: ZIP_SOURCE_FREE)
        add_source(name, src);
    };
    try {
        // Positions first, their data at byte 64 of the file: a padding extra
        // field in the local header (id 0xD935, the one Android's zipalign
        // uses) makes 30 + 19 (name) + 4 + 11 = 64, so readers can map the
        // floats aligned. (A Zip64 local extra, 20 bytes, keeps the alignment.)
        const std::uint64_t pidx = static_cast<std::uint64_t>(zip_get_num_entries(za, 0));
        if (!runs)
            add("positions.3.float32", positions, 3 * V * sizeof(float));
        else
            add_runs("positions.3.float32", positions, 3 * sizeof(float), gap);
        static const zip_uint8_t pad[11] = {};
        if (zip_file_extra_field_set(za, pidx, 0xD935, ZIP_EXTRA_FIELD_NEW, pad, sizeof pad, ZIP_FL_LOCAL) != 0)
            throw FormatError(std::string("zip: ") + zip_strerror(za));
        add("header.json", header.data(), header.size());
        add("offsets.uint64", offsets, (N + 1) * sizeof(std::uint64_t));
        std::map<std::string, bool> seen;
        for (const auto &a : arrays) {
            std::string cols;  // (built piecewise: GCC 12 warns falsely on "." + to_string)
            if (a.cols > 1) cols.append(".").append(std::to_string(a.cols));
            std::string name;
            switch (a.kind) {
            case Kind::Dpv: name = "dpv/" + a.name + cols + "." + dtype_name(a.dtype); break;
            case Kind::Dps: name = "dps/" + a.name + cols + "." + dtype_name(a.dtype); break;
            case Kind::Group: name = "groups/" + a.name + ".uint32"; break;
            case Kind::Dpg: {
                const auto slash = a.name.find('/');
                name = "dpg/" + a.name.substr(0, slash) + "/" + a.name.substr(slash + 1) + cols + "." + dtype_name(a.dtype);
                break;
            }
            }
            if (seen[name]) throw FormatError("two arrays map to the entry '" + name + "'");
            seen[name] = true;
            if (a.kind == Kind::Dpv && selection != nullptr)
                add_runs(name, a.data, a.cols * dtype_size(a.dtype), 0);
            else
                add(name, a.data, a.rows * a.cols * dtype_size(a.dtype));
        }
    } catch (...) {
        zip_discard(za);
        throw;
    }
    if (zip_close(za) != 0) {
        const std::string m = zip_strerror(za);
        zip_discard(za);
        throw FormatError("writing the zip archive failed: " + m);
    }
}

}  // namespace trx
