/*
 * Horizon plugin SDK: the loader interface ("hz.loader/1").
 *
 * A loader reads (and optionally writes) one family of file formats into the
 * host's data model. Everything it hands the host is in RAS+ millimetres,
 * voxel-centre convention (nibabel's RASMM): streamline positions, mesh
 * vertices, and the voxel-to-RAS affine of volumes. get_info() also reports
 * the space the file itself used, so a writer can restore it.
 *
 * Reading protocol (all calls on one reader come from one thread at a time):
 *   open() -> get_info() -> [get_array_info() / visit_metadata()] ->
 *   host allocates destinations from the info -> read_*() -> close()
 * close() is always allowed, also after any failed call.
 *
 * Bulk data goes into HOST-owned destinations, bounded by the capacities the
 * host passes; a loader never returns memory the host has to free.
 *
 * This table is all a loader must provide. Reading a file in place (the host
 * maps the positions instead of receiving a copy), vouching for what was
 * read, and writing streamlines with delimiters are optional extensions a
 * loader may offer (hz_extensions.h).
 */
#ifndef HZ_LOADER_H
#define HZ_LOADER_H

#include "hz_host.h"

HZ_EXTERN_C_BEGIN

/* Kind of data a file holds (bit set in hz_loader.data_kinds). */
typedef uint32_t hz_data_kind;
enum {
    HZ_DATA_STREAMLINES = 1u << 0,
    HZ_DATA_VOLUME = 1u << 1,
    HZ_DATA_MESH = 1u << 2,
    /* Since 1.2. A 2D image, described with the volume fields: ndim = 3,
       dims = {channels (1..4), width, height}, dtype U8, U16, F16 or F32;
       pixels interleaved, rows top to bottom; read with read_volume() and
       written from hz_dataset_view.voxels. Colour values are as stored
       (8/16-bit files are sRGB-encoded; float files linear). */
    HZ_DATA_IMAGE = 1u << 3
};

/* Capabilities (bit set in hz_loader.caps). */
typedef uint32_t hz_loader_caps;
enum {
    HZ_LOADER_CAN_READ = 1u << 0,  /* open/get_info/read_* are non-NULL */
    HZ_LOADER_CAN_WRITE = 1u << 1, /* write is non-NULL                 */
    /* 1.8-1.9, ignored since 1.10 (kept for source compatibility): a writer
       that takes delimited streamlines offers HZ_EXT_DELIMITED_STREAMLINES. */
    HZ_LOADER_WRITES_GAP HZ_DEPRECATED("ignored since ABI 1.10: offer the extension hz.ext.delimited-streamlines/1 "
                                       "(HZ_EXT_DELIMITED_STREAMLINES, hz_extensions.h) to be given delimited streamlines") = 1u << 2
};

/* Coordinate space the file stores its geometry in (informative). */
typedef uint32_t hz_space;
enum {
    HZ_SPACE_UNKNOWN = 0,
    HZ_SPACE_RASMM = 1,       /* world RAS+ mm as stored (TCK, TRX, GIFTI)          */
    HZ_SPACE_VOXMM = 2,       /* voxel index x voxel size, corner origin (TRK)      */
    HZ_SPACE_VOXEL = 3,       /* voxel indices, affine maps to RAS+ mm (NIfTI)      */
    HZ_SPACE_SURFACE_RAS = 4  /* FreeSurfer tkr-RAS                                  */
};

/* What a per-element data array is attached to. */
typedef uint32_t hz_attach;
enum {
    HZ_ATTACH_VERTEX = 1,     /* one row per streamline vertex or mesh vertex (dpv) */
    HZ_ATTACH_STREAMLINE = 2, /* one row per streamline (dps)                       */
    HZ_ATTACH_FACE = 3,       /* one row per mesh triangle                          */
    /* Since 1.1. A named group of streamlines: rows are streamline indices
       (HZ_DTYPE_U32 or U64, 1 component, any count; groups may overlap). */
    HZ_ATTACH_GROUP = 4,
    /* Since 1.1. Data of one group (TRX dpg): 1 row; the array is named
       "<group>/<name>". Readers that do not know a value skip the array. */
    HZ_ATTACH_GROUP_DATA = 5
};

/* Opaque reader, PLUGIN-owned from open() until close(). */
typedef struct hz_reader hz_reader;

