// A scene for the renderer: data objects with their colouring and material,
// a camera, lights and an environment. Scenes come from JSON scene files
// (`horizon render SCENE.json`, docs/scene-format.md) or are built in code
// (`horizon demo`, `horizon view FILES`).
#pragma once

#include <hz/core/data.hpp>
#include <hz/core/plugin_host.hpp>
#include <hz/core/render/connectome.hpp>
#include <hz/core/render/labels.hpp>
#include <hz/core/render/odfs.hpp>
#include <hz/core/render/peaks.hpp>
#include <hz/core/render/tensors.hpp>

#include <array>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hz::core::render {

using Vec3 = std::array<double, 3>;

// A shading model and its parameter values. Values not given keep the
// plugin's schema defaults; names are checked against the schema when the
// renderer builds the program.
struct Material {
    std::string shader = "principled";  // plugin id, or its last component ("principled")
    std::map<std::string, std::vector<double>> params;
};

// How an object gets its base colour (the shading model's first colour
// parameter): "direction" (streamlines: |local tangent| as RGB), "solid",
// "data" (a named per-vertex / per-streamline array through a colormap) or
// "cluster" (one colour per cluster).
struct Coloring {
    std::string mode = "solid";
    std::array<double, 3> color{0.8, 0.8, 0.8};
    std::string array;
    std::string colormap = "viridis";
    std::optional<std::array<double, 2>> range;  // default: the data's min/max
    std::array<double, 3> tint{1, 1, 1};         // "rgb": multiplies the per-vertex colours (glTF baseColorFactor)
    // Streamlines: the points where the per-point array `mark` is not 0 are
    // drawn in `mark_color` (linear), whatever the mode (BUAN's highlight).
    std::string mark;
    std::array<double, 3> mark_color{1, 0, 0};
};

// Replace a tractogram by one level of a clustering tree (paper Fig. 5).
struct ClusterSpec {
    std::string algorithm = "qbx";                      // a clustering plugin: its id, or the last part of it (qb, qbx, qbx_merge, ...)
    std::vector<double> thresholds;                     // empty: the plugin's defaults
    std::map<std::string, std::vector<double>> params;  // the plugin's own parameters, by name (checked by its schema)
    int level = 1;                                      // 1 = coarsest; -1 = finest
    // The tree as a figure (paper Fig. 4): the centroids of all these levels
    // drawn together (non-empty: replaces `level`), each coloured by its
    // subtree, the node it descends from at the first (coarsest) of them
    // (per-streamline "cluster_id"; "cluster_level" holds its level), and
    // only the subtrees `subtrees` lists (indices among the first level's
    // clusters drawn, from 0, in the tree's order; empty: all).
    std::vector<int> levels;
    std::vector<std::uint64_t> subtrees;
    bool width_by_size = true;  // tube radius grows with sqrt(cluster size)
    // Clusters shown only from this many streamlines, and with a centroid at
    // least this long (mm): dipy_horizon's --cluster_size_thr and
    // --cluster_length_thr (ClusterTree::kept).
    std::uint64_t min_size = 0;
    double min_length_mm = 0;
};

// How direct volume rendering maps a volume's values to colour and opacity
// (renderer passes/volume_rendering.hpp): along the object's window, the
// colours of `colormap` and a piecewise-linear opacity, given as (window
// fraction in [0, 1], opacity of one millimetre in [0, 1]) in increasing
// fraction order (clamped at both ends). A preset or a user's (scene file,
// or a JSON file of the same keys; docs/scene-format.md), lit or not.
struct TransferFunction {
    std::string name = "mri";  // the preset's name, or "custom"
    std::string colormap = "gray";
    std::vector<std::array<double, 2>> opacity{{0.0, 0.0}, {0.3, 0.0}, {1.0, 0.25}};
    // Lit by the key light where the values change (the gradient as the
    // normal, two-sided): colour x (0.3 + 0.7 |n . l|); flat regions unlit.
    bool shade = true;
};
// The presets' names: mri (grey, tissue above 30 % of the window), density
// (viridis, anything above 2 %: tract density, fODF amplitude), hot (hot,
// the top half), glow (inferno, the brightest).
const std::vector<std::string> &transfer_presets();
// Preset `name`; throws Error naming the presets otherwise.
TransferFunction transfer_preset(const std::string &name);
// Throws Error "transfer function: ..." unless the colormap is known, the
// opacity has 1 to 256 points with fractions in [0, 1], increasing, and
// opacities in [0, 1], all finite.
void check_transfer(const TransferFunction &tf);
// Reads a transfer function from a JSON file ({"colormap": ..., "opacity":
// [[fraction, opacity per mm], ...]}, 64 KiB at most); throws Error naming
// the file.
TransferFunction load_transfer(const std::filesystem::path &file);

