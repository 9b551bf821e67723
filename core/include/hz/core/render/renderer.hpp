// The renderer: draws a Scene with OpenGL 4.1 core into offscreen
// framebuffers (headless, `horizon render`) or the current window.
//
// Shading: every surface, tube and line is lit by the shading plugin its
// material names. The host assembles each GLSL program from its own prelude
// (HzShadePoint, environment functions, one uniform per schema parameter),
// the plugin's snippet and a host main() for the geometry (mesh, tube, line);
// plugins never call OpenGL. Programs are specialised on the material:
// `#define HZ_ZERO_<param>` for every float parameter that is exactly 0, so a
// plugin can drop the terms that vanish (no clearcoat code at clearcoat = 0).
//
// Threading: one Renderer per GL context; call everything on the thread where
// that context is current.
#pragma once

#include <hz/core/render/scene.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hz::core::render {

// A resolved camera.
// How an object's colours stand for values (its colour bar): `colormap`
// (colormap()) over `range` of the quantity `quantity` ("": the object's
// values) of object `object`.
struct ColourScale {
    std::string object, quantity, colormap;
    std::array<double, 2> range{0, 1};
};

struct View {
    Vec3 eye{0, 0, 100}, target{0, 0, 0}, up{0, 1, 0};
    double fov_deg = 30.0;
    double near_mm = 1.0, far_mm = 1000.0;
};

// 8-bit sRGB RGBA, rows top to bottom.
struct Image {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgba;
};

// Float RGBA, rows top to bottom (debug outputs of the GPU-equals-CPU check).
struct FloatImage {
    int width = 0, height = 0;
    std::vector<float> rgba;
};

struct RenderSettings {
    int width = 1280, height = 720;
    // MSAA samples (1 = off), clamped to GL_MAX_SAMPLES; 0 = automatic: 4,
    // or 1 when the scene has more than 200k streamline segments (llvmpipe
    // rasterises multisampled lines about 5-8x slower).
    int samples = 0;
    double lod_pixels = 0.5;  // streamline decimation tolerance in pixels (0 = keep every point)
    // Every frame through the linear HDR target, also where the display
    // path would do (read_hdr_image: .exr and .hdr pictures).
    bool hdr_output = false;
    // Level of detail: a tractogram of more than `lod_points` points gets a
    // proxy of about that many points, drawn while the camera moves and as
    // the first picture of a progressive frame (begin_progressive): at once a
    // uniform subsample of its streamlines, then (with shell_proxy) the
    // runs of streamlines nearest its outer surface, which is what a frame
    // of a dense tractogram shows, computed on a background thread and
    // adopted by update_proxies().
    double lod_points = 2e5;
    bool shell_proxy = true;
    // With shell_proxy: the fibre volume (a volume of the streamlines'
    // density, mean colour and main direction, ray-marched at the proxy's
    // size) replaces the shell's lines once computed in the background, where
    // no slab is set. The shell's lines stay for the slab and until then.
    bool fibre_volume = true;
    int fibre_grid = 128;  // voxels along the longest side
    // The shell proxy computed on every core (render --preview waits for
    // it) or on one (a window keeps a core for its first frames).
    bool shell_all_cores = false;
    // The proxy frame is drawn at 1/proxy_scale of the size, then upscaled.
    // These two are the proxy's base level; with proxy_levels,
    // proxy_levels() builds coarser and finer ones around it, among which a
    // window picks by its frame times (Renderer::set_proxy_level); without,
    // the base is the only one (a headless render draws no moving frames:
    // its shell is then computed for lod_points, not 4x as many).
    int proxy_scale = 4;
    bool proxy_levels = false;
    // A proxy frame's fibre volume is ray-marched smaller than the proxy,
    // down to 1/volume_scale of the size while its rays stay within 1.5
    // voxels (the marching step) of each other, then upscaled under the
    // proxy's lines.
    int volume_scale = 8;
    // A progressive frame, once complete, is kept (colour and depth, one
    // point per proxy_scale x proxy_scale block), and proxy frames draw it
    // again from their camera under the proxy, which fills what it did not
    // see: while the camera turns, the picture stays the data's.
    bool reproject = true;
    // Streamline geometry kept in GL buffers, all objects together (MiB);
    // chunks beyond it are built again each time they are drawn and
    // streamed through one ring buffer. No GL buffer is larger than one
    // chunk (2^18 input points).
    double gpu_memory_mb = 768;
    // Tractograms of at most this many points are built when the scene is
    // set; larger ones chunk by chunk as they are first drawn.
    std::uint64_t eager_points = 8000000;
    // Full-detail frames of tractograms above eager_points drawn brick by
    // brick, nearest first, skipping the bricks hidden behind what is drawn
    // (line_geometry.hpp: Bricks; occlusion.hpp). The picture is the same
    // (up to which of two streamlines at the same depth wins a pixel); a
    // dense whole-brain tractogram is most of its fragments behind its
    // outer layer. The cut into bricks is one more pass over the points
    // on a background thread when the scene is set (a window refines in
    // streamline order until it is done), and 8 bytes per piece: the grid
    // is the finest of at most brick_grid bricks along the longest side
    // (and at least 8) whose pieces fit brick_memory_mb; none fits: the
    // streamlines are drawn in their order.
    bool occlusion = true;
    bool occlusion_skip = true;  // false: bricks nearest first, none skipped (a check: the same picture)
    int brick_grid = 12;
    double brick_memory_mb = 768;
    // Material parameters, and a base colour shared by every vertex of an
    // object, become constants of the object's program instead of uniforms:
    // the GLSL compiler then folds everything computed from them, and
    // fragments only do the work that varies. Each new set of values
    // compiles a new program, so this is for scenes whose materials stay
    // fixed (`horizon render`); the window, whose sliders change them, keeps
    // uniforms.
    bool bake_materials = false;
    // Time each pass after the geometry (FrameStats::ao_ms): a glFinish
    // before and after it, which stalls a GPU's pipeline; `render` and a
    // window with --stats ask for it.
    bool time_passes = false;
    // A window at rest: once a progressive frame completed at once (within
    // begin_progressive) and was cheap (at most kRestAaMaxPrimitives points
    // and triangles drawn, kRestAaMaxPixels pixels, no volume rendered: by
    // what it drew, not by the clock, so that a scene always decides the
    // same way), this many jittered frames of its view (or
    // Scene::antialiasing's `frames` where more) averaged, one per
    // accumulate_step: supersampling where a frame is cheap. 0 or 1: none,
    // whatever the scene's `frames`; none either where Scene::antialiasing
    // is off.
    int rest_aa_frames = 0;
    static constexpr std::uint64_t kRestAaMaxPrimitives = 2000000;
    static constexpr std::uint64_t kRestAaMaxPixels = 1920 * 1080;
};

