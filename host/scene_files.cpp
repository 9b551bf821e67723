// A scene from data files, shared by `horizon view` and `horizon render`:
// what a user gets without writing a scene file.
#include "annotations_paint.hpp"
#include "commands.hpp"
#include "progress.hpp"

#include <hz/core/io.hpp>
#include <hz/core/render/scene.hpp>

#include <optional>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>

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
            for (auto &part : core::render::connectome_objects(core::render::read_connectome(f, edges), {}, fs::path(f).stem().string())) {
                part.file = f;
                s.objects.push_back(std::move(part));
            }
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
        o.file = f;
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

void GridOptions::apply(core::render::Scene &s) const {
    if (mode.empty()) {
        if (columns) {
            if (!s.grid) throw core::Error("--grid-columns: there is no grid (give --grid files|folders, or a scene file's \"grid\")");
            s.grid->columns = *columns;
        }
        return;
    }
    std::map<std::string, int> cell_of;
    core::render::SubjectGrid g;
    for (auto &o : s.objects) {
        o.cell = -1;  // (builtins: in every cell)
        if (o.file.empty()) continue;
        const fs::path f(o.file);
        const std::string key = mode == "files" ? f.lexically_normal().string() : f.lexically_normal().parent_path().string();
        const auto [it, fresh] = cell_of.emplace(key, int(cell_of.size()));
        if (fresh) {
            std::string title = mode == "files" ? f.filename().string() : fs::path(key).filename().string();
            if (title.empty()) title = fs::absolute(key.empty() ? fs::path(".") : fs::path(key)).lexically_normal().filename().string();
            g.titles.push_back(title);
        }
        o.cell = it->second;
    }
    if (cell_of.empty()) throw core::Error("--grid " + mode + ": no object is read from a file");
    g.columns = columns.value_or(0);
    s.grid = g;
}

GridLayout grid_layout(const core::render::Scene &s, int w, int h) {
    GridLayout g;
    g.tile_w = w, g.tile_h = h;
    if (!s.grid) return g;
    g.cells = core::render::grid_cells(s);
    const int n = int(g.cells.size());
    if (n == 0) return g;
    g.columns = s.grid->columns > 0 ? std::min(s.grid->columns, n) : int(std::ceil(std::sqrt(double(n)) - 1e-9));
    g.rows = (n + g.columns - 1) / g.columns;
    g.tile_w = w / g.columns, g.tile_h = h / g.rows;
    if (g.tile_w < 16 || g.tile_h < 16)
        throw core::Error("--size " + std::to_string(w) + "x" + std::to_string(h) + ": tiles of " + std::to_string(g.tile_w) + "x" +
                          std::to_string(g.tile_h) + " pixels for " + std::to_string(n) + " cells (" + std::to_string(g.columns) + " x " +
                          std::to_string(g.rows) + "): at least 16x16 each");
    return g;
}

core::render::Image render_picture(core::render::Renderer &r, const GridLayout &g, const core::render::View &view, int w, int h) {
    if (!g.on()) {
        r.render(view, w, h);
        return r.read_image();
    }
    const auto &objects = r.scene().objects;
    std::vector<bool> visible;
    for (const auto &o : objects) visible.push_back(o.visible);
    core::render::Image out;
    out.width = w, out.height = h;
    out.rgba.assign(std::size_t(w) * std::size_t(h) * 4, 0);
    std::array<std::uint8_t, 4> background{0, 0, 0, 255};
    for (std::size_t k = 0; k < g.cells.size(); ++k) {
        for (std::size_t i = 0; i < objects.size(); ++i) {
            const bool want = visible[i] && (objects[i].cell < 0 || objects[i].cell == g.cells[k]);
            if (objects[i].visible != want) r.set_visible(i, want);
        }
        r.render(view, g.tile_w, g.tile_h);
        core::render::Image tile = r.read_image();
        if (k == 0) std::memcpy(background.data(), &tile.rgba[std::size_t(g.tile_w - 1) * 4], 4);  // (its top right corner)
        const int x0 = int(k % std::size_t(g.columns)) * g.tile_w, y0 = int(k / std::size_t(g.columns)) * g.tile_h;
        if (k < r.scene().grid->titles.size() && !r.scene().grid->titles[k].empty()) {
            const double lum = (background[0] + background[1] + background[2]) / (3 * 255.0);
            const double c = lum > 0.5 ? 0.08 : 0.92;
            paint_text(tile, 6, 6, r.scene().grid->titles[k], g.tile_w >= 600 ? 2 : 1, {c, c, c});
        }
        for (int y = 0; y < g.tile_h; ++y)
            std::memcpy(&out.rgba[(std::size_t(y0 + y) * std::size_t(w) + std::size_t(x0)) * 4], &tile.rgba[std::size_t(y) * g.tile_w * 4],
                        std::size_t(g.tile_w) * 4);
    }
    for (std::size_t i = 0; i < objects.size(); ++i)
        if (objects[i].visible != visible[i]) r.set_visible(i, visible[i]);
    // (what no tile covers: the background)
    const std::size_t n = g.cells.size();
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const int col = x / g.tile_w, row = y / g.tile_h;
            if (col < g.columns && row < g.rows && std::size_t(row * g.columns + col) < n) continue;
            std::memcpy(&out.rgba[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4], background.data(), 4);
        }
    return out;
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