struct Object {
    std::string name;
    hz_data_kind kind = 0;  // STREAMLINES, MESH or VOLUME (drawn as slices)
    Dataset data;
    bool visible = true;
    // Level of detail: this object stands in for object `proxy_for` while the
    // camera moves (e.g. QuickBundlesX centroids of a large tractogram) and
    // is hidden otherwise; that object is hidden while moving.
    std::optional<std::size_t> proxy_for;
    // Shown only until it is replaced (a tractogram shown whole while its
    // regions' first selection is made): of its level of detail, only the
    // uniform subsample, none of the work on other threads (shell, fibre
    // volume, bricks) that would slow down what replaces it.
    bool provisional = false;
    // streamlines
    std::string render = "lines";  // lines | tubes
    double radius_mm = 0.4;        // tubes; with width_by_size: the radius of the median cluster
    std::optional<ClusterSpec> clustering;
    // surfaces and streamlines
    Coloring coloring;
    Material material;
    double opacity = 1.0;
    // volume slices, RAS+ mm; an absent value hides that slice
    std::optional<double> slice_x, slice_y, slice_z;
    std::optional<std::array<double, 2>> window;  // value range mapped to the colormap
    std::string slice_colormap = "gray";
    std::optional<double> clip_below;  // values below are transparent (e.g. the background)
    // a volume of more than three dimensions (a 4D series): which of its
    // 3D volumes is shown, counting over the dimensions after the third
    // (the 4th's index, for a 4D file)
    std::uint64_t volume_index = 0;
    // slices shown as colour rather than through a colormap (a colour-FA
    // map): the voxel's three values (a 4th dimension of 3 or 4, or an RGB
    // voxel type) mapped each through the window to a display value. Unset:
    // on for RGB voxel types and for 8-bit volumes whose 4th dimension is 3
    // or 4; a float volume of 3 needs it said (it may be a series).
    std::optional<bool> rgb;
    // volumes: drawn by ray-marching through this transfer function instead
    // of as slices (a scene's "type": "volume")
    std::optional<TransferFunction> transfer;
    // Peak glyphs (a scene's "type": "peaks", peaks.hpp): a streamlines
    // object whose tractogram is peak_lines() of this field at the slices
    // slice_x/y/z (or of the whole volume); the renderer's set_slices
    // builds it again where the slices move.
    std::shared_ptr<const PeakField> peaks;
    // ODF glyphs (a scene's "type": "odfs", odfs.hpp): a surface object
    // whose mesh is odf_glyphs() of this field at the slices slice_x/y/z,
    // built again by set_slices.
    std::shared_ptr<const OdfField> odfs;
    // Level of detail for ODF glyphs of a sphere finer than the icosahedron:
    // the glyphs of the field a level coarser (OdfField::coarser: a voxel
    // for each 2 x 2 x 2, their mean ODF, twice the size) on the
    // icosahedron (20 triangles each: 1/64 of the default sphere's on a
    // slice), drawn instead of the mesh while the camera moves; built with
    // it (moving_glyph_mesh). Null otherwise.
    std::shared_ptr<const Mesh> moving_mesh;
    // Tensor glyphs (a scene's "type": "tensors", tensors.hpp): a surface
    // object whose mesh is tensor_glyphs() of this field at the slices.
    std::shared_ptr<const TensorField> tensors;
    // The data file it was read from ("" for builtins and data held in
    // memory); the grid cell it is drawn in (Scene::grid; -1: every cell).
    std::string file;
    int cell = -1;
    // A label volume (a scene's "type": "labels", labels.hpp): slices show
    // each region's area and outline in its colour instead of values
    // through a window and colormap.
    std::shared_ptr<const LabelField> labels;
};

