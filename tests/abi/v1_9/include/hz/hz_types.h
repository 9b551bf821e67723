/*
 * Horizon plugin SDK: types shared by every plugin kind.
 *
 * Conventions that hold for every struct in this SDK:
 *   - Every struct that crosses the boundary starts with `uint32_t struct_size`,
 *     set to sizeof(struct) by whoever fills it in. Readers test HZ_HAS_FIELD
 *     before touching a field added after x.0 of this major.
 *   - Output structs are zero-filled by the caller, who sets struct_size to
 *     what it knows; the callee writes only the fields that fit.
 *   - No C enum type appears in a field or signature (its size is
 *     implementation-defined): each enumeration is a fixed-width typedef plus
 *     an anonymous enum of constants.
 *   - Strings are UTF-8 and NUL-terminated.
 *   - Counts and offsets are uint64_t: tractograms exceed 2^31 vertices.
 */
#ifndef HZ_TYPES_H
#define HZ_TYPES_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hz_macros.h"

HZ_EXTERN_C_BEGIN

/* ---------------------------------------------------------------- sizes */

#define HZ_NAME_SIZE 256           /* fixed capacity of short names, incl. NUL */
#define HZ_PATH_SIZE 4096          /* fixed capacity of paths, incl. NUL       */
#define HZ_ERROR_MESSAGE_SIZE 1024 /* capacity of hz_error.message, incl. NUL  */

/* --------------------------------------------------------------- status */

/*
 * Result of every fallible call. The host treats a code it does not know as
 * HZ_E_INTERNAL, so new codes can be added in a minor version.
 */
typedef int32_t hz_status;
enum {
    HZ_OK = 0,
    HZ_E_INVALID_ARGUMENT = 1, /* a parameter violates the documented contract    */
    HZ_E_UNSUPPORTED = 2,      /* valid request this plugin does not implement     */
    HZ_E_NOT_FOUND = 3,        /* file, id or parameter name does not exist        */
    HZ_E_IO = 4,               /* the operating system refused a read or write     */
    HZ_E_FORMAT = 5,           /* the data is malformed                            */
    HZ_E_DTYPE = 6,            /* a data type the caller or file cannot represent  */
    HZ_E_OUT_OF_MEMORY = 7,    /* an allocation failed                             */
    HZ_E_BUFFER_TOO_SMALL = 8, /* a destination view is smaller than required      */
    HZ_E_CANCELLED = 9,        /* the task asked to stop; not an error to report   */
    HZ_E_BAD_STATE = 10,       /* call made in the wrong order (e.g. read before open) */
    HZ_E_INTERNAL = 11         /* a bug in the plugin (caught exception, assertion) */
};

/*
 * Error details. CALLER-owned; every fallible function takes a pointer that
 * may be NULL (then no message is written). On failure the callee sets `code`
 * and writes a self-contained one-line message into `message` (truncated to
 * fit, always NUL-terminated) that names the file or offset concerned and,
 * where it can, the rule broken. The callee never keeps the pointer.
 */
typedef struct hz_error {
    uint32_t struct_size; /* set by the caller: sizeof(hz_error)       */
    hz_status code;       /* set by the callee on failure              */
    char message[HZ_ERROR_MESSAGE_SIZE];
} hz_error;

/* ---------------------------------------------------------------- dtype */

/* Element type of an array crossing the boundary. */
typedef uint32_t hz_dtype;
enum {
    HZ_DTYPE_UNKNOWN = 0,
    HZ_DTYPE_U8 = 1,
    HZ_DTYPE_I8 = 2,
    HZ_DTYPE_U16 = 3,
    HZ_DTYPE_I16 = 4,
    HZ_DTYPE_U32 = 5,
    HZ_DTYPE_I32 = 6,
    HZ_DTYPE_U64 = 7,
    HZ_DTYPE_I64 = 8,
    HZ_DTYPE_F16 = 9,
    HZ_DTYPE_F32 = 10,
    HZ_DTYPE_F64 = 11,
    HZ_DTYPE_RGB8 = 12,  /* 3 x u8 per element  */
    HZ_DTYPE_RGBA8 = 13  /* 4 x u8 per element  */
};

/* ------------------------------------------------------------ array view */

/*
 * A bounded, byte-strided view of an n-dimensional array (at most 4 axes).
 * Axis 0 varies slowest unless the strides say otherwise; the element at
 * index (i0, i1, ...) lives at data + sum(i_k * stride_bytes[k]).
 * The owner and lifetime are stated wherever a view is passed.
 * A writer MUST NOT touch bytes outside [data, data + capacity_bytes).
 */