/*
 * What to open. HOST-owned, valid for the open() call only; the plugin copies
 * what it keeps.
 */
typedef struct hz_open_request {
    uint32_t struct_size;
    uint32_t flags;      /* zero in 1.0                                     */
    const char *path;    /* UTF-8 file system path                          */
} hz_open_request;

/*
 * Description of an open file. Output struct: the CALLER zero-fills it and
 * sets struct_size; the plugin fills the fields that fit.
 */
typedef struct hz_dataset_info {
    uint32_t struct_size;
    hz_data_kind kind;        /* exactly one bit                                         */
    char format[32];          /* short format name with variant, e.g. "tck Float32LE"     */
    /* streamlines */
    uint64_t nb_streamlines;
    uint64_t nb_vertices;     /* streamline vertices, or mesh vertices                   */
    /* mesh */
    uint64_t nb_faces;        /* triangles                                               */
    /* volume */
    hz_dtype dtype;           /* stored voxel type                                       */
    uint32_t ndim;            /* 1..7                                                    */
    uint64_t dims[8];         /* extents of the first ndim axes, x fastest               */
    double scale_slope;       /* value = raw * slope + inter; slope 1, inter 0 if none   */
    double scale_inter;
    /* geometry: row-major 4x4. Volumes: voxel index -> RAS+ mm. Streamlines and
       meshes: the reference grid (identity when the file has none). */
    double voxel_to_ras[16];
    uint64_t ref_dims[3];     /* reference grid extents, 0 when unknown                  */
    hz_space source_space;    /* the space the file stores geometry in                   */
    uint32_t nb_arrays;       /* extra arrays, described by get_array_info()             */
} hz_dataset_info;

/*
 * One extra data array (per-vertex, per-streamline, per-face). Output struct
 * (caller zero-fills, sets struct_size). `name` is PLUGIN-owned, valid until
 * close().
 */
typedef struct hz_array_info {
    uint32_t struct_size;
    hz_attach attach;
    const char *name;
    hz_dtype dtype;           /* type read_array() produces natively                    */
    uint32_t components;      /* columns, >= 1                                          */
    uint64_t count;           /* rows                                                   */
} hz_array_info;

/*
 * Destination of read_streamlines(). HOST-owned buffers, valid for the call.
 * positions receives nb_vertices x 3 floats (RAS+ mm); offsets receives
 * nb_streamlines + 1 entries with offsets[0] = 0 and the final sentinel
 * nb_vertices. Capacities are in elements (floats, uint64s).
 */
struct hz_positions_check;  /* hz_extensions.h */
struct hz_positions_extent; /* hz_extensions.h */

/* 1.4-1.9, never set since 1.10 (kept for source compatibility). */
typedef uint32_t hz_streamlines_flags;
enum {
    HZ_STREAMLINES_OFFSETS_ONLY HZ_DEPRECATED("never set since ABI 1.10: a loader that reads in place offers "
                                              "hz.ext.mapped-positions/1, whose read_offsets() the host calls instead") = 1u << 0
};

typedef struct hz_streamlines_dst {
    uint32_t struct_size;
    union {
        uint32_t reserved0; /* zero                                */
        /* 1.4-1.9: hz_streamlines_flags; always zero since 1.10. */
        uint32_t flags HZ_DEPRECATED("always zero since ABI 1.10: the host asks for offsets only through "
                                     "hz.ext.mapped-positions/1 (read_offsets)");
    };
    float *positions;
    uint64_t positions_capacity;
    uint64_t *offsets;
    uint64_t offsets_capacity;
    /* 1.7-1.9, always NULL since 1.10 (kept for source compatibility; a
       loader vouches through hz.ext.checked-read/1 instead). */
    struct hz_positions_check *check HZ_DEPRECATED("always NULL since ABI 1.10: vouch for the positions read through "
                                                   "hz.ext.checked-read/1 (read_streamlines_checked, hz_extensions.h)");
} hz_streamlines_dst;

/* The size of hz_streamlines_dst before 1.7 (1.4-1.9 plugins compared with it). */
#define HZ_STREAMLINES_DST_SIZE_1_4 40u

/*
 * Destination of read_mesh(). HOST-owned, valid for the call. vertices
 * receives nb_vertices x 3 floats (RAS+ mm), faces nb_faces x 3 uint32
 * (0-based, counter-clockwise outward). Capacities in elements.
 */
