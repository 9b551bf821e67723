#include <hz/core/data.hpp>
#include <hz/core/render/context.hpp>

#include "gl.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdio>
#include <cstring>

namespace hz::core::render {

std::string GlContext::description() const {
    const auto *ver = reinterpret_cast<const char *>(glGetString(GL_VERSION));
    const auto *ren = reinterpret_cast<const char *>(glGetString(GL_RENDERER));
    return std::string("OpenGL ") + (ver ? ver : "?") + ", " + (ren ? ren : "?");
}

namespace {

std::string egl_error_name(EGLint e) {
    switch (e) {
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    default: {
        char buf[32];
        std::snprintf(buf, sizeof buf, "EGL error 0x%04x", unsigned(e));
        return buf;
    }
    }
}

class EglContext final : public GlContext {
public:
    EglContext() {
        const char *exts = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
        auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
        if (exts && std::strstr(exts, "EGL_MESA_platform_surfaceless") && get_platform_display)
            display_ = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
        if (display_ == EGL_NO_DISPLAY) display_ = eglGetDisplay(EGL_DEFAULT_DISPLAY);
        if (display_ == EGL_NO_DISPLAY) throw Error("headless OpenGL: no EGL display (is Mesa's libegl-mesa0 installed?)");
        EGLint major = 0, minor = 0;
        if (!eglInitialize(display_, &major, &minor))
            throw Error("headless OpenGL: eglInitialize failed: " + egl_error_name(eglGetError()));
        if (!eglBindAPI(EGL_OPENGL_API)) throw Error("headless OpenGL: EGL has no desktop OpenGL API");
        const bool no_config = std::strstr(eglQueryString(display_, EGL_EXTENSIONS), "EGL_KHR_no_config_context") != nullptr;
        EGLConfig config = nullptr;
        if (!no_config) {
            const EGLint attrs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_NONE};
            EGLint n = 0;
            if (!eglChooseConfig(display_, attrs, &config, 1, &n) || n == 0)
                throw Error("headless OpenGL: no EGL config with desktop OpenGL");
        }
        const int versions[][2] = {{4, 5}, {4, 3}, {4, 1}};
        for (const auto &v : versions) {
            const EGLint attrs[] = {
                EGL_CONTEXT_MAJOR_VERSION,           v[0],    EGL_CONTEXT_MINOR_VERSION, v[1], EGL_CONTEXT_OPENGL_PROFILE_MASK,
                EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
            context_ = eglCreateContext(display_, config, EGL_NO_CONTEXT, attrs);
            if (context_ != EGL_NO_CONTEXT) break;
        }
        if (context_ == EGL_NO_CONTEXT) throw Error("headless OpenGL: no OpenGL 4.1+ core context: " + egl_error_name(eglGetError()));
        make_current();
    }
    ~EglContext() override {
        if (display_ != EGL_NO_DISPLAY) {
            eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
            if (context_ != EGL_NO_CONTEXT) eglDestroyContext(display_, context_);
            eglTerminate(display_);
        }
    }
    void make_current() override {
        if (!eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_))
            throw Error("headless OpenGL: eglMakeCurrent failed: " + egl_error_name(eglGetError()));
    }

private:
    EGLDisplay display_ = EGL_NO_DISPLAY;
    EGLContext context_ = EGL_NO_CONTEXT;
};

}  // namespace

std::unique_ptr<GlContext> make_headless_context() { return std::make_unique<EglContext>(); }

}  // namespace hz::core::render
