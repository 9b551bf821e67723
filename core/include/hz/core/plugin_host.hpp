// Plugin discovery, isolation, loading and the registry.
//
// Every candidate file in a plugin directory goes through three gates:
//   1. a static ELF check (empty, text, wrong class or CPU architecture),
//   2. a trial load in a forked child (dlopen RTLD_NOW|RTLD_LOCAL, entry
//      symbol, ABI major, init(), descriptors) so that a plugin that crashes,
//      throws or hangs while loading cannot take the host down,
//   3. the real load in this process.
// A file failing any gate is recorded as rejected with a one-line reason.
#pragma once

#include <hz/hz.h>
#include <hz/core/data.hpp>
#include <hz/core/plugin_guard.hpp>

#include <nlohmann/json_fwd.hpp>

#include <atomic>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hz::core {

namespace fs = std::filesystem;

// The hz_host every plugin receives: logs into spdlog ("plugin:<id>").
const hz_host *host_services();

// A task with a cancel flag and an optional progress callback.
class Task {
public:
    Task();
    const hz_task *get() const { return &task_; }
    void cancel() { cancelled_.store(true, std::memory_order_relaxed); }  // (from any thread)
    std::function<void(double, const char *)> on_progress;

private:
    static bool HZ_ABI is_cancelled(const hz_task *t);
    static void HZ_ABI report(const hz_task *t, double f, const char *msg);
    hz_task task_{};
    std::atomic<bool> cancelled_{false};
};

// Static checks on a file before dlopen; returns the reason it cannot be a
// plugin for this host, or nullopt.
std::optional<std::string> elf_precheck(const fs::path &file);

// Result of running a function in a forked child.
struct ChildResult {
    bool exited = false;  // exited normally
    int exit_code = -1;
    int signal = 0;  // terminating signal, 0 if none
    bool timed_out = false;
    std::string output;            // what the child function returned
    std::string describe() const;  // "crashed (SIGSEGV)", "hung (> 10 s)", "exited with 3"
};

// Runs `fn` in a forked child (its stdout is redirected to stderr), returns
// what it returned. Kills it after `timeout_s`.
ChildResult run_in_child(const std::function<std::string()> &fn, double timeout_s);

// Descriptor data copied out of a plugin.
struct PluginInfo {
    std::string id, name, version, vendor, description, license;
    hz_abi_version abi{};  // the ABI its descriptor declares
    hz_plugin_kind kind = 0;
    std::vector<std::string> interfaces;
    std::string file;
};
const char *plugin_kind_name(hz_plugin_kind k);

// Which file (device, inode) a path or a mapping is.
struct FileId {
    std::uint64_t dev = 0, ino = 0;
    bool operator==(const FileId &) const = default;
};

// A plugin that crashed, or did not return within the plugin timeout, in a
// call the host survived (plugin_guard.hpp): it is not called again.
struct PluginFault : Error {
    using Error::Error;
};

// One loaded library (kept resident until exit). Its calls after dlopen
// (init, the descriptors, get_interface, deinit) are guarded: a crash or a
// call past the plugin timeout throws PluginFault (deinit: a warning), and
// marks the module faulted: no call of it is made again.
class Module {
public:
    // Loads `file`, checks the entry and calls init(). Throws Error with a
    // one-line reason (not naming the file; the caller does). With `expect`,
    // the file must be that inode (the one its trial load saw), checked on
    // the path before dlopen and on the mapped object after, before init():
    // a file replaced in between is refused, never run. A process that
    // init() forks ends (_exit(0)) the moment init() returns to the host,
    // so only the host goes on.
    explicit Module(const fs::path &file, std::optional<FileId> expect = std::nullopt);
    ~Module();
    Module(const Module &) = delete;
    Module &operator=(const Module &) = delete;
    const hz_plugin_entry &entry() const { return *entry_; }
    // Descriptors, checked for mandatory fields and a resolvable core interface.
    std::vector<PluginInfo> plugins() const;
    const void *interface(const std::string &plugin_id, const char *iface) const;
    void deinit();
    const fs::path &file() const { return file_; }
    // Whether a call of it crashed or timed out (then it is not called again).
    bool faulted() const { return faulted_.load(); }
    void mark_faulted() const { faulted_.store(true); }
    // The loaded file's shared-library dependencies, resolved as the dynamic
    // linker found them: the DT_NEEDED closure, as absolute paths.
    std::vector<std::string> dependencies() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    const hz_plugin_entry *entry_ = nullptr;
    fs::path file_;
    bool initialised_ = false;
    mutable std::atomic<bool> faulted_{false};
    // Runs f (a call of this plugin named `call`) guarded; throws
    // PluginFault (`what`: the text before the fault's) on a crash or timeout.
    template <class F>
    void guarded(const char *call, const std::string &what, F &&f) const;
};

