#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
#include <hz/core/plugin_host.hpp>

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
bool HZ_ABI Task::is_cancelled(const hz_task *t) { return static_cast<Task *>(t->task_data)->cancelled_; }
void HZ_ABI Task::report(const hz_task *t, double f, const char *msg) {
    auto *self = static_cast<Task *>(t->task_data);
    if (self->on_progress) self->on_progress(f, msg);
}

// ---------------------------------------------------------------- ELF check

namespace {
const char *machine_name(unsigned m) {
    switch (m) {
    case EM_X86_64: return "x86-64";
    case EM_386: return "i386";
    case EM_AARCH64: return "AArch64";
    case EM_ARM: return "ARM";
    case EM_RISCV: return "RISC-V";
    case EM_PPC64: return "PowerPC64";
    case EM_S390: return "s390";
    default: return nullptr;
    }
}
#if defined(__x86_64__)
constexpr unsigned kHostMachine = EM_X86_64;
#elif defined(__aarch64__)
constexpr unsigned kHostMachine = EM_AARCH64;
#else
constexpr unsigned kHostMachine = 0;
#endif
// Whether the shared object's dynamic symbol table defines a symbol named
// hz_plugin_entry_v* (any major: the loader names a wrong one), read from
// the file without loading it, so that a library that is not a plugin never
// runs a constructor, not even in a trial; nullopt when the file has no
// section headers to tell (then the trial load decides).
std::optional<bool> exports_plugin_entry(std::ifstream &in, std::uintmax_t size, const Elf64_Ehdr &eh) {
    if (eh.e_shoff == 0 || eh.e_shnum == 0 || eh.e_shentsize != sizeof(Elf64_Shdr) || eh.e_shoff > size ||
        std::uintmax_t(eh.e_shnum) * sizeof(Elf64_Shdr) > size - eh.e_shoff)
        return std::nullopt;
    std::vector<Elf64_Shdr> sh(eh.e_shnum);
    in.clear();
    in.seekg(static_cast<std::streamoff>(eh.e_shoff));
    if (!in.read(reinterpret_cast<char *>(sh.data()), static_cast<std::streamsize>(sh.size() * sizeof(Elf64_Shdr)))) return std::nullopt;
    // (a plugin's symbol tables are kilobytes: a bigger one is read by no one here; the trial load decides)
    auto within = [&](const Elf64_Shdr &h) { return h.sh_offset <= size && h.sh_size <= size - h.sh_offset && h.sh_size <= (64u << 20); };
    auto read = [&](const Elf64_Shdr &h, std::vector<char> &out) {
        out.resize(h.sh_size);
        in.clear();
        in.seekg(static_cast<std::streamoff>(h.sh_offset));
        return static_cast<bool>(in.read(out.data(), static_cast<std::streamsize>(out.size())));
    };
    for (const auto &h : sh) {
        if (h.sh_type != SHT_DYNSYM) continue;
        if (h.sh_link >= sh.size() || !within(h) || !within(sh[h.sh_link]) || h.sh_entsize != sizeof(Elf64_Sym)) return std::nullopt;
        std::vector<char> syms, names;
        if (!read(h, syms) || !read(sh[h.sh_link], names)) return std::nullopt;
        constexpr std::string_view prefix = "hz_plugin_entry_v";
        for (std::size_t off = 0; off + sizeof(Elf64_Sym) <= syms.size(); off += sizeof(Elf64_Sym)) {
            Elf64_Sym sym;
            std::memcpy(&sym, syms.data() + off, sizeof sym);
            if (sym.st_shndx == SHN_UNDEF || sym.st_name >= names.size()) continue;
            const std::string_view name(names.data() + sym.st_name, strnlen(names.data() + sym.st_name, names.size() - sym.st_name));
            if (name.starts_with(prefix)) return true;
        }
        return false;
    }
    return std::nullopt;
}

}  // namespace

