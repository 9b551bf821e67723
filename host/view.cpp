// `horizon view`: the interactive window (GLFW + Dear ImGui). Orbit (left
// drag), pan (right or shift drag), zoom (wheel); a material panel generated
// from each shading plugin's parameter schema with live controls and a
// shading-model switcher; S saves a screenshot, R resets the camera, Q or
// Esc quits. `--script FILE` drives the same handlers from a text file
// (tests run it under Xvfb). Without a display it says so and points to
// `horizon render`.
#include "click_point.hpp"
#include "commands.hpp"
#include "progress.hpp"
#include "session.hpp"
#include "slice_view.hpp"
#include "window.hpp"

#include <hz/core/filter.hpp>
#include <hz/core/io.hpp>
#include <hz/core/params.hpp>
#include <hz/core/render/pick.hpp>
#include <hz/core/render/proxy_governor.hpp>
#include <hz/core/render/renderer.hpp>

#define GLFW_INCLUDE_NONE
#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cfloat>
#include <chrono>
#include <array>
#include <cmath>
#include <memory>
#include <unordered_map>
#include <set>
#include <map>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <atomic>
#include <future>
#include <optional>
#include <sstream>
#include <string_view>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace hz::host {

namespace fs = std::filesystem;
using core::render::Vec3;
using namespace win;

namespace {

// An error in a --script file (named with its line): not the data's.
struct ScriptError : core::Error {
    using core::Error::Error;
};

// A modifier of a scripted click or key: ctrl, alt or shift.
int modifier(const std::string &m) {
    if (m == "ctrl") return GLFW_MOD_CONTROL;
    if (m == "alt") return GLFW_MOD_ALT;
    if (m == "shift") return GLFW_MOD_SHIFT;
    throw core::Error("'" + m + "' is not a modifier (ctrl, alt, shift)");
}

// The words of a script line after its command, read strictly: a word a
// command needs must be there and parse whole, and words left over are an
// error (a typo never silently does nothing, nor a test that cannot fail).
class ScriptWords {
public:
    ScriptWords(std::istringstream &in, std::string op) : in_(in), op_(std::move(op)) {}
    std::string word(const std::string &what) {
        std::string w;
        if (!(in_ >> w)) throw core::Error(op_ + " needs " + what);
        return w;
    }
    std::optional<std::string> maybe() {
        if (std::string w; in_ >> w) return w;
        return std::nullopt;
    }
    double number(const std::string &what) { return parse(word(what), what); }
    std::optional<double> maybe_number(const std::string &what) {
        if (const auto w = maybe()) return parse(*w, what);
        return std::nullopt;
    }
    // A whole number in [0, max].
    std::uint64_t count(const std::string &what, std::uint64_t max) {
        const std::string w = word(what);
        const double v = parse(w, what);
        if (!(v >= 0 && v <= double(max) && v == std::floor(v))) throw core::Error(op_ + ": '" + w + "' is not " + what);
        return std::uint64_t(v);
    }
    std::string rest() {
        std::string r;
        std::getline(in_ >> std::ws, r);
        return r;
    }
    void done() {
        if (const auto w = maybe()) throw core::Error(op_ + ": unexpected '" + *w + "'");
    }

private:
    double parse(const std::string &w, const std::string &what) const {
        char *end = nullptr;
        const double v = std::strtod(w.c_str(), &end);
        if (end == w.c_str() || *end || !std::isfinite(v)) throw core::Error(op_ + ": '" + w + "' is not a number (" + what + ")");
        return v;
    }
    std::istringstream &in_;
    std::string op_;
};

// The interactive exploration of the paper's Fig. 5: a tractogram shown as
// the centroids of one QuickBundlesX level (tubes, width by cluster size);
// "expand" replaces a centroid by its children at the next level, or by its
// streamlines at the last; "hide" removes a cluster; "repeat" re-clusters
// what is still shown. Two scene objects: the centroids and the expanded
// streamlines. Clusters are picked in the window by clicking their centroid
// (a toggle; selected ones are drawn lighter); E expands and H hides every
// selected cluster, A selects all shown clusters or none, C clusters again.
// The clustering --explore runs: --algorithm (a plugin id or its last part)
// with its --param values, checked against the plugin's schema.
core::render::ClusterSpec explore_spec(const core::Registry &reg, const ViewOptions &o) {
    core::render::ClusterSpec spec;
    spec.algorithm = o.algorithm;
    const core::LoadedPlugin *plugin = core::find_clustering(reg, o.algorithm);
    spec.params = core::parse_param_items(core::schema_of(*plugin), plugin->info.id, o.params);
    spec.min_size = o.cluster_size_min, spec.min_length_mm = o.cluster_length_min;
    return spec;
}

// A new object drawn as `o` is (everything but its data, which the caller
// sets): Object holds move-only buffers.
core::render::Object styled_like(const core::render::Object &o) {
    core::render::Object n;
    n.name = o.name, n.kind = o.kind, n.visible = o.visible, n.proxy_for = o.proxy_for, n.render = o.render, n.radius_mm = o.radius_mm;
    n.clustering = o.clustering, n.coloring = o.coloring, n.material = o.material, n.opacity = o.opacity;
    n.slice_x = o.slice_x, n.slice_y = o.slice_y, n.slice_z = o.slice_z, n.window = o.window, n.slice_colormap = o.slice_colormap;
    n.clip_below = o.clip_below;
    n.data.kind = o.data.kind, n.data.format = o.data.format, n.data.loader_id = o.data.loader_id;
    n.data.source_space = o.data.source_space, n.data.metadata = o.data.metadata;
    return n;
}

}  // namespace

bool have_display() {
    const char *display = std::getenv("DISPLAY");
    return display != nullptr && *display != '\0';
}

namespace {

// `horizon render` with the inputs `view` was given: what to run without a display.
std::string render_instead(const std::vector<std::string> &inputs) {
    std::string cmd = "horizon render";
    for (const auto &f : inputs) cmd += " " + f;
    return "render headless instead: `" + cmd + " -o out.png`";
}

void require_display(const std::vector<std::string> &inputs) {
    if (!have_display()) throw core::Error("no display (DISPLAY is not set): the window needs an X server; " + render_instead(inputs));
}

}  // namespace

// "z=10,5": a slab along z, centred at 10 mm, 5 mm either side;
// "z=10,points": the points where streamlines cross the plane z = 10 mm.
core::render::Slab parse_slab(const std::string &spec) {
    core::render::Slab sl;
    char axis = 0, eq = 0, comma = 0;
    std::istringstream in(spec);
    const bool points = spec.size() > 7 && spec.ends_with(",points");
    if (points) in.str(spec.substr(0, spec.size() - 7));
    const bool ok = points ? bool(in >> axis >> eq >> sl.centre) : bool(in >> axis >> eq >> sl.centre >> comma >> sl.half);
    if (!ok || eq != '=' || (!points && comma != ',') || axis < 'x' || axis > 'z' || !(sl.half > 0) || !std::isfinite(sl.centre) ||
        !std::isfinite(sl.half) || in.peek() != EOF)
        throw core::Error("--slab '" + spec +
                          "': expected AXIS=CENTRE,HALF (crop; x, y or z; mm; HALF > 0) or AXIS=CENTRE,points (where streamlines cross "
                          "the plane), e.g. z=10,5 or z=10,points");
    sl.axis = axis - 'x';
    sl.points = points;
    return sl;
}

namespace {}  // namespace

namespace {

// One window over a scene: the editing session (regions, strokes, undo,
// save) and the exploration of paper Fig. 5, what clicks, keys and strokes
// do, the `--script` commands, the panel, and the frame loop. Lives while
// the window shows the scene; its Renderer is the caller's.
class Viewer {
public:
    Viewer(const core::Registry &reg, const ViewOptions &o, GLFWwindow *win, App &app, core::render::Renderer &r, int w0, int h0)
        : reg(reg), o(o), win(win), app(app), r(r), w0(w0), h0(h0) {}
    Viewer(const Viewer &) = delete;
    Viewer &operator=(const Viewer &) = delete;
    ~Viewer() {
        app.on_click = nullptr;  // (they refer to this viewer)
        app.actions.clear();
        app.on_ctrl_scroll = nullptr;
        app.on_stroke = nullptr;
        app.r = nullptr;
    }

    // The editing session over the first tractogram (object ti): the
    // regions of interest that select its streamlines, undo / redo, save.
    // With --explore (paper Fig. 5) it becomes QuickBundlesX centroids
    // (object ci = ti) plus the streamlines expanded so far (si). Adds the
    // regions' wire objects to `scene` and installs the input handlers.
    void setup(core::render::Scene &scene) {
        for (std::size_t i = 0; i < scene.objects.size() && !session; ++i) {
            core::render::Object &ob = scene.objects[i];
            if (ob.kind != HZ_DATA_STREAMLINES || ob.proxy_for) continue;
            ti = i;
            std::vector<core::Roi> rois = Session::rois_from_metadata(reg, ob.data.metadata);  // (a file saved by the window)
            for (const std::string &spec : o.include) rois.push_back(core::parse_roi(reg, spec, true));
            for (const std::string &spec : o.exclude) rois.push_back(core::parse_roi(reg, spec, false));
            // A selection the window saved, reopened with --explore: its
            // clusters as they were saved ("horizon_cluster" per streamline,
            // "horizon_clusters" names), not a new clustering.
            std::vector<std::int64_t> saved_label;
            std::vector<std::string> saved_names;
            if (o.explore) {
                const core::Tractogram &t = ob.data.tractogram;
                for (const auto &a : t.arrays)
                    if (a.name == "horizon_cluster" && a.attach == HZ_ATTACH_STREAMLINE && a.count == t.nb_streamlines() &&
                        a.components == 1) {
                        saved_label.resize(a.count);
                        for (std::uint64_t i = 0; i < a.count; ++i)
                            saved_label[i] = std::int64_t(core::value_at(a.bytes.data() + i * core::dtype_size(a.dtype), a.dtype));
                    }
                for (const auto &[k, val] : ob.data.metadata)
                    if (k == "horizon_clusters") {
                        const nlohmann::json j = nlohmann::json::parse(val, nullptr, false);
                        if (j.is_array())
                            for (const auto &e : j) saved_names.push_back(e.is_string() ? e.get<std::string>() : "");
                    }
                if (saved_names.empty()) saved_label.clear();
            }
            // A large tractogram is clustered in the background (QuickBundlesX
            // over 10M streamlines takes half a minute): the window shows it
            // as it would without --explore (level of detail, refinement
            // held back) until the clusters replace it.
            // So is a saved exploration's (each saved cluster's centroid is
            // a run of the plugin: 2 s at 1M).
            const bool large = ob.data.tractogram.nb_streamlines() >= kLater;
            const bool later = o.explore && saved_label.empty() && large;
            const bool restore_later = o.explore && !saved_label.empty() && large;
            const std::size_t saved_clusters = saved_names.size();
            std::unique_ptr<Explorer> explorer;
            if (o.explore)
                explorer = std::make_unique<Explorer>(reg, ob.data.tractogram.shared(), ob.name, explore_spec(reg, o),
                                                      saved_label.empty() && !later, ob.data.bounds);
            if (explorer && !saved_label.empty() && !restore_later) explorer->restore_saved(saved_label, saved_names);
            session = std::make_unique<Session>(reg, ob.data.tractogram.shared(), o.inputs, std::move(explorer));
            all_bounds = ob.data.bounds;
            ex = session->explorer();
            for (auto &roi : rois) session->add_roi(std::move(roi));
            if (later)
                session->apply_in_background(), first_clusters = true;
            else if (restore_later)
                session->restore_in_background(std::move(saved_label), std::move(saved_names)), first_clusters = restoring = true;
            else if (!session->rois().empty() && large)
                session->apply_in_background(saved_label.empty()), first_selection = true;
            else if (!session->rois().empty())
                session->apply(saved_label.empty());
            if (ex) {
                ci = i;
                if (first_clusters) {
                    if (restore_later)
                        std::printf("restoring the %zu saved clusters in the background; the window shows the %llu streamlines meanwhile\n",
                                    saved_clusters, (unsigned long long)ob.data.tractogram.nb_streamlines());
                    else
                        std::printf("clustering %llu streamlines in the background; the window shows them meanwhile\n",
                                    (unsigned long long)ob.data.tractogram.nb_streamlines());
                    ob.provisional = true;
                } else {
                    ob = ex->centroids_object();
                }
                // The expanded streamlines (a saved exploration's): the
                // tractogram itself, a small copy, or drawn once copied on
                // a thread (display, at the first frame).
                si = scene.objects.size();
                const auto &expanded = ex->expanded();
                expanded_ids = std::make_shared<const std::vector<std::uint64_t>>(expanded);
                shown_expanded_id = ex->expanded_id();
                if (expanded.size() == session->all().nb_streamlines() || positions_bytes(expanded) < kCopyOnThread) {
                    scene.objects.push_back(ex->streamlines_object());
                    shown_ids = expanded_ids;
                } else {
                    scene.objects.push_back(ex->streamlines_object(core::Tractogram{}, core::Bounds{}, {}));
                    shown_ids = std::make_shared<const std::vector<std::uint64_t>>();
                    display_at_first_frame = true;
                }
            } else {
                // (a large tractogram's selection comes later: it is shown
                // whole meanwhile)
                if (!session->rois().empty() && !first_selection)
                    ob.data.tractogram = core::subset_with_arrays(session->all(), session->kept(), true);
                ob.provisional = first_selection;
                shown_ids = session->kept_shared();
            }
            if (first_selection && ex)
                std::printf("selecting the streamlines the regions keep in the background\n");
            else if (first_selection)
                std::printf("selecting the streamlines the regions keep in the background; the window shows all %llu meanwhile\n",
                            (unsigned long long)ob.data.tractogram.nb_streamlines());
            // The regions, drawn as wire figures: include green, exclude red.
            for (bool include : {true, false}) {
                core::render::Object w;
                w.name = include ? "include regions" : "exclude regions";
                w.kind = w.data.kind = HZ_DATA_STREAMLINES;
                w.render = "tubes";
                w.radius_mm = 0.35;
                w.coloring.mode = "solid";
                w.coloring.color = include ? std::array<double, 3>{0.15, 0.85, 0.3} : std::array<double, 3>{0.95, 0.2, 0.15};
                w.material.shader = "flat";
                (include ? wire_in : wire_out) = scene.objects.size();
                scene.objects.push_back(std::move(w));
            }
        }
        if (o.explore && !ex) throw core::Error("--explore needs a tractogram");
        if (!session && (!o.include.empty() || !o.exclude.empty())) throw core::Error("--include and --exclude need a tractogram");
        if (session) {
            for (bool include : {true, false}) {
                core::render::Object &w = scene.objects[include ? wire_in : wire_out];
                w.data.tractogram = wires(include);
                w.visible =
                    std::any_of(session->rois().begin(), session->rois().end(), [&](const core::Roi &x) { return x.include == include; });
            }
            report(!session->rois().empty() && !first_selection);
        }

        register_view_actions();
        if (session) {
            // (while a clustering runs in the background, an edit would wait for
            // it: the window says so instead, at once)
            app.on_click = [this](double x, double y, int mods) { busy_editing() ? say_busy() : on_click(x, y, mods); };
            register_session_actions();
            app.on_stroke = [this](const std::vector<std::array<double, 2>> &stroke) { busy_editing() ? say_busy() : on_stroke(stroke); };
            app.on_ctrl_scroll = [this](double dy) { busy_editing() ? say_busy() : on_ctrl_scroll(dy); };
        }
    }

