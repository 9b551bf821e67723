// A colour legend of the clusters a picture shows (`render --legend`).
#pragma once

#include <hz/core/render/scene.hpp>
#include <hz/core/render/renderer.hpp>

#include <array>
#include <string>
#include <vector>

namespace hz::host {

struct LegendEntry {
    std::array<double, 3> srgb;  // the cluster's colour (0..1); negative: a line without a swatch
    std::string label;           // its name (a path the window saved, or "cluster K") and size
};

// One entry per cluster of the visible streamlines coloured by cluster
// (scene clustering's centroids, a selection the window saved), largest
// first; beyond `max_entries`, one line for the rest.
std::vector<LegendEntry> cluster_legend(const core::render::Scene &scene, std::size_t max_entries = 24);
// Draws the entries over the top left of `im` (sRGB RGBA8): a dark box, a
// swatch and a line of text each (Dear ImGui's built-in font; twice as
// large on pictures 1600 pixels wide or more).
void draw_legend(core::render::Image &im, const std::vector<LegendEntry> &entries);

}  // namespace hz::host
