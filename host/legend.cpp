// `render --legend`: the clusters a picture shows, listed over it (colour,
// name, size), in Dear ImGui's built-in bitmap font (ProggyClean), drawn on
// the CPU into the read-back image: no font library, no GL state.
#include "legend.hpp"

#include "annotations_paint.hpp"

#include <hz/core/render/renderer.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>

namespace hz::host {

namespace {

std::string with_commas(std::uint64_t n) {
    std::string s = std::to_string(n), out;
    for (std::size_t i = 0; i < s.size(); ++i) {
        if (i && (s.size() - i) % 3 == 0) out += ',';
        out += s[i];
    }
    return out;
}

}  // namespace

std::vector<LegendEntry> cluster_legend(const core::render::Scene &scene, std::size_t max_entries) {
    struct Cluster {
        double id = 0;
        std::uint64_t size = 0;
        std::string name;
    };
    std::vector<Cluster> all;
    for (const auto &ob : scene.objects) {
        if (!ob.visible || ob.kind != HZ_DATA_STREAMLINES || ob.coloring.mode != "cluster") continue;
        const core::Tractogram &t = ob.data.tractogram;
        const std::uint64_t N = t.nb_streamlines();
        const core::DataArray *ids = nullptr, *sizes = nullptr;
        for (const auto &a : t.arrays)
            if (a.attach == HZ_ATTACH_STREAMLINE && a.count == N && a.components == 1) {
                if (a.name == "cluster_id") ids = &a;
                if (a.name == "cluster_size") sizes = &a;
            }
        // Names saved by the window (the clusters' paths, by group index).
        std::vector<std::string> names;
        for (const auto &[k, v] : ob.data.metadata)
            if (k == "horizon_clusters") {
                const nlohmann::json j = nlohmann::json::parse(v, nullptr, false);
                if (j.is_array())
                    for (const auto &e : j) names.push_back(e.is_string() ? e.get<std::string>() : "");
            }
        std::map<double, Cluster> by_id;
        for (std::uint64_t s = 0; s < N; ++s) {
            const double id = ids ? core::value_at(ids->bytes.data() + s * core::dtype_size(ids->dtype), ids->dtype) : double(s);
            Cluster &c = by_id[id];
            c.id = id;
            c.size +=
                sizes ? std::uint64_t(std::max(0.0, core::value_at(sizes->bytes.data() + s * core::dtype_size(sizes->dtype), sizes->dtype)))
                      : 1;
            if (c.name.empty()) {
                if (id < 0)
                    c.name = "single streamlines";
                else if (std::size_t(id) < names.size() && id == std::floor(id))
                    c.name = names[std::size_t(id)];
            }
        }
        for (auto &[id, c] : by_id) all.push_back(std::move(c));
    }
    std::stable_sort(all.begin(), all.end(), [](const Cluster &a, const Cluster &b) { return a.size > b.size; });
    std::vector<LegendEntry> out;
    for (std::size_t k = 0; k < all.size() && k < max_entries; ++k) {
        LegendEntry e;
        e.srgb = core::render::cluster_palette(all[k].id);
        e.label = (all[k].name.empty() ? "cluster " + std::to_string(k + 1) : all[k].name) + "  " + with_commas(all[k].size) +
                  (all[k].size == 1 ? " streamline" : " streamlines");
        out.push_back(std::move(e));
    }
    if (all.size() > max_entries) {
        std::uint64_t rest = 0;
        for (std::size_t k = max_entries; k < all.size(); ++k) rest += all[k].size;
        out.push_back(
            {{-1, -1, -1}, "... " + std::to_string(all.size() - max_entries) + " more clusters, " + with_commas(rest) + " streamlines"});
    }
    return out;
}

void draw_legend(core::render::Image &im, const std::vector<LegendEntry> &entries) {
    if (entries.empty() || im.width <= 0 || im.height <= 0) return;
    const int s = im.width >= 1600 ? 2 : 1;  // (pixels per font pixel: larger pictures, larger text)
    const int font_px = int(core::render::kGlyphHeight);
    const int line = font_px * s + 4 * s, pad = 8 * s, swatch = font_px * s - 2 * s;
    int box_w = 0;
    for (const auto &e : entries) box_w = std::max(box_w, swatch + 6 * s + text_width(e.label, s));
    box_w = std::min(box_w + 2 * pad, im.width);
    const int box_h = std::min(int(entries.size()) * line + 2 * pad, im.height);
    const int x0 = 10 * s, y0 = 10 * s;
    std::vector<core::render::Mark> boxes;
    auto box = [&](int x, int y, int w, int h, std::array<float, 4> c) {
        core::render::Mark m;
        m.x0 = float(x), m.y0 = float(y), m.x1 = float(x + w), m.y1 = float(y + h), m.srgba = c;
        boxes.push_back(m);
    };
    box(x0, y0, box_w, box_h, {0, 0, 0, 0.55f});
    for (std::size_t k = 0; k < entries.size(); ++k)
        if (entries[k].srgb[0] >= 0)  // (the "more" line has no colour)
            box(x0 + pad, y0 + pad + int(k) * line + s, swatch, swatch,
                {float(entries[k].srgb[0]), float(entries[k].srgb[1]), float(entries[k].srgb[2]), 1.0f});
    paint_marks(im, boxes);
    for (std::size_t k = 0; k < entries.size(); ++k)
        paint_text(im, x0 + pad + swatch + 6 * s, y0 + pad + int(k) * line, entries[k].label, s, {0.95, 0.95, 0.95});
}

}  // namespace hz::host