// Turns volume object `o` into a label volume (Object::labels) drawn on its
// slices (none set: the three through the centre) and, when
// `opt.surfaces`, returns the regions' boundary surfaces as an object of
// their own ("NAME surfaces", per-vertex colours of the labels; the caller
// adds it to the scene). Throws Error naming `what` (make_label_field's
// checks; no shown label with a surface).
std::optional<Object> show_as_labels(Object &o, const LabelOptions &opt, const std::string &what);

// Shows a BUAN profile on tractogram object `o` (buan.hpp): per-point arrays
// "buan_segment" (the point's segment, buan_segments) and
// "buan_significant" (1 where that segment's value in `pvalues` is below
// `threshold`), the latter drawn in `highlight` (Coloring::mark). A
// tractogram read in place with delimiters is copied first. Throws Error
// naming `what` for an empty profile, a value that is not a number, a
// threshold outside (0, 1], an object that is not a tractogram.
void show_buan(Object &o, const std::vector<double> &pvalues, double threshold, const std::array<double, 3> &highlight,
               const std::string &what);

// Turns object `o`, holding a volume of diffusion tensors (6 values a
// voxel), into tensor glyphs (Object::tensors) on its slices (none set: the
// three through the centre), coloured by FA and direction (per-vertex
// "color_fa" array). An object that shows tensors already is drawn again
// with `opt`. Throws Error naming `what` (make_tensor_field's checks).
void show_as_tensors(Object &o, const TensorOptions &opt, const std::string &what);

// A connectome as scene objects: "NAME nodes" (spheres coloured by their
// colour values through `node_map`, one colour where all are equal) and,
// with a matrix and an edge above the threshold, "NAME edges" (tubes as
// thick as their weights, coloured by weight through `edge_map` over
// [-largest, largest]). Throws Error (connectome_nodes' checks).
std::vector<Object> connectome_objects(const Connectome &c, const ConnectomeOptions &o, const std::string &name,
                                       const std::string &node_map = "viridis", const std::string &edge_map = "coolwarm");

// A glyph object's mesh at the slices x, y, z (ODF or tensor glyphs), and
// the box of its grid's voxels; nullopt for any other object.
std::optional<Mesh> glyph_mesh(const Object &o, std::optional<double> x, std::optional<double> y, std::optional<double> z);
// The same glyphs' moving mesh (Object::moving_mesh) at those slices: null
// for an object that has none (not ODFs, or ODFs on the icosahedron).
std::shared_ptr<const Mesh> moving_glyph_mesh(const Object &o, std::optional<double> x, std::optional<double> y, std::optional<double> z);
std::optional<Bounds> glyph_grid(const Object &o);

// Turns object `o`, holding a volume of SH coefficients, into ODF glyphs
// (Object::odfs) on its slices (none set: the three through the centre),
// coloured by direction (per-vertex "direction" array) unless a colour is
// set. An object that shows ODFs already is drawn again with `opt`.
// Throws Error naming `what` (make_odf_field's checks).
void show_as_odfs(Object &o, const OdfOptions &opt, const std::string &what);

// Whether object `o` is a volume drawn as slices of its values (labels,
// colour or intensities), not as glyphs (peaks, ODFs, tensors).
bool shows_value_slices(const Object &o);

// Whether volume object `o`'s slices show colour (Object::rgb, or what its
// volume is: an RGB voxel type, or 8-bit values with a 4th dimension of 3
// or 4).
bool shows_rgb(const Object &o);

