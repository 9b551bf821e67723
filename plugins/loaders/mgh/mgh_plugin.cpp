// hz.loader/1 for FreeSurfer MGH/MGZ volumes (mgh_format.hpp), through the
// SDK's C++ loader adapter (hz/cpp/loader.hpp).
#include "gzip.hpp"
#include "mgh_format.hpp"
#include "voxel_copy.hpp"

#include <hz/cpp/loader.hpp>

#include <algorithm>
#include <bit>
#include <cstring>
#include <memory>

namespace {

constexpr const char *kId = "org.horizon.loader.mgh";

struct MghReader {
    std::unique_ptr<mgh::Volume> volume;
};
struct MghCancelled {};

hz_dtype to_hz(mgh::DType t) {
    switch (t) {
    case mgh::DType::U8: return HZ_DTYPE_U8;
    case mgh::DType::I16: return HZ_DTYPE_I16;
    case mgh::DType::I32: return HZ_DTYPE_I32;
    case mgh::DType::F32: return HZ_DTYPE_F32;
    }
    return HZ_DTYPE_UNKNOWN;
}

int32_t mgh_probe(const uint8_t *head, uint64_t size, const char *name) noexcept { return mgh::probe(head, size, name); }

std::unique_ptr<MghReader> mgh_open(const std::string &path, const hz_task *) {
    auto r = std::make_unique<MghReader>();
    try {
        r->volume = std::make_unique<mgh::Volume>(mgh::Volume::open(path));
    } catch (const hzio::CorruptData &e) {
        throw mgh::FormatError(e.what());
    }
    return r;
}

void mgh_info(const MghReader &r, hz_dataset_info &out) {
    const mgh::Header &h = r.volume->header();
    out.kind = HZ_DATA_VOLUME;
    std::snprintf(out.format, sizeof out.format, "%s", r.volume->gz() ? "mgz" : "mgh");
    out.dtype = to_hz(h.dtype);
    out.ndim = h.dims[3] > 1 ? 4 : 3;  // (one frame: a 3D volume, as nibabel and FreeSurfer see it)
    for (uint32_t i = 0; i < out.ndim; ++i) out.dims[i] = static_cast<uint64_t>(h.dims[i]);
    out.scale_slope = 1;
    out.scale_inter = 0;
    const std::array<double, 16> a = h.affine();
    std::copy(a.begin(), a.end(), out.voxel_to_ras);
    for (int i = 0; i < 3; ++i) out.ref_dims[i] = static_cast<uint64_t>(h.dims[static_cast<std::size_t>(i)]);
    out.source_space = HZ_SPACE_VOXEL;
}

void mgh_metadata(const MghReader &r, hz_metadata_visitor visitor, void *ctx) {
    const mgh::Header &h = r.volume->header();
    char buf[128];
    visitor(ctx, "mgh_type", std::to_string(h.type_code).c_str());
    visitor(ctx, "dof", std::to_string(h.dof).c_str());
    visitor(ctx, "good_ras", h.good_ras ? "1" : "0");
    std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g", h.delta[0], h.delta[1], h.delta[2]);
    visitor(ctx, "voxel_size", buf);
    if (h.has_footer) {
        const std::pair<const char *, double> scan[] = {
            {"tr", h.tr}, {"flip_angle", h.flip_angle}, {"te", h.te}, {"ti", h.ti}, {"fov", h.fov}};
        for (const auto &[k, v] : scan) {
            std::snprintf(buf, sizeof buf, "%.9g", v);
            visitor(ctx, k, buf);
        }
    }
}

// One big-endian voxel as double.
double voxel_value(const unsigned char *p, mgh::DType t) {
    unsigned char b[4];
    const std::size_t n = mgh::dtype_size(t);
    std::reverse_copy(p, p + n, b);
    switch (t) {
    case mgh::DType::U8: return p[0];
    case mgh::DType::I16: return std::bit_cast<std::int16_t>(std::array<unsigned char, 2>{b[0], b[1]});
    case mgh::DType::I32: return std::bit_cast<std::int32_t>(std::array<unsigned char, 4>{b[0], b[1], b[2], b[3]});
    case mgh::DType::F32: return std::bit_cast<float>(std::array<unsigned char, 4>{b[0], b[1], b[2], b[3]});
    }
    return 0;
}

void mgh_read_volume(MghReader &r, const hz_array_view &dst, const hz_task *task) {
    const mgh::Header &h = r.volume->header();
    const bool raw = dst.dtype == to_hz(h.dtype);
    if (!raw && dst.dtype != HZ_DTYPE_F32 && dst.dtype != HZ_DTYPE_F64)
        throw mgh::FormatError("read_volume: destination dtype must be the stored one or float32/float64");
    const std::vector<std::uint64_t> dims(h.dims.begin(), h.dims.end());
    const std::size_t in_size = mgh::dtype_size(h.dtype), out_size = raw ? in_size : dst.dtype == HZ_DTYPE_F32 ? 4 : 8;
    const unsigned char *src = r.volume->voxels();
    const hzio::StridedDest to{dst.data, dst.ndim, dst.shape, dst.stride_bytes, dst.capacity_bytes};
    // (the destination's axes: the volume's, trailing ones merged into its last)
    switch (hzio::copy_voxels(dims, out_size, to, [&](std::uint64_t v, unsigned char *o) {
        if ((v & 0xFFFFF) == 0 && hz::cancelled(task)) throw MghCancelled{};
        const unsigned char *p = src + v * in_size;
        if (raw) {
            std::reverse_copy(p, p + in_size, o);  // (big-endian to the host's order)
        } else if (out_size == 4) {
            const float f = static_cast<float>(voxel_value(p, h.dtype));
            std::memcpy(o, &f, 4);
        } else {
            const double d = voxel_value(p, h.dtype);
            std::memcpy(o, &d, 8);
        }
    })) {
    case hzio::CopyCheck::BadAxes: throw mgh::FormatError("read_volume: destination must have 1..4 axes");
    case hzio::CopyCheck::BadShape: throw mgh::FormatError("read_volume: destination shape does not match the volume");
    case hzio::CopyCheck::TooSmall: throw hz::Error(HZ_E_BUFFER_TOO_SMALL, "mgh: destination too small");
    case hzio::CopyCheck::Ok: break;
    }
    hz::report(task, 1.0);
}

// One value of `t` at `p` (native byte order) as double.
double value_of(const unsigned char *p, hz_dtype t) {
    switch (t) {
    case HZ_DTYPE_U8: return *p;
    case HZ_DTYPE_I8: return static_cast<std::int8_t>(*p);
    case HZ_DTYPE_U16: {
        std::uint16_t v;
        std::memcpy(&v, p, 2);
        return v;
    }
    case HZ_DTYPE_I16: {
        std::int16_t v;
        std::memcpy(&v, p, 2);
        return v;
    }
    case HZ_DTYPE_U32: {
        std::uint32_t v;
        std::memcpy(&v, p, 4);
        return v;
    }
    case HZ_DTYPE_I32: {
        std::int32_t v;
        std::memcpy(&v, p, 4);
        return v;
    }
    case HZ_DTYPE_U64: {
        std::uint64_t v;
        std::memcpy(&v, p, 8);
        return static_cast<double>(v);
    }
    case HZ_DTYPE_I64: {
        std::int64_t v;
        std::memcpy(&v, p, 8);
        return static_cast<double>(v);
    }
    case HZ_DTYPE_F32: {
        float v;
        std::memcpy(&v, p, 4);
        return v;
    }
    case HZ_DTYPE_F64: {
        double v;
        std::memcpy(&v, p, 8);
        return v;
    }
    default: return 0;
    }
}
void mgh_write(const hz_write_request &req, const hz_dataset_view &data, const hz_task *) {
    const std::string ext = req.extension ? req.extension : "mgz";
    if (ext != "mgz" && ext != "mgh" && ext != "mgh.gz") throw mgh::FormatError("writing ." + ext + " is not supported");
    const hz_array_view &vx = data.voxels;
    const bool numeric = vx.dtype != HZ_DTYPE_F16 && vx.dtype != HZ_DTYPE_RGB8 && vx.dtype != HZ_DTYPE_RGBA8;
    const std::size_t es = numeric ? hz::dtype_size(vx.dtype) : 0;
    if (es == 0) throw mgh::FormatError("voxels of this type (half float, colour or unknown) cannot be stored in MGH");
    std::vector<std::uint64_t> dims;
    if (HZ_HAS_FIELD(&data, hz_dataset_view, scale_inter) && data.volume_ndim > 0)
        dims.assign(data.volume_dims, data.volume_dims + std::min<uint32_t>(data.volume_ndim, 7));
    else
        dims.assign(vx.shape, vx.shape + vx.ndim);
    while (dims.size() > 1 && dims.back() == 1 && dims.size() > 3) dims.pop_back();
    if (dims.size() > 4) throw mgh::FormatError("MGH holds at most 4 dimensions (x, y, z, frames), not " + std::to_string(dims.size()));
    std::uint64_t n = es;
    for (uint32_t i = 0; i < vx.ndim; ++i) {
        if (vx.stride_bytes[i] != static_cast<std::int64_t>(n)) throw mgh::FormatError("voxels must be contiguous, x fastest");
        n *= vx.shape[i];
    }
    if (n > vx.capacity_bytes) throw mgh::FormatError("voxel view smaller than its shape");
    double slope = 1, inter = 0;
    if (HZ_HAS_FIELD(&data, hz_dataset_view, scale_inter)) slope = data.scale_slope, inter = data.scale_inter;
    const std::uint64_t count = n / es;
    const auto *src = static_cast<const unsigned char *>(vx.data);
    // Stored as is where MGH has the type; widened where it has a larger
    // one (int8 -> short, uint16 -> int); else, and when scaled, as float.
    mgh::DType out;
    const bool scaled = !(slope == 1 && inter == 0);
    if (!scaled && vx.dtype == HZ_DTYPE_U8)
        out = mgh::DType::U8;
    else if (!scaled && (vx.dtype == HZ_DTYPE_I16 || vx.dtype == HZ_DTYPE_I8))
        out = mgh::DType::I16;
    else if (!scaled && (vx.dtype == HZ_DTYPE_I32 || vx.dtype == HZ_DTYPE_U16))
        out = mgh::DType::I32;
    else
        out = mgh::DType::F32;
    if (out == mgh::DType::F32 && req.on_dropped) {
        if (vx.dtype == HZ_DTYPE_F64)
            req.on_dropped(req.ctx, "float64 precision (MGH stores float32)");
        else if (vx.dtype == HZ_DTYPE_U32 || vx.dtype == HZ_DTYPE_I64 || vx.dtype == HZ_DTYPE_U64)
            req.on_dropped(req.ctx, "integer values above 2^24 (MGH has no such integer type: stored as float32)");
    }
    std::vector<unsigned char> conv;
    const void *voxels = vx.data;
    if (!(to_hz(out) == vx.dtype)) {
        const std::size_t os = mgh::dtype_size(out);
        conv.resize(count * os);
        for (std::uint64_t k = 0; k < count; ++k) {
            const double v = value_of(src + k * es, vx.dtype) * slope + inter;
            if (out == mgh::DType::F32) {
                const float f = static_cast<float>(v);
                std::memcpy(conv.data() + k * os, &f, 4);
            } else if (out == mgh::DType::I16) {
                const std::int16_t s = static_cast<std::int16_t>(v);
                std::memcpy(conv.data() + k * os, &s, 2);
            } else {
                const std::int32_t s = static_cast<std::int32_t>(v);
                std::memcpy(conv.data() + k * os, &s, 4);
            }
        }
        voxels = conv.data();
    }
    // The scan parameters a loaded MGH carried, back into its footer; other
    // entries have no place in MGH.
    double scan[5] = {0, 0, 0, 0, 0};
    static const char *const kScan[5] = {"tr", "flip_angle", "te", "ti", "fov"};
    static const char *const kOwn[] = {"mgh_type", "dof", "good_ras", "voxel_size"};
    for (uint32_t i = 0; i < data.nb_metadata; ++i) {
        const std::string k = data.metadata[i].key ? data.metadata[i].key : "";
        const char *v = data.metadata[i].value ? data.metadata[i].value : "";
        bool used = std::find_if(std::begin(kOwn), std::end(kOwn), [&](const char *o) { return k == o; }) != std::end(kOwn);
        for (int s = 0; s < 5; ++s)
            if (k == kScan[s]) scan[s] = std::strtod(v, nullptr), used = true;
        if (!used && req.on_dropped) req.on_dropped(req.ctx, ("header entry '" + k + "'").c_str());
    }
    std::array<double, 16> aff;
    std::copy(data.voxel_to_ras, data.voxel_to_ras + 16, aff.begin());
    mgh::write(req.path, ext != "mgh", out, dims, voxels, aff, scan[0], scan[1], scan[2], scan[3], scan[4]);
}

const char *const kExtensions[] = {"mgz", "mgh", "mgh.gz", nullptr};

struct Mgh {
    static constexpr const char *prefix = "mgh";
    static constexpr hz_data_kind kinds = HZ_DATA_VOLUME;
    static constexpr uint32_t probe_bytes = 24;
    static constexpr const char *const *extensions = kExtensions;
    using FormatError = mgh::FormatError;
    using IoError = hzio::IoError;
    using Cancelled = MghCancelled;
    using Reader = MghReader;
    static constexpr auto probe = mgh_probe;
    static constexpr auto open = mgh_open;
    static constexpr auto info = mgh_info;
    static constexpr auto metadata = mgh_metadata;
    static constexpr auto read_volume = mgh_read_volume;
    static constexpr auto write = mgh_write;
};
constexpr const hz_loader &kLoader = hz::loader<Mgh>::table;
const char *const kInterfaces[] = {HZ_INTERFACE_LOADER, nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "FreeSurfer MGH/MGZ",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description =
        "FreeSurfer MGH volumes (.mgz, .mgh, .mgh.gz): uchar, short, int, float, 1 to 4 dimensions, the scan parameters; "
        "reads and writes",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader>::entry;
