// Image-based lighting on the GPU (private to the renderer): the
// environment as a cube map, its prefiltered specular mip chain and its
// irradiance, and the split-sum BRDF table (paper section 2: the principled
// BRDF lit by an environment), with black stand-ins so that every sampler of
// a program is always bound. Threading: the GL context's thread.
#pragma once

#include "gpu_object.hpp"

#include <hz/core/plugin_host.hpp>
#include <hz/core/render/scene.hpp>

#include <glm/glm.hpp>

#include <functional>
#include <memory>
#include <string>

namespace hz::core::render {

class ImageLighting {
public:
    // Compiles a fragment program over the full-screen vertex stage.
    using MakeProgram = std::function<std::unique_ptr<Program>(const std::string &vs, const std::string &fs, const std::string &what)>;
    // Compiles its programs, makes the stand-ins and the BRDF table.
    explicit ImageLighting(const MakeProgram &make);
    ~ImageLighting();
    ImageLighting(const ImageLighting &) = delete;
    ImageLighting &operator=(const ImageLighting &) = delete;

    // Builds the cube maps of environment `e` ("none": none; "file": an
    // equirectangular image read through the registry's loaders; else the
    // procedural sky). Returns the milliseconds it took (0 for "none").
    double build(const Registry &reg, const Environment &e);

    bool on = false;           // an environment lights the scene
    glm::mat3 rotation{1.0f};  // about z, from Environment::rotation_deg
    static constexpr int spec_levels = 6;
    GLuint env_cube = 0, spec_cube = 0, diff_cube = 0;  // 0 while off
    GLuint lut_tex = 0, black_cube = 0, black_tex = 0;

private:
    void render_cube(GLuint tex, int size, int level, Program &prog, const std::function<void()> &set);
    static GLuint new_cube(int size, int levels);
    void make_lut();
    static GLuint load_equirect(const Registry &reg, const std::string &path);
    std::unique_ptr<Program> env_face, prefilter, irradiance, lut_prog;
    GLuint empty_vao = 0;
};

}  // namespace hz::core::render
