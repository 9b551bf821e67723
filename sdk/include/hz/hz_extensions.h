/*
 * Horizon plugin SDK: optional extensions.
 *
 * The core tables (hz.loader/1, hz.shader/1, hz.clustering/1) are all a
 * plugin must provide, and they mean only what their headers say. A
 * capability beyond them is an EXTENSION, in the manner of CLAP's: a string
 * id with a table of its own.
 *
 *   - A plugin offers an extension by listing its id in
 *     hz_plugin_descriptor.interfaces (after the core interface) and by
 *     returning its table from get_interface(plugin_id, id). The table is
 *     PLUGIN-owned, static, valid until deinit(), and starts with
 *     struct_size like every table of this SDK.
 *   - A host asks only for the extensions it knows, and only of plugins that
 *     list them; it treats a listed id whose table is NULL, too small, or
 *     missing a function as not offered (`horizon validate` reports it as a
 *     failure). Ids it does not know are ignored.
 *   - A plugin that offers no extension works with every host of the major,
 *     and an extension's absence never changes what the core table means.
 *   - The "/N" at the end of an id is the extension's revision: an
 *     incompatible change gets a new id; a compatible one appends fields.
 *
 * Extensions of this SDK (host support since ABI 1.10):
 *   HZ_EXT_MAPPED_POSITIONS     loader: the host maps the positions from the file
 *   HZ_EXT_CHECKED_READ         loader: vouches for the positions it decodes
 *   HZ_EXT_DELIMITED_STREAMLINES loader (write()) and clustering (run()):
 *                               takes streamlines with a delimiter vertex after each
 *   HZ_EXT_OPEN_TASK            loader: open() with a task (progress, cancel)
 *   HZ_EXT_WRITE_SELECTION      loader: writes chosen streamlines of a view,
 *                               without the host copying them first (1.11)
 *
 * Thread and ownership rules of the functions below are those of the core
 * loader functions they stand beside ([worker, serialized per reader]).
 */
#ifndef HZ_EXTENSIONS_H
#define HZ_EXTENSIONS_H

#include "hz_loader.h"

HZ_EXTERN_C_BEGIN

/* ======================================================= mapped positions */

/*
 * "hz.ext.mapped-positions/1" (loaders): reading a file in place. When the
 * positions of an open file are stored exactly as the host holds them, the
 * loader says where; the host maps that extent read-only (copy-on-write)
 * instead of receiving a copy, and asks only for the offsets.
 */
#define HZ_EXT_MAPPED_POSITIONS "hz.ext.mapped-positions/1"

/* Layout flags of hz_positions_extent (bit set). */
typedef uint32_t hz_extent_flags;
enum {
    /* crc32 holds the zlib CRC-32 of the stored bytes (a zip entry): the
       host verifies it. */
    HZ_EXTENT_HAS_CRC32 = 1u << 0,
    /*
     * Each streamline's vertices are followed in the file by one delimiter
     * vertex that belongs to no streamline (MRtrix TCK's NaN triple). The
     * extent then spans nb_vertices + nb_streamlines vertices, and
     * read_offsets() gives offsets into that span: streamline s is
     * [offsets[s], offsets[s+1] - 1), its delimiter is vertex
     * offsets[s+1] - 1, and offsets[nb_streamlines] is nb_vertices +
     * nb_streamlines. The host checks every delimiter is all-NaN (unless
     * HZ_EXTENT_CHECKED) and keeps them in place: the streamlines reach other
     * plugins with hz_streamlines_view.gap 1 (HZ_EXT_DELIMITED_STREAMLINES)
     * or as a copy without them.
     */
    HZ_EXTENT_DELIMITED = 1u << 1,
    /*
     * The loader has already read every stored coordinate of the extent
     * while opening the file (a TCK scan must, to find the delimiters) and
     * vouches for what the host would otherwise check in a pass over it:
     * every coordinate of every streamline vertex is finite, every delimiter
     * (with HZ_EXTENT_DELIMITED) is an all-NaN triple, and
     * bounds_min/bounds_max are exactly the smallest and largest x, y, z over
     * the streamline vertices. The host then maps the extent without reading
     * it (one with a CRC is read for the CRC anyway). `horizon validate`
     * checks every claim against the host's own pass, and so does a host
     * built with HZ_VERIFY_PLUGIN_CLAIMS (Debug and sanitizer builds).
     */
    HZ_EXTENT_CHECKED = 1u << 2,
    /*
     * `offset` is not a multiple of 4 (a TCK written by nibabel or DIPY stores
     * its data at byte 67): the host maps the extent all the same and copies
     * the floats to aligned memory when they are first used. Set only for an
     * offset that needs it; without it, an unaligned offset is an error.
     */
    HZ_EXTENT_UNALIGNED = 1u << 3
};

