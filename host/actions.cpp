#include "actions.hpp"

#include <GLFW/glfw3.h>

#include <cstring>

namespace hz::host {

const std::vector<Action> &window_actions() {
    constexpr int ctrl = GLFW_MOD_CONTROL, shift = GLFW_MOD_SHIFT;
    static const std::vector<Action> actions = {
        {"screenshot", GLFW_KEY_S, 0, "S", "screenshot", ActionGroup::View},
        {"reset", GLFW_KEY_R, 0, "R", "reset", ActionGroup::View},
        {"fit", GLFW_KEY_V, 0, "V", "fit to what is shown", ActionGroup::View},
        {"occlusion", GLFW_KEY_O, 0, "O", "occlusion", ActionGroup::View},
        {"depth cue", GLFW_KEY_F, 0, "F", "depth cue", ActionGroup::View},
        {"shadows", GLFW_KEY_L, 0, "L", "shadows", ActionGroup::View},
        {"antialiasing", GLFW_KEY_G, 0, "G", "anti-aliasing", ActionGroup::View},
        {"annotations", GLFW_KEY_N, 0, "N", "annotations", ActionGroup::View},
        {"quit", GLFW_KEY_Q, 0, "Q", "quit", ActionGroup::Other},
        {"quit", GLFW_KEY_ESCAPE, 0, "Esc", "quit", ActionGroup::Other},
        {"expand", GLFW_KEY_E, 0, "E", "expand", ActionGroup::Explore},
        {"to streamlines", GLFW_KEY_X, 0, "X", "to streamlines", ActionGroup::Explore},
        {"hide", GLFW_KEY_H, 0, "H", "hide", ActionGroup::Explore},
        {"select all", GLFW_KEY_A, 0, "A", "all/none", ActionGroup::Explore},
        {"cluster again", GLFW_KEY_C, 0, "C", "cluster again", ActionGroup::Explore},
        {"keep picked", GLFW_KEY_K, 0, "K", "keep", ActionGroup::Stroke},
        {"delete picked", GLFW_KEY_D, 0, "D", "delete", ActionGroup::Stroke},
        {"invert picked", GLFW_KEY_I, 0, "I", "invert", ActionGroup::Stroke},
        {"undo", GLFW_KEY_Z, ctrl, "Ctrl+Z", "undo", ActionGroup::Other},
        {"redo", GLFW_KEY_Z, ctrl | shift, "Ctrl+Shift+Z", "redo", ActionGroup::Other},
        {"redo", GLFW_KEY_Y, ctrl, "Ctrl+Y", "redo", ActionGroup::Other},
        {"save", GLFW_KEY_S, ctrl, "Ctrl+S", "save what is shown", ActionGroup::Other},
    };
    return actions;
}

const Action *action_for_key(int key, int mods) {
    constexpr int ctrl = GLFW_MOD_CONTROL, shift = GLFW_MOD_SHIFT;
    const Action *loose = nullptr;
    for (const Action &a : window_actions()) {
        if (a.key != key || (a.mods & ctrl) != (mods & ctrl)) continue;
        if ((a.mods & shift) == (mods & shift)) return &a;
        if (!loose) loose = &a;
    }
    return loose;
}

std::string actions_help(ActionGroup group) {
    std::string s;
    for (const Action &a : window_actions())
        if (a.group == group) s += std::string(s.empty() ? "" : "  ") + a.keys + ": " + a.help;
    return s;
}

std::string actions_help_text() {
    std::string s;
    for (const Action &a : window_actions()) {
        std::string k = a.keys;
        k.resize(std::max<std::size_t>(k.size(), 14), ' ');
        s += "  " + k + a.help + "\n";
    }
    return s;
}

}  // namespace hz::host
