// What a click meets in the window (click_point.hpp).
#include "click_point.hpp"

#include <hz/core/render/pick.hpp>
#include <hz/core/render/renderer.hpp>

#include <algorithm>
#include <cmath>

namespace hz::host {

std::optional<std::array<double, 3>> point_under(const ClickTarget &target, int ww, int wh, int fw, int fh, double x, double y,
                                                 const core::render::View &v) {
    if (ww <= 0 || wh <= 0 || fw <= 0 || fh <= 0) return std::nullopt;
    const double px = x * fw / ww, py = y * fh / wh;
    // The ray through the pixel, in the camera's frame.
    const double fwd[3] = {v.target[0] - v.eye[0], v.target[1] - v.eye[1], v.target[2] - v.eye[2]};
    const double fl = std::sqrt(fwd[0] * fwd[0] + fwd[1] * fwd[1] + fwd[2] * fwd[2]);
    const double f[3] = {fwd[0] / fl, fwd[1] / fl, fwd[2] / fl};
    double rt[3] = {f[1] * v.up[2] - f[2] * v.up[1], f[2] * v.up[0] - f[0] * v.up[2], f[0] * v.up[1] - f[1] * v.up[0]};
    const double rl = std::sqrt(rt[0] * rt[0] + rt[1] * rt[1] + rt[2] * rt[2]);
    for (double &c : rt) c /= rl;
    const double u[3] = {rt[1] * f[2] - rt[2] * f[1], rt[2] * f[0] - rt[0] * f[2], rt[0] * f[1] - rt[1] * f[0]};
    const double th = std::tan(v.fov_deg * M_PI / 360.0), aspect = double(fw) / fh;
    const double sx = (2 * (px + 0.5) / fw - 1) * th * aspect, sy = (1 - 2 * (py + 0.5) / fh) * th;
    const double dir[3] = {f[0] + sx * rt[0] + sy * u[0], f[1] + sx * rt[1] + sy * u[1], f[2] + sx * rt[2] + sy * u[2]};
    std::optional<core::render::PickHit> hit;
    constexpr double kTolerancePx = 6.0;
    const bool streamlines = !target.slices_only && target.object < target.scene->objects.size() &&
                             target.scene->objects[target.object].kind == HZ_DATA_STREAMLINES && (target.centroids || target.session);
    if (!streamlines) {
    } else if (target.centroids) {
        const core::render::Object &ob = target.scene->objects[target.object];
        hit = core::render::pick_streamline(ob.data.tractogram, core::render::tube_radii(ob), v, fw, fh, px, py, kTolerancePx);
    } else {
        // The streamlines shown, only those near the ray when the
        // spatial grid is built, front to back: the first (nearest)
        // depth step along the ray where a streamline passes within
        // half a millimetre of it (or its tube) is what the click
        // meets; a million streamlines cost a few thousand tests.
        const core::render::Object &ob = target.scene->objects[target.object];
        std::vector<float> radii = ob.render == "tubes" ? core::render::tube_radii(ob) : std::vector<float>{};
        const std::uint64_t n = ob.data.tractogram.nb_streamlines();
        if (radii.empty()) radii.assign(n, 0.5f);
        for (float &x : radii) x = std::max(x, 0.5f);
        const std::vector<std::uint64_t> &kept = target.session->kept();
        if (const core::StreamlineGrid *grid = target.session->grid_if_ready()) {
            const std::uint64_t words = (target.session->all().nb_streamlines() + 63) / 64;
            std::vector<std::uint64_t> seen(words, 0), step(words, 0);
            for (double d = v.near_mm; d <= v.far_mm && !hit; d += grid->cell) {
                std::fill(step.begin(), step.end(), 0);
                for (double e : {d, d + grid->cell / 2, d + grid->cell}) {
                    const double reach = kTolerancePx * e * 2 * th / fh + 1e-3 + grid->cell / 2;
                    core::Bounds box;
                    box.empty = false;
                    for (int i = 0; i < 3; ++i) box.min[i] = v.eye[i] + e * dir[i] - reach, box.max[i] = v.eye[i] + e * dir[i] + reach;
                    grid->mark(box, step);
                }
                std::vector<std::uint64_t> near;  // (object indices: the object shows kept[i] as its streamline i)
                for (std::uint64_t w = 0; w < words; ++w) {
                    for (std::uint64_t bits = step[w] & ~seen[w]; bits; bits &= bits - 1) {
                        const std::uint64_t s = w * 64 + std::uint64_t(__builtin_ctzll(bits));
                        const auto it = std::lower_bound(kept.begin(), kept.end(), s);
                        if (it != kept.end() && *it == s) near.push_back(std::uint64_t(it - kept.begin()));
                    }
                    seen[w] |= step[w];
                }
                if (!near.empty()) hit = core::render::pick_streamline(ob.data.tractogram, radii, v, fw, fh, px, py, kTolerancePx, &near);
            }
        } else {
            hit = core::render::pick_streamline(ob.data.tractogram, radii, v, fw, fh, px, py, kTolerancePx);
        }
    }
    // Surfaces and slices in front of it (or without it) are what
    // the click meets instead: the nearest of all.
    std::optional<double> depth;
    if (hit) depth = hit->depth_mm;
    const std::array<double, 3> o3{v.eye[0], v.eye[1], v.eye[2]}, d3{dir[0], dir[1], dir[2]};
    for (const auto &ob : target.scene->objects) {
        if (!ob.visible) continue;
        std::optional<double> t;
        if (ob.kind == HZ_DATA_MESH) {
            if (target.slices_only) continue;
            t = core::render::ray_mesh(ob.data.mesh, o3, d3);
        } else if (ob.kind == HZ_DATA_VOLUME && ob.data.volume.dims.size() >= 3 && !ob.transfer) {
            const core::Volume &vol = ob.data.volume;
            double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            for (int c = 0; c < 8; ++c) {  // (the grid's RAS bounding box, as the slices are drawn)
                const double ijk[3] = {(c & 1) ? double(vol.dims[0]) - 0.5 : -0.5, (c & 2) ? double(vol.dims[1]) - 0.5 : -0.5,
                                       (c & 4) ? double(vol.dims[2]) - 0.5 : -0.5};
                for (int i = 0; i < 3; ++i) {
                    const double x = vol.voxel_to_ras[i * 4] * ijk[0] + vol.voxel_to_ras[i * 4 + 1] * ijk[1] +
                                     vol.voxel_to_ras[i * 4 + 2] * ijk[2] + vol.voxel_to_ras[i * 4 + 3];
                    lo[i] = std::min(lo[i], x), hi[i] = std::max(hi[i], x);
                }
            }
            const std::optional<double> at[3] = {ob.slice_x, ob.slice_y, ob.slice_z};
            for (int axis = 0; axis < 3; ++axis) {
                if (!at[axis] || std::abs(d3[axis]) < 1e-12) continue;
                const double c = std::isnan(*at[axis]) ? (lo[axis] + hi[axis]) / 2 : *at[axis];
                const double tt = (c - o3[axis]) / d3[axis];
                if (!(tt > v.near_mm)) continue;
                bool inside = true;
                for (int i = 0; i < 3; ++i)
                    if (i != axis && (o3[i] + tt * d3[i] < lo[i] || o3[i] + tt * d3[i] > hi[i])) inside = false;
                if (inside && (!t || tt < *t)) t = tt;
            }
        }
        if (t && *t > v.near_mm && (!depth || *t < *depth)) depth = t;
    }
    if (!depth) return std::nullopt;
    std::array<double, 3> p;
    for (int i = 0; i < 3; ++i) p[i] = v.eye[i] + *depth * dir[i];
    return p;
}

std::optional<VoxelValue> voxel_at(const core::render::Scene &scene, const std::array<double, 3> &p) {
    for (std::size_t k = 0; k < scene.objects.size(); ++k)
        if (scene.objects[k].visible && !scene.objects[k].transfer)
            if (auto v = voxel_of(scene, k, p)) return v;
    return std::nullopt;
}

std::optional<VoxelValue> voxel_of(const core::render::Scene &scene, std::size_t k, const std::array<double, 3> &p) {
    return VoxelLookup(scene, k)(p);
}

VoxelLookup::VoxelLookup(const core::render::Scene &scene, std::size_t k) : k_(k) {
    const auto &ob = scene.objects[k];
    if (ob.kind != HZ_DATA_VOLUME || ob.data.volume.dims.size() < 3) return;
    // RAS -> voxel: the inverse of the 3x4 affine.
    const auto &a = ob.data.volume.voxel_to_ras;
    const double m[3][3] = {{a[0], a[1], a[2]}, {a[4], a[5], a[6]}, {a[8], a[9], a[10]}};
    const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                       m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if (!(std::abs(det) > 1e-12)) return;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            const int i1 = (j + 1) % 3, i2 = (j + 2) % 3, j1 = (i + 1) % 3, j2 = (i + 2) % 3;
            inv_[i][j] = (m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]) / det;
        }
    ob_ = &ob;
    rgb_ = core::render::shows_rgb(ob);
}

