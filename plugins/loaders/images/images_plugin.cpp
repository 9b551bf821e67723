// hz.loader/1: images (PNG, JPEG, OpenEXR, Radiance HDR, TIFF) through
// OpenImageIO: environment maps for image-based lighting, textures, and the
// PNG writer of `horizon render`.
//
// This library is cheap to load: it does not link OpenImageIO. The first
// open() or write() dlopen()s the backend images.backend/hz_images_oiio.so
// next to this file (see backend.h), so `horizon info x.tck` never pays
// OpenImageIO's ~200 ms start-up (the relocations of its 261 libraries).
// 8-bit PNGs, what `horizon render` writes, are written with libpng
// here, without the backend: every render is a quarter of a second sooner.
#include "backend.h"
#include "files.hpp"

#include <hz/cpp/loader.hpp>

#include <dlfcn.h>
#include <png.h>

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

int32_t img_probe(const uint8_t *h, uint64_t n, const char *) noexcept {
    auto starts = [&](const char *m, std::size_t len) { return n >= len && std::memcmp(h, m, len) == 0; };
    if (starts("\x89PNG\r\n\x1a\n", 8)) return 100;
    if (starts("\xFF\xD8\xFF", 3)) return 90;
    if (starts("\x76\x2F\x31\x01", 4)) return 100;
    if (starts("#?RADIANCE", 10) || starts("#?RGBE", 6)) return 100;
    if (starts("II*\0", 4) || starts("MM\0*", 4)) return 80;
    return 0;
}

struct ImgReader {
    std::string path;
    hzimg_info info{};
};

std::unique_ptr<ImgReader> img_open(const std::string &path, const hz_task *) {
    const hzimg_backend &b = need_backend();
    auto r = std::make_unique<ImgReader>();
    r->path = path;
    char msg[512] = {};
    if (b.info(path.c_str(), &r->info, msg, sizeof msg) != 0) throw FormatError(msg);
    return r;
}

void img_info(const ImgReader &r, hz_dataset_info &out) {
    out.kind = HZ_DATA_IMAGE;
    std::snprintf(out.format, sizeof out.format, "%s", r.info.format);
    out.dtype = r.info.dtype;
    out.ndim = 3;
    out.dims[0] = r.info.channels;
    out.dims[1] = r.info.width;
    out.dims[2] = r.info.height;
    out.scale_slope = 1.0;
    out.scale_inter = 0.0;
    const double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::memcpy(out.voxel_to_ras, id, sizeof id);
    out.source_space = HZ_SPACE_UNKNOWN;
    out.nb_arrays = 0;
}

void img_metadata(const ImgReader &r, hz_metadata_visitor visit, void *ctx) { visit(ctx, "format", r.info.format); }

std::size_t elem_size(uint32_t dtype) { return dtype == HZ_DTYPE_U8 ? 1 : dtype == HZ_DTYPE_U16 ? 2 : dtype == HZ_DTYPE_F32 ? 4 : 0; }

void img_read_volume(ImgReader &r, const hz_array_view &view, const hz_task *) {
    const hz_array_view *dst = &view;
    if (dst->dtype != r.info.dtype) throw hz::Error(HZ_E_DTYPE, "images: " + r.path + ": pixels are read in their stored type only");
    const uint64_t c = r.info.channels, w = r.info.width, h = r.info.height;
    if (dst->ndim < 3 || dst->shape[0] != c || dst->shape[1] != w || dst->shape[2] != h)
        throw hz::Error(HZ_E_INVALID_ARGUMENT, "images: " + r.path + ": destination shape differs from the image");
    {
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
                        throw hz::Error(HZ_E_BUFFER_TOO_SMALL, "images: " + r.path + ": destination too small");
                    std::memcpy(static_cast<unsigned char *>(dst->data) + off, &tmp[((y * w + x) * c + k) * es], es);
                }
    }
}

// An 8-bit PNG of `c` channels (gray, gray+alpha, RGB, RGBA), rows top to
// bottom, through libpng's simplified API (zlib tuned for speed). (16-bit
// PNGs go through the backend: the simplified API would mark them linear.)
void write_png(const char *path, uint64_t w, uint64_t h, uint64_t c, const std::vector<unsigned char> &px) {
    png_image img{};
    img.version = PNG_IMAGE_VERSION;
    img.width = png_uint_32(w);
    img.height = png_uint_32(h);
    img.format = c == 1 ? PNG_FORMAT_GRAY : c == 2 ? PNG_FORMAT_GA : c == 3 ? PNG_FORMAT_RGB : PNG_FORMAT_RGBA;
    img.flags = PNG_IMAGE_FLAG_FAST;
    // Encoded in memory, then written with every write checked (a full
    // disk or `ulimit -f` named as the system names it).
    png_alloc_size_t bytes = PNG_IMAGE_PNG_SIZE_MAX(img);  // (an upper bound: encoded once)
    std::vector<unsigned char> file(bytes);
    if (png_image_write_to_memory(&img, file.data(), &bytes, 0, px.data(), 0, nullptr) == 0)
        throw FormatError(std::string("cannot encode the PNG: ") + img.message);
    try {
        hzio::write_file(path, file.data(), bytes);
    } catch (const std::exception &e) {
        throw IoError(e.what());
    }
}

void img_write(const hz_write_request &request, const hz_dataset_view &view, const hz_task *) {
    const hz_write_request *req = &request;
    const hz_dataset_view *data = &view;
    {
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
        if (ext == "png" && v.dtype == HZ_DTYPE_U8) return write_png(req->path, w, h, c, px);
        char msg[512] = {};
        if (need_backend().write(req->path, ext.c_str(), w, h, uint32_t(c), v.dtype, px.data(), msg, sizeof msg) != 0) throw IoError(msg);
    }
}

const char *const kExtensions[] = {"png", "jpg", "jpeg", "exr", "hdr", "tif", "tiff", nullptr};

// The format as the SDK's C++ loader adapter takes it (hz/cpp/loader.hpp).
struct Images {
    static constexpr const char *prefix = "images";
    static constexpr hz_data_kind kinds = HZ_DATA_IMAGE;
    static constexpr uint32_t probe_bytes = 16;
    static constexpr const char *const *extensions = kExtensions;
    using FormatError = ::FormatError;
    using IoError = ::IoError;
    using Reader = ImgReader;
    static constexpr auto probe = img_probe;
    static constexpr auto open = img_open;
    static constexpr auto info = img_info;
    static constexpr auto metadata = img_metadata;
    static constexpr auto read_volume = img_read_volume;
    static constexpr auto write = img_write;
};
constexpr const hz_loader &kLoader = hz::loader<Images>::table;
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
