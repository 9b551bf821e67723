// Scene files, built-in demo data and clustering for display.
#include <hz/core/cluster_tree.hpp>
#include <hz/core/io.hpp>
#include <hz/core/params.hpp>
#include <hz/core/phantom.hpp>
#include <hz/core/render/buan.hpp>
#include <hz/core/render/connectome.hpp>
#include <hz/core/render/renderer.hpp>
#include <hz/core/render/scene.hpp>
#include <hz/core/filter.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <cstdlib>

namespace hz::core::render {

using nlohmann::json;

namespace {

[[noreturn]] void fail(const std::string &what, const std::string &where, const std::string &why) {
    throw Error(what + ": " + where + ": " + why);
}

void check_keys(const json &j, const std::set<std::string> &allowed, const std::string &what, const std::string &where) {
    if (!j.is_object()) fail(what, where, "expected an object");
    for (auto it = j.begin(); it != j.end(); ++it)
        if (!allowed.count(it.key())) {
            std::string list;
            for (const auto &a : allowed) list += (list.empty() ? "" : ", ") + a;
            fail(what, where, "unknown key '" + it.key() + "' (expected one of: " + list + ")");
        }
}

double num(const json &j, const std::string &what, const std::string &where) {
    if (!j.is_number()) fail(what, where, "expected a number");
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(what, where, "not a finite number");
    return v;
}

// A number in [lo, hi] (open at lo when lo_open): a meaningless value is an
// error naming where it is, not a blank picture.
double num_in(const json &j, const std::string &what, const std::string &where, double lo, double hi, bool lo_open = false) {
    const double v = num(j, what, where);
    if (v < lo || v > hi || (lo_open && v == lo)) {
        std::ostringstream range;
        range << (lo_open ? "(" : "[") << lo << ", " << hi << "]";
        fail(what, where, "must be in " + range.str() + ", not " + j.dump());
    }
    return v;
}

// A pass's settings: true, false or an object of KEYS whose "on" (a boolean) is true when absent. Sets ON;
// returns the object to read its other keys from, or null for a boolean. EXPECTED is the error when A is
// none of these.
const json *pass_settings(const json &a, const std::string &what, const std::string &key, const std::set<std::string> &keys, bool &on,
                          const std::string &expected) {
    if (a.is_boolean()) {
        on = a.get<bool>();
        return nullptr;
    }
    if (!a.is_object()) fail(what, key, expected);
    check_keys(a, keys, what, key);
    on = true;
    if (a.contains("on")) {
        if (!a["on"].is_boolean()) fail(what, key + ".on", "expected true or false");
        on = a["on"].get<bool>();
    }
    return &a;
}

template <std::size_t N>
std::array<double, N> vec(const json &j, const std::string &what, const std::string &where) {
    if (!j.is_array() || j.size() != N) fail(what, where, "expected an array of " + std::to_string(N) + " numbers");
    std::array<double, N> v{};
    for (std::size_t i = 0; i < N; ++i) v[i] = num(j[i], what, where);
    return v;
}

std::string str(const json &j, const std::string &what, const std::string &where, const std::set<std::string> &choices = {}) {
    if (!j.is_string()) fail(what, where, "expected a string");
    std::string s = j.get<std::string>();
    if (!choices.empty() && !choices.count(s)) {
        std::string list;
        for (const auto &a : choices) list += (list.empty() ? "" : ", ") + a;
        fail(what, where, "'" + s + "' is not one of: " + list);
    }
    return s;
}

Material parse_material(const json &j, const std::string &what, const std::string &where) {
    Material m;
    if (j.is_string()) {
        m.shader = j.get<std::string>();
        return m;
    }
    check_keys(j, {"shader", "params"}, what, where);
    if (j.contains("shader")) m.shader = str(j["shader"], what, where + ".shader");
    if (j.contains("params")) {
        const json &p = j["params"];
        if (!p.is_object()) fail(what, where + ".params", "expected an object");
        for (auto it = p.begin(); it != p.end(); ++it) {
            std::vector<double> v;
            if (it.value().is_array())
                for (std::size_t i = 0; i < it.value().size(); ++i) v.push_back(num(it.value()[i], what, where + ".params." + it.key()));
            else if (it.value().is_boolean())
                v.push_back(it.value().get<bool>() ? 1.0 : 0.0);
            else
                v.push_back(num(it.value(), what, where + ".params." + it.key()));
            m.params[it.key()] = std::move(v);
        }
    }
    return m;
}

}  // namespace

std::string colour_array(const Mesh &m, const std::vector<std::string> *among) {
    for (const auto &a : m.arrays)
        if (a.attach == HZ_ATTACH_VERTEX && a.count == m.nb_vertices() && (a.components == 3 || a.components == 4) &&
            (a.dtype == HZ_DTYPE_U8 || a.dtype == HZ_DTYPE_U16 || a.dtype == HZ_DTYPE_F32 || a.dtype == HZ_DTYPE_F64) &&
            (among == nullptr || std::find(among->begin(), among->end(), a.name) != among->end()))
            return a.name;
    return {};
}

void colour_by_overlay(Object &ob, const std::vector<std::string> &names) {
    if (names.empty()) return;
    const std::string rgb = colour_array(ob.data.mesh, &names);
    ob.coloring.mode = rgb.empty() ? "data" : "rgb";
    ob.coloring.array = rgb.empty() ? names.front() : rgb;
}

namespace {

Coloring parse_coloring(const json &j, const std::string &what, const std::string &where) {
    Coloring c;
    const std::set<std::string> modes = {"direction", "solid", "data", "cluster", "rgb"};
    if (j.is_string()) {
        c.mode = str(j, what, where, modes);
        return c;
    }
    if (j.is_array()) {
        c.mode = "solid";
        c.color = vec<3>(j, what, where);
        return c;
    }
    check_keys(j, {"mode", "value", "array", "colormap", "range"}, what, where);
    if (j.contains("mode")) c.mode = str(j["mode"], what, where + ".mode", modes);
    if (j.contains("value")) c.color = vec<3>(j["value"], what, where + ".value");
    if (j.contains("array")) c.array = str(j["array"], what, where + ".array");
    if (j.contains("colormap"))
        c.colormap = str(j["colormap"], what, where + ".colormap", {"viridis", "inferno", "gray", "coolwarm", "hot"});
    if (j.contains("range")) c.range = vec<2>(j["range"], what, where + ".range");
    if (c.mode == "data" && c.array.empty())
        fail(what, where, "mode 'data' needs 'array' (the name of a per-point or per-streamline array)");
    if (c.mode == "rgb" && c.array.empty()) fail(what, where, "mode 'rgb' needs 'array' (the name of a per-vertex colour array)");
    return c;
}

// Reads `file` (relative to base) or builds a built-in dataset.
Dataset object_data(const Registry &reg, const json &o, const std::string &type, const fs::path &base, const std::string &what,
                    const std::string &where, std::vector<std::string> *files, const MemoryData &memory) {
    Dataset ds;
    if (int(o.contains("file")) + int(o.contains("builtin")) + int(o.contains("data")) != 1)
        fail(what, where, memory.empty() ? "give exactly one of 'file' and 'builtin'" : "give exactly one of 'file', 'builtin' and 'data'");
    if (o.contains("data")) {
        const std::string name = str(o["data"], what, where + ".data");
        const auto it = memory.find(name);
        if (it == memory.end() || !it->second) fail(what, where + ".data", "no dataset in memory is called '" + name + "'");
        return share_dataset(*it->second);
    }
    if (o.contains("file")) {
        fs::path p = str(o["file"], what, where + ".file");
        if (p.is_relative()) p = base / p;
        if (files) files->push_back(p.string());
        ds = read_dataset(reg, p);
        return ds;
    }
    const std::string b =
        str(o["builtin"], what, where + ".builtin", {"phantom", "cortex", "head", "sphere", "brain_bundles", "brain", "t1", "aseg"});
    if (b == "brain_bundles") {
        // (the named bundles of the demo; "phantom": {"streamlines": N, "seed": S})
        if (type != "streamlines") fail(what, where, "builtin 'brain_bundles' is a tractogram (type 'streamlines')");
        std::uint64_t n = 5000, seed = 1;
        if (o.contains("phantom")) {
            const json &p = o["phantom"];
            check_keys(p, {"streamlines", "seed"}, what, where + ".phantom");
            if (p.contains("streamlines"))
                n = static_cast<std::uint64_t>(num_in(p["streamlines"], what, where + ".phantom.streamlines", 0.0, 1e7));
            if (p.contains("seed")) seed = static_cast<std::uint64_t>(num(p["seed"], what, where));
        }
        ds.kind = HZ_DATA_STREAMLINES;
        ds.format = "builtin brain_bundles";
        ds.tractogram = make_brain_phantom(n, seed);
    } else if (b == "phantom") {
        if (type != "streamlines") fail(what, where, "builtin 'phantom' is a tractogram (type 'streamlines')");
        PhantomOptions po;
        if (o.contains("phantom")) {
            const json &p = o["phantom"];
            check_keys(p, {"streamlines", "bundles", "seed"}, what, where + ".phantom");
            // (Bounded before any allocation: 2^32 streamlines grew past 10 GB.
            // A larger realistic tractogram is hz-make-tractogram's job.)
            if (p.contains("streamlines"))
                po.nb_streamlines = static_cast<std::uint64_t>(num_in(p["streamlines"], what, where + ".phantom.streamlines", 0.0, 1e7));
            if (p.contains("bundles"))
                po.nb_bundles = static_cast<std::uint32_t>(num_in(p["bundles"], what, where + ".phantom.bundles", 1.0, 1e4));
            if (p.contains("seed")) po.seed = static_cast<std::uint64_t>(num(p["seed"], what, where));
        }
        ds.kind = HZ_DATA_STREAMLINES;
        ds.format = "builtin phantom";
        ds.tractogram = make_phantom(po);
    } else if (b == "sphere") {
        if (type != "surface") fail(what, where, "builtin 'sphere' is a surface (type 'surface')");
        ds.kind = HZ_DATA_MESH;
        ds.format = "builtin sphere";
        ds.mesh = make_sphere_mesh(50.0, 128, 64);
    } else if (b == "cortex") {
        if (type != "surface") fail(what, where, "builtin 'cortex' is a surface (type 'surface')");
        ds.kind = HZ_DATA_MESH;
        ds.format = "builtin cortex";
        ds.mesh = make_cortex_mesh();
    } else if (b == "brain") {
        if (type != "surface") fail(what, where, "builtin 'brain' is a surface (type 'surface')");
        ds.kind = HZ_DATA_MESH;
        ds.format = "builtin brain";
        ds.mesh = make_brain_surface();
    } else if (b == "aseg") {
        if (type != "labels" && type != "slices") fail(what, where, "builtin 'aseg' is a label volume (type 'labels' or 'slices')");
        ds.kind = HZ_DATA_VOLUME;
        ds.format = "builtin aseg";
        ds.volume = make_aseg_volume();
    } else {
        if (type != "slices" && type != "volume") fail(what, where, "builtin '" + b + "' is a volume (type 'slices' or 'volume')");
        ds.kind = HZ_DATA_VOLUME;
        ds.format = "builtin " + b;
        ds.volume = b == "t1" ? make_t1_volume() : make_head_volume();
    }
    return ds;
}

}  // namespace

// A mesh read from glTF carries its PBR factors as header entries: use them
// for the principled model unless the scene gives a material or a colour.
void apply_file_material(Object &ob, bool has_material, bool has_color) {
    std::map<std::string, std::string> meta(ob.data.metadata.begin(), ob.data.metadata.end());
    if (!meta.count("material.baseColorFactor")) return;
    if (!has_color) {
        std::istringstream in(meta["material.baseColorFactor"]);
        std::array<double, 3> c{};
        // Solid, or the tint of per-vertex colours (glTF: baseColorFactor x COLOR_0).
        if (in >> c[0] >> c[1] >> c[2]) ob.coloring.mode = "solid", ob.coloring.color = c, ob.coloring.tint = c;
    }
    if (!has_material) {
        ob.material.shader = "principled";
        if (meta.count("material.metallicFactor"))
            ob.material.params["metallic"] = {std::clamp(std::atof(meta["material.metallicFactor"].c_str()), 0.0, 1.0)};
        if (meta.count("material.roughnessFactor"))
            ob.material.params["roughness"] = {std::clamp(std::atof(meta["material.roughnessFactor"].c_str()), 0.0, 1.0)};
    }
}

namespace {

// {"view", "position", "target", "up", "fov", "zoom"}, checked.
Camera parse_camera(const json &c, const std::string &what, const std::string &where) {
    Camera cam;
    if (!c.is_object()) fail(what, where, "expected an object {\"view\": ..., \"zoom\": ...} or {\"position\", \"target\", \"up\"}");
    check_keys(c, {"view", "position", "target", "up", "fov", "zoom"}, what, where);
    if (c.contains("view"))
        cam.view = str(c["view"], what, where + ".view", {"left", "right", "anterior", "posterior", "superior", "inferior"});
    if (c.contains("position")) cam.position = vec<3>(c["position"], what, where + ".position");
    if (c.contains("target")) cam.target = vec<3>(c["target"], what, where + ".target");
    if (c.contains("up")) cam.up = vec<3>(c["up"], what, where + ".up");
    if (c.contains("fov")) cam.fov_deg = num_in(c["fov"], what, where + ".fov", 1.0, 150.0);
    if (c.contains("zoom")) cam.zoom = num_in(c["zoom"], what, where + ".zoom", 0.01, 100.0);
    return cam;
}

// {"colormap": name, "opacity": [[fraction, opacity per mm], ...]} (either
// key may be left out: the "mri" preset's), checked.
TransferFunction transfer_from_json(const json &j, const std::string &what, const std::string &where) {
    TransferFunction tf;
    tf.name = "custom";
    if (!j.is_object())
        fail(what, where, "expected a preset name, or an object {\"colormap\": ..., \"opacity\": [[fraction, opacity], ...]}");
    check_keys(j, {"colormap", "opacity", "shade"}, what, where);
    if (j.contains("shade")) {
        if (!j["shade"].is_boolean()) fail(what, where + ".shade", "expected true or false");
        tf.shade = j["shade"].get<bool>();
    }
    if (j.contains("colormap"))
        tf.colormap = str(j["colormap"], what, where + ".colormap", {"viridis", "inferno", "gray", "coolwarm", "hot"});
    if (j.contains("opacity")) {
        const json &o = j["opacity"];
        if (!o.is_array() || o.empty() || o.size() > 256) fail(what, where + ".opacity", "expected 1 to 256 points [fraction, opacity]");
        tf.opacity.clear();
        for (std::size_t i = 0; i < o.size(); ++i) {
            const std::string at = where + ".opacity[" + std::to_string(i) + "]";
            const auto v = vec<2>(o[i], what, at);
            if (!(v[0] >= 0 && v[0] <= 1)) fail(what, at, "the fraction of the window must be in [0, 1], not " + o[i][0].dump());
            if (!(v[1] >= 0 && v[1] <= 1)) fail(what, at, "the opacity of one millimetre must be in [0, 1], not " + o[i][1].dump());
            if (!tf.opacity.empty() && !(v[0] > tf.opacity.back()[0])) fail(what, at, "fractions must increase");
            tf.opacity.push_back(v);
        }
    }
    return tf;
}

}  // namespace

const std::vector<std::string> &transfer_presets() {
    static const std::vector<std::string> names = {"mri", "density", "hot", "glow"};
    return names;
}

TransferFunction transfer_preset(const std::string &name) {
    TransferFunction tf;
    tf.name = name;
    if (name == "mri") return tf;
    if (name == "density") {  // (a density is no surface: unlit)
        tf.colormap = "viridis", tf.opacity = {{0.0, 0.0}, {0.02, 0.0}, {1.0, 0.15}}, tf.shade = false;
        return tf;
    }
    if (name == "hot") {
        tf.colormap = "hot", tf.opacity = {{0.0, 0.0}, {0.5, 0.0}, {1.0, 0.3}};
        return tf;
    }
    if (name == "glow") {
        tf.colormap = "inferno", tf.opacity = {{0.0, 0.0}, {0.6, 0.0}, {1.0, 0.5}};
        return tf;
    }
    std::string list;
    for (const auto &n : transfer_presets()) list += (list.empty() ? "" : ", ") + n;
    throw Error("transfer function: no preset '" + name + "' (presets: " + list + "; or a JSON file)");
}

void check_transfer(const TransferFunction &tf) {
    static const std::set<std::string> maps = {"viridis", "inferno", "gray", "coolwarm", "hot"};
    if (!maps.count(tf.colormap)) throw Error("transfer function: unknown colormap '" + tf.colormap + "'");
    if (tf.opacity.empty() || tf.opacity.size() > 256) throw Error("transfer function: expected 1 to 256 opacity points");
    for (std::size_t i = 0; i < tf.opacity.size(); ++i) {
        const auto &[f, a] = tf.opacity[i];
        if (!(f >= 0 && f <= 1) || !(a >= 0 && a <= 1)) throw Error("transfer function: point " + std::to_string(i) + " is outside [0, 1]");
        if (i > 0 && !(f > tf.opacity[i - 1][0])) throw Error("transfer function: fractions must increase");
    }
}

TransferFunction load_transfer(const fs::path &file) {
    const std::string text = read_small_file(file, 64u << 10, "transfer function");
    const json j = json::parse(text, nullptr, false);
    if (j.is_discarded()) throw Error(file.string() + ": not valid JSON");
    return transfer_from_json(j, file.string(), "transfer function");
}

Dataset share_dataset(const Dataset &d) {
    Dataset c;
    c.kind = d.kind, c.format = d.format, c.loader_id = d.loader_id, c.source_space = d.source_space, c.metadata = d.metadata;
    c.tractogram = d.tractogram.shared();
    c.mesh.vertices = d.mesh.vertices.shared(), c.mesh.faces = d.mesh.faces.shared(), c.mesh.transform = d.mesh.transform;
    for (const DataArray &a : d.mesh.arrays) {
        DataArray b;
        b.name = a.name, b.attach = a.attach, b.dtype = a.dtype, b.components = a.components, b.count = a.count;
        b.bytes = a.bytes.shared();
        c.mesh.arrays.push_back(std::move(b));
    }
    c.volume.dtype = d.volume.dtype, c.volume.dims = d.volume.dims, c.volume.voxels = d.volume.voxels.shared();
    c.volume.scale_slope = d.volume.scale_slope, c.volume.scale_inter = d.volume.scale_inter, c.volume.voxel_to_ras = d.volume.voxel_to_ras;
    c.bounds = d.bounds, c.mapped = d.mapped, c.unaligned = d.unaligned;
    return c;
}

namespace {

// A scene's connectome object: its nodes (spheres coloured by their values
// through `colormap`, a solid colour where they are all equal) and, with
// `edges`, its edges (tubes as thick as their weights, coloured by weight
// through `edge_colormap` over [-largest, largest]: negative ones blue in
// coolwarm).
std::vector<Object> connectome_objects(const Registry &reg, const json &o, const fs::path &base, const std::string &what,
                                       const std::string &where, std::vector<std::string> &files) {
    check_keys(o,
               {"type", "name", "nodes", "edges", "threshold", "node_scale", "edge_radius", "colormap", "edge_colormap", "material",
                "visible", "opacity"},
               what, where);
    if (!o.contains("nodes")) fail(what, where, "a connectome needs 'nodes' (a BrainNet .node file, or x y z per line)");
    fs::path nodes = str(o["nodes"], what, where + ".nodes"), edges;
    if (nodes.is_relative()) nodes = base / nodes;
    files.push_back(nodes.string());
    if (o.contains("edges")) {
        edges = str(o["edges"], what, where + ".edges");
        if (edges.is_relative()) edges = base / edges;
        files.push_back(edges.string());
    }
    ConnectomeOptions co;
    if (o.contains("threshold")) co.threshold = num_in(o["threshold"], what, where + ".threshold", 0.0, 1e300);
    if (o.contains("node_scale")) co.node_scale = num_in(o["node_scale"], what, where + ".node_scale", 1e-3, 100.0);
    if (o.contains("edge_radius")) co.edge_radius = num_in(o["edge_radius"], what, where + ".edge_radius", 1e-3, 100.0);
    const std::set<std::string> maps = {"viridis", "inferno", "gray", "coolwarm", "hot"};
    const std::string node_map = o.contains("colormap") ? str(o["colormap"], what, where + ".colormap", maps) : "viridis";
    const std::string edge_map = o.contains("edge_colormap") ? str(o["edge_colormap"], what, where + ".edge_colormap", maps) : "coolwarm";
    Connectome c;
    try {
        const std::string ext = nodes.extension().string();
        const bool text = ext == ".node" || ext == ".csv" || ext == ".txt" || ext == ".tsv";
        c = text ? read_connectome(nodes, edges) : connectome_of_labels(read_dataset(reg, nodes).volume, nodes.string(), edges);
    } catch (const Error &e) {
        fail(what, where, e.what());
    }
    const std::string name = o.contains("name") ? str(o["name"], what, where + ".name") : "connectome";
    std::vector<Object> out;
    try {
        out = connectome_objects(c, co, name, node_map, edge_map);
    } catch (const Error &e) {
        fail(what, where, e.what());
    }
    for (Object &x : out) {
        if (o.contains("visible")) {
            if (!o["visible"].is_boolean()) fail(what, where + ".visible", "expected true or false");
            x.visible = o["visible"].get<bool>();
        }
        if (o.contains("opacity")) x.opacity = num_in(o["opacity"], what, where + ".opacity", 0.0, 1.0);
        if (o.contains("material")) x.material = parse_material(o["material"], what, where + ".material");
    }
    return out;
}

// {"duration": s, "easing": "smooth"|"linear", "turntable": degrees,
//  "keyframes": [{"time": s, "camera": {...}, "objects": {NAME: {"visible",
//  "x", "y", "z", "params": {...}}}}]}, checked against the scene's objects
// (by name) and their shaders' schemas. A parameter keyed that the object's
// material does not set gets its schema default there (its value at 0).
Timeline parse_timeline(const Registry &reg, const json &t, Scene &s, const std::string &what) {
    Timeline tl;
    if (!t.is_object()) fail(what, "timeline", "expected an object {\"keyframes\": [...], \"duration\": seconds}");
    check_keys(t, {"keyframes", "duration", "easing", "turntable"}, what, "timeline");
    if (t.contains("easing")) tl.smooth = str(t["easing"], what, "timeline.easing", {"smooth", "linear"}) == "smooth";
    if (t.contains("turntable")) tl.turntable_deg = num_in(t["turntable"], what, "timeline.turntable", -36000.0, 36000.0);
    if (!t.contains("keyframes") || !t["keyframes"].is_array() || t["keyframes"].empty())
        fail(what, "timeline.keyframes", "expected a non-empty array of keyframes {\"time\": seconds, ...}");
    std::map<std::string, std::size_t> by_name;
    std::set<std::string> twice;
    for (std::size_t i = 0; i < s.objects.size(); ++i)
        if (!by_name.emplace(s.objects[i].name, i).second) twice.insert(s.objects[i].name);
    for (std::size_t k = 0; k < t["keyframes"].size(); ++k) {
        const json &j = t["keyframes"][k];
        const std::string where = "timeline.keyframes[" + std::to_string(k) + "]";
        if (!j.is_object() || !j.contains("time")) fail(what, where, "expected an object with a 'time' (seconds)");
        check_keys(j, {"time", "camera", "objects"}, what, where);
        Keyframe key;
        key.time = num_in(j["time"], what, where + ".time", 0.0, 3600.0);
        if (!tl.keyframes.empty() && !(key.time > tl.keyframes.back().time))
            fail(what, where + ".time",
                 std::to_string(key.time) + " s is not after the previous keyframe's " + std::to_string(tl.keyframes.back().time) +
                     " s: keyframes go in time order");
        if (j.contains("camera")) key.camera = parse_camera(j["camera"], what, where + ".camera");
        if (j.contains("objects")) {
            if (!j["objects"].is_object())
                fail(what, where + ".objects", "expected an object {NAME: {\"visible\", \"x\", \"params\", ...}}");
            for (const auto &[name, o] : j["objects"].items()) {
                const std::string at = where + ".objects." + name;
                const auto found = by_name.find(name);
                if (found == by_name.end()) {
                    std::string names;
                    for (const auto &[n, i] : by_name) names += (names.empty() ? "" : ", ") + n;
                    fail(what, at, "no object named '" + name + "' (objects: " + names + ")");
                }
                if (twice.count(name)) fail(what, at, "two objects are named '" + name + "': give them names of their own");
                Object &ob = s.objects[found->second];
                if (!o.is_object())
                    fail(what, at, "expected an object {\"visible\", \"opacity\", \"x\", \"y\", \"z\", \"window\", \"params\"}");
                check_keys(o, {"visible", "opacity", "x", "y", "z", "window", "params"}, what, at);
                ObjectKey ok;
                if (o.contains("visible")) {
                    if (!o["visible"].is_boolean()) fail(what, at + ".visible", "expected true or false");
                    ok.visible = o["visible"].get<bool>();
                }
                if (o.contains("opacity")) ok.opacity = num_in(o["opacity"], what, at + ".opacity", 0.0, 1.0);
                if (o.contains("window")) {
                    if (!shows_value_slices(ob) || ob.labels)
                        fail(what, at + ".window", "'" + name + "' has no intensity window (a volume of values has)");
                    ok.window = vec<2>(o["window"], what, at + ".window");
                    if (!((*ok.window)[1] > (*ok.window)[0]))
                        fail(what, at + ".window", "must be [low, high] with high > low, not " + o["window"].dump());
                }
                for (int a = 0; a < 3; ++a) {
                    const std::string ax(1, char('x' + a));
                    if (!o.contains(ax)) continue;
                    if ((ob.kind != HZ_DATA_VOLUME && !ob.peaks && !ob.odfs && !ob.tensors) || ob.transfer)
                        fail(what, at + "." + ax, "'" + name + "' has no slices");
                    ok.slices[std::size_t(a)] =
                        o[ax].is_null() ? std::optional<double>() : std::optional<double>(num(o[ax], what, at + "." + ax));
                }
                if (o.contains("params")) {
                    if (!o["params"].is_object()) fail(what, at + ".params", "expected an object of NAME: value");
                    if (ob.kind == HZ_DATA_VOLUME) fail(what, at + ".params", "'" + name + "' is a volume: it has no material");
                    const LoadedPlugin *plugin = find_shader(reg, ob.material.shader);
                    if (!plugin) fail(what, at + ".params", "no shading plugin '" + ob.material.shader + "'");
                    const std::vector<ParamSpec> schema = schema_of(*plugin);
                    for (const auto &[pn, v] : o["params"].items()) {
                        try {
                            const ParamSpec &spec = find_param(schema, plugin->info.id, pn);
                            if (spec.type == HZ_PARAM_BOOL || spec.type == HZ_PARAM_ENUM || spec.type == HZ_PARAM_INT)
                                throw Error("'" + pn + "' is not a number that can change gradually");
                            ok.params[pn] = param_from_json(spec, v);
                            if (!ob.material.params.count(pn)) ob.material.params[pn] = spec.defaults;
                        } catch (const Error &e) {
                            fail(what, at + ".params." + pn, e.what());
                        }
                    }
                }
                key.objects[found->second] = std::move(ok);
            }
        }
        tl.keyframes.push_back(std::move(key));
    }
    tl.duration = tl.keyframes.back().time;
    if (t.contains("duration")) {
        tl.duration = num_in(t["duration"], what, "timeline.duration", 0.0, 3600.0, true);
        if (tl.duration < tl.keyframes.back().time)
            fail(what, "timeline.duration",
                 std::to_string(tl.duration) + " s ends before the last keyframe (" + std::to_string(tl.keyframes.back().time) + " s)");
    }
    if (!(tl.duration > 0)) fail(what, "timeline", "its duration is 0 s: give \"duration\" or a keyframe after 0 s");
    return tl;
}

}  // namespace

Scene parse_scene(const Registry &reg, const std::string &text, const fs::path &base, const std::string &what, const MemoryData &memory) {
    const json root = json::parse(text, nullptr, false);
    if (root.is_discarded()) throw Error(what + ": not valid JSON");
    check_keys(root,
               {"objects", "camera", "lights", "environment", "background", "exposure", "tonemap", "slab", "ambient_occlusion", "depth_cue",
                "shadows", "antialiasing", "annotations", "timeline", "grid"},
               what, "scene");
    Scene s;
    if (root.contains("ambient_occlusion")) {
        // true | false | {"radius": mm, "strength": 0..1, "on": bool}
        if (const json *a =
                pass_settings(root["ambient_occlusion"], what, "ambient_occlusion", {"on", "radius", "strength"}, s.ambient_occlusion.on,
                              "expected true, false or an object {\"radius\": mm, \"strength\": 0..1}")) {
            if (a->contains("radius"))
                s.ambient_occlusion.radius_mm = num_in((*a)["radius"], what, "ambient_occlusion.radius", 1e-3, 1000.0);
            if (a->contains("strength"))
                s.ambient_occlusion.strength = num_in((*a)["strength"], what, "ambient_occlusion.strength", 0.0, 1.0);
        }
    }
    if (root.contains("depth_cue")) {
        // true | false | strength | {"strength": 0..1, "on": bool}
        const json &d = root["depth_cue"];
        if (d.is_number()) {
            s.depth_cue.on = true;
            s.depth_cue.strength = num_in(d, what, "depth_cue", 0.0, 1.0);
        } else if (const json *a = pass_settings(d, what, "depth_cue", {"on", "strength"}, s.depth_cue.on,
                                                 "expected true, false, a strength in [0, 1] or an object {\"strength\": 0..1}")) {
            if (a->contains("strength")) s.depth_cue.strength = num_in((*a)["strength"], what, "depth_cue.strength", 0.0, 1.0);
        }
    }
    if (root.contains("shadows")) {
        // true | false | {"on": bool, "strength": 0..1, "softness": mm}
        if (const json *a = pass_settings(root["shadows"], what, "shadows", {"on", "strength", "softness"}, s.shadows.on,
                                          "expected true, false or an object {\"strength\": 0..1, \"softness\": mm}")) {
            if (a->contains("strength")) s.shadows.strength = num_in((*a)["strength"], what, "shadows.strength", 0.0, 1.0);
            if (a->contains("softness")) s.shadows.softness_mm = num_in((*a)["softness"], what, "shadows.softness", 0.0, 50.0);
        }
    }
    if (root.contains("antialiasing")) {
        // true | false | {"on": bool, "frames": 1..64}
        if (const json *a = pass_settings(root["antialiasing"], what, "antialiasing", {"on", "frames"}, s.antialiasing.on,
                                          "expected true, false or an object {\"frames\": 1..64}")) {
            if (a->contains("frames")) {
                const double f = num_in((*a)["frames"], what, "antialiasing.frames", 1.0, 64.0);
                if (f != std::floor(f)) fail(what, "antialiasing.frames", "expected a whole number of frames");
                s.antialiasing.frames = int(f);
            }
        }
    }
    if (root.contains("annotations")) {
        // true (all) | false | {"colour_bar": bool, "orientation": bool, "scale_bar": bool}
        const json &a = root["annotations"];
        if (a.is_boolean()) {
            const bool on = a.get<bool>();
            s.annotations = Annotations{on, on, on};
        } else if (a.is_object()) {
            check_keys(a, {"colour_bar", "color_bar", "orientation", "scale_bar"}, what, "annotations");
            auto flag = [&](const char *key, bool &into) {
                if (!a.contains(key)) return;
                if (!a[key].is_boolean()) fail(what, std::string("annotations.") + key, "expected true or false");
                into = a[key].get<bool>();
            };
            flag("colour_bar", s.annotations.colour_bar);
            flag("color_bar", s.annotations.colour_bar);
            flag("orientation", s.annotations.orientation);
            flag("scale_bar", s.annotations.scale_bar);
        } else {
            fail(what, "annotations",
                 "expected true, false or an object {\"colour_bar\": bool, \"orientation\": bool, \"scale_bar\": bool}");
        }
    }
    if (root.contains("camera")) s.camera = parse_camera(root["camera"], what, "camera");
    if (root.contains("lights")) {
        if (!root["lights"].is_array()) fail(what, "lights", "expected an array");
        for (std::size_t i = 0; i < root["lights"].size(); ++i) {
            const json &l = root["lights"][i];
            const std::string where = "lights[" + std::to_string(i) + "]";
            check_keys(l, {"type", "direction", "position", "color", "intensity", "space"}, what, where);
            Light L;
            if (l.contains("type")) L.type = str(l["type"], what, where + ".type", {"directional", "point"});
            if (l.contains("direction")) L.direction = vec<3>(l["direction"], what, where + ".direction");
            if (l.contains("position")) L.position = vec<3>(l["position"], what, where + ".position");
            if (l.contains("color")) L.color = vec<3>(l["color"], what, where + ".color");
            if (l.contains("intensity")) L.intensity = num_in(l["intensity"], what, where + ".intensity", 0.0, 1e6);
            if (l.contains("space")) L.camera_space = str(l["space"], what, where + ".space", {"camera", "world"}) == "camera";
            if (L.type == "directional" && L.direction == Vec3{0, 0, 0}) fail(what, where + ".direction", "must not be zero");
            s.lights.push_back(L);
        }
        if (s.lights.size() > 8) fail(what, "lights", "at most 8 lights");
    }
    if (root.contains("environment")) {
        const json &e = root["environment"];
        check_keys(e, {"type", "path", "intensity", "rotation", "visible"}, what, "environment");
        if (e.contains("type")) s.environment.type = str(e["type"], what, "environment.type", {"studio", "file", "none"});
        if (e.contains("path")) {
            fs::path p = str(e["path"], what, "environment.path");
            if (p.is_relative()) p = base / p;
            s.environment.path = p.string();
            s.files.push_back(p.string());
            if (!e.contains("type")) s.environment.type = "file";
        }
        if (s.environment.type == "file" && s.environment.path.empty()) fail(what, "environment", "type 'file' needs 'path'");
        if (e.contains("intensity")) s.environment.intensity = num_in(e["intensity"], what, "environment.intensity", 0.0, 1e6);
        if (e.contains("rotation")) s.environment.rotation_deg = num(e["rotation"], what, "environment.rotation");
        if (e.contains("visible")) {
            if (!e["visible"].is_boolean()) fail(what, "environment.visible", "expected true or false");
            s.environment.visible = e["visible"].get<bool>();
        }
    }
    if (root.contains("background")) s.background = vec<3>(root["background"], what, "background");
    if (root.contains("exposure")) s.exposure = num_in(root["exposure"], what, "exposure", 1e-4, 1e4);
    if (root.contains("tonemap")) s.tonemap = str(root["tonemap"], what, "tonemap", {"aces", "reinhard", "none"});
    if (root.contains("slab")) {  // {"axis": "x"|"y"|"z", "centre": mm, "half": mm, "show": "crop"|"points", "point_size": px}
        const json &j = root["slab"];
        if (!j.is_object()) fail(what, "slab", "expected an object {\"axis\", \"centre\", \"half\"}");
        check_keys(j, {"axis", "centre", "half", "show", "point_size"}, what, "slab");
        Slab sl;
        if (j.contains("axis")) sl.axis = int(str(j["axis"], what, "slab.axis", {"x", "y", "z"})[0] - 'x');
        if (j.contains("centre")) sl.centre = num_in(j["centre"], what, "slab.centre", -1e5, 1e5);
        if (j.contains("half")) sl.half = num_in(j["half"], what, "slab.half", 0.0, 1e5, true);
        if (j.contains("show")) sl.points = str(j["show"], what, "slab.show", {"crop", "points"}) == "points";
        if (j.contains("point_size")) sl.point_px = num_in(j["point_size"], what, "slab.point_size", 1.0, 64.0);
        s.slab = sl;
    }

    if (!root.contains("objects") || !root["objects"].is_array()) fail(what, "objects", "expected an array of objects");
    for (std::size_t i = 0; i < root["objects"].size(); ++i) {
        const json &o_all = root["objects"][i];
        const std::string where = "objects[" + std::to_string(i) + "]";
        if (!o_all.is_object() || !o_all.contains("type")) fail(what, where, "expected an object with a 'type'");
        // (a grid cell, any object's: checked here, then out of the way of each type's keys)
        int cell = -1;
        json o_cell = o_all;
        if (o_all.contains("cell")) {
            if (!root.contains("grid")) fail(what, where + ".cell", "the scene has no \"grid\": give one, or leave the cells out");
            const double c = num_in(o_all["cell"], what, where + ".cell", 0.0, 1023.0);
            if (c != std::floor(c)) fail(what, where + ".cell", "expected a whole number 0 to 1023");
            cell = int(c);
            o_cell.erase("cell");
        }
        const json &o = o_cell;
        const std::string type = str(o["type"], what, where + ".type",
                                     {"streamlines", "surface", "slices", "volume", "peaks", "odfs", "tensors", "connectome", "labels"});
        if (type == "connectome") {  // (two objects: its nodes and its edges)
            for (Object &part : connectome_objects(reg, o, base, what, where, s.files)) {
                part.cell = cell;
                s.objects.push_back(std::move(part));
            }
            continue;
        }
        Object ob;
        ob.name = type + " " + std::to_string(i);
        ob.cell = cell;
        if (type == "streamlines") {
            check_keys(o,
                       {"type", "name", "file", "builtin", "data", "phantom", "render", "radius", "color", "material", "clustering",
                        "visible", "opacity", "include", "exclude", "min_length", "max_length", "buan"},
                       what, where);
            ob.coloring.mode = "direction";
        } else if (type == "surface") {
            check_keys(
                o, {"type", "name", "file", "builtin", "data", "overlays", "color", "material", "visible", "opacity", "above", "smoothing"},
                what, where);
            ob.coloring.color = {0.85, 0.72, 0.68};
        } else if (type == "volume") {
            check_keys(o, {"type", "name", "file", "builtin", "data", "window", "transfer", "visible", "opacity", "volume_index"}, what,
                       where);
            ob.transfer = transfer_preset("mri");
            if (o.contains("transfer")) {
                const json &t = o["transfer"];
                if (t.is_string()) {
                    const std::string v = t.get<std::string>();
                    const bool file = fs::path(v).extension() == ".json";
                    if (file) s.files.push_back((base / v).string());
                    try {
                        ob.transfer = file ? load_transfer(base / v) : transfer_preset(v);
                    } catch (const Error &e) {
                        fail(what, where + ".transfer", e.what());
                    }
                } else if (t.is_object() && t.contains("file")) {
                    check_keys(t, {"file"}, what, where + ".transfer");
                    const fs::path f = base / str(t["file"], what, where + ".transfer.file");
                    s.files.push_back(f.string());
                    try {
                        ob.transfer = load_transfer(f);
                    } catch (const Error &e) {
                        fail(what, where + ".transfer", e.what());
                    }
                } else {
                    ob.transfer = transfer_from_json(t, what, where + ".transfer");
                }
            }
        } else if (type == "peaks") {
            check_keys(o,
                       {"type", "name", "file", "data", "x", "y", "z", "whole", "scale", "by_value", "threshold", "frame", "render",
                        "radius", "color", "material", "visible", "opacity"},
                       what, where);
            ob.coloring.mode = "direction";
        } else if (type == "tensors") {
            check_keys(o,
                       {"type", "name", "file", "data", "x", "y", "z", "order", "sphere", "scale", "normalise", "color", "material",
                        "visible", "opacity"},
                       what, where);
        } else if (type == "odfs") {
            check_keys(o,
                       {"type", "name", "file", "data", "x", "y", "z", "basis", "legacy", "sphere", "scale", "normalise", "color",
                        "material", "visible", "opacity"},
                       what, where);
        } else if (type == "labels") {
            check_keys(o,
                       {"type", "name", "file", "builtin", "data", "x", "y", "z", "lut", "labels", "fill", "outline", "surfaces",
                        "smoothing", "visible", "opacity"},
                       what, where);
        } else {
            check_keys(o,
                       {"type", "name", "file", "builtin", "data", "x", "y", "z", "window", "colormap", "clip_below", "visible", "opacity",
                        "volume_index", "rgb"},
                       what, where);
        }
        if (o.contains("name")) ob.name = str(o["name"], what, where + ".name");
        if (o.contains("visible")) {
            if (!o["visible"].is_boolean()) fail(what, where + ".visible", "expected true or false");
            ob.visible = o["visible"].get<bool>();
        }
        if (o.contains("opacity")) ob.opacity = num_in(o["opacity"], what, where + ".opacity", 0.0, 1.0);
        if (o.contains("render")) ob.render = str(o["render"], what, where + ".render", {"lines", "tubes"});
        if (o.contains("radius")) ob.radius_mm = num_in(o["radius"], what, where + ".radius", 1e-3, 100.0);
        if (o.contains("color")) ob.coloring = parse_coloring(o["color"], what, where + ".color");
        if (o.contains("material")) ob.material = parse_material(o["material"], what, where + ".material");
        for (const char *ax : {"x", "y", "z"})
            if (o.contains(ax) && !o[ax].is_null()) {
                const double v = num(o[ax], what, where + "." + ax);
                (ax[0] == 'x' ? ob.slice_x : ax[0] == 'y' ? ob.slice_y : ob.slice_z) = v;
            }
        if (o.contains("clip_below") && !o["clip_below"].is_null()) ob.clip_below = num(o["clip_below"], what, where + ".clip_below");
        if (o.contains("rgb")) {
            if (!o["rgb"].is_boolean()) fail(what, where + ".rgb", "expected true or false");
            ob.rgb = o["rgb"].get<bool>();
        }
        if (o.contains("volume_index"))
            ob.volume_index = std::uint64_t(num_in(o["volume_index"], what, where + ".volume_index", 0.0, 1e12));
        if (o.contains("window")) {
            ob.window = vec<2>(o["window"], what, where + ".window");
            if (!((*ob.window)[1] > (*ob.window)[0]))
                fail(what, where + ".window", "must be [low, high] with high > low, not " + o["window"].dump());
        }
        if (o.contains("colormap"))
            ob.slice_colormap = str(o["colormap"], what, where + ".colormap", {"viridis", "inferno", "gray", "coolwarm", "hot"});
        if (o.contains("clustering")) {
            const json &c = o["clustering"];
            check_keys(c, {"algorithm", "thresholds", "level", "subtrees", "width_by_size", "params", "min_size", "min_length"}, what,
                       where + ".clustering");
            ClusterSpec cs;
            if (c.contains("algorithm")) {
                if (!c["algorithm"].is_string()) fail(what, where + ".clustering.algorithm", "expected a plugin id");
                cs.algorithm = c["algorithm"].get<std::string>();
                try {
                    find_clustering(reg, cs.algorithm);
                } catch (const Error &e) {
                    fail(what, where + ".clustering.algorithm", e.what());
                }
            }
            if (c.contains("params")) {
                if (!c["params"].is_object()) fail(what, where + ".clustering.params", "expected an object of NAME: value");
                const LoadedPlugin *plugin = nullptr;
                try {
                    plugin = find_clustering(reg, cs.algorithm);
                } catch (const Error &e) {
                    fail(what, where + ".clustering.algorithm", e.what());
                }
                const std::vector<ParamSpec> schema = schema_of(*plugin);
                for (const auto &[k, v] : c["params"].items()) {
                    try {
                        cs.params[k] = param_from_json(find_param(schema, plugin->info.id, k), v);
                    } catch (const Error &e) {
                        fail(what, where + ".clustering.params." + k, e.what());
                    }
                }
            }
            if (c.contains("thresholds")) {
                if (!c["thresholds"].is_array()) fail(what, where + ".clustering.thresholds", "expected an array of numbers");
                for (const auto &t : c["thresholds"]) cs.thresholds.push_back(num(t, what, where + ".clustering.thresholds"));
            }
            if (c.contains("level") && c["level"].is_array()) {  // (the tree as a figure: several levels)
                for (const auto &l : c["level"]) cs.levels.push_back(static_cast<int>(num(l, what, where + ".clustering.level")));
                if (cs.levels.empty()) fail(what, where + ".clustering.level", "expected a level or a non-empty array of levels");
            } else if (c.contains("level")) {
                cs.level = static_cast<int>(num(c["level"], what, where + ".clustering.level"));
            }
            if (c.contains("subtrees")) {
                if (!c["subtrees"].is_array()) fail(what, where + ".clustering.subtrees", "expected an array of cluster indices");
                for (const auto &k : c["subtrees"]) {
                    const double v = num(k, what, where + ".clustering.subtrees");
                    if (v < 0 || v != std::floor(v) || v > 1e15) fail(what, where + ".clustering.subtrees", "expected whole numbers >= 0");
                    cs.subtrees.push_back(std::uint64_t(v));
                }
            }
            if (c.contains("width_by_size")) cs.width_by_size = c["width_by_size"].get<bool>();
            if (c.contains("min_size")) {
                const double m = num(c["min_size"], what, where + ".clustering.min_size");
                if (m < 0 || m != std::floor(m) || m > 1e15)
                    fail(what, where + ".clustering.min_size", "expected a whole number of streamlines >= 0");
                cs.min_size = std::uint64_t(m);
            }
            if (c.contains("min_length")) {
                cs.min_length_mm = num(c["min_length"], what, where + ".clustering.min_length");
                if (!(cs.min_length_mm >= 0) || cs.min_length_mm > 1e6) fail(what, where + ".clustering.min_length", "expected mm >= 0");
            }
            ob.clustering = cs;
        }
        try {
            ob.data = object_data(reg, o, type, base, what, where, &s.files, memory);
        } catch (const Error &e) {
            const std::string m = e.what();
            if (m.rfind(what + ":", 0) == 0) throw;
            fail(what, where, m);  // name the scene file and the object too
        }
        const hz_data_kind want = type == "streamlines" ? HZ_DATA_STREAMLINES : type == "surface" ? HZ_DATA_MESH : HZ_DATA_VOLUME;
        if (want == HZ_DATA_MESH && ob.data.kind == HZ_DATA_VOLUME) {
            // A volume as a surface: the boundary of its voxels above "above" (default 0: a mask's).
            const double above = o.contains("above") ? num(o["above"], what, where + ".above") : 0.0;
            int smoothing = 20;
            if (o.contains("smoothing")) {
                const double v = num_in(o["smoothing"], what, where + ".smoothing", 0.0, 100.0);
                if (v != std::floor(v)) fail(what, where + ".smoothing", "expected a whole number of iterations");
                smoothing = int(v);
            }
            Dataset ds;
            ds.kind = HZ_DATA_MESH;
            ds.format = ob.data.format + " surface";
            ds.loader_id = ob.data.loader_id;
            ds.source_space = HZ_SPACE_RASMM;
            try {
                ds.mesh = mask_surface(ob.data.volume, above, smoothing, what + ": " + where);
            } catch (const Error &e) {
                fail(what, where, e.what());
            }
            ob.data = std::move(ds);
        } else if (type == "surface" && (o.contains("above") || o.contains("smoothing"))) {
            fail(what, where,
                 "'above' and 'smoothing' make a surface from a volume; this file holds " + std::string(kind_name(ob.data.kind)));
        }
        if (ob.data.kind != want)
            fail(what, where, std::string("the file holds ") + kind_name(ob.data.kind) + ", not what type '" + type + "' shows");
        ob.kind = want;
        if (type == "peaks") {
            PeakOptions po;
            if (o.contains("scale")) po.scale = num_in(o["scale"], what, where + ".scale", 1e-3, 100.0);
            if (o.contains("threshold")) po.threshold = num_in(o["threshold"], what, where + ".threshold", 0.0, 0.999);
            if (o.contains("frame")) po.frame = str(o["frame"], what, where + ".frame", {"world", "voxel"});
            for (const char *key : {"whole", "by_value"})
                if (o.contains(key)) {
                    if (!o[key].is_boolean()) fail(what, where + "." + key, "expected true or false");
                    (std::string(key) == "whole" ? po.whole : po.by_value) = o[key].get<bool>();
                }
            if (po.whole && (o.contains("x") || o.contains("y") || o.contains("z")))
                fail(what, where, "'whole' draws every voxel's peaks: give it or slices (x, y, z), not both");
            try {
                show_as_peaks(ob, po, what + ": " + where);
            } catch (const Error &e) {
                fail(what, where, e.what());
            }
        }
        if (type == "tensors") {
            TensorOptions to;
            if (o.contains("order")) to.order = str(o["order"], what, where + ".order", {"dipy", "fsl", "mrtrix3"});
            if (o.contains("sphere")) to.sphere = int(num_in(o["sphere"], what, where + ".sphere", 0.0, 5.0));
            if (o.contains("scale")) to.scale = num_in(o["scale"], what, where + ".scale", 1e-3, 100.0);
            if (o.contains("normalise")) to.normalise = str(o["normalise"], what, where + ".normalise", {"max", "none"});
            try {
                show_as_tensors(ob, to, what + ": " + where);
            } catch (const Error &e) {
                fail(what, where, e.what());
            }
            if (o.contains("color")) ob.coloring = parse_coloring(o["color"], what, where + ".color");
        }
        if (type == "odfs") {
            OdfOptions oo;
            if (o.contains("basis")) oo.basis = str(o["basis"], what, where + ".basis", {"descoteaux07", "tournier07", "mrtrix3"});
            if (oo.basis == "mrtrix3") oo.basis = "tournier07", oo.legacy = false;
            if (o.contains("legacy")) {
                if (!o["legacy"].is_boolean()) fail(what, where + ".legacy", "expected true or false");
                oo.legacy = o["legacy"].get<bool>();
            }
            if (o.contains("sphere")) oo.sphere = int(num_in(o["sphere"], what, where + ".sphere", 0.0, 5.0));
            if (o.contains("scale")) oo.scale = num_in(o["scale"], what, where + ".scale", 1e-3, 100.0);
            if (o.contains("normalise")) oo.normalise = str(o["normalise"], what, where + ".normalise", {"minmax", "max", "none"});
            try {
                show_as_odfs(ob, oo, what + ": " + where);
            } catch (const Error &e) {
                fail(what, where, e.what());
            }
            if (o.contains("color")) ob.coloring = parse_coloring(o["color"], what, where + ".color");
        }
        std::optional<Object> label_surfaces;
        if (type == "labels") {
            LabelOptions lo;
            if (ob.data.format == "builtin aseg") lo.table = aseg_table();
            if (o.contains("lut")) {
                fs::path p = str(o["lut"], what, where + ".lut");
                if (p.is_relative()) p = base / p;
                s.files.push_back(p.string());
                try {
                    lo.table = read_label_table(p);
                } catch (const Error &e) {
                    fail(what, where + ".lut", e.what());
                }
            }
            if (o.contains("labels")) {
                if (!o["labels"].is_array() || o["labels"].empty())
                    fail(what, where + ".labels", "expected an array of labels (whole numbers)");
                for (const auto &l : o["labels"]) {
                    const double v = num(l, what, where + ".labels");
                    if (v != std::floor(v) || std::abs(v) >= 16777216.0) fail(what, where + ".labels", "expected whole numbers below 2^24");
                    lo.only.push_back(std::int64_t(v));
                }
            }
            if (o.contains("fill")) lo.fill = num_in(o["fill"], what, where + ".fill", 0.0, 1.0);
            for (const char *key : {"outline", "surfaces"})
                if (o.contains(key)) {
                    if (!o[key].is_boolean()) fail(what, where + "." + key, "expected true or false");
                    (std::string(key) == "outline" ? lo.outline : lo.surfaces) = o[key].get<bool>();
                }
            if (o.contains("smoothing")) {
                const double v = num_in(o["smoothing"], what, where + ".smoothing", 0.0, 100.0);
                if (v != std::floor(v)) fail(what, where + ".smoothing", "expected a whole number of iterations");
                lo.smoothing = int(v);
            }
            try {
                label_surfaces = show_as_labels(ob, lo, what + ": " + where);
            } catch (const Error &e) {
                fail(what, where, e.what());
            }
            // (x, y and z all null: no slice, the surfaces alone)
            if (o.contains("x") && o.contains("y") && o.contains("z") && o["x"].is_null() && o["y"].is_null() && o["z"].is_null())
                ob.slice_x.reset(), ob.slice_y.reset(), ob.slice_z.reset();
        }
        if (want == HZ_DATA_MESH && is_overlay(ob.data))
            fail(what, where, "the file holds per-vertex values only; give the surface in 'file' and this file in 'overlays'");
        if (want == HZ_DATA_MESH && !ob.data.metadata.empty()) apply_file_material(ob, o.contains("material"), o.contains("color"));
        // A surface with per-vertex colours (glTF COLOR_0) shows them by default, tinted by the file's base colour.
        if (want == HZ_DATA_MESH && !o.contains("color")) {
            const std::string rgb = colour_array(ob.data.mesh);
            if (!rgb.empty()) ob.coloring.mode = "rgb", ob.coloring.array = rgb;
        }
        if (o.contains("overlays")) {
            // Per-vertex values from other files (curv, thickness, overlay-only GIFTI).
            const json &ov = o["overlays"];
            if (!ov.is_array() && !ov.is_string()) fail(what, where + ".overlays", "expected a file name or an array of file names");
            const json list = ov.is_string() ? json::array({ov}) : ov;
            std::vector<std::string> added;
            for (std::size_t k = 0; k < list.size(); ++k) {
                const std::string at = where + ".overlays[" + std::to_string(k) + "]";
                fs::path p = str(list[k], what, at);
                if (p.is_relative()) p = base / p;
                s.files.push_back(p.string());
                try {
                    const auto names = attach_overlay(ob.data.mesh, read_dataset(reg, p), p.string());
                    added.insert(added.end(), names.begin(), names.end());
                } catch (const Error &e) {
                    fail(what, at, e.what());
                }
            }
            if (!o.contains("color")) colour_by_overlay(ob, added);
        }

        if (type == "streamlines" &&
            (o.contains("include") || o.contains("exclude") || o.contains("min_length") || o.contains("max_length"))) {
            // The streamlines regions of interest and lengths select (the
            // rules of `horizon filter`; relative mask files from the scene's folder).
            FilterSpec f;
            for (const char *key : {"include", "exclude"}) {
                if (!o.contains(key)) continue;
                const json &list = o[key].is_string() ? json::array({o[key]}) : o[key];
                if (!list.is_array())
                    fail(what, where + "." + key, "expected a region (sphere:X,Y,Z,R, box:..., or a mask file) or an array of them");
                for (std::size_t k = 0; k < list.size(); ++k) {
                    const std::string at = where + "." + key + "[" + std::to_string(k) + "]";
                    std::string spec = str(list[k], what, at);
                    if (spec.rfind("sphere:", 0) != 0 && spec.rfind("box:", 0) != 0) {  // a mask file
                        if (fs::path(spec).is_relative()) spec = (base / spec).string();
                        s.files.push_back(spec);
                    }
                    try {
                        f.rois.push_back(parse_roi(reg, spec, std::string(key) == "include"));
                    } catch (const Error &e) {
                        fail(what, at, e.what());
                    }
                }
            }
            if (o.contains("min_length")) f.min_length = num_in(o["min_length"], what, where + ".min_length", 0.0, 1e6);
            if (o.contains("max_length")) f.max_length = num_in(o["max_length"], what, where + ".max_length", 0.0, 1e6);
            const std::vector<std::uint64_t> kept = filter_streamlines(ob.data.tractogram, f);
            if (kept.empty()) fail(what, where, "no streamline is selected (" + f.describe() + ")");
            ob.data.tractogram = subset_with_arrays(ob.data.tractogram, kept);
            ob.data.bounds = core::Bounds{};
        }
        if (type == "slices" && !ob.slice_x && !ob.slice_y && !ob.slice_z) {
            // Default: the three slices through the volume's centre.
            ob.slice_x = ob.slice_y = ob.slice_z = std::nan("");
        }
        if (o.contains("buan")) {  // {"pvalues": FILE.npy, "threshold": p, "highlight": [r, g, b]}
            const json &b = o["buan"];
            if (!b.is_object() || !b.contains("pvalues")) fail(what, where + ".buan", "expected {\"pvalues\": FILE.npy, \"threshold\": p}");
            check_keys(b, {"pvalues", "threshold", "highlight"}, what, where + ".buan");
            if (ob.clustering) fail(what, where + ".buan", "a BUAN profile is drawn on the bundle's streamlines, not on clusters");
            fs::path p = str(b["pvalues"], what, where + ".buan.pvalues");
            if (p.is_relative()) p = base / p;
            s.files.push_back(p.string());
            const double thr = b.contains("threshold") ? num_in(b["threshold"], what, where + ".buan.threshold", 0.0, 1.0, true) : 0.05;
            const std::array<double, 3> hl =
                b.contains("highlight") ? vec<3>(b["highlight"], what, where + ".buan.highlight") : ob.coloring.mark_color;
            try {
                show_buan(ob, read_npy_vector(p), thr, hl, p.string());
            } catch (const Error &e) {
                fail(what, where + ".buan", e.what());
            }
        }
        if (ob.clustering) {
            try {
                ob.data.tractogram = cluster_centroids(reg, ob.data.tractogram, *ob.clustering);
                ob.data.bounds = core::Bounds{};  // (those of the streamlines, not of their centroids)
            } catch (const Error &e) {
                fail(what, where + ".clustering", e.what());
            }
            if (!o.contains("render")) ob.render = "tubes";
            if (ob.clustering->levels.size() > 1 && !o.contains("color")) ob.coloring.mode = "cluster";  // (each subtree its colour)
        }
        if (ob.coloring.mode == "cluster" && ob.kind != HZ_DATA_STREAMLINES)
            fail(what, where + ".color", "mode 'cluster' is for streamlines");
        if (o.contains("file")) ob.file = (base / o["file"].get<std::string>()).string();
        if (label_surfaces) label_surfaces->file = ob.file, label_surfaces->cell = ob.cell;
        s.objects.push_back(std::move(ob));
        if (label_surfaces) s.objects.push_back(std::move(*label_surfaces));
    }
    if (root.contains("grid")) {
        const json &g = root["grid"];
        if (!g.is_object()) fail(what, "grid", "expected an object {\"columns\": N, \"titles\": [...]}");
        check_keys(g, {"columns", "titles"}, what, "grid");
        SubjectGrid grid;
        if (g.contains("columns")) {
            const double c = num_in(g["columns"], what, "grid.columns", 1.0, 64.0);
            if (c != std::floor(c)) fail(what, "grid.columns", "expected a whole number 1 to 64");
            grid.columns = int(c);
        }
        const std::size_t cells = grid_cells(s).size();
        if (cells == 0) fail(what, "grid", "no object has a \"cell\": give each subject's objects theirs (0, 1, ...)");
        if (g.contains("titles")) {
            if (!g["titles"].is_array()) fail(what, "grid.titles", "expected an array of texts, one a cell");
            for (const auto &t : g["titles"]) grid.titles.push_back(str(t, what, "grid.titles"));
            if (grid.titles.size() > cells)
                fail(what, "grid.titles", std::to_string(grid.titles.size()) + " titles for " + std::to_string(cells) + " cells");
        }
        s.grid = grid;
    }
    if (root.contains("timeline")) s.timeline = parse_timeline(reg, root["timeline"], s, what);
    return s;
}

void show_buan(Object &o, const std::vector<double> &pvalues, double threshold, const std::array<double, 3> &highlight,
               const std::string &what) {
    if (o.kind != HZ_DATA_STREAMLINES) throw Error(what + ": a BUAN profile is drawn on a bundle's streamlines");
    if (pvalues.empty()) throw Error(what + ": no value: a profile has one a segment");
    for (std::size_t i = 0; i < pvalues.size(); ++i)
        if (!std::isfinite(pvalues[i])) throw Error(what + ": value " + std::to_string(i) + " is not a number");
    if (!(threshold > 0 && threshold <= 1)) throw Error(what + ": a p-value threshold is in (0, 1], not " + std::to_string(threshold));
    for (double c : highlight)
        if (!(c >= 0 && c <= 1)) throw Error(what + ": the highlight is R, G, B in [0, 1]");
    Tractogram &t = o.data.tractogram;
    if (t.gap != 0) {  // (a TCK file mapped in place: per-point arrays need a copy without its delimiters)
        std::vector<std::uint64_t> all(t.nb_streamlines());
        for (std::uint64_t s = 0; s < all.size(); ++s) all[s] = s;
        t = subset_with_arrays(t, all);
    }
    const std::vector<std::uint32_t> seg = buan_segments(t, std::uint32_t(std::min<std::size_t>(pvalues.size(), 100000)));
    std::vector<float> segment(seg.size()), significant(seg.size());
    for (std::size_t i = 0; i < seg.size(); ++i) {
        segment[i] = float(seg[i]);
        significant[i] = seg[i] < pvalues.size() && pvalues[seg[i]] < threshold ? 1.0f : 0.0f;
    }
    std::erase_if(t.arrays, [](const DataArray &a) { return a.name == "buan_segment" || a.name == "buan_significant"; });
    t.arrays.push_back(f32_array("buan_segment", HZ_ATTACH_VERTEX, segment));
    t.arrays.push_back(f32_array("buan_significant", HZ_ATTACH_VERTEX, significant));
    o.coloring.mark = "buan_significant";
    o.coloring.mark_color = highlight;
}

std::vector<int> grid_cells(const Scene &s) {
    std::vector<int> cells;
    for (const Object &o : s.objects)
        if (o.cell >= 0) cells.push_back(o.cell);
    std::sort(cells.begin(), cells.end());
    cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    return cells;
}

namespace {
// The slices of a glyph object: as set, or the three through the grid's
// centre when none is; NaN the middle of its axis.
void centre_slices(Object &o, const Bounds &box) {
    if (!o.slice_x && !o.slice_y && !o.slice_z) o.slice_x = o.slice_y = o.slice_z = std::nan("");
    std::optional<double> *at[3] = {&o.slice_x, &o.slice_y, &o.slice_z};
    for (int a = 0; a < 3; ++a)
        if (*at[a] && std::isnan(**at[a])) *at[a] = (box.min[a] + box.max[a]) / 2;
}

}  // namespace

std::optional<Object> show_as_labels(Object &o, const LabelOptions &opt, const std::string &what) {
    if (o.data.kind != HZ_DATA_VOLUME) throw Error(what + ": labels are read from a volume, not " + std::string(kind_name(o.data.kind)));
    if (o.volume_index != 0) throw Error(what + ": a label volume is 3D: it has no series to index");
    auto field = std::make_shared<const LabelField>(make_label_field(o.data.volume, opt, what));
    if (!o.slice_x && !o.slice_y && !o.slice_z) o.slice_x = o.slice_y = o.slice_z = std::nan("");
    o.kind = HZ_DATA_VOLUME;
    o.labels = field;
    o.transfer.reset();
    o.rgb = false;
    if (!opt.surfaces) return std::nullopt;
    Object surf;
    surf.name = o.name + " surfaces";
    surf.kind = HZ_DATA_MESH;
    surf.visible = o.visible;
    surf.opacity = o.opacity;
    surf.data.kind = HZ_DATA_MESH;
    surf.data.format = o.data.format + " label surfaces";
    surf.data.loader_id = o.data.loader_id;
    surf.data.source_space = HZ_SPACE_RASMM;
    surf.data.mesh = label_surfaces(*field);
    if (surf.data.mesh.nb_faces() == 0) throw Error(what + ": no label to draw as a surface");
    surf.coloring.mode = "rgb";
    surf.coloring.array = "rgb";
    surf.material.params["roughness"] = {0.5};
    return surf;
}

void show_as_peaks(Object &o, const PeakOptions &opt, const std::string &what) {
    if (!o.peaks && o.data.kind != HZ_DATA_VOLUME)
        throw Error(what + ": peaks are read from a volume, not " + std::string(kind_name(o.data.kind)));
    // (peaks already: drawn again with these options from the same voxels)
    auto field = std::make_shared<const PeakField>(make_peak_field(o.peaks ? o.peaks->volume : o.data.volume, opt, what));
    const std::string format = o.peaks ? o.data.format : o.data.format + " peaks";
    if (opt.whole)
        o.slice_x.reset(), o.slice_y.reset(), o.slice_z.reset();
    else
        centre_slices(o, peak_grid_box(*field));
    Dataset ds;
    ds.kind = HZ_DATA_STREAMLINES;
    ds.format = format;
    ds.loader_id = o.data.loader_id;
    ds.source_space = HZ_SPACE_RASMM;
    ds.tractogram = peak_lines(*field, o.slice_x, o.slice_y, o.slice_z);
    ds.bounds = peak_bounds(*field, ds.tractogram);
    o.data = std::move(ds);
    o.kind = HZ_DATA_STREAMLINES;
    o.peaks = std::move(field);
    if (o.coloring.mode == "solid" && o.coloring.array.empty() && o.coloring.color == Coloring{}.color) o.coloring.mode = "direction";
    o.transfer.reset();
    o.rgb.reset();
}

namespace {
// Object `o` becomes a surface of glyphs: `mesh`, in `bounds`, coloured by
// its per-vertex array `colours`.
void become_glyph_mesh(Object &o, Mesh mesh, const Bounds &bounds, const std::string &format, const std::string &colours) {
    Dataset ds;
    ds.kind = HZ_DATA_MESH;
    ds.format = format;
    ds.loader_id = o.data.loader_id;
    ds.source_space = HZ_SPACE_RASMM;
    ds.mesh = std::move(mesh);
    ds.bounds = bounds;
    o.data = std::move(ds);
    o.kind = HZ_DATA_MESH;
    o.coloring.mode = "rgb", o.coloring.array = colours;
    o.transfer.reset();
    o.rgb.reset();
}
}  // namespace

void show_as_odfs(Object &o, const OdfOptions &opt, const std::string &what) {
    if (!o.odfs && o.data.kind != HZ_DATA_VOLUME)
        throw Error(what + ": ODFs are read from a volume of SH coefficients, not " + std::string(kind_name(o.data.kind)));
    OdfField made = make_odf_field(o.odfs ? o.odfs->volume : o.data.volume, opt, what);
    if (opt.sphere >= 1) made.coarser = std::make_shared<const OdfField>(coarser_odf_field(made));
    auto field = std::make_shared<const OdfField>(std::move(made));
    const std::string format = o.odfs ? o.data.format : o.data.format + " odfs";
    centre_slices(o, grid_box(field->volume.dims, field->volume.voxel_to_ras));
    become_glyph_mesh(o, odf_glyphs(*field, o.slice_x, o.slice_y, o.slice_z, opt.sphere), odf_bounds(*field), format, "direction");
    o.odfs = std::move(field);
    o.moving_mesh = moving_glyph_mesh(o, o.slice_x, o.slice_y, o.slice_z);
}

std::vector<Object> connectome_objects(const Connectome &c, const ConnectomeOptions &co, const std::string &name,
                                       const std::string &node_map, const std::string &edge_map) {
    Object n;
    n.name = name + " nodes";
    n.kind = n.data.kind = HZ_DATA_MESH;
    n.data.format = "connectome nodes";
    n.data.mesh = connectome_nodes(c, co);
    const auto [lo, hi] = std::minmax_element(c.colour.begin(), c.colour.end());
    if (*hi > *lo) {
        n.coloring.mode = "data", n.coloring.array = "node_value", n.coloring.colormap = node_map;
        n.coloring.range = std::array<double, 2>{*lo, *hi};
    } else {
        n.coloring.color = {0.8, 0.25, 0.15};
    }
    std::vector<Object> out;
    out.push_back(std::move(n));
    if (!c.weights.empty()) {
        Object e;
        e.name = name + " edges";
        e.kind = e.data.kind = HZ_DATA_STREAMLINES;
        e.data.format = "connectome edges";
        e.data.tractogram = connectome_edges(c, co);
        e.render = "tubes";
        double largest = 0;
        for (double w : c.weights) largest = std::max(largest, std::abs(w));
        e.coloring.mode = "data", e.coloring.array = "weight", e.coloring.colormap = edge_map;
        e.coloring.range = std::array<double, 2>{-largest, largest > 0 ? largest : 1.0};
        if (e.data.tractogram.nb_streamlines() > 0) out.push_back(std::move(e));
    }
    return out;
}

void show_as_tensors(Object &o, const TensorOptions &opt, const std::string &what) {
    if (!o.tensors && o.data.kind != HZ_DATA_VOLUME)
        throw Error(what + ": tensors are read from a volume of 6 values a voxel, not " + std::string(kind_name(o.data.kind)));
    auto field = std::make_shared<const TensorField>(make_tensor_field(o.tensors ? o.tensors->volume : o.data.volume, opt, what));
    const std::string format = o.tensors ? o.data.format : o.data.format + " tensors";
    centre_slices(o, grid_box(field->volume.dims, field->volume.voxel_to_ras));
    become_glyph_mesh(o, tensor_glyphs(*field, o.slice_x, o.slice_y, o.slice_z), tensor_bounds(*field), format, "color_fa");
    o.tensors = std::move(field);
}

std::optional<Mesh> glyph_mesh(const Object &o, std::optional<double> x, std::optional<double> y, std::optional<double> z) {
    if (o.odfs) return odf_glyphs(*o.odfs, x, y, z, o.odfs->options.sphere);
    if (o.tensors) return tensor_glyphs(*o.tensors, x, y, z);
    return std::nullopt;
}

std::shared_ptr<const Mesh> moving_glyph_mesh(const Object &o, std::optional<double> x, std::optional<double> y, std::optional<double> z) {
    if (!o.odfs || !o.odfs->coarser) return nullptr;
    return std::make_shared<const Mesh>(odf_glyphs(*o.odfs->coarser, x, y, z, 0));
}

std::optional<Bounds> glyph_grid(const Object &o) {
    if (o.odfs) return grid_box(o.odfs->volume.dims, o.odfs->volume.voxel_to_ras);
    if (o.tensors) return grid_box(o.tensors->volume.dims, o.tensors->volume.voxel_to_ras);
    return std::nullopt;
}

void check_ambient_occlusion(const AmbientOcclusion &ao) {
    if (!(ao.radius_mm > 0 && ao.radius_mm <= 1000))
        throw Error("ambient occlusion: radius " + std::to_string(ao.radius_mm) + " mm is outside (0, 1000]");
    if (!(ao.strength >= 0 && ao.strength <= 1))
        throw Error("ambient occlusion: strength " + std::to_string(ao.strength) + " is outside [0, 1]");
}

void check_depth_cue(const DepthCue &cue) {
    if (!(cue.strength >= 0 && cue.strength <= 1))
        throw Error("depth cue: strength " + std::to_string(cue.strength) + " is outside [0, 1]");
}

void check_shadows(const Shadows &sh) {
    if (!(sh.strength >= 0 && sh.strength <= 1)) throw Error("shadows: strength " + std::to_string(sh.strength) + " is outside [0, 1]");
    if (!(sh.softness_mm >= 0 && sh.softness_mm <= 50))
        throw Error("shadows: softness " + std::to_string(sh.softness_mm) + " mm is outside [0, 50]");
}

void check_antialiasing(const Antialiasing &aa) {
    if (!(aa.frames >= 1 && aa.frames <= 64)) throw Error("antialiasing: " + std::to_string(aa.frames) + " frames is outside [1, 64]");
}

Scene load_scene(const Registry &reg, const fs::path &file) {
    const std::string text = read_small_file(file, 64u << 20, "scene file");
    return parse_scene(reg, text, file.parent_path().empty() ? fs::path(".") : file.parent_path(), file.string());
}

// ------------------------------------------------------------------ builtins

namespace {

// Smooth pseudo-random field (sum of oriented sines), deterministic.
double gyri(double x, double y, double z) {
    static const double dirs[][4] = {{0.8, 0.5, 0.3, 0.21},  {-0.3, 0.9, 0.3, 0.17},  {0.2, -0.4, 0.9, 0.19},
                                     {0.7, -0.7, 0.1, 0.23}, {-0.6, -0.2, 0.8, 0.15}, {0.1, 0.6, -0.8, 0.25}};
    double s = 0;
    for (const auto &d : dirs) s += std::sin(d[3] * (d[0] * x + d[1] * y + d[2] * z) + d[3] * 7.0);
    return s / 6.0;
}

}  // namespace

Mesh make_sphere_mesh(double r, int nu, int nv) {
    nu = std::clamp(nu, 3, 4096), nv = std::clamp(nv, 2, 4096);
    Mesh m;
    m.vertices = Buffer<float>(std::size_t(nu + 1) * (nv + 1) * 3);
    m.faces = Buffer<std::uint32_t>(std::size_t(nu) * nv * 6);
    std::size_t k = 0;
    for (int j = 0; j <= nv; ++j)
        for (int i = 0; i <= nu; ++i) {
            const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
            m.vertices[k++] = float(r * std::sin(th) * std::cos(ph));
            m.vertices[k++] = float(r * std::sin(th) * std::sin(ph));
            m.vertices[k++] = float(r * std::cos(th));
        }
    k = 0;
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            const std::uint32_t a = j * (nu + 1) + i, b = a + 1, c = a + (nu + 1), d = c + 1;
            for (std::uint32_t x : {a, c, b, b, c, d}) m.faces[k++] = x;
        }
    return m;
}

