// hz.loader/1: images (PNG, JPEG, OpenEXR, Radiance HDR, TIFF) through
// OpenImageIO: environment maps for image-based lighting, textures, and the
// PNG writer of `horizon render`.
//
// This library is cheap to load: it does not link OpenImageIO. The first
// open() or write() dlopen()s the backend images.backend/hz_images_oiio.so
// next to this file (see backend.h), so `horizon info x.tck` never pays
// OpenImageIO's ~200 ms start-up.
#include "backend.h"

#include <hz/cpp/plugin.hpp>

#include <dlfcn.h>

#include <cstring>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

constexpr const char *kId = "org.horizon.loader.images";

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
struct IoError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

// Loads the backend once per process. Thread-safe.
const hzimg_backend *backend(std::string &why) {
    static std::once_flag once;
    static const hzimg_backend *b = nullptr;
    static std::string error;
    std::call_once(once, [] {
        Dl_info di{};
        if (dladdr(reinterpret_cast<void *>(&backend), &di) == 0 || di.dli_fname == nullptr) {
            error = "cannot locate the images plugin file";
            return;
        }
        std::string dir = di.dli_fname;
        dir = dir.substr(0, dir.find_last_of('/') == std::string::npos ? 0 : dir.find_last_of('/'));
        const std::string path = (dir.empty() ? std::string(".") : dir) + "/images.backend/hz_images_oiio.so";
        void *h = dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL);
        if (h == nullptr) {
            const char *e = dlerror();
            error = "cannot load the OpenImageIO backend " + path + ": " + (e ? e : "?");
            return;
        }
        auto get = reinterpret_cast<const hzimg_backend *(*)()>(dlsym(h, HZIMG_BACKEND_SYMBOL));
        if (get == nullptr || get() == nullptr || get()->struct_size < sizeof(hzimg_backend)) {
            error = path + ": not a Horizon image backend";
            return;
        }
        b = get();  // kept loaded for the life of the process
    });
    why = error;
    return b;
}

const hzimg_backend &need_backend() {
    std::string why;
    const hzimg_backend *b = backend(why);
    if (b == nullptr) throw IoError(why);
    return *b;
}

int32_t HZ_ABI probe(const uint8_t *h, uint64_t n, const char *) {
    auto starts = [&](const char *m, std::size_t len) { return n >= len && std::memcmp(h, m, len) == 0; };
    if (starts("\x89PNG\r\n\x1a\n", 8)) return 100;
    if (starts("\xFF\xD8\xFF", 3)) return 90;
    if (starts("\x76\x2F\x31\x01", 4)) return 100;
    if (starts("#?RADIANCE", 10) || starts("#?RGBE", 6)) return 100;
    if (starts("II*\0", 4) || starts("MM\0*", 4)) return 80;
    return 0;
}

struct Reader {
    std::string path;
    hzimg_info info{};
};
Reader *as_reader(hz_reader *r) { return reinterpret_cast<Reader *>(r); }

template <class F>
hz_status run(hz_error *err, const std::string &path, F &&body) noexcept {
    return hz::format_guard<FormatError, IoError>(err, "images", path, body);
}

hz_status HZ_ABI open(const hz_open_request *req, hz_reader **out, hz_error *err) {
    if (out) *out = nullptr;
    if (req == nullptr || req->path == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "images: open: NULL");
    return run(err, req->path, [&]() -> hz_status {
        const hzimg_backend &b = need_backend();
        auto r = std::make_unique<Reader>();
        r->path = req->path;
        char msg[512] = {};
        if (b.info(req->path, &r->info, msg, sizeof msg) != 0) throw FormatError(msg);
        *out = reinterpret_cast<hz_reader *>(r.release());
        return HZ_OK;
    });
}

hz_status HZ_ABI get_info(hz_reader *reader, hz_dataset_info *out, hz_error *err) {
    if (reader == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "images: get_info: NULL");
    const Reader &r = *as_reader(reader);
    out->kind = HZ_DATA_IMAGE;
    std::snprintf(out->format, sizeof out->format, "%s", r.info.format);
    out->dtype = r.info.dtype;
    out->ndim = 3;
    out->dims[0] = r.info.channels;
    out->dims[1] = r.info.width;
    out->dims[2] = r.info.height;
    out->scale_slope = 1.0;
    out->scale_inter = 0.0;
    const double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::memcpy(out->voxel_to_ras, id, sizeof id);
    out->source_space = HZ_SPACE_UNKNOWN;
    out->nb_arrays = 0;
    return HZ_OK;
}

hz_status HZ_ABI get_array_info(hz_reader *, uint32_t, hz_array_info *, hz_error *err) {
    return hz::set_error(err, HZ_E_NOT_FOUND, "images: no extra arrays");
}

hz_status HZ_ABI visit_metadata(hz_reader *reader, hz_metadata_visitor visitor, void *ctx, hz_error *err) {
    if (reader == nullptr || visitor == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "images: visit_metadata: NULL");
    visitor(ctx, "format", as_reader(reader)->info.format);
    return HZ_OK;
}

std::size_t elem_size(uint32_t dtype) { return dtype == HZ_DTYPE_U8 ? 1 : dtype == HZ_DTYPE_U16 ? 2 : dtype == HZ_DTYPE_F32 ? 4 : 0; }