    // Hands the scene to the renderer with the camera fitted to it, and
    // reads the script.
    void show(core::render::Scene scene, const core::render::RenderSettings &rs, const nlohmann::json &loading) {
        const core::render::View v0 = core::render::fit_view(scene, scene.camera, double(w0) / h0);
        const core::Bounds b = core::render::scene_bounds(scene);
        scene_box = b;  // (the slab's range)
        if (!o.slab.empty()) scene.slab = parse_slab(o.slab);
        if (!b.empty)
            app.radius =
                0.5 * std::sqrt(std::pow(b.max[0] - b.min[0], 2) + std::pow(b.max[1] - b.min[1], 2) + std::pow(b.max[2] - b.min[2], 2));
        r.set_scene(std::move(scene), v0, rs);
        // The proxy's levels and, above the finest, full detail: allowed
        // once a complete still image shows it fits the budget (moving_frame_level).
        governor = core::render::ProxyGovernor(o.lod_frame_ms, r.proxy_level_count() + (o.lod_frame_ms > 0 ? 1 : 0), r.proxy_level());
        full_detail_ms = -1, refining = {};
        app.orbit.from_view(v0);
        app.home = app.orbit;
        if (r.scene().timeline) player.emplace(r, v0, double(w0) / h0), timeline_t = 0, playing = false;
        // Level of detail (paper section 3.4): a tractogram of more than
        // --lod-points points is drawn as a proxy of about that many points
        // while the camera moves and first when it rests, then refined to
        // full detail in steps of about kStepMs.
        // (the tractogram shown until its clusters or its regions'
        // selection replace it: a uniform subsample, not refined)
        if (const std::uint64_t n = r.streamlines_with_proxy(); n > 0 && (first_clusters || (first_selection && !ex)))
            std::printf("level of detail: %llu streamlines drawn as a uniform subsample of about %.0f points until the %s replace them\n",
                        (unsigned long long)n, o.lod.lod_points, first_clusters ? "clusters" : "selected ones");
        else if (n > 0)
            std::printf("level of detail: %llu streamlines drawn as a %s proxy of about %.0f points while moving, refined at rest\n",
                        (unsigned long long)n, o.lod.lod_proxy.c_str(), o.lod.lod_points);
        std::fflush(stdout);

        if (!o.script.empty()) {
            std::ifstream in(o.script);
            if (!in) throw core::Error(o.script + ": cannot open the script");
            // (blank lines and # comments skipped; spaces around a line and
            // a Windows line end dropped; errors name the file's line)
            int number = 0;
            for (std::string line; std::getline(in, line);) {
                ++number;
                const std::size_t a = line.find_first_not_of(" \t\r"), b = line.find_last_not_of(" \t\r");
                if (a == std::string::npos || line[a] == '#') continue;
                script.push_back(line.substr(a, b - a + 1));
                script_line.push_back(number);
            }
        }
        exposure = float(r.scene().exposure);
        for (const auto &ob : r.scene().objects) materials.push_back(ob.material);

        log.loading = loading;
    }

    // Frames until the window closes (or the script quits), then the --stats file.
    void loop() {
        while (!glfwWindowShouldClose(win) && !app.quit) {
            // Nothing to draw (a complete still image, no script, no
            // motion to settle): sleep until an event, so that an idle
            // window costs nothing; wake for the end of a motion or the
            // material bake.
            {
                const double now = glfwGetTime();
                const bool settling = now - app.last_motion < 0.25 || now - app.last_material_edit < App::kBakeAfter + 0.05;
                // (a selection, clustering or stroke in the background is
                // polled every 50 ms; the refinement waits for the first
                // clusters)
                const bool selecting = (session && session->selecting()) || stroking() || copying() || saving();
                const bool busy = ((r.refining() || r.accumulating()) && !holding_refinement()) || r.computing() || !still.valid ||
                                  app.dragging || app.panning || app.force_moving || wait > 0 || queued_click || app.press_stage >= 0 ||
                                  (pc < script.size() && now >= sleep_until) || !app.pending_shot.empty() || first_frame ||
                                  (!o.script.empty() && o.exit_after_script && pc >= script.size());
                if (busy)
                    glfwPollEvents();
                else if (settling || selecting || now < sleep_until)
                    glfwWaitEventsTimeout(std::clamp(sleep_until - now, 0.005, 0.05));
                else
                    glfwWaitEventsTimeout(1.0);
            }
            // One script command per frame (wait N: N frames); a screenshot
            // waits until the still image is complete (as a user would).
            // (and for what the renderer computes in the background: the slab's crossings)
            // (Scripts are deterministic: a selection or clustering still
            // being made in the background is waited for, and shown, before
            // the next command, but `wait`, `sleep` and `nowait` let frames
            // go on meanwhile.)
            const bool pause = pc < script.size() && (script[pc].rfind("wait", 0) == 0 || script[pc].rfind("sleep", 0) == 0 ||
                                                      script[pc].rfind("nowait ", 0) == 0);
            const bool settle_now = pc < script.size() && !pause && wait == 0 && glfwGetTime() >= sleep_until && app.press_stage < 0 &&
                                    session && (session->selecting() || stroking() || copying() || saving());
            if (settle_now && stroking())
                finish_stroke();
            else if (settle_now && session->selecting())
                session->settle(), refresh(r, !std::exchange(reclustering, false));
            if (settle_now && copying()) finish_copy(r);  // (the refresh above may have started it)
            if (settle_now && saving()) finish_save();
            const bool hold_for_still = pc < script.size() && script[pc].rfind("screenshot", 0) == 0 && !app.force_moving &&
                                        (r.refining() || r.accumulating() || r.computing() || !still.valid);
            if (wait > 0)
                --wait;
            else if (glfwGetTime() < sleep_until) {
            } else if (app.press_stage >= 0) {  // a panel press takes its three frames
            } else if (settle_now) {            // (the command runs next frame, over what was shown now)
            } else if (hold_for_still) {
            } else if (pc < script.size()) {
                if (queued_click && !pause) session->wait_for_index(), process_queued_click();
                run_script_line(script[pc++]);
            } else if (!o.script.empty() && o.exit_after_script) {
                app.quit = true;
            }

            if (stroking() && stroke_job.wait_for(std::chrono::seconds(0)) == std::future_status::ready) finish_stroke();
            if (copying() && display_copy->job.wait_for(std::chrono::seconds(0)) == std::future_status::ready) finish_copy(r);
            if (saving() && save_job.wait_for(std::chrono::seconds(0)) == std::future_status::ready) finish_save();
            std::erase_if(copies_retired, [](const auto &f) { return f.wait_for(std::chrono::seconds(0)) == std::future_status::ready; });
            if (std::exchange(display_at_first_frame, false)) display(r, expanded_ids);
            if (session && !stroking() && session->poll()) {  // a selection or clustering made in the background
                first_selection = false;
                const auto t0 = std::chrono::steady_clock::now();
                refresh(r, !std::exchange(reclustering, false));
                spdlog::debug("selection shown: {:.0f} ms",
                              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
            }
            if (queued_click && !stroking() && session->grid_if_ready()) process_queued_click();
            int fw, fh;
            glfwGetFramebufferSize(win, &fw, &fh);
            if (fw <= 0 || fh <= 0) continue;
            const auto frame_t0 = std::chrono::steady_clock::now();
            r.update_proxies(false);  // a shell proxy computed in the background
            const bool moving = app.dragging || app.panning || glfwGetTime() - app.last_motion < 0.25 || app.force_moving;
            const bool full_detail_moving = moving && moving_frame_level(fw, fh) >= r.proxy_level_count();
            r.set_interacting(moving && !full_detail_moving);  // (full detail: the frame a still camera's refinement ends with)
            moving_at_full_detail = full_detail_moving;
            const bool bake = glfwGetTime() - app.last_material_edit > App::kBakeAfter;
            r.set_bake_materials(bake);
            const core::render::View view = app.orbit.view(app.radius);
            Still now;
            now.valid = true;
            for (int k = 0; k < 3; ++k) now.view[k] = view.eye[k], now.view[3 + k] = view.target[k], now.view[6 + k] = view.up[k];
            now.view[9] = view.fov_deg, now.view[10] = view.near_mm, now.view[11] = view.far_mm;
            now.w = fw, now.h = fh, now.generation = r.generation(), now.baked = bake;
            const char *kind;
            if (moving) {
                // The proxy, drawn whole each frame, at the governor's
                // level (or, at its top level, full detail); the still image is gone.
                r.set_proxy_level(governor.level());
                r.render_to_window(view, fw, fh);
                still.valid = false;
                refining.active = false;
                kind = "moving";
            } else if (!(still == now)) {
                // (full detail at once where it fits the moving frames' budget:
                // no proxy picture first, as the moving frames showed none)
                r.begin_progressive(view, fw, fh, full_detail_fits(fw, fh));
                r.present(fw, fh);
                still = now;
                refining = {true, true, 0, {now.generation, std::uint64_t(fw), std::uint64_t(fh)}};
                kind = r.refining() ? "refine" : "complete";
            } else if (r.refining() && !holding_refinement()) {
                // A step and the rest of its frame (presenting it, the
                // panel, the swap) together within kStepMs.
                const double ts = glfwGetTime();
                kind = r.progressive_step(std::max(kStepMs / 4, kStepMs - frame_overhead_ms)) ? "complete" : "refine";
                step_ms = 1000.0 * (glfwGetTime() - ts);
                r.present(fw, fh);
            } else if (r.accumulating() && !holding_refinement()) {
                // the complete still's jittered frames, one a frame, averaged
                r.accumulate_step();
                r.present(fw, fh);
                kind = "accumulate";
            } else if (app.events != seen_events || !app.pending_shot.empty() || app.press_stage >= 0 || wait > 0 ||
                       (pc < script.size() && glfwGetTime() >= sleep_until) || (clustering() && glfwGetTime() >= next_progress_frame)) {
                r.present(fw, fh);  // the kept still image (the panel is redrawn over it)
                kind = "still";
                next_progress_frame = glfwGetTime() + 0.25;  // (the clustering's progress in the panel)
            } else {
                continue;  // nothing changed: no frame at all
            }
            seen_events = app.events;
            if (!app.pending_shot.empty()) {
                const std::string shot = std::exchange(app.pending_shot, {});
                try {
                    save_screenshot(reg, r, shot, fw, fh, annotation_marks(fw, fh));
                } catch (const core::Error &e) {
                    // (S, a user's: one line, and the session goes on; a
                    // script's screenshot command that fails fails it)
                    if (!app.shot_by_key) throw ScriptError(o.script + ": " + e.what());
                    std::fprintf(stderr, "horizon: %s\n", e.what());
                }
                app.shot_by_key = false;
            }

            panel();
            ImGui::Render();
            ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
            glfwSwapBuffers(win);
            const double frame_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - frame_t0).count();
            log.clustering = clustering();
            log.add(kind, r.stats(), frame_ms);
            // (not the first moving frame after others: it also leaves the
            // still image, e.g. allocates the proxy's target)
            const bool moving_frame = std::string_view(kind) == "moving";
            if (moving_frame && (r.stats().proxy || full_detail_moving) && std::exchange(moved_last_frame, true)) governor.add(frame_ms);
            // What full detail costs: the refinement's frames of the last still
            // image refined to completion, or the frame that drew it at once (not
            // the first frame of a refinement, which draws the proxy).
            if (const std::string_view k = kind; refining.active && (k == "refine" || k == "complete")) {
                if (!std::exchange(refining.began, false) || k == "complete") refining.ms += frame_ms;
                if (k == "complete") full_detail_ms = refining.ms, full_detail_key = refining.key, refining.active = false;
            }
            moved_last_frame = moving_frame;
            if (step_ms >= 0) frame_overhead_ms = std::clamp(frame_ms - step_ms, 0.0, kStepMs / 2), step_ms = -1;
            // The regions' spatial index, a second after the first frame
            // (the shell proxy's thread is then done, as a rule).
            // (After the first clusters, which the index would slow down.)
            if (session && !first_clusters && log.first_frame_s >= 0 && seconds_since_launch() > log.first_frame_s + 1.0)
                session->prepare_index();
            if (first_frame) {
                first_frame = false;
                std::printf("first frame after %.2f s\n", seconds_since_launch());
                std::fflush(stdout);
            }
        }
        if (stroking()) stroke_job.wait();
        cancel_copy();
        copies_retired.clear();                 // (each stops at its next 1,024 streamlines)
        if (saving()) finish_save();            // (a save asked for is finished, not lost)
        if (clustering() && session->stop()) {  // (closed before the clusters)
            std::printf("closed before the clusters were there; the clustering stopped\n");
            std::fflush(stdout);
        }
        log.clusters_shown_s = clusters_shown_s;
        if (!o.stats.empty()) log.write(o.stats, r, framebuffer_size(win).first, framebuffer_size(win).second);
    }

private:
    // A wire object's data: the regions of that kind, or a stand-in
    // (hidden) when there is none.
    core::Tractogram wires(bool include) {
        core::Tractogram t = session->roi_wires(include);
        if (t.nb_streamlines() == 0) {
            t.positions = core::Buffer<float>{0, 0, 0, 0, 0, 0.01f};
            t.offsets = core::Buffer<std::uint64_t>{0, 2};
        }
        return t;
    }

