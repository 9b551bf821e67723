// One tractogram on the GPU (private to the renderer): everything that
// draws a large tractogram at interactive rates. Its full detail in chunks
// (cut into bricks on a background thread, nearest first, for occlusion
// culling), its level-of-detail proxy (a uniform subsample at once, the
// shell proxy when computed, decimated for the proxy level's scale), its
// fibre volume (the proxy of the whole, ray-marched), and where it crosses
// the slab's plane; the background jobs that compute them; and the draws
// of each part.
//
// The renderer's frame decides which part a frame draws (the proxy while
// the camera moves, full detail step by step at rest) and binds the program
// and its uniforms; a drawable draws its part with it. All calls on the
// thread that owns the GL context; the background jobs only read the
// tractogram and their own copies, and are cancelled and waited for when
// the drawable goes.
#pragma once

#include "../gl.hpp"
#include "line_geometry.hpp"
#include "line_stream.hpp"
#include "occlusion.hpp"

#include <hz/core/render/renderer.hpp>
#include <hz/core/render/scene.hpp>

#include <glm/glm.hpp>

#include <array>
#include <atomic>
#include <future>
#include <memory>
#include <vector>

namespace hz::core::render {

struct Program;

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

// A full-detail chunk to draw: chunk `chunk` of the tractogram of the
// renderer's object `object`, in brick `brick` (SIZE_MAX: not over bricks).
struct ChunkItem {
    std::size_t object, chunk, brick;
};

// The rectangle (normalised device coordinates) of a box's projection:
// `all` when a corner is behind the eye.
struct NdcRect {
    glm::dvec2 lo{1e30}, hi{-1e30};
    bool all = false;
};

class TractogramDrawable;

// Occlusion culling while full detail is drawn over bricks: the depth drawn
// so far as tiles, read back (with `read`) after every cull_refresh_points()
// input points of a tractogram, and (with `skip` too) the chunks of bricks
// hidden behind it skipped.
struct Culling {
    bool read = false, skip = false;
    DepthTiles tiles;
    std::uint64_t since = 0;
    // Whether `it` (a chunk of `t`) is hidden behind the tiles.
    bool hidden(const TractogramDrawable &t, const ChunkItem &it, const glm::mat4 &view_proj) const;
    // Counts `it` as drawn; true once the depth is due to be read back.
    bool drew(const TractogramDrawable &t, const ChunkItem &it);
    // Reads the depth drawn so far into the bound draw framebuffer (w x h)
    // back into the tiles, through `scratch`; multisampled: culling stops.
    void refresh(std::vector<float> &scratch, int w, int h);
    // The chunks after items[i] of the same tractogram `t` still to be drawn
    // (not hidden now: depth only comes nearer), one per core: built ahead.
    void upcoming(const TractogramDrawable &t, const std::vector<ChunkItem> &items, std::size_t i, const glm::mat4 &view_proj,
                  std::vector<std::size_t> &next) const;
};

class TractogramDrawable {
public:
    // What every tractogram's drawable shares with the renderer; all outlive it.
    struct Context {
        const RenderSettings &settings;
        FrameStats &stats;   // counters of the frame being drawn, and points totals
        LineStream &stream;  // GL buffers of chunks, against the memory budget
    };

    // Object `o` (the renderer's object `index`; its data outlives the
    // drawable) drawn as lines or `tubes`, decimated to `tol_mm` (the
    // proxy to tol_mm x `proxy_scale`, its level's); above
    // settings.lod_points points with a proxy whose finest level draws
    // `finest_points`, and background jobs started (bricks, shell proxy,
    // fibre volume) as the settings ask and unless `o` is provisional.
    // Small objects are built now.
    TractogramDrawable(const Context &ctx, const Object &o, std::size_t index, bool tubes, double tol_mm, int proxy_scale,
                       double finest_points);
    ~TractogramDrawable();
    TractogramDrawable(const TractogramDrawable &) = delete;
    TractogramDrawable &operator=(const TractogramDrawable &) = delete;