hz_status HZ_ABI read_volume(hz_reader *reader, const hz_array_view *dst, const hz_task *task, hz_error *err) {
    if (reader == nullptr || dst == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "images: read_volume: NULL");
    const Reader &r = *as_reader(reader);
    if (hz::cancelled(task)) return hz::set_error(err, HZ_E_CANCELLED, "cancelled");
    if (dst->dtype != r.info.dtype)
        return hz::set_errorf(err, HZ_E_DTYPE, "images: %s: pixels are read in their stored type only", r.path.c_str());
    const uint64_t c = r.info.channels, w = r.info.width, h = r.info.height;
    if (dst->ndim < 3 || dst->shape[0] != c || dst->shape[1] != w || dst->shape[2] != h)
        return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "images: %s: destination shape differs from the image", r.path.c_str());
    return run(err, r.path, [&]() -> hz_status {
        const hzimg_backend &b = need_backend();
        const std::size_t es = elem_size(r.info.dtype);
        std::vector<unsigned char> tmp(c * w * h * es);
        char msg[512] = {};
        if (b.read(r.path.c_str(), r.info.dtype, tmp.data(), tmp.size(), msg, sizeof msg) != 0) throw FormatError(msg);
        for (uint64_t y = 0; y < h; ++y)
            for (uint64_t x = 0; x < w; ++x)
                for (uint64_t k = 0; k < c; ++k) {
                    const int64_t off =
                        int64_t(k) * dst->stride_bytes[0] + int64_t(x) * dst->stride_bytes[1] + int64_t(y) * dst->stride_bytes[2];
                    if (off < 0 || uint64_t(off) + es > dst->capacity_bytes)
                        return hz::set_errorf(err, HZ_E_BUFFER_TOO_SMALL, "images: %s: destination too small", r.path.c_str());
                    std::memcpy(static_cast<unsigned char *>(dst->data) + off, &tmp[((y * w + x) * c + k) * es], es);
                }
        return HZ_OK;
    });
}

void HZ_ABI close(hz_reader *reader) { delete as_reader(reader); }

hz_status HZ_ABI write(const hz_write_request *req, const hz_dataset_view *data, const hz_task *, hz_error *err) {
    if (req == nullptr || req->path == nullptr || data == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "images: write: NULL");
    if (data->kind != HZ_DATA_IMAGE) return hz::set_errorf(err, HZ_E_UNSUPPORTED, "images: %s: holds images only", req->path);
    return run(err, req->path, [&]() -> hz_status {
        const hz_array_view &v = data->voxels;
        const std::size_t es = elem_size(v.dtype);
        if (es == 0) throw FormatError("pixels must be uint8, uint16 or float32");
        if (v.ndim != 3 || v.shape[0] < 1 || v.shape[0] > 4) throw FormatError("an image needs 1 to 4 channels x width x height");
        const uint64_t c = v.shape[0], w = v.shape[1], h = v.shape[2];
        if (w == 0 || h == 0 || w > (1u << 20) || h > (1u << 20)) throw FormatError("image size out of range");
        std::vector<unsigned char> px(c * w * h * es);
        for (uint64_t y = 0; y < h; ++y)
            for (uint64_t x = 0; x < w; ++x)
                for (uint64_t k = 0; k < c; ++k) {
                    const int64_t off = int64_t(k) * v.stride_bytes[0] + int64_t(x) * v.stride_bytes[1] + int64_t(y) * v.stride_bytes[2];
                    if (off < 0 || uint64_t(off) + es > v.capacity_bytes) throw FormatError("pixel view out of bounds");
                    std::memcpy(&px[((y * w + x) * c + k) * es], static_cast<const unsigned char *>(v.data) + off, es);
                }
        std::string ext = req->extension ? req->extension : "png";
        if (ext == "jpg") ext = "jpeg";
        char msg[512] = {};
        if (need_backend().write(req->path, ext.c_str(), w, h, uint32_t(c), v.dtype, px.data(), msg, sizeof msg) != 0) throw IoError(msg);
        return HZ_OK;
    });
}

const char *const kExtensions[] = {"png", "jpg", "jpeg", "exr", "hdr", "tif", "tiff", nullptr};
const hz_loader kLoader = {
    .struct_size = sizeof(hz_loader),
    .data_kinds = HZ_DATA_IMAGE,
    .caps = HZ_LOADER_CAN_READ | HZ_LOADER_CAN_WRITE,
    .probe_bytes = 16,
    .extensions = kExtensions,
    .probe = probe,
    .open = open,
    .get_info = get_info,
    .get_array_info = get_array_info,
    .visit_metadata = visit_metadata,
    .read_streamlines = nullptr,
    .read_array = nullptr,
    .read_volume = read_volume,
    .read_mesh = nullptr,
    .close = close,
    .write = write,
};
const char *const kInterfaces[] = {HZ_INTERFACE_LOADER, nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "Images (OpenImageIO)",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description = "PNG, JPEG, OpenEXR, Radiance HDR and TIFF images: environment maps, textures, rendered frames",
    .license = "MIT",
    .interfaces = kInterfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::single_plugin<kDescriptor, kLoader>::entry;