    void report(bool selection) {
        if (ex && !first_clusters) std::printf("explore: %s\n", ex->summary().c_str());
        if (selection && !first_clusters) std::printf("roi: %s (%.1f ms)\n", session->summary().c_str(), session->last_filter_ms());
        std::fflush(stdout);
    }

    // After every edit: the objects that show the session again.
    // Streamlines picked by a stroke are drawn lighter: a per-streamline
    // "highlight" array over the object's streamlines, `ids` (indices
    // into the session's tractogram).
    void highlight(core::Tractogram &t, const std::vector<std::uint64_t> &ids) {
        const auto &picked = session->picked();
        if (picked.empty()) return;
        std::vector<float> h(ids.size());
        for (std::size_t i = 0; i < ids.size(); ++i) h[i] = std::binary_search(picked.begin(), picked.end(), ids[i]) ? 1.0f : 0.0f;
        t.arrays.push_back(core::f32_array("highlight", HZ_ATTACH_STREAMLINE, h));
    }

    void refresh(core::render::Renderer &rr, bool selection_changed) {
        // (the tractogram stays until its first clusters are there)
        bool arrived = false;
        if (first_clusters && !session->selecting()) {
            if (ex->anything_shown() || session->all().nb_streamlines() == 0) {
                first_clusters = false, arrived = true;
                clusters_shown_s = seconds_since_launch();
                std::printf("clusters shown %.2f s after launch\n", clusters_shown_s);
            } else if (!said_no_clusters) {  // (failed or cancelled: said on stderr)
                said_no_clusters = true;
                std::printf("no clusters (the clustering did not finish); Reset in the panel clusters again\n");
                // The tractogram stays, now as any tractogram is shown (its
                // level of detail prepared, refined at rest), not as the
                // stand-in it was while the clusters were expected.
                // (once: a failed Reset finds it so already)
                if (const core::render::Object &shown = rr.scene().objects[ci]; shown.provisional) {
                    core::render::Object whole = styled_like(shown);
                    whole.data.tractogram = shown.data.tractogram.shared(), whole.data.bounds = shown.data.bounds;
                    rr.replace_object(ci, std::move(whole));
                }
            }
            std::fflush(stdout);
        }
        if (ex && !first_clusters) {
            // (the centroids keep the material the panel gave them; the
            // first ones replace the tractogram's)
            core::render::Object c = ex->centroids_object();
            if (arrived)
                materials[ci] = c.material;
            else
                c.material = materials[ci];
            rr.replace_object(ci, std::move(c));
            // The expanded streamlines' object (up to the whole tractogram:
            // its level of detail is prepared again) only when they or the
            // streamlines picked changed, not on every click.
            if (ex->expanded_id() != shown_expanded_id || session->picked() != shown_picked) {
                if (ex->expanded_id() != shown_expanded_id)
                    expanded_ids = std::make_shared<const std::vector<std::uint64_t>>(ex->expanded());
                display(rr, expanded_ids);
                shown_expanded_id = ex->expanded_id(), shown_picked = session->picked();
            }
        } else if (!ex && selection_changed) {
            display(rr, session->kept_shared());
        }
        for (bool include : {true, false}) {
            const std::size_t k = include ? wire_in : wire_out;
            core::render::Object w = styled_like(rr.scene().objects[k]);
            const bool any =
                std::any_of(session->rois().begin(), session->rois().end(), [&](const core::Roi &x) { return x.include == include; });
            w.data.tractogram = wires(include);
            rr.replace_object(k, std::move(w));
            rr.set_visible(k, any);
        }
        report(selection_changed && !(arrived && session->rois().empty()));
    }

    // An edit: recorded for undo, applied, shown; an error leaves the
    // session as it was (and says why on stderr, or to the script).
    void edit(const std::function<void()> &fn, bool selection_changes) {
        session->record();
        try {
            fn();
        } catch (const core::Error &) {
            session->rollback();
            throw;
        }
        if (!(reclustering && session->selecting())) refresh(r, selection_changes);  // (a repeat shows when it is done)
    }

    void edit_ui(const std::function<void()> &fn, bool selection_changes) {
        try {
            edit(fn, selection_changes);
        } catch (const core::Error &e) {
            std::fprintf(stderr, "horizon: %s\n", e.what());
        }
    }

    void undo_redo(bool undo) {
        if (!(undo ? session->undo() : session->redo())) {
            std::printf("%s: nothing to %s\n", undo ? "undo" : "redo", undo ? "undo" : "redo");
            std::fflush(stdout);
            return;
        }
        refresh(r, true);
    }

    // A save is written on a thread (10M streamlines: a minute of disk
    // writes); the window goes on meanwhile, and says when it is done.
    // What is saved is what was shown when it was asked for.
    void save_to(const std::string &path, bool force, bool by_user = false) {
        if (saving()) throw core::Error("still saving " + save_path + "; save again when it is done");
        save_by_user = by_user;
        auto job = std::make_shared<Session::SaveJob>(session->prepare_save(path, force));
        save_path = path;
        save_job = std::async(std::launch::async, [s = session.get(), job] { return s->write_save(*job); });
    }
    bool saving() const { return save_job.valid(); }
    void finish_save() {
        try {
            const std::string line = save_job.get();
            std::printf("%s\n", line.c_str());
            log.mark("saved");
        } catch (const std::exception &e) {
            // (a script's save command that fails fails the script; Ctrl+S
            // or the panel's Save, a user's: one line, the window goes on)
            if (!save_by_user && !o.script.empty()) throw ScriptError(o.script + ": " + e.what());
            std::fprintf(stderr, "horizon: %s\n", e.what());
        }
        std::fflush(stdout);
    }

    // Ctrl+S: the next free horizon-selection-N.trx in the screenshot folder.
    void save_next() {
        std::error_code ec;
        fs::path p;
        do p = app.shot_dir / ("horizon-selection-" + std::to_string(++saves) + ".trx");
        while (fs::exists(fs::symlink_status(p, ec)));
        try {
            save_to(p.string(), false, true);
        } catch (const std::exception &e) {
            std::fprintf(stderr, "horizon: %s\n", e.what());
        }
    }

    // The world point under window point (x, y): the picked streamline's
    // depth along the ray through it (nullopt over nothing).
    // (v: the camera of the frame the click was made on.)
    std::optional<std::array<double, 3>> point_under(double x, double y, const core::render::View &v) {
        int ww, wh, fw, fh;
        glfwGetWindowSize(win, &ww, &wh);
        glfwGetFramebufferSize(win, &fw, &fh);
        return host::point_under({&r.scene(), ex ? ci : ti, ex != nullptr, session.get()}, ww, wh, fw, fh, x, y, v);
    }

    // Interactive region edits select in the background (the window
    // goes on drawing; the selection is shown when it is there).
    void place_sphere(const std::array<double, 3> &c, double radius, bool include) {
        core::Roi roi;
        roi.shape = core::Roi::Shape::Sphere;
        roi.center = c;
        roi.radius = radius;
        roi.include = include;
        edit(
            [&] {
                session->add_roi(roi);
                session->apply_in_background();
            },
            false);
        active_roi = session->rois().size() - 1;
    }