    const std::shared_ptr<LineData> &lines() const { return lines_; }
    const Bounds &bounds() const { return bounds_; }
    std::uint64_t points() const { return points_total_; }
    std::uint64_t streamlines() const { return streamlines_; }
    std::uint64_t segments() const { return segments_; }  // (an upper bound until a large one is drawn)

    // ----------------------------------------------------------- full detail
    std::size_t chunk_count() const { return chunks_.size(); }
    std::uint64_t chunk_points(std::size_t k) const { return chunks_[k].points; }
    // Draws full-detail chunk k (see LineStream::draw) with the bound program.
    void draw_chunk(std::size_t k, const std::vector<std::size_t> *next = nullptr);
    // Full-detail chunk k is hidden: not drawn (nor built); counted as culled.
    void cull_chunk(std::size_t k);
    // Every full-detail chunk. Over bricks: nearest the camera v first, those
    // hidden behind what the frame has drawn skipped where `cull` (an opaque
    // object drawn into a single-sampled w x h target with depth testing;
    // with settings.occlusion_skip off the depth is read all the same).
    // `object`: this drawable's object in the renderer; `scratch`: reused.
    void draw_full(std::size_t object, const View &v, const glm::mat4 &view_proj, int w, int h, bool cull, std::vector<float> &scratch);

    // ---------------------------------------------------------------- bricks
    bool over_bricks() const { return bricks_ != nullptr; }
    // Whether the cut into bricks is still being computed.
    bool bricks_pending() const { return brick_job_.valid(); }
    // Waits for the cut at most `ms`.
    void wait_bricks(double ms) const;
    // Adopts the cut if done (with `wait`, once it is): full detail becomes
    // chunks over bricks. True if it was adopted (chunk indices changed).
    bool adopt_bricks(bool wait);
    // The full-detail chunks in the order they are drawn from camera v, its
    // bricks nearest centre first (over bricks only).
    std::vector<ChunkItem> brick_sequence(std::size_t object, const View &v) const;
    // Whether brick b lies behind `tiles` (empty: nothing drawn yet).
    bool brick_hidden(std::size_t b, const DepthTiles &tiles, const glm::mat4 &view_proj) const;
    // Input points drawn between two readbacks of the depth (a readback
    // waits for llvmpipe to finish what it was given).
    std::uint64_t cull_refresh_points() const { return std::max<std::uint64_t>(kChunkPoints, points_total_ / 64); }

    // ----------------------------------------------------------------- proxy
    bool has_lod_proxy() const { return !proxy_chunks_.empty(); }
    // How many proxy chunks draw about `target_points` points (at least one).
    std::size_t proxy_chunks_for(double target_points) const;
    // Draws proxy chunk k with the bound program.
    void draw_proxy_chunk(std::size_t k);
    // Builds the proxy again decimated for a level's `proxy_scale`, if it changed.
    void sync_proxy_scale(int proxy_scale);
    // Replaces the uniform proxy by the shell proxy once computed (with
    // `wait`, once it is); true if it did.
    bool adopt_shell_proxy(bool wait, int proxy_scale);

    // ---------------------------------------------------------- fibre volume
    bool has_fibre_volume() const { return fibre_tex_[0] != 0; }
    // Uploads the fibre volume once computed (with `wait`, once it is);
    // true if it was adopted.
    bool adopt_fibre_volume(bool wait);
    // The fibre volume's box projected by `view_proj`.
    NdcRect fibre_box_ndc(const glm::mat4 &view_proj) const;
    // How much smaller than a w x h frame the volume is ray-marched: at most
    // `most` times, and no more than keeps neighbouring rays within the
    // marching step (1.5 voxels) of each other across the box's projection.
    int volume_downscale(const glm::mat4 &view_proj, int w, int h, int most) const;
    // Draws the fibre volume with its bound program `p` (uniforms set but
    // the volume's): one triangle over the box's pixels of the w x h target
    // (drawn with `empty_vao`), blended over what is drawn unless `debug`,
    // writing the depth where the ray became half opaque. The lines it
    // stands for are a pixel wide in a frame `full_h` pixels high seen
    // with a vertical field of `fov_deg`.
    void draw_fibre_volume(Program &p, const glm::mat4 &view_proj, const glm::dmat4 &inv_view_proj, double fov_deg, int full_h, bool debug,
                           int w, int h, GLuint empty_vao);