namespace {

// A unit icosphere of `subdivisions` (0..7) subdivisions (odfs.hpp): vertices, faces.
std::pair<std::vector<Vec3>, std::vector<std::array<std::uint32_t, 3>>> icosphere_lists(int subdivisions) {
    const SphereMesh s = icosphere(std::clamp(subdivisions, 0, 7));
    std::vector<Vec3> v(s.nb_vertices());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = {s.vertices[3 * i], s.vertices[3 * i + 1], s.vertices[3 * i + 2]};
    std::vector<std::array<std::uint32_t, 3>> f(s.faces.size() / 3);
    for (std::size_t i = 0; i < f.size(); ++i) f[i] = {s.faces[3 * i], s.faces[3 * i + 1], s.faces[3 * i + 2]};
    return {std::move(v), std::move(f)};
}

// Two hemispheres made of the unit sphere (v, f): half-ellipsoids
// flattened at the midline, each point (X, Y, Z) scaled by fold(X, Y, Z, side)
// about the hemisphere's centre; a per-vertex "sulc" array of overlay(P, Q),
// P the folded point and Q the point before folding.
Mesh hemispheres(const std::vector<Vec3> &v, const std::vector<std::array<std::uint32_t, 3>> &f,
                 const std::function<double(double, double, double, double)> &fold,
                 const std::function<double(const Vec3 &, const Vec3 &)> &overlay) {
    Mesh m;
    const std::size_t nv = v.size(), nf = f.size();
    m.vertices = Buffer<float>(nv * 3 * 2);
    m.faces = Buffer<std::uint32_t>(nf * 3 * 2);
    std::vector<Vec3> unfolded(nv * 2);
    for (int h = 0; h < 2; ++h) {
        const double side = h == 0 ? -1.0 : 1.0;
        for (std::size_t i = 0; i < nv; ++i) {
            const auto &p = v[i];
            double x = p[0], y = p[1], z = p[2];
            // Flatten the medial side, round the lateral one.
            const double lateral = x * side;
            const double xs = lateral < 0 ? 0.25 * lateral : lateral;
            double X = side * (4.0 + 36.0 * (xs + 0.25)), Y = 88.0 * y;
            double Z = (z < 0 ? 52.0 : 64.0) * z + 4.0;  // flatter base
            unfolded[h * nv + i] = {X, Y, Z};
            const double r = fold(X, Y, Z, side);
            const double cx = side * 22.0;
            X = cx + (X - cx) * r;
            Y *= r;
            Z = 4.0 + (Z - 4.0) * r;
            m.vertices[(h * nv + i) * 3 + 0] = static_cast<float>(X);
            m.vertices[(h * nv + i) * 3 + 1] = static_cast<float>(Y);
            m.vertices[(h * nv + i) * 3 + 2] = static_cast<float>(Z);
        }
        for (std::size_t k = 0; k < nf; ++k)
            for (int c = 0; c < 3; ++c) m.faces[(h * nf + k) * 3 + c] = static_cast<std::uint32_t>(h * nv + f[k][c]);
    }
    std::vector<float> sulc(nv * 2);
    for (std::size_t i = 0; i < nv * 2; ++i)
        sulc[i] = static_cast<float>(overlay({m.vertices[i * 3], m.vertices[i * 3 + 1], m.vertices[i * 3 + 2]}, unfolded[i]));
    m.arrays.push_back(f32_array("sulc", HZ_ATTACH_VERTEX, sulc));
    return m;
}

// Gradient noise in 3D (Perlin's construction: a pseudo-random unit
// gradient at each integer lattice point, blended with a quintic), in about
// [-1, 1], deterministic.
double gradient_noise(double x, double y, double z) {
    auto grad = [](int i, int j, int k, double dx, double dy, double dz) {
        std::uint64_t h =
            std::uint64_t(i) * 0x9E3779B97F4A7C15ull ^ std::uint64_t(j) * 0xC2B2AE3D27D4EB4Full ^ std::uint64_t(k) * 0x165667B19E3779F9ull;
        h = (h ^ (h >> 31)) * 0xBF58476D1CE4E5B9ull;
        h ^= h >> 29;
        const double th = double(h & 0xFFFF) / 65536.0 * 2 * M_PI, u = double((h >> 16) & 0xFFFF) / 65536.0 * 2 - 1;
        const double s = std::sqrt(1 - u * u);
        return s * std::cos(th) * dx + s * std::sin(th) * dy + u * dz;
    };
    auto fade = [](double t) { return t * t * t * (t * (t * 6 - 15) + 10); };
    const int i = int(std::floor(x)), j = int(std::floor(y)), k = int(std::floor(z));
    const double fx = x - i, fy = y - j, fz = z - k, u = fade(fx), w = fade(fy), q = fade(fz);
    double c[2][2][2];
    for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b)
            for (int d = 0; d < 2; ++d) c[a][b][d] = grad(i + a, j + b, k + d, fx - a, fy - b, fz - d);
    auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
    return 1.6 * lerp(lerp(lerp(c[0][0][0], c[1][0][0], u), lerp(c[0][1][0], c[1][1][0], u), w),
                      lerp(lerp(c[0][0][1], c[1][0][1], u), lerp(c[0][1][1], c[1][1][1], u), w), q);
}

