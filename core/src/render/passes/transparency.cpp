// Order-independent transparency by depth peeling (transparency.hpp).
#include "transparency.hpp"

#include "../glsl.hpp"

#include <hz/core/data.hpp>

namespace hz::core::render {

namespace {

// A layer under what the layers in front accumulated: its colour is straight
// (one fragment), or premultiplied (the last layer, blended in drawing order).
constexpr const char *kUnderFS = R"glsl(#version 410 core
in vec2 v_uv;
uniform sampler2D u_layer;
uniform int u_premultiplied;
out vec4 o;
void main() {
    vec4 c = texelFetch(u_layer, ivec2(gl_FragCoord.xy), 0);
    o = u_premultiplied != 0 ? c : vec4(c.rgb * c.a, c.a);
}
)glsl";

// The accumulated layers (premultiplied) over the opaque picture.
constexpr const char *kOverFS = R"glsl(#version 410 core
in vec2 v_uv;
uniform sampler2D u_acc;
out vec4 o;
void main() { o = texelFetch(u_acc, ivec2(gl_FragCoord.xy), 0); }
)glsl";

// A w x h texture of `internal` format, fetched (NEAREST, clamped).
GLuint texture(int w, int h, GLenum internal, GLenum format, GLenum type) {
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexImage2D(GL_TEXTURE_2D, 0, GLint(internal), w, h, 0, format, type, nullptr);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    return t;
}

}  // namespace

DepthPeeling::DepthPeeling(MakeProgram make) : make_(std::move(make)) {}

DepthPeeling::~DepthPeeling() {
    release();
    if (under_) glDeleteProgram(under_->id);
    if (over_) glDeleteProgram(over_->id);
    if (query_) glDeleteQueries(1, &query_);
}

void DepthPeeling::release() {
    if (layer_fbo_) glDeleteFramebuffers(1, &layer_fbo_);
    if (acc_fbo_) glDeleteFramebuffers(1, &acc_fbo_);
    for (GLuint *t : {&layer_tex_, &depth_[0], &depth_[1], &acc_tex_})
        if (*t) glDeleteTextures(1, t), *t = 0;
    layer_fbo_ = acc_fbo_ = 0;
    w_ = h_ = 0;
}

void DepthPeeling::ensure(int w, int h) {
    if (!under_) under_ = make_(glsl::kFullscreenVS, kUnderFS, "transparency: layer under");
    if (!over_) over_ = make_(glsl::kFullscreenVS, kOverFS, "transparency: layers over the opaque picture");
    if (!query_) glGenQueries(1, &query_);
    if (w == w_ && h == h_) return;
    release();
    w_ = w, h_ = h;
    layer_tex_ = texture(w, h, GL_RGBA16F, GL_RGBA, GL_FLOAT), acc_tex_ = texture(w, h, GL_RGBA16F, GL_RGBA, GL_FLOAT);
    for (GLuint &d : depth_) d = texture(w, h, GL_DEPTH_COMPONENT24, GL_DEPTH_COMPONENT, GL_UNSIGNED_INT);
    glGenFramebuffers(1, &layer_fbo_);
    glBindFramebuffer(GL_FRAMEBUFFER, layer_fbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, layer_tex_, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth_[0], 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) throw Error("transparency: incomplete layer framebuffer");
    glGenFramebuffers(1, &acc_fbo_);
    glBindFramebuffer(GL_FRAMEBUFFER, acc_fbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, acc_tex_, 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) throw Error("transparency: incomplete framebuffer");
}

