// Painting annotations (annotations_paint.hpp).
#include "annotations_paint.hpp"

#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <mutex>

namespace hz::host {

namespace {

using core::render::Image;
using core::render::Mark;

// Dear ImGui's built-in font (ProggyClean, 13 px) as an alpha atlas and its
// glyphs, printable ASCII; read once.
struct Glyph {
    int x0, y0, x1, y1;  // its box from the pen, font pixels
    int u0, v0;          // its top left in the atlas
    float advance;
};
struct Font {
    std::vector<unsigned char> alpha;
    int width = 0, height = 0;
    Glyph glyphs[128]{};
};
const Font &font() {
    static Font f;
    static std::once_flag once;
    std::call_once(once, [] {
        ImGuiContext *previous = ImGui::GetCurrentContext();
        ImGuiContext *ctx = ImGui::CreateContext();
        ImFontAtlas &atlas = *ImGui::GetIO().Fonts;
        ImFont *font = atlas.AddFontDefault();
        unsigned char *alpha = nullptr;
        atlas.GetTexDataAsAlpha8(&alpha, &f.width, &f.height);
        f.alpha.assign(alpha, alpha + std::size_t(f.width) * f.height);
        for (int c = 32; c < 127; ++c) {
            const ImFontGlyph *g = font->FindGlyph(ImWchar(c));
            f.glyphs[c] = {int(std::lround(g->X0)),
                           int(std::lround(g->Y0)),
                           int(std::lround(g->X1)),
                           int(std::lround(g->Y1)),
                           int(std::lround(g->U0 * f.width)),
                           int(std::lround(g->V0 * f.height)),
                           g->AdvanceX};
        }
        ImGui::DestroyContext(ctx);
        if (previous) ImGui::SetCurrentContext(previous);
    });
    return f;
}

void blend(Image &im, int x, int y, const float *srgb, double a) {
    if (x < 0 || y < 0 || x >= im.width || y >= im.height || !(a > 0)) return;
    a = std::min(a, 1.0);
    std::uint8_t *p = &im.rgba[(std::size_t(y) * im.width + x) * 4];
    for (int i = 0; i < 3; ++i) p[i] = std::uint8_t(std::lround(p[i] * (1 - a) + std::clamp(double(srgb[i]), 0.0, 1.0) * 255.0 * a));
    p[3] = 255;
}

void paint_rect(Image &im, const Mark &m) {
    const int x0 = int(std::lround(std::min(m.x0, m.x1))), x1 = int(std::lround(std::max(m.x0, m.x1)));
    const int y0 = int(std::lround(std::min(m.y0, m.y1))), y1 = int(std::lround(std::max(m.y0, m.y1)));
    for (int y = std::max(y0, 0); y < std::min(y1, im.height); ++y)
        for (int x = std::max(x0, 0); x < std::min(x1, im.width); ++x) blend(im, x, y, m.srgba.data(), m.srgba[3]);
}

// Each pixel covered by its distance to the segment (a one-pixel ramp at the edge).
void paint_line(Image &im, const Mark &m) {
    const double hw = 0.5 * m.width, ax = m.x0, ay = m.y0, bx = m.x1, by = m.y1;
    const double dx = bx - ax, dy = by - ay, len2 = dx * dx + dy * dy;
    const int x0 = int(std::floor(std::min(ax, bx) - hw - 1)), x1 = int(std::ceil(std::max(ax, bx) + hw + 1));
    const int y0 = int(std::floor(std::min(ay, by) - hw - 1)), y1 = int(std::ceil(std::max(ay, by) + hw + 1));
    for (int y = std::max(y0, 0); y < std::min(y1, im.height); ++y)
        for (int x = std::max(x0, 0); x < std::min(x1, im.width); ++x) {
            const double px = x + 0.5, py = y + 0.5;
            const double t = len2 > 0 ? std::clamp(((px - ax) * dx + (py - ay) * dy) / len2, 0.0, 1.0) : 0.0;
            const double d = std::hypot(px - (ax + t * dx), py - (ay + t * dy));
            blend(im, x, y, m.srgba.data(), m.srgba[3] * std::clamp(hw + 0.5 - d, 0.0, 1.0));
        }
}

void paint_glyphs(Image &im, int x, int y, const std::string &text, int s, const float *srgb, double alpha) {
    const Font &f = font();
    double pen = 0;
    for (unsigned char c : text) {
        if (c < 32 || c > 126) c = '?';
        const Glyph &g = f.glyphs[c];
        for (int gy = g.y0; gy < g.y1; ++gy)
            for (int gx = g.x0; gx < g.x1; ++gx) {
                const double a = f.alpha[std::size_t(g.v0 + gy - g.y0) * f.width + std::size_t(g.u0 + gx - g.x0)] / 255.0;
                if (a <= 0) continue;
                for (int sy = 0; sy < s; ++sy)
                    for (int sx = 0; sx < s; ++sx) blend(im, x + int(std::lround(pen)) * s + gx * s + sx, y + gy * s + sy, srgb, a * alpha);
            }
        pen += g.advance;
    }
}

}  // namespace

int text_width(const std::string &text, int scale) {
    const Font &f = font();
    double w = 0;
    for (unsigned char c : text) w += f.glyphs[c < 32 || c > 126 ? '?' : c].advance;
    return int(std::ceil(w)) * scale;
}

void paint_text(Image &im, int x, int y, const std::string &text, int scale, const std::array<double, 3> &colour) {
    const float c[3] = {float(colour[0]), float(colour[1]), float(colour[2])};
    paint_glyphs(im, x, y, text, std::max(1, scale), c, 1.0);
}

void paint_marks(Image &im, const std::vector<Mark> &marks) {
    for (const Mark &m : marks) {
        if (m.kind == Mark::Kind::Rect) {
            paint_rect(im, m);
        } else if (m.kind == Mark::Kind::Line) {
            paint_line(im, m);
        } else {
            const int s = std::max(1, int(std::lround(m.scale)));
            const int w = text_width(m.text, s), h = int(core::render::kGlyphHeight) * s;
            paint_glyphs(im, int(std::lround(m.x0 - m.align * w)), int(std::lround(m.y0 - m.valign * h)), m.text, s, m.srgba.data(),
                         m.srgba[3]);
        }
    }
}

void paint_marks(ImDrawList *list, const std::vector<Mark> &marks, float x, float y) {
    const auto colour = [](const Mark &m) {
        return ImGui::ColorConvertFloat4ToU32(ImVec4(m.srgba[0], m.srgba[1], m.srgba[2], m.srgba[3]));
    };
    for (const Mark &m : marks) {
        if (m.kind == Mark::Kind::Rect) {
            list->AddRectFilled(ImVec2(x + m.x0, y + m.y0), ImVec2(x + m.x1, y + m.y1), colour(m));
        } else if (m.kind == Mark::Kind::Line) {
            list->AddLine(ImVec2(x + m.x0, y + m.y0), ImVec2(x + m.x1, y + m.y1), colour(m), m.width);
        } else {
            const float s = std::max(1.0f, std::round(m.scale));
            const float size = ImGui::GetFontSize() * s;
            const ImVec2 extent = ImGui::GetFont()->CalcTextSizeA(size, 1e9f, 0.0f, m.text.c_str());
            list->AddText(ImGui::GetFont(), size, ImVec2(x + m.x0 - m.align * extent.x, y + m.y0 - m.valign * extent.y), colour(m),
                          m.text.c_str());
        }
    }
}

}  // namespace hz::host