// The brain surface's sulci: a point at a fundus lies this fraction of the
// way in from the hemisphere's outline (about 5 mm).
constexpr double kSulcusFold = 0.10;

// How deep a point lies in a sulcus: 1 at a fundus, 0 on a gyral crown.
// Sulci are where a band-limited noise crosses zero (narrow valleys between
// broad gyri, about 12 mm apart), and the Sylvian fissure, a deeper groove
// on the lateral side between the frontal and temporal lobes.
double sulcal_depth(double x, double y, double z) {
    const double n = gradient_noise(x / 17.0, y / 17.0, z / 17.0) + 0.35 * gradient_noise(x / 8.0 + 11.3, y / 8.0, z / 8.0);
    const double v = std::max(0.0, 1.0 - 2.6 * std::abs(n));
    double depth = v * v * v;
    // The Sylvian fissure: along a line on the lateral surface from the
    // temporal pole (y = 22, z = -6) up and back (y = -34, z = 22).
    if (std::abs(x) > 30) {
        const double ty = (22 - y) / 56.0;
        if (ty > -0.1 && ty < 1.05) {
            const double zl = -6 + 28 * std::clamp(ty, 0.0, 1.0);
            const double d = (z - zl) / 3.5;
            depth = std::max(depth, 1.4 * std::exp(-d * d) * std::min(1.0, (std::abs(x) - 30) / 15));
        }
    }
    return depth;
}

}  // namespace

