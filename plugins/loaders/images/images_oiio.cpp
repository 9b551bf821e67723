// The OpenImageIO backend of the images plugin (see backend.h).
#include "backend.h"

#include <hz/hz_types.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include "files.hpp"

#include <cstdio>
#include <fcntl.h>
#include <mutex>
#include <vector>
#include <unistd.h>
#include <cstring>
#include <string>

namespace {

// Some of OpenImageIO's format libraries (libpng) also print their errors to
// stderr; OIIO reports the same text through geterror(), which the caller
// turns into one error line. Silence fd 2 around backend calls.
class QuietStderr {
public:
    QuietStderr() {
        std::fflush(stderr);
        saved_ = ::dup(2);
        const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
        if (saved_ >= 0 && null >= 0) ::dup2(null, 2);
        if (null >= 0) ::close(null);
    }
    ~QuietStderr() {
        std::fflush(stderr);
        if (saved_ >= 0) {
            ::dup2(saved_, 2);
            ::close(saved_);
        }
    }
    QuietStderr(const QuietStderr &) = delete;
    QuietStderr &operator=(const QuietStderr &) = delete;

private:
    int saved_ = -1;
};
std::mutex quiet_mutex;  // one redirection at a time

void put(char *err, size_t n, const std::string &msg) {
    if (err && n) {
        std::string one = msg.substr(0, msg.find('\n'));
        std::snprintf(err, n, "%s", one.c_str());
    }
}

OIIO::TypeDesc type_of(uint32_t dtype) {
    switch (dtype) {
    case HZ_DTYPE_U8: return OIIO::TypeDesc::UINT8;
    case HZ_DTYPE_U16: return OIIO::TypeDesc::UINT16;
    case HZ_DTYPE_F32: return OIIO::TypeDesc::FLOAT;
    default: return OIIO::TypeDesc::UNKNOWN;
    }
}

// Pixels as stored: OpenImageIO premultiplies colour by alpha on reading
// (and divides on writing) unless told the data is unassociated.
const OIIO::ImageSpec &unassociated_config() {
    static const OIIO::ImageSpec config = [] {
        OIIO::ImageSpec c;
        c.attribute("oiio:UnassociatedAlpha", 1);
        return c;
    }();
    return config;
}

// The widest pixel count we accept (keeps a forged header from asking for
// an absurd allocation): 2^28 pixels x 4 channels.
constexpr uint64_t kMaxPixels = 1ull << 28;

int info(const char *path, hzimg_info *out, char *err, size_t n) {
    std::lock_guard<std::mutex> lock(quiet_mutex);
    QuietStderr quiet;
    try {
        auto in = OIIO::ImageInput::open(path, &unassociated_config());
        if (!in) {
            put(err, n, OIIO::geterror());
            return -1;
        }
        const OIIO::ImageSpec &s = in->spec();
        if (s.width <= 0 || s.height <= 0 || s.nchannels <= 0) {
            put(err, n, "image has no pixels");
            return -1;
        }
        if (uint64_t(s.width) * uint64_t(s.height) > kMaxPixels) {
            put(err, n, "image of " + std::to_string(s.width) + " x " + std::to_string(s.height) + " pixels exceeds the limit of 2^28");
            return -1;
        }
        out->width = uint64_t(s.width);
        out->height = uint64_t(s.height);
        out->channels = uint32_t(std::min(s.nchannels, 4));
        const OIIO::TypeDesc f = s.format;
        out->dtype = f == OIIO::TypeDesc::UINT8 ? HZ_DTYPE_U8 : f == OIIO::TypeDesc::UINT16 ? HZ_DTYPE_U16 : HZ_DTYPE_F32;
        std::snprintf(out->format, sizeof out->format, "%s", in->format_name());
        return 0;
    } catch (const std::exception &e) {
        put(err, n, e.what());
        return -1;
    }
}

int read(const char *path, uint32_t dtype, void *dst, uint64_t dst_bytes, char *err, size_t n) {
    std::lock_guard<std::mutex> lock(quiet_mutex);
    QuietStderr quiet;
    try {
        auto in = OIIO::ImageInput::open(path, &unassociated_config());
        if (!in) {
            put(err, n, OIIO::geterror());
            return -1;
        }
        const OIIO::ImageSpec &s = in->spec();
        const int ch = std::min(s.nchannels, 4);
        const OIIO::TypeDesc t = type_of(dtype);
        if (t == OIIO::TypeDesc::UNKNOWN) {
            put(err, n, "unsupported destination type");
            return -1;
        }
        if (uint64_t(s.width) * uint64_t(s.height) * uint64_t(ch) * t.size() > dst_bytes) {
            put(err, n, "destination too small");
            return -1;
        }
        // OpenImageIO 2.4 sizes its conversion buffer by the TIFF RowsPerStrip
        // tag; a forged value (more rows per strip than the image has) asks
        // for gigabytes for a tiny image (found by fuzz_images). Such files
        // are read one scanline at a time, converting through a row buffer.
        const int rps = s.get_int_attribute("tiff:RowsPerStrip", 0);
        if (rps > s.height) {
            const size_t px_in = size_t(s.nchannels) * t.size(), px_out = size_t(ch) * t.size();
            std::vector<unsigned char> row(size_t(s.width) * px_in);
            auto *out = static_cast<unsigned char *>(dst);
            for (int y = 0; y < s.height; ++y) {
                if (!in->read_scanline(s.y + y, s.z, t, row.data())) {
                    put(err, n, in->geterror());
                    return -1;
                }
                for (int x = 0; x < s.width; ++x)
                    std::memcpy(out + (size_t(y) * size_t(s.width) + size_t(x)) * px_out, row.data() + size_t(x) * px_in, px_out);
            }
            return 0;
        }
        if (!in->read_image(0, 0, 0, ch, t, dst)) {
            put(err, n, in->geterror());
            return -1;
        }
        return 0;
    } catch (const std::exception &e) {
        put(err, n, e.what());
        return -1;
    }
}

int write(const char *path, const char *ext, uint64_t w, uint64_t h, uint32_t ch, uint32_t dtype, const void *px, char *err, size_t n) {
    try {
        const OIIO::TypeDesc t = type_of(dtype);
        if (t == OIIO::TypeDesc::UNKNOWN || ch < 1 || ch > 4 || w == 0 || h == 0 || w * h > kMaxPixels) {
            put(err, n, "unsupported image layout");
            return -1;
        }
        auto out = OIIO::ImageOutput::create(ext);
        if (!out) {
            put(err, n, "no image writer for '." + std::string(ext) + "': " + OIIO::geterror());
            return -1;
        }
        OIIO::ImageSpec spec(int(w), int(h), int(ch), t);
        spec.attribute("png:compressionLevel", 3);
        spec.attribute("Software", "Horizon");
        spec.attribute("oiio:UnassociatedAlpha", 1);
        // Encoded in memory, then written with every write checked (the
        // PNG and JPEG writers report success, or exit through libjpeg, on
        // a full disk).
        std::vector<unsigned char> encoded;
        OIIO::Filesystem::IOVecOutput mem(encoded);
        const bool in_memory = out->supports("ioproxy");
        if (in_memory) out->set_ioproxy(&mem);
        if (!out->open(path, spec) || !out->write_image(t, px) || !out->close()) {
            put(err, n, out->geterror());
            return -1;
        }
        if (in_memory) hzio::write_file(path, encoded.data(), encoded.size());
        return 0;
    } catch (const std::exception &e) {
        put(err, n, e.what());
        return -1;
    }
}

const hzimg_backend kBackend = {sizeof(hzimg_backend), info, read, write};

}  // namespace

extern "C" __attribute__((visibility("default"))) const hzimg_backend *hzimg_backend_v1() { return &kBackend; }
