// Render targets of the renderer and its passes (private to the renderer):
// a multisampled framebuffer of renderbuffers (Fbo), and a texture with its
// framebuffer (Tex2dFbo), made or remade at a size by ensure(). Not in an
// anonymous namespace: members of Renderer::Impl, whose linkage is external.
// Threading: the GL context's thread.
#pragma once

#include "gl.hpp"

#include <hz/core/data.hpp>

namespace hz::core::render {

namespace targets {

struct Fbo {
    GLuint fbo = 0, color = 0, depth = 0;
    int width = 0, height = 0, samples = 0;
    void destroy() {
        if (fbo) glDeleteFramebuffers(1, &fbo);
        if (color) glDeleteRenderbuffers(1, &color);
        if (depth) glDeleteRenderbuffers(1, &depth);
        fbo = color = depth = 0;
    }
};

struct Tex2dFbo {
    GLuint fbo = 0, tex = 0, depth = 0;
    int width = 0, height = 0;
    GLenum format = 0;
    void destroy() {
        if (fbo) glDeleteFramebuffers(1, &fbo);
        if (tex) glDeleteTextures(1, &tex);
        if (depth) glDeleteRenderbuffers(1, &depth);
        if (depth_tex) glDeleteTextures(1, &depth_tex);
        fbo = tex = depth = depth_tex = 0;
    }
    // A depth texture instead (sampled by a later pass; NEAREST).
    GLuint depth_tex = 0;
    void ensure_depth_texture() {
        if (depth_tex) return;
        glGenTextures(1, &depth_tex);
        glBindTexture(GL_TEXTURE_2D, depth_tex);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT24, width, height, 0, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT, nullptr);
        clamped_texture_2d(GL_NEAREST);
        glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth_tex, 0);
        if (tex && glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) throw Error("renderer: incomplete framebuffer");
    }
    // A depth buffer, for drawing into this target directly.
    void ensure_depth() {
        if (depth) return;
        glGenRenderbuffers(1, &depth);
        glBindRenderbuffer(GL_RENDERBUFFER, depth);
        glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
        glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) throw Error("renderer: incomplete framebuffer");
    }
    // The colour texture (sampled with `filter`) and its framebuffer, w x h;
    // kept while the size and format are those asked.
    void ensure(int w, int h, GLenum internal, GLenum fmt, GLenum type, GLenum filter = GL_LINEAR) {
        if (fbo && tex && width == w && height == h && format == internal) return;
        destroy();
        width = w, height = h, format = internal;
        glGenTextures(1, &tex);
        glBindTexture(GL_TEXTURE_2D, tex);
        glTexImage2D(GL_TEXTURE_2D, 0, GLint(internal), w, h, 0, fmt, type, nullptr);
        clamped_texture_2d(filter);
        glGenFramebuffers(1, &fbo);
        glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex, 0);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) throw Error("renderer: incomplete framebuffer");
    }
    // A framebuffer of a depth texture alone (DEPTH_COMPONENT24, NEAREST), w x
    // h: a copy of a frame's depth that passes sample.
    void ensure_depth_only(int w, int h) {
        if (fbo && depth_tex && !tex && width == w && height == h) return;
        destroy();
        width = w, height = h, format = GL_DEPTH_COMPONENT24;
        glGenFramebuffers(1, &fbo);
        ensure_depth_texture();
        glDrawBuffer(GL_NONE);
        glReadBuffer(GL_NONE);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) throw Error("renderer: incomplete framebuffer");
    }
};

}  // namespace targets

}  // namespace hz::core::render
