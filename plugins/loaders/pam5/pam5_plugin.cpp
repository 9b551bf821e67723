// hz.loader/1 for DIPY's PAM5 peak files (HDF5; dipy.io.peaks.save_peaks),
// through the SDK's C++ loader adapter (hz/cpp/loader.hpp).
//
// A PAM5 file is an HDF5 file whose root attribute `version` is "0.0.1" and
// whose group `pam` holds `peak_dirs` (x, y, z, N, 3: unit vectors),
// `peak_values` (x, y, z, N), an optional `affine` (4 x 4) and DIPY's other
// results (shm_coeff, sphere_vertices, gfa, qa, odf, ...). It is read as a
// peak volume (peaks.hpp in the core): float32 (x, y, z, 3N), peak p of a
// voxel the vector peak_dirs[p] x peak_values[p] (values 3p..3p+2), as
// MRtrix3's sh2peaks stores peaks, and DIPY's reshape_peaks_for_visualization
// times the values. HDF5 arrays are C order (x slowest); the volume is x
// fastest: read one x plane at a time, so that what is held besides the
// volume is a plane.
//
// HDF5 1.10 crashes on some damaged files (a corrupted global heap makes
// H5HG_read copy past its buffer): every call into it runs in a program of
// its own (pam5_reader.cpp, started with posix_spawn) that sends what it read
// through a pipe (pam5_wire.hpp), so that a crash, or a read making no
// progress for two minutes, is a one-line error naming the file rather than
// the end of the program that loaded the plugin. This plugin does not link
// HDF5.
#include <hz/cpp/loader.hpp>

#include "pam5_wire.hpp"

#include <dlfcn.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

extern "C" char **environ;

namespace {

constexpr const char *kId = "org.horizon.loader.pam5";

using pam5wire::FormatError;
using pam5wire::Header;
struct IoError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
struct Cancelled {};

struct Pam5Reader {
    std::string path;
    Header h;
};

// Reads exactly n bytes from the child, waiting at most two minutes for
// each; false at the end of the pipe (the child exited or died).
bool receive(int fd, void *p, std::size_t n, const std::string &what) {
    auto *b = static_cast<char *>(p);
    while (n > 0) {
        pollfd pfd{fd, POLLIN, 0};
        const int ready = ::poll(&pfd, 1, 120000);
        if (ready < 0 && errno == EINTR) continue;
        if (ready == 0) throw FormatError("HDF5 made no progress reading " + what + " for two minutes (a damaged file?)");
        const ssize_t r = ::read(fd, b, n);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) return false;
        b += r, n -= std::size_t(r);
    }
    return true;
}

// The reader program beside this plugin (pam5_reader.cpp, installed in
// pam5.helper/ of the plugin's folder).
std::string reader_program() {
    Dl_info info{};
    if (::dladdr(reinterpret_cast<void *>(&reader_program), &info) == 0 || info.dli_fname == nullptr)
        throw IoError("cannot find where this plugin is (dladdr)");
    std::string dir = info.dli_fname;
    dir = dir.substr(0, dir.find_last_of('/') == std::string::npos ? 0 : dir.find_last_of('/') + 1);
    const std::string program = dir + "pam5.helper/hz_pam5_read";
    if (::access(program.c_str(), X_OK) != 0)
        throw IoError("its HDF5 reader " + program + " is missing or not executable (reinstall Horizon)");
    return program;
}

// The reader program run with `args` (all of HDF5's work: its errors come
// as an 'E' frame, its standard error is dropped), and `parent(fd)` reading
// what it sends. It is waited for (killed first if the parent leaves early,
// by an exception or a cancellation); one that died by a signal, or exited
// without a word, throws FormatError.
template <class Parent>
void in_child(const std::string &what, const std::vector<std::string> &args, Parent &&parent) {
    const std::string program = reader_program();
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) throw IoError(std::string("pipe: ") + std::strerror(errno));
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    std::vector<char *> argv;
    argv.push_back(const_cast<char *>(program.c_str()));
    for (const auto &a : args) argv.push_back(const_cast<char *>(a.c_str()));
    argv.push_back(nullptr);
    pid_t pid = 0;
    const int err = ::posix_spawn(&pid, program.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (err != 0) {
        ::close(fds[0]), ::close(fds[1]);
        throw IoError("cannot run its HDF5 reader " + program + ": " + std::strerror(err));
    }
    ::close(fds[1]);
    struct Reap {
        pid_t pid;
        int fd;
        bool done = false;
        int status = 0;
        void wait(bool kill) {
            if (done) return;
            if (kill) ::kill(pid, SIGKILL);
            ::close(fd);
            while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {}
            done = true;
        }
        ~Reap() { wait(true); }
    } reap{pid, fds[0]};
    const bool complete = parent(fds[0]);
    reap.wait(!complete);
    if (!complete) return;
    if (WIFSIGNALED(reap.status))
        throw FormatError("the HDF5 library crashed reading " + what + " (signal " + std::to_string(WTERMSIG(reap.status)) +
                          "): a damaged file");
}

