// The window's machinery, apart from what it shows: the GLFW window's state
// and input (App, its camera orbit, the callbacks), the panel's material
// controls, screenshots, per-frame statistics (view --stats), and the panel
// that shows a file being read. view.cpp builds the session on it.
#pragma once

#include "actions.hpp"
#include "commands.hpp"
#include "annotations_paint.hpp"

#include <hz/core/io.hpp>
#include <hz/core/render/annotations.hpp>
#include <hz/core/render/renderer.hpp>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>

namespace hz::host::win {

namespace fs = std::filesystem;
using core::render::Vec3;

inline std::string glfw_error;
inline void on_glfw_error(int, const char *msg) { glfw_error = msg ? msg : "unknown GLFW error"; }

// Orbit camera around a target.
struct Orbit {
    Vec3 target{0, 0, 0};
    double yaw = 0, pitch = 0, distance = 100, fov = 30;
    Vec3 up{0, 0, 1};
    void from_view(const core::render::View &v) {
        target = v.target;
        const double dx = v.eye[0] - v.target[0], dy = v.eye[1] - v.target[1], dz = v.eye[2] - v.target[2];
        distance = std::sqrt(dx * dx + dy * dy + dz * dz);
        yaw = std::atan2(dy, dx);
        pitch = std::asin(std::clamp(dz / std::max(distance, 1e-9), -1.0, 1.0));
        if (std::hypot(dx, dy) <= 1e-9 * distance) {
            // Straight down (superior) or up (inferior): no yaw in the eye's
            // position, so take it from the view's up vector, which the
            // screen's up then follows (looking down, screen up is minus the
            // eye's horizontal direction; looking up, plus it), and stay just
            // short of the pole so that the z-up orbit keeps a defined roll.
            const double sgn = dz > 0 ? -1.0 : 1.0;
            yaw = std::atan2(sgn * v.up[1], sgn * v.up[0]);
            pitch = (dz > 0 ? 1.0 : -1.0) * (M_PI / 2 - 1e-6);
        }
        fov = v.fov_deg;
    }
    core::render::View view(double radius) const {
        core::render::View v;
        v.target = target;
        v.eye = {target[0] + distance * std::cos(pitch) * std::cos(yaw), target[1] + distance * std::cos(pitch) * std::sin(yaw),
                 target[2] + distance * std::sin(pitch)};
        v.up = up;
        v.fov_deg = fov;
        v.far_mm = distance + 2.5 * radius;
        v.near_mm = std::max(v.far_mm * 1e-4, distance - 2.5 * radius);
        return v;
    }
};

struct App {
    const core::Registry *reg = nullptr;
    GLFWwindow *win = nullptr;
    core::render::Renderer *r = nullptr;
    Orbit orbit, home;
    double radius = 100;
    bool dragging = false, panning = false;
    double last_x = 0, last_y = 0;
    int shots = 0;
    fs::path shot_dir = ".";
    std::string pending_shot;
    bool shot_by_key = false;  // (S, not a script's screenshot command: a failure is reported, the window goes on)
    bool quit = false;
    double last_motion = -1e9;  // glfwGetTime() of the last camera change
    // glfwGetTime() of the last material change: the programs use uniforms
    // from then until the values have stayed put for kBakeAfter seconds,
    // then baked constants (one compile), faster per frame.
    double last_material_edit = -1e9;
    static constexpr double kBakeAfter = 0.75;
    bool force_moving = false;  // scripts: `moving on|off`
    std::uint64_t events = 0;   // input and window events so far (a frame is drawn only after one, or while busy)
    bool loading = false;       // the data are being read: input waits (the window shows the progress)
    // Scripts: `press LABEL` clicks a panel button through Dear ImGui's own
    // input (the mouse moved over it, pressed, released: one frame each).
    // The buttons drawn in the last frame, by label: their rectangles.
    std::map<std::string, std::array<float, 4>> ui_buttons;
    float press_at[2] = {0, 0};
    int press_stage = -1;  // the frame of the press in progress (0..2), -1 when none
    // A left press released within kClickPx of where it began is a click
    // (picking); the orbit starts only once the cursor has left that circle,
    // so a click does not turn the view under the point it picks.
    static constexpr double kClickPx = 3.0;
    double press_x = 0, press_y = 0;
    bool orbit_started = false;
    // The exploration's hooks (with --explore): a click at window
    // coordinates.
    std::function<void(double, double, int)> on_click;  // (x, y, GLFW modifier bits)
    // The handlers of the window's actions (actions.hpp), by name,
    // registered by the viewer: each returns true when it acted; the
    // camera's own (screenshot, reset, quit) act when none did.
    std::map<std::string, std::function<bool()>> actions;
    // A Ctrl+wheel turn (resizes the region of interest being edited).
    std::function<void(double)> on_ctrl_scroll;
    // A stroke drawn with Ctrl+drag (window points): picks the streamlines
    // it crosses on release.
    bool stroking = false;
    std::vector<std::array<double, 2>> stroke;
    std::function<void(const std::vector<std::array<double, 2>> &)> on_stroke;

