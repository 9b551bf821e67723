// The window's actions, declared once: each one's name, key, help and group
// live in this table, and the key handler (App::key), the panel's help
// lines and `horizon view --help` all read it. Code that performs an action
// registers a handler for its name (App::actions); a key without an action
// does nothing. Threading: the window's thread.
#pragma once

#include <string>
#include <vector>

namespace hz::host {

// Where an action's help is shown: the panel's lines (View, Explore,
// Stroke; Other: none) and the help of `view` (all of them).
enum class ActionGroup { View, Explore, Stroke, Other };

struct Action {
    const char *name;  // the handler's name ("expand")
    int key;           // GLFW key code
    int mods;          // GLFW_MOD_CONTROL and GLFW_MOD_SHIFT bits it needs (Alt is ignored)
    const char *keys;  // the key as help writes it ("E", "Ctrl+Z")
    const char *help;  // what it does, in a few words
    ActionGroup group;
};

// Every action, in the order help lists them.
const std::vector<Action> &window_actions();

// The action of key `key` with modifiers `mods`: the one whose Ctrl and
// Shift bits are exactly those, else one whose Ctrl bit is (Shift+E
// expands as E does; Ctrl+Shift+Z redoes where Ctrl+Z undoes); null if none.
const Action *action_for_key(int key, int mods);

// "E: expand  X: to streamlines ..." for the actions of `group`.
std::string actions_help(ActionGroup group);

// Every action, a line each ("  E          expand"), for `view --help`.
std::string actions_help_text();

}  // namespace hz::host
