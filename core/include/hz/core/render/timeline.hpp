// Playing a scene's timeline (Scene::timeline, docs/scene-format.md): the
// state of the camera and of the objects at any time, for `horizon movie`
// (every frame) and `horizon render --time` (one instant).
//
// The scene as written is the state at time 0 (a keyframe at 0 replaces
// what it sets). Each value (the camera; an object's visibility, its
// opacity, each material parameter, each slice position, a volume's
// window) goes from one keyframe that
// sets it to the next that sets it: numbers interpolate over the span (its
// fraction eased by smoothstep, or linear), visibility and a slice that
// appears or disappears change at the later keyframe; after the last
// keyframe that sets it, a value holds. The camera's target moves on the
// line between the two, the eye's offset from it turns on the great circle
// between the two directions while its length interpolates, the up vector
// turns likewise (kept perpendicular to the view), the field of view
// interpolates. A turntable then turns the camera about the superior axis
// through its target, in proportion to time.
#pragma once

#include <hz/core/render/renderer.hpp>
#include <hz/core/render/scene.hpp>

#include <array>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace hz::core::render {

struct ObjectState {
    bool visible = true;
    double opacity = 1.0;
    std::optional<std::array<double, 2>> window;        // a volume's window (nullopt: not a volume)
    std::map<std::string, std::vector<double>> params;  // the material parameters a timeline sets
    std::array<std::optional<double>, 3> slices;        // slice positions, RAS+ mm (nullopt: hidden)
};

struct TimelineState {
    View view;
    std::vector<ObjectState> objects;  // one per scene object
};

// The state at time 0 of `scene` seen from `view`: each object's
// visibility, opacity, material parameters and slices as the scene has
// them, a slice position of NaN (the volume's centre) replaced by
// centre(object, axis), its window window(object) (the one the renderer
// found for a volume whose scene sets none; nullopt for other objects).
TimelineState timeline_start(const Scene &scene, const View &view, const std::function<double(std::size_t, int)> &centre,
                             const std::function<std::optional<std::array<double, 2>>(std::size_t)> &window);

// Each keyframe's camera as a view (fit_view of the scene at `aspect`);
// nullopt for keyframes without a camera.
std::vector<std::optional<View>> keyframe_views(const Scene &scene, const Timeline &tl, double aspect);

// The state at time `t` (seconds; clamped to [0, duration]).
TimelineState timeline_at(const Timeline &tl, const TimelineState &start, const std::vector<std::optional<View>> &key_views, double t);

// The view a fraction `s` (0..1) of the way from `a` to `b` (the rule above).
View interpolate_views(const View &a, const View &b, double s);

// `v` turned by `deg` degrees about the superior (z) axis through its target.
View turn_view(const View &v, double deg);

}  // namespace hz::core::render