    void click(double x, double y, int mods = 0) {
        if (on_click) on_click(x, y, mods);
    }

    void drag_to(double x, double y) {
        if (dragging && !orbit_started) {
            if (std::hypot(x - press_x, y - press_y) <= kClickPx) return;
            orbit_started = true;
        }
        const double dx = x - last_x, dy = y - last_y;
        if (dragging || panning) last_motion = glfwGetTime();
        last_x = x, last_y = y;
        if (panning) {
            // Move the target in the view plane, in proportion to the distance.
            const double s = orbit.distance * 0.0015;
            const double cy = std::cos(orbit.yaw), sy = std::sin(orbit.yaw);
            const Vec3 right = {-sy, cy, 0};
            const Vec3 upv = {-std::sin(orbit.pitch) * cy, -std::sin(orbit.pitch) * sy, std::cos(orbit.pitch)};
            for (int k = 0; k < 3; ++k) orbit.target[k] += s * (-dx * right[k] + dy * upv[k]);
        } else if (dragging) {
            orbit.yaw -= dx * 0.008;
            orbit.pitch = std::clamp(orbit.pitch + dy * 0.008, -1.55, 1.55);
        }
    }
    void scroll(double dy) {
        last_motion = glfwGetTime();
        orbit.distance = std::clamp(orbit.distance * std::pow(0.9, dy), radius * 0.05, radius * 50);
    }
    void key(int k, int mods = 0) {
        const Action *a = action_for_key(k, mods);
        if (a == nullptr) return;
        const std::string name = a->name;
        if (auto it = actions.find(name); it != actions.end() && it->second()) return;
        if (name == "screenshot")
            pending_shot = (shot_dir / ("horizon-screenshot-" + std::to_string(++shots) + ".png")).string(), shot_by_key = true;
        else if (name == "reset")
            orbit = home;
        else if (name == "quit")
            quit = true;
    }
};

inline App *app_of(GLFWwindow *w) { return static_cast<App *>(glfwGetWindowUserPointer(w)); }

// A progressive step's time budget: input is handled between steps.
constexpr double kStepMs = 50.0;
// The jittered frames a still at rest accumulates where a frame is cheap
// (RenderSettings::rest_aa_frames): 8 bring the error against a 4x4
// supersampled picture to about a third of the edge pass's
// (bench/results/antialiasing.md).
constexpr int kRestAaFrames = 8;

// This process's resident anonymous memory (RssAnon), MiB; file pages of
// mapped inputs are not counted. -1 where /proc is not there.
double rss_anon_mb();

// The window's framebuffer size in pixels.
std::pair<int, int> framebuffer_size(GLFWwindow *w);

// The proxy's levels as [[scale, points], ...] (--stats).
inline nlohmann::json proxy_levels_json(const core::render::Renderer &r) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto &l : r.proxy_levels()) out.push_back({l.scale, l.points});
    return out;
}