    void process_queued_click() {
        const QueuedClick q = *std::exchange(queued_click, std::nullopt);
        const auto t0 = std::chrono::steady_clock::now();
        const auto p = point_under(q.x, q.y, q.view);
        spdlog::debug("pick for a region: {:.0f} ms",
                      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        try {
            if (p)
                place_sphere(*p, 5.0, !(q.mods & GLFW_MOD_ALT));
            else
                std::printf("roi: nothing under (%.0f, %.0f) to place a region on\n", q.x, q.y), std::fflush(stdout);
        } catch (const core::Error &e) {
            std::fprintf(stderr, "horizon: %s\n", e.what());
        }
    }

    // Ctrl+click: an include sphere (5 mm) where the click meets a
    // streamline (or a centroid); a plain click picks a cluster.
    // A clustering runs in the background (the first, a repeat, or over a
    // new selection): edits wait for it, and the window says so at once.
    bool clustering() const { return ex && session->selecting(); }
    bool stroking() const { return stroke_job.valid(); }
    bool copying() const { return display_copy.has_value(); }
    // The bytes of the positions of the session's streamlines `ids`.
    std::uint64_t positions_bytes(const std::vector<std::uint64_t> &ids) const {
        std::uint64_t points = 0;
        for (std::uint64_t s : ids) points += session->all().size(s);
        return points * 12;
    }

    // Shows the streamlines `ids` of the session's tractogram: the kept
    // ones (object ti), or with --explore the expanded ones (si). Every
    // streamline: the tractogram itself; the streamlines of the last copy
    // made: that copy again (a stroke changes only what is highlighted);
    // else a copy, which when large (a region keeping most of ten million
    // streamlines: 17 GB) is made on a thread, cancelled by a newer one,
    // the window showing the last picture meanwhile.
    void display(core::render::Renderer &rr, std::shared_ptr<const std::vector<std::uint64_t>> ids) {
        if (display_copy && (display_copy->ids == ids || *display_copy->ids == *ids)) return;  // (highlighted when it comes)
        cancel_copy();
        const core::Tractogram &all = session->all();
        if (copied_ids && (copied_ids == ids || *copied_ids == *ids)) return show(rr, std::move(ids), copied.t.shared(), copied.bounds);
        copied = CopyData{}, copied_ids.reset();  // (the object holds it while it shows it)
        if (ids->size() == all.nb_streamlines()) return show(rr, std::move(ids), all.shared(), ex ? ex->all_bounds() : all_bounds);
        const std::uint64_t bytes = positions_bytes(*ids);
        // (the kept streamlines carry their data; the expanded ones are
        // coloured by direction)
        auto copy = [&all, with_arrays = !ex](const std::vector<std::uint64_t> &v, const std::atomic<bool> *cancel) {
            return with_arrays ? core::subset_with_arrays(all, v, true, cancel) : core::select_streamlines(all, v, true, cancel);
        };
        if (bytes < kCopyOnThread) {
            copied = CopyData{copy(*ids, nullptr), core::Bounds{}}, copied_ids = ids;
            return show(rr, std::move(ids), copied.t.shared(), copied.bounds);
        }
        auto cancel = std::make_shared<std::atomic<bool>>(false);
        display_copy = Copy{ids, cancel, std::async(std::launch::async, [copy, ids, cancel] {
                                setpriority(PRIO_PROCESS, id_t(syscall(SYS_gettid)), 10);  // (below the frames)
                                CopyData d;
                                d.t = copy(*ids, cancel.get());
                                if (cancel->load()) return d;
                                d.bounds = core::bounds_of(d.t.positions.data(), d.t.nb_stored());  // (not on the window's thread)
                                return d;
                            })};
        std::printf("copying the %zu streamlines %s for display (%.1f GB, in the background)\n", ids->size(), ex ? "expanded" : "kept",
                    double(bytes) / 1e9);
        std::fflush(stdout);
    }
    // Shows `t`, the streamlines `ids` of the session's tractogram (bounds:
    // t's when known, not measured again here).
    void show(core::render::Renderer &rr, std::shared_ptr<const std::vector<std::uint64_t>> ids, core::Tractogram t,
              const core::Bounds &bounds) {
        core::render::Object ob = ex ? ex->streamlines_object(std::move(t), bounds, *ids) : styled_like(rr.scene().objects[ti]);
        if (!ex) ob.data.tractogram = std::move(t), ob.data.bounds = bounds;
        highlight(ob.data.tractogram, *ids);
        rr.replace_object(ex ? si : ti, std::move(ob));
        shown_ids = std::move(ids);
    }
    void finish_copy(core::render::Renderer &rr) {
        Copy c = std::move(*display_copy);
        display_copy.reset();
        try {
            copied = c.job.get(), copied_ids = c.ids;
        } catch (const std::exception &e) {  // (e.g. a copy that fits neither a temporary file nor the memory)
            // What was shown stays shown (its object holds its data), and
            // the session goes on: a save writes from the file, not a copy.
            std::fprintf(stderr, "horizon: the %zu streamlines %s cannot be shown: %s\n", c.ids->size(), ex ? "expanded" : "kept",
                         e.what());
            log.mark("copy-failed");
            return;
        }
        show(rr, c.ids, copied.t.shared(), copied.bounds);
        std::printf("showing the %zu streamlines %s\n", c.ids->size(), ex ? "expanded" : "kept");
        log.mark("copy-shown");  // (in --stats: where the copy made meanwhile replaced the picture)
        std::fflush(stdout);
    }
    void cancel_copy() {
        if (!display_copy) return;
        display_copy->cancel->store(true);
        copies_retired.push_back(std::move(display_copy->job));
        display_copy.reset();
    }
    // Edits wait for a clustering, the first selection of a large
    // tractogram, or a stroke's crossings.
    bool busy_editing() const { return clustering() || selecting_first() || stroking(); }
    bool selecting_first() const { return first_selection && session->selecting(); }
    // The refinement waits for the first clusters or selection, and for a
    // copy for display (the CPU is theirs; what it would refine is about to
    // be replaced).
    bool holding_refinement() const { return ((first_clusters || first_selection) && session->selecting()) || copying(); }

    // Repeat (thresholds: none, fitted to what is shown) or reset, in the
    // background; the clusters shown stay until the new ones are there.
    void recluster(std::vector<double> thresholds, bool reset) {
        session->recluster_in_background(std::move(thresholds), reset);
        reclustering = true, said_no_clusters = false;
        std::printf("clustering again in the background\n");
        std::fflush(stdout);
    }

    // The answer to an edit while a clustering runs in the background, or
    // a stroke's crossings are being found.
    void say_busy() {
        if (stroking() && !clustering()) {
            std::printf("still picking what the last stroke crossed\n");
            std::fflush(stdout);
            return;
        }
        if (selecting_first()) {
            std::printf("still selecting the streamlines the regions keep; edits can be made once they show\n");
            std::fflush(stdout);
            return;
        }
        const ProgressState p = current_progress();
        if (first_clusters && restoring)
            std::printf("still restoring the saved clusters (%.0f %%); they can be picked once they show\n",
                        100 * std::max(0.0, p.fraction));
        else if (p.active && p.fraction >= 0)
            std::printf("still clustering (%.0f %%); the clusters can be picked once they show\n", 100 * p.fraction);
        else
            std::printf("still clustering; the clusters can be picked once they show\n");
        std::fflush(stdout);
    }

    void on_click(double x, double y, int mods) {
        if (mods & GLFW_MOD_CONTROL) {
            // A large tractogram is picked through the spatial
            // index: until it is built, the click waits for it (the
            // window goes on) instead of testing every streamline.
            if (!ex && session->all().nb_streamlines() >= 100000 && !session->grid_if_ready()) {
                session->prepare_index();
                queued_click = QueuedClick{x, y, mods, app.orbit.view(app.radius)};
                std::printf("roi: the click waits for the spatial index\n");
                std::fflush(stdout);
                return;
            }
            const auto p = point_under(x, y, app.orbit.view(app.radius));
            if (!p) {
                std::printf("roi: nothing under (%.0f, %.0f) to place a region on\n", x, y);
                std::fflush(stdout);
                return;
            }
            try {
                place_sphere(*p, 5.0, !(mods & GLFW_MOD_ALT));
            } catch (const core::Error &e) {
                std::fprintf(stderr, "horizon: %s\n", e.what());
            }
            return;
        }
        if (!ex) return;
        // Picking: the centroid under the cursor, on the CPU with the
        // camera the frame is drawn with (cursor coordinates scaled to
        // the framebuffer's pixels).
        int ww, wh, fw, fh;
        glfwGetWindowSize(win, &ww, &wh);
        glfwGetFramebufferSize(win, &fw, &fh);
        if (ww <= 0 || wh <= 0 || fw <= 0 || fh <= 0) return;
        const core::render::Object &cen = r.scene().objects[ci];
        const auto hit = core::render::pick_streamline(cen.data.tractogram, core::render::tube_radii(cen), app.orbit.view(app.radius), fw,
                                                       fh, x * fw / ww, y * fh / wh);
        if (!hit) {
            std::printf("explore: no centroid under (%.0f, %.0f)\n", x, y);
            std::fflush(stdout);
            return;
        }
        const std::size_t k = hit->streamline;
        ex->toggle(k);
        std::printf("explore: %s #%zu %s (level %u, %llu streamlines)\n", ex->is_selected(k) ? "picked" : "unpicked", k,
                    ex->path(ex->shown()[k]).c_str(), ex->level(ex->shown()[k]), (unsigned long long)ex->size(ex->shown()[k]));
        refresh(r, false);
    }

    // The handlers of the session's actions (actions.hpp): edits, answered
    // "busy" while a clustering runs in the background or a stroke's
    // crossings are being found; the exploration's only over one.
    void register_session_actions() {
        auto edit = [this](std::function<void()> fn) {
            return [this, fn] {
                busy_editing() ? say_busy() : fn();
                return true;
            };
        };
        app.actions["undo"] = edit([this] { undo_redo(true); });
        app.actions["redo"] = edit([this] { undo_redo(false); });
        app.actions["save"] = edit([this] { save_next(); });
        // What a stroke picked: keep, delete, invert.
        app.actions["keep picked"] = edit([this] { edit_ui([&] { session->keep_picked(); }, true); });
        app.actions["delete picked"] = edit([this] { edit_ui([&] { session->delete_picked(); }, true); });
        app.actions["invert picked"] = edit([this] { edit_ui([&] { session->invert_picked(); }, true); });
        auto explore = [this](std::function<void()> fn) {
            return [this, fn] {
                if (!ex) return false;
                busy_editing() ? say_busy() : edit_ui(fn, false);
                return true;
            };
        };
        app.actions["expand"] = explore([this] { ex->expand_selected(); });
        app.actions["to streamlines"] =
            explore([this] { ex->expand_selected_to_streamlines(); });  // the selected clusters straight to their streamlines
        app.actions["hide"] = explore([this] { ex->hide_selected(); });
        app.actions["select all"] = explore([this] { ex->select_all(); });
        app.actions["cluster again"] = explore([this] { recluster({}, false); });
    }

    // The handlers of the actions on what is drawn, whatever is shown.
    void register_view_actions() {
        app.actions["annotations"] = [this] {  // annotations on or off (back to those last shown)
            core::render::Annotations a = r.scene().annotations;
            if (a.any())
                shown_annotations = a, a = {};
            else
                a = shown_annotations.any() ? shown_annotations : core::render::Annotations{true, true, true};
            r.set_annotations(a);
            std::printf("annotations: %s\n", a.any() ? "on" : "off");
            std::fflush(stdout);
            return true;
        };
        // A pass on or off: the scene's setting (MEMBER) with its "on" flipped, given back through SET.
        auto toggle = [this](const char *name, auto member, auto set) {
            return [this, name, member, set] {
                auto settings = r.scene().*member;
                settings.on = !settings.on;
                (r.*set)(settings);
                std::printf("%s: %s\n", name, settings.on ? "on" : "off");
                std::fflush(stdout);
                return true;
            };
        };
        app.actions["fit"] = [this] {
            fit_to_shown();
            return true;
        };
        app.actions["depth cue"] = toggle("depth cue", &core::render::Scene::depth_cue, &core::render::Renderer::set_depth_cue);
        app.actions["shadows"] = toggle("shadows", &core::render::Scene::shadows, &core::render::Renderer::set_shadows);
        app.actions["antialiasing"] =
            toggle("anti-aliasing", &core::render::Scene::antialiasing, &core::render::Renderer::set_antialiasing);
        app.actions["occlusion"] =
            toggle("ambient occlusion", &core::render::Scene::ambient_occlusion, &core::render::Renderer::set_ambient_occlusion);
    }

    // The camera refitted to what is shown now (after hiding or expanding
    // clusters, or a region): the same direction, the target at the centre of
    // the visible objects' box, the distance at which the box's extent across
    // the view fits it (as fit_view fits the first view; R still returns to
    // the view the window opened with).
    void fit_to_shown() {
        const core::Bounds b = core::render::scene_bounds(r.scene());
        if (b.empty) {
            std::printf("fit: nothing is shown\n");
            std::fflush(stdout);
            return;
        }
        int fw = 1, fh = 1;
        glfwGetFramebufferSize(win, &fw, &fh);
        const double ty = std::tan(app.orbit.fov * M_PI / 360.0), tx = ty * double(std::max(fw, 1)) / double(std::max(fh, 1));
        const double cp = std::cos(app.orbit.pitch), sp = std::sin(app.orbit.pitch), cy = std::cos(app.orbit.yaw),
                     sy = std::sin(app.orbit.yaw);
        const double dir[3] = {cp * cy, cp * sy, sp};  // (target to eye)
        const double right[3] = {-sy, cy, 0}, up[3] = {-sp * cy, -sp * sy, cp};
        double hw = 0, hh = 0, hd = 0, diagonal = 0;
        for (int k = 0; k < 3; ++k) {
            const double half = std::max(0.5 * (b.max[k] - b.min[k]), 1e-3);
            hw += std::abs(right[k]) * half, hh += std::abs(up[k]) * half, hd += std::abs(dir[k]) * half;
            diagonal += 4 * half * half;
            app.orbit.target[k] = 0.5 * (b.min[k] + b.max[k]);
        }
        app.orbit.distance = std::max(hw / tx, hh / ty) * 1.08 + hd;
        app.radius = std::max(0.5 * std::sqrt(diagonal), 1.0);
        app.last_motion = glfwGetTime();  // (a new still)
        std::printf("fit: %.0f mm across, centred on (%.1f, %.1f, %.1f)\n", std::sqrt(diagonal), app.orbit.target[0], app.orbit.target[1],
                    app.orbit.target[2]);
        std::fflush(stdout);
    }

    // A stroke (Ctrl+drag, or `stroke X0 Y0 X1 Y1 ...`): picks the
    // streamlines it crosses, and over an exploration the clusters
    // whose centroid it crosses.
    // The crossings are found on a thread of their own (a million
    // streamlines: a second of projecting every point); finish_stroke()
    // makes the edit once they are there. Nothing the window shows changes
    // meanwhile: edits are answered "still picking", and a selection made
    // in the background is adopted after the stroke.
    void on_stroke(const std::vector<std::array<double, 2>> &stroke) {
        int ww, wh, fw, fh;
        glfwGetWindowSize(win, &ww, &wh);
        glfwGetFramebufferSize(win, &fw, &fh);
        if (ww <= 0 || wh <= 0 || fw <= 0 || fh <= 0) return;
        std::vector<std::array<double, 2>> px;
        for (const auto &q : stroke) px.push_back({q[0] * fw / ww, q[1] * fh / wh});
        const core::render::View v = app.orbit.view(app.radius);
        stroke_t0 = std::chrono::steady_clock::now();
        stroke_ids = shown_ids;  // (what the object crossed shows; a copy may replace it meanwhile)
        stroke_job = std::async(std::launch::async, [lines = r.scene().objects[ex ? si : ti].data.tractogram.shared(),
                                                     centroids = ex ? r.scene().objects[ci].data.tractogram.shared() : core::Tractogram{},
                                                     v, fw, fh, px, explore = ex != nullptr] {
            // Below the frames' priority (its threads inherit it), as the
            // renderer's background work is.
            setpriority(PRIO_PROCESS, id_t(syscall(SYS_gettid)), 10);
            StrokeHits h;
            h.streamlines = core::render::streamlines_crossing(lines, v, fw, fh, px);
            if (explore)
                for (std::uint64_t k : core::render::streamlines_crossing(centroids, v, fw, fh, px)) h.ranks.push_back(k);
            return h;
        });
    }

    void finish_stroke() {
        StrokeHits h = stroke_job.get();
        std::vector<std::uint64_t> ids = std::move(h.streamlines);
        const std::vector<std::size_t> &ranks = h.ranks;
        for (std::uint64_t &i : ids) i = (*stroke_ids)[i];  // (the object's streamline i is stroke_ids[i])
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - stroke_t0).count();
        edit_ui(
            [&] {
                session->pick(std::move(ids));
                if (ex) ex->select_only(ranks);
            },
            true);
        std::printf("stroke: %zu streamlines picked%s (%.0f ms)\n", session->picked().size(),
                    ex ? (", " + std::to_string(ranks.size()) + " clusters selected").c_str() : "", ms);
        std::fflush(stdout);
    }

    void on_ctrl_scroll(double dy) {
        if (session->rois().empty()) return;
        active_roi = std::min(active_roi, session->rois().size() - 1);
        edit_ui(
            [&] {
                session->resize_roi(active_roi, std::pow(1.1, dy));
                session->apply_in_background();
            },
            false);
    }