Mesh make_cortex_mesh(int subdivisions) {
    const auto [v, f] = icosphere_lists(subdivisions);
    return hemispheres(
        v, f,
        [](double X, double Y, double Z, double) {
            return 1.0 + 0.045 * gyri(X, Y, Z) + 0.03 * gyri(2.1 * Y, 2.1 * Z, 2.1 * X);  // gyri and sulci
        },
        // Per-vertex "curvature-like" overlay for colormap demos.
        [](const Vec3 &p, const Vec3 &) { return gyri(p[0], p[1], p[2]); });
}

Mesh make_brain_surface(int subdivisions) {
    const auto [v, f] = icosphere_lists(subdivisions);
    return hemispheres(
        v, f, [](double X, double Y, double Z, double) { return 1.0 - kSulcusFold * sulcal_depth(X, Y, Z); },
        [](const Vec3 &, const Vec3 &q) { return sulcal_depth(q[0], q[1], q[2]); });
}

namespace {

// How far inside make_brain_surface's cortex a point lies, in mm (negative
// outside), about: from the radius of the unit sphere the hemispheres are
// made of, after undoing the fold about the hemisphere's centre at the
// point itself (exact to within the fold's variation over a few mm), over
// that radius's gradient.
double brain_depth_mm(double x, double y, double z) {
    const double side = x < 0 ? -1.0 : 1.0, cx = side * 22.0;
    const double r = 1.0 - kSulcusFold * sulcal_depth(x, y, z);
    const double X = cx + (x - cx) / r, Y = y / r, Z = 4.0 + (z - 4.0) / r;
    const double ax = std::abs(X), sx = ax >= 13.0 ? 36.0 : 9.0, sz = Z >= 4.0 ? 64.0 : 52.0;
    const double u = (ax - 13.0) / sx, v = Y / 88.0, w = (Z - 4.0) / sz;
    const double rho = std::max(std::sqrt(u * u + v * v + w * w), 1e-6);
    const double gx = u / sx, gy = v / 88.0, gz = w / sz;  // (rho times its gradient)
    return (1.0 - rho) * rho / std::max(std::sqrt(gx * gx + gy * gy + gz * gz), 1e-9);
}

double smoothstep(double e0, double e1, double x) {
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3 - 2 * t);
}