typedef struct hz_mesh_dst {
    uint32_t struct_size;
    uint32_t reserved0;
    float *vertices;
    uint64_t vertices_capacity;
    uint32_t *faces;
    uint64_t faces_capacity;
} hz_mesh_dst;

/* A named extra array handed to write(). HOST-owned, valid for the call. */
typedef struct hz_named_array {
    uint32_t struct_size;
    hz_attach attach;
    const char *name;
    hz_dtype dtype;
    uint32_t components;
    uint64_t count;
    const void *data;         /* count x components, C order, contiguous, native endian */
} hz_named_array;

/* One header entry. Strings HOST- or PLUGIN-owned as stated at each use. */
typedef struct hz_metadata_entry {
    const char *key;
    const char *value;
} hz_metadata_entry;

/*
 * What to write. HOST-owned, valid for the call. All geometry is RAS+ mm;
 * the writer converts to the file's own space.
 */
typedef struct hz_dataset_view {
    uint32_t struct_size;
    hz_data_kind kind;
    hz_streamlines_view streamlines;     /* kind == STREAMLINES                */
    const float *mesh_vertices;          /* kind == MESH: nb x 3               */
    uint64_t mesh_nb_vertices;
    const uint32_t *mesh_faces;          /* kind == MESH: nb x 3               */
    uint64_t mesh_nb_faces;
    hz_array_view voxels;                /* kind == VOLUME: x fastest          */
    double voxel_to_ras[16];             /* as in hz_dataset_info              */
    uint64_t ref_dims[3];
    uint32_t nb_arrays;
    const hz_named_array *arrays;
    uint32_t nb_metadata;                /* header entries to carry over       */
    const hz_metadata_entry *metadata;
    /* Since 1.1 (test HZ_HAS_FIELD): the volume's full extents (voxels.shape
       holds at most 4 axes; trailing axes are merged there) and the scaling
       value = raw * scale_slope + scale_inter (1 and 0 when unscaled). */
    uint32_t volume_ndim;
    uint64_t volume_dims[8];
    double scale_slope;
    double scale_inter;
} hz_dataset_view;

/*
 * Where and how to write. HOST-owned, valid for the call. The host already
 * chose the path (a temporary file it renames on success): the plugin writes
 * exactly that path and nothing else.
 */
typedef struct hz_write_request {
    uint32_t struct_size;
    uint32_t flags;                      /* zero in 1.0                         */
    const char *path;
    const char *extension;               /* the target's extension, e.g. "tck"  */
    /*
     * Called once for every piece of the dataset the format cannot hold
     * (e.g. "per-vertex array 'fa'"), before write() returns. May be NULL.
     * `what` is valid only during the callback. [calling-thread]
     */
    void(HZ_ABI *on_dropped)(void *ctx, const char *what);
    void *ctx;
    /* ---- since 1.3 (check with HZ_HAS_FIELD) ---- */
    /*
     * The name `path` receives when the write succeeds (the user's target).
     * [valid during write()]
     */
    const char *final_path;
    /*
     * For formats that keep one dataset in several files (NIfTI .hdr + .img).
     * The writer writes each extra file to a temporary path of its choice in
     * the directory of `path`, then reports it: `temp_path` is what it wrote,
     * `final` the name the file must take (derived from final_path). The host
     * copies both strings. After a successful write() the host renames every
     * companion into place, then `path` (so a reader never finds the main
     * file without its companions); after a failed write() it deletes them.
     * Returns HZ_E_INVALID_ARGUMENT for a NULL or out-of-directory path.
     * [calling-thread, only during write()]
     */
    hz_status(HZ_ABI *add_companion)(void *companion_ctx, const char *temp_path, const char *final);
    void *companion_ctx;
} hz_write_request;

/* Callback of visit_metadata(); strings valid only during the callback. */
typedef void(HZ_ABI *hz_metadata_visitor)(void *ctx, const char *key, const char *value);

/*
 * The loader interface table. PLUGIN-owned, valid until deinit().
 * Function pointers a capability does not need may be NULL (write without
 * HZ_LOADER_CAN_WRITE; read_volume for a streamline-only loader; ...).
 */
