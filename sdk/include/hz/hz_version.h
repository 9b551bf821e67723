/*
 * Horizon plugin SDK: ABI version.
 *
 * Compatibility rule (enforced by the host, see sdk/docs/ABI.md):
 *   - The major version is part of the entry symbol name (hz_plugin_entry_v1).
 *     A host of major M only looks for hz_plugin_entry_vM and rejects an
 *     entry whose abi.major differs from M.
 *   - Any minor or patch difference is accepted in both directions. Growth
 *     within a major happens only by appending fields (struct_size tells the
 *     reader what is present) and by new interface ids.
 *
 * Changelog
 *   1.0.0  First published ABI: loader, shader and clustering interfaces,
 *          host services (log, extensions), tasks (progress, cancel).
 *   1.1.0  hz_attach gains HZ_ATTACH_GROUP and HZ_ATTACH_GROUP_DATA (TRX
 *          groups and data per group); hz_dataset_view gains volume_ndim,
 *          volume_dims, scale_slope, scale_inter (appended).
 *   1.2.0  hz_data_kind gains HZ_DATA_IMAGE (2D images: environment maps,
 *          textures, rendered frames); hz_shader snippets may define
 *          hz_ambient() and use the host's hz_env_* functions and
 *          HZ_ZERO_<param> specialisation macros (see hz_shader.h).
 *   1.3.0  hz_write_request gains final_path and add_companion (appended):
 *          writers of multi-file formats (NIfTI .hdr/.img pairs).
 *   1.4.0  hz_loader gains locate_positions and hz_positions_extent
 *          (appended); hz_streamlines_dst.reserved0 becomes flags
 *          (HZ_STREAMLINES_OFFSETS_ONLY): zero-copy reading of positions
 *          the host maps from the file (TRX stored zips and directories).
 *   1.5.0  hz_positions_extent.reserved0 becomes `accepts`, and
 *          HZ_EXTENT_DELIMITED: positions mapped with one delimiter vertex
 *          after each streamline (MRtrix TCK Float32LE), offered by a loader
 *          only to a host that accepts it.
 *   1.6.0  hz_positions_extent gains bounds_min/bounds_max (appended), and
 *          HZ_EXTENT_CHECKED: a loader that has read every coordinate while
 *          opening the file vouches for their finiteness and bounds, so the
 *          host need not read the mapped extent again.
 *   1.7.0  hz_streamlines_dst gains `check` (appended) and
 *          hz_positions_check: a loader that looks at every coordinate it
 *          decodes into the host's buffer vouches for their finiteness and
 *          bounds, so the host need not read the copy again.
 *   1.8.0  hz_loader_caps gains HZ_LOADER_WRITES_GAP: a writer that takes
 *          streamlines with gap 1, so the host writes a mapped TCK without
 *          first copying it without its delimiters.
 *   1.9.0  hz_extent_flags gains HZ_EXTENT_UNALIGNED: positions located at
 *          an offset that is not a multiple of 4 (a TCK written by nibabel),
 *          offered by a loader only to a host that accepts it; the host
 *          copies them to aligned memory when they are first used.
 *   1.10.0 The redesign before the freeze. The core tables mean again what
 *          they meant in 1.0: what 1.4-1.9 added to them for reading files
 *          in place becomes optional extensions (hz_extensions.h),
 *          offered through hz_plugin_descriptor.interfaces and
 *          get_interface(), in the manner of CLAP's extension ids:
 *          "hz.ext.mapped-positions/1" (locate_positions, with read_offsets
 *          instead of the HZ_STREAMLINES_OFFSETS_ONLY flag),
 *          "hz.ext.checked-read/1" (hz_positions_check, an argument instead
 *          of hz_streamlines_dst.check) and
 *          "hz.ext.delimited-streamlines/1" (gap 1 for writers and
 *          clustering plugins, instead of HZ_LOADER_WRITES_GAP and the
 *          descriptor's ABI version); and a fourth, "hz.ext.open-task/1"
 *          (open() with a task: progress and cancel while a loader scans
 *          the file). hz_loader ends at write() again,
 *          hz_streamlines_dst at offsets_capacity (flags is reserved0).
 *          A host reads no core table past what 1.3 defined, so a plugin
 *          built against 1.4-1.9 still loads and works, only without
 *          reading in place. (Hosts of 1.4-1.9 were never released: they
 *          are not served.)
 *   1.11.0 A fifth extension, "hz.ext.write-selection/1": a writer writes
 *          chosen streamlines of a view (the streamlines kept, a filter's
 *          selection) without the host copying them first.
 *   1.12.0 hz_shader.display (appended): a model may ask to be shown as it
 *          is, without the scene's exposure and tone curve (non-PBR models).
 */
#ifndef HZ_VERSION_H
#define HZ_VERSION_H

#include <stdint.h>

#ifndef HZ_ABI_VERSION_MAJOR
/* The major this SDK describes. Only the test fixtures override it. */
#  define HZ_ABI_VERSION_MAJOR 1
#endif
#define HZ_ABI_VERSION_MINOR 12
#define HZ_ABI_VERSION_PATCH 0

/* A semantic version triple, passed by value inside boundary structs. */
typedef struct hz_abi_version {
    uint32_t major; /* incompatible changes; part of the entry symbol name */
    uint32_t minor; /* appended fields and new interface ids              */
    uint32_t patch; /* documentation and bug fixes only                   */
} hz_abi_version;

/* Initialiser for the version this SDK was compiled as. */
#define HZ_ABI_VERSION_INIT { HZ_ABI_VERSION_MAJOR, HZ_ABI_VERSION_MINOR, HZ_ABI_VERSION_PATCH }

#define HZ_STRINGIFY_(x) #x
#define HZ_STRINGIFY(x) HZ_STRINGIFY_(x)
#define HZ_CONCAT_(a, b) a##b
#define HZ_CONCAT(a, b) HZ_CONCAT_(a, b)

/*
 * The one exported symbol, as an identifier and as a string for dlsym().
 * For major 1 these are hz_plugin_entry_v1 and "hz_plugin_entry_v1".
 */
#define HZ_PLUGIN_ENTRY HZ_CONCAT(hz_plugin_entry_v, HZ_ABI_VERSION_MAJOR)
#define HZ_PLUGIN_ENTRY_SYMBOL "hz_plugin_entry_v" HZ_STRINGIFY(HZ_ABI_VERSION_MAJOR)

#endif /* HZ_VERSION_H */