    // ------------------------------------------------------- slab crossings
    const Crossings &crossings() const { return crossings_; }
    // Starts computing the crossings of the plane `axis` = `centre` on a
    // background thread (every core) unless those drawn or pending are of
    // it; a job for another plane is cancelled.
    void schedule_crossings(int axis, double centre);
    // Adopts the crossings once computed (with `wait`, once they are);
    // true if they changed.
    bool adopt_crossings(bool wait);
    bool computing_crossings() const { return crossing_job_.valid(); }
    // Draws the first `limit` crossings of chunks [k0, k1) with the bound program.
    void draw_crossings(std::size_t k0, std::size_t k1, std::uint64_t limit = UINT64_MAX);

    // Chunks over bricks are smaller: the nearest are drawn first, most of
    // their fragments seen and shaded (a progressive step of a 2^18-point
    // chunk of them takes 60-100 ms at 1280x800 against 25 for streamlines
    // in file order, most of whose fragments fail the depth test).
    static constexpr std::uint64_t kBrickChunkPoints = kChunkPoints / 4;

private:
    LineSource source(bool proxy) const;
    void schedule_bricks(const Tractogram &t);
    void use_bricks(std::shared_ptr<const Bricks> br);
    void set_proxy_pieces(std::shared_ptr<const std::vector<Piece>> pieces, int proxy_scale);
    void schedule_fibre_volume();
    static void release_crossings(Crossings &c);

    Context ctx_;
    std::size_t index_;
    bool tubes_;
    std::shared_ptr<LineData> lines_;
    Bounds bounds_;
    std::uint64_t points_total_ = 0, streamlines_ = 0, segments_ = 0;
    double tol_mm_ = 0, proxy_tol_mm_ = 0;  // the proxy is drawn at 1/scale of the size: decimated for its level's
    float max_radius_mm_ = 0;               // the widest tube
    // Full detail in chunks; cut into bricks (RenderSettings::occlusion):
    // chunks over bricks_->pieces, brick k's chunks [brick_chunks_[k],
    // brick_chunks_[k + 1]); else null.
    std::vector<LineChunk> chunks_;
    std::shared_ptr<const Bricks> bricks_;
    std::vector<std::size_t> brick_chunks_;
    std::future<Bricks> brick_job_;  // the cut, being computed
    std::shared_ptr<std::atomic<bool>> brick_cancel_;
    // What the proxy draws (outermost first, or in hash order: each proxy
    // level a prefix of it), in small chunks; the shell proxy being computed.
    std::shared_ptr<const std::vector<Piece>> proxy_;
    std::vector<LineChunk> proxy_chunks_;
    std::future<std::vector<Piece>> shell_;
    std::shared_ptr<std::atomic<bool>> shell_cancel_;
    // The slab's crossings: those drawn, and those being computed for the
    // plane and colouring in `crossing_next_`.
    Crossings crossings_, crossing_next_;
    std::future<std::vector<LineVertex>> crossing_job_;
    std::shared_ptr<std::atomic<bool>> crossing_cancel_;
    // The fibre volume (line_geometry.hpp), computed on a background thread
    // and kept as three 3D textures: colour x density (RGBA16F) and
    // direction (RGBA8), filtered, and the skip distance (R8), fetched.
    std::future<FibreVolume> fibre_job_;
    std::shared_ptr<std::atomic<bool>> fibre_cancel_;
    GLuint fibre_tex_[3] = {0, 0, 0};
    std::array<int, 3> fibre_dim_{};
    std::array<float, 3> fibre_origin_{};
    float fibre_voxel_mm_ = 0;
};

}  // namespace hz::core::render