typedef struct hz_loader {
    uint32_t struct_size;
    hz_data_kind data_kinds;             /* kinds this loader produces/accepts  */
    hz_loader_caps caps;
    uint32_t probe_bytes;                /* leading bytes probe() wants (<= 65536) */
    /* NULL-terminated lowercase extensions without the leading dot; may have
       several parts ("nii.gz"). The longest matching suffix wins. */
    const char *const *extensions;

    /*
     * Confidence in [0,100] that a file starting with `head` is this format
     * (>= 50: yes). `head_size` may be smaller than probe_bytes (short file)
     * or 0; `file_name_hint` may be NULL. PURE: no I/O, no allocation, no
     * global state, never reads past head_size. [thread-safe]
     */
    int32_t(HZ_ABI *probe)(const uint8_t *head, uint64_t head_size, const char *file_name_hint);

    /*
     * Opens `req->path` and validates what is needed to answer get_info()
     * without reading past the file (declared sizes are checked against the
     * file size before anything is allocated). On success *out is a
     * PLUGIN-owned reader, valid until close(). On failure *out is NULL and
     * err says why, naming the file. [worker]
     */
    hz_status(HZ_ABI *open)(const hz_open_request *req, hz_reader **out, hz_error *err);

    /* Fills `out` (see hz_dataset_info). [worker, serialized per reader] */
    hz_status(HZ_ABI *get_info)(hz_reader *reader, hz_dataset_info *out, hz_error *err);

    /* Describes extra array `index` < info.nb_arrays. [worker, serialized per reader] */
    hz_status(HZ_ABI *get_array_info)(hz_reader *reader, uint32_t index, hz_array_info *out,
                                      hz_error *err);

    /*
     * Calls `visitor(ctx, key, value)` for each header entry, in file order
     * (repeated keys are visited repeatedly). [worker, serialized per reader]
     */
    hz_status(HZ_ABI *visit_metadata)(hz_reader *reader, hz_metadata_visitor visitor, void *ctx,
                                      hz_error *err);

    /*
     * Reads all streamlines into `dst` (capacities from get_info). Returns
     * HZ_E_BUFFER_TOO_SMALL, writing nothing out of bounds, when they do not
     * fit. [worker, serialized per reader]
     */
    hz_status(HZ_ABI *read_streamlines)(hz_reader *reader, const hz_streamlines_dst *dst,
                                        const hz_task *task, hz_error *err);

    /*
     * Reads extra array `index` into `dst` (dtype as in get_array_info, shape
     * [count, components], any strides within capacity).
     * [worker, serialized per reader]
     */
    hz_status(HZ_ABI *read_array)(hz_reader *reader, uint32_t index, const hz_array_view *dst,
                                  const hz_task *task, hz_error *err);

    /*
     * Reads the voxels into `dst`: dst->dtype is info.dtype (raw values) or
     * HZ_DTYPE_F32/F64 (scaled by slope/inter). Shape = dims, any strides.
     * [worker, serialized per reader]
     */
    hz_status(HZ_ABI *read_volume)(hz_reader *reader, const hz_array_view *dst, const hz_task *task,
                                   hz_error *err);

    /* Reads the triangle mesh into `dst`. [worker, serialized per reader] */
    hz_status(HZ_ABI *read_mesh)(hz_reader *reader, const hz_mesh_dst *dst, const hz_task *task,
                                 hz_error *err);

    /* Releases the reader; NULL is a no-op. [worker] */
    void(HZ_ABI *close)(hz_reader *reader);

    /*
     * Writes `data` to `req->path` in this loader's format. Reports every part
     * it cannot store through req->on_dropped. On failure the file at
     * req->path may be partial: the host deletes it. data->streamlines.gap
     * is 0 unless the loader offers HZ_EXT_DELIMITED_STREAMLINES.
     * [worker]
     */
    hz_status(HZ_ABI *write)(const hz_write_request *req, const hz_dataset_view *data,
                             const hz_task *task, hz_error *err);

    /* 1.4-1.9, never called since 1.10 (kept for source compatibility: a
       1.9 loader's table still compiles): a loader that lets the host map
       its positions offers hz.ext.mapped-positions/1. */
    hz_status(HZ_ABI *locate_positions)(hz_reader *reader, struct hz_positions_extent *out, hz_error *err)
        HZ_DEPRECATED("never called since ABI 1.10: offer hz.ext.mapped-positions/1 (HZ_EXT_MAPPED_POSITIONS, "
                      "hz_extensions.h) to have the host map the positions");
} hz_loader;

HZ_EXTERN_C_END

#endif /* HZ_LOADER_H */