// The demo brain's grid (the T1's and its segmentation's): 4-byte voxels of
// `dtype` over the head, `voxel_mm` apart (clamped to 0.5-10 mm).
Volume brain_grid(double voxel_mm, hz_dtype dtype) {
    voxel_mm = std::clamp(voxel_mm, 0.5, 10.0);
    Volume vol;
    const double lo[3] = {-70, -110, -75}, hi[3] = {70, 100, 92};
    std::uint64_t d[3];
    for (int i = 0; i < 3; ++i) d[i] = static_cast<std::uint64_t>(std::ceil((hi[i] - lo[i]) / voxel_mm)) + 1;
    vol.dims = {d[0], d[1], d[2]};
    vol.dtype = dtype;
    vol.voxels = Buffer<std::byte>(d[0] * d[1] * d[2] * 4);
    vol.voxel_to_ras = {voxel_mm, 0, 0, lo[0], 0, voxel_mm, 0, lo[1], 0, 0, voxel_mm, lo[2], 0, 0, 0, 1};
    return vol;
}

// f(index, x, y, z) for each voxel of a grid of brain_grid's (axis-aligned),
// its RAS+ mm position; slices in parallel.
template <class F>
void for_each_brain_voxel(const Volume &vol, F f) {
    const std::uint64_t nx = vol.dims[0], ny = vol.dims[1];
    const Affine &a = vol.voxel_to_ras;
    parallel_ranges(vol.dims[2], 1, [&](std::uint64_t k0, std::uint64_t k1) {
        for (std::uint64_t k = k0; k < k1; ++k)
            for (std::uint64_t j = 0; j < ny; ++j)
                for (std::uint64_t i = 0; i < nx; ++i) f((k * ny + j) * nx + i, a[3] + a[0] * i, a[7] + a[5] * j, a[11] + a[10] * k);
    });
}

}  // namespace