/*
 * Where a file stores the streamline positions as the host holds them:
 * nb_vertices x 3 float32, little-endian, RAS+ mm (no transform), contiguous
 * (or, with HZ_EXTENT_DELIMITED, one delimiter vertex after each streamline),
 * starting at byte `offset` of the file `path`. Output struct: the host
 * zero-fills it and sets struct_size and `accepts`; the loader writes only
 * fields that struct_size covers.
 */
typedef struct hz_positions_extent {
    uint32_t struct_size;
    hz_extent_flags flags;      /* OUTPUT: the layout, only flags in `accepts`
                                   (and HZ_EXTENT_HAS_CRC32)                     */
    /* OUTPUT: the file holding the positions: the path opened, or another
       file of a multi-file dataset (a TRX directory's positions.3.float32).
       PLUGIN-owned, valid until close(). */
    const char *path;
    uint64_t offset;            /* OUTPUT: byte offset of the first coordinate   */
    uint32_t crc32;             /* OUTPUT with HZ_EXTENT_HAS_CRC32               */
    /* INPUT, set by the host: the layout flags it can map
       (HZ_EXTENT_DELIMITED, HZ_EXTENT_CHECKED, HZ_EXTENT_UNALIGNED). A loader
       answers with no flag the host did not list. */
    hz_extent_flags accepts;
    /* OUTPUT with HZ_EXTENT_CHECKED: the bounds of the streamline vertices'
       coordinates, x y z, RAS+ mm. */
    double bounds_min[3];
    double bounds_max[3];
} hz_positions_extent;

/* The table of HZ_EXT_MAPPED_POSITIONS. */
typedef struct hz_ext_mapped_positions {
    uint32_t struct_size;
    uint32_t reserved0; /* zero */

    /*
     * After get_info(), for a streamlines file: when the positions are stored
     * as hz_positions_extent describes, fills `out` and returns HZ_OK, having
     * checked that the extent lies inside the file; otherwise (another dtype,
     * a compressed entry, a layout the host did not accept) returns
     * HZ_E_UNSUPPORTED, and the host reads with read_streamlines() as usual.
     * Without HZ_EXTENT_CHECKED, the host checks every coordinate is finite
     * as it maps them. [worker, serialized per reader]
     */
    hz_status(HZ_ABI *locate_positions)(hz_reader *reader, hz_positions_extent *out, hz_error *err);

    /*
     * After locate_positions() returned HZ_OK on this reader: writes the
     * nb_streamlines + 1 offsets into the located extent (see
     * HZ_EXTENT_DELIMITED) to `offsets`, HOST-owned with room for `capacity`
     * entries; HZ_E_BUFFER_TOO_SMALL, writing nothing, when they do not fit;
     * HZ_E_BAD_STATE before a successful locate_positions().
     * [worker, serialized per reader]
     */
    hz_status(HZ_ABI *read_offsets)(hz_reader *reader, uint64_t *offsets, uint64_t capacity, const hz_task *task,
                                    hz_error *err);
} hz_ext_mapped_positions;

/* ========================================================== checked read */

/*
 * "hz.ext.checked-read/1" (loaders): a loader that looks at every
 * coordinate while it decodes them (a TRK transform, a TCK copy after its
 * scan) vouches for them, so that the host does not read them all again.
 */
#define HZ_EXT_CHECKED_READ "hz.ext.checked-read/1"

/*
 * What the loader vouches for. HOST-owned, valid for the call; the host
 * zero-fills it and sets struct_size. The loader writes it only when
 * struct_size is at least sizeof(hz_positions_check), and only on the HZ_OK
 * path.
 */
typedef struct hz_positions_check {
    uint32_t struct_size;
    /* OUTPUT: nonzero when the loader vouches that every coordinate it wrote
       to dst->positions (all nb_vertices x 3 of them) is finite and that
       bounds_min/bounds_max are exactly the smallest and largest x, y, z
       among them; left zero otherwise (the host then checks them itself). */
    uint32_t vouched;
    double bounds_min[3]; /* OUTPUT with vouched, RAS+ mm */
    double bounds_max[3];
} hz_positions_check;

/* The table of HZ_EXT_CHECKED_READ. */
typedef struct hz_ext_checked_read {
    uint32_t struct_size;
    uint32_t reserved0; /* zero */

    /*
     * read_streamlines() that also fills `check` (HOST-owned, never NULL).
     * The host calls it instead of read_streamlines(). `horizon validate`
     * checks every vouch against the host's own pass, and so does a host
     * built with HZ_VERIFY_PLUGIN_CLAIMS. [worker, serialized per reader]
     */
    hz_status(HZ_ABI *read_streamlines_checked)(hz_reader *reader, const hz_streamlines_dst *dst, hz_positions_check *check,
                                                const hz_task *task, hz_error *err);
} hz_ext_checked_read;

