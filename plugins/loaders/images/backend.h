/*
 * The private interface between the images plugin (images_plugin.cpp, cheap
 * to load) and its OpenImageIO backend (images_oiio.cpp), which the plugin
 * dlopen()s from <plugin dir>/images.backend/ the first time an image is
 * read or written: linking OpenImageIO costs ~200 ms per process, so only
 * processes that touch images pay it. Not part of the SDK.
 */
#ifndef HZ_IMAGES_BACKEND_H
#define HZ_IMAGES_BACKEND_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define HZIMG_BACKEND_SYMBOL "hzimg_backend_v1"

typedef struct hzimg_info {
    uint64_t width, height;
    uint32_t channels;
    uint32_t dtype;  /* HZ_DTYPE_U8, U16 or F32 (what read() produces) */
    char format[32]; /* "png", "openexr", ...                         */
} hzimg_info;

typedef struct hzimg_backend {
    uint32_t struct_size;
    /* Reads the header of `path`. Returns 0, or -1 with a one-line `err`. */
    int (*info)(const char *path, hzimg_info *out, char *err, size_t err_size);
    /* Reads every pixel of subimage 0 into dst (channels x width x height,
       rows top to bottom) as `dtype`. Returns 0 or -1. */
    int (*read)(const char *path, uint32_t dtype, void *dst, uint64_t dst_bytes, char *err, size_t err_size);
    /* Writes pixels (channels x width x height of `dtype`) to `path` in the
       format named by `extension` ("png", "exr", ...). Returns 0 or -1. */
    int (*write)(const char *path, const char *extension, uint64_t width, uint64_t height, uint32_t channels, uint32_t dtype,
                 const void *pixels, char *err, size_t err_size);
} hzimg_backend;

#ifdef __cplusplus
}
#endif

#endif