    // One command of the script (script[pc - 1], line script_line[pc - 1] of the file).
    void run_script_line(const std::string &line) {
        std::istringstream cmd(line);
        std::string op;
        cmd >> op;
        ScriptWords w(cmd, op);
        try {
            if (op == "nowait") {  // nowait CMD: input at once, as a user's, without waiting for a selection or clustering
                const std::string rest = w.rest();
                const std::string what = rest.substr(0, rest.find(' '));
                if (what != "click" && what != "key" && what != "scroll" && what != "drag" && what != "pan" && what != "stroke")
                    throw core::Error("nowait takes an input command (click, key, scroll, drag, pan, stroke), not '" + what + "'");
                run_script_line(rest);
                return;
            }
            if (op == "wait") {
                wait = int(w.count("a number of frames", 1000000));
                w.done();
            } else if (op == "sleep") {  // wall-clock seconds (frames go on meanwhile)
                const double sec = w.number("seconds");
                if (!(sec >= 0)) throw core::Error("sleep needs seconds >= 0");
                w.done();
                sleep_until = glfwGetTime() + sec;
            } else if (op == "drag" || op == "pan") {
                const double x0 = w.number("X0"), y0 = w.number("Y0"), x1 = w.number("X1"), y1 = w.number("Y1");
                w.done();
                app.last_x = app.press_x = x0, app.last_y = app.press_y = y0;
                app.orbit_started = false;
                (op == "drag" ? app.dragging : app.panning) = true;
                for (int s = 1; s <= 8; ++s) app.drag_to(x0 + (x1 - x0) * s / 8, y0 + (y1 - y0) * s / 8);
                app.dragging = app.panning = false;
            } else if (op == "click") {  // as a left press and release at window point (x, y) [ctrl] [alt] [shift]
                const double x = w.number("X"), y = w.number("Y");
                int mods = 0;
                while (const auto m = w.maybe()) mods |= modifier(*m);
                app.last_x = x, app.last_y = y;
                app.click(x, y, mods);
            } else if (op == "scroll") {
                const double d = w.number("a number of steps");
                w.done();
                app.scroll(d);
            } else if (op == "key") {  // key K, or with modifiers: key ctrl+z, key ctrl+shift+z
                std::string k = w.word("a key (a letter or esc, after ctrl+, shift+, alt+)");
                w.done();
                int mods = 0;
                for (std::size_t plus; (plus = k.find('+')) != std::string::npos && plus + 1 < k.size(); k = k.substr(plus + 1))
                    mods |= modifier(k.substr(0, plus));
                const bool letter = k.size() == 1 && std::isalpha(static_cast<unsigned char>(k[0]));
                if (!letter && k != "esc") throw core::Error("key: '" + k + "' is not a key (a letter or esc)");
                app.key(k == "esc" ? GLFW_KEY_ESCAPE : GLFW_KEY_A + (std::toupper(static_cast<unsigned char>(k[0])) - 'A'), mods);
            } else if (op == "screenshot") {
                const std::string path = w.word("a file name");
                w.done();
                check_outputs({path}, {}, /*force=*/true);  // (its folder, and not a directory or device)
                app.pending_shot = path, app.shot_by_key = false;
            } else if (op == "shader" || op == "set") {
                const std::size_t obj = w.count("an object number", materials.size());
                if (obj >= materials.size()) throw core::Error("no object " + std::to_string(obj));
                if (op == "shader") {
                    materials[obj].shader = w.word("a shading plugin");
                    w.done();
                    materials[obj].params.clear();
                } else {
                    const std::string name = w.word("a parameter name");
                    std::vector<double> v{w.number("a value")};
                    while (const auto x = w.maybe_number("a value")) v.push_back(*x);
                    materials[obj].params[name] = v;
                }
                app.last_material_edit = glfwGetTime();
                r.set_bake_materials(false);
                r.set_material(obj, materials[obj]);
            } else if (op == "expand" || op == "hide" || op == "repeat" || op == "reset") {
                if (!ex) throw core::Error(op + " needs --explore");
                // expand K [streamlines], hide K: K a rank (0 = the
                // largest shown) or a path (c2.1); repeat [T1 T2 ...]:
                // thresholds in mm (default: fitted to what is shown).
                std::string k, mode;
                std::vector<double> thresholds;
                if (op == "expand" || op == "hide") k = w.word("a cluster (a rank such as 0, or a path such as c2.1)");
                if (op == "expand")
                    if (const auto m = w.maybe()) {
                        if (*m != "streamlines") throw core::Error("expand: '" + *m + "' is not 'streamlines'");
                        mode = *m;
                    }
                if (op == "repeat")
                    while (const auto t = w.maybe_number("a threshold in mm")) thresholds.push_back(*t);
                w.done();
                edit(
                    [&] {
                        if (op == "expand" && mode == "streamlines")
                            ex->expand_to_streamlines(ex->rank_of(k));
                        else if (op == "expand")
                            ex->expand(ex->rank_of(k));
                        else if (op == "hide")
                            ex->hide(ex->rank_of(k));
                        else if (op == "repeat")
                            recluster(thresholds, false);
                        else
                            recluster({}, true);
                    },
                    false);
            } else if (op == "roi") {
                // roi sphere X Y Z R [include|exclude], roi box X0 Y0 Z0 X1 Y1 Z1 [...],
                // roi mask FILE [...], roi move K X Y Z, roi scale K F, roi flip K, roi remove K
                if (!session) throw core::Error("roi needs a tractogram");
                const std::string what = w.word("sphere, box, mask, move, scale, flip or remove");
                if (what == "sphere" || what == "box" || what == "mask") {
                    std::string spec;
                    if (what == "mask")
                        spec = w.word("a mask file");
                    else {
                        spec = what + ":";
                        const int n = what == "sphere" ? 4 : 6;
                        for (int i = 0; i < n; ++i) {
                            const auto x = w.maybe();
                            if (!x) throw core::Error("roi " + what + " needs " + std::to_string(n) + " numbers");
                            spec += (i ? "," : "") + *x;
                        }
                    }
                    const std::string mode = w.maybe().value_or("include");
                    if (mode != "include" && mode != "exclude") throw core::Error("roi: '" + mode + "' is neither include nor exclude");
                    w.done();
                    core::Roi roi = core::parse_roi(reg, spec, mode == "include");
                    edit(
                        [&] {
                            session->add_roi(roi);
                            session->apply();
                        },
                        true);
                    active_roi = session->rois().size() - 1;
                } else if (what == "move" || what == "scale" || what == "flip" || what == "remove") {
                    const std::size_t k = w.count("a region number", std::numeric_limits<std::uint32_t>::max());
                    std::array<double, 3> c{};
                    double f = 1;
                    if (what == "move")
                        for (double &x : c) x = w.number("X Y Z");
                    if (what == "scale") f = w.number("a factor");
                    w.done();
                    edit(
                        [&] {
                            if (what == "move")
                                session->move_roi(k, c);
                            else if (what == "scale")
                                session->resize_roi(k, f);
                            else if (what == "flip")
                                session->flip_roi(k);
                            else
                                session->remove_roi(k);
                            session->apply();
                        },
                        true);
                    active_roi = k;
                } else {
                    throw core::Error("roi: unknown '" + what + "' (sphere, box, mask, move, scale, flip, remove)");
                }
            } else if (op == "slice") {  // slice I x|y|z MM, or slice I x|y|z off: volume I's slice along that axis
                const std::size_t obj = w.count("an object number", r.scene().objects.size());
                const std::string axis = w.word("x, y or z");
                if (axis.size() != 1 || axis[0] < 'x' || axis[0] > 'z') throw core::Error("slice needs I x|y|z MM (or off)");
                const std::string at = w.word("a position in mm, or off");
                w.done();
                if (obj >= r.scene().objects.size()) throw core::Error("slice: no object " + std::to_string(obj));
                const auto &ob = r.scene().objects[obj];
                std::optional<double> p[3] = {ob.slice_x, ob.slice_y, ob.slice_z};
                if (at == "off") {
                    p[axis[0] - 'x'].reset();
                } else {
                    char *end = nullptr;
                    const double mm = std::strtod(at.c_str(), &end);
                    if (end == at.c_str() || *end) throw core::Error("slice: '" + at + "' is not a position in mm (or off)");
                    p[axis[0] - 'x'] = mm;
                }
                r.set_slices(obj, p[0], p[1], p[2]);
            } else if (op == "time") {  // time T: the scene's timeline at T seconds (its camera, visibility, materials, slices)
                const double t = w.number("T (seconds)");
                w.done();
                if (!player) throw core::Error("time: the scene has no timeline");
                if (!(t >= 0 && t <= player->duration()))
                    throw core::Error("time " + std::to_string(t) + ": the timeline lasts " + std::to_string(player->duration()) + " s");
                playing = false;
                go_to(t);
            } else if (op == "probe") {  // probe X Y: prints the voxel and value of the slice under window point (X, Y)
                const double x = w.number("X"), y = w.number("Y");
                w.done();
                const std::string v = value_under(x, y);
                std::printf("probe %g %g: %s\n", x, y, v.empty() ? "no slice" : v.c_str());
                std::fflush(stdout);
            } else if (op == "view2d") {  // view2d I x|y|z (or sagittal|coronal|axial), or view2d off: the 2D view of volume I
                const std::string first = w.word("an object number, or off");
                if (first == "off") {
                    w.done();
                    v2d.open = false;
                } else {
                    char *end = nullptr;
                    const unsigned long long obj = std::strtoull(first.c_str(), &end, 10);
                    if (end == first.c_str() || *end) throw core::Error("view2d needs I x|y|z (or sagittal|coronal|axial), or off");
                    const std::string axis = w.word("x, y or z (or sagittal, coronal, axial)");
                    w.done();
                    const auto a = axis_of(axis);
                    if (!a) throw core::Error("view2d: '" + axis + "' is not x, y, z, sagittal, coronal or axial");
                    open_view2d(std::size_t(obj), *a);
                }
            } else if (op == "click2d") {  // click2d X Y: a click on the 2D view's image at pixel (X, Y) from its top left
                const double x = w.number("X"), y = w.number("Y");
                w.done();
                if (!v2d.open) throw core::Error("click2d: no 2D view (view2d I x|y|z first)");
                view2d_click(x, y);
            } else if (op == "save2d") {  // save2d FILE: the 2D view's image, as it is made (a pixel a voxel at the finest)
                const std::string path = w.word("a file name");
                w.done();
                if (!v2d.open) throw core::Error("save2d: no 2D view (view2d I x|y|z first)");
                write_image(reg, view2d_image().image, path, /*force=*/true);
            } else if (op == "window") {  // window I LO HI: the values volume I's colormap spans
                const std::size_t obj = w.count("an object number", r.scene().objects.size());
                const double lo = w.number("LO"), hi = w.number("HI");
                w.done();
                r.set_window(obj, lo, hi);
            } else if (op == "volume") {  // volume I N: volume I shows the N-th 3D volume of its series
                const std::size_t obj = w.count("an object number", r.scene().objects.size());
                const std::uint64_t n = w.count("a volume index", std::uint64_t(1) << 40);
                w.done();
                r.set_volume_index(obj, n);
            } else if (op == "slab") {  // slab x|y|z CENTRE HALF, slab x|y|z CENTRE points [SIZE], or slab off
                const std::string axis = w.word("x|y|z CENTRE HALF, x|y|z CENTRE points [SIZE], or off");
                if (axis == "off") {
                    w.done();
                    r.set_slab(std::nullopt);
                } else {
                    core::render::Slab sl;
                    const char *usage = "slab needs x|y|z CENTRE HALF (mm, HALF > 0), x|y|z CENTRE points [SIZE], or off";
                    if (axis.size() != 1 || axis[0] < 'x' || axis[0] > 'z') throw core::Error(usage);
                    sl.centre = w.number("CENTRE (mm)");
                    const std::string half = w.word("HALF (mm) or points");
                    if (half == "points") {
                        sl.points = true;
                        if (const auto px = w.maybe_number("a point size in pixels")) {
                            if (!(*px >= 1 && *px <= 64)) throw core::Error("slab: the point size is in pixels, 1 to 64");
                            sl.point_px = *px;
                        }
                    } else {
                        char *end = nullptr;
                        sl.half = std::strtod(half.c_str(), &end);
                        if (end == half.c_str() || *end || !(sl.half > 0) || !std::isfinite(sl.half)) throw core::Error(usage);
                    }
                    w.done();
                    sl.axis = axis[0] - 'x';
                    r.set_slab(sl);
                    r.update_proxies(true);  // (scripts are deterministic: the crossings are there for the next command)
                }
            } else if (op == "stroke") {  // stroke X0 Y0 X1 Y1 ...: window points
                if (!session) throw core::Error("stroke needs a tractogram");
                std::vector<std::array<double, 2>> pts;
                while (const auto x = w.maybe_number("X")) pts.push_back({*x, w.number("a Y after each X")});
                if (pts.size() < 2) throw core::Error("stroke needs at least two points (X0 Y0 X1 Y1 ...)");
                app.on_stroke(pts);
            } else if (op == "picked") {  // picked keep|delete|invert
                if (!session) throw core::Error("picked needs a tractogram");
                const std::string what = w.maybe().value_or("");
                if (what != "keep" && what != "delete" && what != "invert") throw core::Error("picked: keep, delete or invert");
                w.done();
                edit(
                    [&] {
                        if (what == "keep")
                            session->keep_picked();
                        else if (what == "delete")
                            session->delete_picked();
                        else
                            session->invert_picked();
                    },
                    true);
            } else if (op == "undo" || op == "redo") {
                if (!session) throw core::Error(op + " needs a tractogram");
                w.done();
                undo_redo(op == "undo");
            } else if (op == "save") {  // save PATH [force]
                if (!session) throw core::Error("save needs a tractogram");
                const std::string path = w.word("a file name");
                const std::string force = w.maybe().value_or("");
                if (!force.empty() && force != "force") throw core::Error("save: '" + force + "' is not 'force'");
                w.done();
                save_to(path, force == "force");
            } else if (op == "press") {
                const std::string label = w.rest();
                const auto b = app.ui_buttons.find(label);
                if (b == app.ui_buttons.end()) throw core::Error("no button '" + label + "' on the panel");
                app.press_at[0] = (b->second[0] + b->second[2]) / 2;
                app.press_at[1] = (b->second[1] + b->second[3]) / 2;
                app.press_stage = 0;
            } else if (op == "moving") {
                const std::string v = w.word("on or off");
                if (v != "on" && v != "off") throw core::Error("moving: '" + v + "' is neither on nor off");
                w.done();
                app.force_moving = v == "on";
                // (scripts are deterministic: the proxies computed in the
                // background, the fibre volume's included, are there first)
                if (app.force_moving) r.update_proxies(true);
            } else if (op == "resize") {  // resize W H: the window's size, as a user's drag of its border would set it
                const auto width = int(w.count("a width in pixels", 16384)), height = int(w.count("a height in pixels", 16384));
                w.done();
                if (width < 1 || height < 1) throw core::Error("resize: the size must be at least 1x1");
                glfwSetWindowSize(win, width, height);
            } else if (op == "fit") {  // fit: the camera refitted to what is shown (V)
                w.done();
                fit_to_shown();
            } else if (op == "mark") {  // mark NAME: a record in --stats between frames (benchmarks, tests)
                const std::string name = w.word("a name");
                w.done();
                log.mark(name);
            } else if (op == "quit") {
                w.done();
                app.quit = true;
            } else {
                throw core::Error("unknown command '" + op + "'");
            }
        } catch (const ScriptError &) {
            throw;  // (a nowait's command: named already)
        } catch (const core::Error &e) {
            throw ScriptError(o.script + ": line " + std::to_string(script_line[pc - 1]) + ": " + e.what());
        }
    }

    // The panel (Dear ImGui) over the frame, and the stroke being drawn.
    void panel() {
        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        if (app.press_stage >= 0) {  // (after the backend, which sets the real pointer's state)
            ImGuiIO &io = ImGui::GetIO();
            io.MousePos = ImVec2(app.press_at[0], app.press_at[1]);
            io.MouseDown[0] = app.press_stage == 1;
            if (++app.press_stage > 2) app.press_stage = -1;
        }
        ImGui::NewFrame();
        app.ui_buttons.clear();
        ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
        // Its height fits what it shows (a section opened below the first
        // height used to be clipped), up to the window's; its width is the
        // user's (dragged, kept from the last frame).
        const float most = std::max(100.0f, ImGui::GetIO().DisplaySize.y - 20.0f);
        ImGui::SetNextWindowSizeConstraints(ImVec2(200.0f, 0.0f), ImVec2(FLT_MAX, most));
        ImGui::SetNextWindowSize(ImVec2(panel_width, 0.0f), ImGuiCond_Always);
        ImGui::Begin("Horizon");
        panel_width = ImGui::GetWindowWidth();
        ImGui::Text("%.0f ms/frame   %llu segments   %llu triangles", r.stats().draw_ms, (unsigned long long)r.stats().segments_drawn,
                    (unsigned long long)r.stats().triangles_drawn);
        if (r.refining())
            ImGui::TextColored(ImVec4(1.0f, 0.8f, 0.3f, 1.0f), "refining: %llu chunks to go",
                               (unsigned long long)r.stats().refine_remaining);
        else if (moving_at_full_detail)
            ImGui::TextColored(ImVec4(1.0f, 0.8f, 0.3f, 1.0f), "moving: full detail (%.0f ms a still image)", full_detail_ms);
        else if (const auto &levels = r.proxy_levels(); r.stats().proxy && std::size_t(r.stats().proxy_level) < levels.size())
            ImGui::TextColored(ImVec4(1.0f, 0.8f, 0.3f, 1.0f), "moving: level of detail at 1/%d of the size, %.0fk points",
                               levels[std::size_t(r.stats().proxy_level)].scale, levels[std::size_t(r.stats().proxy_level)].points / 1e3);
        ImGui::TextDisabled("drag: orbit  right/shift drag: pan  wheel: zoom  %s", actions_help(ActionGroup::View).c_str());
        if (ImGui::SliderFloat("exposure", &exposure, 0.05f, 8.0f, "%.2f", ImGuiSliderFlags_Logarithmic)) r.set_exposure(exposure);
        // What a panel control asks for, done after the panel (an edit:
        // recorded for undo).
        std::function<void()> act;
        bool act_selects = false;
        explore_panel(act);
        regions_panel(act, act_selects);
        if (act && busy_editing())
            say_busy();
        else if (act)
            edit_ui(act, act_selects);
        slab_panel();
        objects_panel();
        depth_cues_panel();
        annotations_panel();
        timeline_panel();
        ImGui::End();
        view2d_window();
        // The annotations over the frame, under the panel: laid out as
        // `render` lays them out (and as screenshots have them).
        if (r.scene().annotations.any()) {
            const ImVec2 size = ImGui::GetIO().DisplaySize;
            paint_marks(ImGui::GetBackgroundDrawList(), annotation_marks(int(size.x), int(size.y)));
        }
        if (app.stroking && app.stroke.size() > 1) {  // the stroke being drawn
            std::vector<ImVec2> pts;
            for (const auto &q : app.stroke) pts.emplace_back(float(q[0]), float(q[1]));
            ImGui::GetForegroundDrawList()->AddPolyline(pts.data(), int(pts.size()), IM_COL32(255, 220, 60, 230), 0, 2.0f);
        }
    }

