// The `horizon` subcommands.
#pragma once

#include <hz/core/plugin_host.hpp>
#include <hz/core/render/context.hpp>
#include <hz/core/render/renderer.hpp>
#include <hz/core/render/buan.hpp>
#include <hz/core/render/timeline.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <array>
#include <optional>
#include <string>
#include <vector>

namespace hz::host {

struct GlobalOptions {
    std::vector<std::filesystem::path> plugin_dirs;
    double plugin_timeout_s = 10.0;  // per trial load of a plugin file
};

struct ValidateOptions {
    std::string file;
    bool json = false;
    double timeout_s = 60.0;
    std::vector<std::string> data_files;
    std::uint64_t seed = 1;
    bool no_gpu = false;  // accept shaders without compiling their GLSL (no headless OpenGL here)
};

// The frame's passes (depth cues, anti-aliasing), the same for `render`,
// `view` and `demo`: they replace a scene file's.
struct PassOptions {
    bool ao = false, no_ao = false;                // --ao, --no-ao
    double ao_radius = 0;                          // --ao-radius MM (0: the scene's, 3 mm by default)
    double ao_strength = -1;                       // --ao-strength S (< 0: the scene's, 0.8 by default)
    bool depth_cue = false, no_depth_cue = false;  // --depth-cue, --no-depth-cue
    double depth_cue_strength = -1;                // --depth-cue-strength S (< 0: the scene's, 0.6 by default)
    bool shadows = false, no_shadows = false;      // --shadows, --no-shadows
    double shadow_strength = -1;                   // --shadow-strength S (< 0: the scene's, 0.75 by default)
    double shadow_softness = -1;                   // --shadow-softness MM (< 0: the scene's, 0.5 mm by default)
    bool no_aa = false;                            // --no-aa
    int aa_frames = 0;                             // --aa-frames N (0: the scene's, 1 by default)
    void apply(core::render::Scene &s) const {
        if (aa_frames > 0) s.antialiasing.on = true, s.antialiasing.frames = aa_frames;
        if (no_aa) s.antialiasing.on = false;
        if (shadows || shadow_strength >= 0 || shadow_softness >= 0) s.shadows.on = true;
        if (no_shadows) s.shadows.on = false;
        if (shadow_strength >= 0) s.shadows.strength = shadow_strength;
        if (shadow_softness >= 0) s.shadows.softness_mm = shadow_softness;
        if (depth_cue || depth_cue_strength >= 0) s.depth_cue.on = true;
        if (no_depth_cue) s.depth_cue.on = false;
        if (depth_cue_strength >= 0) s.depth_cue.strength = depth_cue_strength;
        if (ao || ao_radius > 0 || ao_strength >= 0) s.ambient_occlusion.on = true;
        if (no_ao) s.ambient_occlusion.on = false;
        if (ao_radius > 0) s.ambient_occlusion.radius_mm = ao_radius;
        if (ao_strength >= 0) s.ambient_occlusion.strength = ao_strength;
    }
};

// Volume rendering, the same for `render` and `view`: every volume (a data
// file, or a scene's slices or volume) ray-marched through the transfer
// function `transfer` (a preset, or a JSON file: then an input the outputs
// may not replace); empty: as the scene says. Throws Error.
struct VolumeOptions {
    std::string transfer;  // --volume-render PRESET|FILE.json
    // --volume-index N: every volume of a 4D series shows its N-th 3D volume
    // (Object::volume_index; the renderer says when a file has fewer)
    std::optional<std::uint64_t> volume_index;
    bool rgb = false;  // --rgb: every volume's slices in colour (Object::rgb)
    // --peaks: every volume of 3N values a voxel (MRtrix3's sh2peaks, DIPY's
    // peaks as NIfTI) drawn as peak glyphs (Object::peaks); a PAM5 file is
    // always. --peak-scale S, --peak-threshold F, --peaks-whole,
    // --peaks-voxel-frame: PeakOptions for every peaks object (a scene
    // file's too).
    bool peaks = false;
    std::optional<double> peak_scale, peak_threshold;
    bool peaks_whole = false, peaks_voxel_frame = false;
    // --odfs: every volume of SH coefficients (1, 6, 15, 28, 45, ... a
    // voxel) drawn as ODF glyphs on its slices (Object::odfs); --sh-basis,
    // --sh-not-legacy, --odf-sphere, --odf-scale: OdfOptions for every ODF
    // object (a scene file's too).
    bool odfs = false;
    std::string sh_basis;  // descoteaux07 | tournier07 | mrtrix3 ("": as given)
    bool sh_not_legacy = false;
    std::optional<int> odf_sphere;
    std::optional<double> odf_scale;
    // --tensors: every volume of 6 values a voxel drawn as tensor glyphs
    // (Object::tensors); --tensor-order: TensorOptions::order for every
    // tensor object.
    bool tensors = false;
    std::string tensor_order;
    // --roi-images: every volume is a mask or a label volume (dipy_horizon's
    // --roi_images), its regions' areas and outlines on its slices and their
    // surfaces in 3D (Object::labels, show_as_labels); --lut FILE (their
    // colours and names, FreeSurferColorLUT format), --label-fill F,
    // --no-label-surfaces: LabelOptions for them and for a scene file's
    // labels objects.
    bool roi_images = false;
    std::string lut;
    std::optional<double> label_fill;
    bool no_label_surfaces = false;
    void apply_labels(core::render::Scene &s) const {
        const bool options = !lut.empty() || label_fill || no_label_surfaces;
        if (!roi_images && !options) return;
        core::render::LabelTable table;
        if (!lut.empty()) {
            table = core::render::read_label_table(lut);
            s.files.push_back(lut);
        }
        std::vector<core::render::Object> out;
        bool any = false;
        for (std::size_t i = 0; i < s.objects.size(); ++i) {
            core::render::Object o = std::move(s.objects[i]);
            const bool was = bool(o.labels);
            if (!was && !(roi_images && o.kind == HZ_DATA_VOLUME && !o.peaks && !o.odfs && !o.tensors)) {
                out.push_back(std::move(o));
                continue;
            }
            any = true;
            core::render::LabelOptions lo = was ? o.labels->options : core::render::LabelOptions{};
            if (!was) lo.surfaces = true;
            if (!lut.empty()) lo.table = table;
            if (label_fill) lo.fill = *label_fill;
            if (no_label_surfaces) lo.surfaces = false;
            // (a scene's labels object: its surfaces, the next object, made again)
            if (was && i + 1 < s.objects.size() && s.objects[i + 1].name == o.name + " surfaces") ++i;
            std::optional<core::render::Object> surfaces = core::render::show_as_labels(o, lo, o.name);
            out.push_back(std::move(o));
            if (surfaces) out.push_back(std::move(*surfaces));
        }
        s.objects = std::move(out);
        if (!any)
            throw core::Error(
                "--lut, --label-fill, --no-label-surfaces: no label volume (give --roi-images, or a scene file's labels object)");
    }
    void apply(core::render::Scene &s) const {
        apply_labels(s);
        for (auto &o : s.objects) {
            if (!o.tensors && !(tensors && o.kind == HZ_DATA_VOLUME)) continue;
            if (o.tensors && tensor_order.empty()) continue;
            core::render::TensorOptions to = o.tensors ? o.tensors->options : core::render::TensorOptions{};
            if (!tensor_order.empty()) to.order = tensor_order;
            core::render::show_as_tensors(o, to, o.name);
        }
        const bool odf_options = !sh_basis.empty() || sh_not_legacy || odf_sphere || odf_scale;
        for (auto &o : s.objects) {
            if (!o.odfs && !(odfs && o.kind == HZ_DATA_VOLUME)) continue;
            if (o.odfs && !odf_options) continue;
            core::render::OdfOptions oo = o.odfs ? o.odfs->options : core::render::OdfOptions{};
            if (!sh_basis.empty()) oo.basis = sh_basis == "mrtrix3" ? "tournier07" : sh_basis, oo.legacy = sh_basis != "mrtrix3";
            if (sh_not_legacy) oo.legacy = false;
            if (odf_sphere) oo.sphere = *odf_sphere;
            if (odf_scale) oo.scale = *odf_scale;
            core::render::show_as_odfs(o, oo, o.name);
        }
        const bool options = peak_scale || peak_threshold || peaks_whole || peaks_voxel_frame;
        for (auto &o : s.objects) {
            if (!o.peaks && !(peaks && o.kind == HZ_DATA_VOLUME)) continue;
            if (o.peaks && !options) continue;
            core::render::PeakOptions po = o.peaks ? o.peaks->options : core::render::PeakOptions{};
            if (peak_scale) po.scale = *peak_scale;
            if (peak_threshold) po.threshold = *peak_threshold;
            if (peaks_whole) po.whole = true;
            if (peaks_voxel_frame) po.frame = "voxel";
            core::render::show_as_peaks(o, po, o.name);
        }
        if (volume_index)
            for (auto &o : s.objects)
                if (o.kind == HZ_DATA_VOLUME) o.volume_index = *volume_index;
        if (rgb)
            for (auto &o : s.objects)
                if (o.kind == HZ_DATA_VOLUME) o.rgb = true;
        if (transfer.empty()) return;
        const bool file = std::filesystem::path(transfer).extension() == ".json";
        const core::render::TransferFunction tf = file ? core::render::load_transfer(transfer) : core::render::transfer_preset(transfer);
        if (file) s.files.push_back(transfer);
        for (auto &o : s.objects)
            if (o.kind == HZ_DATA_VOLUME) o.transfer = tf;
    }
};

// Annotations, the same for `render`, `view` and `demo`: they replace a scene file's.
struct AnnotationOptions {
    bool all = false, none = false;                                   // --annotations, --no-annotations
    bool colour_bar = false, orientation = false, scale_bar = false;  // --colour-bar, --orientation, --scale-bar
    void apply(core::render::Scene &s) const {
        if (all) s.annotations = {true, true, true};
        if (none) s.annotations = {};
        if (colour_bar) s.annotations.colour_bar = true;
        if (orientation) s.annotations.orientation = true;
        if (scale_bar) s.annotations.scale_bar = true;
    }
};

// The look in one flag each (as dipy_horizon's --bg_color and per-tractogram
// colours), the same for `render`, `view` and `demo`: they replace a scene
// file's. A colour is black, white, grey (gray) or R,G,B in [0, 1].
std::array<double, 3> parse_colour(const std::string &what, const std::string &text);  // throws Error naming `what`
struct StyleOptions {
    // --background COLOUR: the picture's pixels there (sRGB-encoded values;
    // the scene's background is the radiance its exposure and tone curve
    // show as them).
    std::string background;
    std::string tracts;  // --tract-colour direction|random|COLOUR (linear, as a scene file's colours)
    // --glass-brain FILE: a surface (pial, GIFTI), or a volume whose voxels
    // above 0 make one (a brain mask), added as glass around the data
    std::string glass_brain;
    void add_glass_brain(const core::Registry &reg, core::render::Scene &s) const;
    // --buan PVALUES.npy ... (one a tractogram given, in order; dipy_horizon's
    // --buan), --buan-threshold P, --buan-highlight COLOUR: show_buan.
    std::vector<std::string> buan;
    double buan_threshold = 0.05;
    std::string buan_highlight = "1,0,0";
    // Every streamlines object: "direction" as drawn by default, "random" a
    // solid colour each from the cluster palette (the k-th tractogram the
    // k-th entry), a colour solid. Throws Error.
    void apply(core::render::Scene &s) const;
};

struct DemoOptions {
    std::string out_dir = "horizon-demo";
    std::uint64_t nb_streamlines = 5000;
    std::uint64_t seed = 1;
    std::string size = "1280x720";
    bool window = true;  // open the window afterwards when a display exists
    PassOptions passes;
    AnnotationOptions annotations;
    StyleOptions style;
};

struct ClusterOptions {
    std::string input;
    std::string algorithm = "qbx";    // a clustering plugin's id, or its last part (qb, qbx, qbx_merge)
    std::vector<std::string> params;  // --param NAME=VALUE
    std::vector<double> thresholds;   // empty: the plugin's defaults
    std::uint32_t nb_points = 0;      // 0: the plugin's default
    std::string order = "file";       // file | shuffle
    std::uint64_t seed = 0;
    unsigned threads = 0;
    std::string mode;  // exact | fast; empty: the plugin's default
    std::string labels, centroids, out;
    int level = -1;  // centroid level; -1: the deepest
    bool force = false, json = false;
};

struct FilterOptions {
    std::string input;
    std::vector<std::string> include, exclude;  // ROI specs: sphere:X,Y,Z,R, box:X0,Y0,Z0,X1,Y1,Z1 or a mask file
    double min_length = 0, max_length = 0;      // mm; max 0: no upper bound
    bool ends_only = false, invert = false;
    std::string out;  // the selected streamlines (any streamline format)
    std::string ids;  // their indices, one per line ("-": stdout)
    bool force = false, json = false;
};

// Level-of-detail knobs, the same for `render` and `view`.
struct LodOptions {
    double lod_pixels = 0.5;           // streamline decimation tolerance in pixels (0 = every point)
    double lod_points = 2e5;           // tractograms above this many points get a proxy of about this many
    double gpu_memory_mb = 768;        // streamline geometry kept in GL buffers; the rest is streamed
    int lod_scale = 4;                 // the proxy frame is drawn at 1/lod_scale of the size
    int lod_volume_scale = 8;          // its fibre volume ray-marched down to 1/lod_volume_scale (rays <= 1.5 voxels apart)
    std::string lod_proxy = "volume";  // volume (the fibre volume under the shell), shell (the outer layer) or uniform
    std::string lod_reproject = "on";  // the last complete still drawn again under the proxy while the camera moves
    std::string lod_occlusion = "on";  // full detail drawn brick by brick, nearest first, hidden bricks skipped (order: none skipped)
    void apply(core::render::RenderSettings &rs) const {
        rs.lod_pixels = lod_pixels, rs.lod_points = lod_points, rs.gpu_memory_mb = gpu_memory_mb, rs.proxy_scale = lod_scale;
        rs.volume_scale = lod_volume_scale;
        rs.shell_proxy = lod_proxy == "shell" || lod_proxy == "volume";
        rs.fibre_volume = lod_proxy == "volume";
        rs.reproject = lod_reproject == "on";
        rs.occlusion = lod_occlusion != "off";
        rs.occlusion_skip = lod_occlusion == "on";
    }
};

// Seconds since the program started (the window's --stats, progress lines).
double seconds_since_launch();

// Several subjects at once, the same for `render` and `movie`: --grid files
// (one cell a data file given) or folders (one a folder: a subject's files
// together), titled by the file's or folder's name; --grid-columns N. They
// replace a scene file's grid (its cells from the files its objects read).
struct GridOptions {
    std::string mode;  // "", files, folders
    std::optional<int> columns;
    void apply(core::render::Scene &s) const;
};

// How a picture of a grid scene is cut: `cells` (grid_cells; empty: no
// grid, one tile the whole picture) in `columns` x `rows` tiles of
// tile_w x tile_h pixels, filled row by row from the top left.
struct GridLayout {
    std::vector<int> cells;
    int columns = 1, rows = 1, tile_w = 0, tile_h = 0;
    bool on() const { return !cells.empty(); }
};
// Throws Error when a tile would be smaller than 16 x 16 pixels.
GridLayout grid_layout(const core::render::Scene &s, int w, int h);
// Renderer r's picture of w x h seen from `view` (fitted at the tile's
// aspect): one frame, or with a grid one a tile, each showing the objects
// of its cell and those of every cell (of those visible), its title at the
// top left; tiles without a cell show the background.
core::render::Image render_picture(core::render::Renderer &r, const GridLayout &g, const core::render::View &view, int w, int h);

// A scene's timeline played on renderer `r` (which holds the scene, seen
// from `start` at time 0): at(t) sets the objects' visibility, material
// parameters and slices of time t where they differ from what r draws, and
// returns the camera's view (core/render/timeline.hpp).
class TimelinePlayer {
public:
    TimelinePlayer(core::render::Renderer &r, const core::render::View &start, double aspect);
    core::render::View at(double t);
    double duration() const;

private:
    core::render::Renderer &r_;
    core::render::TimelineState start_;
    std::vector<std::optional<core::render::View>> keys_;
};

struct RenderOptions {
    std::vector<std::string> inputs;  // data files, or one scene file (.json)
    std::string scene;                // the scene file, when one was given (named in errors)
    std::string view;                 // a named camera view fitted to the scene (empty: the scene's own)
    std::string out = "horizon.png";
    std::string size = "1280x720";
    int samples = 0;  // 0: automatic (RenderSettings)
    LodOptions lod;
    PassOptions passes;
    AnnotationOptions annotations;
    VolumeOptions volumes;
    StyleOptions style;
    bool preview = false;        // draw the level-of-detail proxy only (the window's first picture)
    bool force = false;          // replace an existing output
    int frames = 1;              // frames to draw (timing: the median of frames 2..N)
    bool legend = false;         // list the clusters shown (colour, name, size) over the picture
    std::string slab;            // AXIS=CENTRE,HALF or AXIS=CENTRE,points (replaces a scene file's slab)
    std::optional<double> time;  // --time T: the scene's timeline at T seconds (TimelinePlayer)
    GridOptions grid;
    bool json = false;
};

// `horizon movie`: a turntable of the scene (its camera turned about the
// superior axis through its target) to .mp4, .webm or an image sequence.
struct MovieOptions {
    std::vector<std::string> inputs;
    std::string view;
    std::string out = "horizon.mp4";
    std::string size = "1280x720";
    // The movie's length: given, else the scene's timeline's duration, else
    // 10 s; the turn over the whole movie: given, else 360 degrees without a
    // timeline and none with one (its own turntable).
    std::optional<double> seconds;
    int fps = 30;
    std::optional<double> degrees;
    GridOptions grid;
    LodOptions lod;
    PassOptions passes;
    AnnotationOptions annotations;
    VolumeOptions volumes;
    StyleOptions style;
    bool force = false, json = false;
};

struct ShaderCheckOptions {
    std::string shader;  // empty: every shading plugin
    int sets = 8;        // parameter sets per shader (the first: the defaults)
    int size = 160;      // pixels per side
    std::uint64_t seed = 1;
    double rel = 2e-3, abs = 1e-4;
    bool json = false, verbose = false;
};

struct ViewOptions {
    std::vector<std::string> inputs;  // data files, or one scene file
    std::string size = "1280x800";
    int samples = 0;
    std::string script;  // scripted input (tests)
    bool exit_after_script = true;
    std::string screenshot_dir = ".";
    LodOptions lod;
    PassOptions passes;
    AnnotationOptions annotations;
    VolumeOptions volumes;
    StyleOptions style;
    std::string stats;                          // --stats FILE.json: per-frame times and what was drawn
    double lod_frame_ms = 33;                   // moving frames kept within this by the proxy's level (0: the level fixed)
    bool explore = false;                       // Fig. 5: QuickBundlesX centroids, expand / hide / repeat
    std::string algorithm = "qbx";              // --explore's clustering plugin (id or last part)
    std::uint64_t cluster_size_min = 0;         // --cluster-size-min N: clusters of fewer streamlines are not shown
    double cluster_length_min = 0;              // --cluster-length-min MM: nor those with a shorter centroid
    std::vector<std::string> params;            // its --param NAME=VALUE
    std::string view;                           // a named camera view fitted to the scene (empty: the scene's own)
    std::vector<std::string> include, exclude;  // regions of interest over the first tractogram (as `filter` takes them)
    std::string slab;                           // AXIS=CENTRE,HALF (cropped) or AXIS=CENTRE,points (crossings)
};
core::render::Slab parse_slab(const std::string &spec);

core::Registry load_registry(const GlobalOptions &g);

// Every plugin (or the one with id `only`, with its parameters), or --json.
int cmd_plugins(const GlobalOptions &g, bool json, const std::string &only = "");
int cmd_validate(const GlobalOptions &g, const ValidateOptions &o);
int cmd_info(const GlobalOptions &g, const std::string &file, bool json, bool verify);
int cmd_convert(const GlobalOptions &g, const std::string &in, const std::string &out, bool force);
int cmd_cluster(const GlobalOptions &g, const ClusterOptions &o);
int cmd_filter(const GlobalOptions &g, const FilterOptions &o);
int cmd_brdf(const GlobalOptions &g, const std::string &shader_id);
int cmd_demo(const GlobalOptions &g, const DemoOptions &o);
int cmd_render(const GlobalOptions &g, const RenderOptions &o);
int cmd_movie(const GlobalOptions &g, const MovieOptions &o);
int cmd_view(const GlobalOptions &g, const ViewOptions &o);
bool have_display();
int view_scene(const core::Registry &reg, core::render::Scene scene, const ViewOptions &o);
// The same, the scene read by `make_scene` once the window is open (it shows
// the reading's progress meanwhile; see load_in_window in view.cpp).
int view_scene(const core::Registry &reg, const std::function<core::render::Scene()> &make_scene, const ViewOptions &o);
std::pair<int, int> parse_size(const std::string &s);
int cmd_shader_check(const GlobalOptions &g, const ShaderCheckOptions &o);
// Compiles the renderer's fragment programs around `shader`'s GLSL (each
// domain it declares, uniform and baked parameters) with glslang as GLSL
// 4.10 core, without a GPU; returns the first error, located in the
// snippet's own lines, or nullopt when every program compiles.
std::optional<std::string> glsl_offline_error(const core::LoadedPlugin &shader);
// GPU equals CPU for one shading plugin of `reg` (needs a current GL context).
struct ShaderGpuResult {
    int sets = 0;
    std::uint64_t pixels = 0, failures = 0, nonfinite = 0, negative = 0;
    double max_rel = 0, max_err_over_tol = 0;
    bool ok = false;
};
ShaderGpuResult check_shader_gpu(const core::Registry &reg, const core::LoadedPlugin *plugin, const ShaderCheckOptions &o,
                                 std::uint64_t seed);

// Renders `scene` headlessly to o.out (PNG through the images plugin).
// `ctx`: the headless context to draw with, made beforehand (cmd_render makes
// it before reading any file, so that a machine without one, or a wrong
// HORIZON_GPU, is told before the work), and the milliseconds that took;
// null: one is made here.
int render_scene(const core::Registry &reg, core::render::Scene scene, const RenderOptions &o,
                 std::unique_ptr<core::render::GlContext> ctx = nullptr, double ctx_ms = 0);
// A scene from data files: tractograms as direction-coloured tubes (lines
// above 20,000 streamlines), meshes as principled surfaces, volumes as three
// slices; per-vertex overlays go onto the surface named before them.
core::render::Scene scene_from_files(const core::Registry &reg, const std::vector<std::string> &files);
// Whether `view`/`render` inputs are one scene file (.json) rather than data files.
bool is_scene_file(const std::vector<std::string> &inputs);
// The scene of `view`/`render` inputs (`command` names the command in the
// error for none): a scene file's, or scene_from_files'; then, when `view`
// is not empty, the camera placed at that named view (left, right, anterior,
// posterior, superior, inferior) fitted to the scene, replacing any explicit
// position, target and up.
core::render::Scene scene_from_inputs(const core::Registry &reg, const std::vector<std::string> &inputs, const std::string &view,
                                      const char *command);
// The named views (for the command line's check).
const std::vector<std::string> &named_views();
// Writes an image (format by extension) atomically; "-": a PNG on standard
// output. Refuses to replace an existing file unless `force`.
void write_image(const core::Registry &reg, const core::render::Image &im, const std::filesystem::path &path, bool force);

// Before any work: every output (empty ones and "-", standard output,
// skipped) must differ from every input, a NIfTI pair's other half
// included, and from the other outputs; must not be a device, FIFO,
// socket or directory; must not exist unless `force`; and its directory
// must exist. Throws Error naming the output.
void check_outputs(const std::vector<std::string> &outputs, const std::vector<std::string> &inputs, bool force);

}  // namespace hz::host