int DepthPeeling::composite(GLuint opaque_fbo, GLuint target_fbo, int w, int h, int max_layers, const std::function<void(GLuint)> &draw,
                            GLuint empty_vao, const std::function<void(GLuint near, GLuint far)> &between) {
    ensure(w, h);
    glViewport(0, 0, w, h);
    // Nothing accumulated yet; the "previous layer" lies at depth 0, in
    // front of everything.
    glBindFramebuffer(GL_FRAMEBUFFER, acc_fbo_);
    glClearColor(0, 0, 0, 0);
    glClear(GL_COLOR_BUFFER_BIT);
    glBindFramebuffer(GL_FRAMEBUFFER, layer_fbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth_[1], 0);
    glDepthMask(GL_TRUE);
    glClearDepth(0.0);
    glClear(GL_DEPTH_BUFFER_BIT);
    glClearDepth(1.0);
    auto under = [&](bool premultiplied) {
        glBindFramebuffer(GL_FRAMEBUFFER, acc_fbo_);
        glDisable(GL_DEPTH_TEST);
        glEnable(GL_BLEND);
        glBlendFunc(GL_ONE_MINUS_DST_ALPHA, GL_ONE);
        glUseProgram(under_->id);
        bind_sampler(*under_, "u_layer", 0, GL_TEXTURE_2D, layer_tex_);
        glUniform1i(under_->loc("u_premultiplied"), premultiplied ? 1 : 0);
        glBindVertexArray(empty_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glDisable(GL_BLEND);
    };
    // What lies between the layer in front (depth `near`) and this one
    // (`far`), under what is accumulated.
    auto segment = [&](GLuint near, GLuint far) {
        if (!between) return;
        glBindFramebuffer(GL_FRAMEBUFFER, acc_fbo_);
        glViewport(0, 0, w, h);
        glDisable(GL_DEPTH_TEST);
        glEnable(GL_BLEND);
        glBlendFunc(GL_ONE_MINUS_DST_ALPHA, GL_ONE);
        between(near, far);
        glDisable(GL_BLEND);
    };
    // Each layer starts from the opaque depth: what lies behind it is hidden.
    auto start_layer = [&](GLuint depth) {
        glBindFramebuffer(GL_FRAMEBUFFER, layer_fbo_);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth, 0);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, opaque_fbo);
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, layer_fbo_);
        glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_DEPTH_BUFFER_BIT, GL_NEAREST);
        glBindFramebuffer(GL_FRAMEBUFFER, layer_fbo_);
        glClearColor(0, 0, 0, 0);
        glClear(GL_COLOR_BUFFER_BIT);
        glViewport(0, 0, w, h);
        glEnable(GL_DEPTH_TEST);
        glDepthFunc(GL_LESS);
    };
    int cur = 0, layers = 0;
    bool more = true;
    for (; layers < max_layers; ++layers) {
        start_layer(depth_[cur]);
        glDepthMask(GL_TRUE);
        glDisable(GL_BLEND);
        glBeginQuery(GL_ANY_SAMPLES_PASSED, query_);
        draw(depth_[1 - cur]);
        glEndQuery(GL_ANY_SAMPLES_PASSED);
        GLuint any = 0;
        glGetQueryObjectuiv(query_, GL_QUERY_RESULT, &any);
        // (without a fragment this layer's depth is the opaque depth: the
        // segment is then the last, up to the opaque geometry)
        segment(depth_[1 - cur], depth_[cur]);
        if (!any) {
            more = false;
            break;
        }
        under(false);
        cur = 1 - cur;
    }
    if (more && layers == max_layers) {
        // What lies behind the last layer: blended in drawing order (over,
        // premultiplied into the cleared layer), without depth writes.
        start_layer(depth_[cur]);
        glDepthMask(GL_FALSE);
        glEnable(GL_BLEND);
        glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
        draw(depth_[1 - cur]);
        glDisable(GL_BLEND);
        glDepthMask(GL_TRUE);
        // (the rest: what lies between the last layer and the opaque
        // depth, which this draw left in depth_[cur], then what it blended
        // in drawing order)
        segment(depth_[1 - cur], depth_[cur]);
        under(true);
        ++layers;
    }
    // The layers over the opaque picture.
    glBindFramebuffer(GL_FRAMEBUFFER, target_fbo);
    glViewport(0, 0, w, h);
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(over_->id);
    bind_sampler(*over_, "u_acc", 0, GL_TEXTURE_2D, acc_tex_);
    glBindVertexArray(empty_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDisable(GL_BLEND);
    glDepthMask(GL_TRUE);
    return layers;
}

}  // namespace hz::core::render
