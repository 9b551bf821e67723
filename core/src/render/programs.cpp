#include "programs.hpp"

#include "glsl.hpp"

#include <hz/core/io.hpp>
#include <hz/core/render/renderer.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <regex>
#include <sstream>

namespace hz::core::render {

namespace {
// Line numbers (GLSL's #line) of the host's code before and after a
// snippet: far beyond any snippet's, so that a compiler's line number alone
// tells whose code it is (Mesa does not report #line's source string).
constexpr long kHostHeadLine = 100000, kHostTailLine = 200000;
}  // namespace

std::string with_snippet(const std::string &head, const char *snippet, const char *tail) {
    // The snippet is source string 1 from its line 1, the host's code
    // around it string 0 from kHostHeadLine and kHostTailLine, so compilers
    // name the snippet's lines as its author numbers them.
    std::string out = head;
    const auto version_end = out.find('\n');
    if (out.starts_with("#version") && version_end != std::string::npos)
        out.insert(version_end + 1, "#line " + std::to_string(kHostHeadLine + 2) + " 0\n");
    out += "#line 1 1\n";
    out += snippet;
    out += "\n#line " + std::to_string(kHostTailLine) + " 0\n// ---- host\n";
    out += tail;
    return out;
}

std::string glsl_error_where(const std::string &line) {
    // Mesa: "1:3(12): error: ..."; NVIDIA: "1(3) : error C1008: ...".
    static const std::regex mesa(R"(^\s*(\d+):(\d+)\((\d+)\):\s*error:\s*(.*)$)");
    static const std::regex nvidia(R"(^\s*(\d+)\((\d+)\)\s*:\s*error\s*(.*)$)");
    static const std::regex glslang(R"(^\s*ERROR:\s*(\d+):(\d+):\s*(.*)$)");
    std::smatch m;
    std::string file, row, col, msg;
    if (std::regex_match(line, m, mesa))
        file = m[1], row = m[2], col = m[3], msg = m[4];
    else if (std::regex_match(line, m, nvidia))
        file = m[1], row = m[2], msg = m[3];
    else if (std::regex_match(line, m, glslang))
        file = m[1], row = m[2], msg = m[3];
    else
        return line;
    const long n = std::stol(row.substr(0, 9));
    if (file == "1" || n < kHostHeadLine)
        return "the plugin's GLSL snippet, line " + row + (col.empty() ? "" : ", column " + col) + ": " + msg;
    return "the host's code around the snippet (" + std::string(n >= kHostTailLine ? "after" : "before") + " it): " + msg;
}

namespace {

// A GLSL float literal that reads back as float(v) exactly.
std::string glsl_float(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", double(float(v)));
    std::string t = buf;
    if (t.find_first_of(".e") == std::string::npos) t += ".0";
    return t;
}

// Baked materials: parameter `pi` (values v) as a constant of the
// program instead of a uniform, so the compiler folds every expression
// of the parameters (and of a colour every vertex shares) once, instead
// of per fragment. Returns false for a type it does not bake.
bool bake_declaration(std::ostringstream &decl, const hz_param_info *pi, const std::string &u, const double *v, const FragmentSpec &g) {
    switch (pi->type) {
    case HZ_PARAM_FLOAT: decl << "const float " << u << " = " << glsl_float(v[0]) << ";\n"; return true;
    case HZ_PARAM_INT:
    case HZ_PARAM_ENUM: decl << "const int " << u << " = " << std::llround(v[0]) << ";\n"; return true;
    case HZ_PARAM_BOOL: decl << "const bool " << u << " = " << (std::llround(v[0]) != 0 ? "true" : "false") << ";\n"; return true;
    case HZ_PARAM_VEC2: decl << "const vec2 " << u << " = vec2(" << glsl_float(v[0]) << ", " << glsl_float(v[1]) << ");\n"; return true;
    case HZ_PARAM_VEC3:
    case HZ_PARAM_COLOR3:
        if (pi->name == g.albedo) {
            if (!g.uniform_rgba) return false;  // per-vertex colours
            const auto &c = *g.uniform_rgba;
            decl << "const vec3 " << u << " = vec3(" << glsl_float(c[0] / 255.0) << ", " << glsl_float(c[1] / 255.0) << ", "
                 << glsl_float(c[2] / 255.0) << ");  // the colour every vertex has\n#define HZ_ALBEDO " << u << "\n";
            return true;
        }
        decl << "const vec3 " << u << " = vec3(" << glsl_float(v[0]) << ", " << glsl_float(v[1]) << ", " << glsl_float(v[2]) << ");\n";
        return true;
    default: return false;
    }
}

}  // namespace

std::string fragment_program(const FragmentSpec &g) {
    const bool debug = g.output == ProgramOutput::Debug;
    const hz_shader *sh = g.shader->shader();
    const hz_shade_domain dom = g.line_domain ? HZ_SHADE_LINE : HZ_SHADE_SURFACE;
    const char *snippet = sh->glsl_source(dom, 410);
    if (!snippet) throw Error("shader '" + g.shader->info.id + "' gave no GLSL for this geometry");
    std::ostringstream s;
    s << "#version 410 core\n";
    s << (g.geom == ProgramGeom::Mesh     ? "#define HZ_GEOM_MESH 1\n"
          : g.geom == ProgramGeom::Tube   ? "#define HZ_GEOM_TUBE 1\n"
          : g.geom == ProgramGeom::Point  ? "#define HZ_GEOM_POINT 1\n"
          : g.geom == ProgramGeom::Volume ? "#define HZ_GEOM_VOLUME 1\n"
                                          : "#define HZ_GEOM_LINE 1\n");
    s << (dom == HZ_SHADE_LINE ? "#define HZ_DOMAIN_LINE 1\n" : "#define HZ_DOMAIN_SURFACE 1\n");
    if (sh->output == HZ_SHADER_OUTPUT_BRDF) s << "#define HZ_OUTPUT_BRDF 1\n";
    if (sh->output == HZ_SHADER_OUTPUT_EMISSION) s << "#define HZ_OUTPUT_EMISSION 1\n";
    if (HZ_HAS_FIELD(sh, hz_shader, display) && sh->display == HZ_SHADER_DISPLAY_AS_IS) s << "#define HZ_OUTPUT_AS_IS 1\n";
    if (debug) s << "#define HZ_DEBUG_OUTPUTS 1\n";
    if (g.output == ProgramOutput::Display) s << "#define HZ_DISPLAY 1\n";
    if (g.peel && g.output == ProgramOutput::Hdr) s << "#define HZ_PEEL 1\n";
    s << "#define HZ_TONEMAP " << g.tone_curve << "\n";
    // Lights and environment as constants (see kShadeMain); with no
    // light at all, one black light keeps the arrays non-empty.
    // Light i is directional (l = a uniform unit vector) or a point light
    // (l normalised per fragment), fixed in the program.
    const std::vector<Light> &ls = g.lights;
    const std::size_t nl = debug ? 1 : std::clamp<std::size_t>(ls.size(), 1, 8);
    s << "#define HZ_NB_LIGHTS " << nl << "\n";
    s << "#define HZ_UNIT_VECTORS 1\n";
    // One line: GLSL before 4.20 has no line continuation (Mesa accepts it
    // anyway; glslang and stricter drivers do not).
    s << "#define HZ_APPLY_LIGHTS";
    for (std::size_t i = 0; i < nl; ++i) {
        const bool point = i < ls.size() && ls[i].type == "point";
        s << " p.l = "
          << (point ? "hz_safe_normalize(hz_light_vec[" + std::to_string(i) + "].xyz - v_pos, vec3(0.0))"
                    : "hz_light_vec[" + std::to_string(i) + "].xyz")
          << "; HZ_LIGHT_TERM(" << i << ")";
    }
    s << "\n";
    if (!debug && g.shadow_light >= 0 && std::size_t(g.shadow_light) < nl && g.geom != ProgramGeom::Volume &&
        sh->output != HZ_SHADER_OUTPUT_EMISSION)
        s << "#define HZ_SHADOW 1\n#define HZ_SHADOW_LIGHT " << g.shadow_light << "\n";
    s << "#define HZ_ENV " << (!debug && g.env_on ? 1 : 0) << "\n";
    // Lines, tubes and the fibre volume (shaded as lines): a shading
    // model's `anisotropic` parameter makes them shine as hair does
    // (kShadeMain: each light's normal towards a line's glint, the
    // anisotropy's tangent around the fibre).
    if (g.geom == ProgramGeom::Line || g.geom == ProgramGeom::Volume || g.geom == ProgramGeom::Tube)
        for (uint32_t i = 0, k = 0; i < sh->param_count; k += sh->get_param(i)->components, ++i)
            if (const hz_param_info *pi = sh->get_param(i);
                pi->type == HZ_PARAM_FLOAT && std::strcmp(pi->name, "anisotropic") == 0 && g.values[k] != 0.0)
                s << "#define HZ_FIBRE_ANISOTROPY u_anisotropic\n";
    if (g.refractive) s << "#define HZ_REFRACTIVE 1\n";
    if (std::strstr(snippet, "hz_ambient(")) s << "#define HZ_HAS_AMBIENT 1\n";
    // Specialisation: parameters that are exactly zero.
    std::size_t k = 0;
    std::ostringstream decl;
    for (uint32_t i = 0; i < sh->param_count; ++i) {
        const hz_param_info *pi = sh->get_param(i);
        const std::string u = std::string("u_") + pi->name;
        if (pi->type == HZ_PARAM_FLOAT && g.values[k] == 0.0) s << "#define HZ_ZERO_" << pi->name << " 1\n";
        if ((pi->flags & HZ_PARAM_FLAG_REQUIRES_RECOMPILE) &&
            (pi->type == HZ_PARAM_INT || pi->type == HZ_PARAM_ENUM || pi->type == HZ_PARAM_BOOL))
            s << "#define HZ_PARAM_" << pi->name << " " << std::llround(g.values[k]) << "\n";
        if (g.bake && bake_declaration(decl, pi, u, g.values.data() + k, g)) {
            k += pi->components;
            continue;
        }
        switch (pi->type) {
        case HZ_PARAM_FLOAT: decl << "uniform float " << u << ";\n"; break;
        case HZ_PARAM_INT:
        case HZ_PARAM_ENUM: decl << "uniform int " << u << ";\n"; break;
        case HZ_PARAM_BOOL: decl << "uniform bool " << u << ";\n"; break;
        case HZ_PARAM_VEC2: decl << "uniform vec2 " << u << ";\n"; break;
        case HZ_PARAM_VEC3: decl << "uniform vec3 " << u << ";\n"; break;
        case HZ_PARAM_COLOR3:
            if (pi->name == g.albedo)
                decl << "vec3 " << u << ";  // set from the object's colouring\n#define HZ_ALBEDO " << u
                     << "\n#define HZ_ALBEDO_PER_VERTEX 1\n";
            else
                decl << "uniform vec3 " << u << ";\n";
            break;
        case HZ_PARAM_FLOAT_ARRAY: decl << "uniform float " << u << "[" << pi->components << "];\n"; break;
        default: break;
        }
        k += pi->components;
    }
    // HZ_ALBEDO names the first colour parameter (hz_shader.h) also where
    // the object's colouring does not drive it (the material gives the
    // colour, or the validator's check program): a snippet written with it
    // did not compile then.
    if (g.albedo.empty())
        for (uint32_t i = 0; i < sh->param_count; ++i)
            if (const hz_param_info *pi = sh->get_param(i); pi->type == HZ_PARAM_COLOR3) {
                decl << "#define HZ_ALBEDO u_" << pi->name << "\n";
                break;
            }
    s << glsl::kPrelude << glsl::kDisplay << decl.str() << "\n// ---- plugin " << g.shader->info.id << "\n";
    return with_snippet(s.str(), snippet, glsl::kShadeMain);
}

std::string check_fragment_program(const LoadedPlugin &shader, hz_shade_domain domain, bool baked) {
    const hz_shader *sh = shader.shader();
    if (sh == nullptr) throw Error("'" + shader.info.id + "' is not a shader");
    std::vector<double> values;
    for (uint32_t i = 0; i < sh->param_count; ++i) {
        const hz_param_info *pi = sh->get_param(i);
        for (uint32_t c = 0; c < pi->components; ++c) values.push_back(default_component(pi, c));
    }
    FragmentSpec f;
    f.shader = &shader;
    f.geom = domain == HZ_SHADE_LINE ? ProgramGeom::Line : ProgramGeom::Mesh;
    f.line_domain = domain == HZ_SHADE_LINE;
    f.values = values;
    f.bake = baked;
    f.env_on = true;
    Light key, point;
    point.type = "point";
    point.position = {0, 0, 100};
    f.lights = {key, point};
    return fragment_program(f);
}

}  // namespace hz::core::render