struct FrameStats {
    double upload_ms = 0, environment_ms = 0, draw_ms = 0, readback_ms = 0;
    // Of the scene (set_scene): input points of every tractogram, and the
    // points kept by decimation of those built when the scene was set.
    std::uint64_t points_kept = 0, points_total = 0;
    // Of the last frame or progressive step.
    std::uint64_t segments_drawn = 0, triangles_drawn = 0, points_drawn = 0, streamlines_drawn = 0;
    std::uint64_t chunks_drawn = 0, streamed_points = 0;  // streamed: built for this frame, not kept
    std::uint64_t crossings_drawn = 0;                    // the slab's crossings drawn as points (Slab::points)
    std::uint64_t reprojected_points = 0;                 // a proxy frame: points of the last still drawn again (reproject)
    std::uint64_t volumes_drawn = 0;                      // a proxy frame: tractograms drawn as their fibre volume
    std::uint64_t volume_rays = 0;                        // ... and the rays marched through them (pixels of its box)
    // Full-detail chunks hidden behind what was drawn, not drawn
    // (RenderSettings::occlusion): how many, their input points, and the
    // streamlines whose first piece they hold.
    std::uint64_t culled_chunks = 0, culled_points = 0, culled_streamlines = 0;
    // The frame's passes after the geometry, with RenderSettings::time_passes
    // (0 when off or not timed): ambient occlusion (with the resolve of the
    // frame's depth the passes read), depth cue.
    double ao_ms = 0, depth_cue_ms = 0;
    // The key light's shadow map (Scene::shadows) drawn for the last frame:
    // its milliseconds with time_passes (0: not timed, or the last one kept
    // because neither the light nor the scene changed), its side in
    // texels (0: no shadows drawn; as many as make a texel no finer than the
    // frame's pixel at the target, in steps of 256, at most 2048) and a
    // texel's side in mm.
    double shadow_ms = 0;
    int shadow_map = 0;
    double shadow_texel_mm = 0;
    // Volumes rendered by ray-marching (Object::transfer) in the last frame,
    // and the pass's milliseconds with time_passes.
    int volumes_rendered = 0;
    double volume_ms = 0;
    // Translucent layers composited in depth order in the last full frame
    // (depth peeling; 0: nothing translucent, 9: the eighth layer and a
    // last one in drawing order).
    int transparency_layers = 0;
    // Anti-aliasing (Scene::antialiasing): whether the edge pass ran over
    // the last frame (and its milliseconds with time_passes), and the
    // jittered frames averaged into the last still (1: none).
    bool edge_aa = false;
    double aa_ms = 0;
    int aa_frames = 1;
    bool proxy = false;                  // a level-of-detail proxy was drawn, or the frame drawn small and upscaled
    int proxy_level = 0;                 // ... at this level (Renderer::proxy_levels' index)
    int refine_step = 0;                 // progressive: the step (0: a whole frame)
    std::uint64_t refine_remaining = 0;  // progressive: chunks still to draw
    int samples = 1;                     // MSAA samples in use
};

