// Timelines: the state of a scene at a time (timeline.hpp).
#include <hz/core/render/timeline.hpp>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>

namespace hz::core::render {

namespace {

glm::dvec3 to_glm(const Vec3 &v) { return {v[0], v[1], v[2]}; }
Vec3 to_vec3(const glm::dvec3 &v) { return {v.x, v.y, v.z}; }

// Unit vectors p, q: the point a fraction s along the shorter great circle
// between them (their half-way normal where they are opposite).
glm::dvec3 slerp(const glm::dvec3 &p, const glm::dvec3 &q, double s, const glm::dvec3 &fallback_axis) {
    const double c = std::clamp(glm::dot(p, q), -1.0, 1.0);
    const double angle = std::acos(c);
    if (angle < 1e-9) return p;
    glm::dvec3 perp;
    if (std::abs(angle - M_PI) < 1e-6) {  // (opposite: turn about the fallback axis)
        perp = glm::cross(fallback_axis, p);
        if (glm::length(perp) < 1e-9) perp = glm::cross(glm::dvec3(1, 0, 0), p);
        perp = glm::normalize(perp);
    } else {
        perp = glm::normalize(q - c * p);
    }
    return std::cos(s * angle) * p + std::sin(s * angle) * perp;
}

double ease(bool smooth, double u) { return smooth ? u * u * (3.0 - 2.0 * u) : u; }

// Over keyframes that set a value (`has`), where time t falls: the last at
// or before t (or -1: before them all) and the next after it (or -1).
template <class Has>
std::pair<int, int> span(const Timeline &tl, double t, Has has) {
    int before = -1, after = -1;
    for (int k = 0; k < int(tl.keyframes.size()); ++k) {
        if (!has(tl.keyframes[std::size_t(k)])) continue;
        if (tl.keyframes[std::size_t(k)].time <= t)
            before = k;
        else if (after < 0)
            after = k;
    }
    return {before, after};
}

}  // namespace

View turn_view(const View &v, double deg) {
    const glm::dmat4 R = glm::rotate(glm::dmat4(1.0), glm::radians(deg), glm::dvec3(0, 0, 1));
    const glm::dvec3 t = to_glm(v.target), e = to_glm(v.eye), u = to_glm(v.up);
    View out = v;
    out.eye = to_vec3(t + glm::dvec3(R * glm::dvec4(e - t, 0.0)));
    out.up = to_vec3(glm::dvec3(R * glm::dvec4(u, 0.0)));
    return out;
}

View interpolate_views(const View &va, const View &vb, double s) {
    const glm::dvec3 ta = to_glm(va.target), tb = to_glm(vb.target);
    const glm::dvec3 da = to_glm(va.eye) - ta, db = to_glm(vb.eye) - tb;
    const double la = glm::length(da), lb = glm::length(db);
    const glm::dvec3 ua = glm::normalize(to_glm(va.up)), ub = glm::normalize(to_glm(vb.up));
    View v = va;
    const glm::dvec3 target = ta + s * (tb - ta);
    const glm::dvec3 dir = slerp(da / la, db / lb, s, ua);
    glm::dvec3 up = slerp(ua, ub, s, dir);
    up = up - glm::dot(up, dir) * dir;  // (perpendicular to the view)
    if (glm::length(up) < 1e-9) up = ua;
    v.target = to_vec3(target);
    v.eye = to_vec3(target + (la + s * (lb - la)) * dir);
    v.up = to_vec3(glm::normalize(up));
    v.fov_deg = va.fov_deg + s * (vb.fov_deg - va.fov_deg);
    v.near_mm = std::min(va.near_mm, vb.near_mm);
    v.far_mm = std::max(va.far_mm, vb.far_mm);
    return v;
}

TimelineState timeline_start(const Scene &scene, const View &view, const std::function<double(std::size_t, int)> &centre,
                             const std::function<std::optional<std::array<double, 2>>(std::size_t)> &window) {
    TimelineState st;
    st.view = view;
    for (std::size_t i = 0; i < scene.objects.size(); ++i) {
        const Object &o = scene.objects[i];
        ObjectState os;
        os.visible = o.visible;
        os.opacity = o.opacity;
        os.window = window(i);
        os.params = o.material.params;
        const std::optional<double> p[3] = {o.slice_x, o.slice_y, o.slice_z};
        for (int k = 0; k < 3; ++k) {
            os.slices[std::size_t(k)] = p[k];
            if (p[k] && std::isnan(*p[k])) os.slices[std::size_t(k)] = centre(i, k);
        }
        st.objects.push_back(std::move(os));
    }
    return st;
}

std::vector<std::optional<View>> keyframe_views(const Scene &scene, const Timeline &tl, double aspect) {
    std::vector<std::optional<View>> out;
    for (const Keyframe &k : tl.keyframes) out.push_back(k.camera ? std::optional<View>(fit_view(scene, *k.camera, aspect)) : std::nullopt);
    return out;
}

TimelineState timeline_at(const Timeline &tl, const TimelineState &start, const std::vector<std::optional<View>> &key_views, double t) {
    t = std::clamp(t, 0.0, tl.duration);
    TimelineState st = start;
    // The fraction of the way from keyframe `b` (or time 0, b < 0) to `n`, eased.
    auto fraction = [&](int b, int n) {
        const double t0 = b < 0 ? 0.0 : tl.keyframes[std::size_t(b)].time, t1 = tl.keyframes[std::size_t(n)].time;
        return ease(tl.smooth, t1 > t0 ? std::clamp((t - t0) / (t1 - t0), 0.0, 1.0) : 1.0);
    };
    // The camera.
    {
        auto [b, n] = span(tl, t, [](const Keyframe &k) { return k.camera.has_value(); });
        const View from = b < 0 ? start.view : *key_views[std::size_t(b)];
        st.view = n < 0 ? from : interpolate_views(from, *key_views[std::size_t(n)], fraction(b, n));
    }
    if (tl.turntable_deg != 0) st.view = turn_view(st.view, tl.turntable_deg * t / tl.duration);
    // Each object's values.
    for (std::size_t i = 0; i < st.objects.size(); ++i) {
        ObjectState &os = st.objects[i];
        const ObjectState &s0 = start.objects[i];
        auto key_of = [&](const Keyframe &k) -> const ObjectKey * {
            const auto it = k.objects.find(i);
            return it == k.objects.end() ? nullptr : &it->second;
        };
        {
            auto [b, n] = span(tl, t, [&](const Keyframe &k) { return key_of(k) && key_of(k)->visible; });
            if (b >= 0) os.visible = *key_of(tl.keyframes[std::size_t(b)])->visible;
        }
        for (int ax = 0; ax < 3; ++ax) {
            auto has = [&](const Keyframe &k) { return key_of(k) && key_of(k)->slices[std::size_t(ax)].has_value(); };
            auto [b, n] = span(tl, t, has);
            const std::optional<double> from =
                b < 0 ? s0.slices[std::size_t(ax)] : *key_of(tl.keyframes[std::size_t(b)])->slices[std::size_t(ax)];
            os.slices[std::size_t(ax)] = from;
            if (n >= 0) {
                const std::optional<double> to = *key_of(tl.keyframes[std::size_t(n)])->slices[std::size_t(ax)];
                if (from && to) os.slices[std::size_t(ax)] = *from + fraction(b, n) * (*to - *from);
            }
        }
        // Opacity and window: numbers, interpolated as the slices are.
        {
            auto [b, n] = span(tl, t, [&](const Keyframe &k) { return key_of(k) && key_of(k)->opacity; });
            const double from = b < 0 ? s0.opacity : *key_of(tl.keyframes[std::size_t(b)])->opacity;
            os.opacity = n < 0 ? from : from + fraction(b, n) * (*key_of(tl.keyframes[std::size_t(n)])->opacity - from);
        }
        {
            auto [b, n] = span(tl, t, [&](const Keyframe &k) { return key_of(k) && key_of(k)->window; });
            const std::optional<std::array<double, 2>> from = b < 0 ? s0.window : key_of(tl.keyframes[std::size_t(b)])->window;
            os.window = from;
            if (n >= 0 && from) {
                const std::array<double, 2> &to = *key_of(tl.keyframes[std::size_t(n)])->window;
                const double f = fraction(b, n);
                os.window = std::array<double, 2>{(*from)[0] + f * (to[0] - (*from)[0]), (*from)[1] + f * (to[1] - (*from)[1])};
            }
        }
        // Material parameters: those any keyframe sets for this object.
        std::vector<std::string> names;
        for (const Keyframe &k : tl.keyframes)
            if (const ObjectKey *ok = key_of(k))
                for (const auto &[name, v] : ok->params) names.push_back(name);
        std::sort(names.begin(), names.end());
        names.erase(std::unique(names.begin(), names.end()), names.end());
        for (const std::string &name : names) {
            auto has = [&](const Keyframe &k) { return key_of(k) && key_of(k)->params.count(name); };
            auto [b, n] = span(tl, t, has);
            const auto s0p = s0.params.find(name);
            std::vector<double> from = b >= 0 ? key_of(tl.keyframes[std::size_t(b)])->params.at(name)
                                              : (s0p != s0.params.end() ? s0p->second : std::vector<double>{});
            if (n >= 0) {
                const std::vector<double> &to = key_of(tl.keyframes[std::size_t(n)])->params.at(name);
                if (from.size() == to.size()) {
                    const double f = fraction(b, n);
                    for (std::size_t c = 0; c < from.size(); ++c) from[c] += f * (to[c] - from[c]);
                } else if (from.empty()) {
                    from = to;
                }
            }
            if (!from.empty()) os.params[name] = from;
        }
    }
    return st;
}

}  // namespace hz::core::render