std::optional<std::string> elf_precheck(const fs::path &file) {
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) return "not a regular file";
    const auto size = fs::file_size(file, ec);
    if (ec) return "cannot stat: " + ec.message();
    if (size == 0) return "empty file (0 bytes), not a shared object";
    std::ifstream in(file, std::ios::binary);
    if (!in) return std::string("cannot open: ") + std::strerror(errno);
    unsigned char h[sizeof(Elf64_Ehdr)] = {};
    in.read(reinterpret_cast<char *>(h), sizeof h);
    const auto got = static_cast<std::size_t>(in.gcount());
    if (got < 4 || std::memcmp(h, ELFMAG, SELFMAG) != 0) {
        const bool text =
            std::all_of(h, h + got, [](unsigned char c) { return c == '\n' || c == '\r' || c == '\t' || (c >= 32 && c < 127); });
        return text ? "a text file, not a shared object (no ELF header)" : "not a shared object (no ELF magic: random or foreign bytes)";
    }
    if (got < sizeof(Elf64_Ehdr)) return "truncated ELF header";
    if (h[EI_CLASS] != ELFCLASS64) return "32-bit ELF object; this host needs 64-bit plugins";
    if (h[EI_DATA] != ELFDATA2LSB) return "big-endian ELF object; this host is little-endian";
    Elf64_Ehdr eh;
    std::memcpy(&eh, h, sizeof eh);
    if (kHostMachine != 0 && eh.e_machine != kHostMachine) {
        const char *m = machine_name(eh.e_machine);
        return std::string("built for another CPU architecture (") + (m ? m : ("e_machine " + std::to_string(eh.e_machine)).c_str()) +
               "); this host is " + machine_name(kHostMachine);
    }
    if (eh.e_type != ET_DYN) return "an ELF file but not a shared object (e_type " + std::to_string(eh.e_type) + ")";
    if (exports_plugin_entry(in, size, eh) == false) return "not a Horizon plugin: no '" HZ_PLUGIN_ENTRY_SYMBOL "' symbol exported";
    return std::nullopt;
}

// --------------------------------------------------------------- children

std::string ChildResult::describe() const {
    if (timed_out) return "hung (killed after the time limit)";
    if (signal != 0) {
        const char *name = sigabbrev_np(signal);
        return std::string("crashed (signal SIG") + (name ? name : std::to_string(signal).c_str()) + ")";
    }
    if (exited && exit_code != 0) return "exited with status " + std::to_string(exit_code);
    return "ok";
}

namespace {

void write_all(int fd, const std::string &s) {
    const char *p = s.data();
    std::size_t left = s.size();
    while (left > 0) {
        const ssize_t w = ::write(fd, p, left);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) break;
        p += w;
        left -= static_cast<std::size_t>(w);
    }
}

// Forks a child that runs body(fd), fd being the write end of a pipe whose
// read end is returned with the pid. In the child, stdout goes to stderr
// (the parent's stdout stays clean for JSON output) and a crash dies of
// the real signal (sanitizer runtimes would turn it into an exit status),
// so the parent can name it; it exits 0, or 3 when body throws.
std::pair<pid_t, int> spawn(const std::function<void(int)> &body) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) throw Error(std::string("pipe: ") + std::strerror(errno));
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t pid = ::fork();
    if (pid < 0) {
        const int e = errno;
        ::close(fds[0]);
        ::close(fds[1]);
        throw Error(std::string("fork: ") + std::strerror(e));
    }
    if (pid == 0) {
        ::close(fds[0]);
        for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL}) std::signal(sig, SIG_DFL);
        ::dup2(2, 1);
        int code = 0;
        try {
            body(fds[1]);
        } catch (...) {
            code = 3;
        }
        std::fflush(nullptr);
        ::_exit(code);
    }
    ::close(fds[1]);
    return {pid, fds[0]};
}

// Reads what the child writes to `fd` into `buf` until EOF (returns 0), the
// deadline (kills the child, sets r.timed_out, returns -1), or, with
// `until_newline`, a complete line in buf (returns 1).
int read_child(pid_t pid, int fd, std::chrono::steady_clock::time_point deadline, std::string &buf, bool until_newline, ChildResult &r) {
    char chunk[65536];
    for (;;) {
        if (until_newline && buf.find('\n') != std::string::npos) return 1;
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
        if (left <= 0) {
            r.timed_out = true;
            ::kill(pid, SIGKILL);
            return -1;
        }
        pollfd pfd{fd, POLLIN, 0};
        const int pr = ::poll(&pfd, 1, static_cast<int>(std::min<long long>(left, 1000)));
        if (pr < 0 && errno == EINTR) continue;
        if (pr == 0) continue;
        const ssize_t n = ::read(fd, chunk, sizeof chunk);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return 0;  // EOF: the child is done or died
        buf.append(chunk, static_cast<std::size_t>(n));
    }
}