// A level of the level-of-detail proxy: its frame drawn at 1/scale of the
// size, with the first `points` input points of its lines (a prefix of the
// shell proxy: its outermost runs; over a fibre volume 3/4 of them).
struct ProxyLevel {
    int scale = 4;
    double points = 2e5;
};
// The proxy's levels, cheapest first, around the base (scale, points) of
// RenderSettings::proxy_scale and lod_points: two coarser (twice the scale,
// then half the points too) and finer ones, each halving the scale (down to
// 1) or doubling the points in turn, up to 4 x lod_points. At (4, 2e5):
// (8, 1e5) (8, 2e5) [(4, 2e5)] (2, 2e5) (2, 4e5) (1, 4e5) (1, 8e5). Each costs
// about 1.3-1.8 times the one before (llvmpipe, 1280x800, bench/results).
std::vector<ProxyLevel> proxy_levels(int scale, double points);
// The index of the base level in proxy_levels()'s list (2).
int proxy_base_level(int scale, double points);

class Renderer {
public:
    // Needs a current GL 4.1+ core context. `reg` must outlive the renderer.
    explicit Renderer(const Registry &reg);
    ~Renderer();
    Renderer(const Renderer &) = delete;
    Renderer &operator=(const Renderer &) = delete;

    // Uploads the scene (geometry, colours, volumes), prepares the
    // environment and compiles the programs. Throws Error naming the object
    // and the problem (unknown shader or parameter, GLSL compile log, ...).
    // `view` sets the streamline decimation scale (pass fit_view's result).
    void set_scene(Scene scene, const View &view, const RenderSettings &settings);

