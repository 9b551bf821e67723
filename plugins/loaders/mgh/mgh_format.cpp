// FreeSurfer MGH/MGZ volumes (mgh_format.hpp).
#include "mgh_format.hpp"

#include "gzip.hpp"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>

namespace mgh {

namespace {

std::uint32_t be32(const unsigned char *p) {
    return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | std::uint32_t(p[3]);
}
std::int32_t i32(const unsigned char *p) { return static_cast<std::int32_t>(be32(p)); }
std::int16_t i16(const unsigned char *p) { return static_cast<std::int16_t>((p[0] << 8) | p[1]); }
float f32(const unsigned char *p) { return std::bit_cast<float>(be32(p)); }
void put32(unsigned char *p, std::uint32_t v) {
    p[0] = static_cast<unsigned char>(v >> 24), p[1] = static_cast<unsigned char>(v >> 16);
    p[2] = static_cast<unsigned char>(v >> 8), p[3] = static_cast<unsigned char>(v);
}
void putf(unsigned char *p, double v) { put32(p, std::bit_cast<std::uint32_t>(static_cast<float>(v))); }

bool ends_with(const std::string &s, const std::string &suffix) {
    return s.size() >= suffix.size() &&
           std::equal(suffix.rbegin(), suffix.rend(), s.rbegin(), [](char a, char b) { return std::tolower(a) == std::tolower(b); });
}

// The header's fields from its 284 bytes (`size` of them present).
Header parse(const unsigned char *b, std::uint64_t size) {
    if (size < 90) throw FormatError("truncated header: " + std::to_string(size) + " bytes, an MGH header has 284");
    Header h;
    if (const std::int32_t v = i32(b); v != 1) throw FormatError("not an MGH volume (version " + std::to_string(v) + ", expected 1)");
    std::uint64_t n = 1;
    for (int i = 0; i < 4; ++i) {
        const std::int32_t d = i32(b + 4 + 4 * i);
        if (d < 1) throw FormatError("dimension " + std::to_string(i) + " is " + std::to_string(d) + " (must be at least 1)");
        h.dims[static_cast<std::size_t>(i)] = d;
        if (n > std::numeric_limits<std::uint64_t>::max() / static_cast<std::uint64_t>(d)) throw FormatError("absurd size");
        n *= static_cast<std::uint64_t>(d);
    }
    h.type_code = i32(b + 20);
    switch (h.type_code) {
    case 0: h.dtype = DType::U8; break;
    case 4: h.dtype = DType::I16; break;
    case 1: h.dtype = DType::I32; break;
    case 3: h.dtype = DType::F32; break;
    default: throw FormatError("voxel type " + std::to_string(h.type_code) + " is not one of 0 (uchar), 1 (int), 3 (float), 4 (short)");
    }
    h.nb_voxels = n;
    if (n > std::numeric_limits<std::uint64_t>::max() / 8) throw FormatError("absurd size");
    h.data_bytes = n * dtype_size(h.dtype);
    h.dof = i32(b + 24);
    h.good_ras = i16(b + 28) != 0;
    if (h.good_ras) {
        for (int i = 0; i < 3; ++i) h.delta[static_cast<std::size_t>(i)] = f32(b + 30 + 4 * i);
        for (int i = 0; i < 9; ++i) h.mdc[static_cast<std::size_t>(i)] = f32(b + 42 + 4 * i);
        for (int i = 0; i < 3; ++i) h.c_ras[static_cast<std::size_t>(i)] = f32(b + 78 + 4 * i);
        for (double v : h.delta)
            if (!(std::isfinite(v) && v > 0)) throw FormatError("voxel size " + std::to_string(v) + " (must be positive)");
        for (double v : h.mdc)
            if (!std::isfinite(v)) throw FormatError("direction cosines are not finite");
        for (double v : h.c_ras)
            if (!std::isfinite(v)) throw FormatError("centre is not finite");
    } else {  // (FreeSurfer's and nibabel's default: coronal slices, LIA)
        h.mdc = {-1, 0, 0, 0, 0, 1, 0, -1, 0};
    }
    return h;
}

void read_footer(Header &h, const unsigned char *p, std::uint64_t avail) {
    if (avail < 20) return;
    h.has_footer = true;
    h.tr = f32(p), h.flip_angle = f32(p + 4), h.te = f32(p + 8), h.ti = f32(p + 12), h.fov = f32(p + 16);
}

}  // namespace

std::size_t dtype_size(DType t) {
    switch (t) {
    case DType::U8: return 1;
    case DType::I16: return 2;
    case DType::I32: return 4;
    case DType::F32: return 4;
    }
    return 1;
}

std::array<double, 16> Header::affine() const {
    // Column j: direction cosine j times voxel size j; the translation puts
    // voxel dims / 2 at c_ras.
    std::array<double, 16> a{};
    for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) a[static_cast<std::size_t>(4 * i + j)] = mdc[static_cast<std::size_t>(3 * j + i)] * delta[j];
    for (int i = 0; i < 3; ++i) {
        double centre = 0;
        for (int j = 0; j < 3; ++j)
            centre += a[static_cast<std::size_t>(4 * i + j)] * static_cast<double>(dims[static_cast<std::size_t>(j)]) / 2;
        a[static_cast<std::size_t>(4 * i + 3)] = c_ras[static_cast<std::size_t>(i)] - centre;
    }
    a[15] = 1;
    return a;
}

