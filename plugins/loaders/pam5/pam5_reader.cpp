// hz_pam5_read: the PAM5 loader's reader of HDF5 (pam5_plugin.cpp), a
// program of its own that the plugin runs (posix_spawn) for each open and
// each read: HDF5 1.10 crashes on some damaged files (a corrupted global
// heap makes H5HG_read copy past its buffer), and a crash here ends this
// program, which the plugin reports as a damaged file, not the program
// that loaded the plugin. A process of its own, rather than a fork of the
// caller, holds none of the caller's locks (a window's threads, a
// sanitizer's allocator).
//
//     hz_pam5_read open FILE             -> 'H' frame: extents, affine, version, header entries
//     hz_pam5_read read FILE X Y Z N     -> X 'P' frames: a plane of peak_dirs x peak_values each
//
// Frames go to standard output (pam5_wire.hpp); an error is an 'E' frame
// with its one-line message; standard error is not read.
#include "pam5_wire.hpp"

#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace {

using pam5wire::FormatError;
using pam5wire::Header;

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
// Bytes to the plugin; a write that fails (the plugin gone) ends the program.
void send(int fd, const void *p, std::size_t n) {
    const auto *b = static_cast<const char *>(p);
    while (n > 0) {
        const ssize_t w = ::write(fd, b, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) std::_Exit(3);  // (the plugin is gone)
        b += w, n -= std::size_t(w);
    }
}
void send_u64(int fd, std::uint64_t v) { send(fd, &v, 8); }
void send_text(int fd, const std::string &t) {
    send_u64(fd, t.size());
    send(fd, t.data(), t.size());
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

void open_mode(const std::string &path) {
    Open o;
    const Header h = inspect(path, o);
    send(1, "H", 1);
    for (std::uint64_t v : {h.X, h.Y, h.Z, h.N}) send_u64(1, v);
    send(1, h.affine.data(), sizeof h.affine);
    send_text(1, h.version);
    send_u64(1, h.meta.size());
    for (const auto &[k, v] : h.meta) send_text(1, k), send_text(1, v);
}

// The planes of the peaks, as the plugin opened them (X, Y, Z, N).
void read_mode(const std::string &path, const Header &want) {
    Open o;
    const Header r = inspect(path, o);
    if (r.X != want.X || r.Y != want.Y || r.Z != want.Z || r.N != want.N) throw FormatError("the file changed since it was opened");
    const std::vector<hsize_t> dd = {r.X, r.Y, r.Z, r.N, 3}, vd = {r.X, r.Y, r.Z, r.N};
    const std::uint64_t plane = r.Y * r.Z * r.N * 3;
    std::vector<double> dirs, values;
    std::vector<float> out(plane);
    for (std::uint64_t x = 0; x < r.X; ++x) {
        read_plane(o.dirs.id, dd, x, dirs, "peak_dirs");
        read_plane(o.values.id, vd, x, values, "peak_values");
        for (std::uint64_t i = 0; i < plane; ++i) out[i] = static_cast<float>(dirs[i] * values[i / 3]);
        send(1, "P", 1);
        send(1, out.data(), out.size() * 4);
    }
}

}  // namespace

int main(int argc, char **argv) {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // (errors are sent as frames, not printed by HDF5)
    try {
        const std::string mode = argc > 2 ? argv[1] : "";
        if (mode == "open" && argc == 3) {
            open_mode(argv[2]);
        } else if (mode == "read" && argc == 7) {
            Header h;
            h.X = std::strtoull(argv[3], nullptr, 10), h.Y = std::strtoull(argv[4], nullptr, 10);
            h.Z = std::strtoull(argv[5], nullptr, 10), h.N = std::strtoull(argv[6], nullptr, 10);
            read_mode(argv[2], h);
        } else {
            throw FormatError("usage: hz_pam5_read open FILE | read FILE X Y Z N (run by the PAM5 loader plugin)");
        }
    } catch (const std::exception &e) {
        send(1, "E", 1);
        send_text(1, e.what());
        return 1;
    }
    return 0;
}