    // Replaces one object's material at run time (the shading-model switch);
    // compiles the new program if needed. Throws Error.
    void set_material(std::size_t object, const Material &m);
    void set_visible(std::size_t object, bool visible);
    // Object::opacity of object `object` (below 1: composited with the
    // translucent objects from the next frame on). Throws Error naming the
    // object for a value outside [0, 1].
    void set_opacity(std::size_t object, double opacity);
    // The slicer (a volume drawn as slices): moves object `object`'s
    // slices (Object::slice_x/y/z, RAS+ mm; nullopt hides that slice, NaN
    // puts it in the middle),
    // only their quads redrawn; sets the value range its colormap spans
    // (Object::window; a rendered volume's transfer function too); shows
    // another of its 3D volumes (Object::volume_index, a 4D series; its
    // texture uploaded again, the window kept). Each throws Error naming the
    // object for a position outside the volume, lo >= hi or non-finite, an
    // index beyond the file's volumes, or an object that is not a volume.
    void set_slices(std::size_t object, std::optional<double> x, std::optional<double> y, std::optional<double> z);
    void set_window(std::size_t object, double lo, double hi);
    void set_volume_index(std::size_t object, std::uint64_t index);
    // The RAS+ mm box of a volume object's grid (its voxels' outer faces),
    // its number of 3D volumes and its window; nullopt for an object that is
    // not a volume.
    struct VolumeExtent {
        Bounds box;
        std::uint64_t volumes = 1;
        std::array<double, 2> window{0, 1};
    };
    std::optional<VolumeExtent> volume_extent(std::size_t object) const;
    // Replaces object `i` (same kind) with new data, colouring and material,
    // re-uploading only that object. Throws Error.
    void replace_object(std::size_t i, Object o);
    void set_exposure(double exposure);
    // Switches and sets ambient occlusion (Scene::ambient_occlusion); a
    // still image is out of date. Throws Error for values outside
    // radius_mm in (0, 1000], strength in [0, 1].
    void set_ambient_occlusion(const AmbientOcclusion &ao);
    // Switches and sets depth cueing (Scene::depth_cue). Throws Error for a
    // strength outside [0, 1].
    void set_depth_cue(const DepthCue &cue);
    // Switches and sets the key light's shadows (Scene::shadows). Throws
    // Error for values outside those check_shadows accepts.
    void set_shadows(const Shadows &s);
    // Edge anti-aliasing on or off, and the jittered frames of a still
    // (render()); throws Error as check_antialiasing.
    void set_antialiasing(const Antialiasing &aa);
    // Sets what is drawn over the picture (Scene::annotations): kept in the
    // scene for whoever paints them (annotations.hpp); frames do not change.
    void set_annotations(const Annotations &a);
    // Crops the streamlines to a slab (Scene::slab), or not (nullopt). With
    // Slab::points, the crossings of the plane are computed on background
    // threads: update_proxies() adopts them (render() waits for them).
    void set_slab(std::optional<Slab> slab);
    // Switches RenderSettings::bake_materials. The window bakes once the
    // material panel has been left alone for a moment and goes back to
    // uniforms while a slider moves; programs of both forms stay cached.
    void set_bake_materials(bool bake);
    // While interacting, objects with a level-of-detail proxy are replaced
    // by it (Object::proxy_for).
    void set_interacting(bool interacting);
    // The proxy's level (proxy_levels(settings.proxy_scale, lod_points)'s
    // index, clamped to it, with RenderSettings::proxy_levels; else 0, the
    // base, the only one; set_scene starts at the base level): the window
    // raises it while its moving frames are fast and lowers it when they
    // are slow. Takes effect at the next proxy frame. GL thread.
    void set_proxy_level(int level);
    int proxy_level() const;
    int proxy_level_count() const;
    const std::vector<ProxyLevel> &proxy_levels() const;  // (of the scene's settings)
    // Adopts the level-of-detail proxies computed in the background since
    // the last call (RenderSettings::shell_proxy); with `wait`, waits for
    // all of them first. Returns true if a proxy changed (a proxy frame
    // shown now is out of date; a full-detail frame is not). GL thread.
    bool update_proxies(bool wait);
    // Background work whose result update_proxies() adopts is under way
    // (the slab's crossings, Slab::points): a window keeps polling.
    bool computing() const;
    const Scene &scene() const;

    // Camera fitted to the visible objects for the scene's camera spec.
    View fit_view(const Camera &c, double aspect) const;

    // Draws a frame into the offscreen target of the given size: at rest,
    // Scene::antialiasing's `frames` jittered frames averaged.
    void render(const View &view, int width, int height);
    // Draws into the currently bound framebuffer 0 (the window) instead.
    void render_to_window(const View &view, int width, int height);

