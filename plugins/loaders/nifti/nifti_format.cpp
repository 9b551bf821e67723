// NIfTI-1/-2 (nifti1.h, nifti2.h; nibabel nifti1.py for the affine rules).
#include "nifti_format.hpp"

#include "gzip.hpp"
#include "mapped_file.hpp"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

namespace nifti {

namespace fs = std::filesystem;

std::size_t dtype_size(DType t) {
    switch (t) {
    case DType::U8:
    case DType::I8: return 1;
    case DType::U16:
    case DType::I16: return 2;
    case DType::U32:
    case DType::I32:
    case DType::F32: return 4;
    case DType::U64:
    case DType::I64:
    case DType::F64: return 8;
    case DType::RGB24: return 3;
    case DType::RGBA32: return 4;
    }
    return 0;
}

namespace {

template <class T>
T rd(const unsigned char *p, bool swap) {
    using U = std::conditional_t<sizeof(T) == 2, std::uint16_t, std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>;
    U u;
    std::memcpy(&u, p, sizeof u);
    if (swap) {
        if constexpr (sizeof(T) == 2)
            u = __builtin_bswap16(u);
        else if constexpr (sizeof(T) == 4)
            u = __builtin_bswap32(u);
        else
            u = __builtin_bswap64(u);
    }
    return std::bit_cast<T>(u);
}

bool ends_with(const std::string &s, const std::string &suffix) {
    if (s.size() < suffix.size()) return false;
    return std::equal(suffix.rbegin(), suffix.rend(), s.rbegin(), [](char a, char b) { return std::tolower(a) == std::tolower(b); });
}

// A gzip stream inflated up to `limit` bytes (hzio::gunzip), its damage a
// format error.
std::vector<unsigned char> gunzip(const std::string &path, std::uint64_t limit) {
    try {
        return hzio::gunzip(path, limit);
    } catch (const hzio::IoError &e) {
        throw FormatError(e.what());
    } catch (const hzio::CorruptData &e) {
        throw FormatError(e.what());
    }
}

std::array<double, 16> mat_identity() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }

void parse(const unsigned char *b, std::uint64_t size, Header &h, bool single) {
    if (size < 348) throw FormatError("file is " + std::to_string(size) + " bytes, shorter than a NIfTI header");
    const std::int32_t s0 = rd<std::int32_t>(b, false), s1 = rd<std::int32_t>(b, true);
    if (s0 == 348 || s1 == 348) {
        h.version = 1;
        h.swap = s0 != 348;
    } else if (s0 == 540 || s1 == 540) {
        h.version = 2;
        h.swap = s0 != 540;
        if (size < 540) throw FormatError("file is " + std::to_string(size) + " bytes, shorter than a NIfTI-2 header");
    } else {
        throw FormatError("sizeof_hdr is " + std::to_string(s0) + ", not 348 (NIfTI-1) or 540 (NIfTI-2) in either byte order");
    }
    const bool sw = h.swap;
    std::int64_t dim[8];
    double pix[8];
    double quat[6], srow[12];
    if (h.version == 1) {
        const std::string magic(reinterpret_cast<const char *>(b + 344), 4);
        if (magic != std::string("n+1\0", 4) && magic != std::string("ni1\0", 4))
            throw FormatError("magic is not 'n+1' or 'ni1' (not NIfTI-1)");
        if (single && magic[1] != '+') throw FormatError("magic 'ni1' (header/image pair) in a single .nii file");
        for (int i = 0; i < 8; ++i) dim[i] = rd<std::int16_t>(b + 40 + 2 * i, sw);
        h.datatype_code = rd<std::int16_t>(b + 70, sw);
        for (int i = 0; i < 8; ++i) pix[i] = rd<float>(b + 76 + 4 * i, sw);
        const double vo = rd<float>(b + 108, sw);
        if (!std::isfinite(vo) || vo < 0 || vo > 1e15) throw FormatError("vox_offset " + std::to_string(vo) + " is not a valid offset");
        h.vox_offset = static_cast<std::uint64_t>(vo);
        h.scl_slope = rd<float>(b + 112, sw);
        h.scl_inter = rd<float>(b + 116, sw);
        h.qform_code = rd<std::int16_t>(b + 252, sw);
        h.sform_code = rd<std::int16_t>(b + 254, sw);
        for (int i = 0; i < 6; ++i) quat[i] = rd<float>(b + 256 + 4 * i, sw);
        for (int i = 0; i < 12; ++i) srow[i] = rd<float>(b + 280 + 4 * i, sw);
    } else {
        const std::string magic(reinterpret_cast<const char *>(b + 4), 8);
        if (magic != std::string("n+2\0\r\n\032\n", 8) && magic != std::string("ni2\0\r\n\032\n", 8))
            throw FormatError("magic is not 'n+2' or 'ni2' followed by \\r\\n\\032\\n (not NIfTI-2, or damaged by a text-mode transfer)");
        if (single && magic[1] != '+') throw FormatError("magic 'ni2' (header/image pair) in a single .nii file");
        h.datatype_code = rd<std::int16_t>(b + 12, sw);
        for (int i = 0; i < 8; ++i) dim[i] = rd<std::int64_t>(b + 16 + 8 * i, sw);
        for (int i = 0; i < 8; ++i) pix[i] = rd<double>(b + 104 + 8 * i, sw);
        const std::int64_t vo = rd<std::int64_t>(b + 168, sw);
        if (vo < 0) throw FormatError("vox_offset " + std::to_string(vo) + " is negative");
        h.vox_offset = static_cast<std::uint64_t>(vo);
        h.scl_slope = rd<double>(b + 176, sw);
        h.scl_inter = rd<double>(b + 184, sw);
        h.qform_code = rd<std::int32_t>(b + 344, sw);
        h.sform_code = rd<std::int32_t>(b + 348, sw);
        for (int i = 0; i < 6; ++i) quat[i] = rd<double>(b + 352 + 8 * i, sw);
        for (int i = 0; i < 12; ++i) srow[i] = rd<double>(b + 400 + 8 * i, sw);
    }
    if (dim[0] < 1 || dim[0] > 7) throw FormatError("dim[0] = " + std::to_string(dim[0]) + " is not 1..7");
    h.ndim = static_cast<int>(dim[0]);
    h.nb_voxels = 1;
    for (int i = 1; i <= h.ndim; ++i) {
        if (dim[i] < 1) throw FormatError("dim[" + std::to_string(i) + "] = " + std::to_string(dim[i]) + " is not positive");
        if (static_cast<std::uint64_t>(dim[i]) > (std::uint64_t(1) << 62) / h.nb_voxels)
            throw FormatError("dimensions multiply to more than 2^62 voxels");
        h.nb_voxels *= static_cast<std::uint64_t>(dim[i]);
        h.dims[static_cast<std::size_t>(i - 1)] = dim[i];
    }
    switch (h.datatype_code) {
    case 2: h.dtype = DType::U8; break;
    case 4: h.dtype = DType::I16; break;
    case 8: h.dtype = DType::I32; break;
    case 16: h.dtype = DType::F32; break;
    case 64: h.dtype = DType::F64; break;
    case 256: h.dtype = DType::I8; break;
    case 512: h.dtype = DType::U16; break;
    case 768: h.dtype = DType::U32; break;
    case 1024: h.dtype = DType::I64; break;
    case 1280: h.dtype = DType::U64; break;
    case 128: h.dtype = DType::RGB24; break;
    case 2304: h.dtype = DType::RGBA32; break;
    case 32:
    case 1536:
    case 1792:
    case 2048: throw FormatError("datatype " + std::to_string(h.datatype_code) + " (complex or float128) is not supported");
    default: throw FormatError("unknown datatype code " + std::to_string(h.datatype_code));
    }
    if (h.nb_voxels > std::numeric_limits<std::uint64_t>::max() / 8) throw FormatError("absurd size");
    for (int i = 0; i < 8; ++i) h.pixdim[static_cast<std::size_t>(i)] = pix[i];
    const std::uint64_t min_offset = h.version == 1 ? 352 : 544;
    if (single && h.vox_offset < min_offset) {
        h.warnings.push_back("vox_offset " + std::to_string(h.vox_offset) + " is inside the header; using " + std::to_string(min_offset));
        h.vox_offset = min_offset;
    }
    // Scaling applies iff slope is finite and non-zero (not to RGB).
    if (std::isfinite(h.scl_slope) && h.scl_slope != 0 && h.dtype != DType::RGB24 && h.dtype != DType::RGBA32) {
        if (!std::isfinite(h.scl_inter)) {
            h.warnings.emplace_back("scl_inter is not finite: using 0");
            h.scl_inter = 0;
        }
    } else {
        h.scl_slope = 1;
        h.scl_inter = 0;
    }
    if (h.qform_code < 0 || h.qform_code > 5) h.qform_code = 0;
    if (h.sform_code < 0 || h.sform_code > 5) h.sform_code = 0;
    // Affine: sform > qform > nibabel's base affine.
    auto &A = h.affine;
    A = mat_identity();
    if (h.sform_code > 0) {
        for (int i = 0; i < 12; ++i) A[static_cast<std::size_t>(i)] = srow[i];
        h.affine_source = "sform";
    } else if (h.qform_code > 0) {
        const double bq = quat[0], cq = quat[1], dq = quat[2];
        const double a2 = 1.0 - (bq * bq + cq * cq + dq * dq);
        const double a = a2 > 0 ? std::sqrt(a2) : 0.0;
        const double R[9] = {a * a + bq * bq - cq * cq - dq * dq, 2 * (bq * cq - a * dq), 2 * (bq * dq + a * cq), 2 * (bq * cq + a * dq),
                             a * a + cq * cq - bq * bq - dq * dq, 2 * (cq * dq - a * bq), 2 * (bq * dq - a * cq), 2 * (cq * dq + a * bq),
                             a * a + dq * dq - bq * bq - cq * cq};
        double qfac = pix[0];
        if (qfac != 1 && qfac != -1) qfac = 1;
        const double z[3] = {std::fabs(pix[1]), std::fabs(pix[2]), std::fabs(pix[3]) * qfac};
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) A[static_cast<std::size_t>(4 * i + j)] = R[3 * i + j] * z[j];
            A[static_cast<std::size_t>(4 * i + 3)] = quat[3 + i];
        }
        h.affine_source = "qform";
    } else {
        double shape[3], zoom[3];
        for (int i = 0; i < 3; ++i) {
            shape[i] = i < h.ndim ? double(dim[i + 1]) : 1.0;
            zoom[i] = i < h.ndim ? pix[i + 1] : 1.0;
        }
        zoom[0] = -zoom[0];  // nibabel's Analyze default x flip
        for (int i = 0; i < 3; ++i) {
            A[static_cast<std::size_t>(4 * i + i)] = zoom[i];
            A[static_cast<std::size_t>(4 * i + 3)] = -(shape[i] - 1) / 2.0 * zoom[i];
        }
        h.affine_source = "base";
    }
    for (double v : A)
        if (!std::isfinite(v)) throw FormatError("the " + h.affine_source + " affine holds a non-finite value");
}

}  // namespace

