// The compiled part of the `horizon` Python package (horizon._core): the
// same core and plugins as the `horizon` program, through pybind11.
//
// Arrays are lent to numpy without a copy: each array's base is the Python
// object of the dataset it belongs to, which keeps the dataset (and the file
// mapping or memory its buffers view) alive as long as any array does. They
// are read-only: a mapped file's pages are copy-on-write, and a writer would
// otherwise change what every other view sees.
//
// Threading: the GIL is released while a file is read or written and while
// a picture is drawn; the OpenGL context (one per process, made on the first
// render) is used by one call at a time (a lock).
#include <hz/core/data.hpp>
#include <hz/core/filter.hpp>
#include <hz/core/io.hpp>
#include <hz/core/params.hpp>
#include <hz/core/plugin_host.hpp>
#include <hz/core/render/buan.hpp>
#include <hz/core/render/context.hpp>
#include <hz/core/render/renderer.hpp>
#include <hz/core/render/scene.hpp>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <optional>
#include <map>
#include <memory>
#include <mutex>

namespace py = pybind11;
using namespace hz;

namespace {

std::mutex g_mutex;  // the registry's creation, and the GL context's use
std::unique_ptr<core::Registry> g_registry;
std::vector<core::fs::path> g_dirs;  // the package's plugin folders (set by horizon/__init__.py)
std::unique_ptr<core::render::GlContext> g_context;

// (The GIL is released before the lock is taken: a thread that held the GIL
// while it waited for the lock would block the scanning thread, which must
// take the GIL back before it lets the lock go; each plugin file is tried
// in a child process first.)
core::Registry &registry() {
    py::gil_scoped_release nogil;
    std::lock_guard lock(g_mutex);
    if (!g_registry) {
        auto reg = std::make_unique<core::Registry>(core::Registry::Options{true, 10.0, core::default_trial_cache()});
        // As the program's: HORIZON_PLUGIN_PATH, the user's folder, then the
        // bundled plugins (the package's own folders last: the first plugin
        // with an id wins, so a user's plugin replaces a bundled one).
        std::vector<core::fs::path> dirs = core::plugin_search_path({});
        dirs.insert(dirs.end(), g_dirs.begin(), g_dirs.end());
        reg->scan(dirs);
        g_registry = std::move(reg);
    }
    return *g_registry;
}

// A dataset read from a file, shared by the Python object and its arrays.
struct Data {
    std::shared_ptr<core::Dataset> ds;
    std::string path;
};

py::dtype dtype_of(hz_dtype t) {
    switch (t) {
    case HZ_DTYPE_U8: return py::dtype::of<std::uint8_t>();
    case HZ_DTYPE_I8: return py::dtype::of<std::int8_t>();
    case HZ_DTYPE_U16: return py::dtype::of<std::uint16_t>();
    case HZ_DTYPE_I16: return py::dtype::of<std::int16_t>();
    case HZ_DTYPE_U32: return py::dtype::of<std::uint32_t>();
    case HZ_DTYPE_I32: return py::dtype::of<std::int32_t>();
    case HZ_DTYPE_U64: return py::dtype::of<std::uint64_t>();
    case HZ_DTYPE_I64: return py::dtype::of<std::int64_t>();
    case HZ_DTYPE_F32: return py::dtype::of<float>();
    case HZ_DTYPE_F64: return py::dtype::of<double>();
    default: throw core::Error(std::string("arrays of ") + core::dtype_name(t) + " have no numpy type");
    }
}

// A read-only numpy view of `ptr`, owned by `owner` (the Data's Python object).
py::array view(py::dtype dt, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides, const void *ptr, py::handle owner) {
    py::array a(dt, std::move(shape), std::move(strides), ptr, owner);
    py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
    return a;
}

py::array affine(const core::Affine &m) {
    py::array_t<double> a({4, 4});
    std::memcpy(a.mutable_data(), m.data(), sizeof(double) * 16);
    return a;
}

// Every array of `arrays` as {name: (attach, numpy view)}.
py::dict arrays_of(const std::vector<core::DataArray> &arrays, py::handle owner) {
    py::dict d;
    for (const core::DataArray &a : arrays) {
        const auto size = py::ssize_t(core::dtype_size(a.dtype));
        std::vector<py::ssize_t> shape{py::ssize_t(a.count)}, strides{size * py::ssize_t(a.components)};
        if (a.components > 1) shape.push_back(py::ssize_t(a.components)), strides.push_back(size);
        const char *attach = a.attach == HZ_ATTACH_STREAMLINE ? "streamline" : a.attach == HZ_ATTACH_FACE ? "face" : "vertex";
        d[py::str(a.name)] = py::make_tuple(attach, view(dtype_of(a.dtype), shape, strides, a.bytes.data(), owner));
    }
    return d;
}

const core::Dataset &need(const Data &d, hz_data_kind kind, const char *what) {
    if (d.ds->kind != kind)
        throw py::attribute_error(std::string(what) + ": " + d.path + " holds " + core::kind_name(d.ds->kind) + ", not " +
                                  core::kind_name(kind));
    return *d.ds;
}

std::unique_ptr<core::render::GlContext> &context() {
    if (!g_context) g_context = core::render::make_headless_context();
    return g_context;
}

// Long work's progress for Python (issue 54): `fn(fraction, what)` called
// with the GIL held, from whatever thread reports, at most every 0.1 s
// unless the fraction moved by 5 % or reached 1. An exception it raises
// (KeyboardInterrupt from Ctrl-C included) cancels the work, and the call
// that did it raises that exception (rethrow()) instead of its own error.
class Progress {
public:
    explicit Progress(py::object fn) : fn_(std::move(fn)) {
        if (!fn_.is_none()) task_.on_progress = [this](double f, const char *what) { report(f, what); };
    }
    ~Progress() {
        py::gil_scoped_acquire gil;  // (fn_ and a kept exception let go with the GIL)
        error_ = nullptr;
        fn_ = py::object();
    }
    Progress(const Progress &) = delete;
    Progress &operator=(const Progress &) = delete;
    const hz_task *task() const { return fn_.is_none() ? nullptr : task_.get(); }
    // With the GIL held, after the work: the callback's exception, if any.
    void rethrow() {
        if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
    }

private:
    void report(double f, const char *what) {
        std::lock_guard<std::mutex> lock(m_);
        if (error_) return;
        const auto now = std::chrono::steady_clock::now();
        if (f < 1.0 && f - last_f_ < 0.05 && now - last_ < std::chrono::milliseconds(100)) return;
        last_ = now, last_f_ = f;
        py::gil_scoped_acquire gil;
        try {
            fn_(std::clamp(f, 0.0, 1.0), std::string(what ? what : ""));
        } catch (py::error_already_set &) {
            error_ = std::current_exception();
            task_.cancel();
        }
    }
    py::object fn_;
    core::Task task_;
    std::mutex m_;
    std::chrono::steady_clock::time_point last_{};
    double last_f_ = -1.0;
    std::exception_ptr error_;
};

}  // namespace