Volume make_t1_volume(double voxel_mm) {
    Volume vol = brain_grid(voxel_mm, HZ_DTYPE_F32);
    float *out = reinterpret_cast<float *>(vol.voxels.data());
    // T1 contrast: white matter brightest, grey matter darker, CSF and
    // skull dark, the scalp's fat bright.
    constexpr double kWhite = 0.80, kGrey = 0.42, kDeep = 0.58, kCsf = 0.10, kSkull = 0.04, kScalp = 0.60;
    for_each_brain_voxel(vol, [&](std::uint64_t at, double x, double y, double z) {
        // Head: scalp, skull, CSF, in ellipsoidal shells (mm from the skull's inside, about).
        const double head = std::sqrt((x / 56) * (x / 56) + ((y + 4) / 94) * ((y + 4) / 94) + ((z - 6) / 72) * ((z - 6) / 72));
        const double out_mm = (head - 1.0) * 75.0;
        double val = kScalp * (1 - smoothstep(9.0, 10.5, out_mm)) * smoothstep(3.5, 5.0, out_mm) +
                     kSkull * (1 - smoothstep(3.5, 5.0, out_mm)) * smoothstep(-0.5, 0.5, out_mm);
        if (out_mm < 0.5) val += kCsf * (1 - smoothstep(-0.5, 0.5, out_mm));
        // Cortex and white matter: depth below the cortical surface, about, in mm.
        const double in_mm = brain_depth_mm(x, y, z);
        const double brain = smoothstep(-0.75, 0.75, in_mm);
        const double white = smoothstep(2.2, 3.7, in_mm + 1.2 * gradient_noise(x / 6, y / 6, z / 6));
        double tissue = kGrey + (kWhite - kGrey) * white;
        // Deep grey nuclei (thalamus, basal ganglia), the ventricles.
        for (const double side : {-1.0, 1.0}) {
            const double tx = (x - side * 12) / 9, ty = (y + 12) / 14, tz = (z - 6) / 9;
            tissue += (kDeep - tissue) * (1 - smoothstep(0.8, 1.1, std::sqrt(tx * tx + ty * ty + tz * tz)));
            const double vx = (x - side * 9) / 6, vy = (y + 2) / 28, vz = (z - 16) / 8;
            tissue += (kCsf - tissue) * (1 - smoothstep(0.8, 1.1, std::sqrt(vx * vx + vy * vy + vz * vz)));
        }
        val = val * (1 - brain) + tissue * brain;
        // Brainstem and cerebellum below the hemispheres.
        const double bx = x / 11, by = (y + 24 + 0.12 * z) / 12;
        if (z < 0 && z > -68) val = std::max(val, 0.7 * (1 - smoothstep(0.85, 1.1, std::sqrt(bx * bx + by * by))));
        const double cx = x / 46, cy = (y + 62) / 26, cz = (z + 34) / 18;
        const double cb = std::sqrt(cx * cx + cy * cy + cz * cz);
        if (cb < 1.1) val = std::max(val, (1 - smoothstep(0.9, 1.05, cb)) * (0.45 + 0.2 * std::abs(std::sin(z * 1.3 + 0.3 * y))));
        out[at] = static_cast<float>(1000.0 * val);
    });
    return vol;
}

