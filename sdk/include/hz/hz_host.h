/*
 * Horizon plugin SDK: services the host offers to plugins, and tasks.
 *
 * Thread tags used throughout the SDK (CLAP style):
 *   [main-thread]    the host's main thread only (init, deinit).
 *   [thread-safe]    any thread, concurrently.
 *   [worker]         any one host thread; the host never calls the same
 *                    reader/clusterer from two threads at once, but different
 *                    objects may run concurrently (no unsynchronised globals).
 *   [calling-thread] only from inside the call that received the object.
 */
#ifndef HZ_HOST_H
#define HZ_HOST_H

#include "hz_types.h"
#include "hz_version.h"

HZ_EXTERN_C_BEGIN

/* Log severity. Routed into the host's spdlog logger "plugin:<id>". */
typedef int32_t hz_log_level;
enum {
    HZ_LOG_TRACE = 0,
    HZ_LOG_DEBUG = 1,
    HZ_LOG_INFO = 2,
    HZ_LOG_WARN = 3,
    HZ_LOG_ERROR = 4,
    HZ_LOG_CRITICAL = 5
};

/*
 * Services of the host. HOST-owned; the pointer given to init() stays valid
 * until deinit() returns. Plugins never write to it.
 */
typedef struct hz_host {
    uint32_t struct_size;
    hz_abi_version abi;     /* ABI version the host was built with          */
    void *host_data;        /* reserved for the host; plugins ignore it     */
    const char *name;       /* "horizon"                                    */
    const char *version;    /* host version, semver                         */

    /*
     * Logs one message. `plugin_id` names the emitting plugin (may be NULL);
     * `msg` is UTF-8, copied before return, no trailing newline needed.
     * [thread-safe]
     */
    void(HZ_ABI *log)(const struct hz_host *host, const char *plugin_id, hz_log_level level,
                      const char *msg);

    /*
     * Optional host services by id ("hz.host.<name>/<rev>"); NULL when the
     * host does not offer `extension_id`. The returned table is host-owned
     * and valid until deinit() returns. None are defined in 1.0.
     * [thread-safe]
     */
    const void *(HZ_ABI *get_extension)(const struct hz_host *host, const char *extension_id);
} hz_host;

/*
 * A long-running call's link back to the host: progress and cancellation.
 * HOST-owned; valid only for the duration of the call it was passed to.
 * May be NULL: a plugin then neither reports nor polls.
 */
typedef struct hz_task {
    uint32_t struct_size;
    void *task_data; /* reserved for the host */

    /*
     * True when the host wants the call to stop. Poll at least every ~50 ms of
     * work; on true, clean up and return HZ_E_CANCELLED. A call handed a task
     * that is already cancelled may return HZ_E_CANCELLED at once; one that
     * does less than ~50 ms of work need not poll at all and may finish as if
     * not cancelled. Either way the reader (or other object) stays usable:
     * close() or destroy() works after it. [calling-thread]
     */
    bool(HZ_ABI *is_cancelled)(const struct hz_task *task);

    /*
     * Progress `fraction` in [0,1], non-decreasing; `msg` may be NULL, is
     * copied before return. [calling-thread]
     */
    void(HZ_ABI *report)(const struct hz_task *task, double fraction, const char *msg);
} hz_task;

HZ_EXTERN_C_END

#endif /* HZ_HOST_H */
