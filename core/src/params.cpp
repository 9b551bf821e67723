#include <hz/core/params.hpp>

#include <hz/hz_clustering.h>
#include <hz/hz_shader.h>

#include <cmath>
#include <cstdlib>
#include <sstream>

namespace hz::core {

namespace {

std::string fmt(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

std::uint32_t fixed_count(const ParamSpec &s) {
    switch (s.type) {
    case HZ_PARAM_VEC2: return 2;
    case HZ_PARAM_VEC3:
    case HZ_PARAM_COLOR3: return 3;
    case HZ_PARAM_FLOAT_ARRAY: return 0;  // 1..components
    default: return 1;
    }
}

double number(const std::string &name, const std::string &text) {
    char *end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || end == text.c_str() || *end != '\0' || !std::isfinite(v))
        throw Error(name + ": '" + text + "' is not a finite number");
    return v;
}

}  // namespace

const char *param_type_name(hz_param_type t) {
    switch (t) {
    case HZ_PARAM_FLOAT: return "float";
    case HZ_PARAM_INT: return "int";
    case HZ_PARAM_BOOL: return "bool";
    case HZ_PARAM_VEC2: return "vec2";
    case HZ_PARAM_VEC3: return "vec3";
    case HZ_PARAM_COLOR3: return "color3";
    case HZ_PARAM_ENUM: return "enum";
    case HZ_PARAM_FLOAT_ARRAY: return "float_array";
    default: return "unknown";
    }
}

std::vector<ParamSpec> schema_of(const LoadedPlugin &p) {
    std::uint32_t count = 0;
    const hz_param_info *(HZ_ABI * get)(std::uint32_t) = nullptr;
    if (const hz_shader *s = p.shader())
        count = s->param_count, get = s->get_param;
    else if (const hz_clustering *c = p.clustering())
        count = c->param_count, get = c->get_param;
    std::vector<ParamSpec> out;
    for (std::uint32_t i = 0; i < count && get; ++i) {
        const hz_param_info *pi = get(i);
        const std::string where = p.info.id + ": parameter " + std::to_string(i);
        if (pi == nullptr || pi->name == nullptr || !*pi->name) throw Error(where + " has no name");
        ParamSpec s;
        s.type = pi->type;
        s.name = pi->name;
        s.label = pi->label ? pi->label : "";
        s.group = pi->group ? pi->group : "";
        s.unit = pi->unit ? pi->unit : "";
        s.tooltip = pi->tooltip ? pi->tooltip : "";
        s.flags = pi->flags;
        if (std::string(param_type_name(s.type)) == "unknown") throw Error(where + " ('" + s.name + "') has an unknown type");
        const std::uint32_t fixed = fixed_count(s);
        s.components = fixed ? fixed : std::max<std::uint32_t>(1, std::min<std::uint32_t>(pi->components, 64));
        const std::uint32_t ranged = s.type == HZ_PARAM_FLOAT_ARRAY ? 1 : std::min<std::uint32_t>(s.components, 4);
        for (std::uint32_t k = 0; k < ranged; ++k) {
            s.min.push_back(pi->min_value[k]);
            s.max.push_back(pi->max_value[k]);
            if (!(pi->min_value[k] <= pi->max_value[k])) throw Error(where + " ('" + s.name + "') has min > max");
        }
        if (s.type == HZ_PARAM_FLOAT_ARRAY) {
            if (pi->default_array != nullptr)
                s.defaults.assign(pi->default_array, pi->default_array + std::min(pi->default_array_count, s.components));
        } else {
            s.defaults.assign(pi->default_value, pi->default_value + ranged);
        }
        if (s.type == HZ_PARAM_ENUM && pi->enum_labels)
            for (const char *const *l = pi->enum_labels; *l; ++l) s.enum_labels.emplace_back(*l);
        out.push_back(std::move(s));
    }
    return out;
}

const ParamSpec &find_param(const std::vector<ParamSpec> &schema, const std::string &plugin_id, const std::string &name) {
    for (const auto &s : schema)
        if (s.name == name) return s;
    std::string names;
    for (const auto &s : schema) names += (names.empty() ? "" : ", ") + s.name;
    throw Error(plugin_id + " has no parameter '" + name + "' (it has: " + (names.empty() ? "none" : names) + ")");
}

void check_param(const ParamSpec &s, const std::vector<double> &v) {
    const std::uint32_t fixed = fixed_count(s);
    if (fixed && v.size() != fixed)
        throw Error(s.name + ": expected " + std::to_string(fixed) + " value" + (fixed == 1 ? "" : "s") + ", got " +
                    std::to_string(v.size()));
    if (!fixed && (v.empty() || v.size() > s.components))
        throw Error(s.name + ": expected 1 to " + std::to_string(s.components) + " values, got " + std::to_string(v.size()));
    for (std::size_t k = 0; k < v.size(); ++k) {
        const double x = v[k];
        if (!std::isfinite(x)) throw Error(s.name + ": not a finite number");
        if ((s.type == HZ_PARAM_INT || s.type == HZ_PARAM_ENUM || s.type == HZ_PARAM_BOOL) && x != std::floor(x))
            throw Error(s.name + ": " + fmt(x) + " is not an integer");
        if (s.type == HZ_PARAM_BOOL && x != 0 && x != 1) throw Error(s.name + ": expected true or false");
        if (s.type == HZ_PARAM_ENUM && !s.enum_labels.empty() && (x < 0 || x >= double(s.enum_labels.size())))
            throw Error(s.name + ": no choice " + fmt(x));
        const std::size_t r = s.min.size() == 1 ? 0 : k;
        if (r < s.min.size() && s.type != HZ_PARAM_BOOL && s.type != HZ_PARAM_ENUM && (x < s.min[r] || x > s.max[r]))
            throw Error(s.name + ": " + fmt(x) + " is outside [" + fmt(s.min[r]) + ", " + fmt(s.max[r]) + "]" +
                        (s.unit.empty() ? "" : " " + s.unit));
    }
}

std::vector<double> parse_param(const ParamSpec &s, const std::string &text) {
    std::vector<double> v;
    if (s.type == HZ_PARAM_BOOL) {
        if (text == "true" || text == "1" || text == "on" || text == "yes")
            v = {1};
        else if (text == "false" || text == "0" || text == "off" || text == "no")
            v = {0};
        else
            throw Error(s.name + ": expected true or false, not '" + text + "'");
    } else if (s.type == HZ_PARAM_ENUM) {
        for (std::size_t i = 0; i < s.enum_labels.size(); ++i)
            if (s.enum_labels[i] == text) v = {double(i)};
        if (v.empty()) {
            std::string labels;
            for (const auto &l : s.enum_labels) labels += (labels.empty() ? "" : ", ") + l;
            char *end = nullptr;
            const long i = std::strtol(text.c_str(), &end, 10);
            if (text.empty() || *end != '\0') throw Error(s.name + ": '" + text + "' is not one of: " + labels);
            v = {double(i)};
        }
    } else {
        std::string item;
        std::istringstream in(text);
        while (std::getline(in, item, ',')) v.push_back(number(s.name, item));
        if (v.empty()) throw Error(s.name + ": no value");
    }
    check_param(s, v);
    return v;
}

std::vector<double> param_from_json(const ParamSpec &s, const nlohmann::json &j) {
    std::vector<double> v;
    if (j.is_boolean())
        v = {j.get<bool>() ? 1.0 : 0.0};
    else if (j.is_number())
        v = {j.get<double>()};
    else if (j.is_string())
        return parse_param(s, j.get<std::string>());
    else if (j.is_array()) {
        for (const auto &x : j) {
            if (!x.is_number()) throw Error(s.name + ": expected an array of numbers");
            v.push_back(x.get<double>());
        }
    } else {
        throw Error(s.name + ": expected a number, true/false, a label or an array of numbers");
    }
    check_param(s, v);
    return v;
}

std::map<std::string, std::vector<double>> parse_param_items(const std::vector<ParamSpec> &schema, const std::string &plugin_id,
                                                             const std::vector<std::string> &items) {
    std::map<std::string, std::vector<double>> out;
    for (const auto &item : items) {
        const auto eq = item.find('=');
        try {
            if (eq == std::string::npos || eq == 0) throw Error("expected NAME=VALUE");
            const ParamSpec &s = find_param(schema, plugin_id, item.substr(0, eq));
            out[s.name] = parse_param(s, item.substr(eq + 1));
        } catch (const Error &e) {
            throw Error("--param " + item + ": " + e.what());
        }
    }
    return out;
}

const LoadedPlugin *find_plugin(const Registry &reg, const std::string &name, hz_plugin_kind kind, std::string *ambiguous) {
    std::vector<const LoadedPlugin *> match;
    for (const auto &p : reg.plugins()) {
        if (kind != 0 && p.info.kind != kind) continue;
        const std::string &id = p.info.id;
        if (id == name) return &p;
        if (id.size() > name.size() && id.compare(id.size() - name.size(), name.size(), name) == 0 &&
            id[id.size() - name.size() - 1] == '.')
            match.push_back(&p);
    }
    if (match.size() == 1) return match[0];
    if (match.size() > 1 && ambiguous)
        for (const LoadedPlugin *p : match) *ambiguous += (ambiguous->empty() ? "" : ", ") + p->info.id;
    return nullptr;
}

const LoadedPlugin *find_clustering(const Registry &reg, const std::string &name) {
    std::string ambiguous;
    if (const LoadedPlugin *p = find_plugin(reg, name, HZ_KIND_CLUSTERING, &ambiguous)) return p;
    if (!ambiguous.empty()) throw Error("--algorithm " + name + " is ambiguous: " + ambiguous + " (give the full id)");
    std::string all;
    for (const auto &p : reg.plugins())
        if (p.info.kind == HZ_KIND_CLUSTERING) all += (all.empty() ? "" : ", ") + p.info.id;
    throw Error("--algorithm " + name + ": no clustering plugin has this id (found: " + (all.empty() ? "none" : all) + ")");
}

void apply_shortcut(const std::vector<ParamSpec> &schema, const std::string &plugin_id, const std::string &flag,
                    std::initializer_list<const char *> names, const std::vector<double> &values,
                    std::map<std::string, std::vector<double>> &out) {
    for (const char *n : names)
        for (const auto &s : schema)
            if (s.name == n) {
                try {
                    check_param(s, values);
                } catch (const Error &e) {
                    throw Error(flag + ": " + e.what());
                }
                out[n] = values;
                return;
            }
    throw Error(flag + ": " + plugin_id + " has no such parameter (`horizon plugins " + plugin_id + "` lists them)");
}

nlohmann::json schema_json(const std::vector<ParamSpec> &schema) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto &s : schema) {
        nlohmann::json j = {{"name", s.name}, {"type", param_type_name(s.type)}, {"components", s.components}, {"default", s.defaults}};
        if (s.type != HZ_PARAM_BOOL && s.type != HZ_PARAM_ENUM) j["min"] = s.min, j["max"] = s.max;
        if (!s.enum_labels.empty()) j["choices"] = s.enum_labels;
        if (!s.label.empty()) j["label"] = s.label;
        if (!s.unit.empty()) j["unit"] = s.unit;
        if (!s.group.empty()) j["group"] = s.group;
        if (!s.tooltip.empty()) j["doc"] = s.tooltip;
        if (s.flags & HZ_PARAM_FLAG_HIDDEN) j["hidden"] = true;
        a.push_back(std::move(j));
    }
    return a;
}

}  // namespace hz::core
