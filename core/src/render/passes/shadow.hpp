// Shadows of the key light as a pass of the frame (private to the
// renderer): before the scene is drawn, the depth of every opaque caster as
// the key light sees it (a shadow map, Williams 1978), which the lit
// programs then read (HZ_SHADOW in glsl.hpp) to know whether the key light
// reaches a point.
//
// The key light is the first directional light of the frame (the default
// rig's key): its shadow map is an orthographic view along its direction of
// the sphere around the visible objects' box, so that the map's scale does
// not change while the camera (and a camera-space light) turns. Casters are
// the opaque surfaces, lines and tubes (not the slices, which show data and
// neither cast nor receive; not translucent objects, which receive only).
// Receivers compare their depth, moved towards the light by a bias that
// grows with the slope of their surface or line to the light (a line has no
// surface: the map holds its own depth), through a filter of `softness_mm`
// (percentage-closer filtering: 12 taps on a disc and the hardware's
// bilinear comparison), so that shadow edges are soft and without stairs.
//
// Threading: the GL context's thread.
#pragma once

#include "../gl.hpp"
#include "../gpu_object.hpp"

#include <hz/core/data.hpp>

#include <glm/glm.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace hz::core::render {

// The light's view of a scene: an orthographic projection of the sphere
// around `box`, seen along -to_light.
struct ShadowView {
    glm::dmat4 view_proj{1.0};  // world mm -> the light's clip space
    glm::dvec3 to_light{0, 0, 1};
    glm::dvec3 eye{0, 0, 1}, target{0, 0, 0};  // (for ordering bricks nearest the light first)
    double extent_mm = 1;                      // the side of the square the map covers
};

// The view for a directional light towards `to_light` (unit) of the
// scene's box (not empty).
ShadowView fit_shadow_view(const glm::dvec3 &to_light, const Bounds &box);

struct ShadowParams {
    double strength = 0.75;    // 0: no darkening; 1: the key light fully blocked
    double softness_mm = 0.5;  // the filter's radius
};

class ShadowPass {
public:
    using MakeProgram = std::function<std::unique_ptr<Program>(const std::string &vs, const std::string &gs, const std::string &fs,
                                                               const std::string &what)>;
    explicit ShadowPass(MakeProgram make);
    ~ShadowPass();
    ShadowPass(const ShadowPass &) = delete;
    ShadowPass &operator=(const ShadowPass &) = delete;

    // Makes the `size` x `size` map for `view`, binds it as the draw target
    // (depth only, cleared, depth test on, polygon offset for the triangles
    // drawn) for the casters, which the caller then draws with caster().
    // Throws Error if the driver cannot make the target.
    void begin(const ShadowView &view, int size);
    // Binds the map drawn last as the draw target again, to draw more
    // casters into it (not cleared), in begin()'s state.
    void resume();
    // Ends the casters: restores the state begin() changed, except the
    // framebuffer and viewport, which the caller sets.
    void end();
    // The depth-only program of a caster of geometry `g` (Mesh, Line or
    // Tube), compiled on first use: its hz_view_proj, hz_eye and hz_clip
    // the caller sets.
    Program &caster(Geom g);

    // Points the lit program `p` (compiled with HZ_SHADOW) at the map drawn
    // last, on texture unit `unit`.
    void bind(Program &p, int unit, const ShadowParams &params) const;

    const ShadowView &view() const { return view_; }
    int size() const { return size_; }
    // The map's depths in [0, 1] (1: nothing), rows bottom to top: for the
    // tests. Reads back; slow.
    std::vector<float> read() const;

private:
    MakeProgram make_;
    std::unique_ptr<Program> casters_[3];
    GLuint fbo_ = 0, tex_ = 0;
    int size_ = 0;
    ShadowView view_;
};

}  // namespace hz::core::render