std::optional<VoxelValue> VoxelLookup::operator()(const std::array<double, 3> &p) const {
    if (ob_ == nullptr) return std::nullopt;
    const auto &ob = *ob_;
    const core::Volume &vol = ob.data.volume;
    const auto &a = vol.voxel_to_ras;
    const double q[3] = {p[0] - a[3], p[1] - a[7], p[2] - a[11]};
    VoxelValue out;
    out.object = k_;
    bool inside = true;
    for (int i = 0; i < 3; ++i) {
        const double c = inv_[i][0] * q[0] + inv_[i][1] * q[1] + inv_[i][2] * q[2];
        out.ijk[i] = std::int64_t(c < 0 ? -std::floor(-c + 0.5) : std::floor(c + 0.5));
        inside = inside && out.ijk[i] >= 0 && std::uint64_t(out.ijk[i]) < vol.dims[i];
    }
    if (!inside) return std::nullopt;
    const std::uint64_t X = vol.dims[0], Y = vol.dims[1], Z = vol.dims[2];
    const std::uint64_t at =
        std::uint64_t(out.ijk[0]) + X * (std::uint64_t(out.ijk[1]) + Y * std::uint64_t(out.ijk[2])) + ob.volume_index * X * Y * Z;
    const std::size_t es = core::dtype_size(vol.dtype);
    if (es == 0 || (at + 1) * es > vol.voxels.size()) return std::nullopt;
    out.value = core::value_at(vol.voxels.data() + at * es, vol.dtype) * (vol.scale_slope == 0 ? 1.0 : vol.scale_slope) + vol.scale_inter;
    if (rgb_) {
        const std::uint64_t voxel = at - ob.volume_index * X * Y * Z;
        if (vol.dtype == HZ_DTYPE_RGB8 || vol.dtype == HZ_DTYPE_RGBA8) {  // (the voxel's bytes)
            for (int c = 0; c < 3; ++c) out.colour.push_back(double(std::uint8_t(vol.voxels.data()[voxel * es + std::size_t(c)])));
        } else if (vol.dims.size() >= 4 && vol.dims[3] >= 3 && (voxel + 2 * X * Y * Z + 1) * es <= vol.voxels.size()) {
            for (std::uint64_t c = 0; c < 3; ++c)
                out.colour.push_back(core::value_at(vol.voxels.data() + (voxel + c * X * Y * Z) * es, vol.dtype) *
                                         (vol.scale_slope == 0 ? 1.0 : vol.scale_slope) +
                                     vol.scale_inter);
        }
        if (!out.colour.empty()) out.value = out.colour[0];
    }
    return out;
}

}  // namespace hz::host