    // The panel's last item, which a script presses as `press NAME`.
    void scriptable(const std::string &name) {
        const ImVec2 lo = ImGui::GetItemRectMin(), hi = ImGui::GetItemRectMax();
        app.ui_buttons[name] = {lo.x, lo.y, hi.x, hi.y};
    }

    // A panel button that a script can press.
    bool button(const char *label) {
        const bool pressed = ImGui::Button(label);
        scriptable(label);
        return pressed;
    }

    // The exploration: its clusters as a legend, and what to do with them.
    void explore_panel(std::function<void()> &act) {
        if (ex && clustering() && ImGui::CollapsingHeader("Explore (QuickBundlesX, paper Fig. 5)", ImGuiTreeNodeFlags_DefaultOpen)) {
            const ProgressState p = current_progress();
            ImGui::TextColored(ImVec4(1.0f, 0.8f, 0.3f, 1.0f), "%s...", p.active ? p.what.c_str() : "clustering");
            char label[32];
            std::snprintf(label, sizeof label, "%.0f %%", 100 * std::max(0.0, p.fraction));
            ImGui::ProgressBar(p.active && p.fraction >= 0 ? float(p.fraction) : 0.0f, ImVec2(-1, 0), label);
            ImGui::TextDisabled(first_clusters ? "the streamlines are shown meanwhile; their clusters replace them when done"
                                               : "the clusters shown stay until the new ones are there");
            return;
        }
        if (ex && ImGui::CollapsingHeader("Explore (QuickBundlesX, paper Fig. 5)", ImGuiTreeNodeFlags_DefaultOpen)) {
            ImGui::TextWrapped("%s", ex->summary().c_str());
            ImGui::TextDisabled("click a centroid: select  %s", actions_help(ActionGroup::Explore).c_str());
            if (button("Repeat: cluster what is shown")) act = [&] { recluster({}, false); };
            ImGui::SameLine();
            if (button("Reset")) act = [&] { recluster({}, true); };
            // Thresholds for the next repeat (mm, coarse to fine); empty:
            // fitted to the extent of what is shown.
            ImGui::SetNextItemWidth(140);
            ImGui::InputText("##thresholds", thresholds_text, sizeof thresholds_text);
            ImGui::SameLine();
            if (button("Repeat with these thresholds")) {
                std::vector<double> t;
                std::istringstream in{std::string(thresholds_text)};
                for (std::string item; std::getline(in >> std::ws, item, ',');)
                    if (!item.empty()) t.push_back(std::strtod(item.c_str(), nullptr));
                act = [&, t] {
                    if (t.empty() || std::any_of(t.begin(), t.end(), [](double x) { return !(x > 0); }))
                        throw core::Error("thresholds: positive numbers in mm, comma-separated (e.g. 20,10,5)");
                    recluster(t, false);
                };
            }
            if (ImGui::IsItemHovered())
                ImGui::SetTooltip("the thresholds of the last clustering: %s",
                                  [&] {
                                      std::string t;
                                      for (double x : ex->state().thresholds)
                                          t += (t.empty() ? "" : ", ") + std::to_string(int(std::lround(x)));
                                      return t;
                                  }()
                                      .c_str());
            if (ex->nb_selected() > 0) {
                if (button("Expand selected")) act = [&] { ex->expand_selected(); };
                ImGui::SameLine();
                if (button("Hide selected")) act = [&] { ex->hide_selected(); };
            }
            // The legend: each cluster's colour, path, level and size.
            const std::size_t n = std::min<std::size_t>(ex->shown().size(), 40);
            for (std::size_t k = 0; k < n && !act; ++k) {
                const std::uint64_t node = ex->shown()[k];
                ImGui::PushID(int(100000 + k));
                bool sel = ex->is_selected(k);
                if (ImGui::Checkbox("##sel", &sel)) act = [&, k] { ex->toggle(k); };
                ImGui::SameLine();
                const auto rgb = core::render::cluster_palette(double(ex->colour(node)));
                ImGui::ColorButton("##colour", ImVec4(float(rgb[0]), float(rgb[1]), float(rgb[2]), 1.0f), ImGuiColorEditFlags_NoTooltip,
                                   ImVec2(12, 12));
                ImGui::SameLine();
                ImGui::Text("#%zu %s  level %u  %llu", k, ex->path(node).c_str(), ex->level(node), (unsigned long long)ex->size(node));
                ImGui::SameLine();
                if (ImGui::SmallButton("expand")) act = [&, k] { ex->expand(k); };
                ImGui::SameLine();
                if (ImGui::SmallButton("streamlines")) act = [&, k] { ex->expand_to_streamlines(k); };
                ImGui::SameLine();
                if (ImGui::SmallButton("hide")) act = [&, k] { ex->hide(k); };
                ImGui::PopID();
            }
            if (ex->shown().size() > n) ImGui::TextDisabled("... and %zu smaller clusters", ex->shown().size() - n);
        }
        // (Under the exploration's panel, and closed at first there: the
        // panel must fit small windows.)
    }

    // The regions of interest, the strokes' picks, undo, save.
    void regions_panel(std::function<void()> &act, bool &act_selects) {
        if (busy_editing()) return;  // (its edits would wait for the clusters or the stroke)
        if (session && ImGui::CollapsingHeader("Regions of interest", ex ? 0 : ImGuiTreeNodeFlags_DefaultOpen)) {
            if (session->selecting())
                ImGui::TextColored(ImVec4(1.0f, 0.8f, 0.3f, 1.0f), "selecting...");
            else
                ImGui::Text("%llu of %llu streamlines selected (%.0f ms)", (unsigned long long)session->kept().size(),
                            (unsigned long long)session->all().nb_streamlines(), session->last_filter_ms());
            ImGui::TextDisabled(
                "Ctrl+click: include sphere  Ctrl+Alt+click: exclude\nCtrl+wheel: resize  Ctrl+Z / Ctrl+Shift+Z: undo / redo  Ctrl+S: "
                "save");
            if (button("Add sphere")) {
                const std::array<double, 3> c{app.orbit.target[0], app.orbit.target[1], app.orbit.target[2]};
                act = [&, c] {
                    core::Roi roi;
                    roi.center = c, roi.radius = 10.0;
                    session->add_roi(roi);
                    session->apply_in_background();
                    active_roi = session->rois().size() - 1;
                };
            }
            ImGui::SameLine();
            if (button("Undo")) undo_redo(true);
            ImGui::SameLine();
            if (button("Redo")) undo_redo(false);
            ImGui::SameLine();
            if (button("Save")) save_next();
            ImGui::Text("%zu picked, %llu deleted", session->picked().size(), (unsigned long long)session->nb_deleted());
            ImGui::TextDisabled("Ctrl+drag: a stroke picks what it crosses  %s", actions_help(ActionGroup::Stroke).c_str());
            if (!session->picked().empty() || (ex && ex->nb_selected() > 0)) {
                if (button("Keep picked")) act = [&] { session->keep_picked(); }, act_selects = true;
                ImGui::SameLine();
                if (button("Delete picked")) act = [&] { session->delete_picked(); }, act_selects = true;
                ImGui::SameLine();
                if (button("Invert")) act = [&] { session->invert_picked(); }, act_selects = true;
            }
            for (std::size_t k = 0; k < session->rois().size() && !act; ++k) {
                const core::Roi &roi = session->rois()[k];
                ImGui::PushID(int(200000 + k));
                bool include = roi.include;
                if (ImGui::Checkbox("include", &include)) act = [&, k] { session->flip_roi(k), session->apply_in_background(); };
                ImGui::SameLine();
                ImGui::Text("#%zu %s", k, roi.spec().c_str());
                if (roi.shape != core::Roi::Shape::Mask) {
                    // Dragged: the region follows at once; the selection
                    // is made again when the drag ends (one undo step).
                    const auto centre =
                        roi.shape == core::Roi::Shape::Sphere
                            ? roi.center
                            : std::array<double, 3>{(roi.lo[0] + roi.hi[0]) / 2, (roi.lo[1] + roi.hi[1]) / 2, (roi.lo[2] + roi.hi[2]) / 2};
                    float c[3] = {float(centre[0]), float(centre[1]), float(centre[2])};
                    if (ImGui::DragFloat3("centre (mm)", c, 0.25f)) {
                        if (!roi_drag) session->record(), roi_drag = true;
                        session->move_roi(k, {c[0], c[1], c[2]});
                        active_roi = k;
                        refresh(r, false);
                    }
                    if (ImGui::IsItemDeactivatedAfterEdit()) roi_drag = false, session->apply_in_background();
                    float size = float(roi.shape == core::Roi::Shape::Sphere ? roi.radius : (roi.hi[0] - roi.lo[0]) / 2);
                    if (ImGui::SliderFloat(roi.shape == core::Roi::Shape::Sphere ? "radius (mm)" : "half size x (mm)", &size, 0.5f, 60.0f,
                                           "%.1f", ImGuiSliderFlags_Logarithmic)) {
                        if (!roi_drag) session->record(), roi_drag = true;
                        const double now = roi.shape == core::Roi::Shape::Sphere ? roi.radius : (roi.hi[0] - roi.lo[0]) / 2;
                        session->resize_roi(k, size / std::max(now, 1e-6));
                        active_roi = k;
                        refresh(r, false);
                    }
                    if (ImGui::IsItemDeactivatedAfterEdit()) roi_drag = false, session->apply_in_background();
                }
                if (ImGui::SmallButton("remove")) act = [&, k] { session->remove_roi(k), session->apply_in_background(); };
                ImGui::PopID();
            }
        }
    }

    // Cropping streamlines to a slab.
    void slab_panel() {
        if (session && ImGui::CollapsingHeader("Slab (crop streamlines)")) {
            if (r.computing()) ImGui::TextUnformatted("finding the crossings...");
            const auto &sb = scene_box;
            std::optional<core::render::Slab> sl = r.scene().slab;
            bool on = sl.has_value();
            core::render::Slab v = sl.value_or(core::render::Slab{2, (sb.min[2] + sb.max[2]) / 2, 5});
            bool changed = ImGui::Checkbox("crop to a slab", &on);
            ImGui::SameLine();
            changed |= ImGui::Checkbox("points where they cross its centre", &v.points);
            int axis = v.axis;
            changed |= ImGui::Combo("axis", &axis, "x (left-right)\0y (posterior-anterior)\0z (inferior-superior)\0");
            if (axis != v.axis) v.axis = axis, v.centre = (sb.min[axis] + sb.max[axis]) / 2;
            float c = float(v.centre), h = float(v.half);
            changed |= ImGui::SliderFloat("centre (mm)", &c, float(sb.min[v.axis]), float(sb.max[v.axis]), "%.1f");
            changed |= ImGui::SliderFloat("half thickness (mm)", &h, 0.5f, 40.0f, "%.1f", ImGuiSliderFlags_Logarithmic);
            v.centre = c, v.half = h;
            if (changed) r.set_slab(on ? std::optional<core::render::Slab>(v) : std::nullopt);
        }
    }

    // Depth cues (closed at first, after the objects): ambient occlusion,
    // the depth cue and shadows, also switched by O, F and L; and
    // anti-aliasing (G). (A script
    // opens it as `press depth cues`, then presses `press ambient
    // occlusion`, `press depth cue`, `press shadows`.)
    void depth_cues_panel() {
        const bool open = ImGui::CollapsingHeader("depth cues");
        scriptable("depth cues");
        if (!open) return;
        core::render::AmbientOcclusion ao = r.scene().ambient_occlusion;
        float radius = float(ao.radius_mm), strength = float(ao.strength);
        bool changed = ImGui::Checkbox("ambient occlusion (O)", &ao.on);
        scriptable("ambient occlusion");
        if (ao.on) {
            changed |= ImGui::SliderFloat("occlusion radius (mm)", &radius, 0.5f, 30.0f, "%.1f", ImGuiSliderFlags_Logarithmic);
            changed |= ImGui::SliderFloat("occlusion strength", &strength, 0.0f, 1.0f, "%.2f");
            if (r.stats().ao_ms > 0) ImGui::TextDisabled("ambient occlusion: %.1f ms", r.stats().ao_ms);
        }
        if (changed) {
            ao.radius_mm = std::clamp(double(radius), 0.5, 30.0), ao.strength = std::clamp(double(strength), 0.0, 1.0);
            r.set_ambient_occlusion(ao);
        }
        core::render::DepthCue cue = r.scene().depth_cue;
        float fade = float(cue.strength);
        bool cue_changed = ImGui::Checkbox("depth cue (F)", &cue.on);
        scriptable("depth cue");
        if (cue.on) {
            cue_changed |= ImGui::SliderFloat("depth cue strength", &fade, 0.0f, 1.0f, "%.2f");
            if (r.stats().depth_cue_ms > 0) ImGui::TextDisabled("depth cue: %.1f ms", r.stats().depth_cue_ms);
        }
        if (cue_changed) {
            cue.strength = std::clamp(double(fade), 0.0, 1.0);
            r.set_depth_cue(cue);
        }
        core::render::Shadows sh = r.scene().shadows;
        float dark = float(sh.strength), soft = float(sh.softness_mm);
        bool sh_changed = ImGui::Checkbox("shadows (L)", &sh.on);
        scriptable("shadows");
        if (sh.on) {
            sh_changed |= ImGui::SliderFloat("shadow strength", &dark, 0.0f, 1.0f, "%.2f");
            sh_changed |= ImGui::SliderFloat("shadow softness (mm)", &soft, 0.0f, 10.0f, "%.1f");
            if (r.stats().shadow_map > 0)
                ImGui::TextDisabled("shadow map: %dx%d%s", r.stats().shadow_map, r.stats().shadow_map,
                                    r.stats().shadow_ms > 0 ? (", " + std::to_string(int(r.stats().shadow_ms + 0.5)) + " ms").c_str() : "");
        }
        if (sh_changed) {
            sh.strength = std::clamp(double(dark), 0.0, 1.0), sh.softness_mm = std::clamp(double(soft), 0.0, 10.0);
            r.set_shadows(sh);
        }
        core::render::Antialiasing aa = r.scene().antialiasing;
        ImGui::Separator();
        if (ImGui::Checkbox("anti-aliasing (G)", &aa.on)) r.set_antialiasing(aa);
        scriptable("anti-aliasing");
        if (aa.on && r.stats().aa_ms > 0) ImGui::TextDisabled("edge anti-aliasing: %.1f ms", r.stats().aa_ms);
    }