// The table of extension `id` (hz_extensions.h) that plugin `info` of
// `module` offers: listed in its descriptor's interfaces after the core
// interface, served by get_interface(), and at least `min_size` bytes (its
// struct_size); else NULL. The host asks for no other.
const void *offered_extension(const Module &module, const PluginInfo &info, const char *id, std::size_t min_size);

struct LoadedPlugin {
    PluginInfo info;
    const void *iface = nullptr;  // the core interface table (hz_loader*, ...)
    std::shared_ptr<Module> module;
    const hz_loader *loader() const { return info.kind == HZ_KIND_LOADER ? static_cast<const hz_loader *>(iface) : nullptr; }
    const hz_shader *shader() const { return info.kind == HZ_KIND_SHADER ? static_cast<const hz_shader *>(iface) : nullptr; }
    const hz_clustering *clustering() const {
        return info.kind == HZ_KIND_CLUSTERING ? static_cast<const hz_clustering *>(iface) : nullptr;
    }
    // The table of extension `id` (hz_extensions.h) when the plugin offers
    // it: lists it in its descriptor's interfaces and serves a table of at
    // least `min_size` bytes (its struct_size); else NULL.
    const void *extension(const char *id, std::size_t min_size) const;
    template <class Table>
    const Table *extension(const char *id) const {
        return static_cast<const Table *>(extension(id, sizeof(Table)));
    }
    // Whether hz_streamlines_view.gap may be 1 for it (HZ_EXT_DELIMITED_STREAMLINES).
    bool takes_gap() const {
        const auto *e = extension<hz_ext_delimited_streamlines>(HZ_EXT_DELIMITED_STREAMLINES);
        return e != nullptr && e->max_gap >= 1;
    }
    // `t` as this plugin takes it through hz_streamlines_view: the same
    // buffers, or a copy without delimiters for a plugin that does not take them.
    Tractogram streamlines_for(const Tractogram &t) const { return takes_gap() ? t.shared() : t.compacted(); }
    // Calls `f`, a call into this plugin's C functions named `call`
    // ("open", "run", ...), and turns a C++ exception that escapes it (a
    // C++ plugin that lets one cross the ABI) into one Error naming the
    // plugin, its file and the call, where it used to surface as its bare
    // message ("stof"). `what` (a file, or empty) is named first.
    // A crash in it names the plugin and the call (PluginCallMark).
    template <class F>
    decltype(auto) call(const char *call, const std::string &what, F &&f) const {
        const PluginCallMark mark(info.file.c_str(), call);
        try {
            return f();
        } catch (const Error &) {
            throw;  // (the host's own, from a callback)
        } catch (const std::exception &e) {
            throw Error(escaped(call, what, e.what()));
        } catch (...) {
            throw Error(escaped(call, what, "not a std::exception"));
        }
    }

    // Whether a guarded call of it crashed or timed out (Module::faulted).
    bool faulted() const { return module && module->faulted(); }
    // The error for a C++ exception that escaped `call`.
    std::string escaped(const char *call, const std::string &what, const char *message) const;
};

