#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
#include <hz/core/params.hpp>
#include <hz/core/plugin_host.hpp>

#include "plugin_internal.hpp"

#include <boost/dll/shared_library.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <array>
#include <dlfcn.h>
#include <elf.h>
#include <link.h>
#include <set>
#include <optional>
#include <string_view>
#include <sys/stat.h>
#include <tuple>
#include <fcntl.h>
#include <fstream>
#include <map>
#include <mutex>
#include <poll.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstddef>
#include <cstdio>

namespace hz::core {

// ------------------------------------------------------------ host services

namespace {

void HZ_ABI host_log(const hz_host *, const char *plugin_id, hz_log_level lvl, const char *msg) {
    static std::mutex m;
    static std::map<std::string, std::shared_ptr<spdlog::logger>> loggers;
    std::shared_ptr<spdlog::logger> logger;
    {
        std::lock_guard lock(m);
        const std::string name = std::string("plugin:") + (plugin_id ? plugin_id : "?");
        auto &slot = loggers[name];
        if (!slot) slot = spdlog::default_logger()->clone(name);
        logger = slot;
    }
    const spdlog::level::level_enum levels[] = {spdlog::level::trace, spdlog::level::debug, spdlog::level::info,
                                                spdlog::level::warn,  spdlog::level::err,   spdlog::level::critical};
    logger->log(levels[std::clamp(lvl, 0, 5)], "{}", msg ? msg : "");
}

const void *HZ_ABI host_get_extension(const hz_host *, const char *) { return nullptr; }

const hz_host kHost = {
    sizeof(hz_host), HZ_ABI_VERSION_INIT, nullptr, "horizon", "0.1.0", host_log, host_get_extension,
};

}  // namespace

const hz_host *host_services() { return &kHost; }

Task::Task() {
    task_.struct_size = sizeof task_;
    task_.task_data = this;
    task_.is_cancelled = &Task::is_cancelled;
    task_.report = &Task::report;
}
bool HZ_ABI Task::is_cancelled(const hz_task *t) { return static_cast<Task *>(t->task_data)->cancelled_.load(std::memory_order_relaxed); }
void HZ_ABI Task::report(const hz_task *t, double f, const char *msg) {
    auto *self = static_cast<Task *>(t->task_data);
    if (self->on_progress) self->on_progress(f, msg);
}

using namespace detail;

// ---------------------------------------------------------------- registry

fs::path executable_path() {
    std::error_code ec;
    auto p = fs::read_symlink("/proc/self/exe", ec);
    return ec ? fs::path() : p;
}

std::vector<fs::path> plugin_search_path(const std::vector<fs::path> &cli_dirs) {
    std::vector<fs::path> dirs(cli_dirs.begin(), cli_dirs.end());
    if (const char *env = std::getenv("HORIZON_PLUGIN_PATH"); env && *env) {
        std::string s(env);
        std::size_t start = 0;
        while (start <= s.size()) {
            const auto colon = s.find(':', start);
            const std::string part = s.substr(start, colon == std::string::npos ? std::string::npos : colon - start);
            if (!part.empty()) dirs.emplace_back(part);
            if (colon == std::string::npos) break;
            start = colon + 1;
        }
    }
    if (const char *xdg = std::getenv("XDG_DATA_HOME"); xdg && *xdg)
        dirs.push_back(fs::path(xdg) / "horizon" / "plugins");
    else if (const char *home = std::getenv("HOME"); home && *home)
        dirs.push_back(fs::path(home) / ".local" / "share" / "horizon" / "plugins");
    const auto exe = executable_path();
    if (!exe.empty()) dirs.push_back(exe.parent_path().parent_path() / "lib" / "horizon" / "plugins");
    return dirs;
}

fs::path default_trial_cache() {
    if (const char *env = std::getenv("HORIZON_PLUGIN_CACHE"); env != nullptr && *env != '\0')
        return std::string_view(env) == "off" ? fs::path() : fs::path(env);
    if (const char *xdg = std::getenv("XDG_CACHE_HOME"); xdg != nullptr && *xdg != '\0')
        return fs::path(xdg) / "horizon" / "plugin-trials.json";
    if (const char *home = std::getenv("HOME"); home != nullptr && *home != '\0')
        return fs::path(home) / ".cache" / "horizon" / "plugin-trials.json";
    return {};
}

namespace {

// What identifies one version of a file (stat, following links): device,
// inode, size, modification and change times in ns.
using Stamp = std::array<std::int64_t, 5>;

Stamp stamp_from(const struct stat &st) {
    auto ns = [](const timespec &t) { return std::int64_t(t.tv_sec) * 1000000000 + t.tv_nsec; };
    return Stamp{static_cast<std::int64_t>(st.st_dev), static_cast<std::int64_t>(st.st_ino), static_cast<std::int64_t>(st.st_size),
                 ns(st.st_mtim), ns(st.st_ctim)};
}

std::optional<Stamp> stamp_of(const fs::path &f) {
    struct stat st {};
    if (::stat(f.c_str(), &st) != 0) return std::nullopt;
    return stamp_from(st);
}

FileId id_of(const Stamp &s) { return {static_cast<std::uint64_t>(s[0]), static_cast<std::uint64_t>(s[1])}; }

std::string key_of(const fs::path &f) {
    std::error_code ec;
    const fs::path a = fs::absolute(f, ec);
    return (ec ? f : a).lexically_normal().string();
}

// The list of trial loads that passed (Registry::Options::trial_cache):
// {"format": "horizon-plugin-trials", "version": 2, "passed": [{"file": F,
// "stamp": [5 integers], "deps": [[PATH, [5 integers]], ...], "host": EXE,
// "host_stamp": [5 integers]}, ...]}. Version 1 lists (no deps) are ignored.
class TrialList {
public:
    explicit TrialList(fs::path file) : file_(std::move(file)) {
        if (file_.empty()) return;
        host_ = key_of(executable_path());
        const auto hs = stamp_of(host_);
        if (!hs) {  // (no way to tell this host from another)
            file_.clear();
            return;
        }
        host_stamp_ = *hs;
        // Only a regular file (or none yet): a FIFO would block every
        // command, a folder or device is not a list. Anything else disables
        // the list for this run (trial loads as without one).
        struct stat st {};
        if (::lstat(file_.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
            spdlog::warn("plugin trial list {} is not a regular file: not used", file_.string());
            file_.clear();
            return;
        }
        std::ifstream in(file_, std::ios::binary);
        if (!in) return;
        const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
        if (j.is_discarded() || !j.is_object() || j.value("format", "") != kFormat || j.value("version", 0) != kVersion ||
            !j.contains("passed") || !j["passed"].is_array()) {
            spdlog::debug("plugin trial list {} ignored: not a version {} list", file_.string(), kVersion);
            return;
        }
        for (const auto &e : j["passed"]) {
            Entry x;
            if (!e.is_object() || !read(e, "file", x.file) || !read(e, "host", x.host) || !read(e, "stamp", x.stamp) ||
                !read(e, "host_stamp", x.host_stamp) || !read_deps(e, x.deps))
                continue;
            entries_.push_back(std::move(x));
        }
    }
    bool enabled() const { return !file_.empty(); }
    // Whether `file`, as it is now, passed a trial load by this host, with
    // the libraries it needs as they are now.
    bool vouches(const std::string &file, const Stamp &now) {
        return enabled() && std::any_of(entries_.begin(), entries_.end(), [&](const Entry &e) {
                   return e.file == file && e.stamp == now && e.host == host_ && e.host_stamp == host_stamp_ &&
                          std::all_of(e.deps.begin(), e.deps.end(), [&](const auto &d) { return current(d.first) == d.second; });
               });
    }
    // Records a trial that passed, with the libraries it loaded (not
    // recorded when one of them cannot be stamped).
    void passed(const std::string &file, const Stamp &now, const std::vector<std::string> &deps) {
        if (!enabled()) return;
        std::erase_if(entries_, [&](const Entry &e) { return e.file == file && e.host == host_; });
        Entry x{file, now, {}, host_, host_stamp_};
        for (const auto &d : deps) {
            const std::string k = key_of(d);
            const auto st = current(k);
            if (!st) return;
            x.deps.emplace_back(k, *st);
        }
        entries_.push_back(std::move(x));
        changed_ = true;
    }
    // A file it vouched for crashed or hung in this process: tried again
    // (in a child) next time.
    void forget(const std::string &file) {
        if (std::erase_if(entries_, [&](const Entry &e) { return e.file == file && e.host == host_; }) > 0) changed_ = true;
    }
    // Writes the list if it changed (to a temporary file, then renamed over
    // it), without the entries whose file, libraries or host are gone or
    // changed, and without the oldest beyond kMax.
    void save() {
        if (!changed_ || !enabled()) return;
        std::erase_if(entries_, [&](const Entry &e) {
            return current(e.file) != e.stamp || current(e.host) != e.host_stamp ||
                   std::any_of(e.deps.begin(), e.deps.end(), [&](const auto &d) { return current(d.first) != d.second; });
        });
        if (entries_.size() > kMax) entries_.erase(entries_.begin(), entries_.end() - kMax);
        nlohmann::json list = nlohmann::json::array();
        for (const auto &e : entries_) {
            nlohmann::json deps = nlohmann::json::array();
            for (const auto &d : e.deps) deps.push_back({d.first, d.second});
            list.push_back({{"file", e.file}, {"stamp", e.stamp}, {"deps", deps}, {"host", e.host}, {"host_stamp", e.host_stamp}});
        }
        const std::string text = nlohmann::json{{"format", kFormat}, {"version", kVersion}, {"passed", list}}.dump(1) + "\n";
        std::error_code ec;
        fs::create_directories(file_.parent_path(), ec);
        try {
            write_text_atomic(file_, text, true);
        } catch (const std::exception &e) {
            spdlog::debug("plugin trial list not written: {}", e.what());
        }
    }

private:
    static constexpr const char *kFormat = "horizon-plugin-trials";
    static constexpr int kVersion = 2;
    static constexpr std::size_t kMax = 256;
    struct Entry {
        std::string file;
        Stamp stamp{};
        std::vector<std::pair<std::string, Stamp>> deps;
        std::string host;
        Stamp host_stamp{};
    };
    // A file's stamp now, each file stat()ed once per list (most plugins
    // share the C and C++ runtimes).
    std::optional<Stamp> current(const std::string &f) {
        const auto it = stamps_.find(f);
        if (it != stamps_.end()) return it->second;
        return stamps_[f] = stamp_of(f);
    }
    static bool read(const nlohmann::json &e, const char *key, std::string &out) {
        if (!e.contains(key) || !e[key].is_string()) return false;
        out = e[key].get<std::string>();
        return true;
    }
    static bool read(const nlohmann::json &e, const char *key, Stamp &out) {
        if (!e.contains(key)) return false;
        return read_stamp(e[key], out);
    }
    static bool read_stamp(const nlohmann::json &v, Stamp &out) {
        if (!v.is_array() || v.size() != out.size()) return false;
        for (std::size_t i = 0; i < out.size(); ++i) {
            if (!v[i].is_number_integer()) return false;
            out[i] = v[i].get<std::int64_t>();
        }
        return true;
    }
    static bool read_deps(const nlohmann::json &e, std::vector<std::pair<std::string, Stamp>> &out) {
        if (!e.contains("deps") || !e["deps"].is_array()) return false;
        for (const auto &d : e["deps"]) {
            Stamp st{};
            if (!d.is_array() || d.size() != 2 || !d[0].is_string() || !read_stamp(d[1], st)) return false;
            out.emplace_back(d[0].get<std::string>(), st);
        }
        return true;
    }
    fs::path file_;
    std::string host_;
    Stamp host_stamp_{};
    std::vector<Entry> entries_;
    std::map<std::string, std::optional<Stamp>> stamps_;
    bool changed_ = false;
};

// A trial load of `file`, as a one-line JSON report: {"ok": true, "count":
// N, "deps": [PATH, ...], "index": I} or {"ok": false, "reason": "...",
// "index": I}; `index` tells the reports of one child apart.
std::string trial_report(const fs::path &file, std::optional<FileId> expect, std::size_t index) {
    try {
        Module m(file, expect);
        auto ps = m.plugins();
        auto deps = m.dependencies();
        m.deinit();
        return nlohmann::json{{"ok", true}, {"count", ps.size()}, {"deps", deps}, {"index", index}}.dump();
    } catch (const std::exception &e) {
        return nlohmann::json{{"ok", false}, {"reason", e.what()}, {"index", index}}.dump();
    }
}

// A file held open from its stamp to its load, so that the stamp and the
// trial name one inode (the loads check they got that one).
struct Candidate {
    fs::path file;
    std::string key;  // absolute, normal form (the trial list's name)
    std::optional<Stamp> stamp;
    int fd = -1;
    explicit Candidate(fs::path f) : file(std::move(f)), key(key_of(file)) {
        fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
        struct stat st {};
        if (fd >= 0 && ::fstat(fd, &st) == 0) stamp = stamp_from(st);
    }
    ~Candidate() {
        if (fd >= 0) ::close(fd);
    }
    Candidate(Candidate &&o) noexcept : file(std::move(o.file)), key(std::move(o.key)), stamp(o.stamp), fd(std::exchange(o.fd, -1)) {}
    Candidate(const Candidate &) = delete;
    std::optional<FileId> id() const { return stamp ? std::optional<FileId>(id_of(*stamp)) : std::nullopt; }
};

}  // namespace

namespace {

// A plugin file: NAME.so, not hidden (a `.x.so.old` left by an editor or an
// upgrade must not shadow `x.so`). Other files (LICENSE.txt, README) are
// not candidates, and not reported.
bool is_candidate(const fs::path &f) {
    const std::string name = f.filename().string();
    return !name.empty() && name[0] != '.' && name.size() > 3 && name.compare(name.size() - 3, 3, ".so") == 0;
}

// Anyone may replace what lies in a world-writable folder, or a
// world-writable file: code from there is not loaded (as ssh refuses keys
// others can write).
bool world_writable(const fs::path &p) {
    struct stat st {};
    return ::stat(p.c_str(), &st) == 0 && (st.st_mode & S_IWOTH);
}

// Plugin code run in this process (init) writing to standard output would
// corrupt what the command prints there (--json): it goes to stderr instead.
class StdoutToStderr {
public:
    StdoutToStderr() {
        std::fflush(stdout);
        saved_ = ::dup(STDOUT_FILENO);
        if (saved_ >= 0) ::dup2(STDERR_FILENO, STDOUT_FILENO);
    }
    ~StdoutToStderr() {
        std::fflush(stdout);
        if (saved_ >= 0) {
            ::dup2(saved_, STDOUT_FILENO);
            ::close(saved_);
        }
    }
    StdoutToStderr(const StdoutToStderr &) = delete;
    StdoutToStderr &operator=(const StdoutToStderr &) = delete;

private:
    int saved_ = -1;
};

}  // namespace

void Registry::scan(const std::vector<fs::path> &dirs) {
    StdoutToStderr quiet;
    std::vector<Candidate> files;  // every candidate, in search order
    for (const auto &dir : dirs) {
        searched_.push_back(dir);
        std::error_code ec;
        if (!fs::is_directory(dir, ec)) continue;
        // NAME.so in the folder, and in its sub-folders one level down (a
        // plugin shipped as a folder with its README, licence and data, as
        // CLAP bundles are); each sub-folder's files after the folder's own.
        std::vector<std::pair<fs::path, bool>> here;  // file, its folder open to all
        std::vector<fs::path> subdirs;
        for (const auto &de : fs::directory_iterator(dir, fs::directory_options::skip_permission_denied, ec)) {
            if ((de.is_regular_file(ec) || de.is_symlink(ec)) && is_candidate(de.path()))
                here.emplace_back(de.path(), false);
            else if (de.is_directory(ec) && !de.path().filename().string().starts_with("."))
                subdirs.push_back(de.path());
        }
        std::sort(here.begin(), here.end());
        std::sort(subdirs.begin(), subdirs.end());
        for (const auto &sub : subdirs) {
            std::vector<std::pair<fs::path, bool>> inside;
            for (const auto &de : fs::directory_iterator(sub, fs::directory_options::skip_permission_denied, ec))
                if ((de.is_regular_file(ec) || de.is_symlink(ec)) && is_candidate(de.path()))
                    inside.emplace_back(de.path(), world_writable(sub));
            std::sort(inside.begin(), inside.end());
            here.insert(here.end(), inside.begin(), inside.end());
        }
        const bool open_dir = world_writable(dir);
        for (auto &[f, open_sub] : here) {
            const bool in_sub = f.parent_path() != dir;
            if (open_dir || open_sub)
                reject(f, "its folder is world-writable (anyone could replace it): not loaded");
            else if (world_writable(f))
                reject(f, "the file is world-writable (anyone could replace it): not loaded");
            else if (auto why = elf_precheck(f)) {
                // A sub-folder's other libraries are the plugin's own (the
                // images loader's OpenImageIO backend): not plugins, not
                // reported.
                if (in_sub && why->starts_with("not a Horizon plugin: no"))
                    spdlog::debug("{} is not a plugin: {}", f.string(), *why);
                else
                    reject(f, *why);
            } else
                files.emplace_back(std::move(f));
        }
    }
    if (!options_.isolate) {
        for (const auto &c : files) load(c.file, c.id());
        return;
    }
    // Files the trial list vouches for are loaded at once; the others go to
    // one child, which trial-loads them in order and reports each as soon as
    // it is done, so the host loads it for real while the child tries the
    // next (a fork per file cost about 1 ms each, twice the loading). A file
    // the child dies or hangs on is rejected, and a new child goes on after
    // it. Either way the files are loaded in search order (the first plugin
    // with a given id wins), each the inode its trial saw.
    TrialList list(options_.trial_cache);
    std::vector<std::size_t> todo;  // the files to trial-load, in order
    for (std::size_t i = 0; i < files.size(); ++i)
        if (!files[i].stamp || !list.vouches(files[i].key, *files[i].stamp)) todo.push_back(i);
    const auto limit = std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(options_.timeout_s));
    pid_t pid = -1;
    int fd = -1;
    std::string buf;
    ChildResult r;
    std::chrono::steady_clock::time_point deadline;
    std::size_t next = 0;  // todo[next]: the next report the child owes
    auto start_child = [&] {
        const std::size_t from = next;
        std::tie(pid, fd) = spawn([&, from](int out) {
            const pid_t self = ::getpid();
            for (std::size_t k = from; k < todo.size(); ++k) {
                const Candidate &c = files[todo[k]];
                std::string report = trial_report(c.file, c.id(), todo[k]);
                if (::getpid() != self) ::_exit(0);  // a process the plugin forked: it reports nothing
                write_all(out, report + "\n");
            }
        });
        buf.clear();
        r = ChildResult{};
        deadline = std::chrono::steady_clock::now() + limit;
    };
    auto end_child = [&] {
        ::close(fd);
        reap(pid, deadline, r);
        pid = -1;
    };
    trial_loads_ += todo.size();  // (each tried once, by the child running when it is reached)
    if (!todo.empty()) start_child();
    for (std::size_t i = 0; i < files.size(); ++i) {
        const Candidate &c = files[i];
        if (next == todo.size() || todo[next] != i) {  // vouched for
            if (!load(c.file, c.id())) list.forget(c.key);
            continue;
        }
        if (pid < 0) start_child();
        ++next;
        if (read_child(pid, fd, deadline, buf, true, r) != 1) {  // died or hung on this file
            end_child();
            reject(c.file, trial_failure(r));
            continue;
        }
        const std::size_t nl = buf.find('\n');
        const std::string report = buf.substr(0, nl);
        buf.erase(0, nl + 1);
        deadline = std::chrono::steady_clock::now() + limit;
        const nlohmann::json j = nlohmann::json::parse(report, nullptr, false);
        if (j.is_discarded() || !j.is_object() || j.value("index", std::size_t(-1)) != i) {
            // Not this file's report: nothing the child says can be matched
            // to a file any more; a new child goes on after this one.
            end_child();
            reject(c.file, "its trial load's report came out of order (did its init() start a process?): not loaded");
            continue;
        }
        std::vector<std::string> deps;
        if (j.contains("deps") && j["deps"].is_array())
            for (const auto &d : j["deps"])
                if (d.is_string()) deps.push_back(d.get<std::string>());
        if (take_report(c.file, j, "trial load gave a malformed report", c.id()) && c.stamp) list.passed(c.key, *c.stamp, deps);
    }
    if (pid >= 0) end_child();
    list.save();
}

std::string Registry::trial_failure(const ChildResult &r) const {
    if (r.timed_out) return "hung while loading or in init() (killed after " + std::to_string(int(options_.timeout_s)) + " s)";
    if (r.signal != 0) return r.describe() + " while loading or in init()";
    return "trial load " + r.describe() + " without a report";
}

bool Registry::take_report(const fs::path &file, const nlohmann::json &j, const std::string &if_malformed, std::optional<FileId> expect) {
    if (j.is_discarded() || !j.is_object() || !j.contains("ok") || !j["ok"].is_boolean()) {
        reject(file, if_malformed);
        return false;
    }
    if (!j["ok"].get<bool>()) {
        reject(file, j.contains("reason") && j["reason"].is_string() ? j["reason"].get<std::string>() : if_malformed);
        return false;
    }
    return load(file, expect);  // (not listed when it crashed or hung here)
}

void Registry::reject(const fs::path &file, const std::string &why) {
    rejected_.push_back({file.string(), why});
    spdlog::debug("plugin {} rejected: {}", file.string(), why);
}

void Registry::add_file(const fs::path &file) {
    if (auto why = elf_precheck(file)) return reject(file, *why);
    const Candidate c(file);
    if (options_.isolate) {
        ++trial_loads_;
        const ChildResult r = run_in_child([&] { return trial_report(c.file, c.id(), 0); }, options_.timeout_s);
        if (r.timed_out || r.signal != 0) return reject(file, trial_failure(r));
        take_report(file, nlohmann::json::parse(r.output, nullptr, false), trial_failure(r), c.id());
        return;
    }
    load(file, c.id());
}

namespace {
// A plugin's parameter schema must be sane before anything uses it: its
// descriptions well formed (schema_of) and each default inside its own
// range, type and count, as a value given with --param must be. Throws
// Error naming the plugin and the parameter.
void check_schema(const LoadedPlugin &lp) {
    for (const ParamSpec &s : schema_of(lp)) {
        if (s.defaults.empty()) continue;  // (a FLOAT_ARRAY without defaults)
        try {
            check_param(s, s.defaults);
        } catch (const Error &e) {
            throw Error(lp.info.id + ": the default of parameter " + s.name + " breaks its own schema: " + e.what());
        }
    }
}
}  // namespace

bool Registry::load(const fs::path &file, std::optional<FileId> expect) {
    try {
        auto module = std::make_shared<Module>(file, expect);
        for (auto &p : module->plugins()) {
            if (const LoadedPlugin *prev = find(p.id)) {
                reject(file, "duplicate plugin id '" + p.id + "' (already provided by " + prev->info.file + ")");
                continue;
            }
            LoadedPlugin lp;
            lp.iface = module->interface(p.id, core_interface(p.kind));
            lp.info = std::move(p);
            lp.module = module;
            check_schema(lp);
            plugins_.push_back(std::move(lp));
        }
    } catch (const PluginFault &e) {
        reject(file, e.what());
        return false;
    } catch (const std::exception &e) {
        reject(file, e.what());
    }
    return true;
}

void Registry::add_module(const Module &m) {
    for (auto &p : m.plugins()) {
        if (find(p.id)) continue;
        LoadedPlugin lp;
        lp.iface = m.interface(p.id, core_interface(p.kind));
        lp.info = std::move(p);
        plugins_.push_back(std::move(lp));
    }
}

const LoadedPlugin *Registry::find(const std::string &id) const {
    for (const auto &p : plugins_)
        if (p.info.id == id) return &p;
    return nullptr;
}

std::vector<const LoadedPlugin *> Registry::of_kind(hz_plugin_kind k) const {
    std::vector<const LoadedPlugin *> out;
    for (const auto &p : plugins_)
        if (p.info.kind == k) out.push_back(&p);
    return out;
}

}  // namespace hz::core
