// `horizon validate`: a conformance checker for plugin files, in the manner
// of clap-validator and pluginval. Every check runs in a forked child that
// loads the plugin afresh, so a crash or a hang is reported as that check's
// result instead of taking the validator down.
#include "commands.hpp"

#include <hz/core/render/context.hpp>

#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
#include <hz/core/phantom.hpp>

#include <boost/dll/library_info.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <zlib.h>

#include <algorithm>
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

namespace hz::host {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Outcome {
    std::string status = "passed";  // passed | failed | skipped
    std::string reason;
};
Outcome pass(std::string why = "") { return {"passed", std::move(why)}; }
Outcome fail(std::string why) { return {"failed", std::move(why)}; }
Outcome skip(std::string why) { return {"skipped", std::move(why)}; }

struct Ctx {
    const core::Module &module;
    const core::PluginInfo &plugin;
    const ValidateOptions &opts;
    fs::path scratch;  // private temporary directory of this check
};

using CheckFn = std::function<Outcome(const Ctx &)>;

struct Check {
    const char *name;
    hz_plugin_kind kind;  // 0: library-level
    const char *description;
    CheckFn fn;
};

// ------------------------------------------------------------------ helpers

hz_error new_error() {
    hz_error e{};
    e.struct_size = sizeof e;
    return e;
}

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

// Reads a streamline file through `l`; returns status, fills `t` and `msg`.
hz_status read_with(const hz_loader &l, const fs::path &file, core::Tractogram &t, std::string &msg,
                    const hz_task *task = nullptr) {
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

const hz_loader &loader_of(const Ctx &c) { return *static_cast<const hz_loader *>(c.module.interface(c.plugin.id, HZ_INTERFACE_LOADER)); }
const hz_shader &shader_of(const Ctx &c) { return *static_cast<const hz_shader *>(c.module.interface(c.plugin.id, HZ_INTERFACE_SHADER)); }
const hz_clustering &clustering_of(const Ctx &c) {
    return *static_cast<const hz_clustering *>(c.module.interface(c.plugin.id, HZ_INTERFACE_CLUSTERING));
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
fs::path write_view(const Ctx &c, const hz_dataset_view &v, std::string &msg) {
    const hz_loader &l = loader_of(c);
    const std::string ext = l.extensions && l.extensions[0] ? l.extensions[0] : "dat";
    const fs::path out = c.scratch / ("sample." + ext);
    hz_write_request req{};
    req.struct_size = sizeof req;
    const std::string p = out.string();
    req.path = p.c_str();
    req.extension = ext.c_str();
    req.final_path = p.c_str();  // written in place: companions stay where the plugin put them
    req.add_companion = [](void *, const char *t, const char *f) -> hz_status { return t && f ? HZ_OK : HZ_E_INVALID_ARGUMENT; };
    hz_error err = new_error();
    const hz_status st = l.write(&req, &v, nullptr, &err);
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
        return read_volume_with(l, file, v, msg);
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

bool is_identifier(std::string_view s) {
    auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
    return !s.empty() && !std::isdigit(static_cast<unsigned char>(s[0])) && std::all_of(s.begin(), s.end(), word);
}

// Position of `name` followed by optional blanks and '(' as a whole word, or npos.
std::size_t find_call(const std::string &src, const std::string &name) {
    for (std::size_t at = src.find(name); at != std::string::npos; at = src.find(name, at + 1)) {
        const bool left_ok = at == 0 || !(std::isalnum(static_cast<unsigned char>(src[at - 1])) || src[at - 1] == '_');
        std::size_t k = at + name.size();
        while (k < src.size() && (src[k] == ' ' || src[k] == '\t' || src[k] == '\n')) ++k;
        if (left_ok && k < src.size() && src[k] == '(') return at;
    }
    return std::string::npos;
}
bool has_word(const std::string &src, const std::string &w) {
    for (std::size_t at = src.find(w); at != std::string::npos; at = src.find(w, at + 1)) {
        const bool l = at == 0 || !(std::isalnum(static_cast<unsigned char>(src[at - 1])) || src[at - 1] == '_');
        const std::size_t e = at + w.size();
        const bool r = e >= src.size() || !(std::isalnum(static_cast<unsigned char>(src[e])) || src[e] == '_');
        if (l && r) return true;
    }
    return false;
}

// Parameter schema rules shared by shaders and clustering.
Outcome check_schema(uint32_t count, const hz_param_info *(HZ_ABI *get)(uint32_t)) {
    std::set<std::string> names;
    for (uint32_t i = 0; i < count; ++i) {
        const hz_param_info *p = get(i);
        const std::string at = "parameter " + std::to_string(i);
        if (p == nullptr) return fail(at + ": get_param returned NULL");
        if (p->struct_size < sizeof(hz_param_info)) return fail(at + ": struct_size too small");
        if (p->name == nullptr || !is_identifier(p->name)) return fail(at + ": name is not an identifier");
        const std::string n = p->name;
        if (!names.insert(n).second) return fail("duplicate parameter name '" + n + "'");
        if (p->type < HZ_PARAM_FLOAT || p->type > HZ_PARAM_FLOAT_ARRAY) return fail(n + ": unknown type " + std::to_string(p->type));
        const uint32_t comps = p->type == HZ_PARAM_FLOAT_ARRAY ? 1 : p->components;
        if (p->components < 1 || (p->type != HZ_PARAM_FLOAT_ARRAY && p->components > 4) || p->components > 64)
            return fail(n + ": components " + std::to_string(p->components) + " out of range");
        for (uint32_t k = 0; k < comps; ++k) {
            const double lo = p->min_value[k], hi = p->max_value[k], d = p->default_value[k];
            if (!std::isfinite(lo) || !std::isfinite(hi) || !std::isfinite(d)) return fail(n + ": non-finite min/max/default");
            if (!(lo <= d && d <= hi))
                return fail(n + ": default " + std::to_string(d) + " outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
        }
        if (p->type == HZ_PARAM_FLOAT_ARRAY) {
            if (p->default_array_count > p->components) return fail(n + ": default_array_count > components");
            if (p->default_array_count > 0 && p->default_array == nullptr) return fail(n + ": default_array is NULL");
            for (uint32_t k = 0; k < p->default_array_count; ++k)
                if (!std::isfinite(p->default_array[k]) || p->default_array[k] < p->min_value[0] || p->default_array[k] > p->max_value[0])
                    return fail(n + ": default_array[" + std::to_string(k) + "] outside [min, max]");
        }
        if (p->type == HZ_PARAM_ENUM) {
            if (p->enum_labels == nullptr) return fail(n + ": ENUM without labels");
            uint32_t cnt = 0;
            while (p->enum_labels[cnt] != nullptr && cnt < 1024) ++cnt;
            if (double(cnt) != p->max_value[0] - p->min_value[0] + 1) return fail(n + ": enum label count != max - min + 1");
        }
        if ((p->flags & HZ_PARAM_FLAG_REQUIRES_RECOMPILE) &&
            !(p->type == HZ_PARAM_INT || p->type == HZ_PARAM_BOOL || p->type == HZ_PARAM_ENUM))
            return fail(n + ": REQUIRES_RECOMPILE on a continuous parameter");
    }
    return pass(std::to_string(count) + " parameters");
}

// Flattened default values of a schema, in schema order.
std::vector<double> default_params(uint32_t count, const hz_param_info *(HZ_ABI *get)(uint32_t)) {
    std::vector<double> v;
    for (uint32_t i = 0; i < count; ++i) {
        const hz_param_info *p = get(i);
        for (uint32_t k = 0; k < p->components; ++k)
            v.push_back(p->type == HZ_PARAM_FLOAT_ARRAY ? (k < p->default_array_count ? p->default_array[k] : p->default_value[0])
                                                        : p->default_value[k]);
    }
    return v;
}

// ------------------------------------------------------------- clustering

struct Tree {
    hz_cluster_tree_view v{};
    std::vector<double> thresholds;
    std::vector<int64_t> parent;
    std::vector<uint32_t> level;
    std::vector<uint64_t> offsets, members;
    std::vector<float> centroids;
};

hz_status run_clustering(const hz_clustering &c, const core::Tractogram &t, const uint64_t *ordering, Tree &out,
                         std::string &msg, const hz_task *task = nullptr) {
    hz_error err = new_error();
    hz_clusterer *cl = nullptr;
    hz_status st = c.create(core::host_services(), &cl, &err);
    if (st != HZ_OK) {
        msg = std::string("create: ") + err.message;
        return st;
    }
    const hz_streamlines_view view = t.view();
    st = c.run(cl, &view, ordering, task, &err);
    if (st == HZ_OK) {
        out.v.struct_size = sizeof out.v;
        st = c.get_result(cl, &out.v, &err);
        if (st == HZ_OK) {
            const auto &v = out.v;
            out.thresholds.assign(v.level_thresholds, v.level_thresholds + v.nb_levels);
            out.parent.assign(v.parent, v.parent + v.nb_nodes);
            out.level.assign(v.level, v.level + v.nb_nodes);
            out.offsets.assign(v.member_offsets, v.member_offsets + v.nb_nodes + 1);
            out.members.assign(v.members, v.members + out.offsets.back());
            out.centroids.assign(v.centroids, v.centroids + v.nb_nodes * v.nb_points * 3);
        }
    }
    if (st != HZ_OK) msg = err.message;
    c.destroy(cl);
    return st;
}

// Label of every streamline at every level (-1 where missing); checks the
// tree invariants on the way.
bool tree_labels(const Tree &tr, uint64_t n, std::vector<std::vector<int64_t>> &labels, std::string &why) {
    const auto &v = tr.v;
    if (v.nb_nodes < 1) return why = "no root node", false;
    if (tr.parent[0] != -1 || tr.level[0] != 0) return why = "node 0 is not the root", false;
    if (tr.offsets[0] != 0) return why = "member_offsets[0] != 0", false;
    for (uint64_t k = 0; k < v.nb_nodes; ++k)
        if (tr.offsets[k + 1] < tr.offsets[k]) return why = "member_offsets decrease at node " + std::to_string(k), false;
    if (tr.offsets[0 + 1] - tr.offsets[0] != n) return why = "root does not hold every streamline", false;
    for (float f : tr.centroids)
        if (!std::isfinite(f)) return why = "non-finite centroid value", false;
    labels.assign(v.nb_levels + 1, std::vector<int64_t>(n, -1));
    std::vector<std::set<uint64_t>> member_sets(v.nb_nodes);
    for (uint64_t k = 0; k < v.nb_nodes; ++k) {
        const uint32_t lvl = tr.level[k];
        if (lvl > v.nb_levels) return why = "node " + std::to_string(k) + " has level > nb_levels", false;
        if (k > 0) {
            const int64_t p = tr.parent[k];
            if (p < 0 || uint64_t(p) >= v.nb_nodes) return why = "node " + std::to_string(k) + " has an invalid parent", false;
            if (tr.level[p] + 1 != lvl) return why = "node " + std::to_string(k) + " is not one level below its parent", false;
        }
        for (uint64_t m = tr.offsets[k]; m < tr.offsets[k + 1]; ++m) {
            const uint64_t s = tr.members[m];
            if (s >= n) return why = "member index " + std::to_string(s) + " out of range", false;
            if (labels[lvl][s] != -1)
                return why = "streamline " + std::to_string(s) + " is in two clusters of level " + std::to_string(lvl), false;
            labels[lvl][s] = static_cast<int64_t>(k);
            member_sets[k].insert(s);
        }
    }
    for (uint32_t l = 0; l <= v.nb_levels; ++l)
        for (uint64_t s = 0; s < n; ++s)
            if (labels[l][s] == -1) return why = "streamline " + std::to_string(s) + " is in no cluster of level " + std::to_string(l), false;
    for (uint64_t k = 1; k < v.nb_nodes; ++k)
        for (uint64_t s : member_sets[k])
            if (!member_sets[tr.parent[k]].count(s))
                return why = "node " + std::to_string(k) + " holds streamline " + std::to_string(s) + " that its parent lacks", false;
    return true;
}

// Two labelings describe the same partition (cluster ids may differ).
bool same_partition(const std::vector<int64_t> &a, const std::vector<int64_t> &b) {
    std::map<int64_t, int64_t> ab, ba;
    for (std::size_t i = 0; i < a.size(); ++i) {
        auto [it1, new1] = ab.emplace(a[i], b[i]);
        auto [it2, new2] = ba.emplace(b[i], a[i]);
        if (it1->second != b[i] || it2->second != a[i]) return false;
    }
    return true;
}

// Well-separated bundles: any sane clustering agrees on them.
core::Tractogram clustering_sample(std::uint64_t seed) {
    core::PhantomOptions o;
    o.nb_streamlines = 300;
    o.nb_bundles = 6;
    o.bundle_radius_mm = 1.0;
    o.stray_fraction = 0.0;
    o.seed = seed;
    return core::make_phantom(o);
}

// ------------------------------------------------------------ the catalogue

std::vector<Check> catalogue() {
    std::vector<Check> c;
    // Library level.
    c.push_back({"exports-only-entry", 0, "the library exports only hz_plugin_entry_v*", [](const Ctx &x) {
                     boost::dll::library_info info(x.module.file());
                     std::vector<std::string> extra;
                     for (const auto &s : info.symbols())
                         if (s.rfind("hz_plugin_entry_v", 0) != 0 && !s.empty() && s != "_init" && s != "_fini") extra.push_back(s);
                     if (!extra.empty()) return fail(std::to_string(extra.size()) + " extra exported symbols, e.g. '" + extra[0] + "' (build with -fvisibility=hidden and the SDK's version script)");
                     return pass();
                 }});
    c.push_back({"init-deinit-cycle", 0, "deinit() then init() again works and descriptors stay the same", [](const Ctx &x) {
                     const hz_plugin_entry &e = x.module.entry();
                     const uint32_t n0 = e.get_plugin_count();
                     e.deinit();
                     if (!e.init(core::host_services(), x.module.file().c_str())) return fail("second init() returned false");
                     if (e.get_plugin_count() != n0) return fail("plugin count changed across init/deinit/init");
                     return pass();
                 }});
    c.push_back({"interface-unknown-ids", 0, "unknown interface and plugin ids give NULL", [](const Ctx &x) {
                     const hz_plugin_entry &e = x.module.entry();
                     if (e.get_interface(x.plugin.id.c_str(), "hz.nonexistent/1") != nullptr) return fail("unknown interface id resolved");
                     if (e.get_interface((x.plugin.id + "x1").c_str(), x.plugin.interfaces[0].c_str()) != nullptr)
                         return fail("plugin id with trailing garbage resolved");
                     if (e.get_plugin_descriptor(e.get_plugin_count()) != nullptr) return fail("descriptor index out of range is not NULL");
                     for (const auto &i : x.plugin.interfaces)
                         if (e.get_interface(x.plugin.id.c_str(), i.c_str()) == nullptr) return fail("declared interface '" + i + "' does not resolve");
                     return pass();
                 }});

    // Loaders.
    c.push_back({"loader-extensions-wellformed", HZ_KIND_LOADER, "extensions are lowercase, without dot, non-empty", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (l.extensions == nullptr || l.extensions[0] == nullptr) return fail("no extensions");
                     for (auto e = l.extensions; *e; ++e) {
                         const std::string s = *e;
                         if (s.empty() || s[0] == '.') return fail("extension '" + s + "' is empty or starts with a dot");
                         for (char ch : s)
                             if (!(std::islower(static_cast<unsigned char>(ch)) || std::isdigit(static_cast<unsigned char>(ch)) || ch == '.' || ch == '_'))
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
    c.push_back({"loader-probe-purity", HZ_KIND_LOADER, "probe is deterministic, in [0,100], never reads past head_size", [](const Ctx &x) {
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
    c.push_back({"loader-roundtrip", HZ_KIND_LOADER, "write then read gives the same streamlines (empty and 1-point ones included)", [](const Ctx &x) {
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
                 "a writer declaring HZ_LOADER_WRITES_GAP (1.8) skips the vertex after each streamline, NaN or not", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!(l.caps & HZ_LOADER_WRITES_GAP)) return skip("does not declare HZ_LOADER_WRITES_GAP");
                     if (!writes_streamlines(l)) return fail("declares HZ_LOADER_WRITES_GAP without writing streamlines");
                     const core::Tractogram t = sample_tractogram(x.opts.seed);
                     for (const float fill : {std::numeric_limits<float>::quiet_NaN(), 1234.5f}) {
                         const std::string what = std::isnan(fill) ? "NaN" : "finite";
                         std::string msg;
                         const fs::path p = write_sample(x, with_gap(t, fill), msg);
                         if (p.empty()) return fail("with gap 1 (" + what + " gap vertices): " + msg);
                         core::Tractogram back;
                         if (read_with(l, p, back, msg) != HZ_OK) return fail("reading its own output failed: " + msg);
                         if (!same_tractogram(t, back, msg)) return fail("written with gap 1 (" + what + " gap vertices), read back: " + msg);
                     }
                     return pass(std::to_string(t.nb_streamlines()) + " streamlines with NaN and with finite gap vertices");
                 }});
    c.push_back({"loader-malformed-survival", HZ_KIND_LOADER, "truncated and corrupted samples fail cleanly (no crash, message, valid output when accepted)", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!l.read_streamlines && !l.read_volume) return skip("reads neither streamlines nor volumes");
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
                             if (m.find(bad.filename().string()) == std::string::npos) return fail("error message does not name the file: " + m);
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
    c.push_back({"loader-buffer-too-small", HZ_KIND_LOADER, "a short destination gives HZ_E_BUFFER_TOO_SMALL and no write past it", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     std::string msg;
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
    c.push_back({"loader-cancel", HZ_KIND_LOADER, "a pre-cancelled task gives HZ_E_CANCELLED and close() still works", [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!l.read_streamlines && !l.read_volume) return skip("reads neither streamlines nor volumes");
                     std::string msg;
                     const auto files = loader_samples(x, msg);
                     if (files.empty()) return skip("no sample file");
                     core::Task task;
                     task.cancel();
                     core::Tractogram t;
                     core::Volume v;
                     const hz_status st = l.read_streamlines ? read_with(l, files[0], t, msg, task.get())
                                                             : read_volume_with(l, files[0], v, msg, task.get());
                     if (st != HZ_E_CANCELLED) return fail("status " + std::to_string(st) + " instead of HZ_E_CANCELLED");
                     return pass();
                 }});

    c.push_back({"loader-locate-positions", HZ_KIND_LOADER,
                 "locate_positions (1.4), when offered, names bytes equal to what read_streamlines gives, and offsets-only reads agree",
                 [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!HZ_HAS_FIELD(&l, hz_loader, locate_positions) || !l.locate_positions) return skip("no locate_positions");
                     if (!l.read_streamlines) return fail("locate_positions without read_streamlines");
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
                     // Asked without, then with, the delimited layout (1.5), then also
                     // offering to take vouched bounds (1.6), from a host of this size
                     // and of the 1.4 size: never a layout the host did not accept; a
                     // delimited extent holds each streamline's bytes followed by an
                     // all-NaN delimiter vertex; vouched bounds are the exact bounds.
                     std::string how;
                     // Last, a host of 1.9 that also maps unaligned offsets.
                     const hz_extent_flags kDelimited = HZ_EXTENT_DELIMITED, kChecked = HZ_EXTENT_DELIMITED | HZ_EXTENT_CHECKED;
                     const std::pair<hz_extent_flags, std::uint32_t> asks[] = {
                         {0, sizeof(hz_positions_extent)},
                         {kDelimited, sizeof(hz_positions_extent)},
                         {kChecked, HZ_POSITIONS_EXTENT_SIZE_1_4},
                         {kChecked, sizeof(hz_positions_extent)},
                         {kChecked | HZ_EXTENT_UNALIGNED, sizeof(hz_positions_extent)}};
                     for (const auto &[accepts, size] : asks) {
                         hz_positions_extent ext{};
                         ext.struct_size = size;
                         ext.accepts = accepts;
                         constexpr double kUntouched = -12345.5;  // (past a 1.4-sized struct)
                         for (int d = 0; d < 3; ++d) ext.bounds_min[d] = ext.bounds_max[d] = kUntouched;
                         const hz_status st = l.locate_positions(r, &ext, &err);
                         if (st == HZ_E_UNSUPPORTED) {
                             if (accepts == 0) how += " declines the plain layout;";
                             else if (accepts == kDelimited) how += " declines the delimited layout too;";
                             continue;
                         }
                         if (st == HZ_OK && size < sizeof ext) {
                             if (ext.flags & HZ_EXTENT_CHECKED) return fail("vouches for bounds to a host whose struct has no room for them");
                             for (int d = 0; d < 3; ++d)
                                 if (ext.bounds_min[d] != kUntouched || ext.bounds_max[d] != kUntouched)
                                     return fail("writes past the struct_size the host gave");
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
                         if ((ext.flags & HZ_EXTENT_HAS_CRC32) &&
                             crc32_z(0, reinterpret_cast<const Bytef *>(stored.data()), bytes) != ext.crc32)
                             return fail("the CRC-32 given does not match the located bytes");
                         core::Buffer<std::uint64_t> off(info.nb_streamlines + 1);
                         hz_streamlines_dst dst{};
                         dst.struct_size = sizeof dst;
                         dst.flags = HZ_STREAMLINES_OFFSETS_ONLY;
                         dst.offsets = off.data();
                         dst.offsets_capacity = off.size();
                         if (l.read_streamlines(r, &dst, nullptr, &err) != HZ_OK)
                             return fail(std::string("an offsets-only read fails: ") + err.message);
                         if (!delimited) {
                             if (full.positions.size() * 4 != bytes || std::memcmp(stored.data(), full.positions.data(), bytes) != 0)
                                 return fail("the located bytes differ from read_streamlines' positions");
                             if (!std::equal(off.begin(), off.end(), full.offsets.begin()))
                                 return fail("offsets-only read gives other offsets");
                             if (accepts == 0) how += " maps the plain layout;";
                             continue;
                         }
                         if (off[0] != 0 || off[info.nb_streamlines] != stored_vertices)
                             return fail("delimited offsets do not span the extent");
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
                 "a vouch for the positions read_streamlines wrote (1.7), when given, is exact, and only given to a host with room for it",
                 [](const Ctx &x) {
                     const hz_loader &l = loader_of(x);
                     if (!l.read_streamlines) return skip("no read_streamlines");
                     std::string msg;
                     const auto files = loader_samples(x, msg);
                     if (files.empty()) return skip("no sample file");
                     // Each ask on a fresh reader: a host of this size, a host of the
                     // 1.6 size (whose struct ends before `check`: a loader must not
                     // look there), and a check record too small to write into.
                     enum Ask { kFull, kOldHost, kShortCheck };
                     std::string how;
                     for (const Ask ask : {kFull, kOldHost, kShortCheck}) {
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
                         check.struct_size = ask == kShortCheck ? sizeof check - 8 : sizeof check;
                         for (int d = 0; d < 3; ++d) check.bounds_min[d] = check.bounds_max[d] = kUntouched;
                         hz_streamlines_dst dst{};
                         dst.struct_size = ask == kOldHost ? HZ_STREAMLINES_DST_SIZE_1_4 : sizeof dst;
                         dst.positions = t.positions.data();
                         dst.positions_capacity = t.positions.size();
                         dst.offsets = t.offsets.data();
                         dst.offsets_capacity = t.offsets.size();
                         dst.check = &check;  // (past the struct of a 1.6-sized host)
                         if (l.read_streamlines(sample.r, &dst, nullptr, &err) != HZ_OK)
                             return skip(std::string("sample does not read: ") + err.message);
                         bool touched = false;
                         for (int d = 0; d < 3; ++d) touched |= check.bounds_min[d] != kUntouched || check.bounds_max[d] != kUntouched;
                         if (ask != kFull) {
                             if (check.vouched != 0 || touched)
                                 return fail(ask == kOldHost ? "writes through `check` for a host whose struct ends before it"
                                                             : "writes a check record whose struct_size has no room for it");
                             continue;
                         }
                         if (check.vouched == 0) {
                             if (touched) return fail("writes bounds without vouching for them");
                             return pass("does not vouch; the host checks what it wrote");
                         }
                         if (info.nb_vertices == 0) return pass("vouches for an empty sample");
                         core::Bounds b;
                         try {
                             b = core::finite_bounds(t.positions.data(), info.nb_vertices, "the sample");
                         } catch (const std::exception &e) {
                             return fail(std::string("vouches for positions that are not all finite: ") + e.what());
                         }
                         for (int d = 0; d < 3; ++d)
                             if (b.empty || check.bounds_min[d] != b.min[d] || check.bounds_max[d] != b.max[d])
                                 return fail("vouches for bounds other than the positions it wrote (" + std::string("xyz").substr(d, 1) + ")");
                         how = "vouches for exact bounds";
                     }
                     return pass(how + "; nothing for a host without room");
                 }});

    // Shaders.
    c.push_back({"shader-schema-wellformed", HZ_KIND_SHADER, "parameter names, types, ranges and defaults are sane", [](const Ctx &x) {
                     const hz_shader &s = shader_of(x);
                     if (!s.get_param && s.param_count) return fail("param_count > 0 but get_param is NULL");
                     return check_schema(s.param_count, s.get_param);
                 }});
    c.push_back({"shader-glsl-contract", HZ_KIND_SHADER, "GLSL snippets define hz_shade( and no #version, main( or uniform", [](const Ctx &x) {
                     const hz_shader &s = shader_of(x);
                     if (!s.glsl_source || !s.eval_reference) return fail("glsl_source or eval_reference is NULL");
                     if (!(s.domains & (HZ_SHADE_SURFACE | HZ_SHADE_LINE))) return fail("no domain");
                     if (s.output != HZ_SHADER_OUTPUT_BRDF && s.output != HZ_SHADER_OUTPUT_RADIANCE_FACTOR && s.output != HZ_SHADER_OUTPUT_EMISSION)
                         return fail("unknown output kind");
                     for (hz_shade_domain d : {HZ_SHADE_SURFACE, HZ_SHADE_LINE}) {
                         if (!(s.domains & d)) continue;
                         const char *src = s.glsl_source(d, 410);
                         if (!src) return fail("glsl_source returns NULL for a declared domain");
                         const std::string g = src;
                         const std::size_t def = find_call(g, "hz_shade");
                         if (def == std::string::npos || g.rfind("vec3", def) == std::string::npos) return fail("snippet does not define vec3 hz_shade(");
                         if (g.find("#version") != std::string::npos) return fail("snippet has #version");
                         if (find_call(g, "main") != std::string::npos) return fail("snippet defines main(");
                         if (has_word(g, "uniform")) return fail("snippet declares uniforms");
                     }
                     return pass();
                 }});
    c.push_back({"shader-glsl-compiles", HZ_KIND_SHADER, "the host's programs built around the GLSL compile as GLSL 4.10 core (glslang, no GPU needed; errors at the snippet's lines)", [](const Ctx &x) {
                     core::Registry reg(core::Registry::Options{false, 10.0, {}});
                     reg.add_module(x.module);
                     const core::LoadedPlugin *p = reg.find(x.plugin.id);
                     if (p == nullptr || p->shader() == nullptr) return fail("the shader interface does not resolve");
                     try {
                         if (auto e = glsl_offline_error(*p)) return fail("GLSL compile error in the " + *e);
                     } catch (const std::exception &e) {
                         return fail(e.what());
                     }
                     return pass();
                 }});
    c.push_back({"shader-reference-finite-nonnegative", HZ_KIND_SHADER, "CPU reference is finite and >= 0 over sampled directions and parameters, grazing and degenerate cases included", [](const Ctx &x) {
                     const hz_shader &s = shader_of(x);
                     if (!s.eval_reference) return fail("no eval_reference");
                     std::mt19937_64 rng(x.opts.seed);
                     std::uniform_real_distribution<double> U(-1, 1), U01(0, 1);
                     auto rnd_dir = [&](double *d) {
                         double n2;
                         do {
                             for (int k = 0; k < 3; ++k) d[k] = U(rng);
                             n2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                         } while (n2 < 1e-6 || n2 > 1);
                     };
                     const auto defaults = default_params(s.param_count, s.get_param);
                     // Parameter sets: defaults, every min corner, every max corner, random.
                     std::vector<std::vector<double>> sets = {defaults};
                     for (int corner = 0; corner < 2; ++corner) {
                         std::vector<double> v;
                         for (uint32_t i = 0; i < s.param_count; ++i) {
                             const hz_param_info *p = s.get_param(i);
                             for (uint32_t k = 0; k < p->components; ++k) {
                                 const uint32_t kk = p->type == HZ_PARAM_FLOAT_ARRAY ? 0 : k;
                                 v.push_back(corner ? p->max_value[kk] : p->min_value[kk]);
                             }
                         }
                         sets.push_back(v);
                     }
                     for (int r = 0; r < 64; ++r) {
                         std::vector<double> v;
                         for (uint32_t i = 0; i < s.param_count; ++i) {
                             const hz_param_info *p = s.get_param(i);
                             for (uint32_t k = 0; k < p->components; ++k) {
                                 const uint32_t kk = p->type == HZ_PARAM_FLOAT_ARRAY ? 0 : k;
                                 double val = p->min_value[kk] + U01(rng) * (p->max_value[kk] - p->min_value[kk]);
                                 if (p->type == HZ_PARAM_INT || p->type == HZ_PARAM_ENUM || p->type == HZ_PARAM_BOOL) val = std::round(val);
                                 v.push_back(val);
                             }
                         }
                         sets.push_back(v);
                     }
                     long evaluated = 0;
                     for (hz_shade_domain d : {HZ_SHADE_SURFACE, HZ_SHADE_LINE}) {
                         if (!(s.domains & d)) continue;
                         for (const auto &params : sets)
                             for (int k = 0; k < 400; ++k) {
                                 hz_shade_point p{};
                                 p.struct_size = sizeof p;
                                 p.domain = d;
                                 p.n[2] = 1;
                                 rnd_dir(p.t);
                                 rnd_dir(p.b);
                                 rnd_dir(p.l);
                                 rnd_dir(p.v);
                                 p.thickness_mm = U01(rng) * 10;
                                 switch (k % 10) {  // the cases where formulas break
                                 case 1: std::copy(p.n, p.n + 3, p.l); break;                            // l = n
                                 case 2: for (int j = 0; j < 3; ++j) p.l[j] = -p.v[j]; break;            // l = -v
                                 case 3: p.l[0] = 1; p.l[1] = 0; p.l[2] = 1e-6; break;                   // grazing light
                                 case 4: p.v[0] = 0; p.v[1] = 1; p.v[2] = 1e-7; std::copy(p.v, p.v + 3, p.l); break;  // grazing both
                                 case 5: std::copy(p.n, p.n + 3, p.t); break;                            // tangent along n
                                 case 6: p.t[0] = p.t[1] = p.t[2] = 0; p.b[0] = p.b[1] = p.b[2] = 0; break;  // no tangent
                                 case 7: p.l[2] = 0; p.v[2] = 0; break;                                  // both in the horizon
                                 case 8: std::copy(p.t, p.t + 3, p.l); break;                            // light along the line
                                 default: break;
                                 }
                                 double rgb[3] = {-1, -1, -1};
                                 const hz_status st = s.eval_reference(&p, params.data(), static_cast<uint32_t>(params.size()), rgb);
                                 ++evaluated;
                                 static const char *const kCase[] = {"random directions", "l = n", "l = -v", "grazing light", "grazing light and view",
                                                                     "tangent along n", "no tangent", "l and v in the horizon", "light along the tangent",
                                                                     "random directions"};
                                 // The inputs, as a case `horizon brdf` reads (to reproduce it).
                                 auto inputs = [&] {
                                     const std::string& id = x.plugin.id;
                                     nlohmann::json c{{"id", "validate"}, {"model", id.substr(id.rfind('.') + 1)}, {"N", p.n}, {"L", p.l}, {"V", p.v}};
                                     if (d == HZ_SHADE_LINE) c["T"] = p.t;
                                     else c["X"] = p.t, c["Y"] = p.b;
                                     nlohmann::json values = nlohmann::json::object();
                                     std::size_t at = 0;
                                     for (uint32_t i = 0; i < s.param_count; ++i) {
                                         const hz_param_info *pi = s.get_param(i);
                                         if (pi->components == 1) values[pi->name] = params[at];
                                         else values[pi->name] = std::vector<double>(params.begin() + at, params.begin() + at + pi->components);
                                         at += pi->components;
                                     }
                                     c["params"] = values;
                                     return std::string(" (") + kCase[k % 10] + "); reproduce with: echo '" + c.dump() +
                                            "' | horizon brdf --shader " + x.plugin.id;
                                 };
                                 if (st != HZ_OK) return fail("eval_reference returned status " + std::to_string(st) + " on valid input" + inputs());
                                 for (double c : rgb) {
                                     if (!std::isfinite(c)) return fail(std::string("non-finite output (") + (std::isnan(c) ? "NaN" : "Inf") + ")" + inputs());
                                     if (c < 0) return fail("negative output " + std::to_string(c) + inputs());
                                 }
                             }
                     }
                     return pass(std::to_string(evaluated) + " evaluations");
                 }});
    c.push_back({"shader-gpu-equals-cpu", HZ_KIND_SHADER, "the host's programs built from the GLSL equal the CPU reference pixel by pixel (headless OpenGL; see `horizon shader-check`)", [](const Ctx &x) {
                     if (x.opts.no_gpu) return skip("--no-gpu: the GLSL was not compiled");
                     std::unique_ptr<core::render::GlContext> gl;
                     try {
                         gl = core::render::make_headless_context();
                     } catch (const std::exception &e) {
                         // Not a pass: GLSL nobody compiled may not compile.
                         return fail(std::string("the GLSL was not compiled: no headless OpenGL here (") + e.what() +
                                     "); install Mesa's EGL (libegl1, libgl1-mesa-dri) or pass --no-gpu to accept it unchecked");
                     }
                     core::Registry reg(core::Registry::Options{false, 10.0, {}});
                     reg.add_module(x.module);
                     const core::LoadedPlugin *p = reg.find(x.plugin.id);
                     if (p == nullptr || p->shader() == nullptr) return fail("the shader interface does not resolve");
                     ShaderCheckOptions o;
                     o.sets = 4;
                     o.size = 96;
                     try {
                         const ShaderGpuResult r = check_shader_gpu(reg, p, o, x.opts.seed);
                         if (r.pixels == 0) return fail("nothing was drawn");
                         if (!r.ok)
                             return fail(std::to_string(r.failures) + " of " + std::to_string(r.pixels) + " pixels differ beyond tolerance (" +
                                         std::to_string(r.nonfinite) + " NaN/Inf, " + std::to_string(r.negative) + " negative); max error/tolerance " +
                                         std::to_string(r.max_err_over_tol));
                         return pass(std::to_string(r.pixels) + " pixels, max error/tolerance " + std::to_string(r.max_err_over_tol));
                     } catch (const std::exception &e) {
                         return fail(e.what());  // e.g. the GLSL does not compile, with the compiler's line
                     }
                 }});
    c.push_back({"shader-reference-reciprocity", HZ_KIND_SHADER, "f(l, v) == f(v, l) when the plugin claims reciprocity", [](const Ctx &x) {
                     const hz_shader &s = shader_of(x);
                     if (!(s.claims & HZ_CLAIM_RECIPROCAL)) return skip("not claimed");
                     std::mt19937_64 rng(x.opts.seed);
                     std::uniform_real_distribution<double> U(-1, 1);
                     const auto params = default_params(s.param_count, s.get_param);
                     for (int k = 0; k < 5000; ++k) {
                         hz_shade_point p{};
                         p.struct_size = sizeof p;
                         p.domain = (s.domains & HZ_SHADE_SURFACE) ? HZ_SHADE_SURFACE : HZ_SHADE_LINE;
                         p.n[2] = 1;
                         for (int j = 0; j < 3; ++j) p.t[j] = U(rng), p.b[j] = U(rng), p.l[j] = U(rng), p.v[j] = U(rng);
                         double a[3], b[3];
                         s.eval_reference(&p, params.data(), uint32_t(params.size()), a);
                         std::swap(p.l, p.v);
                         s.eval_reference(&p, params.data(), uint32_t(params.size()), b);
                         for (int j = 0; j < 3; ++j)
                             if (std::fabs(a[j] - b[j]) > 1e-9 * std::max(1.0, std::fabs(a[j]))) return fail("f(l,v) != f(v,l)");
                     }
                     return pass();
                 }});

    // Clustering.
    c.push_back({"clustering-schema-wellformed", HZ_KIND_CLUSTERING, "parameter names, types, ranges and defaults are sane", [](const Ctx &x) {
                     const hz_clustering &cl = clustering_of(x);
                     if (!cl.create || !cl.run || !cl.get_result || !cl.destroy || !cl.set_param) return fail("NULL function in the table");
                     return check_schema(cl.param_count, cl.get_param);
                 }});
    c.push_back({"clustering-empty-input", HZ_KIND_CLUSTERING, "zero streamlines give HZ_OK and a root-only partition", [](const Ctx &x) {
                     core::Tractogram t;
                     Tree tr;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, tr, msg) != HZ_OK) return fail("run failed on empty input: " + msg);
                     std::vector<std::vector<int64_t>> labels;
                     if (!tree_labels(tr, 0, labels, msg)) return fail(msg);
                     return pass();
                 }});
    c.push_back({"clustering-partition-invariants", HZ_KIND_CLUSTERING, "every streamline in exactly one cluster per level; children within parents; CSR sentinel; finite centroids", [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     Tree tr;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, tr, msg) != HZ_OK) return fail("run failed: " + msg);
                     std::vector<std::vector<int64_t>> labels;
                     if (!tree_labels(tr, t.nb_streamlines(), labels, msg)) return fail(msg);
                     if (tr.v.nb_levels < 1) return fail("no level below the root");
                     return pass(std::to_string(tr.v.nb_nodes) + " nodes over " + std::to_string(tr.v.nb_levels) + " levels");
                 }});
    c.push_back({"clustering-determinism", HZ_KIND_CLUSTERING, "the same input and ordering give the same tree", [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     Tree a, b;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, a, msg) != HZ_OK) return fail(msg);
                     if (run_clustering(clustering_of(x), t, nullptr, b, msg) != HZ_OK) return fail(msg);
                     if (a.parent != b.parent || a.offsets != b.offsets || a.members != b.members) return fail("two runs gave different trees");
                     for (std::size_t i = 0; i < a.centroids.size(); ++i)
                         if (std::fabs(a.centroids[i] - b.centroids[i]) > 1e-6) return fail("two runs gave different centroids");
                     return pass();
                 }});
    c.push_back({"clustering-ordering", HZ_KIND_CLUSTERING, "an explicit ordering is honoured: the same ordering gives the same tree, and the result is still a partition", [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     std::vector<uint64_t> order(t.nb_streamlines());
                     std::iota(order.begin(), order.end(), 0);
                     std::mt19937_64 rng(x.opts.seed);
                     std::shuffle(order.begin(), order.end(), rng);
                     Tree a, b;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, order.data(), a, msg) != HZ_OK) return fail(msg);
                     if (run_clustering(clustering_of(x), t, order.data(), b, msg) != HZ_OK) return fail(msg);
                     if (a.parent != b.parent || a.members != b.members) return fail("same ordering, different trees");
                     std::vector<std::vector<int64_t>> labels;
                     if (!tree_labels(a, t.nb_streamlines(), labels, msg)) return fail(msg);
                     return pass();
                 }});
    c.push_back({"clustering-flip-invariance", HZ_KIND_CLUSTERING, "reversing every streamline gives the same partition at every level", [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     core::Tractogram r;
                     r.positions = core::Buffer<float>(t.positions.size());
                     r.offsets = core::Buffer<uint64_t>(t.offsets.size());
                     std::copy(t.offsets.begin(), t.offsets.end(), r.offsets.begin());
                     for (uint64_t s = 0; s < t.nb_streamlines(); ++s)
                         for (uint64_t i = t.offsets[s], j = t.offsets[s + 1] - 1; i < t.offsets[s + 1]; ++i, --j)
                             std::copy(&t.positions[3 * j], &t.positions[3 * j] + 3, &r.positions[3 * i]);
                     Tree a, b;
                     std::string msg;
                     if (run_clustering(clustering_of(x), t, nullptr, a, msg) != HZ_OK) return fail(msg);
                     if (run_clustering(clustering_of(x), r, nullptr, b, msg) != HZ_OK) return fail(msg);
                     std::vector<std::vector<int64_t>> la, lb;
                     if (!tree_labels(a, t.nb_streamlines(), la, msg) || !tree_labels(b, t.nb_streamlines(), lb, msg)) return fail(msg);
                     if (la.size() != lb.size()) return fail("different number of levels");
                     for (std::size_t l = 0; l < la.size(); ++l)
                         if (!same_partition(la[l], lb[l])) return fail("level " + std::to_string(l) + " partition changes when streamlines are reversed");
                     return pass();
                 }});
    c.push_back({"clustering-nonfinite-input", HZ_KIND_CLUSTERING, "a NaN coordinate gives a clean error, not a crash", [](const Ctx &x) {
                     core::Tractogram t = clustering_sample(x.opts.seed);
                     t.positions[7] = std::numeric_limits<float>::quiet_NaN();
                     Tree tr;
                     std::string msg;
                     const hz_status st = run_clustering(clustering_of(x), t, nullptr, tr, msg);
                     if (st == HZ_OK) return fail("NaN input accepted");
                     if (msg.empty()) return fail("rejected without a message");
                     return pass();
                 }});
    c.push_back({"clustering-cancel", HZ_KIND_CLUSTERING, "a pre-cancelled task gives HZ_E_CANCELLED", [](const Ctx &x) {
                     const core::Tractogram t = clustering_sample(x.opts.seed);
                     core::Task task;
                     task.cancel();
                     Tree tr;
                     std::string msg;
                     const hz_status st = run_clustering(clustering_of(x), t, nullptr, tr, msg, task.get());
                     if (st != HZ_E_CANCELLED) return fail("status " + std::to_string(st) + " instead of HZ_E_CANCELLED");
                     return pass();
                 }});
    return c;
}

struct Result {
    std::string check, plugin, status, reason;
};

}  // namespace

int cmd_validate(const GlobalOptions &, const ValidateOptions &o) {
    std::vector<Result> results;
    auto emit = [&](Result r) {
        if (!o.json)
            std::printf("%-8s %-36s %s%s%s\n", r.status.c_str(), r.check.c_str(), r.plugin.empty() ? "" : ("[" + r.plugin + "] ").c_str(),
                        r.reason.c_str(), "");
        results.push_back(std::move(r));
    };
    const fs::path file = fs::absolute(o.file);
    if (!o.json) std::printf("Validating %s\n\n", file.c_str());

    // 1. Static checks and the load in a child.
    bool loaded = false;
    std::vector<std::pair<std::string, hz_plugin_kind>> plugins;
    if (auto why = core::elf_precheck(file)) {
        emit({"elf", "", "failed", *why});
    } else {
        emit({"elf", "", "passed", ""});
        const auto r = core::run_in_child(
            [&]() -> std::string {
                try {
                    core::Module m(file);
                    json j = json::array();
                    for (const auto &p : m.plugins()) j.push_back({p.id, p.kind});
                    return json{{"ok", true}, {"plugins", j}}.dump();
                } catch (const std::exception &e) {
                    return json{{"ok", false}, {"reason", e.what()}}.dump();
                }
            },
            o.timeout_s);
        const json j = json::parse(r.output, nullptr, false);
        if (r.timed_out || r.signal != 0 || j.is_discarded()) {
            emit({"load", "", "crashed", r.describe() + " while loading or in init()"});
        } else if (!j["ok"].get<bool>()) {
            emit({"load", "", "failed", j["reason"].get<std::string>()});
        } else {
            loaded = true;
            for (const auto &p : j["plugins"]) plugins.emplace_back(p[0].get<std::string>(), p[1].get<hz_plugin_kind>());
            emit({"load", "", "passed", std::to_string(plugins.size()) + " plugin(s), descriptors and core interfaces valid"});
        }
    }

    // 2. Every check of the catalogue, each in its own child.
    if (loaded) {
        const auto checks = catalogue();
        const fs::path scratch_root = fs::temp_directory_path() / ("horizon-validate-" + std::to_string(::getpid()));
        for (std::size_t pi = 0; pi < plugins.size(); ++pi) {
            const auto &[id, kind] = plugins[pi];
            for (const auto &chk : checks) {
                if (chk.kind != 0 && chk.kind != kind) continue;
                if (chk.kind == 0 && pi > 0) continue;  // library checks once per file
                const fs::path scratch = scratch_root / (id + "-" + chk.name);
                fs::create_directories(scratch);
                const auto r = core::run_in_child(
                    [&]() -> std::string {
                        spdlog::set_level(spdlog::level::err);  // plugins' warnings on malformed input are expected
                        core::Module m(file);
                        for (const auto &p : m.plugins())
                            if (p.id == id) {
                                Ctx ctx{m, p, o, scratch};
                                Outcome out;
                                try {
                                    out = chk.fn(ctx);
                                } catch (const std::exception &e) {
                                    out = fail(std::string("exception escaped the plugin or check: ") + e.what());
                                }
                                return json{{"status", out.status}, {"reason", out.reason}}.dump();
                            }
                        return json{{"status", "failed"}, {"reason", "plugin vanished on reload"}}.dump();
                    },
                    o.timeout_s);
                std::error_code ec;
                fs::remove_all(scratch, ec);
                const json j = json::parse(r.output, nullptr, false);
                if (r.timed_out || r.signal != 0 || j.is_discarded() || !j.contains("status"))
                    emit({chk.name, id, "crashed", r.describe()});
                else
                    emit({chk.name, id, j["status"].get<std::string>(), j["reason"].get<std::string>()});
            }
        }
        std::error_code ec;
        fs::remove_all(scratch_root, ec);
    }

    int failed = 0, passed = 0, skipped = 0;
    for (const auto &r : results) {
        if (r.status == "passed") ++passed;
        else if (r.status == "skipped") ++skipped;
        else ++failed;
    }
    if (o.json) {
        json j;
        j["file"] = file.string();
        j["checks"] = json::array();
        for (const auto &r : results) j["checks"].push_back({{"check", r.check}, {"plugin", r.plugin}, {"status", r.status}, {"reason", r.reason}});
        j["summary"] = {{"passed", passed}, {"failed", failed}, {"skipped", skipped}};
        j["ok"] = failed == 0;
        std::cout << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
    } else {
        std::printf("\n%d passed, %d failed, %d skipped: %s\n", passed, failed, skipped, failed ? "FAIL" : "OK");
    }
    return failed == 0 ? 0 : 1;
}

}  // namespace hz::host
