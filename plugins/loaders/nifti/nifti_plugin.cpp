// hz.loader/1 for NIfTI-1/-2 volumes (nifti_format.hpp), through the SDK's
// C++ loader adapter (hz/cpp/loader.hpp).
#include "mapped_file.hpp"
#include "nifti_format.hpp"
#include "voxel_copy.hpp"

#include <hz/cpp/loader.hpp>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <memory>

namespace {

constexpr const char *kId = "org.horizon.loader.nifti";
const hz_host *host();

struct NiiReader {
    std::string path;
    std::unique_ptr<nifti::Image> image;
};
struct NiiCancelled {};

hz_dtype to_hz(nifti::DType t) {
    switch (t) {
    case nifti::DType::U8: return HZ_DTYPE_U8;
    case nifti::DType::I8: return HZ_DTYPE_I8;
    case nifti::DType::U16: return HZ_DTYPE_U16;
    case nifti::DType::I16: return HZ_DTYPE_I16;
    case nifti::DType::U32: return HZ_DTYPE_U32;
    case nifti::DType::I32: return HZ_DTYPE_I32;
    case nifti::DType::U64: return HZ_DTYPE_U64;
    case nifti::DType::I64: return HZ_DTYPE_I64;
    case nifti::DType::F32: return HZ_DTYPE_F32;
    case nifti::DType::F64: return HZ_DTYPE_F64;
    case nifti::DType::RGB24: return HZ_DTYPE_RGB8;
    case nifti::DType::RGBA32: return HZ_DTYPE_RGBA8;
    }
    return HZ_DTYPE_UNKNOWN;
}
bool from_hz(hz_dtype t, nifti::DType &out) {
    for (auto d : {nifti::DType::U8, nifti::DType::I8, nifti::DType::U16, nifti::DType::I16, nifti::DType::U32, nifti::DType::I32,
                   nifti::DType::U64, nifti::DType::I64, nifti::DType::F32, nifti::DType::F64, nifti::DType::RGB24, nifti::DType::RGBA32})
        if (to_hz(d) == t) {
            out = d;
            return true;
        }
    return false;
}

int32_t nii_probe(const uint8_t *head, uint64_t size, const char *) noexcept { return nifti::probe(head, size); }

std::unique_ptr<NiiReader> nii_open(const std::string &path, const hz_task *) {
    auto r = std::make_unique<NiiReader>();
    r->path = path;
    r->image = std::make_unique<nifti::Image>(nifti::Image::open(r->path));
    for (const auto &w : r->image->header().warnings) hz::log(host(), kId, HZ_LOG_WARN, r->path + ": " + w);
    return r;
}

void nii_info(const NiiReader &r, hz_dataset_info &info) {
    hz_dataset_info *out = &info;
    const nifti::Header &h = r.image->header();
    out->kind = HZ_DATA_VOLUME;
    std::snprintf(out->format, sizeof out->format, "nifti%d%s%s", h.version, h.data_gz ? " gz" : "", h.swap ? " swapped" : "");
    out->dtype = to_hz(h.dtype);
    out->ndim = static_cast<uint32_t>(h.ndim);
    for (int i = 0; i < h.ndim; ++i) out->dims[i] = static_cast<uint64_t>(h.dims[static_cast<std::size_t>(i)]);
    out->scale_slope = h.scl_slope;
    out->scale_inter = h.scl_inter;
    std::copy(h.affine.begin(), h.affine.end(), out->voxel_to_ras);
    for (int i = 0; i < 3; ++i) out->ref_dims[i] = i < h.ndim ? static_cast<uint64_t>(h.dims[static_cast<std::size_t>(i)]) : 1;
    out->source_space = HZ_SPACE_VOXEL;
}

void nii_metadata(const NiiReader &r, hz_metadata_visitor visitor, void *ctx) {
    const nifti::Header &h = r.image->header();
    char buf[256];
    std::snprintf(buf, sizeof buf, "%g %g %g %g", h.pixdim[1], h.pixdim[2], h.pixdim[3], h.pixdim[4]);
    visitor(ctx, "pixdim", buf);
    visitor(ctx, "datatype", std::to_string(h.datatype_code).c_str());
    visitor(ctx, "vox_offset", std::to_string(h.vox_offset).c_str());
    visitor(ctx, "qform_code", std::to_string(h.qform_code).c_str());
    visitor(ctx, "sform_code", std::to_string(h.sform_code).c_str());
    visitor(ctx, "affine_source", h.affine_source.c_str());
    std::snprintf(buf, sizeof buf, "%.9g %.9g", h.scl_slope, h.scl_inter);
    visitor(ctx, "scaling", buf);
}

template <class T>
T load(const unsigned char *p, bool swap) {
    T v;
    unsigned char tmp[sizeof(T)];
    std::memcpy(tmp, p, sizeof(T));
    if (swap) std::reverse(tmp, tmp + sizeof(T));
    std::memcpy(&v, tmp, sizeof(T));
    return v;
}

// One voxel as double (for scaled output).
double voxel_value(const unsigned char *p, nifti::DType t, bool swap) {
    switch (t) {
    case nifti::DType::U8: return *p;
    case nifti::DType::I8: return static_cast<std::int8_t>(*p);
    case nifti::DType::U16: return load<std::uint16_t>(p, swap);
    case nifti::DType::I16: return load<std::int16_t>(p, swap);
    case nifti::DType::U32: return load<std::uint32_t>(p, swap);
    case nifti::DType::I32: return load<std::int32_t>(p, swap);
    case nifti::DType::U64: return static_cast<double>(load<std::uint64_t>(p, swap));
    case nifti::DType::I64: return static_cast<double>(load<std::int64_t>(p, swap));
    case nifti::DType::F32: return load<float>(p, swap);
    case nifti::DType::F64: return load<double>(p, swap);
    default: return 0;
    }
}

void nii_read_volume(NiiReader &r, const hz_array_view &view, const hz_task *task) {
    const hz_array_view *dst = &view;
    const nifti::Header &h = r.image->header();
    {
        const bool raw = dst->dtype == to_hz(h.dtype);
        const bool scaled = !raw && (dst->dtype == HZ_DTYPE_F32 || dst->dtype == HZ_DTYPE_F64) && h.dtype != nifti::DType::RGB24 &&
                            h.dtype != nifti::DType::RGBA32;
        if (!raw && !scaled) throw nifti::FormatError("read_volume: destination dtype must be the stored one or float32/float64");
        std::vector<std::uint64_t> dims(static_cast<std::size_t>(h.ndim));
        for (int i = 0; i < h.ndim; ++i)
            dims[static_cast<std::size_t>(i)] = static_cast<std::uint64_t>(h.dims[static_cast<std::size_t>(i)]);
        const std::size_t in_size = nifti::dtype_size(h.dtype);
        const std::size_t out_size = raw ? in_size : (dst->dtype == HZ_DTYPE_F32 ? 4 : 8);
        const unsigned char *src = r.image->data();
        const bool swap_elems = h.swap && h.dtype != nifti::DType::RGB24 && h.dtype != nifti::DType::RGBA32;
        const hzio::StridedDest to{dst->data, dst->ndim, dst->shape, dst->stride_bytes, dst->capacity_bytes};
        // (the destination's axes: the image's, trailing ones merged into its last)
        switch (hzio::copy_voxels(dims, out_size, to, [&](std::uint64_t v, unsigned char *o) {
            if ((v & 0xFFFFF) == 0 && hz::cancelled(task)) throw NiiCancelled{};
            const unsigned char *p = src + v * in_size;
            if (raw) {
                std::memcpy(o, p, in_size);
                if (swap_elems) std::reverse(o, o + in_size);
            } else {
                const double val = voxel_value(p, h.dtype, h.swap) * h.scl_slope + h.scl_inter;
                if (out_size == 4) {
                    const float f = static_cast<float>(val);
                    std::memcpy(o, &f, 4);
                } else {
                    std::memcpy(o, &val, 8);
                }
            }
        })) {
        case hzio::CopyCheck::BadAxes: throw nifti::FormatError("read_volume: destination must have 1..4 axes");
        case hzio::CopyCheck::BadShape: throw nifti::FormatError("read_volume: destination shape does not match the image");
        case hzio::CopyCheck::TooSmall: throw hz::Error(HZ_E_BUFFER_TOO_SMALL, "nifti: " + r.path + ": destination too small");
        case hzio::CopyCheck::Ok: break;
        }
        hz::report(task, 1.0);
    }
}

void nii_write(const hz_write_request &request, const hz_dataset_view &view, const hz_task *) {
    const hz_write_request *req = &request;
    const hz_dataset_view *data = &view;
    {
        const std::string ext = req->extension ? req->extension : "nii";
        const bool pair = ext == "hdr" || ext == "img" || ext == "hdr.gz" || ext == "img.gz";
        if (ext != "nii" && ext != "nii.gz" && !pair) throw nifti::FormatError("writing ." + ext + " is not supported");
        // A pair: `path` gets the file the user named, the other one is a
        // companion the host renames with it.
        std::string header_tmp = req->path, image_tmp, companion_final;
        const bool gz = ext == "nii.gz" || ext == "hdr.gz" || ext == "img.gz";
        if (pair) {
            if (!HZ_HAS_FIELD(req, hz_write_request, companion_ctx) || req->add_companion == nullptr || req->final_path == nullptr)
                throw nifti::FormatError("this host cannot receive the second file of a .hdr/.img pair (needs ABI 1.3)");
            const std::string final_path = req->final_path;
            const std::string named = ext.substr(0, 3), other = named == "hdr" ? "img" : "hdr";
            const std::size_t cut = final_path.size() - ext.size();
            auto lower = [](std::string x) {
                for (char &c : x) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
                return x;
            };
            if (final_path.size() < ext.size() || lower(final_path.substr(cut)) != ext)
                throw nifti::FormatError("cannot derive the ." + other + " name from " + final_path);
            companion_final = final_path.substr(0, cut) + other + (gz ? ".gz" : "");
            const std::string companion_tmp = std::string(req->path) + "." + other;
            if (named == "hdr")
                image_tmp = companion_tmp;
            else
                header_tmp = companion_tmp, image_tmp = req->path;
        }
        const hz_array_view &vx = data->voxels;
        nifti::DType dt;
        if (!from_hz(vx.dtype, dt)) throw nifti::FormatError("voxel type cannot be stored in NIfTI");
        std::vector<std::uint64_t> dims;
        if (HZ_HAS_FIELD(data, hz_dataset_view, scale_inter) && data->volume_ndim > 0) {
            dims.assign(data->volume_dims, data->volume_dims + std::min<uint32_t>(data->volume_ndim, 7));
        } else {
            dims.assign(vx.shape, vx.shape + vx.ndim);
        }
        // The host passes contiguous, x-fastest voxels.
        std::uint64_t expect = nifti::dtype_size(dt);
        for (uint32_t i = 0; i < vx.ndim; ++i) {
            if (vx.stride_bytes[i] != static_cast<std::int64_t>(expect)) throw nifti::FormatError("voxels must be contiguous, x fastest");
            expect *= vx.shape[i];
        }
        if (expect > vx.capacity_bytes) throw nifti::FormatError("voxel view smaller than its shape");
        double slope = 1, inter = 0;
        if (HZ_HAS_FIELD(data, hz_dataset_view, scale_inter)) slope = data->scale_slope, inter = data->scale_inter;
        std::array<double, 16> aff;
        std::copy(data->voxel_to_ras, data->voxel_to_ras + 16, aff.begin());
        for (uint32_t i = 0; i < data->nb_metadata && req->on_dropped; ++i) {
            const std::string k = data->metadata[i].key ? data->metadata[i].key : "";
            static const char *own[] = {"pixdim", "datatype", "vox_offset", "qform_code", "sform_code", "affine_source", "scaling"};
            if (std::find(std::begin(own), std::end(own), k) == std::end(own))
                req->on_dropped(req->ctx, ("header entry '" + k + "'").c_str());
        }
        if (pair && req->add_companion(req->companion_ctx, (header_tmp == req->path ? image_tmp : header_tmp).c_str(),
                                       companion_final.c_str()) != HZ_OK)
            throw nifti::FormatError("the host refused the companion file " + companion_final);
        nifti::write(header_tmp, image_tmp, gz, dt, dims, vx.data, aff, slope, inter);
    }
}

const char *const kExtensions[] = {"nii", "nii.gz", "hdr", "img", "hdr.gz", "img.gz", nullptr};

// The format as the SDK's C++ loader adapter takes it (hz/cpp/loader.hpp).
struct Nifti {
    static constexpr const char *prefix = "nifti";
    static constexpr hz_data_kind kinds = HZ_DATA_VOLUME;
    static constexpr uint32_t probe_bytes = 548;
    static constexpr const char *const *extensions = kExtensions;
    using FormatError = nifti::FormatError;
    using IoError = hzio::IoError;
    using Cancelled = NiiCancelled;
    using Reader = NiiReader;
    static constexpr auto probe = nii_probe;
    static constexpr auto open = nii_open;
    static constexpr auto info = nii_info;
    static constexpr auto metadata = nii_metadata;
    static constexpr auto read_volume = nii_read_volume;
    static constexpr auto write = nii_write;
};
constexpr const hz_loader &kLoader = hz::loader<Nifti>::table;
const char *const kInterfaces[] = {HZ_INTERFACE_LOADER, nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "NIfTI-1/2",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "NIfTI-1 and NIfTI-2 volumes (.nii, .nii.gz, .hdr/.img pairs), both byte orders; writes all of these",
    .license = "MIT",
    .interfaces = kInterfaces,
};

const hz_host *host() { return hz::single_plugin<kDescriptor, kLoader>::host(); }

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader>::entry;