PYBIND11_MODULE(_core, m) {
    m.doc() = "Horizon's core: loaders, writers and the headless renderer, through the same plugins as the horizon program";
    py::register_exception<core::Error>(m, "Error", PyExc_RuntimeError);

    m.def(
        "_set_plugin_dirs",
        [](const std::vector<std::string> &dirs) {
            std::lock_guard lock(g_mutex);
            if (g_registry) throw core::Error("the plugins are loaded already: set their folders before the first call");
            g_dirs.assign(dirs.begin(), dirs.end());
        },
        "The bundled plugins' folders, searched after HORIZON_PLUGIN_PATH and the user's folder.");

    m.def(
        "plugins",
        []() {
            py::list out;
            for (const auto &p : registry().plugins()) {
                py::dict d;
                d["id"] = p.info.id;
                d["name"] = p.info.name;
                d["version"] = p.info.version;
                d["kind"] = std::string(core::plugin_kind_name(p.info.kind));
                d["file"] = p.info.file;
                if (const hz_loader *l = p.loader()) {
                    py::list ext;
                    for (std::uint32_t i = 0; l->extensions && l->extensions[i]; ++i) ext.append(std::string(l->extensions[i]));
                    d["extensions"] = ext;
                }
                out.append(d);
            }
            return out;
        },
        "The plugins found: id, name, version, kind (loader, shader, clustering), file, and a loader's extensions.");

    py::class_<Data>(m, "Data", "What a file holds, read by a loader plugin (horizon.load)")
        .def_property_readonly("kind", [](const Data &d) { return std::string(core::kind_name(d.ds->kind)); })
        .def_property_readonly("format", [](const Data &d) { return d.ds->format; })
        .def_property_readonly("loader", [](const Data &d) { return d.ds->loader_id; })
        .def_property_readonly("path", [](const Data &d) { return d.path; })
        .def_property_readonly("metadata", [](const Data &d) { return d.ds->metadata; })
        .def_property_readonly(
            "positions",
            [](py::object self) {
                const Data &d = self.cast<const Data &>();
                const core::Tractogram &t = need(d, HZ_DATA_STREAMLINES, "positions").tractogram;
                return view(py::dtype::of<float>(), {py::ssize_t(t.nb_stored()), 3}, {12, 4}, t.positions.data(), self);
            },
            "Every point, float32 (points, 3), RAS+ mm, read-only, without a copy; with `gap` rows after each streamline "
            "that belong to none")
        .def_property_readonly(
            "offsets",
            [](py::object self) {
                const Data &d = self.cast<const Data &>();
                const core::Tractogram &t = need(d, HZ_DATA_STREAMLINES, "offsets").tractogram;
                return view(py::dtype::of<std::uint64_t>(), {py::ssize_t(t.offsets.size())}, {8}, t.offsets.data(), self);
            },
            "uint64 (streamlines + 1): streamline s is positions[offsets[s]:offsets[s + 1] - gap]")
        .def_property_readonly("gap", [](const Data &d) { return need(d, HZ_DATA_STREAMLINES, "gap").tractogram.gap; })
        .def_property_readonly("reference",
                               [](const Data &d) { return affine(need(d, HZ_DATA_STREAMLINES, "reference").tractogram.reference); })
        .def_property_readonly("reference_dims",
                               [](const Data &d) { return need(d, HZ_DATA_STREAMLINES, "reference_dims").tractogram.reference_dims; })
        .def_property_readonly(
            "vertices",
            [](py::object self) {
                const core::Mesh &mesh = need(self.cast<const Data &>(), HZ_DATA_MESH, "vertices").mesh;
                return view(py::dtype::of<float>(), {py::ssize_t(mesh.nb_vertices()), 3}, {12, 4}, mesh.vertices.data(), self);
            },
            "float32 (vertices, 3), RAS+ mm, read-only")
        .def_property_readonly(
            "faces",
            [](py::object self) {
                const core::Mesh &mesh = need(self.cast<const Data &>(), HZ_DATA_MESH, "faces").mesh;
                return view(py::dtype::of<std::uint32_t>(), {py::ssize_t(mesh.nb_faces()), 3}, {12, 4}, mesh.faces.data(), self);
            },
            "uint32 (faces, 3), 0-based, read-only")
        .def_property_readonly(
            "voxels",
            [](py::object self) {
                const core::Volume &v = need(self.cast<const Data &>(), HZ_DATA_VOLUME, "voxels").volume;
                const auto size = py::ssize_t(core::dtype_size(v.dtype));
                std::vector<py::ssize_t> shape, strides;
                py::ssize_t step = size;
                for (std::uint64_t n : v.dims) shape.push_back(py::ssize_t(n)), strides.push_back(step), step *= py::ssize_t(n);
                return view(dtype_of(v.dtype), shape, strides, v.voxels.data(), self);
            },
            "The stored values, (x, y, z[, t...]) in Fortran order as nibabel's dataobj, read-only; multiply by scale[0] and add "
            "scale[1] for the values")
        .def_property_readonly("scale",
                               [](const Data &d) {
                                   const core::Volume &v = need(d, HZ_DATA_VOLUME, "scale").volume;
                                   return py::make_tuple(v.scale_slope, v.scale_inter);
                               })
        .def_property_readonly("affine", [](const Data &d) { return affine(need(d, HZ_DATA_VOLUME, "affine").volume.voxel_to_ras); })
        .def_property_readonly(
            "arrays",
            [](py::object self) {
                const Data &d = self.cast<const Data &>();
                return arrays_of(d.ds->kind == HZ_DATA_MESH ? d.ds->mesh.arrays : d.ds->tractogram.arrays, self);
            },
            "{name: (attach, array)}: per-vertex, per-streamline or per-face data, read-only")
        .def("__repr__",
             [](const Data &d) { return "<horizon.Data " + std::string(core::kind_name(d.ds->kind)) + " from " + d.path + ">"; });

    m.def(
        "load",
        [](const std::string &path, py::object progress) {
            core::Registry &reg = registry();
            auto ds = std::make_shared<core::Dataset>();
            Progress prog(std::move(progress));
            try {
                py::gil_scoped_release nogil;
                *ds = core::read_dataset(reg, path, prog.task());
            } catch (...) {
                prog.rethrow();
                throw;
            }
            prog.rethrow();
            return Data{std::move(ds), path};
        },
        py::arg("path"), py::arg("progress") = py::none(),
        "Reads a file through the loader plugin that claims it; raises horizon.Error naming the file. `progress`: "
        "progress(fraction, what), called as the file is read (an exception it raises stops the reading and is raised).");

    m.def(
        "save",
        [](const Data &d, const std::string &path, bool force, std::optional<std::vector<std::uint64_t>> selection) {
            core::Registry &reg = registry();
            std::error_code ec;
            if (!force && core::fs::exists(path, ec)) throw core::Error(path + ": already exists (save(..., force=True) replaces it)");
            if (selection) {
                const std::uint64_t n = need(d, HZ_DATA_STREAMLINES, "save(selection=...)").tractogram.nb_streamlines();
                for (std::size_t i = 0; i < selection->size(); ++i)
                    if ((*selection)[i] >= n || (i > 0 && (*selection)[i] <= (*selection)[i - 1]))
                        throw py::value_error("save: selection must be increasing streamline indices below " + std::to_string(n));
            }
            std::vector<std::string> dropped;
            {
                py::gil_scoped_release nogil;
                core::write_dataset(reg, *d.ds, path, force, &dropped, d.path, nullptr, selection ? &*selection : nullptr);
            }
            return dropped;
        },
        py::arg("data"), py::arg("path"), py::arg("force") = false, py::arg("selection") = py::none(),
        "Writes through the writer plugin of the extension, atomically (a temporary file renamed into place); never over the "
        "file it was read from; an existing file only with force. `selection`: the streamlines to write (increasing indices, "
        "as filter() returns them), read where they lie. Returns what the format could not hold.");

    m.def(
        "_filter",
        [](const Data &d, const std::vector<std::string> &include, const std::vector<std::string> &exclude, double min_length,
           double max_length, bool ends_only, bool invert) {
            const core::Tractogram &t = need(d, HZ_DATA_STREAMLINES, "filter").tractogram;
            core::Registry &reg = registry();
            core::FilterSpec spec;
            // (as `horizon filter` reads --include and --exclude: spheres, boxes, masks)
            for (const std::string &r : include) spec.rois.push_back(core::parse_roi(reg, r, true));
            for (const std::string &r : exclude) spec.rois.push_back(core::parse_roi(reg, r, false));
            spec.min_length = min_length, spec.max_length = max_length, spec.ends_only = ends_only, spec.invert = invert;
            std::vector<std::uint64_t> kept;
            {
                py::gil_scoped_release nogil;
                kept = core::filter_streamlines(t, spec);
            }
            return py::array_t<std::uint64_t>(py::ssize_t(kept.size()), kept.data());
        },
        py::arg("data"), py::arg("include"), py::arg("exclude"), py::arg("min_length"), py::arg("max_length"), py::arg("ends_only"),
        py::arg("invert"));

    m.def(
        "_render",
        [](const std::string &scene_json, const std::string &base, int width, int height, const std::map<std::string, Data> &memory) {
            if (width < 16 || height < 16 || width > 16384 || height > 16384)
                throw py::value_error("size: expected 16 to 16384 pixels a side, not " + std::to_string(width) + "x" +
                                      std::to_string(height));
            core::Registry &reg = registry();
            core::render::Image im;
            {
                py::gil_scoped_release nogil;
                std::lock_guard lock(g_mutex);
                context();
                core::render::MemoryData held;
                for (const auto &[name, d] : memory) held[name] = d.ds;
                core::render::Scene scene = core::render::parse_scene(reg, scene_json, base, "scene", held);
                core::render::Renderer r(reg);
                core::render::RenderSettings rs;
                rs.width = width, rs.height = height;
                rs.shell_proxy = false;
                rs.bake_materials = true;
                const core::render::View v = core::render::fit_view(scene, scene.camera, double(width) / height);
                r.set_scene(std::move(scene), v, rs);
                r.render(v, width, height);
                im = r.read_image();
            }
            py::array_t<std::uint8_t> a({im.height, im.width, 4});
            std::memcpy(a.mutable_data(), im.rgba.data(), im.rgba.size());
            return a;
        },
        py::arg("scene_json"), py::arg("base"), py::arg("width"), py::arg("height"), py::arg("memory"));

    m.def(
        "_buan_segments",
        [](const Data &d, std::uint32_t n) {
            const core::Tractogram &t = need(d, HZ_DATA_STREAMLINES, "buan_segments").tractogram;
            std::vector<std::uint32_t> seg;
            {
                py::gil_scoped_release unlocked;
                seg = core::render::buan_segments(t, n);
            }
            py::array_t<std::uint32_t> out(py::ssize_t(seg.size()));
            std::memcpy(out.mutable_data(), seg.data(), seg.size() * sizeof(std::uint32_t));
            return out;
        },
        py::arg("data"), py::arg("n"), "Each point's BUAN segment (horizon.buan_segments).");

    m.def(
        "_sh_matrix",
        [](py::array_t<double, py::array::c_style | py::array::forcecast> vertices, int order, const std::string &basis, bool legacy) {
            if (vertices.ndim() != 2 || vertices.shape(1) != 3) throw core::Error("sh_to_sf: vertices must be (N, 3)");
            if (order < 0 || order > 16 || order % 2) throw core::Error("sh_to_sf: the order must be even, 0 to 16");
            if (basis != "descoteaux07" && basis != "tournier07")
                throw core::Error("sh_to_sf: basis '" + basis + "' is neither descoteaux07 nor tournier07");
            std::vector<double> xyz(vertices.data(), vertices.data() + vertices.size());
            const std::vector<double> B = core::render::sh_matrix(xyz, order, basis, legacy);
            const py::ssize_t C = py::ssize_t(core::render::sh_coefficients(order));
            py::array_t<double> out({py::ssize_t(vertices.shape(0)), C});
            std::memcpy(out.mutable_data(), B.data(), B.size() * sizeof(double));
            return out;
        },
        py::arg("vertices"), py::arg("order"), py::arg("basis"), py::arg("legacy"),
        "B (vertices x coefficients): the real SH basis of the ODF glyphs at the vertices (horizon.sh_to_sf).");

    m.def(
        "_cluster",
        [](const Data &d, const std::string &algorithm, const std::vector<double> &thresholds, const std::string &params_json,
           std::optional<std::vector<std::uint64_t>> ordering, py::object progress) {
            const core::Tractogram &t = need(d, HZ_DATA_STREAMLINES, "cluster").tractogram;
            core::Registry &reg = registry();
            core::render::ClusterSpec spec;
            spec.algorithm = algorithm;
            spec.thresholds = thresholds;
            const core::LoadedPlugin *plugin = core::find_clustering(reg, algorithm);
            const std::vector<core::ParamSpec> schema = core::schema_of(*plugin);
            const nlohmann::json params = nlohmann::json::parse(params_json);
            for (const auto &[k, v] : params.items())
                spec.params[k] = core::param_from_json(core::find_param(schema, plugin->info.id, k), v);
            core::render::ClusterTree tree;
            Progress prog(std::move(progress));
            try {
                py::gil_scoped_release nogil;
                tree = core::render::run_clustering(reg, t, spec, prog.task(), ordering ? &*ordering : nullptr);
            } catch (...) {
                prog.rethrow();
                throw;
            }
            prog.rethrow();
            const auto nodes = py::ssize_t(tree.parent.size());
            py::dict out;
            out["algorithm"] = plugin->info.id;
            out["nb_levels"] = tree.nb_levels;
            out["thresholds"] = tree.thresholds;
            out["parent"] = py::array_t<std::int64_t>(nodes, tree.parent.data());
            out["level"] = py::array_t<std::uint32_t>(nodes, tree.level.data());
            out["centroids"] = py::array_t<float>({nodes, py::ssize_t(tree.nb_points), py::ssize_t(3)}, tree.centroids.data());
            out["member_offsets"] = py::array_t<std::uint64_t>(py::ssize_t(tree.member_offsets.size()), tree.member_offsets.data());
            out["members"] = py::array_t<std::uint64_t>(py::ssize_t(tree.members.size()), tree.members.data());
            return out;
        },
        py::arg("data"), py::arg("algorithm"), py::arg("thresholds"), py::arg("params_json"), py::arg("ordering"),
        py::arg("progress") = py::none());

    m.def(
        "_from_streamlines",
        [](py::array_t<float, py::array::c_style | py::array::forcecast> positions,
           py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast> offsets) {
            if (positions.ndim() != 2 || positions.shape(1) != 3) throw py::value_error("streamlines: points must be an (n, 3) array");
            if (offsets.ndim() != 1 || offsets.shape(0) < 1) throw py::value_error("streamlines: offsets must be 1-D, streamlines + 1");
            auto ds = std::make_shared<core::Dataset>();
            ds->kind = HZ_DATA_STREAMLINES;
            ds->format = "numpy";
            ds->loader_id = "python";
            core::Tractogram &t = ds->tractogram;
            t.positions = core::Buffer<float>::copy_of({positions.data(), std::size_t(positions.size())});
            t.offsets = core::Buffer<std::uint64_t>::copy_of({offsets.data(), std::size_t(offsets.size())});
            ds->bounds = t.validate("streamlines");  // (offsets from 0, non-decreasing, to the points; finite points)
            return Data{std::move(ds), "<memory>"};
        },
        py::arg("positions"), py::arg("offsets"));

    m.def(
        "_from_mesh",
        [](py::array_t<float, py::array::c_style | py::array::forcecast> vertices,
           py::array_t<std::int64_t, py::array::c_style | py::array::forcecast> faces) {
            if (vertices.ndim() != 2 || vertices.shape(1) != 3) throw py::value_error("from_mesh: vertices must be an (n, 3) array");
            if (faces.ndim() != 2 || faces.shape(1) != 3) throw py::value_error("from_mesh: faces must be an (m, 3) array");
            const auto n = std::uint64_t(vertices.shape(0));
            if (n > 0xffffffffull) throw py::value_error("from_mesh: more than 2^32 - 1 vertices");
            std::vector<std::uint32_t> f(std::size_t(faces.size()));
            for (std::size_t i = 0; i < f.size(); ++i) {
                const std::int64_t k = faces.data()[i];
                if (k < 0 || std::uint64_t(k) >= n)
                    throw py::value_error("from_mesh: face " + std::to_string(i / 3) + " uses vertex " + std::to_string(k) +
                                          ", not one of the " + std::to_string(n));
                f[i] = std::uint32_t(k);
            }
            auto ds = std::make_shared<core::Dataset>();
            ds->kind = HZ_DATA_MESH;
            ds->format = "numpy";
            ds->loader_id = "python";
            ds->mesh.vertices = core::Buffer<float>::copy_of({vertices.data(), std::size_t(vertices.size())});
            ds->mesh.faces = core::Buffer<std::uint32_t>::copy_of({f.data(), f.size()});
            try {
                ds->bounds = core::finite_bounds(ds->mesh.vertices.data(), n, "from_mesh");
            } catch (const core::Error &e) {
                throw py::value_error(e.what());
            }
            return Data{std::move(ds), "<memory>"};
        },
        py::arg("vertices"), py::arg("faces"));

    m.def(
        "_from_volume",
        [](py::array voxels, py::array_t<double, py::array::c_style | py::array::forcecast> affine) {
            // (horizon.from_volume hands them in Fortran order: x fastest)
            if (!(voxels.flags() & py::array::f_style)) throw py::value_error("from_volume: the voxels must be in Fortran order");
            if (voxels.ndim() < 3 || voxels.ndim() > 5) throw py::value_error("from_volume: the voxels must have 3 to 5 dimensions");
            for (py::ssize_t d = 0; d < voxels.ndim(); ++d)
                if (voxels.shape(d) < 1) throw py::value_error("from_volume: the voxels have an empty dimension");
            if (affine.ndim() != 2 || affine.shape(0) != 4 || affine.shape(1) != 4)
                throw py::value_error("from_volume: affine must be 4 x 4");
            const std::pair<py::dtype, hz_dtype> types[] = {
                {py::dtype::of<std::uint8_t>(), HZ_DTYPE_U8},   {py::dtype::of<std::int8_t>(), HZ_DTYPE_I8},
                {py::dtype::of<std::uint16_t>(), HZ_DTYPE_U16}, {py::dtype::of<std::int16_t>(), HZ_DTYPE_I16},
                {py::dtype::of<std::uint32_t>(), HZ_DTYPE_U32}, {py::dtype::of<std::int32_t>(), HZ_DTYPE_I32},
                {py::dtype::of<std::uint64_t>(), HZ_DTYPE_U64}, {py::dtype::of<std::int64_t>(), HZ_DTYPE_I64},
                {py::dtype::of<float>(), HZ_DTYPE_F32},         {py::dtype::of<double>(), HZ_DTYPE_F64}};
            const auto *type = std::find_if(std::begin(types), std::end(types),
                                            [&](const auto &t) { return t.first.is(voxels.dtype()) || t.first.equal(voxels.dtype()); });
            if (type == std::end(types))
                throw py::value_error("from_volume: voxels of " + std::string(py::str(voxels.dtype())) + " (integers or floats only)");
            core::Affine a{};
            std::copy(affine.data(), affine.data() + 16, a.begin());
            for (double v : a)
                if (!std::isfinite(v)) throw py::value_error("from_volume: the affine is not finite");
            if (a[12] != 0 || a[13] != 0 || a[14] != 0 || a[15] != 1)
                throw py::value_error("from_volume: the affine's last row must be 0 0 0 1");
            const double det =
                a[0] * (a[5] * a[10] - a[6] * a[9]) - a[1] * (a[4] * a[10] - a[6] * a[8]) + a[2] * (a[4] * a[9] - a[5] * a[8]);
            if (!(std::abs(det) > 1e-12)) throw py::value_error("from_volume: the affine is singular");
            auto ds = std::make_shared<core::Dataset>();
            ds->kind = HZ_DATA_VOLUME;
            ds->format = "numpy";
            ds->loader_id = "python";
            core::Volume &v = ds->volume;
            v.dtype = type->second;
            for (py::ssize_t d = 0; d < voxels.ndim(); ++d) v.dims.push_back(std::uint64_t(voxels.shape(d)));
            v.voxels = core::Buffer<std::byte>::copy_of({static_cast<const std::byte *>(voxels.data()), std::size_t(voxels.nbytes())});
            v.voxel_to_ras = a;
            return Data{std::move(ds), "<memory>"};
        },
        py::arg("voxels"), py::arg("affine"));
}