    // Progressive drawing, for a window at rest: begin_progressive draws
    // the first picture (everything small, and the level-of-detail proxy of
    // each large tractogram) into the offscreen target; each
    // progressive_step adds full-detail streamlines over it for about
    // `budget_ms` (at least one chunk) and returns true once the frame is
    // complete; the finished image equals render()'s. present() copies the
    // offscreen image into the window (framebuffer 0). Any change to the
    // scene (see generation()) ends a progressive frame: begin again.
    // `at_once` (for a window that knows full detail is cheap): no proxy
    // picture first, every step drawn now, so the frame is complete on
    // return (unless the tractograms' bricks are still being computed:
    // then as without it).
    void begin_progressive(const View &view, int width, int height, bool at_once = false);
    bool progressive_step(double budget_ms);
    bool refining() const;
    // The still's jittered frames (RenderSettings::rest_aa_frames): true
    // while more are due; accumulate_step draws one, leaves the average so
    // far as the picture present() shows (smoothed by the edge pass while
    // fewer than 4), and returns true once the last is in. Any
    // begin_progressive, render or render_to_window ends it.
    bool accumulating() const;
    bool accumulate_step();
    void present(int width, int height);
    // Bumped by every change to what a frame shows (objects, materials,
    // visibility, exposure): a still image is current while it is unchanged.
    std::uint64_t generation() const;
    // Streamlines of the tractograms drawn through a level-of-detail proxy.
    std::uint64_t streamlines_with_proxy() const;
    // The colour scales of the visible objects a colormap colours (data
    // colouring of streamlines and meshes, volumes' slices), in scene
    // order, with the ranges they are drawn with.
    std::vector<ColourScale> colour_scales() const;
    // Reads the last offscreen frame.
    Image read_image();
    // The last offscreen frame before the tone curve: linear RGB radiance
    // with the scene's exposure applied (what the curve was given), alpha 1;
    // rows top to bottom. Needs RenderSettings::hdr_output (then every
    // frame goes through the RGBA16F target) and a full-size frame (not the
    // proxy's); throws Error otherwise.
    FloatImage read_hdr_image();
    // Reads the window's back buffer after render_to_window (screenshots).
    Image read_window_image(int width, int height);

    // GPU-equals-CPU support: renders without tonemapping, MSAA or the
    // environment, lit by exactly one light, with the shading inputs as extra
    // outputs. outputs[0] = hz_shade's raw value for that light (alpha 1 where
    // covered, 0 elsewhere), [1] = n, [2] = l, [3] = v, [4] = t (xyz, world).
    std::array<FloatImage, 5> render_debug(const View &view, int width, int height);

    const FrameStats &stats() const;
    std::string gl_description() const;

    // The GLSL of an object's program (for `horizon render --dump-glsl`).
    std::string program_source(std::size_t object) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// The camera for `c` fitted to the visible objects of `scene`.
View fit_view(const Scene &scene, const Camera &c, double aspect);
// Axis-aligned RAS+ bounds of the visible objects.
Bounds scene_bounds(const Scene &scene);

// The radius (mm) each streamline of tractogram object `o` is drawn with as
// a tube: o.radius_mm, times sqrt(cluster size / the median size) clamped to
// [0.35, 3] when o.clustering asks for width by size and the tractogram has
// a per-streamline "cluster_size" array. (A per-streamline "highlight" array
// mixes a streamline's colour towards white by its value in [0, 1]; a
// per-streamline "radius_mm" array, clamped to [0.001, 100], replaces
// both: connectome edges.)
std::vector<float> tube_radii(const Object &o);
// The colour (sRGB, 0..1) of cluster colour id `id` in "cluster" colouring (legends).
std::array<double, 3> cluster_palette(double id);

// Looks up a shader plugin by id or by the last component of its id.
const LoadedPlugin *find_shader(const Registry &reg, const std::string &name);

// 256-entry RGB colormap lookup, t in [0,1]; names: viridis, inferno, gray, coolwarm, hot.
std::array<float, 3> colormap(const std::string &name, double t);

// A fragment program: `head` (the host's declarations), a shader plugin's
// GLSL `snippet`, then `tail` (the host's main). The snippet is GLSL source
// string 1 from line 1 (#line 1 1), the host's code string 0 with its own
// line numbers, so compiler messages name the snippet's lines as its author
// numbers them.
std::string with_snippet(const std::string &head, const char *snippet, const char *tail);
// One compiler error line (Mesa's "1:3(12): error: ...", NVIDIA's
// "1(3) : error ...", glslang's "ERROR: 1:3: ...") as "the plugin's GLSL
// snippet, line 3, column 12: ..." (or the host's code around it); a line
// of another form is returned as it is.
std::string glsl_error_where(const std::string &line);
// The fragment program the renderer builds around `shader`'s snippet for
// `domain` (a mesh or a line), at its parameters' defaults, with uniforms or
// (`baked`) constants, the environment on and a directional and a point
// light: what a GLSL compiler must accept (`horizon validate`).
std::string check_fragment_program(const LoadedPlugin &shader, hz_shade_domain domain, bool baked);

}  // namespace hz::core::render
