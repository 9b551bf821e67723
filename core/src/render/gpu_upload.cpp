// Meshes and volume slices on the GPU (gpu_object.hpp).
#include "gpu_object.hpp"
#include "passes/volume_rendering.hpp"

#include "colour.hpp"

#include <hz/core/render/renderer.hpp>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>

namespace hz::core::render {

namespace {

// The colour all vertices share, if they share one.
template <class Vertex>
std::optional<std::array<std::uint8_t, 4>> same_colour(const std::vector<Vertex> &verts) {
    if (verts.empty()) return std::nullopt;
    std::array<std::uint8_t, 4> c;
    std::memcpy(c.data(), verts[0].rgba, 4);
    for (const Vertex &v : verts)
        if (std::memcmp(v.rgba, c.data(), 4) != 0) return std::nullopt;
    return c;
}

// Mesh `m` of object `o` (its own, or its level of detail) uploaded as
// vertex array `vao` of buffers `vbo` and `ebo`; the colour scale and the
// uniform colour of g set for its own (`own`).
void upload_triangles(GpuObject &g, const Object &o, const Mesh &m, bool own, GLuint &vao, GLuint &vbo, GLuint &ebo) {
    const std::uint64_t nv = m.nb_vertices(), nf = m.nb_faces();
    for (std::uint64_t i = 0; i < nf * 3; ++i)
        if (m.faces[i] >= nv) throw Error(o.name + ": face index " + std::to_string(m.faces[i]) + " out of range");
    // Area-weighted vertex normals.
    std::vector<glm::vec3> nrm(nv, glm::vec3(0));
    const float *V = m.vertices.data();
    auto vp = [&](std::uint32_t i) { return glm::vec3(V[i * 3], V[i * 3 + 1], V[i * 3 + 2]); };
    for (std::uint64_t f = 0; f < nf; ++f) {
        const std::uint32_t a = m.faces[f * 3], b = m.faces[f * 3 + 1], c = m.faces[f * 3 + 2];
        const glm::vec3 n = glm::cross(vp(b) - vp(a), vp(c) - vp(a));
        if (!std::isfinite(n.x + n.y + n.z)) continue;
        nrm[a] += n, nrm[b] += n, nrm[c] += n;
    }
    std::vector<double> data;
    std::array<double, 2> range{0, 1};
    const Coloring &c = o.coloring;
    if (c.mode == "data") {
        const DataArray *a = nullptr;
        for (const auto &x : m.arrays)
            if (x.name == c.array && x.attach == HZ_ATTACH_VERTEX && x.count == nv) a = &x;
        if (!a) {
            std::string list;
            for (const auto &x : m.arrays) list += (list.empty() ? "" : ", ") + x.name;
            throw Error(o.name + ": color: no per-vertex array '" + c.array + "' (arrays: " + (list.empty() ? "none" : list) + ")");
        }
        data = array_values(*a);
        range = c.range ? *c.range : finite_range(data);
        if (own) g.colour_scale = ColourScale{o.name, c.array, c.colormap, range};
    }
    // Per-vertex colours ("rgb"): 8/16-bit values are sRGB-encoded (FreeSurfer annotation colours), float
    // values linear in 0..1 (glTF COLOR_0).
    std::vector<std::array<double, 3>> rgb;
    if (c.mode == "rgb") {
        const DataArray *a = nullptr;
        for (const auto &x : m.arrays)
            if (x.name == c.array && x.attach == HZ_ATTACH_VERTEX && x.count == nv && x.components >= 3) a = &x;
        if (!a) throw Error(o.name + ": color: no per-vertex colour array '" + c.array + "' (3 or 4 components)");
        const std::size_t es = dtype_size(a->dtype);
        const double scale = a->dtype == HZ_DTYPE_U8 ? 255.0 : a->dtype == HZ_DTYPE_U16 ? 65535.0 : 0.0;
        rgb.resize(nv);
        for (int k = 0; k < 3; ++k) {
            const auto v = values_of(a->bytes.data() + k * es, a->dtype, a->count, es * a->components);
            for (std::uint64_t i = 0; i < nv; ++i) {
                const double x = std::isfinite(v[i]) ? v[i] : 0.0;
                rgb[i][std::size_t(k)] =
                    c.tint[std::size_t(k)] * (scale > 0 ? srgb_to_linear(std::clamp(x / scale, 0.0, 1.0)) : std::clamp(x, 0.0, 1.0));
            }
        }
    }
    struct MV {
        float pos[3];
        float normal[3];
        std::uint8_t rgba[4];
    };
    std::vector<MV> verts(nv);
    for (std::uint64_t i = 0; i < nv; ++i) {
        MV &v = verts[i];
        for (int k = 0; k < 3; ++k) v.pos[k] = V[i * 3 + k];
        const float l = glm::length(nrm[i]);
        const glm::vec3 n = l > 0 ? nrm[i] / l : glm::vec3(0, 0, 1);
        v.normal[0] = n.x, v.normal[1] = n.y, v.normal[2] = n.z;
        std::array<std::uint8_t, 4> col;
        if (c.mode == "data") {
            const auto cm = colormap(c.colormap, (data[i] - range[0]) / (range[1] - range[0]));
            col = rgba8(srgb_to_linear(cm[0]), srgb_to_linear(cm[1]), srgb_to_linear(cm[2]));
        } else if (c.mode == "rgb")
            col = rgba8(rgb[i][0], rgb[i][1], rgb[i][2]);
        else
            col = rgba8(c.color[0], c.color[1], c.color[2]);
        std::memcpy(v.rgba, col.data(), 4);
    }
    if (own) g.uniform_rgba = same_colour(verts);
    glGenVertexArrays(1, &vao);
    glBindVertexArray(vao);
    glGenBuffers(1, &vbo);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(verts.size() * sizeof(MV)), verts.data(), GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(MV), reinterpret_cast<void *>(0));
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, sizeof(MV), reinterpret_cast<void *>(12));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(MV), reinterpret_cast<void *>(24));
    glGenBuffers(1, &ebo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ebo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(nf * 3 * 4), m.faces.data(), GL_STATIC_DRAW);
}
}  // namespace

