#include "commands.hpp"
#include "progress.hpp"

#include <hz/core/io.hpp>
#include <hz/core/params.hpp>
#include <hz/core/phantom.hpp>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <cstdio>
#include <sstream>
#include <unistd.h>
#include <iostream>

namespace hz::host {

using nlohmann::json;

namespace {

json plugin_json(const core::LoadedPlugin &p) {
    json j = {{"id", p.info.id},
              {"kind", core::plugin_kind_name(p.info.kind)},
              {"name", p.info.name},
              {"version", p.info.version},
              {"abi", std::to_string(p.info.abi.major) + "." + std::to_string(p.info.abi.minor)},
              {"vendor", p.info.vendor},
              {"license", p.info.license},
              {"description", p.info.description},
              {"interfaces", p.info.interfaces},
              {"file", p.info.file},
              {"status", "loaded"}};
    if (p.shader() || p.clustering()) j["parameters"] = core::schema_json(core::schema_of(p));
    return j;
}

}  // namespace

int cmd_plugins(const GlobalOptions &g, bool as_json, const std::string &only) {
    const core::Registry reg = load_registry(g);
    if (!only.empty()) {
        const core::LoadedPlugin *p = core::find_plugin(reg, only);  // an id, or its last part ("qbx", "principled")
        if (p == nullptr) throw core::Error("no plugin has the id '" + only + "' (see `horizon plugins`)");
        const json j = plugin_json(*p);
        if (as_json) {
            std::cout << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
            return 0;
        }
        std::printf("%s  %s %s (%s), ABI %s\n  %s\n  %s\n", p->info.id.c_str(), p->info.name.c_str(), p->info.version.c_str(),
                    core::plugin_kind_name(p->info.kind), j["abi"].get<std::string>().c_str(), p->info.description.c_str(),
                    p->info.file.c_str());
        if (j.contains("parameters")) {
            std::printf("\nParameters (--param NAME=VALUE, or in a scene file):\n");
            for (const auto &s : core::schema_of(*p)) {
                std::string range;
                if (!s.enum_labels.empty()) {
                    for (const auto &l : s.enum_labels) range += (range.empty() ? "" : "|") + l;
                } else if (s.type == HZ_PARAM_BOOL) {
                    range = "true|false";
                } else {
                    std::ostringstream r;
                    r << "[" << s.min[0] << ", " << s.max[0] << "]";
                    range = r.str();
                }
                std::string def;
                for (double d : s.defaults)
                    def += (def.empty() ? "" : ",") + ([&] {
                               std::ostringstream o;
                               o << d;
                               return o.str();
                           })();
                if (!s.enum_labels.empty() && s.defaults.size() == 1 && s.defaults[0] >= 0 && s.defaults[0] < double(s.enum_labels.size()))
                    def = s.enum_labels[std::size_t(s.defaults[0])];
                if (s.type == HZ_PARAM_BOOL && s.defaults.size() == 1) def = s.defaults[0] != 0 ? "true" : "false";
                std::printf("  %-18s %-11s %-22s default %-12s %s%s%s\n", s.name.c_str(), core::param_type_name(s.type), range.c_str(),
                            def.c_str(), s.unit.empty() ? "" : ("(" + s.unit + ") ").c_str(), s.tooltip.c_str(),
                            s.type == HZ_PARAM_FLOAT_ARRAY ? (" (up to " + std::to_string(s.components) + " values)").c_str() : "");
            }
        }
        return 0;
    }
    if (as_json) {
        json j;
        j["search_path"] = json::array();
        for (const auto &d : reg.searched()) j["search_path"].push_back(d.string());
        j["plugins"] = json::array();
        for (const auto &p : reg.plugins()) j["plugins"].push_back(plugin_json(p));
        j["rejected"] = json::array();
        for (const auto &r : reg.rejected()) j["rejected"].push_back({{"file", r.file}, {"status", "rejected"}, {"reason", r.reason}});
        const auto list = core::default_trial_cache();
        j["trial_list"] = list.empty() ? json(nullptr) : json(list.string());
        j["trial_loads"] = reg.trial_loads();
        std::cout << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
        return 0;
    }
    std::printf("Search path:\n");
    for (const auto &d : reg.searched()) {
        std::error_code ec;
        std::printf("  %s%s\n", d.c_str(), std::filesystem::is_directory(d, ec) ? "" : "  (missing)");
    }
    std::printf("\n%-34s %-11s %-8s %s\n", "ID", "KIND", "VERSION", "FILE");
    for (const auto &p : reg.plugins())
        std::printf("%-34s %-11s %-8s %s\n", p.info.id.c_str(), core::plugin_kind_name(p.info.kind), p.info.version.c_str(),
                    p.info.file.c_str());
    if (!reg.rejected().empty()) {
        std::printf("\nRejected:\n");
        for (const auto &r : reg.rejected()) std::printf("  %s: %s\n", r.file.c_str(), r.reason.c_str());
    }
    std::printf("\n%zu plugins loaded, %zu files rejected\n", reg.plugins().size(), reg.rejected().size());
    const auto list = core::default_trial_cache();
    std::printf("%zu files trial-loaded in a child this time; trial list (files that passed, loaded without one while unchanged): %s\n",
                reg.trial_loads(), list.empty() ? "off" : list.c_str());
    return 0;
}

namespace {

const char *attach_name(hz_attach a) {
    switch (a) {
    case HZ_ATTACH_VERTEX: return "vertex";
    case HZ_ATTACH_STREAMLINE: return "streamline";
    case HZ_ATTACH_FACE: return "face";
    case HZ_ATTACH_GROUP: return "group";
    case HZ_ATTACH_GROUP_DATA: return "group data";
    default: return "unknown";
    }
}

json affine_json(const core::Affine &a) {
    json rows = json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({a[4 * r], a[4 * r + 1], a[4 * r + 2], a[4 * r + 3]});
    return rows;
}

json describe(const core::Dataset &ds) {
    json j;
    j["format"] = ds.format;
    j["loader"] = ds.loader_id;
    j["kind"] = core::kind_name(ds.kind);
    j["source_space"] = core::space_name(ds.source_space);
    if (ds.kind == HZ_DATA_STREAMLINES) {
        const auto &t = ds.tractogram;
        j["nb_streamlines"] = t.nb_streamlines();
        j["nb_vertices"] = t.nb_vertices();
        std::uint64_t empty = 0, min_pts = UINT64_MAX, max_pts = 0;
        for (std::uint64_t s = 0; s < t.nb_streamlines(); ++s) {
            const std::uint64_t n = t.size(s);
            empty += n == 0;
            min_pts = std::min(min_pts, n);
            max_pts = std::max(max_pts, n);
        }
        j["nb_empty_streamlines"] = empty;
        j["points_per_streamline"] = {{"min", t.nb_streamlines() ? min_pts : 0}, {"max", max_pts}};
        // read_dataset computed the bounds while validating the positions.
        const auto b = !ds.bounds.empty || t.nb_vertices() == 0 ? ds.bounds : core::bounds_of(t.positions.data(), t.nb_stored());
        j["bbox_ras_mm"] = b.empty ? json(nullptr) : json{{"min", b.min}, {"max", b.max}};
        j["positions_mapped"] = ds.mapped;
        // (Mapped at an offset float32 cannot be read at: copied when first used.)
        j["positions_copied_on_use"] = ds.mapped && ds.unaligned;
        j["affine"] = affine_json(t.reference);
        j["reference_dims"] = t.reference_dims;
        j["arrays"] = json::array();
        for (const auto &a : t.arrays)
            j["arrays"].push_back({{"name", a.name},
                                   {"attach", attach_name(a.attach)},
                                   {"count", a.count},
                                   {"dtype", core::dtype_name(a.dtype)},
                                   {"components", a.components}});
    }
    if (ds.kind == HZ_DATA_MESH) {
        const auto &m = ds.mesh;
        j["nb_vertices"] = m.nb_vertices();
        j["nb_faces"] = m.nb_faces();
        if (core::is_overlay(ds)) j["overlay_vertices"] = core::overlay_vertices(ds);
        const auto b = core::bounds_of(m.vertices.data(), m.nb_vertices());
        j["bbox_ras_mm"] = b.empty ? json(nullptr) : json{{"min", b.min}, {"max", b.max}};
        j["transform"] = affine_json(m.transform);
        j["arrays"] = json::array();
        for (const auto &a : m.arrays)
            j["arrays"].push_back({{"name", a.name},
                                   {"attach", attach_name(a.attach)},
                                   {"count", a.count},
                                   {"dtype", core::dtype_name(a.dtype)},
                                   {"components", a.components}});
    }
    if (ds.kind == HZ_DATA_VOLUME) {
        const auto &v = ds.volume;
        j["dims"] = v.dims;
        j["dtype"] = core::dtype_name(v.dtype);
        j["scale"] = {{"slope", v.scale_slope}, {"inter", v.scale_inter}};
        j["affine"] = affine_json(v.voxel_to_ras);
        // Bounding box of the voxel centres in RAS+ mm (the 8 corners).
        std::array<double, 3> mn{1e300, 1e300, 1e300}, mx{-1e300, -1e300, -1e300};
        for (int c = 0; c < 8; ++c) {
            double ijk[3];
            for (int a = 0; a < 3; ++a) ijk[a] = (c >> a & 1) && a < (int)v.dims.size() ? double(v.dims[a] - 1) : 0.0;
            for (int r = 0; r < 3; ++r) {
                const double x = v.voxel_to_ras[4 * r] * ijk[0] + v.voxel_to_ras[4 * r + 1] * ijk[1] + v.voxel_to_ras[4 * r + 2] * ijk[2] +
                                 v.voxel_to_ras[4 * r + 3];
                mn[r] = std::min(mn[r], x);
                mx[r] = std::max(mx[r], x);
            }
        }
        j["bbox_ras_mm"] = {{"min", mn}, {"max", mx}};
    }
    if (ds.kind == HZ_DATA_IMAGE && ds.volume.dims.size() == 3) {  // dims = {channels, width, height}
        const auto &v = ds.volume;
        j["width"] = v.dims[1];
        j["height"] = v.dims[2];
        j["channels"] = v.dims[0];
        j["dtype"] = core::dtype_name(v.dtype);
    }
    j["header"] = json::array();
    for (const auto &[k, v] : ds.metadata) j["header"].push_back({k, v});
    return j;
}

}  // namespace

int cmd_info(const GlobalOptions &g, const std::string &file, bool as_json, bool verify) {
    const core::Registry reg = load_registry(g);
    const core::Dataset ds = core::read_dataset(reg, file);
    json j = describe(ds);
    if (verify && ds.kind == HZ_DATA_STREAMLINES) {
        // The host's own pass over every coordinate (and delimiter), instead
        // of the loader's word for them: the floats of a deferred copy are
        // copied here.
        core::check_reported_bounds(ds.tractogram, ds.bounds, file, ds.loader_id);
        j["verified"] = true;
    }
    if (as_json) {
        json out = j;
        out["file"] = file;
        std::cout << out.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
        return 0;
    }
    std::printf("file:          %s\n", file.c_str());
    std::printf("format:        %s (plugin %s)\n", ds.format.c_str(), ds.loader_id.c_str());
    std::printf("kind:          %s\n", core::kind_name(ds.kind));
    std::printf("source space:  %s\n", core::space_name(ds.source_space));
    if (ds.kind == HZ_DATA_STREAMLINES) {
        std::printf("streamlines:   %llu (%llu empty)\n", (unsigned long long)j["nb_streamlines"].get<std::uint64_t>(),
                    (unsigned long long)j["nb_empty_streamlines"].get<std::uint64_t>());
        std::printf("vertices:      %llu (per streamline %llu..%llu)\n", (unsigned long long)j["nb_vertices"].get<std::uint64_t>(),
                    (unsigned long long)j["points_per_streamline"]["min"].get<std::uint64_t>(),
                    (unsigned long long)j["points_per_streamline"]["max"].get<std::uint64_t>());
        if (j.contains("verified")) std::printf("verified:      every coordinate read again: finite, bounds as reported\n");
        if (j["positions_copied_on_use"].get<bool>())
            std::printf("positions:     mapped from the file at an offset that is not a multiple of 4 (copied when first used)\n");
        else if (ds.mapped)
            std::printf("positions:     mapped from the file (no copy)\n");
        if (!j["bbox_ras_mm"].is_null()) {
            const auto &mn = j["bbox_ras_mm"]["min"];
            const auto &mx = j["bbox_ras_mm"]["max"];
            std::printf("bbox RAS mm:   [%.2f %.2f %.2f] .. [%.2f %.2f %.2f]\n", mn[0].get<double>(), mn[1].get<double>(),
                        mn[2].get<double>(), mx[0].get<double>(), mx[1].get<double>(), mx[2].get<double>());
        }
        std::printf("affine:\n");
        for (const auto &row : j["affine"])
            std::printf("  %10.4f %10.4f %10.4f %10.4f\n", row[0].get<double>(), row[1].get<double>(), row[2].get<double>(),
                        row[3].get<double>());
        std::size_t groups = 0;
        for (const auto &a : ds.tractogram.arrays) {
            if (a.attach == HZ_ATTACH_GROUP) {
                if (groups++ < 5) std::printf("group:         %s (%llu streamlines)\n", a.name.c_str(), (unsigned long long)a.count);
                continue;
            }
            std::printf("array:         %s (per %s, %s x %u)\n", a.name.c_str(), attach_name(a.attach), core::dtype_name(a.dtype),
                        a.components);
        }
        if (groups > 5) std::printf("group:         ... %zu groups in all\n", groups);
    }
    if (ds.kind == HZ_DATA_MESH) {
        if (core::is_overlay(ds))
            std::printf("overlay:       per-vertex values for a surface of %llu vertices (no geometry)\n",
                        (unsigned long long)core::overlay_vertices(ds));
        else
            std::printf("vertices:      %llu\ntriangles:     %llu\n", (unsigned long long)ds.mesh.nb_vertices(),
                        (unsigned long long)ds.mesh.nb_faces());
        if (!j["bbox_ras_mm"].is_null()) {
            const auto &mn = j["bbox_ras_mm"]["min"];
            const auto &mx = j["bbox_ras_mm"]["max"];
            std::printf("bbox RAS mm:   [%.2f %.2f %.2f] .. [%.2f %.2f %.2f]\n", mn[0].get<double>(), mn[1].get<double>(),
                        mn[2].get<double>(), mx[0].get<double>(), mx[1].get<double>(), mx[2].get<double>());
        }
        for (const auto &a : ds.mesh.arrays)
            std::printf("array:         %s (per vertex, %s x %u)\n", a.name.c_str(), core::dtype_name(a.dtype), a.components);
    }
    if (ds.kind == HZ_DATA_VOLUME) {
        std::string dims;
        for (auto d : ds.volume.dims) dims += (dims.empty() ? "" : " x ") + std::to_string(d);
        std::printf("dims:          %s (%s)\n", dims.c_str(), core::dtype_name(ds.volume.dtype));
        std::printf("scaling:       value = raw * %g + %g\n", ds.volume.scale_slope, ds.volume.scale_inter);
        const auto &mn = j["bbox_ras_mm"]["min"];
        const auto &mx = j["bbox_ras_mm"]["max"];
        std::printf("bbox RAS mm:   [%.2f %.2f %.2f] .. [%.2f %.2f %.2f] (voxel centres)\n", mn[0].get<double>(), mn[1].get<double>(),
                    mn[2].get<double>(), mx[0].get<double>(), mx[1].get<double>(), mx[2].get<double>());
        std::printf("affine:\n");
        for (const auto &row : j["affine"])
            std::printf("  %10.4f %10.4f %10.4f %10.4f\n", row[0].get<double>(), row[1].get<double>(), row[2].get<double>(),
                        row[3].get<double>());
    }
    if (j.contains("width"))
        std::printf("image:         %llu x %llu pixels, %llu channel%s (%s)\n", (unsigned long long)j["width"].get<std::uint64_t>(),
                    (unsigned long long)j["height"].get<std::uint64_t>(), (unsigned long long)j["channels"].get<std::uint64_t>(),
                    j["channels"].get<std::uint64_t>() == 1 ? "" : "s", j["dtype"].get<std::string>().c_str());
    if (!ds.metadata.empty()) {
        std::printf("header:\n");
        for (const auto &[k, v] : ds.metadata) std::printf("  %s: %s\n", k.c_str(), v.c_str());
    }
    return 0;
}

namespace {

// The files an input is read from: itself, and the other half of a NIfTI
// pair (.hdr/.img, also gzipped).
std::vector<std::filesystem::path> files_of_input(const std::string &in) {
    std::vector<std::filesystem::path> out{in};
    for (const char *gz : {"", ".gz"}) {
        const std::string g = gz;
        for (const auto &[a, b] : {std::pair{".hdr", ".img"}, std::pair{".img", ".hdr"}}) {
            const std::string suffix = std::string(a) + g;
            if (in.size() > suffix.size() && in.compare(in.size() - suffix.size(), suffix.size(), suffix) == 0)
                out.emplace_back(in.substr(0, in.size() - suffix.size()) + b + g);
        }
    }
    return out;
}

}  // namespace

void check_outputs(const std::vector<std::string> &outputs, const std::vector<std::string> &inputs, bool force) {
    namespace fs = std::filesystem;
    std::error_code ec;
    for (std::size_t i = 0; i < outputs.size(); ++i) {
        const std::string &o = outputs[i];
        if (o.empty() || o == "-") continue;
        for (std::size_t j = 0; j < i; ++j)
            if (outputs[j] == o || (fs::exists(o, ec) && fs::exists(outputs[j], ec) && fs::equivalent(o, outputs[j], ec)))
                throw core::Error(o + ": named as two outputs");
        for (const auto &in : inputs)
            for (const auto &f : files_of_input(in))
                if (fs::path(o).lexically_normal() == f.lexically_normal() ||
                    (fs::exists(o, ec) && fs::exists(f, ec) && fs::equivalent(o, f, ec)))
                    throw core::Error(o + ": refusing to overwrite the input file " + f.string());
        core::check_output_target(o);
        if (fs::exists(fs::symlink_status(o, ec)) && !force) throw core::Error(o + ": already exists (use --force to replace it)");
        const fs::path dir = fs::path(o).has_parent_path() ? fs::path(o).parent_path() : fs::path(".");
        if (!fs::is_directory(dir, ec)) throw core::Error(o + ": directory " + dir.string() + " does not exist");
    }
}

int cmd_convert(const GlobalOptions &g, const std::string &in, const std::string &out, bool force) {
    const core::Registry reg = load_registry(g);
    check_outputs({out}, {in}, force);
    // Pick the writer first: an unsupported target fails before any reading.
    core::loader_for_write(reg, out);
    std::optional<Progress> reading(std::in_place, "reading " + in, true);
    const core::Dataset ds = core::read_dataset(reg, in, reading->task());
    reading.reset();
    std::vector<std::string> dropped;
    core::write_dataset(reg, ds, out, force, &dropped, in);
    for (const auto &d : dropped) std::fprintf(stderr, "horizon: warning: %s: dropped %s\n", out.c_str(), d.c_str());
    if (ds.kind == HZ_DATA_STREAMLINES)
        std::printf("%s -> %s (%llu streamlines)\n", in.c_str(), out.c_str(), (unsigned long long)ds.tractogram.nb_streamlines());
    else if (core::is_overlay(ds))
        std::printf("%s -> %s (per-vertex values for %llu vertices)\n", in.c_str(), out.c_str(),
                    (unsigned long long)core::overlay_vertices(ds));
    else if (ds.kind == HZ_DATA_MESH)
        std::printf("%s -> %s (mesh, %llu vertices, %llu triangles)\n", in.c_str(), out.c_str(), (unsigned long long)ds.mesh.nb_vertices(),
                    (unsigned long long)ds.mesh.nb_faces());
    else
        std::printf("%s -> %s (%s)\n", in.c_str(), out.c_str(), core::kind_name(ds.kind));
    return 0;
}

int cmd_demo(const GlobalOptions &g, const DemoOptions &o) {
    const core::Registry reg = load_registry(g);
    std::filesystem::create_directories(o.out_dir);
    core::Dataset ds;
    ds.kind = HZ_DATA_STREAMLINES;
    ds.tractogram = core::make_brain_phantom(o.nb_streamlines, o.seed);
    ds.metadata = {{"generator", "horizon demo phantom"}, {"seed", std::to_string(o.seed)}};
    const auto path = std::filesystem::path(o.out_dir) / "phantom.tck";
    core::write_dataset(reg, ds, path, /*force=*/true, nullptr);
    std::string names;
    for (const std::string &n : core::brain_bundle_names()) names += (names.empty() ? "" : ", ") + n;
    std::printf("Wrote the demo phantom (%llu streamlines in %zu named bundles: %s) to %s\n\n", (unsigned long long)o.nb_streamlines,
                core::brain_bundle_names().size(), names.c_str(), path.c_str());
    const int rc = cmd_info(g, path.string(), false, false);
    if (rc != 0 || reg.find("org.horizon.clustering.qbx") == nullptr) return rc;
    // The paper's level of detail: QuickBundlesX centroids before streamlines.
    std::printf("\n");
    ClusterOptions co;
    co.input = path.string();
    co.algorithm = "qbx";
    co.labels = (std::filesystem::path(o.out_dir) / "qbx_labels.csv").string();
    co.centroids = (std::filesystem::path(o.out_dir) / "qbx_centroids_level1.tck").string();
    co.level = 1;
    co.force = true;
    if (const int c = cmd_cluster(g, co); c != 0) return c;
    // The picture: the bundles as tubes, the cortex and slices of a
    // T1-like volume, principled shading.
    std::printf("\n");
    RenderOptions ro;
    ro.out = (std::filesystem::path(o.out_dir) / "demo.png").string();
    ro.size = o.size;
    core::render::Scene scene = core::render::demo_scene(o.nb_streamlines, o.seed);
    o.passes.apply(scene);
    o.annotations.apply(scene);
    o.style.apply(scene);
    o.style.add_glass_brain(reg, scene);
    if (const int c = render_scene(reg, std::move(scene), ro); c != 0) return c;
    // On a desktop, the same scene in the window.
    if (o.window && have_display() && ::isatty(STDOUT_FILENO)) {
        std::printf("\nOpening the window (Q or Esc closes it; --no-window skips it).\n");
        std::fflush(stdout);
        const ViewOptions defaults;  // (named: GCC 12 warns of a temporary's strings as maybe uninitialised)
        core::render::Scene shown = core::render::demo_scene(o.nb_streamlines, o.seed);
        o.passes.apply(shown);
        o.annotations.apply(shown);
        o.style.apply(shown);
        o.style.add_glass_brain(reg, shown);
        return view_scene(reg, std::move(shown), defaults);
    }
    return 0;
}

std::array<double, 3> parse_colour(const std::string &what, const std::string &text) {
    if (text == "black") return {0, 0, 0};
    if (text == "white") return {1, 1, 1};
    if (text == "grey" || text == "gray") return {0.5, 0.5, 0.5};
    std::array<double, 3> c{};
    std::istringstream in(text);
    char comma1 = 0, comma2 = 0;
    if (in >> c[0] >> comma1 >> c[1] >> comma2 >> c[2] && comma1 == ',' && comma2 == ',' && (in >> std::ws).eof() &&
        std::all_of(c.begin(), c.end(), [](double v) { return v >= 0 && v <= 1; }))
        return c;
    throw core::Error((what.empty() ? std::string() : what + ": ") + "'" + text +
                      "' is not a colour (black, white, grey, or R,G,B each in [0, 1])");
}

namespace {
// The linear radiance that the scene's exposure and tone curve show as the
// sRGB-encoded value `v` (0..1): a background the picture shows as asked.
double radiance_shown_as(double v, const core::render::Scene &s) {
    double d = v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
    d = std::min(d, 0.999);
    double c = d;
    if (s.tonemap == "aces") {  // (the inverse of the ACES fit the display applies: glsl.hpp, hz_display)
        const double a = 2.51 - 2.43 * d, b = 0.03 - 0.59 * d;
        c = (-b + std::sqrt(b * b + 4 * a * 0.14 * d)) / (2 * a);
    } else if (s.tonemap == "reinhard") {
        c = d / (1 - d);
    }
    return c / std::max(s.exposure, 1e-30);
}
}  // namespace

void StyleOptions::add_glass_brain(const core::Registry &reg, core::render::Scene &s) const {
    if (glass_brain.empty()) return;
    core::render::Object o;
    o.name = "glass brain";
    o.file = glass_brain;
    o.data = core::read_dataset(reg, glass_brain);
    if (o.data.kind == HZ_DATA_VOLUME) {
        core::Dataset ds;
        ds.kind = HZ_DATA_MESH;
        ds.format = o.data.format + " surface";
        ds.source_space = HZ_SPACE_RASMM;
        ds.mesh = core::render::mask_surface(o.data.volume, 0.0, 20, glass_brain);
        o.data = std::move(ds);
    } else if (o.data.kind != HZ_DATA_MESH || core::is_overlay(o.data)) {
        throw core::Error(glass_brain + ": --glass-brain takes a surface or a volume (a brain mask), not " + core::kind_name(o.data.kind));
    }
    o.kind = HZ_DATA_MESH;
    // Clear glass that bends the light a little: the data inside stays legible.
    o.material.shader = "glass";
    o.material.params = {{"ior", {1.12}}, {"roughness", {0.15}}, {"thickness", {1.0}}};
    o.coloring.color = {0.9, 0.95, 1.0};
    s.files.push_back(glass_brain);
    s.objects.push_back(std::move(o));
}

void StyleOptions::apply(core::render::Scene &s) const {
    if (!buan.empty()) {
        std::vector<core::render::Object *> tracts;
        for (auto &o : s.objects)
            if (o.kind == HZ_DATA_STREAMLINES && !o.peaks && !o.clustering) tracts.push_back(&o);
        if (tracts.size() != buan.size())
            throw core::Error("--buan: " + std::to_string(buan.size()) + " profile" + (buan.size() == 1 ? "" : "s") + " for " +
                              std::to_string(tracts.size()) + " tractogram" + (tracts.size() == 1 ? "" : "s") +
                              " (one .npy a bundle, in the order given)");
        const std::array<double, 3> hl = parse_colour("--buan-highlight", buan_highlight);
        for (std::size_t k = 0; k < buan.size(); ++k) {
            core::render::show_buan(*tracts[k], core::render::read_npy_vector(buan[k]), buan_threshold, hl, buan[k]);
            s.files.push_back(buan[k]);
        }
    }
    if (!background.empty()) {
        const std::array<double, 3> shown = parse_colour("--background", background);
        for (int i = 0; i < 3; ++i) s.background[i] = radiance_shown_as(shown[i], s);
    }
    if (tracts.empty() || tracts == "direction") {
        if (tracts == "direction")
            for (auto &o : s.objects)
                if (o.kind == HZ_DATA_STREAMLINES) o.coloring.mode = "direction";
        return;
    }
    const bool random = tracts == "random";
    const std::array<double, 3> solid = random ? std::array<double, 3>{} : parse_colour("--tract-colour", tracts);
    std::size_t k = 0;
    for (auto &o : s.objects) {
        if (o.kind != HZ_DATA_STREAMLINES) continue;
        o.coloring.mode = "solid";
        o.coloring.color = solid;
        if (random) {  // (the palette is sRGB-encoded; scene colours are linear)
            const auto c = core::render::cluster_palette(double(k++));
            for (int i = 0; i < 3; ++i) o.coloring.color[i] = c[i] <= 0.04045 ? c[i] / 12.92 : std::pow((c[i] + 0.055) / 1.055, 2.4);
        }
    }
}

}  // namespace hz::host
