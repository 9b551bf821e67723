// Annotations over a picture (a scene's "annotations"): a colour bar for
// every object coloured through a colormap, an orientation triad, a scale
// bar. They are laid out here once, as 2D marks in the picture's pixels,
// and painted by whoever shows the picture: `horizon render` into the image
// it writes, the window over its frame (host/annotations_paint.hpp). Pure
// computation: no GL, any thread.
#pragma once

#include <hz/core/render/renderer.hpp>
#include <hz/core/render/scene.hpp>

#include <array>
#include <string>
#include <vector>

namespace hz::core::render {

// One 2D mark, in pixels of the picture (origin at its top left, y down).
struct Mark {
    enum class Kind { Rect, Line, Text };
    Kind kind = Kind::Rect;
    // Rect: its corners (x0, y0) - (x1, y1), filled. Line: its ends.
    // Text: its anchor (x0, y0).
    float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    std::array<float, 4> srgba{1, 1, 1, 1};  // sRGB colour, alpha (over what is below)
    float width = 1;                         // Line: pixels
    std::string text;                        // Text: printable ASCII
    float align = 0;                         // Text: 0 starts at x0, 0.5 centred on it, 1 ends at it
    float valign = 0;                        // Text: 0 top at y0, 0.5 centred, 1 bottom at y0
    float scale = 1;                         // Text: picture pixels per font pixel
    std::string role;                        // what it shows: "colour bar", "orientation R", "scale bar", ...
};

// The metrics of the painters' font (Dear ImGui's built-in ProggyClean, a
// fixed-width bitmap font) in font pixels: the layout sizes text boxes by them.
constexpr float kGlyphAdvance = 7.0f, kGlyphHeight = 13.0f;

// What a picture shows of its scene's annotations `a`: for each colour
// scale a vertical bar (colormap sampled at every row, its range's ends and
// middle as labels, the object and quantity as title), at the right edge;
// an orientation triad of the patient's axes (R, A, S and their opposites
// L, P, I) as camera `v` sees them, at the bottom left; a scale bar (a
// round length in mm, at the depth of the camera's target), at the bottom
// right. For a w x h picture; larger text from 1600 pixels wide.
std::vector<Mark> layout_annotations(const Annotations &a, const std::vector<ColourScale> &scales, const View &v, int w, int h);

// The scale bar's length for camera v and a picture h pixels high: the
// roundest length (1, 2 or 5 x 10^k mm) at most `max_px` pixels long at the
// target's depth, and its length in pixels.
std::pair<double, double> scale_bar_length(const View &v, int h, double max_px);

// A value for a label: at most 4 significant digits, no trailing zeros.
std::string format_value(double x);

}  // namespace hz::core::render
