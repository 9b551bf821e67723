/*
 * Template loader plugin, in plain C: a tiny text streamline format (.hzt).
 *
 *   hzt 1                   first line: magic and version
 *   3                       points in streamline 0
 *   1.5 2 3                 x y z in RAS+ mm, one point per line
 *   ...
 *
 * It shows the whole contract: a pure probe, sizes checked against the file
 * before allocating, errors that name the file, cancellation, bounded
 * destinations and a writer that reports what it drops and skips the
 * delimiter after each streamline of a mapped TCK (HZ_LOADER_WRITES_GAP).
 */
#include <hz/hz.h>

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PLUGIN_ID "org.example.loader.hzt"

typedef struct reader {
    char *path;
    float *positions; /* parsed at open: the format is text */
    uint64_t nb_vertices;
    uint64_t *offsets;
    uint64_t nb_streamlines;
} reader;

static hz_status fail(hz_error *err, hz_status code, const char *path, const char *what) {
    if (err != NULL && err->struct_size >= sizeof(hz_error)) {
        err->code = code;
        snprintf(err->message, sizeof err->message, "hzt: %s: %s", path, what);
    }
    return code;
}

static int32_t HZ_ABI probe(const uint8_t *head, uint64_t size, const char *hint) {
    (void)hint;
    if (size >= 6 && memcmp(head, "hzt 1", 5) == 0 && (head[5] == '\n' || head[5] == '\r')) return 100;
    return 0;
}

static void free_reader(reader *r) {
    if (r == NULL) return;
    free(r->path);
    free(r->positions);
    free(r->offsets);
    free(r);
}

