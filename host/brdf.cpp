// `horizon brdf [--shader ID]`: evaluates shading plugins' CPU references
// over JSON lines on stdin, one answer line per input line, in order (the
// protocol of ../shared/brdf/check_vectors.py). A case's "model" selects the
// plugin whose id ends in ".<model>" ("principled" -> org.horizon.shader.
// principled); "<model>_isotropic" is the same model with "anisotropic" = 0.
// Parameters are taken from the case's "params" by the plugin's schema names;
// N, X, Y, L, V become the shade point's n, t, b, l, v. Unknown models are
// answered {"id": ..., "unsupported": true}.
#include "commands.hpp"

#include <hz/core/data.hpp>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

namespace hz::host {

namespace {

std::string base_name(const std::string &id) {
    const auto dot = id.rfind('.');
    return dot == std::string::npos ? id : id.substr(dot + 1);
}

bool vec3_of(const nlohmann::json &j, const char *key, double out[3]) {
    out[0] = out[1] = out[2] = 0;
    if (!j.contains(key)) return false;
    const auto &a = j[key];
    if (!a.is_array() || a.size() != 3) throw core::Error(std::string("field ") + key + " is not a 3-vector");
    for (int i = 0; i < 3; ++i) out[i] = a[i].is_number() ? a[i].get<double>() : std::nan("");
    return true;
}

// A shader function matching `model`: "name(arg, arg[3], ...)" in a
// plugin's `functions`. Returns the plugin and fills the argument list.
struct Arg {
    std::string name;
    int count = 1;
};
const hz_shader *find_function(const std::vector<const core::LoadedPlugin *> &shaders, const std::string &model, std::vector<Arg> &args) {
    for (const auto *p : shaders) {
        const hz_shader *s = p->shader();
        if (!HZ_HAS_FIELD(s, hz_shader, eval_function) || s->functions == nullptr || s->eval_function == nullptr) continue;
        for (const char *const *f = s->functions; *f; ++f) {
            const std::string sig = *f;
            const auto open = sig.find('('), close = sig.rfind(')');
            if (open == std::string::npos || close == std::string::npos || sig.substr(0, open) != model) continue;
            args.clear();
            std::string list = sig.substr(open + 1, close - open - 1);
            std::size_t pos = 0;
            while (pos < list.size()) {
                std::size_t comma = list.find(',', pos);
                std::string a = list.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos);
                a.erase(0, a.find_first_not_of(' '));
                a.erase(a.find_last_not_of(' ') + 1);
                Arg arg;
                const auto br = a.find('[');
                arg.name = a.substr(0, br);
                if (br != std::string::npos) arg.count = std::max(1, std::atoi(a.c_str() + br + 1));
                if (!arg.name.empty()) args.push_back(arg);
                if (comma == std::string::npos) break;
                pos = comma + 1;
            }
            return s;
        }
    }
    return nullptr;
}

}  // namespace

int cmd_brdf(const GlobalOptions &g, const std::string &shader_id) {
    const core::Registry reg = load_registry(g);
    std::vector<const core::LoadedPlugin *> shaders;
    for (const auto *p : reg.of_kind(HZ_KIND_SHADER))
        if (shader_id.empty() || p->info.id == shader_id) shaders.push_back(p);
    if (!shader_id.empty() && shaders.empty()) throw core::Error("shader plugin '" + shader_id + "' not found (see `horizon plugins`)");
    std::string line;
    std::uint64_t line_no = 0;
    while (std::getline(std::cin, line)) {
        ++line_no;
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        const nlohmann::json c = nlohmann::json::parse(line, nullptr, false);
        if (c.is_discarded() || !c.is_object()) {
            std::fprintf(stderr, "horizon: error: stdin line %llu is not a JSON object\n", (unsigned long long)line_no);
            return 1;
        }
        nlohmann::json answer = {{"id", c.value("id", nlohmann::json())}};
        const std::string model = c.value("model", "");
        const bool iso = model.size() > 10 && model.compare(model.size() - 10, 10, "_isotropic") == 0;
        const std::string want = iso ? model.substr(0, model.size() - 10) : model;
        const core::LoadedPlugin *plugin = nullptr;
        for (const auto *p : shaders)
            if (base_name(p->info.id) == want) plugin = p;
        std::vector<Arg> fargs;
        const hz_shader *fn = plugin == nullptr ? find_function(shaders, model, fargs) : nullptr;
        if (fn != nullptr) {
            // A named building block (Fresnel, Beer-Lambert, ...).
            std::vector<double> a;
            for (const Arg &arg : fargs) {
                // Top-level fields first, then the case's "params".
                nlohmann::json v = c.value(arg.name, nlohmann::json());
                if (v.is_null() && c.contains("params") && c["params"].is_object()) v = c["params"].value(arg.name, nlohmann::json());
                for (int k = 0; k < arg.count; ++k) {
                    const nlohmann::json &x = v.is_array() ? (k < int(v.size()) ? v[k] : nlohmann::json()) : v;
                    a.push_back(x.is_number() ? x.get<double>() : std::nan(""));
                }
            }
            double rgb[3];
            if (fn->eval_function(model.c_str(), a.data(), static_cast<uint32_t>(a.size()), rgb) != HZ_OK)
                answer["unsupported"] = true;
            else
                answer["value"] = {rgb[0], rgb[1], rgb[2]};
        } else if (plugin == nullptr) {
            answer["unsupported"] = true;
        } else {
            const hz_shader *s = plugin->shader();
            const nlohmann::json params = c.value("params", nlohmann::json::object());
            std::vector<double> values;
            for (uint32_t i = 0; i < s->param_count; ++i) {
                const hz_param_info *pi = s->get_param(i);
                // Parameters live in "params" (principled) or at the top level (other models).
                const nlohmann::json *v = params.contains(pi->name) ? &params[pi->name] : c.contains(pi->name) ? &c[pi->name] : nullptr;
                for (uint32_t k = 0; k < pi->components; ++k) {
                    double x = pi->type == HZ_PARAM_FLOAT_ARRAY ? pi->min_value[0] : pi->default_value[k];
                    if (v != nullptr && v->is_array() && k < v->size() && (*v)[k].is_number())
                        x = (*v)[k].get<double>();
                    else if (v != nullptr && v->is_number() && pi->components == 1)
                        x = v->get<double>();
                    if (iso && std::string(pi->name) == "anisotropic") x = 0;
                    values.push_back(x);
                }
            }
            hz_shade_point p{};
            p.struct_size = sizeof p;
            p.domain = HZ_SHADE_SURFACE;
            vec3_of(c, "N", p.n);
            vec3_of(c, "L", p.l);
            vec3_of(c, "V", p.v);
            if (!iso) {
                vec3_of(c, "X", p.t);
                vec3_of(c, "Y", p.b);
            }
            if (c.contains("T") && vec3_of(c, "T", p.t)) p.domain = HZ_SHADE_LINE;  // line models: the tangent
            double rgb[3];
            const hz_status st = s->eval_reference(&p, values.data(), static_cast<uint32_t>(values.size()), rgb);
            if (st != HZ_OK)
                answer["unsupported"] = true;
            else
                answer["value"] = {rgb[0], rgb[1], rgb[2]};
        }
        std::cout << answer.dump() << '\n' << std::flush;
    }
    return 0;
}

}  // namespace hz::host
