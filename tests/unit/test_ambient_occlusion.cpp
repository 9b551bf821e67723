// The ambient occlusion pass on the GPU against its C++ statement
// (ao_reference) on the same depth buffer, and what the estimate must show
// whatever its implementation: no darkening on a plane however tilted, on
// the background or on what nothing is in front of; darkening in a gap
// between nearer things, growing with strength.
#include <hz/core/render/context.hpp>

#include "gl.hpp"
#include "passes/ambient_occlusion.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

using namespace hz::core::render;

namespace {

constexpr int W = 160, H = 120;

GLuint compile(GLenum type, const std::string &src) {
    const GLuint s = glCreateShader(type);
    const char *p = src.c_str();
    glShaderSource(s, 1, &p, nullptr);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    REQUIRE(ok);
    return s;
}

std::unique_ptr<Program> make(const std::string &vs, const std::string &fs, const std::string &) {
    auto p = std::make_unique<Program>();
    p->id = glCreateProgram();
    glAttachShader(p->id, compile(GL_VERTEX_SHADER, vs));
    glAttachShader(p->id, compile(GL_FRAGMENT_SHADER, fs));
    glLinkProgram(p->id);
    GLint ok = 0;
    glGetProgramiv(p->id, GL_LINK_STATUS, &ok);
    REQUIRE(ok);
    return p;
}

// Window depth of a point `z_mm` from the eye for the camera of `p`.
float window_depth(double z_mm, const AoParams &p) { return float((1.0 / p.near_mm - 1.0 / z_mm) / (1.0 / p.near_mm - 1.0 / p.far_mm)); }

}  // namespace

