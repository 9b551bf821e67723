// One plugin library: the ELF checks made before dlopen, the load and its
// checks (entry, descriptors, interfaces, the trial's inode), init/deinit,
// its dependencies, and the extension tables its plugins serve.
#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
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

namespace detail {
const char *core_interface(hz_plugin_kind k) {
    switch (k) {
    case HZ_KIND_LOADER: return HZ_INTERFACE_LOADER;
    case HZ_KIND_SHADER: return HZ_INTERFACE_SHADER;
    case HZ_KIND_CLUSTERING: return HZ_INTERFACE_CLUSTERING;
    default: return nullptr;
    }
}
}  // namespace detail

namespace {
using detail::core_interface;
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

template <class F>
void Module::guarded(const char *call, const std::string &what, F &&f) const {
    if (faulted()) throw PluginFault(what + "not called: it crashed or hung in an earlier call");
    PluginCallSite site;
    site.plugin = file_.c_str();
    site.call = call;
    site.timeout_s = plugin_call_timeout();
    if (guarded_call(site, std::forward<F>(f))) return;
    mark_faulted();
    throw PluginFault(what + fault_text(site));
}

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
    register_plugin_object(entry_, file_.string());  // (a crash at exit in its code is named)
    bool ok = false;
    const pid_t self = ::getpid();
    // The working directory is the user's: a plugin that changes it in
    // init() would send every relative input and output path elsewhere.
    // It is put back, and the plugin named.
    const int cwd = ::open(".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    struct stat before {};
    const bool known = cwd >= 0 && ::fstat(cwd, &before) == 0;
    bool threw = false;
    try {
        guarded("init", "", [&] {
            try {
                ok = e.init(host_services(), file_.c_str());
            } catch (...) {
                threw = true;
            }
        });
    } catch (const PluginFault &) {
        if (::getpid() != self) ::_exit(0);
        if (cwd >= 0) (void)::fchdir(cwd), ::close(cwd);
        throw;
    }
    if (threw) {
        if (::getpid() != self) ::_exit(0);
        if (cwd >= 0) (void)::fchdir(cwd), ::close(cwd);
        throw Error("init() threw a C++ exception (exceptions must not cross the ABI)");
    }
    // A process init() forked must not go on as a second host (a second
    // trial reporter, or a second command writing the same outputs).
    if (::getpid() != self) ::_exit(0);
    if (known) {
        struct stat after {};
        if (::stat(".", &after) != 0 || after.st_dev != before.st_dev || after.st_ino != before.st_ino) {
            if (::fchdir(cwd) != 0) {
                ::close(cwd);
                throw Error("init() changed the working directory, and it could not be put back");
            }
            spdlog::warn("{}: init() changed the working directory; it was put back (report it to the plugin's author)", file_.string());
        }
    }
    if (cwd >= 0) ::close(cwd);
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
    if (!initialised_) return;
    initialised_ = false;
    if (faulted()) return;
    // (after the command's work: a fault is a warning, and the command's
    // status stands)
    try {
        guarded("deinit", "", [&] {
            try {
                entry_->deinit();
            } catch (...) {}
        });
    } catch (const PluginFault &f) {
        spdlog::warn("the plugin {} {}; move it out of the plugin folders or report it to its author", file_.string(), f.what());
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
    // (each call guarded: the first in this process may well be after the
    // trial's, and a crash or hang in it must not take the host with it)
    const std::string after = "in this process (after its trial load): ";
    uint32_t n = 0;
    guarded("get_plugin_count", after, [&] { n = entry_->get_plugin_count(); });
    if (n == 0) throw Error("get_plugin_count() returned 0");
    if (n > 1024) throw Error("get_plugin_count() returned " + std::to_string(n) + " (absurd)");
    for (uint32_t i = 0; i < n; ++i) {
        const hz_plugin_descriptor *d = nullptr;
        guarded("get_plugin_descriptor", after, [&] { d = entry_->get_plugin_descriptor(i); });
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
        const void *t = nullptr;
        guarded("get_interface", after, [&] { t = entry_->get_interface(d->id, ci); });
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
    const void *t = nullptr;
    try {
        guarded("get_interface", "the plugin " + plugin_id + " (" + file_.string() + ") ",
                [&] { t = entry_->get_interface(plugin_id.c_str(), iface); });
    } catch (const PluginFault &f) {
        throw PluginFault(std::string(f.what()) + "; move it out of the plugin folders or report it to its author");
    }
    return t;
}

const void *offered_extension(const Module &module, const PluginInfo &info, const char *id, std::size_t min_size) {
    if (info.interfaces.empty() || std::find(info.interfaces.begin() + 1, info.interfaces.end(), id) == info.interfaces.end())
        return nullptr;
    const void *t = module.interface(info.id, id);
    if (t == nullptr || *static_cast<const std::uint32_t *>(t) < min_size) return nullptr;
    return t;
}

std::string LoadedPlugin::escaped(const char *call, const std::string &what, const char *message) const {
    return (what.empty() ? "" : what + ": ") + "the plugin " + info.id + " (" + info.file + ") let a C++ exception out of " + call +
           "() (exceptions must not cross the ABI; report it to its author): " + message;
}

const void *LoadedPlugin::extension(const char *id, std::size_t min_size) const {
    return module ? offered_extension(*module, info, id, min_size) : nullptr;
}

}  // namespace hz::core
