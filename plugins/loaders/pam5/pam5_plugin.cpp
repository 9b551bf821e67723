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
// H5HG_read copy past its buffer): every call into it runs in a child
// process (fork) that sends what it read through a pipe, so that a crash, or
// a read making no progress for two minutes, is a one-line error naming the
// file rather than the end of the program.
#include <hz/cpp/loader.hpp>

#include <hdf5.h>
#include <poll.h>
#include <signal.h>
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

namespace {

constexpr const char *kId = "org.horizon.loader.pam5";

struct FormatError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
struct IoError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
struct Cancelled {};

// An HDF5 identifier closed by `close` when it goes.
struct Id {
    hid_t id = H5I_INVALID_HID;
    herr_t (*close)(hid_t) = nullptr;
    Id() = default;
    Id(hid_t i, herr_t (*c)(hid_t)) : id(i), close(c) {}
    Id(const Id &) = delete;
    Id &operator=(const Id &) = delete;
    Id(Id &&o) noexcept : id(std::exchange(o.id, H5I_INVALID_HID)), close(o.close) {}
    Id &operator=(Id &&o) noexcept {
        std::swap(id, o.id), std::swap(close, o.close);
        return *this;
    }
    ~Id() {
        if (id >= 0 && close) close(id);
    }
    bool ok() const { return id >= 0; }
};

// The extents of a numeric (integer or float) dataset; throws naming it.
std::vector<hsize_t> numeric_shape(hid_t ds, const std::string &name) {
    const Id type(H5Dget_type(ds), H5Tclose);
    if (!type.ok()) throw FormatError("'pam/" + name + "': its type cannot be read");
    const H5T_class_t c = H5Tget_class(type.id);
    if (c != H5T_FLOAT && c != H5T_INTEGER) throw FormatError("'pam/" + name + "' holds no numbers");
    const Id space(H5Dget_space(ds), H5Sclose);
    if (!space.ok() || H5Sget_simple_extent_type(space.id) != H5S_SIMPLE) throw FormatError("'pam/" + name + "' is not an array");
    const int rank = H5Sget_simple_extent_ndims(space.id);
    if (rank < 0 || rank > 8) throw FormatError("'pam/" + name + "' has an unreadable rank");
    std::vector<hsize_t> dims(static_cast<std::size_t>(rank));
    if (rank > 0 && H5Sget_simple_extent_dims(space.id, dims.data(), nullptr) < 0)
        throw FormatError("'pam/" + name + "': its extents cannot be read");
    return dims;
}

std::string shape_text(const std::vector<hsize_t> &d) {
    std::string s = "(";
    for (std::size_t i = 0; i < d.size(); ++i) s += (i ? ", " : "") + std::to_string(d[i]);
    return s + (d.size() == 1 ? ",)" : ")");
}

// What the child reads at open: the extents, the affine, the header entries.
struct Header {
    std::uint64_t X = 0, Y = 0, Z = 0, N = 0;
    std::array<double, 16> affine{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::string version;
    std::vector<std::pair<std::string, std::string>> meta;
};

struct Pam5Reader {
    std::string path;
    Header h;
};

// ------------------------------------------------------- the child's side

// Bytes to the parent; a write that fails (the parent gone) ends the child.
void send(int fd, const void *p, std::size_t n) {
    const auto *b = static_cast<const char *>(p);
    while (n > 0) {
        const ssize_t w = ::write(fd, b, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) ::_exit(3);
        b += w, n -= std::size_t(w);
    }
}
void send_u64(int fd, std::uint64_t v) { send(fd, &v, 8); }
void send_text(int fd, const std::string &t) {
    send_u64(fd, t.size());
    send(fd, t.data(), t.size());
}

// -------------------------------------------------------- the parent's side

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

// A child running `work(fd)` (all of HDF5's work: the child's exceptions
// are sent as an 'E' frame), and `parent(fd, pid)` reading what it sends.
// The child is waited for (killed first if the parent leaves early, by an
// exception or a cancellation); one that died by a signal, or exited
// without a word, throws FormatError.
template <class Work, class Parent>
void in_child(const std::string &what, Work &&work, Parent &&parent) {
    int fds[2];
    if (::pipe(fds) != 0) throw IoError(std::string("pipe: ") + std::strerror(errno));
    // (HDF5 is only ever called in such children: the program's own copy of
    // it is never initialised, and children of threads do not share it)
    const pid_t pid = ::fork();
    if (pid < 0) {
        ::close(fds[0]), ::close(fds[1]);
        throw IoError(std::string("fork: ") + std::strerror(errno));
    }
    if (pid == 0) {
        ::close(fds[0]);
        // (a crash here ends the child, silently: not the program's handlers, which would report it as the program's)
        for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGTRAP, SIGSYS}) ::signal(sig, SIG_DFL);
        try {
            H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // (errors are reported here, not printed by HDF5)
            work(fds[1]);
        } catch (const std::exception &e) {
            send(fds[1], "E", 1);
            send_text(fds[1], e.what());
        } catch (...) {
            send(fds[1], "E", 1);
            send_text(fds[1], "an unknown error in HDF5");
        }
        ::_exit(0);  // (no atexit handlers: the parent's HDF5 state is not the child's to close)
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

// The root attribute `version` as text (fixed or variable length).
std::string read_version(hid_t file) {
    if (H5Aexists(file, "version") <= 0) throw FormatError("no 'version' attribute: not a PAM5 file (dipy.io.peaks.save_peaks)");
    const Id attr(H5Aopen(file, "version", H5P_DEFAULT), H5Aclose);
    const Id type(attr.ok() ? H5Aget_type(attr.id) : H5I_INVALID_HID, H5Tclose);
    if (!type.ok() || H5Tget_class(type.id) != H5T_STRING) throw FormatError("the 'version' attribute is not text");
    const Id space(H5Aget_space(attr.id), H5Sclose);
    if (!space.ok() || H5Sget_simple_extent_npoints(space.id) != 1) throw FormatError("the 'version' attribute is not one string");
    if (H5Tis_variable_str(type.id) > 0) {
        const Id mem(H5Tcopy(H5T_C_S1), H5Tclose);
        H5Tset_size(mem.id, H5T_VARIABLE);
        H5Tset_cset(mem.id, H5Tget_cset(type.id));  // (h5py writes UTF-8: no conversion from it to ASCII)
        char *s = nullptr;
        if (H5Aread(attr.id, mem.id, &s) < 0 || s == nullptr) throw FormatError("the 'version' attribute cannot be read");
        std::string out(s, strnlen(s, 64));
        H5free_memory(s);
        return out;
    }
    const std::size_t n = H5Tget_size(type.id);
    if (n == 0 || n > 64) throw FormatError("the 'version' attribute is " + std::to_string(n) + " bytes long");
    std::string buf(n + 1, '\0');  // (room for the terminator: a null-padded string of n bytes keeps all n)
    const Id mem(H5Tcopy(H5T_C_S1), H5Tclose);
    H5Tset_size(mem.id, n + 1);
    H5Tset_cset(mem.id, H5Tget_cset(type.id));
    if (H5Aread(attr.id, mem.id, buf.data()) < 0) throw FormatError("the 'version' attribute cannot be read");
    buf.resize(strnlen(buf.data(), n + 1));
    return buf;
}

// The child's open: the file checked and described (the datasets stay open
// in `ids`, for the planes that follow when `ids` is given).
struct Open {
    Id file, group, dirs, values;
};
Header inspect(const std::string &path, Open &o) {
    Header h;
    Header *r = &h;
    Open *ids = &o;
    if (H5Fis_hdf5(path.c_str()) <= 0) throw FormatError("not an HDF5 file");
    ids->file = Id(H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT), H5Fclose);
    if (!ids->file.ok()) throw FormatError("HDF5 cannot open it (damaged or truncated)");
    r->version = read_version(ids->file.id);
    if (r->version != "0.0.1") throw FormatError("PAM5 version '" + r->version + "' is not one this reader knows (0.0.1)");
    if (H5Lexists(ids->file.id, "pam", H5P_DEFAULT) <= 0) throw FormatError("no group 'pam'");
    ids->group = Id(H5Gopen2(ids->file.id, "pam", H5P_DEFAULT), H5Gclose);
    if (!ids->group.ok()) throw FormatError("'pam' is not a group");
    const auto dataset = [&](const char *name, bool required) {
        if (H5Lexists(ids->group.id, name, H5P_DEFAULT) <= 0) {
            if (required) throw FormatError(std::string("no dataset 'pam/") + name + "'");
            return Id();
        }
        Id d(H5Dopen2(ids->group.id, name, H5P_DEFAULT), H5Dclose);
        if (!d.ok()) throw FormatError(std::string("'pam/") + name + "' is not a dataset");
        return d;
    };
    ids->dirs = dataset("peak_dirs", true);
    ids->values = dataset("peak_values", true);
    const std::vector<hsize_t> dd = numeric_shape(ids->dirs.id, "peak_dirs"), vd = numeric_shape(ids->values.id, "peak_values");
    if (dd.size() != 5 || dd[4] != 3) throw FormatError("'pam/peak_dirs' is " + shape_text(dd) + ": expected (x, y, z, peaks, 3)");
    if (vd.size() != 4 || !std::equal(vd.begin(), vd.end(), dd.begin()))
        throw FormatError("'pam/peak_values' is " + shape_text(vd) + ", 'pam/peak_dirs' " + shape_text(dd) +
                          ": the values must be (x, y, z, peaks) of the same extents");
    for (int k = 0; k < 4; ++k)
        if (dd[std::size_t(k)] == 0) throw FormatError("'pam/peak_dirs' is " + shape_text(dd) + ": an extent is 0");
    r->X = dd[0], r->Y = dd[1], r->Z = dd[2], r->N = dd[3];
    // (the host bounds the volume by the memory available before reading;
    // extents past 2^40 voxels would overflow its arithmetic first)
    if (r->X > (1u << 20) || r->Y > (1u << 20) || r->Z > (1u << 20) || r->N > 4096 || r->X * r->Y * r->Z > (std::uint64_t(1) << 36))
        throw FormatError("'pam/peak_dirs' is " + shape_text(dd) + ": beyond any volume this reader accepts");
    if (Id a = dataset("affine", false); a.ok()) {
        const std::vector<hsize_t> ad = numeric_shape(a.id, "affine");
        if (ad != std::vector<hsize_t>{4, 4}) throw FormatError("'pam/affine' is " + shape_text(ad) + ", not (4, 4)");
        double m[16];
        if (H5Dread(a.id, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, m) < 0) throw FormatError("'pam/affine' cannot be read");
        for (double v : m)
            if (!std::isfinite(v)) throw FormatError("'pam/affine' holds a value that is not finite");
        const double det = m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) + m[2] * (m[4] * m[9] - m[5] * m[8]);
        if (!(std::abs(det) > 1e-12)) throw FormatError("'pam/affine' is singular");
        std::copy(m, m + 16, r->affine.begin());
    } else {
        r->meta.emplace_back("affine", "none in the file: voxel indices as mm");
    }
    r->meta.emplace_back("pam5_version", r->version);
    r->meta.emplace_back("peaks_per_voxel", std::to_string(r->N));
    for (const char *name : {"shm_coeff", "sphere_vertices", "odf", "gfa", "qa", "peak_indices", "B"}) {
        if (H5Lexists(ids->group.id, name, H5P_DEFAULT) <= 0) continue;
        const Id d(H5Dopen2(ids->group.id, name, H5P_DEFAULT), H5Dclose);
        if (!d.ok()) continue;
        const Id space(H5Dget_space(d.id), H5Sclose);
        std::vector<hsize_t> ext(8);
        const int rank = space.ok() ? H5Sget_simple_extent_dims(space.id, ext.data(), nullptr) : -1;
        if (rank < 0) continue;
        ext.resize(std::size_t(rank));
        r->meta.emplace_back(name, shape_text(ext));
    }
    return h;
}

