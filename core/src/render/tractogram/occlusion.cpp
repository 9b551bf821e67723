#include "occlusion.hpp"

#include <glm/vec4.hpp>

#include <algorithm>
#include <cmath>

namespace hz::core::render {

void DepthTiles::build(const float *depth, int w, int h) {
    w_ = w, h_ = h;
    tx_ = (w + kTile - 1) / kTile, ty_ = (h + kTile - 1) / kTile;
    far_.assign(std::size_t(tx_) * ty_, 0.0f);
    for (int y = 0; y < h; ++y) {
        float *row = far_.data() + std::size_t(y / kTile) * tx_;
        const float *d = depth + std::size_t(y) * w;
        for (int x = 0; x < w; ++x) row[x / kTile] = std::max(row[x / kTile], d[x]);
    }
}

bool DepthTiles::hidden(const std::array<float, 6> &box, float margin_mm, const glm::mat4 &view_proj, float margin_px) const {
    if (far_.empty() || !(box[0] <= box[3] && box[1] <= box[4] && box[2] <= box[5])) return false;
    float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY, zmin = INFINITY;
    for (int c = 0; c < 8; ++c) {
        const glm::vec4 p(c & 1 ? box[3] + margin_mm : box[0] - margin_mm, c & 2 ? box[4] + margin_mm : box[1] - margin_mm,
                          c & 4 ? box[5] + margin_mm : box[2] - margin_mm, 1.0f);
        const glm::vec4 q = view_proj * p;
        // A box reaching the eye's plane projects to no bounded rectangle,
        // and one cut by the near plane has fragments nearer than its
        // corners say: both are drawn.
        if (!(q.w > 0.0f) || q.z < -q.w) return false;
        const float iw = 1.0f / q.w;
        const float x = (q.x * iw * 0.5f + 0.5f) * float(w_), y = (q.y * iw * 0.5f + 0.5f) * float(h_);
        x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        zmin = std::min(zmin, q.z * iw * 0.5f + 0.5f);
    }
    // (the projection of a box wholly in front of the eye is the hull of
    // its corners' projections)
    x0 -= margin_px, y0 -= margin_px, x1 += margin_px, y1 += margin_px;
    if (!(std::isfinite(x0) && std::isfinite(x1) && std::isfinite(y0) && std::isfinite(y1) && std::isfinite(zmin))) return false;
    if (x1 < 0.0f || y1 < 0.0f || x0 >= float(w_) || y0 >= float(h_)) return true;  // off the picture
    const int a0 = std::max(0, int(std::floor(x0)) / kTile), a1 = std::min(tx_ - 1, int(std::floor(x1)) / kTile);
    const int b0 = std::max(0, int(std::floor(y0)) / kTile), b1 = std::min(ty_ - 1, int(std::floor(y1)) / kTile);
    // Depths are stored with 24 bits: a fragment as near as the box's
    // nearest corner may be stored up to a step nearer (2^-24); 2^-20 more.
    constexpr float kSlack = 1.0f / (1 << 20);
    for (int b = b0; b <= b1; ++b) {
        const float *row = far_.data() + std::size_t(b) * tx_;
        for (int a = a0; a <= a1; ++a)
            if (!(zmin > row[a] + kSlack)) return false;
    }
    return true;
}

}  // namespace hz::core::render
