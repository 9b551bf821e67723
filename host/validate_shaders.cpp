// `horizon validate`: the shader checks (see validate_checks.hpp).
#include "validate_checks.hpp"

#include <hz/core/render/context.hpp>

#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
#include <hz/core/phantom.hpp>

#include <boost/dll/library_info.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <iostream>
#include <random>
#include <set>
#include <sys/mman.h>
#include <unistd.h>

namespace hz::host::validation {

using nlohmann::json;

namespace {

bool is_identifier(std::string_view s) {
    auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
    return !s.empty() && !std::isdigit(static_cast<unsigned char>(s[0])) && std::all_of(s.begin(), s.end(), word);
}

// Position of `name` followed by optional blanks and '(' as a whole word, or npos.
std::size_t find_call(const std::string &src, const std::string &name) {
    for (std::size_t at = src.find(name); at != std::string::npos; at = src.find(name, at + 1)) {
        const bool left_ok = at == 0 || !(std::isalnum(static_cast<unsigned char>(src[at - 1])) || src[at - 1] == '_');
        std::size_t k = at + name.size();
        while (k < src.size() && (src[k] == ' ' || src[k] == '\t' || src[k] == '\n')) ++k;
        if (left_ok && k < src.size() && src[k] == '(') return at;
    }
    return std::string::npos;
}
bool has_word(const std::string &src, const std::string &w) {
    for (std::size_t at = src.find(w); at != std::string::npos; at = src.find(w, at + 1)) {
        const bool l = at == 0 || !(std::isalnum(static_cast<unsigned char>(src[at - 1])) || src[at - 1] == '_');
        const std::size_t e = at + w.size();
        const bool r = e >= src.size() || !(std::isalnum(static_cast<unsigned char>(src[e])) || src[e] == '_');
        if (l && r) return true;
    }
    return false;
}

}  // namespace

// Parameter schema rules shared by shaders and clustering.
Outcome check_schema(uint32_t count, const hz_param_info *(HZ_ABI *get)(uint32_t)) {
    std::set<std::string> names;
    for (uint32_t i = 0; i < count; ++i) {
        const hz_param_info *p = get(i);
        const std::string at = "parameter " + std::to_string(i);
        if (p == nullptr) return fail(at + ": get_param returned NULL");
        if (p->struct_size < sizeof(hz_param_info)) return fail(at + ": struct_size too small");
        if (p->name == nullptr || !is_identifier(p->name)) return fail(at + ": name is not an identifier");
        const std::string n = p->name;
        if (!names.insert(n).second) return fail("duplicate parameter name '" + n + "'");
        if (p->type < HZ_PARAM_FLOAT || p->type > HZ_PARAM_FLOAT_ARRAY) return fail(n + ": unknown type " + std::to_string(p->type));
        const uint32_t comps = p->type == HZ_PARAM_FLOAT_ARRAY ? 1 : p->components;
        if (p->components < 1 || (p->type != HZ_PARAM_FLOAT_ARRAY && p->components > 4) || p->components > 64)
            return fail(n + ": components " + std::to_string(p->components) + " out of range");
        for (uint32_t k = 0; k < comps; ++k) {
            const double lo = p->min_value[k], hi = p->max_value[k], d = p->default_value[k];
            if (!std::isfinite(lo) || !std::isfinite(hi) || !std::isfinite(d)) return fail(n + ": non-finite min/max/default");
            if (!(lo <= d && d <= hi))
                return fail(n + ": default " + std::to_string(d) + " outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
        }
        if (p->type == HZ_PARAM_FLOAT_ARRAY) {
            if (p->default_array_count > p->components) return fail(n + ": default_array_count > components");
            if (p->default_array_count > 0 && p->default_array == nullptr) return fail(n + ": default_array is NULL");
            for (uint32_t k = 0; k < p->default_array_count; ++k)
                if (!std::isfinite(p->default_array[k]) || p->default_array[k] < p->min_value[0] || p->default_array[k] > p->max_value[0])
                    return fail(n + ": default_array[" + std::to_string(k) + "] outside [min, max]");
        }
        if (p->type == HZ_PARAM_ENUM) {
            if (p->enum_labels == nullptr) return fail(n + ": ENUM without labels");
            uint32_t cnt = 0;
            while (p->enum_labels[cnt] != nullptr && cnt < 1024) ++cnt;
            if (double(cnt) != p->max_value[0] - p->min_value[0] + 1) return fail(n + ": enum label count != max - min + 1");
        }
        if ((p->flags & HZ_PARAM_FLAG_REQUIRES_RECOMPILE) &&
            !(p->type == HZ_PARAM_INT || p->type == HZ_PARAM_BOOL || p->type == HZ_PARAM_ENUM))
            return fail(n + ": REQUIRES_RECOMPILE on a continuous parameter");
    }
    return pass(std::to_string(count) + " parameters");
}

// Flattened default values of a schema, in schema order.
std::vector<double> default_params(uint32_t count, const hz_param_info *(HZ_ABI *get)(uint32_t)) {
    std::vector<double> v;
    for (uint32_t i = 0; i < count; ++i) {
        const hz_param_info *p = get(i);
        for (uint32_t k = 0; k < p->components; ++k)
            v.push_back(p->type == HZ_PARAM_FLOAT_ARRAY ? (k < p->default_array_count ? p->default_array[k] : p->default_value[0])
                                                        : p->default_value[k]);
    }
    return v;
}

// ------------------------------------------------------------- clustering

void add_shader_checks(std::vector<Check> &c) {
    c.push_back({"shader-schema-wellformed", HZ_KIND_SHADER, "parameter names, types, ranges and defaults are sane", [](const Ctx &x) {
                     const hz_shader &s = shader_of(x);
                     if (!s.get_param && s.param_count) return fail("param_count > 0 but get_param is NULL");
                     return check_schema(s.param_count, s.get_param);
                 }});
    c.push_back(
        {"shader-glsl-contract", HZ_KIND_SHADER, "GLSL snippets define hz_shade( and no #version, main( or uniform", [](const Ctx &x) {
             const hz_shader &s = shader_of(x);
             if (!s.glsl_source || !s.eval_reference) return fail("glsl_source or eval_reference is NULL");
             if (!(s.domains & (HZ_SHADE_SURFACE | HZ_SHADE_LINE))) return fail("no domain");
             if (s.output != HZ_SHADER_OUTPUT_BRDF && s.output != HZ_SHADER_OUTPUT_RADIANCE_FACTOR && s.output != HZ_SHADER_OUTPUT_EMISSION)
                 return fail("unknown output kind");
             for (hz_shade_domain d : {HZ_SHADE_SURFACE, HZ_SHADE_LINE}) {
                 if (!(s.domains & d)) continue;
                 const char *src = s.glsl_source(d, 410);
                 if (!src) return fail("glsl_source returns NULL for a declared domain");
                 const std::string g = src;
                 const std::size_t def = find_call(g, "hz_shade");
                 if (def == std::string::npos || g.rfind("vec3", def) == std::string::npos)
                     return fail("snippet does not define vec3 hz_shade(");
                 if (g.find("#version") != std::string::npos) return fail("snippet has #version");
                 if (find_call(g, "main") != std::string::npos) return fail("snippet defines main(");
                 if (has_word(g, "uniform")) return fail("snippet declares uniforms");
             }
             return pass();
         }});
    c.push_back(
        {"shader-glsl-compiles", HZ_KIND_SHADER,
         "the host's programs built around the GLSL compile as GLSL 4.10 core (glslang, no GPU needed; errors at the snippet's lines)",
         [](const Ctx &x) {
             core::Registry reg(core::Registry::Options{false, 10.0, {}});
             reg.add_module(x.module);
             const core::LoadedPlugin *p = reg.find(x.plugin.id);
             if (p == nullptr || p->shader() == nullptr) return fail("the shader interface does not resolve");
             try {
                 if (auto e = glsl_offline_error(*p)) return fail("GLSL compile error in the " + *e);
             } catch (const std::exception &e) {
                 return fail(e.what());
             }
             return pass();
         }});
    c.push_back({"shader-reference-finite-nonnegative", HZ_KIND_SHADER,
                 "CPU reference is finite and >= 0 over sampled directions and parameters, grazing and degenerate cases included",
                 [](const Ctx &x) {
                     const hz_shader &s = shader_of(x);
                     if (!s.eval_reference) return fail("no eval_reference");
                     std::mt19937_64 rng(x.opts.seed);
                     std::uniform_real_distribution<double> U(-1, 1), U01(0, 1);
                     auto rnd_dir = [&](double *d) {
                         double n2;
                         do {
                             for (int k = 0; k < 3; ++k) d[k] = U(rng);
                             n2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                         } while (n2 < 1e-6 || n2 > 1);
                     };
                     const auto defaults = default_params(s.param_count, s.get_param);
                     // Parameter sets: defaults, every min corner, every max corner, random.
                     std::vector<std::vector<double>> sets = {defaults};
                     for (int corner = 0; corner < 2; ++corner) {
                         std::vector<double> v;
                         for (uint32_t i = 0; i < s.param_count; ++i) {
                             const hz_param_info *p = s.get_param(i);
                             for (uint32_t k = 0; k < p->components; ++k) {
                                 const uint32_t kk = p->type == HZ_PARAM_FLOAT_ARRAY ? 0 : k;
                                 v.push_back(corner ? p->max_value[kk] : p->min_value[kk]);
                             }
                         }
                         sets.push_back(v);
                     }
                     for (int r = 0; r < 64; ++r) {
                         std::vector<double> v;
                         for (uint32_t i = 0; i < s.param_count; ++i) {
                             const hz_param_info *p = s.get_param(i);
                             for (uint32_t k = 0; k < p->components; ++k) {
                                 const uint32_t kk = p->type == HZ_PARAM_FLOAT_ARRAY ? 0 : k;
                                 double val = p->min_value[kk] + U01(rng) * (p->max_value[kk] - p->min_value[kk]);
                                 if (p->type == HZ_PARAM_INT || p->type == HZ_PARAM_ENUM || p->type == HZ_PARAM_BOOL) val = std::round(val);
                                 v.push_back(val);
                             }
                         }
                         sets.push_back(v);
                     }
                     long evaluated = 0;
                     for (hz_shade_domain d : {HZ_SHADE_SURFACE, HZ_SHADE_LINE}) {
                         if (!(s.domains & d)) continue;
                         for (const auto &params : sets)
                             for (int k = 0; k < 400; ++k) {
                                 hz_shade_point p{};
                                 p.struct_size = sizeof p;
                                 p.domain = d;
                                 p.n[2] = 1;
                                 rnd_dir(p.t);
                                 rnd_dir(p.b);
                                 rnd_dir(p.l);
                                 rnd_dir(p.v);
                                 p.thickness_mm = U01(rng) * 10;
                                 switch (k % 10) {                             // the cases where formulas break
                                 case 1: std::copy(p.n, p.n + 3, p.l); break;  // l = n
                                 case 2:
                                     for (int j = 0; j < 3; ++j) p.l[j] = -p.v[j];
                                     break;  // l = -v
                                 case 3:
                                     p.l[0] = 1;
                                     p.l[1] = 0;
                                     p.l[2] = 1e-6;
                                     break;  // grazing light
                                 case 4:
                                     p.v[0] = 0;
                                     p.v[1] = 1;
                                     p.v[2] = 1e-7;
                                     std::copy(p.v, p.v + 3, p.l);
                                     break;                                    // grazing both
                                 case 5: std::copy(p.n, p.n + 3, p.t); break;  // tangent along n
                                 case 6:
                                     p.t[0] = p.t[1] = p.t[2] = 0;
                                     p.b[0] = p.b[1] = p.b[2] = 0;
                                     break;  // no tangent
                                 case 7:
                                     p.l[2] = 0;
                                     p.v[2] = 0;
                                     break;                                    // both in the horizon
                                 case 8: std::copy(p.t, p.t + 3, p.l); break;  // light along the line
                                 default: break;
                                 }
                                 double rgb[3] = {-1, -1, -1};
                                 const hz_status st = s.eval_reference(&p, params.data(), static_cast<uint32_t>(params.size()), rgb);
                                 ++evaluated;
                                 static const char *const kCase[] = {"random directions",
                                                                     "l = n",
                                                                     "l = -v",
                                                                     "grazing light",
                                                                     "grazing light and view",
                                                                     "tangent along n",
                                                                     "no tangent",
                                                                     "l and v in the horizon",
                                                                     "light along the tangent",
                                                                     "random directions"};
                                 // The inputs, as a case `horizon brdf` reads (to reproduce it).
                                 auto inputs = [&] {
                                     const std::string &id = x.plugin.id;
                                     nlohmann::json c{
                                         {"id", "validate"}, {"model", id.substr(id.rfind('.') + 1)}, {"N", p.n}, {"L", p.l}, {"V", p.v}};
                                     if (d == HZ_SHADE_LINE)
                                         c["T"] = p.t;
                                     else
                                         c["X"] = p.t, c["Y"] = p.b;
                                     nlohmann::json values = nlohmann::json::object();
                                     std::size_t at = 0;
                                     for (uint32_t i = 0; i < s.param_count; ++i) {
                                         const hz_param_info *pi = s.get_param(i);
                                         if (pi->components == 1)
                                             values[pi->name] = params[at];
                                         else
                                             values[pi->name] =
                                                 std::vector<double>(params.begin() + at, params.begin() + at + pi->components);
                                         at += pi->components;
                                     }
                                     c["params"] = values;
                                     return std::string(" (") + kCase[k % 10] + "); reproduce with: echo '" + c.dump() +
                                            "' | horizon brdf --shader " + x.plugin.id;
                                 };
                                 if (st != HZ_OK)
                                     return fail("eval_reference returned status " + std::to_string(st) + " on valid input" + inputs());
                                 for (double c : rgb) {
                                     if (!std::isfinite(c))
                                         return fail(std::string("non-finite output (") + (std::isnan(c) ? "NaN" : "Inf") + ")" + inputs());
                                     if (c < 0) return fail("negative output " + std::to_string(c) + inputs());
                                 }
                             }
                     }
                     return pass(std::to_string(evaluated) + " evaluations");
                 }});
    c.push_back(
        {"shader-gpu-equals-cpu", HZ_KIND_SHADER,
         "the host's programs built from the GLSL equal the CPU reference pixel by pixel (headless OpenGL; see `horizon shader-check`)",
         [](const Ctx &x) {
             if (x.opts.no_gpu) return skip("--no-gpu: the GLSL was not compiled");
             std::unique_ptr<core::render::GlContext> gl;
             try {
                 gl = core::render::make_headless_context();
             } catch (const std::exception &e) {
                 // Not a pass: GLSL nobody compiled may not compile.
                 return fail(std::string("the GLSL was not compiled: no headless OpenGL here (") + e.what() +
                             "); install Mesa's EGL (libegl1, libgl1-mesa-dri) or pass --no-gpu to accept it unchecked");
             }
             core::Registry reg(core::Registry::Options{false, 10.0, {}});
             reg.add_module(x.module);
             const core::LoadedPlugin *p = reg.find(x.plugin.id);
             if (p == nullptr || p->shader() == nullptr) return fail("the shader interface does not resolve");
             ShaderCheckOptions o;
             o.sets = 4;
             o.size = 96;
             try {
                 const ShaderGpuResult r = check_shader_gpu(reg, p, o, x.opts.seed);
                 if (r.pixels == 0) return fail("nothing was drawn");
                 if (!r.ok)
                     return fail(std::to_string(r.failures) + " of " + std::to_string(r.pixels) + " pixels differ beyond tolerance (" +
                                 std::to_string(r.nonfinite) + " NaN/Inf, " + std::to_string(r.negative) +
                                 " negative); max error/tolerance " + std::to_string(r.max_err_over_tol));
                 return pass(std::to_string(r.pixels) + " pixels, max error/tolerance " + std::to_string(r.max_err_over_tol));
             } catch (const std::exception &e) {
                 return fail(e.what());  // e.g. the GLSL does not compile, with the compiler's line
             }
         }});
    c.push_back({"shader-reference-reciprocity", HZ_KIND_SHADER, "f(l, v) == f(v, l) when the plugin claims reciprocity", [](const Ctx &x) {
                     const hz_shader &s = shader_of(x);
                     if (!(s.claims & HZ_CLAIM_RECIPROCAL)) return skip("not claimed");
                     std::mt19937_64 rng(x.opts.seed);
                     std::uniform_real_distribution<double> U(-1, 1);
                     const auto params = default_params(s.param_count, s.get_param);
                     for (int k = 0; k < 5000; ++k) {
                         hz_shade_point p{};
                         p.struct_size = sizeof p;
                         p.domain = (s.domains & HZ_SHADE_SURFACE) ? HZ_SHADE_SURFACE : HZ_SHADE_LINE;
                         p.n[2] = 1;
                         for (int j = 0; j < 3; ++j) p.t[j] = U(rng), p.b[j] = U(rng), p.l[j] = U(rng), p.v[j] = U(rng);
                         double a[3], b[3];
                         s.eval_reference(&p, params.data(), uint32_t(params.size()), a);
                         std::swap(p.l, p.v);
                         s.eval_reference(&p, params.data(), uint32_t(params.size()), b);
                         for (int j = 0; j < 3; ++j)
                             if (std::fabs(a[j] - b[j]) > 1e-9 * std::max(1.0, std::fabs(a[j]))) return fail("f(l,v) != f(v,l)");
                     }
                     return pass();
                 }});
}

}  // namespace hz::host::validation