int probe(const unsigned char *head, std::uint64_t size, const char *name_hint) {
    if (size >= 2 && head[0] == 0x1f && head[1] == 0x8b)
        return name_hint && (ends_with(name_hint, ".mgz") || ends_with(name_hint, ".mgh.gz")) ? 60 : 0;
    if (size < 24 || i32(head) != 1) return 0;
    for (int i = 0; i < 4; ++i)
        if (i32(head + 4 + 4 * i) < 1) return 0;
    const std::int32_t t = i32(head + 20);
    if (t != 0 && t != 1 && t != 3 && t != 4) return 0;
    return name_hint && ends_with(name_hint, ".mgh") ? 80 : 40;  // (version 1 and sizes: weak alone)
}

Volume Volume::open(const std::string &path) {
    Volume v;
    v.gz_ = ends_with(path, ".mgz") || ends_with(path, ".gz");
    if (v.gz_) {
        // The header first, then exactly what it declares (and the footer):
        // a stream that holds less is truncated, one that declares more than
        // it holds costs only what it holds.
        const std::vector<unsigned char> head = hzio::gunzip(path, kDataOffset);
        v.h_ = parse(head.data(), head.size());
        if (head.size() < kDataOffset)
            throw FormatError("truncated header: " + std::to_string(head.size()) + " bytes, an MGH header has 284");
        const std::uint64_t want = kDataOffset + v.h_.data_bytes + 20;
        v.inflated_ = hzio::gunzip(path, want);
        if (v.inflated_.size() < kDataOffset + v.h_.data_bytes)
            throw FormatError("truncated: " + std::to_string(v.inflated_.size() - kDataOffset) + " bytes of voxels, the header declares " +
                              std::to_string(v.h_.data_bytes));
        read_footer(v.h_, v.inflated_.data() + kDataOffset + v.h_.data_bytes, v.inflated_.size() - kDataOffset - v.h_.data_bytes);
        v.data_ = v.inflated_.data() + kDataOffset;
    } else {
        v.mapped_ = std::make_shared<hzio::MappedFile>(path);
        const hzio::MappedFile &m = *v.mapped_;
        v.h_ = parse(m.data(), m.size());
        if (m.size() < kDataOffset + v.h_.data_bytes)
            throw FormatError("truncated: the file has " + std::to_string(m.size()) + " bytes, the header declares " +
                              std::to_string(kDataOffset + v.h_.data_bytes));
        read_footer(v.h_, m.data() + kDataOffset + v.h_.data_bytes, m.size() - kDataOffset - v.h_.data_bytes);
        v.data_ = m.data() + kDataOffset;
    }
    return v;
}

void write(const std::string &path, bool gz, DType dtype, const std::vector<std::uint64_t> &dims, const void *voxels,
           const std::array<double, 16> &A, double tr, double flip_angle, double te, double ti, double fov) {
    if (dims.empty() || dims.size() > 4) throw FormatError("MGH holds 1 to 4 dimensions, not " + std::to_string(dims.size()));
    unsigned char h[kDataOffset] = {};
    put32(h, 1);
    std::array<std::uint64_t, 4> d{1, 1, 1, 1};
    std::uint64_t n = 1;
    for (std::size_t i = 0; i < dims.size(); ++i) {
        if (dims[i] < 1 || dims[i] > 0x7FFFFFFF) throw FormatError("dimension " + std::to_string(dims[i]) + " does not fit MGH");
        d[i] = dims[i];
        n *= dims[i];
    }
    for (int i = 0; i < 4; ++i) put32(h + 4 + 4 * i, static_cast<std::uint32_t>(d[static_cast<std::size_t>(i)]));
    const int code = dtype == DType::U8 ? 0 : dtype == DType::I16 ? 4 : dtype == DType::I32 ? 1 : 3;
    put32(h + 20, static_cast<std::uint32_t>(code));
    h[28] = 0, h[29] = 1;  // goodRASFlag
    // Voxel sizes: the columns' lengths; direction cosines: the columns
    // over them; c_ras: where voxel dims / 2 lands.
    for (int j = 0; j < 3; ++j) {
        const double len = std::sqrt(A[static_cast<std::size_t>(j)] * A[static_cast<std::size_t>(j)] +
                                     A[static_cast<std::size_t>(4 + j)] * A[static_cast<std::size_t>(4 + j)] +
                                     A[static_cast<std::size_t>(8 + j)] * A[static_cast<std::size_t>(8 + j)]);
        if (!(len > 0) || !std::isfinite(len)) throw FormatError("the affine's column " + std::to_string(j) + " is not a voxel axis");
        putf(h + 30 + 4 * j, len);
        for (int i = 0; i < 3; ++i) putf(h + 42 + 12 * j + 4 * i, A[static_cast<std::size_t>(4 * i + j)] / len);
    }
    for (int i = 0; i < 3; ++i) {
        double c = A[static_cast<std::size_t>(4 * i + 3)];
        for (int j = 0; j < 3; ++j) c += A[static_cast<std::size_t>(4 * i + j)] * static_cast<double>(d[static_cast<std::size_t>(j)]) / 2;
        putf(h + 78 + 4 * i, c);
    }
    // The voxels, big-endian.
    const std::size_t es = dtype_size(dtype);
    std::vector<unsigned char> body(n * es);
    std::memcpy(body.data(), voxels, body.size());
    static_assert(std::endian::native == std::endian::little, "the MGH writer assumes a little-endian host");
    if (es > 1)
        for (std::size_t k = 0; k < body.size(); k += es)
            std::reverse(body.begin() + static_cast<std::ptrdiff_t>(k), body.begin() + static_cast<std::ptrdiff_t>(k + es));
    unsigned char footer[20];
    putf(footer, tr), putf(footer + 4, flip_angle), putf(footer + 8, te), putf(footer + 12, ti), putf(footer + 16, fov);
    hzio::write_parts(path, gz, {{h, sizeof h}, {body.data(), body.size()}, {footer, sizeof footer}});
}

}  // namespace mgh