// The next frame's tag from the child: 'E' is thrown as its message; the
// end of the pipe (the child died) as a crash.
char next_tag(int fd, const std::string &what) {
    char tag = 0;
    if (!receive(fd, &tag, 1, what)) throw FormatError("the HDF5 library crashed reading " + what + ": a damaged file");
    if (tag == 'E') {
        std::uint64_t n = 0;
        std::string m;
        if (receive(fd, &n, 8, what) && n < 4096) {
            m.resize(n);
            if (!receive(fd, m.data(), n, what)) m.clear();
        }
        throw FormatError(m.empty() ? "the HDF5 library failed reading " + what : m);
    }
    return tag;
}
std::uint64_t receive_u64(int fd, const std::string &what) {
    std::uint64_t v = 0;
    if (!receive(fd, &v, 8, what)) throw FormatError("the HDF5 library crashed reading " + what + ": a damaged file");
    return v;
}
std::string receive_text(int fd, const std::string &what) {
    const std::uint64_t n = receive_u64(fd, what);
    if (n > 4096) throw FormatError("a malformed answer from the HDF5 reader");
    std::string t(n, '\0');
    if (n && !receive(fd, t.data(), n, what)) throw FormatError("the HDF5 library crashed reading " + what + ": a damaged file");
    return t;
}