// Turns object `o`, holding a peak volume (a 4th dimension of 3N values),
// into peak glyphs (Object::peaks): lines coloured by direction, at the
// object's slices (none set: the three through the volume's centre) unless
// `opt.whole`. An object that shows peaks already is drawn again with
// `opt` (from the same voxels). Throws Error naming `what`
// (make_peak_field's checks).
void show_as_peaks(Object &o, const PeakOptions &opt, const std::string &what);

struct Camera {
    // Either explicit (position/target/up) or fitted to the scene bounds
    // from a named view: left, right, anterior, posterior, superior, inferior.
    std::optional<Vec3> position, target;
    Vec3 up{0, 0, 1};
    std::string view = "left";
    double fov_deg = 30.0;
    double zoom = 1.0;
};

struct Light {
    std::string type = "directional";  // directional | point
    Vec3 direction{0, 0, 1};           // directional: towards the light
    Vec3 position{0, 0, 0};            // point
    std::array<double, 3> color{1, 1, 1};
    double intensity = 1.0;    // radiance scale (directional: irradiance at normal incidence)
    bool camera_space = true;  // direction/position given in camera space (x right, y up, z back)
};

struct Environment {
    std::string type = "studio";  // studio (procedural) | file | none
    std::string path;             // type = file: an equirectangular image (.hdr, .exr, .png)
    double intensity = 0.5;
    double rotation_deg = 0.0;  // about the superior (z) axis
    bool visible = false;       // draw it as the background
};

// Streamlines cropped to a slab: only what lies within `half` mm of the
// plane axis = centre (RAS+ mm; axis 0 x, 1 y, 2 z) is drawn (mrview's
// crop to slab). Or, with `points`, each streamline is shown only where it
// crosses the plane axis = centre: a shaded disc of `point_px` pixels across
// per crossing, in the streamline's colour there (`half` is then unused).
// Surfaces and slices are not cropped.
struct Slab {
    int axis = 2;
    double centre = 0, half = 5;
    bool points = false;
    double point_px = 5;
    bool operator==(const Slab &) const = default;
};

// Ambient occlusion, a depth cue (renderer passes/ambient_occlusion.hpp):
// each pixel darkened by how much of the scene within `radius_mm` of it
// lies in front of it, up to `strength` (1: a fully hidden pixel black).
struct AmbientOcclusion {
    bool on = false;
    double radius_mm = 3.0;
    double strength = 0.8;
};

// Depth cueing (renderer passes/depth_cue.hpp): what lies farther fades
// towards the background, linearly across the scene's depth, up to
// `strength` at its far end.
struct DepthCue {
    bool on = false;
    double strength = 0.6;
};

// Shadows of the key light, the first directional light (renderer
// passes/shadow.hpp): opaque surfaces, lines and tubes cast them on
// everything lit (slices, which show data, neither cast nor receive).
// `strength`: how much of the key light a point in full shadow loses;
// `softness_mm`: the radius over which shadow edges blend.
struct Shadows {
    bool on = false;
    double strength = 0.75;
    double softness_mm = 0.5;
};

// Anti-aliasing (renderer passes/antialiasing.hpp). With `on`, every frame
// drawn without multisampling (large tractograms, the window's moving
// frames) is smoothed along its edges and lines by a post-process; a still
// of `frames` > 1 (`horizon render`) is that many frames, each moved by a
// different fraction of a pixel, averaged instead: supersampling at `frames`
// times the cost of one frame.
struct Antialiasing {
    bool on = true;
    int frames = 1;
};

// Throws Error "ambient occlusion: ..." unless 0 < radius_mm <= 1000 and
// 0 <= strength <= 1 (finite).
void check_ambient_occlusion(const AmbientOcclusion &ao);
// Throws Error "depth cue: ..." unless 0 <= strength <= 1.
void check_depth_cue(const DepthCue &cue);
// Throws Error "shadows: ..." unless 0 <= strength <= 1 and
// 0 <= softness_mm <= 50 (finite).
void check_shadows(const Shadows &s);
// Throws Error "antialiasing: ..." unless 1 <= frames <= 64.
void check_antialiasing(const Antialiasing &aa);

