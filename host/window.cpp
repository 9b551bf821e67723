// The window's machinery (see window.hpp).
#include "window.hpp"
#include "progress.hpp"

#include <hz/core/params.hpp>

#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <future>

namespace hz::host::win {

// This process's resident anonymous memory (RssAnon), MiB; file pages of
// mapped inputs are not counted. -1 where /proc is not there.
double rss_anon_mb() {
    std::ifstream in("/proc/self/status");
    for (std::string line; std::getline(in, line);)
        if (line.rfind("RssAnon:", 0) == 0) return std::strtod(line.c_str() + 8, nullptr) / 1024.0;
    return -1;
}

// The window's framebuffer size in pixels.
std::pair<int, int> framebuffer_size(GLFWwindow *w) {
    int fw = 0, fh = 0;
    glfwGetFramebufferSize(w, &fw, &fh);
    return {fw, fh};
}

void cb_button(GLFWwindow *w, int button, int action, int mods) {
    ++app_of(w)->events;
    if (app_of(w)->loading) return;
    App &a = *app_of(w);
    if (a.stroking && action == GLFW_RELEASE && button == GLFW_MOUSE_BUTTON_LEFT) {
        // The end of a Ctrl+drag: a stroke, or a Ctrl+click if it stayed put.
        a.stroking = false;
        glfwGetCursorPos(w, &a.last_x, &a.last_y);
        if (std::hypot(a.last_x - a.press_x, a.last_y - a.press_y) > App::kClickPx && a.on_stroke)
            a.on_stroke(a.stroke);
        else
            a.click(a.last_x, a.last_y, mods | GLFW_MOD_CONTROL);
        a.stroke.clear();
        return;
    }
    if (ImGui::GetIO().WantCaptureMouse) return;
    glfwGetCursorPos(w, &a.last_x, &a.last_y);
    const bool down = action == GLFW_PRESS;
    if (down && button == GLFW_MOUSE_BUTTON_LEFT && (mods & GLFW_MOD_CONTROL) && a.on_stroke) {
        a.stroking = true;
        a.press_x = a.last_x, a.press_y = a.last_y;
        a.stroke = {{a.last_x, a.last_y}};
        return;
    }
    const bool left = button == GLFW_MOUSE_BUTTON_LEFT && !(mods & GLFW_MOD_SHIFT);
    if (left)
        a.dragging = down;
    else
        a.panning = down;
    if (left && down) a.press_x = a.last_x, a.press_y = a.last_y, a.orbit_started = false;
    if (!down) a.dragging = a.panning = false;
    if (left && !down && std::hypot(a.last_x - a.press_x, a.last_y - a.press_y) <= App::kClickPx) a.click(a.last_x, a.last_y, mods);
}
void cb_cursor(GLFWwindow *w, double x, double y) {
    ++app_of(w)->events;
    if (app_of(w)->loading) return;
    App &a = *app_of(w);
    if (a.stroking) {
        if (std::hypot(x - a.stroke.back()[0], y - a.stroke.back()[1]) >= 2.0) a.stroke.push_back({x, y});
        return;
    }
    a.drag_to(x, y);
}
void cb_scroll(GLFWwindow *w, double, double dy) {
    ++app_of(w)->events;
    if (app_of(w)->loading) return;
    if (ImGui::GetIO().WantCaptureMouse) return;
    App &a = *app_of(w);
    if ((glfwGetKey(w, GLFW_KEY_LEFT_CONTROL) == GLFW_PRESS || glfwGetKey(w, GLFW_KEY_RIGHT_CONTROL) == GLFW_PRESS) && a.on_ctrl_scroll)
        a.on_ctrl_scroll(dy);
    else
        a.scroll(dy);
}
void cb_char(GLFWwindow *w, unsigned int) { ++app_of(w)->events; }
void cb_refresh(GLFWwindow *w) { ++app_of(w)->events; }
void cb_key(GLFWwindow *w, int key, int, int action, int mods) {
    ++app_of(w)->events;
    if (app_of(w)->loading) return;
    if (action == GLFW_PRESS && !ImGui::GetIO().WantCaptureKeyboard) app_of(w)->key(key, mods);
}

// The material panel: one control per schema parameter.
bool material_controls(const core::Registry &reg, const core::render::Object &o, core::render::Material &m) {
    bool changed = false;
    const auto shaders = reg.of_kind(HZ_KIND_SHADER);
    const core::LoadedPlugin *cur = core::render::find_shader(reg, m.shader);
    if (ImGui::BeginCombo("shading model", cur ? cur->info.name.c_str() : m.shader.c_str())) {
        for (const auto *p : shaders) {
            const hz_shader *sh = p->shader();
            const bool ok = o.kind == HZ_DATA_MESH || o.render == "tubes" ? (sh->domains & HZ_SHADE_SURFACE) : true;
            if (!ok) continue;
            if (ImGui::Selectable(p->info.name.c_str(), p == cur) && p != cur) {
                m.shader = p->info.id;
                m.params.clear();
                changed = true;
            }
        }
        ImGui::EndCombo();
    }
    if (!cur || changed) return changed;
    const hz_shader *sh = cur->shader();
    for (uint32_t i = 0; i < sh->param_count; ++i) {
        const hz_param_info *pi = sh->get_param(i);
        if (pi->flags & HZ_PARAM_FLAG_HIDDEN) continue;
        if (pi->type == HZ_PARAM_COLOR3 && i == 0) continue;  // the object's colouring drives the first colour
        auto it = m.params.find(pi->name);
        std::vector<double> v(pi->components);
        for (uint32_t c = 0; c < pi->components; ++c)
            v[c] = it != m.params.end() && c < it->second.size() ? it->second[c] : pi->default_value[c];
        const char *label = pi->label && *pi->label ? pi->label : pi->name;
        bool ch = false;
        if (pi->type == HZ_PARAM_FLOAT) {
            float f = float(v[0]);
            ch = ImGui::SliderFloat(label, &f, float(pi->min_value[0]), float(pi->max_value[0]), "%.3f",
                                    (pi->flags & HZ_PARAM_FLAG_LOG_SCALE) ? ImGuiSliderFlags_Logarithmic : 0);
            v[0] = f;
        } else if (pi->type == HZ_PARAM_COLOR3) {
            float c[3] = {float(v[0]), float(v[1]), float(v[2])};
            ch = ImGui::ColorEdit3(label, c);
            v = {c[0], c[1], c[2]};
        } else if (pi->type == HZ_PARAM_ENUM && pi->enum_labels) {
            int k = int(v[0]);
            int n = 0;
            while (pi->enum_labels[n]) ++n;
            ch = ImGui::Combo(label, &k, pi->enum_labels, n);
            v[0] = k;
        } else if (pi->type == HZ_PARAM_BOOL) {
            bool b = v[0] != 0;
            ch = ImGui::Checkbox(label, &b);
            v[0] = b;
        } else if (pi->type == HZ_PARAM_INT) {
            int k = int(v[0]);
            ch = ImGui::SliderInt(label, &k, int(pi->min_value[0]), int(pi->max_value[0]));
            v[0] = k;
        }
        if (ch) {
            m.params[pi->name] = v;
            changed = true;
        }
        if (pi->tooltip && *pi->tooltip && ImGui::IsItemHovered()) ImGui::SetTooltip("%s", pi->tooltip);
    }
    return changed;
}

void save_screenshot(const core::Registry &reg, core::render::Renderer &r, const std::string &path, int w, int h,
                     const std::vector<core::render::Mark> &marks) {
    core::render::Image im = r.read_window_image(w, h);
    paint_marks(im, marks);  // (the annotations the window shows over it)
    write_image(reg, im, path, /*force=*/true);
    std::printf("screenshot: %s\n", path.c_str());
    std::fflush(stdout);
}

// Reads the scene (`make`) on another thread while the window shows what is
// being read, how far and for how long (the innermost Progress), instead of
// nothing: a 1M TRK takes seconds to decode. Input waits; closing the
// window cancels the read (the command then ends with status 0). Returns
// the scene, or nullopt when the window was closed; rethrows a read's error.
std::optional<core::render::Scene> load_in_window(GLFWwindow *win, App &app, const std::function<core::render::Scene()> &make,
                                                  nlohmann::json &log) {
    app.loading = true;
    auto future = std::async(std::launch::async, make);
    const auto t0 = std::chrono::steady_clock::now();
    int frames = 0;
    nlohmann::json seen = nlohmann::json::array();
    bool closed = false;
    for (;;) {
        // One frame at once, then one per 0.1 s or event, until the data are read.
        if (frames > 0 && future.wait_for(std::chrono::milliseconds(0)) == std::future_status::ready) break;
        if (!closed && glfwWindowShouldClose(win)) {
            closed = true;
            cancel_progress();
        }
        const ProgressState p = current_progress();
        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();
        const float fw = ImGui::GetIO().DisplaySize.x, fh = ImGui::GetIO().DisplaySize.y;
        ImGui::GetBackgroundDrawList()->AddRectFilled(ImVec2(0, 0), ImVec2(fw, fh), IM_COL32(20, 20, 23, 255));
        const ImVec2 size(std::max(100.0f, std::min(460.0f, fw - 20.0f)), 0.0f);
        ImGui::SetNextWindowPos(ImVec2(fw * 0.5f, fh * 0.5f), ImGuiCond_Always, ImVec2(0.5f, 0.5f));
        ImGui::SetNextWindowSize(size);
        ImGui::Begin("##loading", nullptr, ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings);
        const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        ImGui::TextUnformatted(closed ? "cancelling..." : p.active ? p.what.c_str() : "preparing the scene");
        if (p.active && p.fraction >= 0 && p.fraction <= 1) {
            char label[32];
            std::snprintf(label, sizeof label, "%.0f %%", p.fraction * 100);
            ImGui::ProgressBar(float(p.fraction), ImVec2(-1, 0), label);
        } else {
            ImGui::ProgressBar(float(std::fmod(secs, 1.0)), ImVec2(-1, 0), "");
        }
        ImGui::Text("%.1f s", secs);
        ImGui::End();
        ImGui::Render();
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
        glfwSwapBuffers(win);
        ++frames;
        seen.push_back({{"t", secs}, {"what", p.active ? p.what : ""}, {"fraction", p.active ? p.fraction : -1.0}});
        glfwWaitEventsTimeout(0.1);
    }
    app.loading = false;
    log = {
        {"frames", frames}, {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}, {"progress", seen}};
    if (closed) {
        try {
            (void)future.get();
        } catch (const std::exception &) {  // (the cancelled read)
        }
        return std::nullopt;
    }
    return future.get();
}

}  // namespace hz::host::win
