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
 *          host services (log, mem, extensions), tasks (progress, cancel).
 */
#ifndef HZ_VERSION_H
#define HZ_VERSION_H

#include <stdint.h>

#ifndef HZ_ABI_VERSION_MAJOR
/* The major this SDK describes. Only the test fixtures override it. */
#  define HZ_ABI_VERSION_MAJOR 1
#endif
#define HZ_ABI_VERSION_MINOR 0
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
