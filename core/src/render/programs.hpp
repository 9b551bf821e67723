// Assembly of the host's fragment programs around a shader plugin's GLSL
// snippet (private to the renderer and the validator's GLSL check).
#pragma once

#include <hz/core/plugin_host.hpp>
#include <hz/core/render/scene.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace hz::core::render {

enum class ProgramGeom { Mesh, Tube, Line, Point, Volume };
enum class ProgramOutput { Hdr, Display, Debug };

// What a fragment program depends on.
struct FragmentSpec {
    const LoadedPlugin *shader = nullptr;
    ProgramGeom geom = ProgramGeom::Mesh;
    bool line_domain = false;                                 // the snippet's line domain (HZ_SHADE_LINE)
    std::span<const double> values;                           // the shader's parameter values, in schema order
    std::string albedo;                                       // the colour parameter the colouring drives ("" if none)
    std::optional<std::array<std::uint8_t, 4>> uniform_rgba;  // the colour every vertex has, if one
    bool refractive = false;
    bool bake = true;  // parameters as constants instead of uniforms
    ProgramOutput output = ProgramOutput::Hdr;
    bool peel = false;   // a depth-peeling layer's program (HDR output; passes/transparency.hpp)
    int tone_curve = 0;  // 0 ACES, 1 Reinhard, 2 none
    bool env_on = false;
    std::vector<Light> lights;
    // The light whose shadows the program reads (a directional light of
    // `lights`; passes/shadow.hpp), or -1: none. Ignored by the debug
    // output, emission shaders and the fibre volume.
    int shadow_light = -1;
};

// Component `c` of parameter `pi`'s default: default_value[c], or for a
// FLOAT_ARRAY its default_array (default_value[0] past its end). The one
// rule for a material's values (Renderer) and the validator's programs.
inline double default_component(const hz_param_info *pi, std::uint32_t c) {
    if (pi->type == HZ_PARAM_FLOAT_ARRAY) return c < pi->default_array_count ? pi->default_array[c] : pi->default_value[0];
    return pi->default_value[c];
}

// The fragment program for `f`: the host's prelude and declarations, the
// snippet (GLSL source string 1 from line 1; see with_snippet), the host's
// main. Throws Error when the shader gives no GLSL for the domain.
std::string fragment_program(const FragmentSpec &f);

}  // namespace hz::core::render