Volume make_aseg_volume(double voxel_mm) {
    Volume vol = brain_grid(voxel_mm, HZ_DTYPE_I32);
    auto *out = reinterpret_cast<std::int32_t *>(vol.voxels.data());
    // make_t1_volume's tissues where they are more than half present, with
    // FreeSurfer's aseg numbers (left, right).
    for_each_brain_voxel(vol, [&](std::uint64_t at, double x, double y, double z) {
        const bool left = x < 0;
        std::int32_t label = 0;
        const double in_mm = brain_depth_mm(x, y, z);
        if (in_mm > 0) {
            label = in_mm + 1.2 * gradient_noise(x / 6, y / 6, z / 6) > 2.95 ? (left ? 2 : 41) : (left ? 3 : 42);
            for (const double side : {-1.0, 1.0}) {
                const double tx = (x - side * 12) / 9, ty = (y + 12) / 14, tz = (z - 6) / 9;
                if (std::sqrt(tx * tx + ty * ty + tz * tz) < 0.95) label = side < 0 ? 10 : 49;
                const double vx = (x - side * 9) / 6, vy = (y + 2) / 28, vz = (z - 16) / 8;
                if (std::sqrt(vx * vx + vy * vy + vz * vz) < 0.95) label = side < 0 ? 4 : 43;
            }
        }
        const double bx = x / 11, by = (y + 24 + 0.12 * z) / 12;
        if (z < 0 && z > -68 && std::sqrt(bx * bx + by * by) < 0.975 && label == 0) label = 16;
        const double cx = x / 46, cy = (y + 62) / 26, cz = (z + 34) / 18;
        if (std::sqrt(cx * cx + cy * cy + cz * cz) < 0.975 && label == 0) label = left ? 8 : 47;
        out[at] = label;
    });
    return vol;
}

LabelTable aseg_table() {
    LabelTable t;
    const auto add = [&](std::int64_t l, const char *name, std::uint8_t r, std::uint8_t g, std::uint8_t b) { t[l] = {name, {r, g, b}}; };
    add(2, "Left-Cerebral-White-Matter", 236, 232, 218), add(41, "Right-Cerebral-White-Matter", 236, 232, 218);
    add(3, "Left-Cerebral-Cortex", 214, 126, 98), add(42, "Right-Cerebral-Cortex", 214, 126, 98);
    add(4, "Left-Lateral-Ventricle", 118, 84, 204), add(43, "Right-Lateral-Ventricle", 118, 84, 204);
    add(10, "Left-Thalamus", 34, 162, 140), add(49, "Right-Thalamus", 34, 162, 140);
    add(8, "Left-Cerebellum-Cortex", 226, 172, 58), add(47, "Right-Cerebellum-Cortex", 226, 172, 58);
    add(16, "Brain-Stem", 112, 158, 222);
    return t;
}

