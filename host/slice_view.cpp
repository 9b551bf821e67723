#include "slice_view.hpp"

#include "click_point.hpp"

#include <hz/core/data.hpp>

#include <algorithm>
#include <cmath>

namespace hz::host {

namespace {

// The columns' and rows' world axes of each view, and their directions
// (neurological: right on the right; sagittal from the left).
struct ViewPlane {
    int u, v;
    double us, vs;
};
ViewPlane plane_of(int axis) {
    switch (axis) {
    case 0: return {1, 2, -1, 1};  // sagittal: anterior to the left, superior up
    case 1: return {0, 2, 1, 1};   // coronal: right on the right, superior up
    default: return {0, 1, 1, 1};  // axial: right on the right, anterior up
    }
}

std::uint8_t channel_byte(double c) { return std::uint8_t(std::lround(std::clamp(c, 0.0, 1.0) * 255.0)); }

}  // namespace

std::array<double, 3> SliceImage::world(double x, double y) const {
    std::array<double, 3> p = corner;
    p[std::size_t(u_axis)] += u_sign * x * mm_per_pixel;
    p[std::size_t(v_axis)] -= v_sign * y * mm_per_pixel;
    return p;
}

std::array<double, 2> SliceImage::pixel(const std::array<double, 3> &p) const {
    return {(p[std::size_t(u_axis)] - corner[std::size_t(u_axis)]) * u_sign / mm_per_pixel,
            (corner[std::size_t(v_axis)] - p[std::size_t(v_axis)]) * v_sign / mm_per_pixel};
}

const char *axis_view_name(int axis) { return axis == 0 ? "sagittal" : axis == 1 ? "coronal" : "axial"; }

std::optional<int> axis_of(const std::string &w) {
    if (w == "x" || w == "sagittal") return 0;
    if (w == "y" || w == "coronal") return 1;
    if (w == "z" || w == "axial") return 2;
    return std::nullopt;
}

SliceImage slice_image(const core::render::Scene &scene, std::size_t object, int axis, double position, const std::array<double, 2> &window,
                       const core::Bounds &box) {
    if (object >= scene.objects.size()) throw core::Error("2D view: no object " + std::to_string(object));
    const core::render::Object &ob = scene.objects[object];
    if (!core::render::shows_value_slices(ob) || ob.data.volume.dims.size() < 3 || box.empty)
        throw core::Error("2D view: " + ob.name + " is not a volume drawn as slices");
    if (axis < 0 || axis > 2) throw core::Error("2D view: axis " + std::to_string(axis) + " is not x, y or z");
    // The finest voxel size: the shortest column of the affine.
    const auto &a = ob.data.volume.voxel_to_ras;
    double voxel = 1e300;
    for (int c = 0; c < 3; ++c)
        voxel = std::min(voxel, std::sqrt(a[std::size_t(c)] * a[std::size_t(c)] + a[std::size_t(4 + c)] * a[std::size_t(4 + c)] +
                                          a[std::size_t(8 + c)] * a[std::size_t(8 + c)]));
    const ViewPlane pl = plane_of(axis);
    const double span_u = box.max[pl.u] - box.min[pl.u], span_v = box.max[pl.v] - box.min[pl.v];
    constexpr double kMaxSide = 2048;
    const double mm = std::max({voxel, span_u / kMaxSide, span_v / kMaxSide, 1e-6});
    SliceImage s;
    s.axis = axis, s.position = position, s.mm_per_pixel = mm;
    s.u_axis = pl.u, s.v_axis = pl.v, s.u_sign = pl.us, s.v_sign = pl.vs;
    s.corner[std::size_t(axis)] = position;
    s.corner[std::size_t(pl.u)] = pl.us > 0 ? box.min[pl.u] : box.max[pl.u];
    s.corner[std::size_t(pl.v)] = pl.vs > 0 ? box.max[pl.v] : box.min[pl.v];
    const int w = std::max(1, int(std::ceil(span_u / mm - 1e-9))), h = std::max(1, int(std::ceil(span_v / mm - 1e-9)));
    s.image.width = w, s.image.height = h;
    s.image.rgba.assign(std::size_t(w) * std::size_t(h) * 4, 0);
    const double lo = window[0], span = window[1] > window[0] ? window[1] - window[0] : 1.0;
    const bool rgb8 = ob.data.volume.dtype == HZ_DTYPE_RGB8 || ob.data.volume.dtype == HZ_DTYPE_RGBA8;
    const VoxelLookup voxel_of(scene, object);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            std::uint8_t *px = &s.image.rgba[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 4];
            px[3] = 255;
            const auto vv = voxel_of(s.world(x + 0.5, y + 0.5));
            if (!vv) continue;
            std::array<float, 3> c{};
            if (ob.labels) {
                if (std::int64_t(vv->value) == 0) continue;  // (no label: the background)
                const auto l = core::render::label_colour(ob.labels->options.table, std::int64_t(vv->value));
                c = {l[0] / 255.f, l[1] / 255.f, l[2] / 255.f};
            } else if (vv->colour.size() == 3) {
                for (int k = 0; k < 3; ++k)
                    c[std::size_t(k)] = float(rgb8 ? vv->colour[std::size_t(k)] / 255.0 : (vv->colour[std::size_t(k)] - lo) / span);
            } else {
                c = core::render::colormap(ob.slice_colormap, (vv->value - lo) / span);
            }
            for (int k = 0; k < 3; ++k) px[k] = channel_byte(c[std::size_t(k)]);
        }
    return s;
}

}  // namespace hz::host