struct Rejection {
    std::string file;
    std::string reason;
};

// The search path, in priority order: --plugin-dir options, then
// HORIZON_PLUGIN_PATH (':'-separated), then the per-user dir
// ($XDG_DATA_HOME or ~/.local/share)/horizon/plugins, then the bundled dir
// <exe>/../lib/horizon/plugins. Missing directories are kept (reported).
std::vector<fs::path> plugin_search_path(const std::vector<fs::path> &cli_dirs);
fs::path executable_path();

// Where the host keeps the trial loads that passed (Registry::Options::
// trial_cache): $HORIZON_PLUGIN_CACHE when set ("off": none), else
// ($XDG_CACHE_HOME or ~/.cache)/horizon/plugin-trials.json; empty when there
// is no such place.
fs::path default_trial_cache();

class Registry {
public:
    struct Options {
        bool isolate = true;      // trial-load every file in a child first
        double timeout_s = 10.0;  // per trial load
        // A JSON file of the plugin files whose trial load passed, each with
        // what identified it then (device, inode, size, modification and
        // change times), the same stamp of every shared library it needs
        // (the DT_NEEDED closure the trial loaded: a system upgrade that
        // changes one is a new trial), and the host that tried it (the
        // executable's stamp). A file listed unchanged, for this host, is loaded without
        // a new trial: the child's fork and its loading of every plugin
        // cost `horizon info` on a small file 4-5 ms of its 15 ms. Any
        // change to the file or the host, or a file missing from the list,
        // means a trial as before; failed trials are never listed (a plugin
        // that crashed is tried again next time). Empty: no list, a trial
        // for every file. A list that cannot be read is ignored, one that
        // cannot be written is not written (logged at debug level).
        fs::path trial_cache;
    };
    Registry() = default;
    // (sets the guarded calls' timeout: set_plugin_call_timeout)
    explicit Registry(Options o) : options_(o) { set_plugin_call_timeout(o.timeout_s); }

    // Scans `dirs` in order; the first plugin with a given id wins.
    void scan(const std::vector<fs::path> &dirs);
    // Loads one file (used by scan and by tests).
    void add_file(const fs::path &file);
    // Registers the plugins of a module the caller already loaded and keeps
    // alive for the registry's lifetime (`horizon validate`).
    void add_module(const Module &m);

    const std::vector<LoadedPlugin> &plugins() const { return plugins_; }
    const std::vector<Rejection> &rejected() const { return rejected_; }
    const std::vector<fs::path> &searched() const { return searched_; }
    // How many files scan() and add_file() trial-loaded in a child (those
    // taken on the trial list's word are not counted).
    std::size_t trial_loads() const { return trial_loads_; }
    const LoadedPlugin *find(const std::string &id) const;
    std::vector<const LoadedPlugin *> of_kind(hz_plugin_kind k) const;

private:
    void reject(const fs::path &file, const std::string &why);
    // In this process, after its trial; `expect`: the inode the trial saw.
    // False when a call of it crashed or hung here (PluginFault): rejected,
    // and not to be vouched for again.
    bool load(const fs::path &file, std::optional<FileId> expect = std::nullopt);
    // Acts on a trial load's JSON report: loads the file (returns true: the
    // trial passed, and its load here did not crash or hang), or rejects it
    // with the plugin's reason, or with `if_malformed` when the report is not one.
    bool take_report(const fs::path &file, const nlohmann::json &report, const std::string &if_malformed,
                     std::optional<FileId> expect = std::nullopt);
    std::string trial_failure(const ChildResult &r) const;  // why a trial load gave no report

    Options options_;
    std::vector<LoadedPlugin> plugins_;
    std::vector<Rejection> rejected_;
    std::vector<fs::path> searched_;
    std::size_t trial_loads_ = 0;
};

}  // namespace hz::core
