// A scene from data files, shared by `horizon view` and `horizon render`:
// what a user gets without writing a scene file.
#include "commands.hpp"
#include "progress.hpp"

#include <hz/core/io.hpp>
#include <hz/core/render/scene.hpp>

#include <optional>
#include <algorithm>
#include <cmath>
#include <filesystem>

namespace hz::host {

namespace fs = std::filesystem;

// A scene from data files: tractograms as direction-coloured tubes or lines,
// meshes as principled surfaces, volumes as three slices.
core::render::Scene scene_from_files(const core::Registry &reg, const std::vector<std::string> &files) {
    core::render::Scene s;
    for (std::size_t k = 0; k < files.size(); ++k) {
        const std::string &f = files[k];
        if (fs::path(f).extension() == ".node") {
            // A BrainNet Viewer connectome: its nodes, and the .edge file named right after it.
            std::string edges;
            if (k + 1 < files.size() && fs::path(files[k + 1]).extension() == ".edge") edges = files[++k];
            for (auto &part : core::render::connectome_objects(core::render::read_connectome(f, edges), {}, fs::path(f).stem().string()))
                s.objects.push_back(std::move(part));
            continue;
        }
        core::render::Object o;
        std::optional<Progress> reading(std::in_place, "reading " + f, true);
        core::Dataset data = core::read_dataset(reg, f, reading->task());
        reading.reset();
        if (core::is_overlay(data)) {
            // Per-vertex values (lh.thickness, overlay-only GIFTI): onto the
            // last surface named before it, which is then coloured by them.
            auto last =
                std::find_if(s.objects.rbegin(), s.objects.rend(), [](const core::render::Object &x) { return x.kind == HZ_DATA_MESH; });
            if (last == s.objects.rend())
                throw core::Error(f + ": per-vertex values need their surface named before them (view lh.white lh.thickness)");
            core::render::colour_by_overlay(*last, core::attach_overlay(last->data.mesh, data, f));
            continue;
        }
        o.name = fs::path(f).filename().string();
        o.data = std::move(data);
        o.kind = o.data.kind;
        if (o.kind == HZ_DATA_STREAMLINES) {
            o.coloring.mode = "direction";
            o.render = o.data.tractogram.nb_streamlines() <= 20000 ? "tubes" : "lines";
            o.radius_mm = 0.3;
            // A selection the window saved: coloured by the clusters it was
            // saved with (per-streamline "horizon_cluster", -1 for streamlines
            // expanded on their own), with the palette the window used.
            core::Tractogram &t = o.data.tractogram;
            std::vector<float> ids;
            for (const auto &a : t.arrays)
                if (a.name == "horizon_cluster" && a.attach == HZ_ATTACH_STREAMLINE && a.count == t.nb_streamlines() && a.components == 1) {
                    ids.resize(a.count);
                    for (std::uint64_t i = 0; i < a.count; ++i)
                        ids[i] = float(core::value_at(a.bytes.data() + i * core::dtype_size(a.dtype), a.dtype));
                }
            if (!ids.empty()) {
                t.arrays.push_back(core::f32_array("cluster_id", HZ_ATTACH_STREAMLINE, ids));
                o.coloring.mode = "cluster";
            }
        } else if (o.kind == HZ_DATA_MESH) {
            o.coloring.color = {0.85, 0.72, 0.68};
            core::render::apply_file_material(o, false, false);
        } else if (o.kind == HZ_DATA_VOLUME) {
            o.slice_x = o.slice_y = o.slice_z = std::nan("");
            // (a PAM5 file holds peaks: drawn as their glyphs)
            if (o.data.format.rfind("pam5", 0) == 0) core::render::show_as_peaks(o, {}, f);
        } else {
            throw core::Error(f + ": " + core::kind_name(o.kind) + " data cannot be shown in the 3D view");
        }
        s.objects.push_back(std::move(o));
    }
    return s;
}

const std::vector<std::string> &named_views() {
    static const std::vector<std::string> names = {"left", "right", "anterior", "posterior", "superior", "inferior"};
    return names;
}

bool is_scene_file(const std::vector<std::string> &inputs) { return inputs.size() == 1 && fs::path(inputs[0]).extension() == ".json"; }

core::render::Scene scene_from_inputs(const core::Registry &reg, const std::vector<std::string> &inputs, const std::string &view,
                                      const char *command) {
    if (inputs.empty()) throw core::Error(std::string(command) + ": give data files or a scene file (.json)");
    core::render::Scene scene = is_scene_file(inputs) ? core::render::load_scene(reg, inputs[0]) : scene_from_files(reg, inputs);
    if (!view.empty()) {
        if (std::find(named_views().begin(), named_views().end(), view) == named_views().end())
            throw core::Error("unknown view '" + view + "' (left, right, anterior, posterior, superior, inferior)");
        scene.camera.view = view;
        scene.camera.position.reset();
        scene.camera.target.reset();
        scene.camera.up = {0, 0, 1};
    }
    return scene;
}

}  // namespace hz::host