/* ================================================= delimited streamlines */

/*
 * "hz.ext.delimited-streamlines/1" (loaders and clustering plugins): the
 * plugin takes streamlines with one vertex after each that belongs to none
 * (hz_streamlines_view.gap 1: a TCK mapped as it is, NaN delimiters in
 * place), in write()'s data (a loader) or in run()'s input (a clustering
 * plugin). Streamline s is then positions[offsets[s] .. offsets[s+1] - 1);
 * the plugin never reads the gap vertices, whatever they hold. A plugin that
 * does not offer it always receives gap 0 (the host copies the streamlines
 * without their delimiters first: 1.2 GB for 1M streamlines of 100 points).
 * A host passes gap 1 to a writer only when the dataset has no per-vertex
 * arrays.
 */
#define HZ_EXT_DELIMITED_STREAMLINES "hz.ext.delimited-streamlines/1"

/* The table of HZ_EXT_DELIMITED_STREAMLINES (a capability: no functions). */
typedef struct hz_ext_delimited_streamlines {
    uint32_t struct_size;
    uint32_t max_gap; /* the largest gap the plugin takes: 1 */
} hz_ext_delimited_streamlines;

/* ============================================================ open task */

/*
 * "hz.ext.open-task/1" (loaders): open() with a task. A loader whose open()
 * reads the whole file (a TCK or TRK scan: seconds for a 2 GB file, minutes
 * from a slow disk) reports its progress through task->report and stops
 * when task->is_cancelled; the host shows the one and offers the other
 * (the window's loading panel, the progress line on a terminal).
 */
#define HZ_EXT_OPEN_TASK "hz.ext.open-task/1"

/* The table of HZ_EXT_OPEN_TASK. */
typedef struct hz_ext_open_task {
    uint32_t struct_size;
    uint32_t reserved0; /* zero */

    /*
     * open() as hz_loader.open describes it, and the same reader, polling
     * `task` (HOST-owned, valid for the call, may be NULL): fractions
     * reported are in [0, 1] and do not decrease; a cancelled task gives
     * HZ_E_CANCELLED, *out NULL and nothing left open. The host calls it
     * instead of hz_loader.open. [worker]
     */
    hz_status(HZ_ABI *open)(const hz_open_request *req, const hz_task *task, hz_reader **out, hz_error *err);
} hz_ext_open_task;

/* ======================================================= write selection */

/*
 * "hz.ext.write-selection/1" (loaders that write streamlines; host support
 * since ABI 1.11): write() of some of a view's streamlines. Saving the
 * streamlines kept after cleaning a tractogram, or those a filter selects,
 * is then a pass over the kept streamlines where they lie (a mapped input
 * file) instead of a copy of them first: 19 GB at 10M streamlines of 175
 * points. A host that has a selection and a writer without this extension
 * copies the selected streamlines and calls write().
 */
#define HZ_EXT_WRITE_SELECTION "hz.ext.write-selection/1"

/* The table of HZ_EXT_WRITE_SELECTION. */
typedef struct hz_ext_write_selection {
    uint32_t struct_size;
    uint32_t reserved0; /* zero */

    /*
     * As hz_loader.write, of a file holding the streamlines
     * selection[0 .. nb_selected) of data->streamlines, in that order:
     *   - `selection` (HOST-owned, valid for the call) is strictly
     *     increasing, every entry < data->streamlines.nb_streamlines;
     *     nb_selected may be 0 (a file with no streamline), and `selection`
     *     is then NULL or not read.
     *   - data->streamlines is the whole view (its gap as for write(): 0
     *     unless the loader offers HZ_EXT_DELIMITED_STREAMLINES).
     *   - HZ_ATTACH_VERTEX arrays are the whole view's too (count =
     *     data->streamlines.nb_vertices, rows indexed like the positions):
     *     the writer takes the rows of the selected streamlines' vertices.
     *   - Every other array is already the selection's: HZ_ATTACH_STREAMLINE
     *     arrays have nb_selected rows, row k for the file's streamline k;
     *     HZ_ATTACH_GROUP arrays list indices of the file's streamlines
     *     (0 .. nb_selected); group data belong to the groups passed.
     * The file must read back as write() would have written the same
     * streamlines and arrays copied out beforehand; `horizon validate`
     * checks that it does. [worker]
     */
    hz_status(HZ_ABI *write_selection)(const hz_write_request *req, const hz_dataset_view *data, const uint64_t *selection,
                                       uint64_t nb_selected, const hz_task *task, hz_error *err);
} hz_ext_write_selection;

HZ_EXTERN_C_END

#endif /* HZ_EXTENSIONS_H */
