// Annotations laid out as 2D marks (annotations.hpp).
#include <hz/core/render/annotations.hpp>

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace hz::core::render {

namespace {

using Srgba = std::array<float, 4>;
constexpr Srgba kPanel{0.0f, 0.0f, 0.0f, 0.55f};  // the dark box behind text
constexpr Srgba kInk{0.95f, 0.95f, 0.95f, 1.0f};

Mark rect(float x0, float y0, float x1, float y1, Srgba c, std::string role) {
    Mark m;
    m.kind = Mark::Kind::Rect;
    m.x0 = x0, m.y0 = y0, m.x1 = x1, m.y1 = y1, m.srgba = c, m.role = std::move(role);
    return m;
}
Mark line(float x0, float y0, float x1, float y1, float width, Srgba c, std::string role) {
    Mark m = rect(x0, y0, x1, y1, c, std::move(role));
    m.kind = Mark::Kind::Line;
    m.width = width;
    return m;
}
Mark text(float x, float y, std::string s, float align, float valign, float scale, Srgba c, std::string role) {
    Mark m = rect(x, y, x, y, c, std::move(role));
    m.kind = Mark::Kind::Text;
    m.text = std::move(s), m.align = align, m.valign = valign, m.scale = scale;
    return m;
}
float text_width(const std::string &s, float scale) { return float(s.size()) * kGlyphAdvance * scale; }

// The camera's right, up and back (towards the eye) unit vectors.
struct Basis {
    glm::dvec3 right, up, back;
};
Basis basis_of(const View &v) {
    const glm::dvec3 eye(v.eye[0], v.eye[1], v.eye[2]), target(v.target[0], v.target[1], v.target[2]);
    Basis b;
    b.back = glm::normalize(eye - target);
    glm::dvec3 up(v.up[0], v.up[1], v.up[2]);
    if (glm::length(glm::cross(up, b.back)) < 1e-9) up = std::abs(b.back.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(0, 1, 0);
    b.right = glm::normalize(glm::cross(up, b.back));
    b.up = glm::cross(b.back, b.right);
    return b;
}

void colour_bars(const std::vector<ColourScale> &scales, float s, int w, int h, std::vector<Mark> &out) {
    const float bar_w = 14 * s, pad = 6 * s, gap = 10 * s;
    const float bar_h = std::floor(std::clamp(0.4f * float(h), std::min(60 * s, float(h) / 2), std::max(float(h) - 80 * s, 1.0f)));
    const float top = 12 * s + kGlyphHeight * s + pad;  // (the title above)
    float right = float(w) - 12 * s;
    for (const ColourScale &c : scales) {
        const double lo = c.range[0], hi = c.range[1];
        const std::string labels[3] = {format_value(hi), format_value(0.5 * (lo + hi)), format_value(lo)};
        float label_w = 0;
        for (const auto &l : labels) label_w = std::max(label_w, text_width(l, s));
        std::string title = c.quantity.empty() ? c.object : c.object + ": " + c.quantity;
        if (title.size() > 32) title = title.substr(0, 31) + "~";
        const float bar_x1 = right - pad, bar_x0 = bar_x1 - bar_w;
        const float left = std::min(bar_x0 - 8 * s - label_w - pad, right - text_width(title, s) - 2 * pad);
        out.push_back(rect(left, top - kGlyphHeight * s - 2 * pad, right, top + bar_h + pad, kPanel, "colour bar panel"));
        out.push_back(text(right - pad, top - pad, title, 1.0f, 1.0f, s, kInk, "colour bar title"));
        // One row per pixel, the colormap at its centre: the top row is the
        // range's upper end.
        for (int r = 0; r < int(bar_h); ++r) {
            const double t = 1.0 - (r + 0.5) / bar_h;
            const auto m = colormap(c.colormap, t);
            out.push_back(rect(bar_x0, top + float(r), bar_x1, top + float(r + 1), {m[0], m[1], m[2], 1.0f}, "colour bar"));
        }
        for (int k = 0; k < 3; ++k) {
            const float y = top + (k == 0 ? 0.5f : k == 1 ? 0.5f * bar_h : bar_h - 0.5f);
            out.push_back(line(bar_x0 - 4 * s, y, bar_x0, y, s, kInk, "colour bar tick"));
            out.push_back(text(bar_x0 - 6 * s, y, labels[k], 1.0f, 0.5f, s, kInk, "colour bar label"));
        }
        right = left - gap;
        if (right < float(w) / 2) break;  // (no more than half the picture)
    }
}

void orientation(const View &v, float s, int h, std::vector<Mark> &out) {
    const Basis b = basis_of(v);
    const float L = 30 * s, cx = 16 * s + L + kGlyphAdvance * s, cy = float(h) - 16 * s - L - kGlyphHeight * s;
    struct End {
        glm::dvec3 axis;
        const char *letter;
        Srgba colour;
    };
    // RAS+: the direction colouring's convention (x red, y green, z blue);
    // the opposite ends grey.
    const End ends[6] = {{{1, 0, 0}, "R", {1.0f, 0.35f, 0.3f, 1}}, {{0, 1, 0}, "A", {0.35f, 0.9f, 0.35f, 1}},
                         {{0, 0, 1}, "S", {0.45f, 0.6f, 1.0f, 1}}, {{-1, 0, 0}, "L", {0.7f, 0.7f, 0.7f, 1}},
                         {{0, -1, 0}, "P", {0.7f, 0.7f, 0.7f, 1}}, {{0, 0, -1}, "I", {0.7f, 0.7f, 0.7f, 1}}};
    out.push_back(rect(cx - L - kGlyphAdvance * s - 8 * s, cy - L - kGlyphHeight * s - 6 * s, cx + L + kGlyphAdvance * s + 8 * s,
                       cy + L + kGlyphHeight * s + 6 * s, kPanel, "orientation panel"));
    int order[6] = {0, 1, 2, 3, 4, 5};  // farthest first: the nearer drawn over
    std::sort(order, order + 6, [&](int i, int j) { return glm::dot(ends[i].axis, b.back) < glm::dot(ends[j].axis, b.back); });
    for (int i : order) {
        const End &e = ends[i];
        const float dx = float(glm::dot(e.axis, b.right)), dy = float(-glm::dot(e.axis, b.up));
        const bool positive = i < 3;
        out.push_back(line(cx, cy, cx + dx * L, cy + dy * L, positive ? 2 * s : s, e.colour, std::string("orientation axis ") + e.letter));
        const float lx = cx + dx * (L + 6 * s), ly = cy + dy * (L + 6 * s);
        out.push_back(text(lx, ly, e.letter, 0.5f, 0.5f, s, e.colour, std::string("orientation ") + e.letter));
    }
}

void scale_bar(const View &v, float s, int w, int h, std::vector<Mark> &out) {
    const auto [mm, px] = scale_bar_length(v, h, 0.2 * w);
    if (!(mm > 0) || px < 4) return;
    const std::string label = format_value(mm) + " mm";
    const float x1 = float(w) - 16 * s, x0 = x1 - float(px), y = float(h) - 16 * s;
    const float lw = std::max(float(px), text_width(label, s));
    out.push_back(rect(x1 - lw - 8 * s, y - kGlyphHeight * s - 14 * s, x1 + 8 * s, y + 8 * s, kPanel, "scale bar panel"));
    out.push_back(rect(x0, y - 3 * s, x1, y, kInk, "scale bar"));
    out.push_back(text(0.5f * (x0 + x1), y - 7 * s, label, 0.5f, 1.0f, s, kInk, "scale bar label"));
}

}  // namespace

std::string format_value(double x) {
    if (!std::isfinite(x)) return std::isnan(x) ? "nan" : x > 0 ? "inf" : "-inf";
    if (x == 0) return "0";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.4g", x);
    return buf;
}

std::pair<double, double> scale_bar_length(const View &v, int h, double max_px) {
    const glm::dvec3 eye(v.eye[0], v.eye[1], v.eye[2]), target(v.target[0], v.target[1], v.target[2]);
    const double dist = glm::length(eye - target);
    const double mm_per_px = 2.0 * dist * std::tan(glm::radians(v.fov_deg) / 2) / std::max(h, 1);
    if (!(mm_per_px > 0) || !std::isfinite(mm_per_px) || !(max_px > 0)) return {0, 0};
    const double most = max_px * mm_per_px;
    double mm = std::pow(10.0, std::floor(std::log10(most)));
    for (double f : {5.0, 2.0})
        if (mm * f <= most) {
            mm *= f;
            break;
        }
    return {mm, mm / mm_per_px};
}

std::vector<Mark> layout_annotations(const Annotations &a, const std::vector<ColourScale> &scales, const View &v, int w, int h) {
    std::vector<Mark> out;
    if (w <= 0 || h <= 0) return out;
    const float s = w >= 1600 ? 2.0f : 1.0f;
    if (a.colour_bar && !scales.empty()) colour_bars(scales, s, w, h, out);
    if (a.orientation) orientation(v, s, h, out);
    if (a.scale_bar) scale_bar(v, s, w, h, out);
    return out;
}

}  // namespace hz::core::render