void upload_mesh(GpuObject &g, const Object &o) {
    const Mesh &m = o.data.mesh;
    upload_triangles(g, o, m, true, g.vao, g.vbo, g.ebo);
    g.index_count = GLsizei(m.nb_faces() * 3);
    g.triangles = m.nb_faces();
    g.bounds = bounds_of(m.vertices.data(), m.nb_vertices());
    if (o.moving_mesh) {
        upload_triangles(g, o, *o.moving_mesh, false, g.moving.vao, g.moving.vbo, g.moving.ebo);
        g.moving.index_count = GLsizei(o.moving_mesh->nb_faces() * 3);
        g.moving.triangles = o.moving_mesh->nb_faces();
        glBindVertexArray(g.vao);  // (the caller's: its own, bound)
    }
}

std::vector<float> volume_values(const Object &o) {
    const Volume &v = o.data.volume;
    const std::uint64_t X = v.dims[0], Y = v.dims[1], Z = v.dims[2];
    // The 3D volume shown (Object::volume_index), scaled to float (read in
    // place, no copy of the voxels).
    const std::uint64_t volumes = volume_count(v);
    if (o.volume_index >= volumes)
        throw Error(o.name + ": volume_index " + std::to_string(o.volume_index) + ", but the file holds " + std::to_string(volumes) +
                    (volumes == 1 ? " volume" : " volumes") + " (0 to " + std::to_string(volumes - 1) + ")");
    const std::size_t es = dtype_size(v.dtype);
    const std::vector<double> vals = values_of(v.voxels.data() + o.volume_index * X * Y * Z * es, v.dtype, X * Y * Z, es);
    std::vector<float> f(vals.size());
    for (std::size_t i = 0; i < vals.size(); ++i) f[i] = float(vals[i] * v.scale_slope + v.scale_inter);
    return f;
}

bool shows_value_slices(const Object &o) { return o.kind == HZ_DATA_VOLUME && !o.peaks && !o.odfs && !o.tensors; }

bool shows_rgb(const Object &o) {
    const Volume &v = o.data.volume;
    const bool rgb_type = v.dtype == HZ_DTYPE_RGB8 || v.dtype == HZ_DTYPE_RGBA8;
    const bool channels = v.dims.size() == 4 && (v.dims[3] == 3 || v.dims[3] == 4);
    if (o.rgb) return *o.rgb;
    return rgb_type || (channels && v.dtype == HZ_DTYPE_U8);
}

