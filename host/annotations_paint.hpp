// Painting the annotations' 2D marks (core/render/annotations.hpp): into a
// read-back picture on the CPU (`horizon render`), or into a Dear ImGui draw
// list over the window's frame. Both in Dear ImGui's built-in bitmap font.
#pragma once

#include <hz/core/render/annotations.hpp>
#include <hz/core/render/renderer.hpp>

#include <array>
#include <string>
#include <vector>

struct ImDrawList;

namespace hz::host {

// Paints `marks` over `im` (sRGB RGBA8, rows top first), in order, each
// blended over what is below by its alpha; lines with anti-aliased edges.
void paint_marks(core::render::Image &im, const std::vector<core::render::Mark> &marks);

// The same into `list` (the window's background draw list: over the frame,
// under the panel), the picture's top left at (x, y) of the draw list.
void paint_marks(ImDrawList *list, const std::vector<core::render::Mark> &marks, float x = 0, float y = 0);

// Text on the CPU: `text` (printable ASCII) over `im` with its top left at
// (x, y), `scale` picture pixels per font pixel, sRGB `colour` by the
// glyphs' coverage. The font's glyphs are read once per process.
void paint_text(core::render::Image &im, int x, int y, const std::string &text, int scale, const std::array<double, 3> &colour);
// Its width in pixels.
int text_width(const std::string &text, int scale);

}  // namespace hz::host
