// GLSL checked without a GPU: the fragment programs the renderer builds
// around a shader plugin's snippet, compiled by glslang (Khronos' reference
// GLSL front end) as GLSL 4.10 core, as a driver would (`horizon validate`).
#include "commands.hpp"

#include <hz/core/render/renderer.hpp>

#include <glslang/Public/ResourceLimits.h>
#include <glslang/Public/ShaderLang.h>

#include <mutex>
#include <sstream>

namespace hz::host {

std::optional<std::string> glsl_offline_error(const core::LoadedPlugin &shader) {
    static std::once_flag once;
    std::call_once(once, [] { glslang::InitializeProcess(); });
    const hz_shader *sh = shader.shader();
    for (hz_shade_domain d : {HZ_SHADE_SURFACE, HZ_SHADE_LINE}) {
        if (!(sh->domains & d)) continue;
        for (bool baked : {false, true}) {
            const std::string src = core::render::check_fragment_program(shader, d, baked);
            const char *text = src.c_str();
            glslang::TShader fs(EShLangFragment);
            fs.setStrings(&text, 1);
            const bool ok = fs.parse(GetDefaultResources(), 410, ECoreProfile, false, false, EShMsgDefault);
            if (ok) continue;
            // The first error line of the log ("ERROR: 1:3: 'x' : undeclared identifier").
            std::istringstream log(fs.getInfoLog());
            std::string line, first;
            while (std::getline(log, line))
                if (line.starts_with("ERROR:")) {
                    first = line;
                    break;
                }
            return std::string(d == HZ_SHADE_LINE ? "line" : "surface") + " domain" + (baked ? " (baked parameters)" : "") + ": " +
                   core::render::glsl_error_where(first.empty() ? std::string(fs.getInfoLog()) : first);
        }
    }
    return std::nullopt;
}

}  // namespace hz::host