// Waits for the child (its pipe closed, or it was killed) and records how it
// ended; one still running at the deadline is killed.
void reap(pid_t pid, std::chrono::steady_clock::time_point deadline, ChildResult &r) {
    int status = 0;
    if (!r.timed_out) {
        // Woken the moment it exits (a pidfd polls readable then, Linux 5.3;
        // elsewhere, short sleeps).
        const int pidfd = static_cast<int>(::syscall(SYS_pidfd_open, pid, 0));
        for (;;) {
            const pid_t w = ::waitpid(pid, &status, WNOHANG);
            if (w == pid) break;
            const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
            if (left <= 0) {
                r.timed_out = true;
                ::kill(pid, SIGKILL);
                ::waitpid(pid, &status, 0);
                break;
            }
            if (pidfd >= 0) {
                pollfd pfd{pidfd, POLLIN, 0};
                (void)::poll(&pfd, 1, static_cast<int>(std::min<long long>(left, 1000)));
            } else {
                ::usleep(200);
            }
        }
        if (pidfd >= 0) ::close(pidfd);
    } else {
        ::waitpid(pid, &status, 0);
    }
    if (!r.timed_out) {
        if (WIFEXITED(status)) {
            r.exited = true;
            r.exit_code = WEXITSTATUS(status);
        } else if (WIFSIGNALED(status)) {
            r.signal = WTERMSIG(status);
        }
    }
}

}  // namespace

ChildResult run_in_child(const std::function<std::string()> &fn, double timeout_s) {
    ChildResult r;
    const auto [pid, fd] = spawn([&](int out) {
        const pid_t self = ::getpid();
        std::string s = fn();
        if (::getpid() != self) ::_exit(0);  // a process `fn` forked reports nothing
        write_all(out, s);
    });
    const auto deadline = std::chrono::steady_clock::now() +
                          std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(timeout_s));
    read_child(pid, fd, deadline, r.output, false, r);
    ::close(fd);
    reap(pid, deadline, r);
    return r;
}

// ------------------------------------------------------------------ module

const char *plugin_kind_name(hz_plugin_kind k) {
    switch (k) {
    case HZ_KIND_LOADER: return "loader";
    case HZ_KIND_SHADER: return "shader";
    case HZ_KIND_CLUSTERING: return "clustering";
    default: return "unknown";
    }
}

struct Module::Impl {
    boost::dll::shared_library lib;
};

namespace {
const char *core_interface(hz_plugin_kind k) {
    switch (k) {
    case HZ_KIND_LOADER: return HZ_INTERFACE_LOADER;
    case HZ_KIND_SHADER: return HZ_INTERFACE_SHADER;
    case HZ_KIND_CLUSTERING: return HZ_INTERFACE_CLUSTERING;
    default: return nullptr;
    }
}
// The smallest table a plugin of this major may give: the table as ABI 1.0
// defined it. Fields appended since (hz_shader.functions and eval_function
// in 1.2) are read only where struct_size covers them (HZ_HAS_FIELD), so a
// plugin built against an older 1.x header loads (tests/abi/v1_0). (The
// loader table is the 1.0 table: what 1.4-1.9 appended to it a host of 1.10
// never reads; those capabilities are extensions now, hz_extensions.h.)
std::size_t core_interface_min_size(hz_plugin_kind k) {
    switch (k) {
    case HZ_KIND_LOADER: return offsetof(hz_loader, write) + sizeof(hz_loader::write);
    case HZ_KIND_SHADER: return offsetof(hz_shader, functions);
    case HZ_KIND_CLUSTERING: return sizeof(hz_clustering);
    default: return 0;
    }
}
// Reverse-DNS style ids: [a-z0-9][a-z0-9._-]*
bool valid_plugin_id(std::string_view id) {
    if (id.empty() || !(std::islower(static_cast<unsigned char>(id[0])) || std::isdigit(static_cast<unsigned char>(id[0])))) return false;
    return std::all_of(id.begin(), id.end(), [](char c) {
        return std::islower(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c)) || c == '.' || c == '_' ||
               c == '-';
    });
}
std::string first_line(std::string s) {
    const auto nl = s.find('\n');
    if (nl != std::string::npos) s.resize(nl);
    return s;
}
}  // namespace

