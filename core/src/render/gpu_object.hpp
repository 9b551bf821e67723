// What the renderer keeps of each scene object on the GPU (private to the
// renderer): its buffers, its streamline chunks and level-of-detail proxy,
// its shading, and for volumes its slices' textures; and the uploads of the
// kinds that need no renderer state (meshes, slices).
#pragma once

#include "gl.hpp"
#include "line_geometry.hpp"

#include <hz/core/plugin_host.hpp>
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

// (Point: only the slab's crossings are drawn as points; Volume: only the
// fibre volume, a tractogram's proxy, is drawn as a volume.)
enum class Geom { Mesh, Tube, Line, Point, Volume };

// Where a tractogram crosses the slab's plane (Slab::points): vertices in
// GL buffers of at most kCrossingChunk each (about 20 ms of llvmpipe's time:
// a step of a progressive frame), for the plane `axis` = `centre` of the
// object's colouring `lines`.
constexpr std::size_t kCrossingChunk = 1u << 16;
struct Crossings {
    std::vector<GLuint> vaos, vbos;
    std::vector<GLsizei> counts;
    std::uint64_t total = 0;
    int axis = -1;
    double centre = 0;
    const LineData *lines = nullptr;
};

struct GpuObject {
    std::size_t index = 0;
    Geom geom = Geom::Mesh;
    bool slices = false;
    GLuint vao = 0, vbo = 0, ebo = 0;
    std::vector<GLint> firsts;
    std::vector<GLsizei> counts;
    GLsizei index_count = 0;
    std::uint64_t segments = 0, triangles = 0;
    // streamlines: full detail in chunks, and the level-of-detail proxy
    // drawn while the camera moves and as the first picture of a
    // progressive frame: first a uniform subsample (immediate), replaced by
    // the shell proxy (shell_proxy.hpp) when a background thread has
    // computed it. An object small enough to be its own proxy has none.
    std::shared_ptr<LineData> lines;
    std::vector<LineChunk> chunks, proxy_chunks;
    // Full detail cut into bricks (RenderSettings::occlusion): `chunks` are
    // then over bricks->pieces, brick k's chunks [brick_chunks[k],
    // brick_chunks[k + 1]); else null.
    std::shared_ptr<const Bricks> bricks;
    std::vector<std::size_t> brick_chunks;
    std::future<Bricks> brick_job;  // the cut, being computed
    std::shared_ptr<std::atomic<bool>> brick_cancel;
    float max_radius_mm = 0;  // the widest tube
    // What the proxy draws (outermost first, or in hash order): each
    // proxy level a prefix of it (proxy_chunks: small chunks over it).
    std::shared_ptr<const std::vector<Piece>> proxy;
    std::future<std::vector<Piece>> shell;  // the shell proxy, being computed
    std::shared_ptr<std::atomic<bool>> shell_cancel;
    // The slab's crossings: those drawn, and those being computed on a
    // background thread for the plane and colouring in `crossing_next`.
    Crossings crossings, crossing_next;
    std::future<std::vector<LineVertex>> crossing_job;
    std::shared_ptr<std::atomic<bool>> crossing_cancel;
    // The fibre volume (line_geometry.hpp), computed on a background thread
    // and kept as three 3D textures: colour x density (RGBA16F) and
    // direction (RGBA8), filtered, and the skip distance (R8), fetched.
    std::future<FibreVolume> fibre_job;
    std::shared_ptr<std::atomic<bool>> fibre_cancel;
    GLuint fibre_tex[3] = {0, 0, 0};
    std::array<int, 3> fibre_dim{};
    std::array<float, 3> fibre_origin{};
    float fibre_voxel_mm = 0;
    bool has_fibre_volume() const { return fibre_tex[0] != 0; }
    ~GpuObject() {
        if (shell_cancel) *shell_cancel = true;
        if (crossing_cancel) *crossing_cancel = true;
        if (fibre_cancel) *fibre_cancel = true;
        if (brick_cancel) *brick_cancel = true;
        if (shell.valid()) shell.wait();
        if (brick_job.valid()) brick_job.wait();
        if (crossing_job.valid()) crossing_job.wait();
        if (fibre_job.valid()) fibre_job.wait();
    }
    GpuObject() = default;
    GpuObject(GpuObject &&) = default;
    GpuObject &operator=(GpuObject &&) = default;
    std::uint64_t points_total = 0, streamlines = 0;
    double tol_mm = 0, proxy_tol_mm = 0;  // the proxy is drawn at 1/scale of the size: decimated for its finest level's
    bool has_lod_proxy() const { return !proxy_chunks.empty(); }
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
    mutable Program *program = nullptr, *display_program = nullptr, *debug_program = nullptr;
    mutable Program *point_programs[3] = {};   // the slab's crossings, by output
    mutable Program *volume_programs[3] = {};  // the fibre volume, by output
    // slices
    GLuint volume_tex = 0, colormap_tex = 0;
    GLsizei slice_vertices = 0;
    glm::mat4 ras_to_tex{1.0f};
    std::array<double, 2> window{0, 1};
    Bounds bounds;
};

// A mesh object: vertices with area-weighted normals and colours, faces.
// GL objects g.vao/vbo/ebo are created and bound by the caller's context.
void upload_mesh(GpuObject &g, const Object &o);
// A volume's three slices: the volume as a 3D texture, its colour map, and
// the slice quads.
void upload_slices(GpuObject &g, const Object &o);

}  // namespace hz::core::render
