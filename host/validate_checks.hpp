// `horizon validate`'s checks, by kind of plugin (private to the host):
// what a check is, what it is given, and the helpers the kinds share. Each
// check runs in a forked child that loads the plugin afresh (validate.cpp).
#pragma once

#include "commands.hpp"

#include <hz/core/plugin_host.hpp>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace hz::host::validation {

namespace fs = std::filesystem;

struct Outcome {
    std::string status = "passed";  // passed | failed | skipped
    std::string reason;
};
inline Outcome pass(std::string why = "") { return {"passed", std::move(why)}; }
inline Outcome fail(std::string why) { return {"failed", std::move(why)}; }
inline Outcome skip(std::string why) { return {"skipped", std::move(why)}; }

struct Ctx {
    const core::Module &module;
    const core::PluginInfo &plugin;
    const ValidateOptions &opts;
    fs::path scratch;  // private temporary directory of this check
};

using CheckFn = std::function<Outcome(const Ctx &)>;

struct Check {
    const char *name;
    hz_plugin_kind kind;  // 0: library-level
    const char *description;
    CheckFn fn;
};

inline const hz_loader &loader_of(const Ctx &c) {
    return *static_cast<const hz_loader *>(c.module.interface(c.plugin.id, HZ_INTERFACE_LOADER));
}
inline const hz_shader &shader_of(const Ctx &c) {
    return *static_cast<const hz_shader *>(c.module.interface(c.plugin.id, HZ_INTERFACE_SHADER));
}
inline const hz_clustering &clustering_of(const Ctx &c) {
    return *static_cast<const hz_clustering *>(c.module.interface(c.plugin.id, HZ_INTERFACE_CLUSTERING));
}

// The table of extension `id` (hz_extensions.h) the checked plugin offers:
// listed in its descriptor's interfaces, served, and at least sizeof(Table)
// bytes; else NULL.
template <class Table>
const Table *extension_of(const Ctx &c, const char *id) {
    return static_cast<const Table *>(core::offered_extension(c.module, c.plugin, id, sizeof(Table)));
}

// `t` (gap 0) with one vertex holding `fill` after each streamline, as a
// mapped TCK holds its NaN delimiters (gap 1). (validate_loaders.cpp)
core::Tractogram with_gap(const core::Tractogram &t, float fill);

// An hz_error ready to be filled by a plugin.
inline hz_error new_error() {
    hz_error e{};
    e.struct_size = sizeof e;
    return e;
}

// A parameter schema's sanity (names, types, ranges, defaults), for shaders
// and clustering plugins alike.
Outcome check_schema(uint32_t count, const hz_param_info *(HZ_ABI *get)(uint32_t));
// The schema's default values, in order, components expanded.
std::vector<double> default_params(uint32_t count, const hz_param_info *(HZ_ABI *get)(uint32_t));

// The checks of each kind, appended to `c` in the order they run.
void add_loader_checks(std::vector<Check> &c);      // validate_loaders.cpp
void add_shader_checks(std::vector<Check> &c);      // validate_shaders.cpp
void add_clustering_checks(std::vector<Check> &c);  // validate_clustering.cpp

}  // namespace hz::host::validation