int probe(const unsigned char *b, std::uint64_t size) {
    if (size >= 348) {
        for (bool sw : {false, true})
            if (rd<std::int32_t>(b, sw) == 348 && (std::memcmp(b + 344, "n+1", 4) == 0 || std::memcmp(b + 344, "ni1", 4) == 0)) return 100;
    }
    if (size >= 12) {
        for (bool sw : {false, true})
            if (rd<std::int32_t>(b, sw) == 540 &&
                (std::memcmp(b + 4, "n+2\0\r\n\032\n", 8) == 0 || std::memcmp(b + 4, "ni2\0\r\n\032\n", 8) == 0))
                return 100;
    }
    if (size >= 2 && b[0] == 0x1f && b[1] == 0x8b) return 20;  // gzip: maybe .nii.gz
    return 0;
}

struct Image::Impl {
    std::unique_ptr<hzio::MappedFile> map;  // uncompressed data file
    std::vector<unsigned char> inflated;    // gzipped data file
    const unsigned char *data = nullptr;
};

Image::Image() : impl_(std::make_unique<Impl>()) {}
Image::Image(Image &&) noexcept = default;
Image::~Image() = default;
const unsigned char *Image::data() const { return impl_->data; }

Image Image::open(const std::string &path) {
    Image img;
    Header &h = img.h_;
    const bool gz = ends_with(path, ".gz");
    const std::string base = gz ? path.substr(0, path.size() - 3) : path;
    std::string hdr_path = path, img_path = path;
    bool pair = false;
    if (ends_with(base, ".hdr") || ends_with(base, ".img")) {
        pair = true;
        const std::string stem = base.substr(0, base.size() - 4);
        const std::string ext = gz ? ".gz" : "";
        hdr_path = stem + ".hdr" + ext;
        img_path = stem + ".img" + ext;
        std::error_code ec;
        if (!fs::exists(hdr_path, ec)) throw FormatError("header file " + hdr_path + " does not exist");
        if (!fs::exists(img_path, ec)) throw FormatError("image file " + img_path + " does not exist");
        if (!fs::is_regular_file(hdr_path, ec)) throw FormatError("header file " + hdr_path + " is not a regular file");
        if (!fs::is_regular_file(img_path, ec)) throw FormatError("image file " + img_path + " is not a regular file");
    }
    // Header bytes.
    std::vector<unsigned char> head;
    if (gz) {
        head = gunzip(hdr_path, 540);
    } else {
        hzio::MappedFile m(hdr_path);
        head.assign(m.data(), m.data() + std::min<std::uint64_t>(m.size(), 540));
    }
    parse(head.data(), head.size(), h, !pair);
    const std::uint64_t bytes = h.nb_voxels * dtype_size(h.dtype);
    const std::uint64_t need = h.vox_offset + bytes;
    h.data_path = img_path;
    h.data_gz = gz;
    if (gz) {
        img.impl_->inflated = gunzip(img_path, need);
        if (img.impl_->inflated.size() < need)
            throw FormatError("the gzip stream holds " + std::to_string(img.impl_->inflated.size()) + " bytes; the header declares " +
                              std::to_string(need) + " (" + std::to_string(h.nb_voxels) + " voxels)");
        img.impl_->data = img.impl_->inflated.data() + h.vox_offset;
    } else {
        img.impl_->map = std::make_unique<hzio::MappedFile>(img_path);
        if (img.impl_->map->size() < need)
            throw FormatError(std::string(pair ? "image file" : "file") + " holds " + std::to_string(img.impl_->map->size()) +
                              " bytes; the header declares " + std::to_string(need) + " (" + std::to_string(h.nb_voxels) +
                              " voxels at offset " + std::to_string(h.vox_offset) + ")");
        img.impl_->data = img.impl_->map->data() + h.vox_offset;
    }
    return img;
}

