#include <hz/core/data.hpp>
#include <hz/core/render/context.hpp>

#include "gl.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

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
        // Candidates in order: each EGL device that is not a software
        // renderer (a workstation's or a server's GPU, with or without a
        // display; skipped when LIBGL_ALWAYS_SOFTWARE is set; only the one
        // HORIZON_GPU names, if set), then Mesa's surfaceless platform
        // (llvmpipe where there is no GPU), then the default display. The
        // first on which an OpenGL 4.1+ core context can be made is used.
        const char *exts = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
        auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
        auto has = [&](const char *ext) { return exts && std::strstr(exts, ext) && get_platform_display; };
        std::string why = "no EGL display (is Mesa's libegl-mesa0 installed?)";
        // The GPUs: EGL devices that are not software renderers, in EGL's order.
        std::vector<EGLDeviceEXT> gpus;
        if (has("EGL_EXT_platform_device")) {
            auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
            auto query_device_string = reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
            EGLDeviceEXT devices[64];
            EGLint n = 0;
            if (query_devices && query_device_string && query_devices(64, devices, &n))
                for (EGLint i = 0; i < n; ++i) {
                    const char *dev_exts = query_device_string(devices[i], EGL_EXTENSIONS);
                    if (!(dev_exts && std::strstr(dev_exts, "EGL_MESA_device_software"))) gpus.push_back(devices[i]);
                }
        }
        // HORIZON_GPU=N: the N-th of them (from 0) and nothing else (a server's
        // processes spread over its GPUs).
        if (const char *want = std::getenv("HORIZON_GPU"); want && *want) {
            char *end = nullptr;
            const long k = std::strtol(want, &end, 10);
            if (*end || k < 0) throw Error(std::string("HORIZON_GPU='") + want + "' is not a GPU's number (0 for the first)");
            if (std::size_t(k) >= gpus.size())
                throw Error(std::string("HORIZON_GPU=") + want + ": no such GPU (this machine's EGL has " + std::to_string(gpus.size()) +
                            (gpus.size() == 1 ? " GPU device" : " GPU devices") + ")");
            if (open(get_platform_display(EGL_PLATFORM_DEVICE_EXT, gpus[std::size_t(k)], nullptr), why)) return;
            throw Error(std::string("headless OpenGL: HORIZON_GPU=") + want + ": " + why);
        }
        const char *soft = std::getenv("LIBGL_ALWAYS_SOFTWARE");
        if (!(soft && *soft && std::strcmp(soft, "0") != 0))
            for (EGLDeviceEXT d : gpus)
                if (open(get_platform_display(EGL_PLATFORM_DEVICE_EXT, d, nullptr), why)) return;
        if (has("EGL_MESA_platform_surfaceless") &&
            open(get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr), why))
            return;
        if (open(eglGetDisplay(EGL_DEFAULT_DISPLAY), why)) return;
        throw Error("headless OpenGL: " + why);
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
    // Makes an OpenGL 4.1+ core context on d current; on failure leaves
    // nothing open, says why, and returns false.
    bool open(EGLDisplay d, std::string &why) {
        if (d == EGL_NO_DISPLAY) return false;
        EGLint major = 0, minor = 0;
        if (!eglInitialize(d, &major, &minor)) {
            why = "eglInitialize failed: " + egl_error_name(eglGetError());
            return false;
        }
        auto fail = [&](std::string what) {
            eglTerminate(d);
            why = std::move(what);
            return false;
        };
        if (!eglBindAPI(EGL_OPENGL_API)) return fail("EGL has no desktop OpenGL API");
        const char *dexts = eglQueryString(d, EGL_EXTENSIONS);
        const bool no_config = dexts && std::strstr(dexts, "EGL_KHR_no_config_context") != nullptr;
        EGLConfig config = nullptr;
        if (!no_config) {
            const EGLint attrs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_NONE};
            EGLint n = 0;
            if (!eglChooseConfig(d, attrs, &config, 1, &n) || n == 0) return fail("no EGL config with desktop OpenGL");
        }
        const int versions[][2] = {{4, 5}, {4, 3}, {4, 1}};
        EGLContext c = EGL_NO_CONTEXT;
        for (const auto &v : versions) {
            const EGLint attrs[] = {
                EGL_CONTEXT_MAJOR_VERSION,           v[0],    EGL_CONTEXT_MINOR_VERSION, v[1], EGL_CONTEXT_OPENGL_PROFILE_MASK,
                EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
            c = eglCreateContext(d, config, EGL_NO_CONTEXT, attrs);
            if (c != EGL_NO_CONTEXT) break;
        }
        if (c == EGL_NO_CONTEXT) return fail("no OpenGL 4.1+ core context: " + egl_error_name(eglGetError()));
        if (!eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, c)) {
            eglDestroyContext(d, c);
            return fail("eglMakeCurrent failed: " + egl_error_name(eglGetError()));
        }
        display_ = d, context_ = c;
        return true;
    }

    EGLDisplay display_ = EGL_NO_DISPLAY;
    EGLContext context_ = EGL_NO_CONTEXT;
};

}  // namespace

std::unique_ptr<GlContext> make_headless_context() { return std::make_unique<EglContext>(); }

}  // namespace hz::core::render