TEST_CASE("ambient occlusion: the GPU pass equals its C++ statement, planes stay lit, gaps between nearer things darken") {
    // (Kept for the life of the process: terminating EGL unloads Mesa's
    // driver, whose allocations LeakSanitizer then cannot attribute to it,
    // as tests/lsan.supp does while it is loaded.)
    static GlContext *const ctx = make_headless_context().release();
    ctx->make_current();
    AoParams p;
    p.radius_mm = 6, p.strength = 1, p.pairs = 16, p.fov_deg = 30, p.near_mm = 200, p.far_mm = 2000;
    // A depth image: background; a plane tilted 75 degrees from the view
    // (grazing) on the left; on the right, a floor at 330.25 mm (no depth difference a whole number) under random
    // bars at 322-328 mm (streamlines nearer than what they lie on), and
    // two bars at 325 mm around a gap 3 px wide at x = 120.
    std::vector<float> depth(std::size_t(W) * H, 1.0f);
    const double focal = 0.5 * H / std::tan(p.fov_deg * M_PI / 360);
    for (int y = 10; y < 110; ++y)
        for (int x = 5; x < 70; ++x) {
            // (a plane: 1/z linear across the picture; z = 320 mm at x = 5)
            const double slope = std::tan(75 * M_PI / 180) / focal / 320;  // d(1/z)/dx at x = 5
            depth[std::size_t(y) * W + x] = window_depth(1 / (1.0 / 320 - (x - 5) * slope), p);
        }
    for (int y = 10; y < 110; ++y)
        for (int x = 80; x < 155; ++x) depth[std::size_t(y) * W + x] = window_depth(330.25, p);
    std::mt19937 rng(7);
    for (int k = 0; k < 12; ++k) {
        const int y0 = 12 + int(rng() % 90), x0 = 82 + int(rng() % 20);
        const double z = 322 + (rng() % 7);
        for (int y = y0; y < std::min(y0 + 3, 110); ++y)
            for (int x = x0; x < x0 + 25; ++x) depth[std::size_t(y) * W + x] = window_depth(z, p);
    }
    for (int y = 30; y < 90; ++y)
        for (int x : {116, 117, 118, 122, 123, 124}) depth[std::size_t(y) * W + x] = window_depth(325, p);

    // The depth into a framebuffer as the renderer's would hold it.
    GLuint fbo = 0, depth_tex = 0, colour = 0, vao = 0;
    glGenVertexArrays(1, &vao);
    glGenTextures(1, &depth_tex);
    glBindTexture(GL_TEXTURE_2D, depth_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT24, W, H, 0, GL_DEPTH_COMPONENT, GL_FLOAT, depth.data());
    glGenTextures(1, &colour);
    glBindTexture(GL_TEXTURE_2D, colour);
    std::vector<std::uint8_t> grey(std::size_t(W) * H * 4, 200);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, W, H, 0, GL_RGBA, GL_UNSIGNED_BYTE, grey.data());
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, colour, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth_tex, 0);
    REQUIRE(glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE);

    AmbientOcclusionPass pass(make);
    FrameDepth frame;
    frame.resolve(fbo, W, H);
    pass.apply(fbo, frame, p, vao, /*encoded=*/false);
    const std::vector<float> stored = frame.read();  // (as the GPU holds it: 24 bits)
    const std::vector<float> gpu = pass.read_factors(frame, p, vao, /*blur=*/false);
    const std::vector<float> cpu = ao_reference(stored, W, H, p);
    REQUIRE(gpu.size() == cpu.size());
    std::size_t off = 0;
    double worst = 0;
    for (std::size_t i = 0; i < gpu.size(); ++i) {
        const double d = std::abs(double(gpu[i]) - cpu[i]);
        worst = std::max(worst, d);
        off += d > 1e-3;
    }
    INFO("pixels off by more than 1e-3: " << off << ", worst " << worst);
    CHECK(off <= gpu.size() / 1000);  // (an offset exactly at .5 px may round either way)
    CHECK(worst < 0.1);

    auto at = [&](const std::vector<float> &v, int x, int y) { return v[std::size_t(y) * W + x]; };
    // The grazing plane is not darkened (away from its edges), nor the background.
    double plane_min = 1;
    for (int y = 30; y < 90; ++y)
        for (int x = 25; x < 50; ++x) plane_min = std::min(plane_min, double(at(cpu, x, y)));
    CHECK(plane_min > 0.98);
    CHECK(at(cpu, 2, 2) == 1.0f);
    // The near bars themselves have nothing in front; the floor in the gap
    // between two of them is darkened, the floor far from any bar is not.
    CHECK(at(cpu, 117, 60) > 0.98);
    CHECK(at(cpu, 120, 60) < 0.75);
    CHECK(at(cpu, 145, 20) > 0.98);
    // Blurred over 4 x 4 pixels within a radius in depth, as its C++
    // statement says; a bar's pixels take nothing from the floor behind.
    const std::vector<float> gpu_blur = pass.read_factors(frame, p, vao, /*blur=*/true);
    const std::vector<float> cpu_blur = ao_blur_reference(cpu, stored, W, H, p);
    double worst_blur = 0;
    for (std::size_t i = 0; i < gpu_blur.size(); ++i) worst_blur = std::max(worst_blur, std::abs(double(gpu_blur[i]) - cpu_blur[i]));
    CHECK(worst_blur < 1e-3);
    CHECK(at(cpu_blur, 117, 60) > 0.98);
    CHECK(at(cpu_blur, 120, 60) < 0.8);
    // The picture is multiplied by the blurred factor (linear here).
    std::vector<std::uint8_t> out(std::size_t(W) * H * 4);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
    glReadPixels(0, 0, W, H, GL_RGBA, GL_UNSIGNED_BYTE, out.data());
    const std::size_t g = (std::size_t(60) * W + 120) * 4;
    CHECK(std::abs(int(out[g]) - int(std::lround(200 * at(gpu_blur, 120, 60)))) <= 1);
    CHECK(out[(std::size_t(2) * W + 2) * 4] == 200);

    // Half the strength, half the darkening.
    AoParams half = p;
    half.strength = 0.5;
    const std::vector<float> h2 = ao_reference(stored, W, H, half);
    CHECK(std::abs((1 - at(h2, 120, 60)) - 0.5 * (1 - at(cpu, 120, 60))) < 1e-5);
    glDeleteFramebuffers(1, &fbo);
    glDeleteTextures(1, &depth_tex);
    glDeleteTextures(1, &colour);
    glDeleteVertexArrays(1, &vao);
}