    // What is drawn over the frame (closed at first, last): a colour bar, the
    // orientation, a scale bar; all switched by N. (A script opens it as
    // `press annotations`, then presses `press colour bar`, ...)
    core::render::Annotations shown_annotations;  // (those N brings back)
    float panel_width = 340.0f;                   // the panel's, as the user left it
    // The scene's timeline at time t: its objects' state, and the camera
    // (the window's orbit keeps the superior axis up).
    void go_to(double t) {
        timeline_t = t;
        app.orbit.from_view(player->at(t));
        app.last_motion = glfwGetTime();  // (a moving frame, refined once it stops)
    }

    // A time slider and play for a scene with a timeline; while playing,
    // each frame the instant of the wall clock.
    void timeline_panel() {
        if (!player) return;
        if (playing) {
            const double t = play_from + (glfwGetTime() - play_started);
            if (t >= player->duration()) playing = false;
            go_to(std::min(t, player->duration()));
        }
        if (!ImGui::CollapsingHeader("Timeline", ImGuiTreeNodeFlags_DefaultOpen)) return;
        try {
            float t = float(timeline_t);
            if (ImGui::SliderFloat("time", &t, 0.0f, float(player->duration()), "%.2f s")) playing = false, go_to(t);
            if (ImGui::Checkbox("play", &playing) && playing) {
                if (timeline_t >= player->duration()) timeline_t = 0;
                play_from = timeline_t, play_started = glfwGetTime();
            }
        } catch (const core::Error &e) {
            playing = false;
            std::fprintf(stderr, "horizon: %s\n", e.what());
        }
    }

    void annotations_panel() {
        const bool open = ImGui::CollapsingHeader("annotations");
        scriptable("annotations");
        if (!open) return;
        core::render::Annotations a = r.scene().annotations;
        bool changed = ImGui::Checkbox("colour bar", &a.colour_bar);
        scriptable("colour bar");
        changed |= ImGui::Checkbox("orientation", &a.orientation);
        scriptable("orientation");
        changed |= ImGui::Checkbox("scale bar", &a.scale_bar);
        scriptable("scale bar");
        ImGui::TextDisabled("N: all on or off");
        if (changed) r.set_annotations(a);
    }

    // The annotations' marks for a w x h picture of the current camera.
    std::vector<core::render::Mark> annotation_marks(int w, int h) const {
        if (!r.scene().annotations.any()) return {};
        return core::render::layout_annotations(r.scene().annotations, r.colour_scales(), app.orbit.view(app.radius), w, h);
    }

    // The slicer's readout: the voxel and value of the slice under window
    // point (x, y), "NAME: voxel (i, j, k) = V at (x, y, z) mm"; empty over
    // no slice.
    std::string value_under(double x, double y) {
        int ww, wh, fw, fh;
        glfwGetWindowSize(win, &ww, &wh);
        glfwGetFramebufferSize(win, &fw, &fh);
        host::ClickTarget t{&r.scene(), 0, false, nullptr, true};
        const auto p = host::point_under(t, ww, wh, fw, fh, x, y, app.orbit.view(app.radius));
        if (!p) return {};
        const auto vv = host::voxel_at(r.scene(), *p);
        if (!vv) return {};
        char value[128], line[640];
        const auto &labels = r.scene().objects[vv->object].labels;
        if (vv->colour.size() == 3)  // (a colour volume: its three values)
            std::snprintf(value, sizeof value, "(%.6g, %.6g, %.6g)", vv->colour[0], vv->colour[1], vv->colour[2]);
        else if (labels)  // (a label volume: the label and its name)
            std::snprintf(value, sizeof value, "%.0f %s", vv->value,
                          core::render::label_name(labels->options.table, std::int64_t(vv->value)).c_str());
        else
            std::snprintf(value, sizeof value, "%.6g", vv->value);
        std::snprintf(line, sizeof line, "%s: voxel (%lld, %lld, %lld) = %s at (%.1f, %.1f, %.1f) mm",
                      r.scene().objects[vv->object].name.c_str(), (long long)vv->ijk[0], (long long)vv->ijk[1], (long long)vv->ijk[2],
                      value, (*p)[0], (*p)[1], (*p)[2]);
        return line;
    }

    // A volume's slicer in the panel: each slice's position (a box shows or
    // hides it), the window its colormap spans, the 3D volume of a series.
    // A change goes to the renderer at once (slices and window: no upload;
    // the volume: its texture). Peak, ODF and tensor glyphs get the slices alone
    // (their segments or meshes built again).
    void slicer_controls(std::size_t i) {
        const auto ext = r.volume_extent(i);
        if (!ext) return;
        const auto &ob = r.scene().objects[i];
        try {
            if (ob.peaks && ob.peaks->options.whole) return;  // (every voxel's peaks: no slices to move)
            if (!ob.transfer) {
                std::optional<double> p[3] = {ob.slice_x, ob.slice_y, ob.slice_z};
                bool changed = false;
                for (int a = 0; a < 3; ++a) {
                    ImGui::PushID(a);
                    bool on = p[a].has_value();
                    const float lo = float(ext->box.min[a]), hi = float(ext->box.max[a]);
                    if (ImGui::Checkbox("##on", &on)) p[a] = on ? std::optional<double>((lo + hi) / 2) : std::nullopt, changed = true;
                    ImGui::SameLine();
                    float v = p[a] && !std::isnan(*p[a]) ? float(*p[a]) : (lo + hi) / 2;
                    const char label[] = {char('x' + a), 0};
                    if (ImGui::SliderFloat(label, &v, lo, hi, "%.1f mm") && p[a])
                        p[a] = std::clamp(double(v), ext->box.min[a], ext->box.max[a]), changed = true;
                    ImGui::PopID();
                }
                if (changed) r.set_slices(i, p[0], p[1], p[2]);
            }
            if (ob.peaks || ob.odfs || ob.tensors) return;  // (glyphs: no window, no value under the cursor)
            float win[2] = {float(ext->window[0]), float(ext->window[1])};
            const float span = std::max(win[1] - win[0], 1e-6f);
            if (!ob.labels && ImGui::DragFloatRange2("window", &win[0], &win[1], span / 200, 0, 0, "%.4g", "%.4g") && win[1] > win[0])
                r.set_window(i, win[0], win[1]);
            if (!ob.transfer && !ImGui::GetIO().WantCaptureMouse) under_cursor = value_under(app.last_x, app.last_y);
            ImGui::TextWrapped("%s", under_cursor.empty() ? "(point at a slice: its voxel and value)" : under_cursor.c_str());
            if (!ob.transfer && ImGui::Button("2D view")) open_view2d(i, v2d.open && v2d.object == i ? v2d.axis : 2);
            scriptable("view2d " + std::to_string(i));
            if (ext->volumes > 1) {
                int k = int(std::min<std::uint64_t>(ob.volume_index, INT32_MAX));
                if (ImGui::SliderInt("volume", &k, 0, int(std::min<std::uint64_t>(ext->volumes - 1, INT32_MAX))))
                    r.set_volume_index(i, std::uint64_t(k));
            }
        } catch (const core::Error &e) {
            std::fprintf(stderr, "horizon: %s\n", e.what());
        }
    }