namespace {

std::optional<FileId> path_id(const fs::path &f) {
    struct stat st {};
    if (::stat(f.c_str(), &st) != 0) return std::nullopt;
    return FileId{static_cast<std::uint64_t>(st.st_dev), static_cast<std::uint64_t>(st.st_ino)};
}

// The file mapped at `addr` in this process: the stat of its
// /proc/self/map_files link (what a stat of the path gives, overlay file
// systems included). nullopt when that link cannot be followed (it takes
// CAP_SYS_ADMIN or CAP_CHECKPOINT_RESTORE on most kernels): the device and
// inode /proc/self/maps shows are those of the layer below an overlay, not
// what stat gives, so they cannot stand in.
std::optional<FileId> mapped_id(const void *addr) {
    std::ifstream maps("/proc/self/maps");
    const auto a = reinterpret_cast<std::uintptr_t>(addr);
    std::string line;
    while (std::getline(maps, line)) {
        unsigned long lo = 0, hi = 0, off = 0, ino = 0;
        unsigned maj = 0, min = 0;
        char perms[8] = {};
        if (std::sscanf(line.c_str(), "%lx-%lx %7s %lx %x:%x %lu", &lo, &hi, perms, &off, &maj, &min, &ino) != 7) continue;
        if (a < lo || a >= hi) continue;
        char link[64];
        std::snprintf(link, sizeof link, "/proc/self/map_files/%lx-%lx", lo, hi);
        struct stat st {};
        if (::stat(link, &st) == 0) return FileId{static_cast<std::uint64_t>(st.st_dev), static_cast<std::uint64_t>(st.st_ino)};
        return std::nullopt;
    }
    return std::nullopt;
}

const char *const kReplaced = "the file was replaced after its trial load: not loaded (the next command tries the new file)";

}  // namespace

Module::Module(const fs::path &file, std::optional<FileId> expect) : impl_(std::make_unique<Impl>()), file_(fs::absolute(file)) {
    namespace dll = boost::dll;
    if (expect && path_id(file_) != expect) throw Error(kReplaced);
    try {
        impl_->lib.load(file_, dll::load_mode::rtld_now | dll::load_mode::rtld_local);
    } catch (const std::exception &e) {
        // Boost appends a stale strerror; the dlerror part comes first.
        std::string m = first_line(e.what());
        const auto cut = m.find(": Bad file descriptor");
        if (cut != std::string::npos) m.resize(cut);
        throw Error("dlopen failed: " + m);
    }
    if (!impl_->lib.has(HZ_PLUGIN_ENTRY_SYMBOL)) {
        for (int major = 0; major < 16; ++major) {
            const std::string sym = "hz_plugin_entry_v" + std::to_string(major);
            if (major != HZ_ABI_VERSION_MAJOR && impl_->lib.has(sym))
                throw Error("built for Horizon plugin ABI " + std::to_string(major) + " (exports " + sym + "); this host supports ABI " +
                            std::to_string(HZ_ABI_VERSION_MAJOR));
        }
        throw Error("not a Horizon plugin: no '" HZ_PLUGIN_ENTRY_SYMBOL "' symbol exported");
    }
    entry_ = &impl_->lib.get<const hz_plugin_entry>(HZ_PLUGIN_ENTRY_SYMBOL);
    const hz_plugin_entry &e = *entry_;
    if (e.struct_size < HZ_PLUGIN_ENTRY_MIN_SIZE)
        throw Error("entry struct_size " + std::to_string(e.struct_size) + " < " + std::to_string(HZ_PLUGIN_ENTRY_MIN_SIZE) +
                    " (corrupt entry or pre-1.0 SDK)");
    if (e.abi.major != HZ_ABI_VERSION_MAJOR)
        throw Error("built for Horizon plugin ABI " + std::to_string(e.abi.major) + "." + std::to_string(e.abi.minor) +
                    "; this host supports ABI " + std::to_string(HZ_ABI_VERSION_MAJOR) + ".x");
    // The object mapped must be the inode the trial saw (a replacement
    // between the check above and dlopen): its constructors have run, but
    // none of its code is called. (Where the mapping cannot be identified,
    // the check of the path just before dlopen stands alone.)
    if (expect) {
        const auto mapped = mapped_id(entry_);
        if (mapped && *mapped != *expect) throw Error(kReplaced);
    }
    if (!e.init || !e.deinit || !e.get_plugin_count || !e.get_plugin_descriptor || !e.get_interface)
        throw Error("entry has a NULL function pointer");
    bool ok = false;
    const pid_t self = ::getpid();
    try {
        ok = e.init(host_services(), file_.c_str());
    } catch (...) {
        if (::getpid() != self) ::_exit(0);
        throw Error("init() threw a C++ exception (exceptions must not cross the ABI)");
    }
    // A process init() forked must not go on as a second host (a second
    // trial reporter, or a second command writing the same outputs).
    if (::getpid() != self) ::_exit(0);
    if (!ok) throw Error("init() returned false (the plugin refused to load; see its log)");
    initialised_ = true;
}