namespace {
// The RGB values of a colour volume, 3 per voxel (x fastest), scaled: from
// an RGB voxel type's bytes, or from the 4th dimension's first three.
std::vector<float> rgb_values(const Object &o) {
    const Volume &v = o.data.volume;
    const std::uint64_t n = v.dims[0] * v.dims[1] * v.dims[2];
    std::vector<float> out(n * 3);
    if (v.dtype == HZ_DTYPE_RGB8 || v.dtype == HZ_DTYPE_RGBA8) {
        const std::size_t es = v.dtype == HZ_DTYPE_RGB8 ? 3 : 4;
        if (v.voxels.size() < n * es) throw Error(o.name + ": fewer voxels than its dimensions");
        const auto *b = reinterpret_cast<const std::uint8_t *>(v.voxels.data());
        for (std::uint64_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) out[i * 3 + c] = float(b[i * es + c]);
        return out;
    }
    if (v.dims.size() != 4 || (v.dims[3] != 3 && v.dims[3] != 4))
        throw Error(o.name + ": \"rgb\": its 4th dimension must hold 3 or 4 values per voxel, not " +
                    (v.dims.size() > 3 ? std::to_string(v.dims[3]) : std::string("none (a 3D volume)")));
    const std::size_t es = dtype_size(v.dtype);
    const double slope = v.scale_slope == 0 ? 1.0 : v.scale_slope;
    for (int c = 0; c < 3; ++c) {
        const std::vector<double> vals = values_of(v.voxels.data() + c * n * es, v.dtype, n, es);
        for (std::uint64_t i = 0; i < n; ++i) out[i * 3 + c] = float(vals[i] * slope + v.scale_inter);
    }
    return out;
}
}  // namespace

void upload_slices(GpuObject &g, const Object &o) {
    const Volume &v = o.data.volume;
    if (v.dims.size() < 3) throw Error(o.name + ": slices need a 3D volume");
    GLint max3d = 0;
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &max3d);
    const std::uint64_t X = v.dims[0], Y = v.dims[1], Z = v.dims[2];
    if (X > std::uint64_t(max3d) || Y > std::uint64_t(max3d) || Z > std::uint64_t(max3d))
        throw Error(o.name + ": volume larger than the GL 3D texture limit " + std::to_string(max3d));
    g.labels = o.labels && !o.transfer;
    g.rgb = !o.transfer && !g.labels && shows_rgb(o);
    if (g.rgb && o.volume_index != 0) throw Error(o.name + ": a colour volume has no series to index (volume_index 0)");
    const std::vector<float> f = g.labels ? label_texture(*o.labels) : g.rgb ? rgb_values(o) : volume_values(o);
    glGenTextures(1, &g.volume_tex);
    glBindTexture(GL_TEXTURE_3D, g.volume_tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    const GLenum internal = g.labels ? GL_RGBA32F : g.rgb ? GL_RGB32F : GL_R32F, format = g.labels ? GL_RGBA : g.rgb ? GL_RGB : GL_RED;
    glTexImage3D(GL_TEXTURE_3D, 0, GLint(internal), GLsizei(X), GLsizei(Y), GLsizei(Z), 0, format, GL_FLOAT, f.data());
    // (labels: a voxel's own, never a blend of two labels)
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, g.labels ? GL_NEAREST : GL_LINEAR);
    glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, g.labels ? GL_NEAREST : GL_LINEAR);
    for (GLenum w : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R}) glTexParameteri(GL_TEXTURE_3D, w, GL_CLAMP_TO_EDGE);
    // Window: given, else the 1st..99th percentile of the finite values
    // (colour: 0 to 255 for 8-bit values, else 0 to 1).
    if (o.window)
        g.window = *o.window;
    else if (g.labels)
        g.window = {0, 1};
    else if (g.rgb) {
        const hz_dtype t = o.data.volume.dtype;
        g.window =
            t == HZ_DTYPE_U8 || t == HZ_DTYPE_RGB8 || t == HZ_DTYPE_RGBA8 ? std::array<double, 2>{0, 255} : std::array<double, 2>{0, 1};
    } else {
        std::vector<float> s;
        for (float x : f)
            if (std::isfinite(x)) s.push_back(x);
        if (!s.empty()) {
            std::nth_element(s.begin(), s.begin() + s.size() / 100, s.end());
            const float lo = s[s.size() / 100];
            std::nth_element(s.begin(), s.begin() + s.size() * 99 / 100, s.end());
            g.window = {lo, std::max(s[s.size() * 99 / 100], lo + 1e-6f)};
        }
    }
    if (o.transfer) {  // a volume rendered: the transfer function's table instead of a colormap
        check_transfer(*o.transfer);
        g.dvr = true;
        g.colour_scale = ColourScale{o.name, "", o.transfer->colormap, g.window};
        const std::vector<float> table = transfer_table(*o.transfer);
        glGenTextures(1, &g.colormap_tex);
        glBindTexture(GL_TEXTURE_2D, g.colormap_tex);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA16F, 256, 1, 0, GL_RGBA, GL_FLOAT, table.data());
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    }
    if (!o.transfer && !g.rgb && !g.labels) g.colour_scale = ColourScale{o.name, "", o.slice_colormap, g.window};
    // Colormap texture (sRGB table).
    std::vector<std::uint8_t> lut(256 * 4);
    for (int i = 0; i < 256; ++i) {
        const auto cm = colormap(o.slice_colormap, i / 255.0);
        const auto q = rgba8(cm[0], cm[1], cm[2]);
        std::memcpy(&lut[i * 4], q.data(), 4);
    }
    if (!g.dvr) glGenTextures(1, &g.colormap_tex);
    glBindTexture(GL_TEXTURE_2D, g.colormap_tex);
    if (!g.dvr) glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, 256, 1, 0, GL_RGBA, GL_UNSIGNED_BYTE, lut.data());
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    // RAS -> texture coordinates, and the RAS bounding box of the grid.
    glm::dmat4 A(1.0);
    for (int r = 0; r < 4; ++r)
        for (int cc = 0; cc < 4; ++cc) A[cc][r] = v.voxel_to_ras[r * 4 + cc];
    const glm::dmat4 to_tex = glm::scale(glm::dmat4(1.0), glm::dvec3(1.0 / X, 1.0 / Y, 1.0 / Z)) *
                              glm::translate(glm::dmat4(1.0), glm::dvec3(0.5)) * glm::inverse(A);
    g.ras_to_tex = glm::mat4(to_tex);
    glm::dvec3 lo(INFINITY), hi(-INFINITY);
    for (int corner = 0; corner < 8; ++corner) {
        const glm::dvec4 ijk((corner & 1) ? X - 0.5 : -0.5, (corner & 2) ? Y - 0.5 : -0.5, (corner & 4) ? Z - 0.5 : -0.5, 1.0);
        const glm::dvec3 p = glm::dvec3(A * ijk);
        lo = glm::min(lo, p), hi = glm::max(hi, p);
    }
    g.bounds.empty = false;
    for (int k = 0; k < 3; ++k) g.bounds.min[k] = lo[k], g.bounds.max[k] = hi[k];
    // (the ray march's step: half the smallest voxel side)
    g.step_mm = 0.5 * std::min({glm::length(glm::dvec3(A[0])), glm::length(glm::dvec3(A[1])), glm::length(glm::dvec3(A[2]))});
    if (o.transfer) {
        g.slice_vertices = 0;
        return;
    }
    glGenVertexArrays(1, &g.vao);
    glBindVertexArray(g.vao);
    glGenBuffers(1, &g.vbo);
    glBindBuffer(GL_ARRAY_BUFFER, g.vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 12, nullptr);
    upload_slice_quads(g, o);
}