Volume make_head_volume(double voxel_mm) {
    voxel_mm = std::clamp(voxel_mm, 0.5, 10.0);
    Volume vol;
    const double half[3] = {80, 100, 80};
    std::uint64_t d[3];
    for (int i = 0; i < 3; ++i) d[i] = static_cast<std::uint64_t>(std::ceil(2 * half[i] / voxel_mm)) + 1;
    vol.dims = {d[0], d[1], d[2]};
    vol.dtype = HZ_DTYPE_F32;
    vol.voxels = Buffer<std::byte>(d[0] * d[1] * d[2] * 4);
    vol.voxel_to_ras = {voxel_mm, 0, 0, -half[0], 0, voxel_mm, 0, -half[1], 0, 0, voxel_mm, -half[2], 0, 0, 0, 1};
    float *out = reinterpret_cast<float *>(vol.voxels.data());
    for (std::uint64_t k = 0; k < d[2]; ++k)
        for (std::uint64_t j = 0; j < d[1]; ++j)
            for (std::uint64_t i = 0; i < d[0]; ++i) {
                const double x = -half[0] + voxel_mm * i, y = -half[1] + voxel_mm * j, z = -half[2] + voxel_mm * k;
                // Distance-like coordinate inside an ellipsoidal head.
                const double r = std::sqrt((x / 72) * (x / 72) + (y / 92) * (y / 92) + ((z - 4) / 68) * ((z - 4) / 68));
                double val = 0;
                if (r < 1.08) val = 0.15;                                           // scalp/skull
                if (r < 1.0) val = 0.35;                                            // CSF
                if (r < 0.96) val = 0.55 + 0.1 * gyri(x, y, z);                     // grey matter
                if (r < 0.80 + 0.06 * gyri(1.3 * x, 1.3 * y, 1.3 * z)) val = 0.85;  // white matter
                const double vx = std::abs(x) - 6, vy = y / 2.2, vz = z - 8;        // lateral ventricles
                if (vx > 0 && vx * vx + vy * vy + vz * vz < 70) val = 0.2;
                out[(k * d[1] + j) * d[0] + i] = static_cast<float>(1000.0 * val);
            }
    return vol;
}

ClusterTree run_clustering(const Registry &reg, const Tractogram &t, const ClusterSpec &spec, const hz_task *task,
                           const std::vector<std::uint64_t> *ordering) {
    if (ordering) {
        const std::uint64_t n = t.nb_streamlines();
        if (ordering->size() != n)
            throw Error("ordering: " + std::to_string(ordering->size()) + " indices for " + std::to_string(n) + " streamlines");
        std::vector<bool> seen(n);
        for (std::uint64_t i : *ordering) {
            if (i >= n || seen[i]) throw Error("ordering: not a permutation of the streamlines (index " + std::to_string(i) + ")");
            seen[i] = true;
        }
    }
    const LoadedPlugin *plugin = find_clustering(reg, spec.algorithm);
    const std::string id = plugin->info.id;
    const std::vector<ParamSpec> schema = schema_of(*plugin);
    std::map<std::string, std::vector<double>> settings;
    // Display only needs a plugin's fast mode, where it has one; what the
    // spec sets wins.
    for (const auto &s : schema)
        if (s.name == "mode" && s.enum_labels.size() > 1 && s.enum_labels[1] == "fast") settings["mode"] = {1.0};
    if (!spec.thresholds.empty())
        apply_shortcut(schema, id, "clustering.thresholds", {"thresholds", "threshold"}, spec.thresholds, settings);
    for (const auto &[k, v] : spec.params) settings[k] = v;
    const hz_clustering *c = plugin->clustering();
    hz_error err{};
    err.struct_size = sizeof err;
    hz_clusterer *obj = nullptr;
    if (plugin->call("create", "", [&] { return c->create(host_services(), &obj, &err); }) != HZ_OK) throw Error(id + ": " + err.message);
    struct Guard {
        const hz_clustering *c;
        hz_clusterer *o;
        ~Guard() { c->destroy(o); }
    } guard{c, obj};
    for (const auto &[k, v] : settings)
        if (plugin->call("set_param", "", [&] { return c->set_param(obj, k.c_str(), v.data(), static_cast<uint32_t>(v.size()), &err); }) !=
            HZ_OK)
            throw Error(id + ": parameter " + k + ": " + err.message);
    const Tractogram input = plugin->streamlines_for(t);
    const hz_streamlines_view view = input.view();
    Task own;
    const std::uint64_t *order = ordering && !ordering->empty() ? ordering->data() : nullptr;
    if (plugin->call("run", "", [&] { return c->run(obj, &view, order, task ? task : own.get(), &err); }) != HZ_OK)
        throw Error(id + ": " + err.message);
    hz_cluster_tree_view v{};
    v.struct_size = sizeof v;
    if (plugin->call("get_result", "", [&] { return c->get_result(obj, &v, &err); }) != HZ_OK) throw Error(id + ": " + err.message);
    check_cluster_tree(v, input.nb_streamlines(), id);
    ClusterTree tree;
    tree.nb_levels = v.nb_levels;
    tree.nb_points = v.nb_points;
    if (v.level_thresholds) tree.thresholds.assign(v.level_thresholds, v.level_thresholds + v.nb_levels);
    tree.parent.assign(v.parent, v.parent + v.nb_nodes);
    tree.level.assign(v.level, v.level + v.nb_nodes);
    tree.centroids.assign(v.centroids, v.centroids + v.nb_nodes * v.nb_points * 3);
    tree.member_offsets.assign(v.member_offsets, v.member_offsets + v.nb_nodes + 1);
    tree.members.assign(v.members, v.members + tree.member_offsets.back());
    return tree;
}

double ClusterTree::centroid_length(std::uint64_t node) const {
    const float *c = centroids.data() + node * nb_points * 3;
    double len = 0;
    for (std::uint32_t i = 1; i < nb_points; ++i)
        len += std::hypot(double(c[3 * i]) - c[3 * i - 3], double(c[3 * i + 1]) - c[3 * i - 2], double(c[3 * i + 2]) - c[3 * i - 1]);
    return len;
}

Tractogram cluster_centroids(const Registry &reg, const Tractogram &t, const ClusterSpec &spec) {
    const ClusterTree tree = run_clustering(reg, t, spec);
    // The levels drawn, coarsest first (-1 the finest, -2 the one above, ...).
    std::vector<std::uint32_t> levels;
    for (int l : spec.levels.empty() ? std::vector<int>{spec.level} : spec.levels) {
        const std::int64_t resolved = l < 0 ? std::int64_t(tree.nb_levels) + 1 + l : l;
        if (resolved < 1 || resolved > std::int64_t(tree.nb_levels))
            throw Error("clustering.level " + std::to_string(l) + ": the tree has levels 1.." + std::to_string(tree.nb_levels));
        levels.push_back(std::uint32_t(resolved));
    }
    std::sort(levels.begin(), levels.end());
    levels.erase(std::unique(levels.begin(), levels.end()), levels.end());
    // Each node's subtree: the index of its ancestor among the first level's kept nodes.
    std::vector<char> kept(tree.level.size());  // (the cut-offs, min_size and min_length)
    for (std::uint64_t k = 0; k < kept.size(); ++k) kept[k] = tree.kept(k, spec);
    std::vector<std::int64_t> subtree(tree.level.size(), -1);
    std::uint64_t roots = 0;
    for (std::uint64_t k = 0; k < tree.level.size(); ++k)
        if (tree.level[k] == levels[0] && kept[k]) subtree[k] = std::int64_t(roots++);
    for (std::uint64_t s : spec.subtrees)
        if (s >= roots)
            throw Error("clustering.subtrees: " + std::to_string(s) + ", but level " + std::to_string(levels[0]) + " has " +
                        std::to_string(roots) + " clusters drawn (0 to " + std::to_string(roots == 0 ? 0 : roots - 1) + ")");
    const auto ancestor = [&](std::uint64_t k) {
        while (tree.level[k] > levels[0] && tree.parent[k] >= 0) k = std::uint64_t(tree.parent[k]);
        return tree.level[k] == levels[0] ? subtree[k] : std::int64_t(-1);
    };
    std::vector<std::uint64_t> nodes;
    std::vector<float> ids, lv;
    for (std::uint32_t level : levels)
        for (std::uint64_t k = 0; k < tree.level.size(); ++k) {
            if (tree.level[k] != level || !kept[k]) continue;
            const std::int64_t root = ancestor(k);
            if (root < 0) continue;  // (under a cluster cut off at the first level)
            if (!spec.subtrees.empty() && std::find(spec.subtrees.begin(), spec.subtrees.end(), std::uint64_t(root)) == spec.subtrees.end())
                continue;
            nodes.push_back(k);
            ids.push_back(float(root));
            lv.push_back(float(level));
        }
    Tractogram out;
    const std::uint64_t K = nodes.size(), P = tree.nb_points;
    out.positions = Buffer<float>(K * P * 3);
    out.offsets = Buffer<std::uint64_t>(K + 1);
    std::vector<float> sizes(K);
    for (std::uint64_t i = 0; i < K; ++i) {
        std::copy_n(tree.centroids.data() + nodes[i] * P * 3, P * 3, out.positions.data() + i * P * 3);
        out.offsets[i] = i * P;
        sizes[i] = static_cast<float>(tree.size(nodes[i]));
    }
    out.offsets[K] = K * P;
    out.arrays.push_back(f32_array("cluster_size", HZ_ATTACH_STREAMLINE, sizes));
    if (!spec.levels.empty() || !spec.subtrees.empty()) {
        out.arrays.push_back(f32_array("cluster_id", HZ_ATTACH_STREAMLINE, ids));
        out.arrays.push_back(f32_array("cluster_level", HZ_ATTACH_STREAMLINE, lv));
    }
    out.reference = t.reference;
    out.reference_dims = t.reference_dims;
    return out;
}

Scene demo_scene(std::uint64_t nb_streamlines, std::uint64_t seed) {
    Scene s;
    s.ambient_occlusion.on = true;  // (the tubes' contact shadows on the cortex and slices; --no-ao)
    s.shadows.on = true;            // (the key light's, cast by the tubes and the cortex; --no-shadows)
    Object tracts;
    tracts.name = "bundles (corticospinal, arcuate, cingulum, IFOF, uncinate, ILF, corpus callosum)";
    tracts.kind = HZ_DATA_STREAMLINES;
    tracts.data.kind = HZ_DATA_STREAMLINES;
    tracts.data.tractogram = make_brain_phantom(nb_streamlines, seed);
    tracts.render = "tubes";
    tracts.radius_mm = 0.35;
    tracts.coloring.mode = "direction";
    tracts.material.shader = "principled";
    tracts.material.params = {{"roughness", {0.35}}, {"specular", {0.5}}, {"clearcoat", {0.6}}, {"clearcoat_gloss", {0.8}}};
    s.objects.push_back(std::move(tracts));

    Object cortex;
    cortex.name = "cortex (right hemisphere)";
    cortex.kind = HZ_DATA_MESH;
    cortex.data.kind = HZ_DATA_MESH;
    Mesh full = make_brain_surface(6);
    // Keep the right hemisphere only, so the bundles stay visible.
    const std::uint64_t half_faces = full.nb_faces() / 2;
    Mesh right;
    right.vertices = std::move(full.vertices);
    right.faces = Buffer<std::uint32_t>(half_faces * 3);
    std::copy_n(full.faces.data() + half_faces * 3, half_faces * 3, right.faces.data());
    right.arrays = std::move(full.arrays);
    cortex.data.mesh = std::move(right);
    cortex.coloring.color = {0.80, 0.55, 0.50};
    cortex.material.shader = "principled";
    cortex.material.params = {{"subsurface", {0.5}}, {"roughness", {0.6}}, {"sheen", {0.2}}, {"specular", {0.3}}};
    s.objects.push_back(std::move(cortex));

    Object head;
    head.name = "synthetic T1 (axial and coronal slices)";
    head.kind = HZ_DATA_VOLUME;
    head.data.kind = HZ_DATA_VOLUME;
    head.data.volume = make_t1_volume(1.0);
    head.slice_z = -16.0;
    head.slice_y = -62.0;
    head.window = std::array<double, 2>{0.0, 1000.0};
    head.clip_below = 1.0;
    s.objects.push_back(std::move(head));

    s.camera.view = "left";
    s.camera.position = Vec3{-280, 160, 128};
    s.camera.target = Vec3{0, -5, -5};
    s.camera.fov_deg = 30;
    s.environment.type = "studio";
    s.environment.intensity = 0.5;
    s.exposure = 0.9;
    s.background = {0.015, 0.017, 0.022};
    return s;
}

}  // namespace hz::core::render