typedef struct hz_array_view {
    uint32_t struct_size;
    hz_dtype dtype;
    void *data;
    uint64_t capacity_bytes;
    uint32_t ndim;           /* 1..4                                    */
    uint32_t reserved0;      /* zero                                    */
    uint64_t shape[4];       /* extents of the first ndim axes          */
    int64_t stride_bytes[4]; /* byte strides of the first ndim axes     */
} hz_array_view;

/* ------------------------------------------------------- streamlines view */

/*
 * Streamlines as positions + offsets with a sentinel (the TRX layout), in
 * RAS+ millimetres. Streamline s is positions[offsets[s] .. offsets[s+1] - gap).
 * offsets has nb_streamlines + 1 entries, offsets[0] == 0,
 * offsets[s+1] >= offsets[s] + gap, offsets[nb_streamlines] == nb_vertices.
 * A streamline of gap vertices only is empty. Owner and lifetime are stated
 * wherever it is passed.
 *
 * gap (since 1.5; reserved zero before): vertices after each streamline
 * that belong to none, 0 or 1 (an MRtrix TCK file mapped as it is: its NaN
 * delimiter triples stay in place, and nb_vertices counts them). The host
 * passes gap 1 only to clustering plugins whose descriptor declares ABI
 * 1.5 or later and (since 1.8) to writers whose loader declares
 * HZ_LOADER_WRITES_GAP; other plugins receive gap 0 (a copy without
 * delimiters when needed).
 */
typedef struct hz_streamlines_view {
    uint32_t struct_size;
    uint32_t gap;              /* since 1.5 (was reserved0): see above  */
    const float *positions;    /* nb_vertices x 3, xyz interleaved      */
    uint64_t nb_vertices;
    const uint64_t *offsets;   /* nb_streamlines + 1                    */
    uint64_t nb_streamlines;
} hz_streamlines_view;

/* --------------------------------------------------------- param schema */

/* Parameter value type. Every value travels as double[components]. */
typedef uint32_t hz_param_type;
enum {
    HZ_PARAM_FLOAT = 1,       /* components == 1                                  */
    HZ_PARAM_INT = 2,         /* integral double, components == 1                 */
    HZ_PARAM_BOOL = 3,        /* 0 or 1                                           */
    HZ_PARAM_VEC2 = 4,
    HZ_PARAM_VEC3 = 5,
    HZ_PARAM_COLOR3 = 6,      /* linear RGB in [0,1]                              */
    HZ_PARAM_ENUM = 7,        /* integral index into enum_labels                  */
    HZ_PARAM_FLOAT_ARRAY = 8  /* 1..components values; min/max/default[0] apply to every element */
};

/* Parameter flags (bit set). */
typedef uint32_t hz_param_flags;
enum {
    HZ_PARAM_FLAG_LOG_SCALE = 1u << 0,          /* UI hint: logarithmic slider                  */
    HZ_PARAM_FLAG_HIDDEN = 1u << 1,             /* not shown in generated UIs                   */
    HZ_PARAM_FLAG_REQUIRES_RECOMPILE = 1u << 2  /* shader: value selects code (INT/BOOL/ENUM only) */
};

/*
 * One parameter of a shader or clustering plugin. PLUGIN-owned, static,
 * valid until the library's deinit() returns. Rules checked by
 * `horizon validate`: `name` is a unique identifier [A-Za-z_][A-Za-z0-9_]*;
 * all of min/max/default are finite for the first `components` slots and
 * min <= default <= max; ENUM has enum_labels with exactly max-min+1 entries.
 */
typedef struct hz_param_info {
    uint32_t struct_size;
    hz_param_type type;
    const char *name;     /* identifier, used in scene files and as GLSL uniform suffix */
    const char *label;    /* display label, may be ""                                  */
    const char *group;    /* UI grouping, may be ""                                    */
    const char *unit;     /* "mm", "", ...                                             */
    const char *tooltip;  /* one sentence, may be ""                                   */
    hz_param_flags flags;
    uint32_t components;  /* 1..4; for FLOAT_ARRAY the maximum array length (<= 64)    */
    double min_value[4];
    double max_value[4];
    double default_value[4]; /* FLOAT_ARRAY: see default_array                          */
    const char *const *enum_labels; /* ENUM: NULL-terminated; otherwise NULL            */
    /* FLOAT_ARRAY only: default_array_count values (<= components); otherwise 0/NULL. */
    uint32_t default_array_count;
    const double *default_array;
} hz_param_info;

HZ_EXTERN_C_END

#endif /* HZ_TYPES_H */