std::uint64_t volume_count(const Volume &v) {
    std::uint64_t n = 1;
    for (std::size_t k = 3; k < v.dims.size(); ++k) n *= std::max<std::uint64_t>(v.dims[k], 1);
    return n;
}

void upload_slice_quads(GpuObject &g, const Object &o) {
    const glm::dvec3 lo(g.bounds.min[0], g.bounds.min[1], g.bounds.min[2]), hi(g.bounds.max[0], g.bounds.max[1], g.bounds.max[2]);
    const glm::dvec3 mid = (lo + hi) * 0.5;
    std::vector<float> quads;
    auto quad = [&](int axis, double at) {
        if (std::isnan(at)) at = mid[axis];
        if (at < lo[axis] || at > hi[axis]) {
            char msg[160];
            std::snprintf(msg, sizeof msg, ": slice %c = %g mm lies outside the volume (%.1f to %.1f mm)", "xyz"[axis], at, lo[axis],
                          hi[axis]);
            throw Error(o.name + msg);
        }
        const int u = (axis + 1) % 3, w = (axis + 2) % 3;
        const double cu[4] = {lo[u], hi[u], hi[u], lo[u]}, cw[4] = {lo[w], lo[w], hi[w], hi[w]};
        const int order[6] = {0, 1, 2, 0, 2, 3};
        for (int k : order) {
            glm::dvec3 p;
            p[axis] = at, p[u] = cu[k], p[w] = cw[k];
            quads.push_back(float(p.x)), quads.push_back(float(p.y)), quads.push_back(float(p.z));
        }
    };
    if (o.slice_x) quad(0, *o.slice_x);
    if (o.slice_y) quad(1, *o.slice_y);
    if (o.slice_z) quad(2, *o.slice_z);
    g.slice_vertices = GLsizei(quads.size() / 3);
    g.triangles = g.slice_vertices / 3;
    glBindBuffer(GL_ARRAY_BUFFER, g.vbo);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(quads.size() * 4), quads.data(), GL_DYNAMIC_DRAW);
}

}  // namespace hz::core::render