std::unique_ptr<Pam5Reader> pam5_open(const std::string &path, const hz_task *) {
    auto r = std::make_unique<Pam5Reader>();
    r->path = path;
    in_child(
        "the file",
        [&](int fd) {
            Open o;
            const Header h = inspect(path, o);
            send(fd, "H", 1);
            for (std::uint64_t v : {h.X, h.Y, h.Z, h.N}) send_u64(fd, v);
            send(fd, h.affine.data(), sizeof h.affine);
            send_text(fd, h.version);
            send_u64(fd, h.meta.size());
            for (const auto &[k, v] : h.meta) send_text(fd, k), send_text(fd, v);
        },
        [&](int fd) {
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

// Reads the x plane `x` of a dataset of extents `dims` (x slowest) as doubles.
void read_plane(hid_t ds, const std::vector<hsize_t> &dims, hsize_t x, std::vector<double> &out, const char *name) {
    const Id file_space(H5Dget_space(ds), H5Sclose);
    std::vector<hsize_t> start(dims.size(), 0), count = dims;
    start[0] = x, count[0] = 1;
    if (!file_space.ok() || H5Sselect_hyperslab(file_space.id, H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr) < 0)
        throw FormatError(std::string("'pam/") + name + "': a plane cannot be selected");
    hsize_t n = 1;
    for (std::size_t i = 1; i < dims.size(); ++i) n *= dims[i];
    out.resize(n);
    const Id mem_space(H5Screate_simple(1, &n, nullptr), H5Sclose);
    if (H5Dread(ds, H5T_NATIVE_DOUBLE, mem_space.id, file_space.id, H5P_DEFAULT, out.data()) < 0)
        throw FormatError(std::string("'pam/") + name + "' cannot be read (damaged, truncated or compressed by a filter HDF5 lacks)");
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
    in_child(
        "its peaks",
        [&](int fd) {
            Open o;
            const Header again = inspect(reader.path, o);
            if (again.X != r.X || again.Y != r.Y || again.Z != r.Z || again.N != r.N)
                throw FormatError("the file changed since it was opened");
            const std::vector<hsize_t> dd = {r.X, r.Y, r.Z, r.N, 3}, vd = {r.X, r.Y, r.Z, r.N};
            std::vector<double> dirs, values;
            std::vector<float> out(plane);
            for (std::uint64_t x = 0; x < r.X; ++x) {
                read_plane(o.dirs.id, dd, x, dirs, "peak_dirs");
                read_plane(o.values.id, vd, x, values, "peak_values");
                for (std::uint64_t i = 0; i < plane; ++i) out[i] = static_cast<float>(dirs[i] * values[i / 3]);
                send(fd, "P", 1);
                send(fd, out.data(), out.size() * 4);
            }
        },
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