static hz_status HZ_ABI open_file(const hz_open_request *req, hz_reader **out, hz_error *err) {
    FILE *f;
    long size;
    char *text, *cur, *end;
    reader *r;
    uint64_t cap_v, cap_s;
    if (out != NULL) *out = NULL;
    if (req == NULL || req->path == NULL || out == NULL) return fail(err, HZ_E_INVALID_ARGUMENT, "?", "NULL argument");
    f = fopen(req->path, "rb");
    if (f == NULL) return fail(err, errno == ENOENT ? HZ_E_NOT_FOUND : HZ_E_IO, req->path, strerror(errno));
    if (fseek(f, 0, SEEK_END) != 0 || (size = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return fail(err, HZ_E_IO, req->path, "cannot determine the file size");
    }
    text = malloc((size_t)size + 1);
    if (text == NULL) {
        fclose(f);
        return fail(err, HZ_E_OUT_OF_MEMORY, req->path, "out of memory");
    }
    if (fread(text, 1, (size_t)size, f) != (size_t)size) {
        fclose(f);
        free(text);
        return fail(err, HZ_E_IO, req->path, "read error");
    }
    fclose(f);
    text[size] = '\0';
    if (probe((const uint8_t *)text, (uint64_t)size, NULL) < 50) {
        free(text);
        return fail(err, HZ_E_FORMAT, req->path, "first line is not 'hzt 1'");
    }
    r = calloc(1, sizeof *r);
    if (r == NULL || (r->path = malloc(strlen(req->path) + 1)) == NULL) {
        free(text);
        free(r);
        return fail(err, HZ_E_OUT_OF_MEMORY, req->path, "out of memory");
    }
    strcpy(r->path, req->path);
    /* Every point takes at least 6 bytes ("0 0 0\n") and every count 2:
       these bounds keep allocations proportional to the file size. */
    cap_v = (uint64_t)size / 6 + 1;
    cap_s = (uint64_t)size / 2 + 2;
    end = text + size;
    cur = strchr(text, '\n');
    cur = cur != NULL ? cur + 1 : end;
    r->offsets = malloc(sizeof(uint64_t) * 16);
    r->positions = malloc(sizeof(float) * 3 * 16);
    {
        uint64_t alloc_s = 16, alloc_v = 16;
        r->offsets[0] = 0;
        while (r->offsets && r->positions) {
            char *next;
            unsigned long long n, i;
            while (cur < end && (*cur == ' ' || *cur == '\n' || *cur == '\r' || *cur == '\t')) ++cur;
            if (cur >= end) break;
            errno = 0;
            n = strtoull(cur, &next, 10);
            if (next == cur || errno != 0 || *cur == '-') {
                free(text);
                free_reader(r);
                return fail(err, HZ_E_FORMAT, req->path, "expected a point count");
            }
            cur = next;
            if (n > cap_v - r->nb_vertices || r->nb_streamlines + 2 > cap_s) {
                free(text);
                free_reader(r);
                return fail(err, HZ_E_FORMAT, req->path, "point count larger than the file can hold");
            }
            if (r->nb_streamlines + 2 > alloc_s) {
                uint64_t *o;
                alloc_s *= 2;
                o = realloc(r->offsets, sizeof(uint64_t) * alloc_s);
                if (o == NULL) break;
                r->offsets = o;
            }
            if (r->nb_vertices + n > alloc_v) {
                float *p;
                while (r->nb_vertices + n > alloc_v) alloc_v *= 2;
                p = realloc(r->positions, sizeof(float) * 3 * alloc_v);
                if (p == NULL) break;
                r->positions = p;
            }
            for (i = 0; i < 3 * n; ++i) {
                double v;
                errno = 0;
                v = strtod(cur, &next);
                if (next == cur || !isfinite(v) || fabs(v) > 3.4e38) {
                    free(text);
                    free_reader(r);
                    return fail(err, HZ_E_FORMAT, req->path, "bad or missing coordinate (finite numbers only)");
                }
                r->positions[3 * r->nb_vertices + i] = (float)v;
                cur = next;
            }
            r->nb_vertices += n;
            r->offsets[++r->nb_streamlines] = r->nb_vertices;
        }
        if (r->offsets == NULL || r->positions == NULL) {
            free(text);
            free_reader(r);
            return fail(err, HZ_E_OUT_OF_MEMORY, req->path, "out of memory");
        }
    }
    free(text);
    *out = (hz_reader *)r;
    return HZ_OK;
}

static hz_status HZ_ABI get_info(hz_reader *h, hz_dataset_info *out, hz_error *err) {
    static const double identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    const reader *r = (const reader *)h;
    if (r == NULL || out == NULL || out->struct_size < sizeof *out) return fail(err, HZ_E_INVALID_ARGUMENT, "?", "bad get_info call");
    out->kind = HZ_DATA_STREAMLINES;
    snprintf(out->format, sizeof out->format, "hzt 1");
    out->nb_streamlines = r->nb_streamlines;
    out->nb_vertices = r->nb_vertices;
    memcpy(out->voxel_to_ras, identity, sizeof identity);
    out->source_space = HZ_SPACE_RASMM;
    return HZ_OK;
}

static hz_status HZ_ABI get_array_info(hz_reader *h, uint32_t i, hz_array_info *out, hz_error *err) {
    (void)i;
    (void)out;
    return fail(err, HZ_E_NOT_FOUND, h ? ((reader *)h)->path : "?", "the format holds no extra arrays");
}

static hz_status HZ_ABI visit_metadata(hz_reader *h, hz_metadata_visitor visit, void *ctx, hz_error *err) {
    (void)err;
    if (h != NULL && visit != NULL) visit(ctx, "version", "1");
    return HZ_OK;
}

static hz_status HZ_ABI read_streamlines(hz_reader *h, const hz_streamlines_dst *dst, const hz_task *task, hz_error *err) {
    const reader *r = (const reader *)h;
    uint64_t v;
    if (r == NULL || dst == NULL) return fail(err, HZ_E_INVALID_ARGUMENT, "?", "NULL argument");
    if (task != NULL && task->is_cancelled != NULL && task->is_cancelled(task)) return fail(err, HZ_E_CANCELLED, r->path, "cancelled");
    if (dst->positions_capacity < 3 * r->nb_vertices || dst->offsets_capacity < r->nb_streamlines + 1)
        return fail(err, HZ_E_BUFFER_TOO_SMALL, r->path, "destination too small");
    if (r->nb_vertices) memcpy(dst->positions, r->positions, sizeof(float) * 3 * r->nb_vertices);
    memcpy(dst->offsets, r->offsets, sizeof(uint64_t) * (r->nb_streamlines + 1));
    /* ABI 1.7: a loader that has every coordinate at hand may vouch for them
       (all finite, these exact bounds), and the host then does not read its
       copy again. Only when the host's struct has the field and its check
       record has room; left alone otherwise (the host checks for itself). */
    if (HZ_HAS_FIELD(dst, hz_streamlines_dst, check) && dst->check != NULL && dst->check->struct_size >= sizeof(hz_positions_check) &&
        r->nb_vertices > 0) {
        double lo[3], hi[3];
        int finite = 1, d;
        for (d = 0; d < 3; ++d) lo[d] = hi[d] = r->positions[d];
        for (v = 0; v < 3 * r->nb_vertices; ++v) {
            const double x = r->positions[v];
            finite &= isfinite(x) != 0;
            if (x < lo[v % 3]) lo[v % 3] = x;
            if (x > hi[v % 3]) hi[v % 3] = x;
        }
        if (finite) {
            dst->check->vouched = 1;
            for (d = 0; d < 3; ++d) {
                dst->check->bounds_min[d] = lo[d];
                dst->check->bounds_max[d] = hi[d];
            }
        }
    }
    if (task != NULL && task->report != NULL) task->report(task, 1.0, NULL);
    return HZ_OK;
}

static void HZ_ABI close_reader(hz_reader *h) { free_reader((reader *)h); }

static hz_status HZ_ABI write_file(const hz_write_request *req, const hz_dataset_view *data, const hz_task *task, hz_error *err) {
    FILE *f;
    uint64_t s, v, end;
    uint32_t i;
    const hz_streamlines_view *sv;
    (void)task;
    if (req == NULL || req->path == NULL || data == NULL) return fail(err, HZ_E_INVALID_ARGUMENT, "?", "NULL argument");
    if (data->kind != HZ_DATA_STREAMLINES) return fail(err, HZ_E_UNSUPPORTED, req->path, "streamlines only");
    for (i = 0; i < data->nb_arrays && req->on_dropped != NULL; ++i) req->on_dropped(req->ctx, data->arrays[i].name);
    sv = &data->streamlines;
    /* HZ_LOADER_WRITES_GAP (1.8): streamline s ends `gap` vertices before
       offsets[s + 1] (a mapped TCK's NaN delimiter), never read here. */
    if (sv->gap > 1) return fail(err, HZ_E_INVALID_ARGUMENT, req->path, "streamlines with a gap other than 0 or 1");
    f = fopen(req->path, "wb");
    if (f == NULL) return fail(err, HZ_E_IO, req->path, strerror(errno));
    fprintf(f, "hzt 1\n");
    for (s = 0; s < sv->nb_streamlines; ++s) {
        end = sv->offsets[s + 1] - sv->gap;
        fprintf(f, "%llu\n", (unsigned long long)(end - sv->offsets[s]));
        for (v = sv->offsets[s]; v < end; ++v)
            fprintf(f, "%.9g %.9g %.9g\n", sv->positions[3 * v], sv->positions[3 * v + 1], sv->positions[3 * v + 2]);
    }
    if (ferror(f) | fclose(f)) return fail(err, HZ_E_IO, req->path, "write error");
    return HZ_OK;
}

static const char *const k_extensions[] = {"hzt", NULL};
static const hz_loader k_loader = {
    .struct_size = sizeof(hz_loader),
    .data_kinds = HZ_DATA_STREAMLINES,
    .caps = HZ_LOADER_CAN_READ | HZ_LOADER_CAN_WRITE | HZ_LOADER_WRITES_GAP,
    .probe_bytes = 8,
    .extensions = k_extensions,
    .probe = probe,
    .open = open_file,
    .get_info = get_info,
    .get_array_info = get_array_info,
    .visit_metadata = visit_metadata,
    .read_streamlines = read_streamlines,
    .read_array = NULL, /* no per-point or per-streamline arrays */
    .read_volume = NULL,
    .read_mesh = NULL,
    .close = close_reader,
    .write = write_file,
    .locate_positions = NULL, /* (1.4) no zero-copy here */
};

static const char *const k_interfaces[] = {HZ_INTERFACE_LOADER, NULL};
static const hz_plugin_descriptor k_descriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = PLUGIN_ID,
    .name = "Text streamlines (template)",
    .version = "1.0.0",
    .vendor = "Example Vendor",
    .description = "A tiny text streamline format: a starting point for loaders",
    .license = "MIT",
    .interfaces = k_interfaces,
};

static bool HZ_ABI init(const hz_host *host, const char *path) {
    (void)host;
    (void)path;
    return true;
}
static void HZ_ABI deinit(void) {}
static uint32_t HZ_ABI count(void) { return 1; }
static const hz_plugin_descriptor *HZ_ABI descriptor(uint32_t i) { return i == 0 ? &k_descriptor : NULL; }
static const void *HZ_ABI get_interface(const char *id, const char *iface) {
    if (id && iface && strcmp(id, PLUGIN_ID) == 0 && strcmp(iface, HZ_INTERFACE_LOADER) == 0) return &k_loader;
    return NULL;
}

HZ_DECLARE_PLUGIN_ENTRY = {
    .struct_size = sizeof(hz_plugin_entry),
    .abi = HZ_ABI_VERSION_INIT,
    .init = init,
    .deinit = deinit,
    .get_plugin_count = count,
    .get_plugin_descriptor = descriptor,
    .get_interface = get_interface,
};
