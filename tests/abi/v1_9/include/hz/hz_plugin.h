/*
 * Horizon plugin SDK: the entry point and the plugin descriptor.
 *
 * A plugin library is a shared object that exports exactly one data symbol,
 * `hz_plugin_entry_v1` (HZ_PLUGIN_ENTRY), of type `const hz_plugin_entry`.
 * The host reads struct_size and abi from it before calling any plugin code,
 * so a library built for another ABI major is rejected without running it.
 * One library may hold several plugins (e.g. a loader for two formats).
 *
 * Lifecycle, as the host drives it:
 *   dlopen(RTLD_NOW|RTLD_LOCAL) -> read entry -> init(host) ->
 *   get_plugin_count/get_plugin_descriptor/get_interface ... -> deinit()
 * The library then stays loaded until the process exits.
 */
#ifndef HZ_PLUGIN_H
#define HZ_PLUGIN_H

#include "hz_host.h"

HZ_EXTERN_C_BEGIN

/* Plugin kind: which core interface id the plugin implements. */
typedef uint32_t hz_plugin_kind;
enum {
    HZ_KIND_LOADER = 1,     /* implements HZ_INTERFACE_LOADER     */
    HZ_KIND_SHADER = 2,     /* implements HZ_INTERFACE_SHADER     */
    HZ_KIND_CLUSTERING = 3  /* implements HZ_INTERFACE_CLUSTERING */
};

/*
 * Identity and metadata of one plugin. PLUGIN-owned, static, valid until
 * deinit() returns. [thread-safe] to read.
 */
typedef struct hz_plugin_descriptor {
    uint32_t struct_size;
    hz_abi_version abi;       /* HZ_ABI_VERSION_INIT as compiled by the plugin */
    hz_plugin_kind kind;
    const char *id;           /* mandatory: reverse-DNS, [a-z0-9._-]+, unique, e.g. "org.horizon.loader.tck" */
    const char *name;         /* mandatory: display name                       */
    const char *version;      /* mandatory: plugin's own semver, "1.0.0"       */
    const char *vendor;       /* may be ""                                     */
    const char *description;  /* one sentence, may be ""                       */
    const char *license;      /* SPDX identifier, e.g. "MIT"                   */
    /* NULL-terminated list of interface ids this plugin serves; the first is
       its core interface (e.g. "hz.loader/1"). Never NULL. */
    const char *const *interfaces;
} hz_plugin_descriptor;

/* Minimum struct_size of an hz_plugin_entry the host accepts. */
#define HZ_PLUGIN_ENTRY_MIN_SIZE 56u /* the 1.0 layout on LP64 */

/*
 * The exported entry table. PLUGIN-owned, a const object with static storage:
 * it must not depend on dynamic initialisation (the host reads it before
 * calling init()).
 */
typedef struct hz_plugin_entry {
    uint32_t struct_size;     /* sizeof(hz_plugin_entry) as compiled by the plugin */
    hz_abi_version abi;       /* HZ_ABI_VERSION_INIT                                 */

    /*
     * Called once after loading, before anything else. `host` is HOST-owned
     * and valid until deinit() returns; `library_path` is the absolute path
     * of this library, valid only during the call. Must be fast (< 100 ms):
     * no GL, no UI, no heavy I/O. Returns false to refuse loading (say why
     * through host->log first). Must tolerate init/deinit/init cycles.
     * [main-thread, never concurrent with any other call into this library]
     */
    bool(HZ_ABI *init)(const hz_host *host, const char *library_path);

    /*
     * Releases everything init() acquired. After it returns the host calls
     * nothing in this library but init(). [main-thread]
     */
    void(HZ_ABI *deinit)(void);

    /* Number of plugins in this library (>= 1). [thread-safe] */
    uint32_t(HZ_ABI *get_plugin_count)(void);

    /*
     * Descriptor of plugin `index` (< get_plugin_count()), or NULL when out of
     * range. PLUGIN-owned, valid until deinit(). [thread-safe]
     */
    const hz_plugin_descriptor *(HZ_ABI *get_plugin_descriptor)(uint32_t index);

    /*
     * The interface table `interface_id` (e.g. "hz.loader/1") of plugin
     * `plugin_id`, or NULL when either id is unknown. The table type is the
     * one documented for that id; it starts with uint32_t struct_size.
     * PLUGIN-owned, valid until deinit(). [thread-safe]
     */
    const void *(HZ_ABI *get_interface)(const char *plugin_id, const char *interface_id);
} hz_plugin_entry;

/* Core interface ids (string ids with a revision). */
#define HZ_INTERFACE_LOADER "hz.loader/1"
#define HZ_INTERFACE_SHADER "hz.shader/1"
#define HZ_INTERFACE_CLUSTERING "hz.clustering/1"

/*
 * Declares the exported entry symbol in a plugin's source file:
 *     HZ_DECLARE_PLUGIN_ENTRY = { sizeof(hz_plugin_entry), HZ_ABI_VERSION_INIT, ... };
 * (C++ sources get extern "C" from the header guard.)
 */
#ifdef __cplusplus
#  define HZ_DECLARE_PLUGIN_ENTRY extern "C" HZ_EXPORT const hz_plugin_entry HZ_PLUGIN_ENTRY
#else
#  define HZ_DECLARE_PLUGIN_ENTRY HZ_EXPORT const hz_plugin_entry HZ_PLUGIN_ENTRY
#endif

HZ_EXTERN_C_END

#endif /* HZ_PLUGIN_H */