void write(const std::string &path, const std::string &image_path, bool gz, DType dtype, const std::vector<std::uint64_t> &dims,
           const void *voxels, const std::array<double, 16> &A, double slope, double inter) {
    if (dims.empty() || dims.size() > 7) throw FormatError("NIfTI holds 1 to 7 dimensions");
    unsigned char h[352] = {};
    auto put16 = [&](int off, std::int16_t v) { std::memcpy(h + off, &v, 2); };
    auto put32 = [&](int off, std::int32_t v) { std::memcpy(h + off, &v, 4); };
    auto putf = [&](int off, double v) {
        const float f = static_cast<float>(v);
        std::memcpy(h + off, &f, 4);
    };
    static_assert(std::endian::native == std::endian::little, "the NIfTI writer assumes a little-endian host");
    put32(0, 348);
    put16(40, static_cast<std::int16_t>(dims.size()));
    std::uint64_t n = 1;
    for (std::size_t i = 0; i < dims.size(); ++i) {
        if (dims[i] < 1 || dims[i] > 32767) throw FormatError("dimension " + std::to_string(dims[i]) + " does not fit NIfTI-1");
        put16(42 + 2 * static_cast<int>(i), static_cast<std::int16_t>(dims[i]));
        n *= dims[i];
    }
    for (std::size_t i = dims.size(); i < 7; ++i) put16(42 + 2 * static_cast<int>(i), 1);
    static const std::pair<DType, std::int16_t> codes[] = {
        {DType::U8, 2},    {DType::I16, 4},   {DType::I32, 8},    {DType::F32, 16},   {DType::F64, 64},    {DType::I8, 256},
        {DType::U16, 512}, {DType::U32, 768}, {DType::I64, 1024}, {DType::U64, 1280}, {DType::RGB24, 128}, {DType::RGBA32, 2304}};
    for (const auto &[d, c] : codes)
        if (d == dtype) put16(70, c);
    put16(72, static_cast<std::int16_t>(8 * dtype_size(dtype)));
    putf(76, 1.0);  // qfac
    for (int j = 0; j < 3; ++j) putf(80 + 4 * j, std::sqrt(A[j] * A[j] + A[4 + j] * A[4 + j] + A[8 + j] * A[8 + j]));
    for (int j = 3; j < 7; ++j) putf(80 + 4 * j, 1.0);
    const bool pair = !image_path.empty();
    putf(108, pair ? 0 : 352);
    const bool scaled = !(slope == 1 && inter == 0);
    putf(112, scaled ? slope : 0.0);  // slope 0: no scaling
    putf(116, scaled ? inter : 0.0);
    h[123] = 10;    // xyzt_units: mm and seconds
    put16(252, 0);  // qform_code: unknown (the sform carries the affine)
    put16(254, 1);  // sform_code: scanner
    for (int i = 0; i < 12; ++i) putf(280 + 4 * i, A[static_cast<std::size_t>(i)]);
    std::memcpy(h + 344, pair ? "ni1" : "n+1", 4);
    const std::uint64_t bytes = n * dtype_size(dtype);
    // One file: `head` bytes of header, then (optionally) the voxels.
    auto put_file = [&](const std::string &file, const unsigned char *head, std::size_t head_bytes, const void *body,
                        std::uint64_t body_bytes) {
        try {
            hzio::write_parts(file, gz, {{head, head_bytes}, {body, body_bytes}});
        } catch (const hzio::IoError &e) {
            throw FormatError(e.what());
        }
    };
    if (pair) {
        put_file(path, h, 348, nullptr, 0);  // a .hdr is the bare 348-byte header
        put_file(image_path, nullptr, 0, voxels, bytes);
    } else {
        put_file(path, h, sizeof h, voxels, bytes);
    }
}

}  // namespace nifti