// `view --stats FILE.json`: every frame the window drew, what it drew and
// how long it took (render, panel and buffer swap), for tests and the
// benchmark; a proxy frame's level (an index into "proxy_levels"). Kinds: "moving" (the level-of-detail proxy while the camera
// moves), "refine" (a progressive step of a still frame, not complete),
// "complete" (the step that completed it, or a frame drawn whole),
// "accumulate" (one more jittered frame of a complete still, averaged in:
// `aa_frames` so far), "still" (the kept image presented again, e.g. for
// the panel; no scene drawing).
struct FrameLog {
    // The peak of RssAnon is also sampled 20 times a second on a thread of
    // its own: frames alone miss what happens while none is drawn.
    FrameLog()
        : sampler_([this](std::stop_token stop) {
              std::mutex m;
              std::unique_lock<std::mutex> lock(m);
              std::condition_variable_any cv;  // (only to wait 50 ms, or less once stopped)
              while (!stop.stop_requested()) {
                  const double a = rss_anon_mb();
                  for (double p = sampled_peak_mb_.load(); a > p && !sampled_peak_mb_.compare_exchange_weak(p, a);) {}
                  cv.wait_for(lock, stop, std::chrono::milliseconds(50), [] { return false; });
              }
          }) {}
    FrameLog(const FrameLog &) = delete;
    FrameLog &operator=(const FrameLog &) = delete;
    nlohmann::json frames = nlohmann::json::array();
    nlohmann::json loading;  // the frames that showed the data being read (load_in_window)
    double peak_anon_mb = 0;
    double first_frame_s = -1, first_complete_s = -1;
    double clusters_shown_s = -1;  // --explore: when the first clusters replaced the tractogram (-1: never, or at once)
    bool clustering = false;       // the frames added now are drawn while the first clustering runs
    // A named point in time among the frames (a script's `mark NAME`).
    void mark(const std::string &name) { frames.push_back({{"t", seconds_since_launch()}, {"kind", "mark"}, {"name", name}}); }
    void add(const char *kind, const core::render::FrameStats &s, double ms) {
        const double t = seconds_since_launch();
        const double anon = rss_anon_mb();
        peak_anon_mb = std::max(peak_anon_mb, anon);
        if (first_frame_s < 0) first_frame_s = t;
        if (first_complete_s < 0 && std::string(kind) == "complete") first_complete_s = t;
        const bool drew = std::string(kind) != "still";
        frames.push_back({{"t", t},
                          {"ms", ms},
                          {"kind", kind},
                          {"step", drew ? s.refine_step : 0},
                          {"chunks_left", s.refine_remaining},
                          {"streamlines", drew ? s.streamlines_drawn : 0},
                          {"points", drew ? s.points_drawn : 0},
                          {"segments", drew ? s.segments_drawn : 0},
                          {"triangles", drew ? s.triangles_drawn : 0},
                          {"streamed_points", drew ? s.streamed_points : 0},
                          {"slab_crossings", drew ? s.crossings_drawn : 0},
                          {"reprojected", drew ? s.reprojected_points : 0},
                          {"fibre_volumes", drew ? s.volumes_drawn : 0},
                          {"fibre_volume_rays", drew ? s.volume_rays : 0},
                          {"culled_chunks", drew ? s.culled_chunks : 0},
                          {"culled_streamlines", drew ? s.culled_streamlines : 0},
                          {"proxy", drew && s.proxy},
                          {"proxy_level", drew && s.proxy ? s.proxy_level : -1},
                          {"ao_ms", drew ? s.ao_ms : 0},
                          {"depth_cue_ms", drew ? s.depth_cue_ms : 0},
                          {"shadow_ms", drew ? s.shadow_ms : 0},
                          {"shadow_map", drew ? s.shadow_map : 0},
                          {"volume_ms", drew ? s.volume_ms : 0},
                          {"edge_aa", drew && s.edge_aa},
                          {"aa_ms", drew ? s.aa_ms : 0},
                          {"aa_frames", drew ? s.aa_frames : 0},
                          {"clustering", clustering},
                          {"rss_anon_mb", anon}});
    }
    void write(const std::string &path, const core::render::Renderer &r, int w, int h) const {
        std::uint64_t streamlines = 0, points = 0;
        for (const auto &ob : r.scene().objects)
            if (ob.kind == HZ_DATA_STREAMLINES && !ob.proxy_for && ob.visible)  // (not the hidden stand-ins of the region figures)
                streamlines += ob.data.tractogram.nb_streamlines(), points += ob.data.tractogram.nb_vertices();
        const nlohmann::json j = {{"window", {w, h}},
                                  {"step_budget_ms", kStepMs},
                                  {"streamlines", streamlines},
                                  {"points", points},
                                  {"streamlines_with_proxy", r.streamlines_with_proxy()},
                                  {"proxy_levels", proxy_levels_json(r)},
                                  {"first_frame_s", first_frame_s},
                                  {"first_complete_s", first_complete_s},
                                  {"clusters_shown_s", clusters_shown_s},
                                  {"peak_rss_anon_mb", std::max(peak_anon_mb, sampled_peak_mb_.load())},
                                  {"gl", r.gl_description()},
                                  {"loading", loading},
                                  {"frames", frames}};
        core::write_text_atomic(path, j.dump(1) + "\n", /*force=*/true);
        std::printf("stats: %s (%zu frames)\n", path.c_str(), frames.size());
        std::fflush(stdout);
    }

private:
    std::atomic<double> sampled_peak_mb_{0};
    std::jthread sampler_;  // (last: stopped and joined first)
};

// GLFW callbacks, installed before Dear ImGui's (which chains to them).
void cb_button(GLFWwindow *w, int button, int action, int mods);
void cb_cursor(GLFWwindow *w, double x, double y);
void cb_scroll(GLFWwindow *w, double, double dy);
void cb_char(GLFWwindow *w, unsigned int);
void cb_refresh(GLFWwindow *w);
void cb_key(GLFWwindow *w, int key, int, int action, int mods);

// The material panel: one control per schema parameter.
bool material_controls(const core::Registry &reg, const core::render::Object &o, core::render::Material &m);

void save_screenshot(const core::Registry &reg, core::render::Renderer &r, const std::string &path, int w, int h,
                     const std::vector<core::render::Mark> &marks = {});

// Reads the scene (`make`) on another thread while the window shows what is
// being read, how far and for how long (the innermost Progress), instead of
// nothing: a 1M TRK takes seconds to decode. Input waits; closing the
// window cancels the read (the command then ends with status 0). Returns
// the scene, or nullopt when the window was closed; rethrows a read's error.
std::optional<core::render::Scene> load_in_window(GLFWwindow *win, App &app, const std::function<core::render::Scene()> &make,
                                                  nlohmann::json &log);

}  // namespace hz::host::win
