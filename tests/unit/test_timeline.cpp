// Timelines (core/render/timeline.hpp): the camera between two keyframes
// (its target on the line, its offset's direction on the great circle, its
// length and field of view interpolated, up perpendicular), a turntable,
// and each object's values: the scene's at 0, eased or linear spans,
// visibility and hidden slices as steps, values held after their last key;
// opacity and a volume's window interpolated likewise.
#include <hz/core/render/timeline.hpp>

#include <catch2/catch.hpp>

#include <cmath>

using namespace hz::core;
using namespace hz::core::render;

namespace {

double dot(const Vec3 &a, const Vec3 &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm(const Vec3 &a) { return std::sqrt(dot(a, a)); }
Vec3 sub(const Vec3 &a, const Vec3 &b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }

View view(Vec3 eye, Vec3 target, Vec3 up, double fov = 30) {
    View v;
    v.eye = eye, v.target = target, v.up = up, v.fov_deg = fov;
    return v;
}

}  // namespace

TEST_CASE("timeline cameras: target on the line, offset on the great circle, up perpendicular", "[timeline]") {
    const View a = view({100, 0, 0}, {0, 0, 0}, {0, 0, 1}, 30), b = view({10, 200, 0}, {10, 0, 0}, {0, 0, 1}, 50);
    CHECK(interpolate_views(a, b, 0).eye == a.eye);
    const View e = interpolate_views(a, b, 1);
    for (int k = 0; k < 3; ++k) CHECK(e.eye[std::size_t(k)] == Approx(b.eye[std::size_t(k)]).margin(1e-9));
    const View m = interpolate_views(a, b, 0.5);
    CHECK(m.target[0] == Approx(5));
    const Vec3 d = sub(m.eye, m.target);
    CHECK(norm(d) == Approx(150));                        // (100 and 200)
    CHECK(d[0] / norm(d) == Approx(std::cos(M_PI / 4)));  // (half of the quarter turn from +x to +y)
    CHECK(d[1] / norm(d) == Approx(std::sin(M_PI / 4)));
    CHECK(m.fov_deg == Approx(40));
    CHECK(dot(m.up, d) == Approx(0).margin(1e-9));
    CHECK(norm(m.up) == Approx(1));
    // Ups that do not turn with the view: kept perpendicular to it.
    const View tilted = interpolate_views(view({0, -100, 0}, {0, 0, 0}, {0.7071, 0, 0.7071}), view({100, 0, 0}, {0, 0, 0}, {0, 0, 1}), 0.5);
    CHECK(dot(tilted.up, sub(tilted.eye, tilted.target)) == Approx(0).margin(1e-9));
    CHECK(tilted.up[2] > 0.9);
    // Opposite directions: a half turn about the up vector, not through the target.
    const View c = view({-100, 0, 0}, {0, 0, 0}, {0, 0, 1});
    const View h = interpolate_views(a, c, 0.5);
    CHECK(norm(sub(h.eye, h.target)) == Approx(100));
    CHECK(std::abs(h.eye[2]) < 1e-6);
    // A turntable: about z through the target.
    const View t = turn_view(view({20, 0, 5}, {10, 0, 0}, {0, 0, 1}), 90);
    CHECK(t.eye[0] == Approx(10));
    CHECK(t.eye[1] == Approx(10));
    CHECK(t.eye[2] == Approx(5));
}

TEST_CASE("timeline values: the scene's at 0, spans eased or linear, steps, held after the last key", "[timeline]") {
    Timeline tl;
    tl.duration = 10;
    tl.smooth = false;
    Keyframe k2, k4, k8;
    k2.time = 2, k4.time = 4, k8.time = 8;
    ObjectKey o2, o4, o8;
    o2.params["sheen"] = {1.0};
    o2.visible = false;
    o2.slices[2] = std::optional<double>(20.0);
    o4.slices[2] = std::optional<double>();  // (hidden from 4 s)
    o4.visible = true;
    o8.params["sheen"] = {0.5};
    o8.slices[2] = std::optional<double>(-10.0);
    k2.objects[0] = o2, k4.objects[0] = o4, k8.objects[0] = o8;
    tl.keyframes = {k2, k4, k8};
    TimelineState start;
    start.view = view({0, -100, 0}, {0, 0, 0}, {0, 0, 1});
    ObjectState s0;
    s0.visible = true;
    s0.params["sheen"] = {0.0};
    s0.slices = {std::nullopt, std::nullopt, 0.0};
    start.objects = {s0};
    const std::vector<std::optional<View>> views(3);
    auto at = [&](double t) { return timeline_at(tl, start, views, t).objects[0]; };
    CHECK(at(0).params.at("sheen")[0] == Approx(0.0));
    CHECK(at(1).params.at("sheen")[0] == Approx(0.5));  // (linear from the scene's 0 at 0 s to 1 at 2 s)
    CHECK(at(5).params.at("sheen")[0] == Approx(1.0 - 0.5 * 3 / 6));
    CHECK(at(9).params.at("sheen")[0] == Approx(0.5));  // (held)
    CHECK(at(1).visible);
    CHECK_FALSE(at(2).visible);
    CHECK_FALSE(at(3.9).visible);
    CHECK(at(4).visible);
    CHECK(*at(1).slices[2] == Approx(10));
    CHECK(*at(3).slices[2] == Approx(20));  // (hidden at 4: held until then)
    CHECK_FALSE(at(4).slices[2].has_value());
    CHECK_FALSE(at(7.9).slices[2].has_value());
    CHECK(*at(8).slices[2] == Approx(-10));
    CHECK_FALSE(at(5).slices[0].has_value());  // (never keyed: the scene's)
    tl.smooth = true;
    CHECK(at(0.5).params.at("sheen")[0] == Approx(0.25 * 0.25 * (3 - 0.5)));  // (smoothstep of a quarter)
    CHECK(at(1).params.at("sheen")[0] == Approx(0.5));
    // The camera: the scene's at 0, the keyframe's from its time; a turntable over the duration.
    Keyframe cam;
    cam.time = 5;
    cam.camera = Camera{};
    tl.keyframes = {cam};
    tl.smooth = false;
    const std::vector<std::optional<View>> kv{view({100, 0, 0}, {0, 0, 0}, {0, 0, 1})};
    const View v = timeline_at(tl, start, kv, 2.5).view;
    CHECK(v.eye[0] == Approx(100 * std::cos(M_PI / 4)));
    CHECK(v.eye[1] == Approx(-100 * std::sin(M_PI / 4)));
    CHECK(timeline_at(tl, start, kv, 10).view.eye[0] == Approx(100));
    tl.turntable_deg = 90;
    const View turned = timeline_at(tl, start, kv, 10).view;
    CHECK(turned.eye[0] == Approx(0).margin(1e-9));
    CHECK(turned.eye[1] == Approx(100));
}

TEST_CASE("timeline opacity and window: interpolated from the scene's, held after the last key", "[timeline]") {
    Timeline tl;
    tl.duration = 10;
    tl.smooth = false;
    Keyframe k2, k6;
    k2.time = 2, k6.time = 6;
    ObjectKey o2, o6;
    o2.opacity = 0.2;
    o2.window = std::array<double, 2>{100, 300};
    o6.opacity = 1.0;
    k2.objects[0] = o2, k6.objects[0] = o6;
    tl.keyframes = {k2, k6};
    TimelineState start;
    start.view = view({0, -100, 0}, {0, 0, 0}, {0, 0, 1});
    ObjectState s0;
    s0.opacity = 0.6;
    s0.window = std::array<double, 2>{0, 1000};
    ObjectState plain;  // (an object that is not a volume: no window)
    start.objects = {s0, plain};
    const std::vector<std::optional<View>> views(2);
    auto at = [&](double t) { return timeline_at(tl, start, views, t).objects[0]; };
    CHECK(at(0).opacity == Approx(0.6));
    CHECK(at(1).opacity == Approx(0.4));  // (half-way from 0.6 to 0.2)
    CHECK(at(4).opacity == Approx(0.6));  // (half-way from 0.2 to 1)
    CHECK(at(9).opacity == Approx(1.0));
    CHECK((*at(1).window)[0] == Approx(50));
    CHECK((*at(1).window)[1] == Approx(650));
    CHECK((*at(5).window)[1] == Approx(300));  // (its last key at 2 s: held)
    tl.smooth = true;
    CHECK(at(0.5).opacity == Approx(0.6 - 0.4 * 0.25 * 0.25 * (3 - 0.5)));
    CHECK_FALSE(timeline_at(tl, start, views, 1).objects[1].window.has_value());
    CHECK(timeline_at(tl, start, views, 1).objects[1].opacity == Approx(1.0));
}