int32_t pam5_probe(const uint8_t *head, uint64_t size, const char *name) noexcept {
    static const unsigned char sig[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
    if (size < 8 || std::memcmp(head, sig, 8) != 0) return 0;
    const std::string n = name ? name : "";
    const bool ext = n.size() >= 5 && std::equal(n.end() - 5, n.end(), ".pam5", [](char a, char b) { return std::tolower(a) == b; });
    return ext ? 90 : 0;  // (an HDF5 file of another kind is not ours)
}

std::unique_ptr<Pam5Reader> pam5_open(const std::string &path, const hz_task *) {
    auto r = std::make_unique<Pam5Reader>();
    r->path = path;
    in_child("the file", {"open", path}, [&](int fd) {
        if (next_tag(fd, "the file") != 'H') throw FormatError("a malformed answer from the HDF5 reader");
        Header &h = r->h;
        h.X = receive_u64(fd, "the file"), h.Y = receive_u64(fd, "the file"), h.Z = receive_u64(fd, "the file"),
        h.N = receive_u64(fd, "the file");
        if (!receive(fd, h.affine.data(), sizeof h.affine, "the file")) throw FormatError("the HDF5 library crashed reading the file");
        h.version = receive_text(fd, "the file");
        const std::uint64_t n = receive_u64(fd, "the file");
        if (n > 64) throw FormatError("a malformed answer from the HDF5 reader");
        for (std::uint64_t i = 0; i < n; ++i) {
            std::string k = receive_text(fd, "the file");
            h.meta.emplace_back(std::move(k), receive_text(fd, "the file"));
        }
        return true;
    });
    return r;
}

void pam5_info(const Pam5Reader &reader, hz_dataset_info &out) {
    const Header &r = reader.h;
    out.kind = HZ_DATA_VOLUME;
    std::snprintf(out.format, sizeof out.format, "pam5 %s", r.version.c_str());
    out.dtype = HZ_DTYPE_F32;
    out.ndim = 4;
    out.dims[0] = r.X, out.dims[1] = r.Y, out.dims[2] = r.Z, out.dims[3] = 3 * r.N;
    out.scale_slope = 1;
    out.scale_inter = 0;
    std::copy(r.affine.begin(), r.affine.end(), out.voxel_to_ras);
    out.ref_dims[0] = r.X, out.ref_dims[1] = r.Y, out.ref_dims[2] = r.Z;
    out.source_space = HZ_SPACE_VOXEL;
}

void pam5_metadata(const Pam5Reader &reader, hz_metadata_visitor visitor, void *ctx) {
    const Header &r = reader.h;
    for (const auto &[k, v] : r.meta) visitor(ctx, k.c_str(), v.c_str());
}

void pam5_read_volume(Pam5Reader &reader, const hz_array_view &dst, const hz_task *task) {
    const Header &r = reader.h;
    if (dst.dtype != HZ_DTYPE_F32 && dst.dtype != HZ_DTYPE_F64)
        throw FormatError("read_volume: the destination must be float32 or float64");
    const std::uint64_t C = 3 * r.N;
    // The destination's axes: the volume's, trailing ones merged into its last.
    if (dst.ndim < 1 || dst.ndim > 4) throw FormatError("read_volume: the destination must have 1 to 4 axes");
    std::vector<std::uint64_t> dims = {r.X, r.Y, r.Z, C};
    while (dims.size() > dst.ndim) {
        const std::uint64_t last = dims.back();
        dims.pop_back();
        dims.back() *= last;
    }
    for (std::size_t i = 0; i < dims.size(); ++i)
        if (dst.shape[i] != dims[i]) throw FormatError("read_volume: the destination's shape does not match the volume");
    const std::size_t es = dst.dtype == HZ_DTYPE_F32 ? 4 : 8;
    std::int64_t lo = 0, hi = 0;
    for (std::size_t i = 0; i < dims.size(); ++i) {
        const std::int64_t span = static_cast<std::int64_t>(dims[i] - 1) * dst.stride_bytes[i];
        (span < 0 ? lo : hi) += span;
    }
    if (lo < 0 || static_cast<std::uint64_t>(hi) + es > dst.capacity_bytes)
        throw hz::Error(HZ_E_BUFFER_TOO_SMALL, "pam5: destination too small");
    auto *base = static_cast<unsigned char *>(dst.data);
    const auto put = [&](std::uint64_t linear, double v) {  // (linear: x fastest over (X, Y, Z, C))
        std::int64_t off = 0;
        for (std::size_t i = 0; i < dims.size(); ++i) {
            off += static_cast<std::int64_t>(linear % dims[i]) * dst.stride_bytes[i];
            linear /= dims[i];
        }
        if (es == 4) {
            const float f = static_cast<float>(v);
            std::memcpy(base + off, &f, 4);
        } else {
            std::memcpy(base + off, &v, 8);
        }
    };
    // The child reads each x plane of both datasets and sends their products
    // (C order within the plane: y, z, peak, component); here they go to
    // their places in the destination as they come.
    const std::uint64_t plane = r.Y * r.Z * r.N * 3, XYZ = r.X * r.Y * r.Z;
    in_child("its peaks", {"read", reader.path, std::to_string(r.X), std::to_string(r.Y), std::to_string(r.Z), std::to_string(r.N)},
             [&](int fd) {
                 std::vector<float> in(plane);
                 for (std::uint64_t x = 0; x < r.X; ++x) {
                     if (hz::cancelled(task)) throw Cancelled{};
                     if (next_tag(fd, "its peaks") != 'P' || !receive(fd, in.data(), in.size() * 4, "its peaks"))
                         throw FormatError("the HDF5 library crashed reading its peaks: a damaged file");
                     for (std::uint64_t y = 0; y < r.Y; ++y)
                         for (std::uint64_t z = 0; z < r.Z; ++z)
                             for (std::uint64_t p = 0; p < r.N; ++p) {
                                 const std::uint64_t at = (y * r.Z + z) * r.N + p;  // (C order within the plane)
                                 for (std::uint64_t k = 0; k < 3; ++k) put(x + r.X * (y + r.Y * z) + XYZ * (3 * p + k), in[3 * at + k]);
                             }
                     hz::report(task, double(x + 1) / double(r.X));
                 }
                 return true;
             });
}

const char *const kExtensions[] = {"pam5", nullptr};

struct Pam5 {
    static constexpr const char *prefix = "pam5";
    static constexpr hz_data_kind kinds = HZ_DATA_VOLUME;
    static constexpr uint32_t probe_bytes = 8;
    static constexpr const char *const *extensions = kExtensions;
    using FormatError = ::FormatError;
    using IoError = ::IoError;
    using Cancelled = ::Cancelled;
    using Reader = Pam5Reader;
    static constexpr auto probe = pam5_probe;
    static constexpr auto open = pam5_open;
    static constexpr auto info = pam5_info;
    static constexpr auto metadata = pam5_metadata;
    static constexpr auto read_volume = pam5_read_volume;
};

const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_LOADER,
    .id = kId,
    .name = "DIPY PAM5 peaks",
    .version = "1.0.0",
    .vendor = "Horizon",
    .description =
        "DIPY's PAM5 peak files (.pam5, HDF5, version 0.0.1): the peaks as a volume of 3 values a peak "
        "(direction x value), drawn as peak glyphs; reads",
    .license = "MIT",
    .interfaces = hz::loader<Pam5>::interfaces,
};

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = hz::loader_plugin<kDescriptor, Pam5>::entry;
