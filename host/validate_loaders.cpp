// `horizon validate`: the loader checks (see validate_checks.hpp).
#include "validate_checks.hpp"

#include <hz/core/render/context.hpp>

#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
#include <hz/core/phantom.hpp>

#include <boost/dll/library_info.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <iostream>
#include <random>
#include <set>
#include <sys/mman.h>
#include <unistd.h>

namespace hz::host::validation {

using nlohmann::json;

// `t` (gap 0) with one vertex holding `fill` after each streamline, as a
// mapped TCK holds its NaN delimiters (gap 1).
core::Tractogram with_gap(const core::Tractogram &t, float fill) {
    std::vector<float> pos;
    std::vector<std::uint64_t> off{0};
    for (std::uint64_t s = 0; s < t.nb_streamlines(); ++s) {
        pos.insert(pos.end(), t.positions.data() + 3 * t.begin(s), t.positions.data() + 3 * t.end(s));
        pos.insert(pos.end(), {fill, fill, fill});
        off.push_back(pos.size() / 3);
    }
    core::Tractogram g;
    g.positions = core::Buffer<float>::copy_of(pos);
    g.offsets = core::Buffer<std::uint64_t>::copy_of(off);
    g.gap = 1;
    g.reference = t.reference;
    return g;
}

namespace {

// ------------------------------------------------------------------ helpers

// Opens `file` with `l`; NULL (with err filled) when it does not open.
hz_reader *open_sample(const hz_loader &l, const fs::path &file, hz_error &err) {
    hz_open_request req{};
    req.struct_size = sizeof req;
    const std::string p = file.string();
    req.path = p.c_str();
    hz_reader *r = nullptr;
    return l.open(&req, &r, &err) == HZ_OK ? r : nullptr;
}

// A sample opened with `l` and its info read; closed when it goes. `error`
// says what failed, if anything.
struct OpenedSample {
    const hz_loader &l;
    hz_reader *r = nullptr;
    hz_dataset_info info{};
    std::string error;
    OpenedSample(const hz_loader &loader, const fs::path &file) : l(loader) {
        hz_error err = new_error();
        r = open_sample(l, file, err);
        if (r == nullptr) {
            error = std::string("sample does not open: ") + err.message;
            return;
        }
        info.struct_size = sizeof info;
        if (l.get_info(r, &info, &err) != HZ_OK) error = std::string("get_info: ") + err.message;
    }
    ~OpenedSample() {
        if (r != nullptr) l.close(r);
    }
    OpenedSample(const OpenedSample &) = delete;
    OpenedSample &operator=(const OpenedSample &) = delete;
};

// A buffer whose last byte is followed by an inaccessible page: a write or
// read past the end faults at once (the child reports "crashed").
class GuardedBuffer {
public:
    explicit GuardedBuffer(std::size_t size) : size_(size) {
        const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
        const std::size_t data_pages = (size + page - 1) / page;
        total_ = (data_pages + 1) * page;
        base_ = static_cast<unsigned char *>(::mmap(nullptr, total_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0));
        if (base_ == MAP_FAILED) throw std::bad_alloc();
        ::mprotect(base_ + data_pages * page, page, PROT_NONE);
        data_ = base_ + data_pages * page - size;
    }
    ~GuardedBuffer() { ::munmap(base_, total_); }
    unsigned char *data() { return data_; }
    std::size_t size() const { return size_; }

private:
    unsigned char *base_ = nullptr, *data_ = nullptr;
    std::size_t size_ = 0, total_ = 0;
};

std::string read_file(const fs::path &p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}
void write_file(const fs::path &p, const std::string &bytes) {
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// A small tractogram with the cases loaders get wrong: an empty streamline,
// a single point, a long one, negative and large coordinates.
core::Tractogram sample_tractogram(std::uint64_t seed) {
    core::PhantomOptions o;
    o.nb_streamlines = 40;
    o.nb_bundles = 4;
    o.seed = seed;
    o.min_length_mm = 10;
    o.max_length_mm = 60;
    core::Tractogram base = core::make_phantom(o);
    std::vector<float> pos(base.positions.begin(), base.positions.end());
    std::vector<std::uint64_t> off(base.offsets.begin(), base.offsets.end());
    off.push_back(off.back());  // empty streamline
    pos.insert(pos.end(), {-123.25f, 45.5f, 1e-3f});
    off.push_back(pos.size() / 3);  // single point
    core::Tractogram t;
    t.positions = core::Buffer<float>::copy_of(pos);
    t.offsets = core::Buffer<std::uint64_t>::copy_of(off);
    return t;
}

// Reads a streamline file through `l`; returns status, fills `t` and `msg`.
hz_status read_with(const hz_loader &l, const fs::path &file, core::Tractogram &t, std::string &msg, const hz_task *task = nullptr) {
    hz_error err = new_error();
    hz_open_request req{};
    req.struct_size = sizeof req;
    const std::string path = file.string();
    req.path = path.c_str();
    hz_reader *r = nullptr;
    hz_status st = l.open(&req, &r, &err);
    if (st != HZ_OK) {
        msg = err.message;
        if (r != nullptr) return HZ_E_INTERNAL;  // must be NULL on failure
        return st;
    }
    hz_dataset_info info{};
    info.struct_size = sizeof info;
    st = l.get_info(r, &info, &err);
    if (st == HZ_OK && info.kind != HZ_DATA_STREAMLINES) st = HZ_E_UNSUPPORTED;
    if (st == HZ_OK) {
        // A loader must not report more data than the file can hold.
        std::error_code ec;
        const auto fsize = fs::is_regular_file(file, ec) ? fs::file_size(file, ec) : UINT64_MAX;
        if (info.nb_vertices > fsize || info.nb_streamlines > fsize) {
            l.close(r);
            msg = "get_info reports " + std::to_string(info.nb_vertices) + " vertices for a " + std::to_string(fsize) + "-byte file";
            return HZ_E_INTERNAL;
        }
        t.positions = core::Buffer<float>(3 * info.nb_vertices);
        t.offsets = core::Buffer<std::uint64_t>(info.nb_streamlines + 1);
        hz_streamlines_dst dst{};
        dst.struct_size = sizeof dst;
        dst.positions = t.positions.data();
        dst.positions_capacity = t.positions.size();
        dst.offsets = t.offsets.data();
        dst.offsets_capacity = t.offsets.size();
        st = l.read_streamlines(r, &dst, task, &err);
    }
    if (st != HZ_OK) msg = err.message;
    l.close(r);
    return st;
}

// Reads a mesh file through `l`: every face index below the vertex count
// and every coordinate finite, else HZ_E_INTERNAL (an accepted file's output
// must be valid). `shrink` vertex floats less room than described (the
// buffer-too-small check: a guard page after it). Returns the status.
hz_status read_mesh_with(const hz_loader &l, const fs::path &file, std::string &msg, const hz_task *task = nullptr,
                         std::uint64_t shrink = 0) {
    hz_error err = new_error();
    hz_open_request req{};
    req.struct_size = sizeof req;
    const std::string path = file.string();
    req.path = path.c_str();
    hz_reader *r = nullptr;
    hz_status st = l.open(&req, &r, &err);
    if (st != HZ_OK) {
        msg = err.message;
        return r != nullptr ? HZ_E_INTERNAL : st;
    }
    hz_dataset_info info{};
    info.struct_size = sizeof info;
    st = l.get_info(r, &info, &err);
    if (st == HZ_OK && info.kind != HZ_DATA_MESH) st = HZ_E_UNSUPPORTED;
    if (st == HZ_OK) {
        std::error_code ec;
        const auto fsize = fs::is_regular_file(file, ec) ? fs::file_size(file, ec) : UINT64_MAX;
        if (info.nb_vertices > fsize || info.nb_faces > fsize) {
            l.close(r);
            msg = "get_info reports " + std::to_string(info.nb_vertices) + " vertices for a " + std::to_string(fsize) + "-byte file";
            return HZ_E_INTERNAL;
        }
        const std::uint64_t nv = 3 * info.nb_vertices > shrink ? 3 * info.nb_vertices - shrink : 0;
        GuardedBuffer vb(std::max<std::uint64_t>(nv, 1) * sizeof(float));
        std::vector<std::uint32_t> faces(3 * info.nb_faces);
        hz_mesh_dst dst{};
        dst.struct_size = sizeof dst;
        dst.vertices = reinterpret_cast<float *>(vb.data());
        dst.vertices_capacity = nv;
        dst.faces = faces.data();
        dst.faces_capacity = faces.size();
        st = l.read_mesh(r, &dst, task, &err);
        if (st == HZ_OK && shrink == 0) {
            const float *v = dst.vertices;
            for (std::uint64_t i = 0; i < 3 * info.nb_vertices; ++i)
                if (!std::isfinite(v[i])) {
                    l.close(r);
                    msg = "accepted input: non-finite coordinate at vertex " + std::to_string(i / 3);
                    return HZ_E_INTERNAL;
                }
            for (std::uint32_t f : faces)
                if (f >= info.nb_vertices) {
                    l.close(r);
                    msg = "accepted input: face index " + std::to_string(f) + " of " + std::to_string(info.nb_vertices) + " vertices";
                    return HZ_E_INTERNAL;
                }
        }
    }
    if (st != HZ_OK && msg.empty()) msg = err.message;
    l.close(r);
    return st;
}

// The kind of data a sample holds (0 when it does not open).
hz_data_kind sample_kind(const hz_loader &l, const fs::path &file) {
    const OpenedSample s(l, file);
    return s.error.empty() ? s.info.kind : 0;
}

// Reads a volume file through `l` (raw dtype); returns status, fills `v`.
hz_status read_volume_with(const hz_loader &l, const fs::path &file, core::Volume &v, std::string &msg, const hz_task *task = nullptr,
                           std::int64_t shrink_capacity = 0) {
    hz_error err = new_error();
    hz_open_request req{};
    req.struct_size = sizeof req;
    const std::string path = file.string();
    req.path = path.c_str();
    hz_reader *r = nullptr;
    hz_status st = l.open(&req, &r, &err);
    if (st != HZ_OK) {
        msg = err.message;
        return r != nullptr ? HZ_E_INTERNAL : st;
    }
    hz_dataset_info info{};
    info.struct_size = sizeof info;
    st = l.get_info(r, &info, &err);
    if (st == HZ_OK && (info.kind != HZ_DATA_VOLUME || info.ndim < 1 || info.ndim > 7 || core::dtype_size(info.dtype) == 0)) {
        msg = "get_info describes no valid volume";
        l.close(r);
        return HZ_E_INTERNAL;
    }
    if (st == HZ_OK) {
        std::uint64_t n = 1;
        for (uint32_t i = 0; i < info.ndim; ++i) n *= info.dims[i];
        if (n > (std::uint64_t(1) << 32)) {  // a few validator fixtures are tiny; refuse to follow absurd claims
            msg = "volume too large for the validator";
            l.close(r);
            return HZ_E_FORMAT;
        }
        v.dtype = info.dtype;
        v.dims.assign(info.dims, info.dims + info.ndim);
        v.voxels = core::Buffer<std::byte>(n * core::dtype_size(info.dtype));
        std::copy(std::begin(info.voxel_to_ras), std::end(info.voxel_to_ras), v.voxel_to_ras.begin());
        hz_array_view dst = core::volume_view(v);
        dst.capacity_bytes -= static_cast<std::uint64_t>(shrink_capacity);
        if (shrink_capacity) {  // put the end of the view right before an inaccessible page
            GuardedBuffer g(dst.capacity_bytes);
            dst.data = g.data();
            st = l.read_volume(r, &dst, task, &err);
        } else {
            st = l.read_volume(r, &dst, task, &err);
        }
    }
    if (st != HZ_OK) msg = err.message;
    l.close(r);
    return st;
}

bool same_tractogram(const core::Tractogram &a, const core::Tractogram &b, std::string &why) {
    if (a.nb_streamlines() != b.nb_streamlines() || a.nb_vertices() != b.nb_vertices()) {
        why = "counts differ: " + std::to_string(a.nb_streamlines()) + "/" + std::to_string(a.nb_vertices()) + " vs " +
              std::to_string(b.nb_streamlines()) + "/" + std::to_string(b.nb_vertices());
        return false;
    }
    if (!std::equal(a.offsets.begin(), a.offsets.end(), b.offsets.begin())) {
        why = "offsets differ";
        return false;
    }
    for (std::size_t i = 0; i < a.positions.size(); ++i)
        if (std::fabs(double(a.positions[i]) - double(b.positions[i])) > 1e-3) {
            why = "vertex " + std::to_string(i / 3) + " differs by more than 1e-3 mm";
            return false;
        }
    return true;
}

bool writes_streamlines(const hz_loader &l) {
    return (l.caps & HZ_LOADER_CAN_WRITE) && l.write != nullptr && (l.data_kinds & HZ_DATA_STREAMLINES);
}
bool writes_volumes(const hz_loader &l) {
    return (l.caps & HZ_LOADER_CAN_WRITE) && l.write != nullptr && (l.data_kinds & HZ_DATA_VOLUME) && l.read_volume != nullptr;
}

// A small int16 volume with an oblique affine.
core::Volume sample_volume() {
    core::Volume v;
    v.dtype = HZ_DTYPE_I16;
    v.dims = {5, 4, 3};
    v.voxels = core::Buffer<std::byte>(60 * 2);
    for (int i = 0; i < 60; ++i) {
        const std::int16_t x = static_cast<std::int16_t>(i * 7 - 50);
        std::memcpy(v.voxels.data() + 2 * i, &x, 2);
    }
    v.voxel_to_ras = {-1.5, 0.2, 0, 30, 0.1, 2, 0.3, -20, 0, -0.2, 2.5, 10, 0, 0, 0, 1};
    return v;
}

// Writes `v` with the plugin's own writer to scratch/sample.<first extension>;
// returns the path, or empty with `msg` set.
// With `selected`, through hz_ext_write_selection.write_selection instead.
fs::path write_view(const Ctx &c, const hz_dataset_view &v, std::string &msg, const hz_ext_write_selection *selective = nullptr,
                    const std::vector<std::uint64_t> *selected = nullptr) {
    const hz_loader &l = loader_of(c);
    const std::string ext = l.extensions && l.extensions[0] ? l.extensions[0] : "dat";
    const fs::path out = c.scratch / ((selected ? "selected." : "sample.") + ext);
    hz_write_request req{};
    req.struct_size = sizeof req;
    const std::string p = out.string();
    req.path = p.c_str();
    req.extension = ext.c_str();
    req.final_path = p.c_str();  // written in place: companions stay where the plugin put them
    req.add_companion = [](void *, const char *t, const char *f) -> hz_status { return t && f ? HZ_OK : HZ_E_INVALID_ARGUMENT; };
    hz_error err = new_error();
    const hz_status st = selected != nullptr ? selective->write_selection(&req, &v, selected->data(), selected->size(), nullptr, &err)
                                             : l.write(&req, &v, nullptr, &err);
    if (st != HZ_OK) {
        msg = std::string("write failed (status ") + std::to_string(st) + "): " + err.message;
        return {};
    }
    return out;
}

fs::path write_volume_sample(const Ctx &c, const core::Volume &vol, std::string &msg) {
    hz_dataset_view v{};
    v.struct_size = sizeof v;
    v.kind = HZ_DATA_VOLUME;
    v.voxels = core::volume_view(vol);
    std::copy(vol.voxel_to_ras.begin(), vol.voxel_to_ras.end(), v.voxel_to_ras);
    v.volume_ndim = static_cast<uint32_t>(vol.dims.size());
    std::copy(vol.dims.begin(), vol.dims.end(), v.volume_dims);
    v.scale_slope = 1;
    v.scale_inter = 0;
    return write_view(c, v, msg);
}

// Reads any file the loader accepts; checks the result's invariants.
hz_status read_any(const hz_loader &l, const fs::path &file, std::string &msg) {
    if (l.read_streamlines && (l.data_kinds & HZ_DATA_STREAMLINES)) {
        core::Tractogram t;
        const hz_status st = read_with(l, file, t, msg);
        if (st == HZ_OK) t.validate("accepted input");
        if (st != HZ_E_UNSUPPORTED) return st;
    }
    if (l.read_volume && (l.data_kinds & HZ_DATA_VOLUME)) {
        core::Volume v;
        const hz_status st = read_volume_with(l, file, v, msg);
        if (st != HZ_E_UNSUPPORTED) return st;
    }
    if (l.read_mesh && (l.data_kinds & HZ_DATA_MESH)) {
        msg.clear();
        const hz_status st = read_mesh_with(l, file, msg);
        if (st != HZ_E_UNSUPPORTED) return st;
    }
    msg = "no reader for this kind";
    return HZ_E_UNSUPPORTED;
}

// Writes `t` with the plugin's own writer to scratch/sample.<ext>.
fs::path write_sample(const Ctx &c, const core::Tractogram &t, std::string &msg) {
    hz_dataset_view v{};
    v.struct_size = sizeof v;
    v.kind = HZ_DATA_STREAMLINES;
    v.streamlines = t.view();
    std::copy(t.reference.begin(), t.reference.end(), v.voxel_to_ras);
    return write_view(c, v, msg);
}

// Files to exercise a loader with: those given by --data, else one it wrote.
std::vector<fs::path> loader_samples(const Ctx &c, std::string &msg) {
    std::vector<fs::path> files(c.opts.data_files.begin(), c.opts.data_files.end());
    if (files.empty() && writes_streamlines(loader_of(c))) {
        const fs::path p = write_sample(c, sample_tractogram(c.opts.seed), msg);
        if (!p.empty()) files.push_back(p);
    } else if (files.empty() && writes_volumes(loader_of(c))) {
        const fs::path p = write_volume_sample(c, sample_volume(), msg);
        if (!p.empty()) files.push_back(p);
    }
    return files;
}

}  // namespace

void add_loader_checks(std::vector<Check> &c) {
    c.push_back({"loader-extensions-wellformed", HZ_KIND_LOADER, "extensions are lowercase, without dot, non-empty", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (l.extensions == nullptr || l.extensions[0] == nullptr) return fail("no extensions");
                     for (auto e = l.extensions; *e; ++e) {
                         const std::string s = *e;
                         if (s.empty() || s[0] == '.') return fail("extension '" + s + "' is empty or starts with a dot");
                         for (char ch : s)
                             if (!(std::islower(static_cast<unsigned char>(ch)) || std::isdigit(static_cast<unsigned char>(ch)) ||
                                   ch == '.' || ch == '_'))
                                 return fail("extension '" + s + "' is not lowercase [a-z0-9._]");
                     }
                     if ((l.caps & HZ_LOADER_CAN_READ) && (!l.open || !l.get_info || !l.close || !l.probe))
                         return fail("CAN_READ without open/get_info/close/probe");
                     if ((l.caps & HZ_LOADER_CAN_WRITE) && !l.write) return fail("CAN_WRITE without write");
                     if ((l.data_kinds & HZ_DATA_STREAMLINES) && (l.caps & HZ_LOADER_CAN_READ) && !l.read_streamlines)
                         return fail("reads streamlines without read_streamlines");
                     if (l.probe_bytes > 65536) return fail("probe_bytes > 65536");
                     return pass();
                 }});
    c.push_back(
        {"loader-probe-purity", HZ_KIND_LOADER, "probe is deterministic, in [0,100], never reads past head_size", [](const Ctx &x) {
             const hz_loader &l = loader_of(x);
             if (!l.probe) return skip("no probe");
             std::mt19937_64 rng(x.opts.seed);
             std::string msg;
             std::vector<std::string> heads = {std::string(), std::string("\0", 1), std::string(4096, '\0'), std::string(4096, '\xff')};
             for (int k = 0; k < 64; ++k) {
                 std::string r(rng() % 2048, '\0');
                 for (auto &ch : r) ch = static_cast<char>(rng());
                 heads.push_back(r);
             }
             for (const auto &f : loader_samples(x, msg)) heads.push_back(read_file(f).substr(0, std::max<uint32_t>(l.probe_bytes, 1)));
             for (const auto &h : heads)
                 for (std::size_t len = 0; len <= h.size(); len += (len < 64 ? 1 : 97)) {
                     GuardedBuffer b(len);  // ends right before an inaccessible page
                     std::memcpy(b.data(), h.data(), len);
                     const int32_t s1 = l.probe(b.data(), len, "sample");
                     const int32_t s2 = l.probe(b.data(), len, "sample");
                     if (s1 != s2) return fail("probe is not deterministic");
                     if (s1 < 0 || s1 > 100) return fail("probe returned " + std::to_string(s1));
                 }
             return pass(std::to_string(heads.size()) + " heads at every length");
         }});
    c.push_back({"loader-probe-positive", HZ_KIND_LOADER, "probe scores >= 50 on valid samples, < 50 on random bytes", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     std::string msg;
                     const auto files = loader_samples(x, msg);
                     if (files.empty()) return skip("no sample file (pass --data FILE)" + (msg.empty() ? "" : ": " + msg));
                     for (const auto &f : files) {
                         const std::string h = read_file(f).substr(0, std::max<uint32_t>(l.probe_bytes, 1));
                         const int32_t s = l.probe(reinterpret_cast<const uint8_t *>(h.data()), h.size(), f.filename().c_str());
                         if (s < 50) return fail("probe gives " + std::to_string(s) + " for valid sample " + f.string());
                     }
                     std::mt19937_64 rng(x.opts.seed);
                     std::string r(4096, '\0');
                     for (auto &ch : r) ch = static_cast<char>(rng());
                     const int32_t s = l.probe(reinterpret_cast<const uint8_t *>(r.data()), r.size(), "random.bin");
                     if (s >= 50) return fail("probe gives " + std::to_string(s) + " for random bytes");
                     return pass();
                 }});
    c.push_back({"loader-open-missing-file", HZ_KIND_LOADER, "opening a missing file fails with a message naming it", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!l.open) return skip("cannot read");
                     const std::string p = (x.scratch / "does-not-exist.dat").string();
                     hz_open_request req{};
                     req.struct_size = sizeof req;
                     req.path = p.c_str();
                     hz_reader *r = nullptr;
                     hz_error err = new_error();
                     const hz_status st = l.open(&req, &r, &err);
                     if (st == HZ_OK) {
                         l.close(r);
                         return fail("open succeeded on a missing file");
                     }
                     if (r != nullptr) return fail("open failed but left *out non-NULL");
                     if (std::string(err.message).find("does-not-exist.dat") == std::string::npos)
                         return fail("error message does not name the file: '" + std::string(err.message) + "'");
                     return pass();
                 }});
    c.push_back({"loader-roundtrip", HZ_KIND_LOADER, "write then read gives the same streamlines (empty and 1-point ones included)",
                 [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!writes_streamlines(l) && writes_volumes(l)) {
                         const core::Volume vol = sample_volume();
                         std::string msg;
                         const fs::path p = write_volume_sample(x, vol, msg);
                         if (p.empty()) return fail(msg);
                         core::Volume back;
                         if (read_volume_with(l, p, back, msg) != HZ_OK) return fail("reading its own output failed: " + msg);
                         if (back.dims != vol.dims || back.dtype != vol.dtype) return fail("dims or dtype changed");
                         if (std::memcmp(back.voxels.data(), vol.voxels.data(), vol.voxels.size()) != 0) return fail("voxels changed");
                         for (int i = 0; i < 16; ++i)
                             if (std::fabs(back.voxel_to_ras[i] - vol.voxel_to_ras[i]) > 1e-5) return fail("affine changed");
                         return pass("5x4x3 int16 volume, oblique affine");
                     }
                     if (!writes_streamlines(l)) return skip("does not write streamlines or volumes");
                     const core::Tractogram t = sample_tractogram(x.opts.seed);
                     std::string msg;
                     const fs::path p = write_sample(x, t, msg);
                     if (p.empty()) return fail(msg);
                     core::Tractogram back;
                     if (read_with(l, p, back, msg) != HZ_OK) return fail("reading its own output failed: " + msg);
                     if (!same_tractogram(t, back, msg)) return fail(msg);
                     return pass(std::to_string(t.nb_streamlines()) + " streamlines");
                 }});
    c.push_back({"loader-writes-gap", HZ_KIND_LOADER,
                 "a writer offering HZ_EXT_DELIMITED_STREAMLINES skips the vertex after each streamline, NaN or not", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!extension_of<hz_ext_delimited_streamlines>(x, HZ_EXT_DELIMITED_STREAMLINES))
                         return skip("does not offer HZ_EXT_DELIMITED_STREAMLINES");
                     if (!writes_streamlines(l)) return fail("offers HZ_EXT_DELIMITED_STREAMLINES without writing streamlines");
                     const core::Tractogram t = sample_tractogram(x.opts.seed);
                     for (const float fill : {std::numeric_limits<float>::quiet_NaN(), 1234.5f}) {
                         const std::string what = std::isnan(fill) ? "NaN" : "finite";
                         std::string msg;
                         const fs::path p = write_sample(x, with_gap(t, fill), msg);
                         if (p.empty()) return fail("with gap 1 (" + what + " gap vertices): " + msg);
                         core::Tractogram back;
                         if (read_with(l, p, back, msg) != HZ_OK) return fail("reading its own output failed: " + msg);
                         if (!same_tractogram(t, back, msg))
                             return fail("written with gap 1 (" + what + " gap vertices), read back: " + msg);
                     }
                     return pass(std::to_string(t.nb_streamlines()) + " streamlines with NaN and with finite gap vertices");
                 }});
    c.push_back({"loader-writes-selection", HZ_KIND_LOADER,
                 "a writer offering HZ_EXT_WRITE_SELECTION writes exactly the selected streamlines, in order", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     const auto *ws = extension_of<hz_ext_write_selection>(x, HZ_EXT_WRITE_SELECTION);
                     if (ws == nullptr) return skip("does not offer HZ_EXT_WRITE_SELECTION");
                     if (!writes_streamlines(l)) return fail("offers HZ_EXT_WRITE_SELECTION without writing streamlines");
                     const core::Tractogram t = sample_tractogram(x.opts.seed);
                     const std::uint64_t N = t.nb_streamlines();
                     // About half, at random, with the first and the last two
                     // (the empty streamline and the single point); none; all.
                     std::mt19937_64 rng(x.opts.seed + 7);
                     std::vector<std::uint64_t> half{0};
                     for (std::uint64_t s = 1; s + 2 < N; ++s)
                         if (rng() % 2) half.push_back(s);
                     half.insert(half.end(), {N - 2, N - 1});
                     std::vector<std::uint64_t> all(N);
                     std::iota(all.begin(), all.end(), std::uint64_t(0));
                     const bool gap = extension_of<hz_ext_delimited_streamlines>(x, HZ_EXT_DELIMITED_STREAMLINES) != nullptr;
                     const core::Tractogram delimited = with_gap(t, std::numeric_limits<float>::quiet_NaN());
                     int written = 0;
                     for (const std::vector<std::uint64_t> *sel : {&half, &all, static_cast<std::vector<std::uint64_t> *>(nullptr)}) {
                         const std::vector<std::uint64_t> none;
                         const std::vector<std::uint64_t> &ids = sel ? *sel : none;
                         const std::string what = std::to_string(ids.size()) + " of " + std::to_string(N) + " streamlines";
                         for (const core::Tractogram *src : {&t, gap ? &delimited : nullptr}) {
                             if (src == nullptr) continue;
                             hz_dataset_view v{};
                             v.struct_size = sizeof v;
                             v.kind = HZ_DATA_STREAMLINES;
                             v.streamlines = src->view();
                             std::copy(t.reference.begin(), t.reference.end(), v.voxel_to_ras);
                             std::string msg;
                             const fs::path p = write_view(x, v, msg, ws, &ids);
                             const std::string how = what + (src->gap ? " (gap 1)" : "");
                             if (p.empty()) return fail("writing " + how + ": " + msg);
                             core::Tractogram back;
                             if (read_with(l, p, back, msg) != HZ_OK) return fail("reading " + how + " back failed: " + msg);
                             if (!same_tractogram(core::select_streamlines(t, ids), back, msg)) return fail(how + ", read back: " + msg);
                             ++written;
                         }
                     }
                     return pass(std::to_string(written) + " selections (about half, all, none" + (gap ? "; with and without gap" : "") +
                                 ") of " + std::to_string(N) + " streamlines read back as selected");
                 }});
    c.push_back({"loader-malformed-survival", HZ_KIND_LOADER,
                 "truncated and corrupted samples fail cleanly (no crash, message, valid output when accepted)", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!l.read_streamlines && !l.read_volume && !l.read_mesh) return skip("reads no streamlines, volumes or meshes");
                     std::string msg;
                     const auto files = loader_samples(x, msg);
                     if (files.empty()) return skip("no sample file (pass --data FILE)");
                     std::mt19937_64 rng(x.opts.seed);
                     int variants = 0, rejected = 0;
                     const fs::path bad = x.scratch / ("malformed." + std::string(l.extensions[0]));
                     auto try_one = [&](const std::string &bytes) -> std::optional<Outcome> {
                         write_file(bad, bytes);
                         std::string m;
                         hz_status st;
                         try {
                             st = read_any(l, bad, m);
                         } catch (const std::exception &e) {
                             return fail(e.what());
                         }
                         ++variants;
                         if (st == HZ_E_INTERNAL) return fail("internal error on malformed input: " + m);
                         if (st != HZ_OK) {
                             ++rejected;
                             if (m.empty()) return fail("rejected a malformed file without a message");
                             if (m.find('\n') != std::string::npos) return fail("error message is not one line: " + m);
                             if (m.find(bad.filename().string()) == std::string::npos)
                                 return fail("error message does not name the file: " + m);
                             return std::nullopt;
                         }
                         return std::nullopt;
                     };
                     for (const auto &f : files) {
                         const std::string good = read_file(f);
                         // Truncations: every byte of the first 512, then spread over the file.
                         for (std::size_t cut = 0; cut < good.size(); cut += (cut < 512 ? 1 : std::max<std::size_t>(1, good.size() / 200)))
                             if (auto o = try_one(good.substr(0, cut))) return *o;
                         // Random corruption.
                         for (int k = 0; k < 300; ++k) {
                             std::string b = good;
                             const int flips = 1 + int(rng() % 8);
                             for (int i = 0; i < flips && !b.empty(); ++i) b[rng() % b.size()] = static_cast<char>(rng());
                             if (auto o = try_one(b)) return *o;
                         }
                     }
                     return pass(std::to_string(variants) + " variants, " + std::to_string(rejected) + " rejected cleanly");
                 }});
    c.push_back({"loader-buffer-too-small", HZ_KIND_LOADER, "a short destination gives HZ_E_BUFFER_TOO_SMALL and no write past it",
                 [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     std::string msg;
                     if (l.read_mesh) {
                         const auto files = loader_samples(x, msg);
                         if (!files.empty() && sample_kind(l, files[0]) == HZ_DATA_MESH) {
                             const hz_status st = read_mesh_with(l, files[0], msg, nullptr, 1);
                             if (st != HZ_E_BUFFER_TOO_SMALL)
                                 return fail("read_mesh: status " + std::to_string(st) + " instead of HZ_E_BUFFER_TOO_SMALL");
                             return pass("read_mesh");
                         }
                     }
                     if (!l.read_streamlines && l.read_volume) {
                         const auto files = loader_samples(x, msg);
                         if (files.empty()) return skip("no sample file");
                         core::Volume v;
                         const hz_status st = read_volume_with(l, files[0], v, msg, nullptr, 1);
                         if (st != HZ_E_BUFFER_TOO_SMALL) return fail("status " + std::to_string(st) + " instead of HZ_E_BUFFER_TOO_SMALL");
                         return pass();
                     }
                     if (!l.read_streamlines) return skip("no read_streamlines");
                     const auto files = loader_samples(x, msg);
                     if (files.empty()) return skip("no sample file");
                     hz_error err = new_error();
                     hz_reader *r = open_sample(l, files[0], err);
                     if (r == nullptr) return fail(std::string("sample does not open: ") + err.message);
                     hz_dataset_info info{};
                     info.struct_size = sizeof info;
                     l.get_info(r, &info, &err);
                     if (info.nb_vertices == 0) {
                         l.close(r);
                         return skip("sample has no vertices");
                     }
                     GuardedBuffer pos((3 * info.nb_vertices - 1) * sizeof(float));
                     GuardedBuffer off((info.nb_streamlines + 1) * sizeof(uint64_t));
                     hz_streamlines_dst dst{};
                     dst.struct_size = sizeof dst;
                     dst.positions = reinterpret_cast<float *>(pos.data());
                     dst.positions_capacity = 3 * info.nb_vertices - 1;
                     dst.offsets = reinterpret_cast<uint64_t *>(off.data());
                     dst.offsets_capacity = info.nb_streamlines + 1;
                     const hz_status st = l.read_streamlines(r, &dst, nullptr, &err);
                     l.close(r);
                     if (st != HZ_E_BUFFER_TOO_SMALL) return fail("status " + std::to_string(st) + " instead of HZ_E_BUFFER_TOO_SMALL");
                     return pass();
                 }});
    c.push_back({"loader-cancel", HZ_KIND_LOADER,
                 "a read handed a cancelled task returns HZ_E_CANCELLED, or finishes when it is short (under ~50 ms of work: hz_task "
                 "lets it skip polling); close() still works",
                 [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!l.read_streamlines && !l.read_volume && !l.read_mesh) return skip("reads no streamlines, volumes or meshes");
                     std::string msg;
                     const auto files = loader_samples(x, msg);
                     if (files.empty()) return skip("no sample file");
                     core::Task task;
                     task.cancel();
                     core::Tractogram t;
                     core::Volume v;
                     const bool mesh = l.read_mesh && sample_kind(l, files[0]) == HZ_DATA_MESH;
                     const char *call = mesh ? "read_mesh" : l.read_streamlines ? "read_streamlines" : "read_volume";
                     const auto t0 = std::chrono::steady_clock::now();
                     const hz_status st = mesh                 ? read_mesh_with(l, files[0], msg, task.get())
                                          : l.read_streamlines ? read_with(l, files[0], t, msg, task.get())
                                                               : read_volume_with(l, files[0], v, msg, task.get());
                     const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
                     if (st == HZ_E_CANCELLED) return pass();
                     if (st != HZ_OK)
                         return fail(std::string(call) + " with a cancelled task returned status " + std::to_string(st) + " (" + msg +
                                     "): expected HZ_E_CANCELLED, or HZ_OK for a short read");
                     // (open, get_info and the read together: a bound on the read's work)
                     if (ms > 250)
                         return fail(std::string(call) + " with a cancelled task ran " + std::to_string(int(ms)) +
                                     " ms and returned HZ_OK: hz_task asks a call to poll at least every ~50 ms of work");
                     return pass(std::string(call) + " finished its short read (" + std::to_string(int(ms)) +
                                 " ms) without polling: allowed under ~50 ms");
                 }});

    c.push_back({"loader-open-task", HZ_KIND_LOADER,
                 "HZ_EXT_OPEN_TASK, when offered, opens as open() does, reports fractions in [0, 1] that never decrease, and stops "
                 "when cancelled",
                 [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     const auto *ot = extension_of<hz_ext_open_task>(x, HZ_EXT_OPEN_TASK);
                     if (ot == nullptr) return skip("does not offer HZ_EXT_OPEN_TASK");
                     if (!ot->open) return fail("HZ_EXT_OPEN_TASK table with a NULL function");
                     std::string msg;
                     const auto files = loader_samples(x, msg);
                     if (files.empty()) return skip("no sample file");
                     const OpenedSample plain(l, files[0]);
                     if (!plain.error.empty()) return skip(plain.error);
                     hz_open_request req{};
                     req.struct_size = sizeof req;
                     const std::string path = files[0].string();
                     req.path = path.c_str();
                     // Opened with a task: the same description, and sane reports.
                     core::Task task;
                     std::vector<double> reports;
                     task.on_progress = [&](double f, const char *) { reports.push_back(f); };
                     hz_error err = new_error();
                     hz_reader *r = nullptr;
                     if (ot->open(&req, task.get(), &r, &err) != HZ_OK || r == nullptr)
                         return fail(std::string("open with a task fails where open() succeeds: ") + err.message);
                     hz_dataset_info info{};
                     info.struct_size = sizeof info;
                     const hz_status st = l.get_info(r, &info, &err);
                     l.close(r);
                     if (st != HZ_OK) return fail(std::string("get_info after open with a task: ") + err.message);
                     if (info.kind != plain.info.kind || info.nb_streamlines != plain.info.nb_streamlines ||
                         info.nb_vertices != plain.info.nb_vertices || info.nb_faces != plain.info.nb_faces ||
                         std::memcmp(info.dims, plain.info.dims, sizeof info.dims) != 0)
                         return fail("open with a task describes the file otherwise than open()");
                     for (std::size_t i = 0; i < reports.size(); ++i) {
                         if (!(reports[i] >= 0 && reports[i] <= 1)) return fail("reports fraction " + std::to_string(reports[i]));
                         if (i > 0 && reports[i] < reports[i - 1]) return fail("reported fractions decrease");
                     }
                     // And with a task cancelled before the call.
                     core::Task cancelled;
                     cancelled.cancel();
                     err = new_error();
                     r = nullptr;
                     const hz_status cst = ot->open(&req, cancelled.get(), &r, &err);
                     if (r != nullptr) l.close(r);
                     if (cst != HZ_E_CANCELLED)
                         return fail("status " + std::to_string(cst) + " instead of HZ_E_CANCELLED for a cancelled task");
                     if (r != nullptr) return fail("a cancelled open gives a reader");
                     return pass(std::to_string(reports.size()) + " progress reports; a cancelled task stops it");
                 }});

    c.push_back(
        {"loader-locate-positions", HZ_KIND_LOADER,
         "HZ_EXT_MAPPED_POSITIONS, when offered, names bytes equal to what read_streamlines gives, and read_offsets agrees",
         [](const Ctx &x) {
             const hz_loader &l = loader_of(x);
             const auto *m = extension_of<hz_ext_mapped_positions>(x, HZ_EXT_MAPPED_POSITIONS);
             if (m == nullptr) return skip("does not offer HZ_EXT_MAPPED_POSITIONS");
             if (!m->locate_positions || !m->read_offsets) return fail("HZ_EXT_MAPPED_POSITIONS table with a NULL function");
             if (!l.read_streamlines) return fail("HZ_EXT_MAPPED_POSITIONS without read_streamlines");
             std::string msg;
             const auto files = loader_samples(x, msg);
             if (files.empty()) return skip("no sample file");
             core::Tractogram full;
             if (read_with(l, files[0], full, msg) != HZ_OK) return skip("sample does not read: " + msg);
             const OpenedSample sample(l, files[0]);
             if (!sample.error.empty()) return fail(sample.error);
             hz_reader *r = sample.r;
             const hz_dataset_info &info = sample.info;
             hz_error err = new_error();
             {  // Offsets before any extent was located: refused, nothing written.
                 std::vector<std::uint64_t> off(info.nb_streamlines + 1, 7);
                 if (m->read_offsets(r, off.data(), off.size(), nullptr, &err) == HZ_OK)
                     return fail("read_offsets answers HZ_OK before locate_positions");
                 err = new_error();
             }
             // Asked without, then with, the delimited layout, then also
             // offering to take vouched bounds, then also unaligned offsets:
             // never a layout the host did not accept; a delimited extent
             // holds each streamline's bytes followed by an all-NaN delimiter
             // vertex; vouched bounds are the exact bounds.
             std::string how;
             const hz_extent_flags kDelimited = HZ_EXTENT_DELIMITED, kChecked = HZ_EXTENT_DELIMITED | HZ_EXTENT_CHECKED;
             for (const hz_extent_flags accepts : {hz_extent_flags(0), kDelimited, kChecked, kChecked | HZ_EXTENT_UNALIGNED}) {
                 hz_positions_extent ext{};
                 ext.struct_size = sizeof ext;
                 ext.accepts = accepts;
                 const hz_status st = m->locate_positions(r, &ext, &err);
                 if (st == HZ_E_UNSUPPORTED) {
                     if (accepts == 0)
                         how += " declines the plain layout;";
                     else if (accepts == kDelimited)
                         how += " declines the delimited layout too;";
                     continue;
                 }
                 if (st != HZ_OK) return fail("status " + std::to_string(st) + ": " + err.message);
                 if ((ext.flags & ~accepts & ~hz_extent_flags(HZ_EXTENT_HAS_CRC32)) != 0)
                     return fail("answers with a layout flag the host did not accept");
                 if (ext.path == nullptr) return fail("HZ_OK with a NULL path");
                 const bool unaligned = (ext.flags & HZ_EXTENT_UNALIGNED) != 0;
                 if (ext.offset % 4 != 0 && !unaligned)
                     return fail("offset " + std::to_string(ext.offset) + " is not a multiple of 4 (and HZ_EXTENT_UNALIGNED not set)");
                 if (ext.offset % 4 == 0 && unaligned)
                     return fail("HZ_EXTENT_UNALIGNED set for offset " + std::to_string(ext.offset) + ", a multiple of 4");
                 if (unaligned) how += " maps an unaligned extent;";
                 const bool delimited = (ext.flags & HZ_EXTENT_DELIMITED) != 0;
                 const std::uint64_t stored_vertices = info.nb_vertices + (delimited ? info.nb_streamlines : 0);
                 const std::uint64_t bytes = stored_vertices * 12;
                 std::ifstream in(ext.path, std::ios::binary);
                 std::string stored(bytes, '\0');
                 in.seekg(static_cast<std::streamoff>(ext.offset));
                 if (!in.read(stored.data(), static_cast<std::streamsize>(bytes)))
                     return fail(std::string("the extent lies past the end of ") + ext.path);
                 if ((ext.flags & HZ_EXTENT_HAS_CRC32) && crc32_z(0, reinterpret_cast<const Bytef *>(stored.data()), bytes) != ext.crc32)
                     return fail("the CRC-32 given does not match the located bytes");
                 core::Buffer<std::uint64_t> off(info.nb_streamlines + 1);
                 if (info.nb_streamlines > 0 && m->read_offsets(r, off.data(), off.size() - 1, nullptr, &err) == HZ_OK)
                     return fail("read_offsets answers HZ_OK into a destination one entry short");
                 err = new_error();
                 if (m->read_offsets(r, off.data(), off.size(), nullptr, &err) != HZ_OK)
                     return fail(std::string("read_offsets fails: ") + err.message);
                 if (!delimited) {
                     if (full.positions.size() * 4 != bytes || std::memcmp(stored.data(), full.positions.data(), bytes) != 0)
                         return fail("the located bytes differ from read_streamlines' positions");
                     if (!std::equal(off.begin(), off.end(), full.offsets.begin())) return fail("read_offsets gives other offsets");
                     if (accepts == 0) how += " maps the plain layout;";
                     continue;
                 }
                 if (off[0] != 0 || off[info.nb_streamlines] != stored_vertices) return fail("delimited offsets do not span the extent");
                 for (std::uint64_t k = 0; k < info.nb_streamlines; ++k) {
                     if (off[k + 1] <= off[k] || off[k + 1] - off[k] - 1 != full.size(k))
                         return fail("delimited offsets give streamline " + std::to_string(k) + " another length");
                     if (std::memcmp(stored.data() + 12 * off[k], full.positions.data() + 3 * full.begin(k), 12 * full.size(k)) != 0)
                         return fail("the located bytes of streamline " + std::to_string(k) + " differ from read_streamlines'");
                     float d[3];
                     std::memcpy(d, stored.data() + 12 * (off[k + 1] - 1), 12);
                     if (!(std::isnan(d[0]) && std::isnan(d[1]) && std::isnan(d[2])))
                         return fail("the delimiter after streamline " + std::to_string(k) + " is not all NaN");
                 }
                 if (accepts == kDelimited) how += " maps the delimited layout;";
                 if (ext.flags & HZ_EXTENT_CHECKED) {
                     // Every coordinate finite (the delimiters were checked above).
                     core::Bounds b;
                     try {
                         b = core::finite_bounds(full.positions.data(), full.nb_vertices(), "the sample");
                     } catch (const std::exception &e) {
                         return fail(std::string("vouches for positions that are not all finite: ") + e.what());
                     }
                     for (int d = 0; d < 3; ++d)
                         if (b.empty || ext.bounds_min[d] != b.min[d] || ext.bounds_max[d] != b.max[d])
                             return fail("vouches for bounds other than its positions' (" + std::string("xyz").substr(d, 1) + ")");
                     if (how.find(" vouches for exact bounds;") == std::string::npos) how += " vouches for exact bounds;";
                 }
             }
             how.pop_back();
             return pass(how.substr(1));
         }});

    c.push_back({"loader-vouched-positions", HZ_KIND_LOADER,
                 "HZ_EXT_CHECKED_READ, when offered, reads what read_streamlines reads and vouches exactly, only into a record with room",
                 [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     const auto *cr = extension_of<hz_ext_checked_read>(x, HZ_EXT_CHECKED_READ);
                     if (cr == nullptr) return skip("does not offer HZ_EXT_CHECKED_READ");
                     if (!cr->read_streamlines_checked) return fail("HZ_EXT_CHECKED_READ table with a NULL function");
                     if (!l.read_streamlines) return fail("HZ_EXT_CHECKED_READ without read_streamlines");
                     std::string msg;
                     const auto files = loader_samples(x, msg);
                     if (files.empty()) return skip("no sample file");
                     core::Tractogram plain;
                     if (read_with(l, files[0], plain, msg) != HZ_OK) return skip("sample does not read: " + msg);
                     // Each ask on a fresh reader: a full check record, and one
                     // whose struct_size has no room (the loader must not write it).
                     std::string how;
                     for (const bool room : {true, false}) {
                         const OpenedSample sample(l, files[0]);
                         if (!sample.error.empty()) return fail(sample.error);
                         const hz_dataset_info &info = sample.info;
                         hz_error err = new_error();
                         if (info.kind != HZ_DATA_STREAMLINES) return skip("sample holds no streamlines");
                         core::Tractogram t;
                         t.positions = core::Buffer<float>(3 * info.nb_vertices);
                         t.offsets = core::Buffer<std::uint64_t>(info.nb_streamlines + 1);
                         constexpr double kUntouched = -12345.5;
                         hz_positions_check check{};
                         check.struct_size = room ? sizeof check : sizeof check - 8;
                         for (int d = 0; d < 3; ++d) check.bounds_min[d] = check.bounds_max[d] = kUntouched;
                         hz_streamlines_dst dst{};
                         dst.struct_size = sizeof dst;
                         dst.positions = t.positions.data();
                         dst.positions_capacity = t.positions.size();
                         dst.offsets = t.offsets.data();
                         dst.offsets_capacity = t.offsets.size();
                         if (cr->read_streamlines_checked(sample.r, &dst, &check, nullptr, &err) != HZ_OK)
                             return fail(std::string("read_streamlines_checked fails where read_streamlines reads: ") + err.message);
                         if (!std::equal(t.offsets.begin(), t.offsets.end(), plain.offsets.begin(), plain.offsets.end()) ||
                             std::memcmp(t.positions.data(), plain.positions.data(), t.positions.size() * sizeof(float)) != 0)
                             return fail("read_streamlines_checked writes other streamlines than read_streamlines");
                         bool touched = false;
                         for (int d = 0; d < 3; ++d) touched |= check.bounds_min[d] != kUntouched || check.bounds_max[d] != kUntouched;
                         if (!room) {
                             if (check.vouched != 0 || touched) return fail("writes a check record whose struct_size has no room for it");
                             continue;
                         }
                         if (check.vouched == 0) {
                             if (touched) return fail("writes bounds without vouching for them");
                             how = "does not vouch for this sample; the host checks what it wrote";
                             continue;
                         }
                         if (info.nb_vertices == 0) {
                             how = "vouches for an empty sample";
                             continue;
                         }
                         core::Bounds b;
                         try {
                             b = core::finite_bounds(t.positions.data(), info.nb_vertices, "the sample");
                         } catch (const std::exception &e) {
                             return fail(std::string("vouches for positions that are not all finite: ") + e.what());
                         }
                         for (int d = 0; d < 3; ++d)
                             if (b.empty || check.bounds_min[d] != b.min[d] || check.bounds_max[d] != b.max[d])
                                 return fail("vouches for bounds other than the positions it wrote (" + std::string("xyz").substr(d, 1) +
                                             ")");
                         how = "vouches for exact bounds";
                     }
                     return pass(how + "; nothing into a record without room");
                 }});
}

}  // namespace hz::host::validation