// What is drawn over the picture (annotations.hpp): a colour bar for every
// object coloured through a colormap, the orientation of the patient's
// axes, a scale bar.
struct Annotations {
    bool colour_bar = false;
    bool orientation = false;
    bool scale_bar = false;
    bool any() const { return colour_bar || orientation || scale_bar; }
};

// A scene's timeline (its "timeline" key; timeline.hpp plays it): keyframes
// of the camera and of objects' visibility, material parameters and slice
// positions over seconds. The scene as written is its state at time 0.
struct ObjectKey {
    std::optional<bool> visible;
    std::optional<double> opacity;                      // Object::opacity, [0, 1]
    std::optional<std::array<double, 2>> window;        // Object::window of a volume (low < high)
    std::map<std::string, std::vector<double>> params;  // material parameters (checked against the shader's schema)
    // Slice positions x, y, z (RAS+ mm): unset, not keyed here; an empty
    // optional inside, the slice hidden from this keyframe on.
    std::array<std::optional<std::optional<double>>, 3> slices;
};
struct Keyframe {
    double time = 0;  // seconds
    std::optional<Camera> camera;
    std::map<std::size_t, ObjectKey> objects;  // by the object's index in Scene::objects
};
struct Timeline {
    std::vector<Keyframe> keyframes;  // times >= 0, increasing
    double duration = 0;              // seconds (> 0): at least the last keyframe's time
    bool smooth = true;               // eased (smoothstep of each span's fraction), or linear
    double turntable_deg = 0;         // a turn about the superior axis through the target, over the duration
};

// Several subjects at once (a scene's "grid"): a picture of one tile a cell,
// each the same camera on the objects of that cell (Object::cell) and those
// of every cell, its title at the top left.
struct SubjectGrid {
    int columns = 0;                  // 0: about square (the ceiling of the cells' square root)
    std::vector<std::string> titles;  // per cell, in increasing cell order (fewer: the rest untitled)
};

struct Scene {
    std::vector<Object> objects;
    std::optional<Timeline> timeline;
    std::optional<SubjectGrid> grid;
    AmbientOcclusion ambient_occlusion;
    DepthCue depth_cue;
    Shadows shadows;
    Antialiasing antialiasing;
    Annotations annotations;
    std::optional<Slab> slab;
    Camera camera;
    std::vector<Light> lights;  // empty: a three-point rig (key, fill, rim)
    Environment environment;
    std::array<double, 3> background{0.02, 0.02, 0.025};  // linear RGB
    double exposure = 1.0;
    std::string tonemap = "aces";  // aces | reinhard | none
    // Every file a scene file names and parse_scene read (objects, overlays,
    // masks, the environment map), as resolved: inputs that no output of
    // the command may replace.
    std::vector<std::string> files;
};

// The cells of a grid scene's objects (Object::cell >= 0), increasing.
std::vector<int> grid_cells(const Scene &s);

// Parses a scene file, reading every data file it names (relative to the
// scene file) through the registry's loaders and running any clustering.
// Throws Error naming the file and the offending key.
Scene load_scene(const Registry &reg, const fs::path &scene_file);

// Datasets a program holds in memory, by name: an object's "data": NAME
// shows one (in place of "file" or "builtin"; the Python package's scenes).
using MemoryData = std::map<std::string, std::shared_ptr<const Dataset>>;

// The same from already-parsed JSON text; `base_dir` resolves relative
// paths; `memory`: the datasets objects may name with "data".
Scene parse_scene(const Registry &reg, const std::string &json_text, const fs::path &base_dir, const std::string &what,
                  const MemoryData &memory = {});

// Another Dataset over the same buffers (each kept alive), with the same
// arrays, metadata and descriptions: a copy of nothing but the fields.
Dataset share_dataset(const Dataset &d);

// Uses a mesh file's own material (glTF PBR factors in its header) unless
// the scene sets the material (`has_material`) or the colour (`has_color`).
void apply_file_material(Object &ob, bool has_material, bool has_color);