Module::~Module() {
    // Libraries stay resident (boost unloads on destruction only if we let it):
    // plugins may have registered atexit handlers or thread-locals.
    if (impl_) {
        deinit();
        // Kept resident until exit, reachable from a global (no leak report).
        static auto *resident = new std::vector<boost::dll::shared_library>();
        static std::mutex m;
        std::lock_guard lock(m);
        resident->push_back(std::move(impl_->lib));
    }
}

void Module::deinit() {
    if (initialised_) {
        initialised_ = false;
        entry_->deinit();
    }
}

namespace {

struct LoadedObject {
    std::string path;
    ElfW(Addr) base = 0;
    const ElfW(Phdr) *phdr = nullptr;
    int phnum = 0;
    bool contains(std::uintptr_t a) const {
        for (int i = 0; i < phnum; ++i)
            if (phdr[i].p_type == PT_LOAD && a >= base + phdr[i].p_vaddr && a < base + phdr[i].p_vaddr + phdr[i].p_memsz) return true;
        return false;
    }
    // DT_SONAME and DT_NEEDED, read from the dynamic section in memory.
    void dynamic(std::string &soname, std::vector<std::string> &needed) const {
        const ElfW(Dyn) *d = nullptr;
        for (int i = 0; i < phnum; ++i)
            if (phdr[i].p_type == PT_DYNAMIC) d = reinterpret_cast<const ElfW(Dyn) *>(base + phdr[i].p_vaddr);
        if (d == nullptr) return;
        std::uintptr_t strtab = 0;
        std::vector<ElfW(Xword)> offsets;
        ElfW(Xword) so = ~ElfW(Xword)(0);
        for (; d->d_tag != DT_NULL; ++d) {
            if (d->d_tag == DT_STRTAB)
                strtab = d->d_un.d_ptr;
            else if (d->d_tag == DT_NEEDED)
                offsets.push_back(d->d_un.d_val);
            else if (d->d_tag == DT_SONAME)
                so = d->d_un.d_val;
        }
        if (strtab == 0) return;
        // glibc relocates these entries in place where the section is
        // writable; where it is not, they are still link-time addresses.
        if (strtab < base) strtab += base;
        const char *str = reinterpret_cast<const char *>(strtab);
        if (so != ~ElfW(Xword)(0)) soname = str + so;
        for (auto o : offsets) needed.emplace_back(str + o);
    }
};

int collect_object(dl_phdr_info *info, std::size_t, void *data) {
    auto &out = *static_cast<std::vector<LoadedObject> *>(data);
    out.push_back({info->dlpi_name ? info->dlpi_name : "", info->dlpi_addr, info->dlpi_phdr, info->dlpi_phnum});
    return 0;
}

}  // namespace

std::vector<std::string> Module::dependencies() const {
    std::vector<LoadedObject> objects;
    ::dl_iterate_phdr(collect_object, &objects);
    const auto self = std::find_if(objects.begin(), objects.end(),
                                   [&](const LoadedObject &o) { return o.contains(reinterpret_cast<std::uintptr_t>(entry_)); });
    if (self == objects.end()) return {};
    std::vector<std::string> sonames(objects.size());
    std::vector<std::vector<std::string>> needed(objects.size());
    for (std::size_t i = 0; i < objects.size(); ++i)
        if (!objects[i].path.empty()) objects[i].dynamic(sonames[i], needed[i]);
    auto resolve = [&](const std::string &name) -> std::ptrdiff_t {
        for (std::size_t i = 0; i < objects.size(); ++i)
            if (!objects[i].path.empty() && (sonames[i] == name || objects[i].path == name || fs::path(objects[i].path).filename() == name))
                return static_cast<std::ptrdiff_t>(i);
        return -1;
    };
    std::vector<std::string> out;
    std::set<std::size_t> seen{static_cast<std::size_t>(self - objects.begin())};
    std::vector<std::size_t> todo(seen.begin(), seen.end());
    while (!todo.empty()) {
        const std::size_t k = todo.back();
        todo.pop_back();
        for (const auto &n : needed[k]) {
            const auto j = resolve(n);
            if (j < 0 || !seen.insert(static_cast<std::size_t>(j)).second) continue;
            out.push_back(objects[static_cast<std::size_t>(j)].path);
            todo.push_back(static_cast<std::size_t>(j));
        }
    }
    std::sort(out.begin(), out.end());
    return out;
}

