// Image-based lighting on the GPU (image_lighting.hpp).
#include "image_lighting.hpp"

#include "colour.hpp"
#include "glsl.hpp"

#include <hz/core/io.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace hz::core::render {

ImageLighting::ImageLighting(const MakeProgram &make) {
    glGenVertexArrays(1, &empty_vao);
    const std::string head = "#version 410 core\n";
    env_face = make(glsl::kFullscreenVS, head + glsl::kCubeCommon + glsl::kEnvSource + glsl::kEnvFaceFS, "environment");
    prefilter = make(glsl::kFullscreenVS, head + glsl::kCubeCommon + glsl::kPrefilterFS, "environment prefilter");
    irradiance = make(glsl::kFullscreenVS, head + glsl::kCubeCommon + glsl::kIrradianceFS, "environment irradiance");
    lut_prog = make(glsl::kFullscreenVS, head + glsl::kCubeCommon + glsl::kLutFS, "BRDF table");
    // 1x1 black stand-ins so every sampler is always valid.
    const float zero[4] = {0, 0, 0, 1};
    glGenTextures(1, &black_cube);
    glBindTexture(GL_TEXTURE_CUBE_MAP, black_cube);
    for (int f = 0; f < 6; ++f) glTexImage2D(GL_TEXTURE_CUBE_MAP_POSITIVE_X + f, 0, GL_RGBA16F, 1, 1, 0, GL_RGBA, GL_FLOAT, zero);
    glTexParameteri(GL_TEXTURE_CUBE_MAP, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glGenTextures(1, &black_tex);
    glBindTexture(GL_TEXTURE_2D, black_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA16F, 1, 1, 0, GL_RGBA, GL_FLOAT, zero);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    make_lut();
}

ImageLighting::~ImageLighting() {
    for (auto *p : {&env_face, &prefilter, &irradiance, &lut_prog})
        if (*p) glDeleteProgram((*p)->id);
    GLuint texs[] = {env_cube, spec_cube, diff_cube, lut_tex, black_cube, black_tex};
    glDeleteTextures(6, texs);
    glDeleteVertexArrays(1, &empty_vao);
}

void ImageLighting::render_cube(GLuint tex, int size, int level, Program &prog, const std::function<void()> &set) {
    GLuint fbo = 0;
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, size, size);
    glUseProgram(prog.id);
    set();
    glUniform1f(prog.loc("u_size"), float(size));
    glBindVertexArray(empty_vao);
    for (int f = 0; f < 6; ++f) {
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_CUBE_MAP_POSITIVE_X + f, tex, level);
        glUniform1i(prog.loc("u_face"), f);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    }
    glDeleteFramebuffers(1, &fbo);
}

GLuint ImageLighting::new_cube(int size, int levels) {
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_CUBE_MAP, t);
    for (int l = 0; l < levels; ++l)
        for (int f = 0; f < 6; ++f)
            glTexImage2D(GL_TEXTURE_CUBE_MAP_POSITIVE_X + f, l, GL_RGBA16F, std::max(1, size >> l), std::max(1, size >> l), 0, GL_RGBA,
                         GL_FLOAT, nullptr);
    glTexParameteri(GL_TEXTURE_CUBE_MAP, GL_TEXTURE_MIN_FILTER, levels > 1 ? GL_LINEAR_MIPMAP_LINEAR : GL_LINEAR);
    glTexParameteri(GL_TEXTURE_CUBE_MAP, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_CUBE_MAP, GL_TEXTURE_MAX_LEVEL, levels - 1);
    for (GLenum w : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R}) glTexParameteri(GL_TEXTURE_CUBE_MAP, w, GL_CLAMP_TO_EDGE);
    return t;
}

void ImageLighting::make_lut() {
    const int size = 64;
    glGenTextures(1, &lut_tex);
    glBindTexture(GL_TEXTURE_2D, lut_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RG16F, size, size, 0, GL_RG, GL_FLOAT, nullptr);
    clamped_texture_2d(GL_LINEAR);
    GLuint fbo = 0;
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, lut_tex, 0);
    glViewport(0, 0, size, size);
    glUseProgram(lut_prog->id);
    glUniform1f(lut_prog->loc("u_size"), float(size));
    glBindVertexArray(empty_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDeleteFramebuffers(1, &fbo);
}