// Built-in data for demos and tests (deterministic).
Mesh make_cortex_mesh(int subdivisions = 5);
Mesh make_sphere_mesh(double radius_mm, int nu, int nv);  // UV sphere at the origin   // two hemispheres around the phantom's box
Volume make_head_volume(double voxel_mm = 2.0);           // a T1-like synthetic volume, same frame
// The demo's brain: two hemispheres with sulci (where a band-limited noise
// crosses zero: narrow valleys between broad gyri) and a Sylvian fissure,
// a per-vertex "sulc" array of sulcal depth (0 on crowns, 1 at fundi); and
// a T1-weighted-like volume of the same brain (white matter within the
// cortex's grey, deep grey nuclei, ventricles, CSF, skull, scalp,
// brainstem, cerebellum; boundaries blended over about 1.5 mm), in the
// frame of make_brain_phantom's bundles.
Mesh make_brain_surface(int subdivisions = 6);
Volume make_t1_volume(double voxel_mm = 1.0);
// Its segmentation: a label volume (int32) of the T1's tissues where each is
// more than half present, numbered as FreeSurfer's aseg (cerebral white
// matter 2/41, cortex 3/42, lateral ventricles 4/43, thalami 10/49,
// cerebellum 8/47, brainstem 16); aseg_table() names and colours them.
Volume make_aseg_volume(double voxel_mm = 1.0);
LabelTable aseg_table();

// A clustering tree, copied out of the plugin (hz_cluster_tree_view).
struct ClusterTree {
    std::uint32_t nb_levels = 0, nb_points = 0;
    std::vector<double> thresholds;             // per level (1..nb_levels), mm; empty when the plugin reports none
    std::vector<std::int64_t> parent;           // per node; -1 for the root
    std::vector<std::uint32_t> level;           // per node; 0 for the root
    std::vector<float> centroids;               // nodes x nb_points x 3
    std::vector<std::uint64_t> member_offsets;  // nodes + 1
    std::vector<std::uint64_t> members;         // streamline indices into the input
    std::uint64_t size(std::uint64_t node) const { return member_offsets[node + 1] - member_offsets[node]; }
    // The length of node's centroid (mm: the sum of its segments).
    double centroid_length(std::uint64_t node) const;
    // Whether node passes spec's cut-offs (min_size, min_length_mm).
    bool kept(std::uint64_t node, const ClusterSpec &spec) const {
        return size(node) >= spec.min_size && (spec.min_length_mm <= 0 || centroid_length(node) >= spec.min_length_mm);
    }
};

// Runs clustering plugin `spec.algorithm` (fast mode: for display) with
// spec.thresholds over `t`. `task` (may be null; not owned, alive for the
// call) receives the plugin's progress and may cancel the run, which then
// throws Error ("cancelled"). `ordering` (may be null): the processing
// order, a permutation of the streamlines' indices (checked). Throws Error.
ClusterTree run_clustering(const Registry &reg, const Tractogram &t, const ClusterSpec &spec, const hz_task *task = nullptr,
                           const std::vector<std::uint64_t> *ordering = nullptr);

// The first per-vertex array of `m` that holds colours (3 or 4 components:
// uint8/uint16 sRGB-encoded, float linear 0..1), or "" (coloring mode "rgb");
// only arrays named in `among` when it is given.
std::string colour_array(const Mesh &m, const std::vector<std::string> *among = nullptr);
// Colours `ob` by the overlay arrays `names` just attached to its mesh: the
// first colour array among them (an annotation's label colours), else the
// first array through the colormap. No-op for no names.
void colour_by_overlay(Object &ob, const std::vector<std::string> &names);

// Applies `spec` to a tractogram: returns the chosen level's centroids with a
// per-streamline "cluster_size" array. Throws Error.
Tractogram cluster_centroids(const Registry &reg, const Tractogram &t, const ClusterSpec &spec);

// The scene of `horizon demo`: the named bundles of make_brain_phantom as
// direction-coloured tubes, the right hemisphere's cortex
// (make_brain_surface), axial and coronal slices of make_t1_volume,
// principled shading, ambient occlusion and shadows.
Scene demo_scene(std::uint64_t nb_streamlines, std::uint64_t seed);

}  // namespace hz::core::render