std::vector<PluginInfo> Module::plugins() const {
    std::vector<PluginInfo> out;
    const uint32_t n = entry_->get_plugin_count();
    if (n == 0) throw Error("get_plugin_count() returned 0");
    if (n > 1024) throw Error("get_plugin_count() returned " + std::to_string(n) + " (absurd)");
    for (uint32_t i = 0; i < n; ++i) {
        const hz_plugin_descriptor *d = entry_->get_plugin_descriptor(i);
        const std::string at = "descriptor " + std::to_string(i);
        if (d == nullptr) throw Error(at + " is NULL");
        if (d->struct_size < sizeof(hz_plugin_descriptor)) throw Error(at + ": struct_size too small");
        if (d->abi.major != HZ_ABI_VERSION_MAJOR) throw Error(at + ": built for ABI " + std::to_string(d->abi.major));
        if (!d->id || !*d->id) throw Error(at + ": missing id");
        if (!valid_plugin_id(d->id)) throw Error(at + ": id '" + std::string(d->id) + "' is not [a-z0-9._-]+");
        if (!d->name || !*d->name) throw Error(at + " (" + d->id + "): missing name");
        if (!d->version || !*d->version) throw Error(at + " (" + d->id + "): missing version");
        const char *ci = core_interface(d->kind);
        if (ci == nullptr) throw Error(std::string(d->id) + ": unknown kind " + std::to_string(d->kind));
        if (d->interfaces == nullptr) throw Error(std::string(d->id) + ": interfaces list is NULL");
        PluginInfo p;
        p.id = d->id;
        p.name = d->name;
        p.version = d->version;
        p.vendor = d->vendor ? d->vendor : "";
        p.description = d->description ? d->description : "";
        p.license = d->license ? d->license : "";
        p.kind = d->kind;
        p.abi = d->abi;
        p.file = file_.string();
        for (const char *const *it = d->interfaces; *it != nullptr && p.interfaces.size() < 64; ++it) p.interfaces.emplace_back(*it);
        if (std::find(p.interfaces.begin(), p.interfaces.end(), ci) == p.interfaces.end())
            throw Error(p.id + ": kind " + plugin_kind_name(d->kind) + " but '" + ci + "' not in its interfaces");
        const void *t = entry_->get_interface(d->id, ci);
        if (t == nullptr) throw Error(p.id + ": get_interface(\"" + ci + "\") returned NULL");
        const auto size = *static_cast<const uint32_t *>(t);
        if (size < core_interface_min_size(d->kind))
            throw Error(p.id + ": '" + ci + "' table struct_size " + std::to_string(size) + " < " +
                        std::to_string(core_interface_min_size(d->kind)));
        out.push_back(std::move(p));
    }
    return out;
}

const void *Module::interface(const std::string &plugin_id, const char *iface) const {
    return entry_->get_interface(plugin_id.c_str(), iface);
}

const void *LoadedPlugin::extension(const char *id, std::size_t min_size) const {
    if (!module ||
        std::find(info.interfaces.begin() + (info.interfaces.empty() ? 0 : 1), info.interfaces.end(), id) == info.interfaces.end())
        return nullptr;
    const void *t = module->interface(info.id, id);
    if (t == nullptr || *static_cast<const std::uint32_t *>(t) < min_size) return nullptr;
    return t;
}

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
            load(c.file, c.id());
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
    load(file, expect);
    return true;
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

void Registry::load(const fs::path &file, std::optional<FileId> expect) {
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
            plugins_.push_back(std::move(lp));
        }
    } catch (const std::exception &e) {
        reject(file, e.what());
    }
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