double ImageLighting::build(const Registry &reg, const Environment &e) {
    const auto t0 = std::chrono::steady_clock::now();
    for (GLuint *t : {&env_cube, &spec_cube, &diff_cube})
        if (*t) glDeleteTextures(1, t), *t = 0;
    on = e.type != "none";
    const double rot = -e.rotation_deg * M_PI / 180.0;
    rotation = glm::mat3(glm::vec3(std::cos(rot), std::sin(rot), 0), glm::vec3(-std::sin(rot), std::cos(rot), 0), glm::vec3(0, 0, 1));
    if (!on) return 0;
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    GLuint equirect = 0;
    if (e.type == "file") equirect = load_equirect(reg, e.path);
    const int env_size = 128, env_levels = 8;
    env_cube = new_cube(env_size, env_levels);
    render_cube(env_cube, env_size, 0, *env_face, [&] {
        glUniform1i(env_face->loc("u_source"), equirect ? 1 : 0);
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_2D, equirect ? equirect : black_tex);
        glUniform1i(env_face->loc("u_equirect"), 0);
    });
    if (equirect) glDeleteTextures(1, &equirect);
    glBindTexture(GL_TEXTURE_CUBE_MAP, env_cube);
    glGenerateMipmap(GL_TEXTURE_CUBE_MAP);
    glTexParameteri(GL_TEXTURE_CUBE_MAP, GL_TEXTURE_CUBE_MAP_SEAMLESS, GL_TRUE);
    glEnable(GL_TEXTURE_CUBE_MAP_SEAMLESS);

    const int spec_size = 128;
    spec_cube = new_cube(spec_size, spec_levels);
    for (int l = 0; l < spec_levels; ++l)
        render_cube(spec_cube, spec_size >> l, l, *prefilter, [&] {
            glActiveTexture(GL_TEXTURE0);
            glBindTexture(GL_TEXTURE_CUBE_MAP, env_cube);
            glUniform1i(prefilter->loc("u_env"), 0);
            glUniform1f(prefilter->loc("u_roughness"), float(l) / float(spec_levels - 1));
            glUniform1f(prefilter->loc("u_env_size"), float(env_size));
        });
    const int diff_size = 16;
    diff_cube = new_cube(diff_size, 1);
    render_cube(diff_cube, diff_size, 0, *irradiance, [&] {
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_CUBE_MAP, env_cube);
        glUniform1i(irradiance->loc("u_env"), 0);
        glUniform1f(irradiance->loc("u_lod"), 3.0f);
    });
    glFinish();
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

GLuint ImageLighting::load_equirect(const Registry &reg, const std::string &path) {
    // (An equirectangular map of 16384 x 8192, a 16k HDRI, is the largest:
    // a larger one is refused before it is decoded, where a 0.8 MB PNG of
    // 16384 x 16384 took 11 GB.)
    ReadLimits limits;
    limits.max_pixels = std::uint64_t(16384) * 8192;
    limits.what = "environment map";
    Dataset ds = read_dataset(reg, path, nullptr, limits);
    if (ds.kind != HZ_DATA_IMAGE) throw Error(path + ": environment: not an image");
    const Volume &im = ds.volume;  // dims = channels, width, height
    if (im.dims.size() != 3 || im.dims[0] < 1 || im.dims[0] > 4) throw Error(path + ": environment: unsupported image layout");
    const std::uint64_t c = im.dims[0], w = im.dims[1], h = im.dims[2];
    std::vector<float> rgba(w * h * 4, 1.0f);
    const double scale = im.dtype == HZ_DTYPE_U8 ? 1.0 / 255 : im.dtype == HZ_DTYPE_U16 ? 1.0 / 65535 : 1.0;
    const bool srgb = im.dtype == HZ_DTYPE_U8 || im.dtype == HZ_DTYPE_U16;
    const std::size_t es = dtype_size(im.dtype);
    for (std::uint64_t y = 0; y < h; ++y) {  // (a row at a time: no copy of the whole image as doubles)
        const std::vector<double> vals = values_of(im.voxels.data() + y * w * c * es, im.dtype, c * w, es);
        for (std::uint64_t x = 0; x < w; ++x)
            for (std::uint64_t k = 0; k < 3; ++k) {
                const double v = vals[x * c + std::min(k, c - 1)] * scale;
                rgba[(y * w + x) * 4 + k] = float(srgb ? srgb_to_linear(v) : (std::isfinite(v) ? std::max(v, 0.0) : 0.0));
            }
    }
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, GLsizei(w), GLsizei(h), 0, GL_RGBA, GL_FLOAT, rgba.data());
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    return t;
}

}  // namespace hz::core::render