    // The 2D view (slice_view.hpp): opens it on volume `i` across `axis`.
    void open_view2d(std::size_t i, int axis) {
        if (i >= r.scene().objects.size() || !r.volume_extent(i)) throw core::Error("2D view: no volume " + std::to_string(i));
        const auto &ob = r.scene().objects[i];
        if (!core::render::shows_value_slices(ob) || ob.transfer)
            throw core::Error("2D view: " + ob.name + " is not a volume drawn as slices");
        v2d.open = true, v2d.object = i, v2d.axis = axis, v2d.made.reset();
    }
    // Where its plane is: the object's slice on that axis, or the middle of
    // the volume where that slice is hidden.
    double view2d_position() const {
        const auto &ob = r.scene().objects[v2d.object];
        const std::optional<double> p[3] = {ob.slice_x, ob.slice_y, ob.slice_z};
        const auto ext = r.volume_extent(v2d.object);
        const double mid = (ext->box.min[v2d.axis] + ext->box.max[v2d.axis]) / 2;
        return p[v2d.axis] && !std::isnan(*p[v2d.axis]) ? *p[v2d.axis] : mid;
    }
    // Its image, made again when what it shows changed; uploaded.
    const SliceImage &view2d_image() {
        const auto ext = r.volume_extent(v2d.object);
        const auto &ob = r.scene().objects[v2d.object];
        const double pos = view2d_position();
        if (!v2d.made || v2d.made->axis != v2d.axis || v2d.made->position != pos || v2d.made_window != ext->window ||
            v2d.made_volume != ob.volume_index) {
            v2d.made = slice_image(r.scene(), v2d.object, v2d.axis, pos, ext->window, ext->box);
            v2d.made_window = ext->window, v2d.made_volume = ob.volume_index;
            if (v2d.texture == 0) glGenTextures(1, &v2d.texture);
            glBindTexture(GL_TEXTURE_2D, v2d.texture);
            glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);  // (the voxels as they are)
            glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
            glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
            glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, v2d.made->image.width, v2d.made->image.height, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                         v2d.made->image.rgba.data());
            glBindTexture(GL_TEXTURE_2D, 0);
        }
        return *v2d.made;
    }
    // A click at image point (x, y) (pixels from its top left): the other
    // two slices of the object, those shown, go through that point.
    void view2d_click(double x, double y) {
        const SliceImage &im = view2d_image();
        const std::array<double, 3> p = im.world(x, y);
        const auto &ob = r.scene().objects[v2d.object];
        std::optional<double> s[3] = {ob.slice_x, ob.slice_y, ob.slice_z};
        const auto ext = r.volume_extent(v2d.object);
        for (int a = 0; a < 3; ++a)
            if (a != v2d.axis && s[a]) s[a] = std::clamp(p[std::size_t(a)], ext->box.min[a], ext->box.max[a]);
        r.set_slices(v2d.object, s[0], s[1], s[2]);
    }
    // Its plane moved by `steps` pixels (the finest voxel) along its axis.
    void view2d_step(int steps) {
        const auto &ob = r.scene().objects[v2d.object];
        std::optional<double> s[3] = {ob.slice_x, ob.slice_y, ob.slice_z};
        const auto ext = r.volume_extent(v2d.object);
        s[v2d.axis] = std::clamp(view2d_position() + steps * view2d_image().mm_per_pixel, ext->box.min[v2d.axis], ext->box.max[v2d.axis]);
        r.set_slices(v2d.object, s[0], s[1], s[2]);
    }
    // The 2D view's own window: the axis, the image fitted to the window
    // (kept square-pixelled), orientation letters, the other slices as
    // lines, the voxel and value under the pointer; a click moves the other
    // slices there, the wheel steps the plane a voxel at a time.
    void view2d_window() {
        if (!v2d.open) return;
        try {
            ImGui::SetNextWindowSize(ImVec2(360, 400), ImGuiCond_FirstUseEver);
            ImGui::SetNextWindowPos(ImVec2(ImGui::GetIO().DisplaySize.x - 370, 10), ImGuiCond_FirstUseEver);
            const std::string title = "2D view: " + r.scene().objects[v2d.object].name + "###view2d";
            if (!ImGui::Begin(title.c_str(), &v2d.open)) {
                ImGui::End();
                return;
            }
            for (int a = 0; a < 3; ++a) {
                if (a) ImGui::SameLine();
                if (ImGui::RadioButton(axis_view_name(a), v2d.axis == a)) v2d.axis = a;
            }
            const SliceImage &im = view2d_image();
            ImGui::Text("%s %c = %.1f mm", axis_view_name(v2d.axis), char('x' + v2d.axis), im.position);
            const ImVec2 room = ImGui::GetContentRegionAvail();
            const float scale = std::max(0.01f, std::min((room.x) / float(im.image.width),
                                                         (room.y - ImGui::GetTextLineHeightWithSpacing()) / float(im.image.height)));
            const ImVec2 size(float(im.image.width) * scale, float(im.image.height) * scale);
            const ImVec2 at = ImGui::GetCursorScreenPos();
            ImGui::Image(ImTextureID(std::intptr_t(v2d.texture)), size);
            ImDrawList *dl = ImGui::GetWindowDrawList();
            // The other slices shown, as lines across the image.
            const auto &ob = r.scene().objects[v2d.object];
            const std::optional<double> s[3] = {ob.slice_x, ob.slice_y, ob.slice_z};
            for (int a = 0; a < 3; ++a) {
                if (a == v2d.axis || !s[a] || std::isnan(*s[a])) continue;
                std::array<double, 3> p = im.world(0, 0);
                p[std::size_t(a)] = *s[a];
                const auto q = im.pixel(p);
                const ImU32 col = IM_COL32(255, 210, 60, 160);
                if (a == im.u_axis)
                    dl->AddLine(ImVec2(at.x + float(q[0]) * scale, at.y), ImVec2(at.x + float(q[0]) * scale, at.y + size.y), col);
                else
                    dl->AddLine(ImVec2(at.x, at.y + float(q[1]) * scale), ImVec2(at.x + size.x, at.y + float(q[1]) * scale), col);
            }
            // Orientation letters at the middle of each edge.
            static const char *plus[3] = {"R", "A", "S"}, *minus[3] = {"L", "P", "I"};
            const ImU32 text = IM_COL32(255, 255, 255, 220);
            const float th = ImGui::GetTextLineHeight();
            dl->AddText(ImVec2(at.x + 3, at.y + size.y / 2 - th / 2), text, (im.u_sign > 0 ? minus : plus)[im.u_axis]);
            dl->AddText(ImVec2(at.x + size.x - 12, at.y + size.y / 2 - th / 2), text, (im.u_sign > 0 ? plus : minus)[im.u_axis]);
            dl->AddText(ImVec2(at.x + size.x / 2 - 4, at.y + 2), text, (im.v_sign > 0 ? plus : minus)[im.v_axis]);
            dl->AddText(ImVec2(at.x + size.x / 2 - 4, at.y + size.y - th - 2), text, (im.v_sign > 0 ? minus : plus)[im.v_axis]);
            v2d.readout.clear();
            if (ImGui::IsItemHovered()) {
                const ImVec2 m = ImGui::GetIO().MousePos;
                const double x = (m.x - at.x) / scale, y = (m.y - at.y) / scale;
                const std::array<double, 3> p = im.world(x, y);
                if (const auto vv = voxel_of(r.scene(), v2d.object, p)) {
                    char line[256];
                    std::snprintf(line, sizeof line, "voxel (%lld, %lld, %lld) = %.6g at (%.1f, %.1f, %.1f) mm", (long long)vv->ijk[0],
                                  (long long)vv->ijk[1], (long long)vv->ijk[2], vv->value, p[0], p[1], p[2]);
                    v2d.readout = line;
                }
                if (ImGui::IsMouseClicked(0)) view2d_click(x, y);
                if (const float wheel = ImGui::GetIO().MouseWheel; wheel != 0) view2d_step(wheel > 0 ? 1 : -1);
            }
            ImGui::TextUnformatted(v2d.readout.empty() ? "(point at the image: its voxel and value)" : v2d.readout.c_str());
            ImGui::End();
        } catch (const core::Error &e) {
            std::fprintf(stderr, "horizon: %s\n", e.what());
            ImGui::End();
            v2d.open = false;
        }
    }

    // Each object: visible, and its material's controls.
    void objects_panel() {
        for (std::size_t i = 0; i < r.scene().objects.size(); ++i) {
            const auto &ob = r.scene().objects[i];
            ImGui::PushID(int(i));
            const bool open = ImGui::CollapsingHeader(ob.name.c_str(), i == 0 ? ImGuiTreeNodeFlags_DefaultOpen : 0);
            scriptable("object " + std::to_string(i));  // (opened or closed as `press object I`)
            if (open) {
                bool vis = ob.visible;
                if (ImGui::Checkbox("visible", &vis)) r.set_visible(i, vis);
                scriptable("visible " + std::to_string(i));
                if (ob.kind == HZ_DATA_VOLUME || ob.peaks || ob.odfs || ob.tensors) slicer_controls(i);
                if (ob.kind != HZ_DATA_VOLUME && material_controls(reg, ob, materials[i])) {
                    try {
                        app.last_material_edit = glfwGetTime();
                        r.set_bake_materials(false);
                        r.set_material(i, materials[i]);
                    } catch (const core::Error &e) {
                        std::fprintf(stderr, "horizon: %s\n", e.what());
                        materials[i] = ob.material;
                    }
                }
            }
            ImGui::PopID();
        }
    }

    const core::Registry &reg;
    const ViewOptions &o;
    GLFWwindow *win;
    App &app;
    core::render::Renderer &r;
    int w0, h0;
    std::unique_ptr<Session> session;
    Explorer *ex = nullptr;
    std::size_t ti = 0, ci = 0, si = 0, wire_in = 0, wire_out = 0;
    int saves = 0;
    std::string under_cursor;  // the slicer's readout (value_under) at the cursor
    // The 2D view of a slice (slice_view.hpp), beside the 3D view: the
    // object and the axis across its plane; the image, made again when the
    // plane, the window or the 3D volume shown changes, and its texture.
    struct View2D {
        bool open = false;
        std::size_t object = 0;
        int axis = 2;
        std::optional<SliceImage> made;
        std::array<double, 2> made_window{};
        std::uint64_t made_volume = 0;
        GLuint texture = 0;
        std::string readout;  // the voxel and value under the pointer, over the image
    } v2d;
    std::size_t active_roi = 0;     // the region Ctrl+wheel resizes (the last placed or edited)
    bool roi_drag = false;          // a panel drag of a region in progress (recorded once for undo)
    char thresholds_text[64] = "";  // the panel's thresholds for the next repeat
    struct QueuedClick {
        double x, y;
        int mods;
        core::render::View view;
    };
    std::optional<QueuedClick> queued_click;  // a Ctrl+click waiting for the spatial index
    struct StrokeHits {
        std::vector<std::uint64_t> streamlines;  // (indices into the object's streamlines)
        std::vector<std::size_t> ranks;          // (the clusters whose centroids it crosses)
    };
    std::future<StrokeHits> stroke_job;  // a stroke's crossings, being found (on_stroke)
    // Streamlines copied for display (display): the copy being made on a
    // thread, copies a newer one cancelled, finishing, and the last copy
    // made, of copied_ids. shown_ids: the streamlines the kept or expanded
    // object shows (indices into the session's tractogram); stroke_ids:
    // those of the object a stroke being picked crossed.
    static constexpr std::uint64_t kCopyOnThread = std::uint64_t(256) << 20;  // bytes of positions
    struct CopyData {
        core::Tractogram t;
        core::Bounds bounds;
    };
    struct Copy {
        std::shared_ptr<const std::vector<std::uint64_t>> ids;
        std::shared_ptr<std::atomic<bool>> cancel;
        std::future<CopyData> job;
    };
    std::optional<Copy> display_copy;
    std::vector<std::future<CopyData>> copies_retired;
    std::shared_ptr<const std::vector<std::uint64_t>> copied_ids, expanded_ids;
    CopyData copied;
    std::future<std::string> save_job;  // a save being written (save_to), to save_path
    std::string save_path;
    std::shared_ptr<const std::vector<std::uint64_t>> shown_ids, stroke_ids;
    std::chrono::steady_clock::time_point stroke_t0;
    core::Bounds scene_box;  // (the slab's range)
    std::vector<std::string> script;
    std::vector<int> script_line;  // each command's line in the file
    std::size_t pc = 0;
    int wait = 0;
    double sleep_until = 0;
    bool save_by_user = false;  // the save under way: Ctrl+S or the panel's (else a script's save command)
    float exposure = 1;
    std::vector<core::render::Material> materials;
    // The still image: the view, size and scene generation it shows.
    struct Still {
        bool valid = false;
        std::array<double, 12> view{};
        int w = 0, h = 0;
        std::uint64_t generation = 0;
        bool baked = false;  // (the baked programs draw the same picture, faster: drawn again with them)
        bool operator==(const Still &) const = default;
    };
    Still still;
    FrameLog log;
    // The proxy's level while the camera moves, from the moving frames'
    // times (--lod-frame-ms); set up with the scene (show).
    core::render::ProxyGovernor governor{0, 1, 0};
    bool moved_last_frame = false;
    // Full detail while moving, the governor's top level (one above the
    // proxy's finest): allowed while the last still image refined to
    // completion took, all its frames together, under kFastShare of
    // --lod-frame-ms, for the data now shown at the window's size (a GPU's
    // window at up to a few hundred thousand streamlines: the moving picture
    // is then the data's). Another camera may cost more (zoomed in: longer
    // lines): the governor steps down on slow moving frames, and a still
    // drawn at once that took longer ends it.
    double full_detail_ms = -1;          // (-1: not known)
    bool moving_at_full_detail = false;  // (this frame: the panel says so)
    // The scene's timeline (TimelinePlayer): the instant shown, and whether
    // it plays (in real time from `play_started`, when it was at `play_from`).
    std::optional<TimelinePlayer> player;
    double timeline_t = 0, play_from = 0, play_started = 0;
    bool playing = false;
    std::array<std::uint64_t, 3> full_detail_key{};  // (the data's generation and the window's size it was measured at)
    // The still image being refined (active): whether its refinement began
    // this frame, its steps' frames so far, and the key it is measured for.
    struct Refining {
        bool active = false, began = false;
        double ms = 0;
        std::array<std::uint64_t, 3> key{};
    } refining;
    bool full_detail_fits(int w, int h) const {
        const std::array<std::uint64_t, 3> key{r.generation(), std::uint64_t(w), std::uint64_t(h)};
        return o.lod_frame_ms > 0 && full_detail_ms >= 0 && full_detail_key == key &&
               full_detail_ms < core::render::ProxyGovernor::kFastShare * o.lod_frame_ms;
    }
    int moving_frame_level(int w, int h) {
        const int proxies = r.proxy_level_count();
        governor.set_finest(full_detail_fits(w, h) ? proxies : proxies - 1);
        return governor.level();
    }
    std::uint64_t seen_events = ~0ull;
    // A refinement frame: its step's time (-1: none this frame), and what
    // the last one's frame took besides.
    double step_ms = -1, frame_overhead_ms = 0;
    bool first_frame = true;
    // The first clustering of a large tractogram, and the first selection
    // of its regions, run in the background (Session::apply_in_background):
    // the tractogram is shown meanwhile, unrefined, and edits wait for them.
    static constexpr std::uint64_t kLater = 100000;
    core::Bounds all_bounds;  // of the whole tractogram, as loaded (objects of all of it are given them)
    // What the expanded streamlines' object (si) was last built from.
    std::uint64_t shown_expanded_id = ~std::uint64_t(0);
    std::vector<std::uint64_t> shown_picked;
    bool first_clusters = false;  // the tractogram is shown (object ci) until its first clusters are there
    bool restoring = false;       // (they are a saved exploration's, restored in the background)
    // The regions' first selection of a large tractogram runs in the
    // background too: the tractogram is shown whole meanwhile (plain view).
    bool first_selection = false;
    bool display_at_first_frame = false;  // (a saved exploration's expanded streamlines, copied on a thread)
    bool said_no_clusters = false;        // (the first clustering failed: said once)
    bool reclustering = false;            // (the clustering in the background is a repeat or reset: no new selection)
    double clusters_shown_s = -1;         // (seconds after launch; the --stats file's)
    double next_progress_frame = 0;       // (the panel's progress, redrawn 4 times a second)
};

}  // namespace

int view_scene(const core::Registry &reg, core::render::Scene scene, const ViewOptions &o) {
    auto shared = std::make_shared<core::render::Scene>(std::move(scene));
    return view_scene(reg, std::function<core::render::Scene()>([shared] { return std::move(*shared); }), o);
}

int view_scene(const core::Registry &reg, const std::function<core::render::Scene()> &make_scene, const ViewOptions &o) {
    require_display(o.inputs);
    const char *display = std::getenv("DISPLAY");
    glfwSetErrorCallback(on_glfw_error);
    if (!glfwInit())
        throw core::Error("cannot open the display " + std::string(display) + " (" + glfw_error + "); " + render_instead(o.inputs));
    struct GlfwGuard {
        ~GlfwGuard() { glfwTerminate(); }
    } glfw_guard;
    const auto [w0, h0] = parse_size(o.size);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    GLFWwindow *win = glfwCreateWindow(w0, h0, "Horizon", nullptr, nullptr);
    if (!win) throw core::Error("cannot create an OpenGL 4.1 core window: " + glfw_error);
    glfwMakeContextCurrent(win);
    glfwSwapInterval(1);

    App app;
    app.reg = &reg;
    app.win = win;
    app.shot_dir = o.screenshot_dir;
    glfwSetWindowUserPointer(win, &app);
    // Our handlers first: ImGui's GLFW backend (install_callbacks = true)
    // chains to the callbacks already installed.
    glfwSetMouseButtonCallback(win, cb_button);
    glfwSetCursorPosCallback(win, cb_cursor);
    glfwSetScrollCallback(win, cb_scroll);
    glfwSetKeyCallback(win, cb_key);
    glfwSetCharCallback(win, cb_char);
    glfwSetWindowRefreshCallback(win, cb_refresh);
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOpenGL(win, true);
    ImGui_ImplOpenGL3_Init("#version 410");

    int result = 0;
    nlohmann::json loading;
    std::optional<core::render::Scene> loaded = load_in_window(win, app, make_scene, loading);
    if (!loaded) {
        ImGui_ImplOpenGL3_Shutdown();
        ImGui_ImplGlfw_Shutdown();
        ImGui::DestroyContext();
        glfwDestroyWindow(win);
        return 0;
    }
    core::render::Scene scene = std::move(*loaded);
    {
        core::render::Renderer r(reg);
        app.r = &r;
        core::render::RenderSettings rs;
        rs.width = w0, rs.height = h0, rs.samples = o.samples;
        rs.proxy_levels = o.lod_frame_ms > 0;  // (moving frames pick one: ProxyGovernor)
        o.lod.apply(rs);
        rs.time_passes = !o.stats.empty();  // (a sync per pass: only when the frames are recorded)
        // At rest, where a frame is cheap, the still's jittered frames averaged
        // (the scene's `antialiasing.frames` where more; --aa-frames N: N,
        // 1 for the edge pass alone).
        rs.rest_aa_frames = o.passes.aa_frames > 0 ? o.passes.aa_frames : kRestAaFrames;
        // Baked materials, except while the material panel is being edited
        // (each new value would compile a program): see App::material_edited.
        rs.bake_materials = true;
        Viewer viewer(reg, o, win, app, r, w0, h0);
        viewer.setup(scene);
        viewer.show(std::move(scene), rs, loading);
        viewer.loop();
    }
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
    glfwDestroyWindow(win);
    return result;
}

int cmd_view(const GlobalOptions &g, const ViewOptions &o) {
    const core::Registry reg = load_registry(g);
    if (o.explore) explore_spec(reg, o);  // (a bad --algorithm or --param fails before anything opens)
    if (!o.slab.empty()) parse_slab(o.slab);
    for (const auto *list : {&o.include, &o.exclude})  // (and a bad region)
        for (const std::string &spec : *list) core::parse_roi(reg, spec, list == &o.include);
    // (--stats is written at exit: its place is checked now, not after the session)
    if (!o.stats.empty()) check_outputs({o.stats}, o.inputs, /*force=*/true);
    require_display(o.inputs);
    try {
        // (read once the window is open, which shows the progress)
        return view_scene(reg, std::function<core::render::Scene()>([&] {
                              core::render::Scene s = scene_from_inputs(reg, o.inputs, o.view, "view");
                              o.passes.apply(s);
                              o.annotations.apply(s);
                              o.style.apply(s);
                              o.style.add_glass_brain(reg, s);
                              o.volumes.apply(s);
                              return s;
                          }),
                          o);
    } catch (const ScriptError &) {
        throw;  // (names the script and its line, not the data)
    } catch (const core::Error &e) {
        // (a reading error names the file already)
        if (o.inputs.size() == 1 && std::string_view(e.what()).find(o.inputs[0]) == std::string_view::npos)
            throw core::Error(o.inputs[0] + ": " + e.what());
        throw;
    }
}

}  // namespace hz::host
