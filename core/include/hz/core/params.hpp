// The parameter model: one owner, in core, of what a plugin's parameter
// schema (hz_param_info) means. The command line (--param NAME=VALUE), scene
// files, the window's panel and `horizon plugins` read schemas through it
// instead of retyping names and ranges.
#pragma once

#include <hz/core/plugin_host.hpp>

#include <nlohmann/json.hpp>

#include <map>
#include <string>
#include <vector>

namespace hz::core {

struct ParamSpec {
    hz_param_type type = HZ_PARAM_FLOAT;
    std::string name, label, group, unit, tooltip;
    std::uint32_t flags = 0;
    std::uint32_t components = 1;  // values of a scalar or vector; FLOAT_ARRAY: the maximum length
    std::vector<double> min, max;  // per component (FLOAT_ARRAY: one, for every element)
    std::vector<double> defaults;  // the default value(s)
    std::vector<std::string> enum_labels;
};

// A plugin's schema, copied from its interface table (shader or clustering);
// empty for loaders. Throws Error if the plugin describes a parameter
// inconsistently (no name, unknown type, min > max, ...), naming the plugin.
std::vector<ParamSpec> schema_of(const LoadedPlugin &p);

// The spec named `name`, or an Error naming the plugin and the names it has.
const ParamSpec &find_param(const std::vector<ParamSpec> &schema, const std::string &plugin_id, const std::string &name);

// Parses a value as written on the command line: FLOAT/INT "0.5"; BOOL
// true/false/1/0; ENUM a label (or its index); VEC2/VEC3/COLOR3 and
// FLOAT_ARRAY comma-separated numbers. Checks the count, integrality and
// range. Throws Error "NAME: ..." (one line).
std::vector<double> parse_param(const ParamSpec &spec, const std::string &text);

// The same checks for values from JSON (a number, a bool, a label, or an
// array of numbers). Throws Error "NAME: ...".
std::vector<double> param_from_json(const ParamSpec &spec, const nlohmann::json &value);

// Checks count and range of `values` for `spec`. Throws Error "NAME: ...".
void check_param(const ParamSpec &spec, const std::vector<double> &values);

// "NAME=VALUE" items (repeatable --param) against a schema: name -> values.
// Throws Error "--param ITEM: ..." for an unknown name, a malformed item or
// a bad value.
std::map<std::string, std::vector<double>> parse_param_items(const std::vector<ParamSpec> &schema, const std::string &plugin_id,
                                                             const std::vector<std::string> &items);

// The plugin (of `kind`; 0: any) whose id is `name` or ends in "." + name;
// nullptr when none or several match (then, with `ambiguous`, their ids).
const LoadedPlugin *find_plugin(const Registry &reg, const std::string &name, hz_plugin_kind kind = 0, std::string *ambiguous = nullptr);

// The clustering plugin `name` names: its id, or the last part of one
// ("qbx" for org.horizon.clustering.qbx). Throws Error listing the
// clustering plugins when none (or more than one) matches.
const LoadedPlugin *find_clustering(const Registry &reg, const std::string &name);

// A shortcut option (--thresholds, "thresholds" in a scene) set as the first
// of `names` the schema has: checked, stored in out[name]. Throws Error
// "FLAG: ..." when the plugin has none of them or the values do not fit.
void apply_shortcut(const std::vector<ParamSpec> &schema, const std::string &plugin_id, const std::string &flag,
                    std::initializer_list<const char *> names, const std::vector<double> &values,
                    std::map<std::string, std::vector<double>> &out);

// The schema as JSON (names, types, ranges, defaults, docs), for
// `horizon plugins --json` and `horizon plugins ID`.
nlohmann::json schema_json(const std::vector<ParamSpec> &schema);
const char *param_type_name(hz_param_type t);

}  // namespace hz::core
