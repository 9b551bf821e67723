/*
 * Horizon plugin SDK: compiler and platform macros.
 *
 * This header is part of the plugin C ABI. It is plain C11 and C++ safe.
 * Nothing here allocates or has state.
 */
#ifndef HZ_MACROS_H
#define HZ_MACROS_H

/*
 * HZ_EXPORT marks the one symbol a plugin exports (hz_plugin_entry_v1).
 * Plugins are built with -fvisibility=hidden, so nothing else leaves the
 * shared object unless it is marked with this macro.
 */
#if defined(_WIN32)
#  define HZ_EXPORT __declspec(dllexport)
#else
#  define HZ_EXPORT __attribute__((visibility("default")))
#endif

/*
 * HZ_ABI is the calling convention of every function pointer in the ABI.
 * It is empty on the System V platforms Horizon supports and __cdecl on
 * Windows, so that plugins built by another compiler agree with the host.
 */
#if defined(_WIN32)
#  define HZ_ABI __cdecl
#else
#  define HZ_ABI
#endif

/*
 * C linkage guards for C++ translation units.
 */
#ifdef __cplusplus
#  define HZ_EXTERN_C_BEGIN extern "C" {
#  define HZ_EXTERN_C_END }
#else
#  define HZ_EXTERN_C_BEGIN
#  define HZ_EXTERN_C_END
#endif

/*
 * HZ_HAS_FIELD(ptr, type, field): true when the struct that `ptr` points to,
 * whose first member is `uint32_t struct_size`, is large enough to contain
 * `field`. Every reader of a field that was added after x.0 of the ABI major
 * MUST test it first (growth rule, see sdk/docs/ABI.md section "Growth").
 * A function-pointer field must also be tested for NULL.
 */
/*
 * HZ_DEPRECATED("what replaced it"): on a name kept within the major for
 * source compatibility only (ABI.md, "Migration"): code that uses it still
 * compiles and works, with a compiler warning that names the replacement.
 */
#if defined(__GNUC__) || defined(__clang__)
#  define HZ_DEPRECATED(msg) __attribute__((deprecated(msg)))
#elif defined(_MSC_VER)
#  define HZ_DEPRECATED(msg) __declspec(deprecated(msg))
#else
#  define HZ_DEPRECATED(msg)
#endif

#define HZ_HAS_FIELD(ptr, type, field) \
    (offsetof(type, field) + sizeof(((type *)0)->field) <= (ptr)->struct_size)

#endif /* HZ_MACROS_H */
