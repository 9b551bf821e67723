// What the renderer keeps of each scene object on the GPU (private to the
// renderer): its buffers, its tractogram's drawable, its shading, and for
// volumes its slices' textures; and the uploads of the kinds that need no
// renderer state (meshes, slices).
#pragma once

#include "gl.hpp"
#include "tractogram/drawable.hpp"

#include <hz/core/plugin_host.hpp>
#include <hz/core/render/annotations.hpp>
#include <hz/core/render/scene.hpp>

#include <glm/glm.hpp>

#include <array>
#include <atomic>
#include <future>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

namespace hz::core::render {

// A linked program and its uniform locations, looked up once each.
struct Program {
    GLuint id = 0;
    std::string fragment_source;
    std::unordered_map<std::string, GLint> cache;
    GLint loc(const std::string &name) {
        auto it = cache.find(name);
        if (it != cache.end()) return it->second;
        return cache[name] = glGetUniformLocation(id, name.c_str());
    }
};

// Binds `tex` to texture unit `unit` and points sampler `name` of the bound program `p` at it.
inline void bind_sampler(Program &p, const char *name, int unit, GLenum target, GLuint tex) {
    glActiveTexture(GL_TEXTURE0 + unit);
    glBindTexture(target, tex);
    glUniform1i(p.loc(name), unit);
}

// (Point: only the slab's crossings are drawn as points; Volume: only the
// fibre volume, a tractogram's proxy, is drawn as a volume.)
enum class Geom { Mesh, Tube, Line, Point, Volume };

struct GpuObject {
    std::size_t index = 0;
    Geom geom = Geom::Mesh;
    bool slices = false;
    bool rgb = false;  // slices in colour (Object::rgb): volume_tex is RGB, each channel through the window
    // slices of a label volume (Object::labels): volume_tex is RGBA, the
    // label's colour and the label (label_texture), read without filtering
    bool labels = false;
    GLuint vao = 0, vbo = 0, ebo = 0;
    std::vector<GLint> firsts;
    std::vector<GLsizei> counts;
    GLsizei index_count = 0;
    std::uint64_t segments = 0, triangles = 0;
    // A mesh's level of detail (Object::moving_mesh), drawn instead while
    // the camera moves; vao 0 without one.
    struct MeshBuffers {
        GLuint vao = 0, vbo = 0, ebo = 0;
        GLsizei index_count = 0;
        std::uint64_t triangles = 0;
    };
    MeshBuffers moving;
    // streamlines: everything that draws them (tractogram/drawable.hpp);
    // null for other kinds.
    std::unique_ptr<TractogramDrawable> tract;
    // shading
    const LoadedPlugin *shader = nullptr;
    std::vector<double> values;  // schema order, every component
    std::string albedo;          // name of the colour parameter the colouring drives ("" if none)
    // Every vertex has this colour (solid colouring, or data that happens to
    // be constant): with baked materials it is a constant of the program.
    std::optional<std::array<std::uint8_t, 4>> uniform_rgba;
    bool use_line_domain = false;
    bool refractive = false;  // the snippet reads hz_scene_behind: drawn after the opaque objects
    // Programs by output (see Impl::Output), compiled when first needed.
    mutable Program *program = nullptr, *display_program = nullptr, *debug_program = nullptr, *peel_program = nullptr;
    mutable Program *point_programs[4] = {};   // the slab's crossings, by output
    mutable Program *volume_programs[4] = {};  // the fibre volume, by output
    // slices, or a volume rendered (dvr: ray-marched through its transfer
    // function, colormap_tex then the pass's table; step_mm: half its
    // smallest voxel side)
    bool dvr = false;
    double step_mm = 0.5;
    GLuint volume_tex = 0, colormap_tex = 0;
    GLsizei slice_vertices = 0;
    glm::mat4 ras_to_tex{1.0f};
    std::array<double, 2> window{0, 1};
    Bounds bounds;
    // How its colours stand for values, where a colormap colours it (its
    // colour bar): the range it was drawn with.
    std::optional<ColourScale> colour_scale;
};

// A mesh object: vertices with area-weighted normals and colours, faces.
// GL objects g.vao/vbo/ebo are created and bound by the caller's context.
void upload_mesh(GpuObject &g, const Object &o);
// A volume's three slices: the volume as a 3D texture, its colour map, and
// the slice quads; or, with o.transfer, the texture and the transfer
// function's table for the volume rendering pass.
void upload_slices(GpuObject &g, const Object &o);
// The slice quads of g (made by upload_slices) again for o's positions
// (Object::slice_x/y/z): only the vertex buffer changes. Throws Error for a
// position outside the volume.
void upload_slice_quads(GpuObject &g, const Object &o);
// How many 3D volumes a volume holds (the product of its dimensions after
// the third; 1 for a 3D one).
std::uint64_t volume_count(const Volume &v);
// The values of o's volume shown (Object::volume_index; a 3D volume of
// dims[0..2], x fastest), scaled, as float. Throws Error for an index
// beyond the file's volumes.
std::vector<float> volume_values(const Object &o);
// (shows_rgb: scene.hpp)

}  // namespace hz::core::render
