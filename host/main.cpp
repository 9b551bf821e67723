// horizon: the command-line host.
//   horizon plugins [--json]
//   horizon validate PLUGIN_FILE [--json] [--timeout S] [--data FILE]...
//   horizon info FILE [--json]
//   horizon convert IN OUT [--force]
//   horizon demo [--out DIR]
#include "actions.hpp"
#include "commands.hpp"
#include "progress.hpp"

#include <hz/core/io.hpp>
#include <hz/core/plugin_guard.hpp>

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <cerrno>
#include <cstring>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <iostream>

namespace hz::host {

namespace {
const auto kLaunch = std::chrono::steady_clock::now();

// --size WIDTHxHEIGHT, checked before anything is read (parse_size's rule).
const CLI::Validator kSize(
    [](std::string &s) {
        try {
            (void)parse_size(s);
            return std::string();
        } catch (const core::Error &) {
            return "expected WIDTHxHEIGHT between 16x16 and 16384x16384, not '" + s + "'";
        }
    },
    "WIDTHxHEIGHT");

// A pass's two flags: --NAME (ON_HELP) and --no-NAME (NOUN off whatever the scene file says), which exclude
// each other. Returns --no-NAME, which the pass's settings exclude too.
CLI::Option *add_pass_switch(CLI::App *cmd, const std::string &name, bool &on, bool &off, const std::string &on_help,
                             const std::string &noun) {
    auto *yes = cmd->add_flag("--" + name, on, on_help);
    auto *no = cmd->add_flag("--no-" + name, off, "no " + noun + ", whatever the scene file says");
    yes->excludes(no);
    return no;
}

// The options of the frame's passes that `render`, `view` and `demo` share (documented once).
void add_pass_options(CLI::App *cmd, PassOptions &c) {
    auto *off = add_pass_switch(cmd, "ao", c.ao, c.no_ao,
                                "ambient occlusion: each pixel darkened by the scene in front of it within --ao-radius (a depth cue; "
                                "a scene file's \"ambient_occlusion\")",
                                "ambient occlusion");
    cmd->add_option("--ao-radius", c.ao_radius, "ambient occlusion: the radius sampled around each pixel, in mm (default 3; implies --ao)")
        ->check(CLI::Range(1e-3, 1000.0))
        ->excludes(off);
    cmd->add_option("--ao-strength", c.ao_strength,
                    "ambient occlusion: 0 (none) to 1 (a fully hidden pixel is black; default 0.8; implies --ao)")
        ->check(CLI::Range(0.0, 1.0))
        ->excludes(off);
    auto *no_cue = add_pass_switch(cmd, "depth-cue", c.depth_cue, c.no_depth_cue,
                                   "depth cue: what lies farther fades towards the background across the scene's depth (a scene "
                                   "file's \"depth_cue\")",
                                   "depth cue");
    cmd->add_option("--depth-cue-strength", c.depth_cue_strength,
                    "depth cue: the fraction of the background at the scene's far end, 0 to 1 (default 0.6; implies --depth-cue)")
        ->check(CLI::Range(0.0, 1.0))
        ->excludes(no_cue);
    auto *no_sh = add_pass_switch(cmd, "shadows", c.shadows, c.no_shadows,
                                  "shadows of the key light (the first directional light) cast by surfaces, lines and tubes (a scene "
                                  "file's \"shadows\")",
                                  "shadows");
    cmd->add_option("--shadow-strength", c.shadow_strength,
                    "shadows: how much of the key light a point in full shadow loses, 0 to 1 (default 0.75; implies --shadows)")
        ->check(CLI::Range(0.0, 1.0))
        ->excludes(no_sh);
    cmd->add_option("--shadow-softness", c.shadow_softness,
                    "shadows: the radius over which their edges blend, in mm, 0 to 50 (default 0.5; implies --shadows)")
        ->check(CLI::Range(0.0, 50.0))
        ->excludes(no_sh);
    auto *no_aa = cmd->add_flag("--no-aa", c.no_aa,
                                "no anti-aliasing: neither the edge pass over frames drawn without multisampling nor jittered frames, "
                                "whatever the scene file says");
    cmd->add_option("--aa-frames", c.aa_frames,
                    "anti-aliasing of a still: N frames, each moved by a fraction of a pixel, averaged (supersampling at N "
                    "times a frame's cost; a scene file's \"antialiasing\": {\"frames\": N}; render: 1 by default; the window at "
                    "rest: N, else 8 or the scene's where more, where a still is drawn at once and cheap; 1: the edge pass alone)")
        ->check(CLI::Range(1, 64))
        ->excludes(no_aa);
}

void add_volume_options(CLI::App *cmd, VolumeOptions &v) {
    std::string presets;
    for (const auto &n : core::render::transfer_presets()) presets += (presets.empty() ? "" : ", ") + n;
    cmd->add_option("--volume-render", v.transfer,
                    "draw every volume by ray-marching through this transfer function instead of as slices: a preset (" + presets +
                        ") or a JSON file {\"colormap\": ..., \"opacity\": [[fraction of the window, opacity of 1 mm], ...]}");
    cmd->add_option("--volume-index", v.volume_index,
                    "a 4D series (e.g. diffusion volumes): show its N-th 3D volume, counting from 0 (a scene file's \"volume_index\"; "
                    "the window's panel and `volume I N` step through them)")
        ->check(CLI::Range(std::uint64_t(0), std::uint64_t(1) << 40));
    cmd->add_flag("--peaks", v.peaks,
                  "volumes of 3 values a peak a voxel (MRtrix3's sh2peaks, DIPY's peaks saved as NIfTI) drawn as peak glyphs: "
                  "lines centred on their voxels, coloured by direction, on the three slices through the centre (a PAM5 file "
                  "always is; a scene file's \"type\": \"peaks\")");
    cmd->add_option("--peak-scale", v.peak_scale, "peak glyphs: the longest spans this many voxels (default 1)")
        ->check(CLI::Range(1e-3, 100.0));
    cmd->add_option("--peak-threshold", v.peak_threshold,
                    "peak glyphs: peaks shorter than this fraction of the longest are not drawn (default 0)")
        ->check(CLI::Range(0.0, 0.999));
    cmd->add_flag("--peaks-whole", v.peaks_whole, "peak glyphs of every voxel rather than of the slices");
    cmd->add_flag("--peaks-voxel-frame", v.peaks_voxel_frame,
                  "peak vectors are in the voxel axes (turned by the affine), not in world RAS+ axes (MRtrix3's and DIPY's)");
    cmd->add_flag("--odfs", v.odfs,
                  "volumes of spherical-harmonic coefficients (1, 6, 15, 28, 45, ... a voxel: DIPY's or MRtrix3's fODFs) drawn as "
                  "ODF glyphs on the three slices through the centre (a scene file's \"type\": \"odfs\")");
    cmd->add_option("--sh-basis", v.sh_basis,
                    "ODF glyphs: the SH basis, descoteaux07 (DIPY's default, legacy), tournier07 (DIPY's, legacy) or mrtrix3 "
                    "(tournier07, not legacy)")
        ->check(CLI::IsMember({"descoteaux07", "tournier07", "mrtrix3"}));
    cmd->add_flag("--sh-not-legacy", v.sh_not_legacy, "ODF glyphs: DIPY's non-legacy form of the basis (legacy=False)");
    cmd->add_option("--odf-sphere", v.odf_sphere, "ODF glyphs: icosphere subdivisions, 0 (12 vertices) to 5 (10242); default 2 (162)")
        ->check(CLI::Range(0, 5));
    cmd->add_option("--odf-scale", v.odf_scale, "ODF glyphs: the largest spans this many voxels (default 1)")
        ->check(CLI::Range(1e-3, 100.0));
    cmd->add_flag("--roi-images", v.roi_images,
                  "every volume is a mask or a label volume (dipy_horizon's --roi_images): each region's area and outline on the slices, "
                  "its surface in 3D (a scene file's \"type\": \"labels\"); --roi selects streamlines instead");
    cmd->add_option("--lut", v.lut, "label volumes: their colours and names, a FreeSurferColorLUT.txt-format file (INDEX NAME R G B A)");
    cmd->add_option("--label-fill", v.label_fill,
                    "label volumes: the opacity of a region's area on the slices (default 0.4; 0: outlines only)")
        ->check(CLI::Range(0.0, 1.0));
    cmd->add_flag("--no-label-surfaces", v.no_label_surfaces, "label volumes: on slices only, no surfaces in 3D");
    cmd->add_flag("--tensors", v.tensors,
                  "volumes of 6 values a voxel (diffusion tensors) drawn as ellipsoids coloured by FA and direction on the three "
                  "slices through the centre (a scene file's \"type\": \"tensors\")");
    cmd->add_option("--tensor-order", v.tensor_order,
                    "tensor glyphs: the order of the six values, dipy (Dxx, Dxy, Dyy, Dxz, Dyz, Dzz: DIPY, NIfTI's symmetric matrix; "
                    "the default), fsl (dtifit: Dxx, Dxy, Dxz, Dyy, Dyz, Dzz) or mrtrix3 (dwi2tensor: Dxx, Dyy, Dzz, Dxy, Dxz, Dyz)")
        ->check(CLI::IsMember({"dipy", "fsl", "mrtrix3"}));
    cmd->add_flag("--rgb", v.rgb,
                  "volumes of 3 values a voxel (a colour-FA map) in colour, each value through the window (on by itself for 8-bit "
                  "and RGB voxels; a scene file's \"rgb\")");
}

void add_annotation_options(CLI::App *cmd, AnnotationOptions &a) {
    auto *all = cmd->add_flag("--annotations", a.all,
                              "draw every annotation: --colour-bar, --orientation and --scale-bar (a scene file's "
                              "\"annotations\": true)");
    auto *none = cmd->add_flag("--no-annotations", a.none, "no annotations, whatever the scene file says");
    all->excludes(none);
    cmd->add_flag("--colour-bar,--color-bar", a.colour_bar,
                  "a colour bar for every object coloured through a colormap: its name, quantity and range")
        ->excludes(none);
    cmd->add_flag("--orientation", a.orientation, "the patient's axes (R, A, S and L, P, I) as the camera sees them, bottom left")
        ->excludes(none);
    cmd->add_flag("--scale-bar", a.scale_bar, "a scale bar (a round length in mm at the depth of the camera's target), bottom right")
        ->excludes(none);
}

void add_style_options(CLI::App *cmd, StyleOptions &st) {
    // (checked as the command line is read, before any file is)
    const auto colour = [](const std::string &flag) {
        return CLI::Validator(
            [flag](std::string &v) {
                try {
                    if (flag == "--tract-colour" && (v == "direction" || v == "random")) return std::string();
                    (void)parse_colour("", v);
                    return std::string();
                } catch (const std::exception &e) {
                    return std::string(e.what());
                }
            },
            "COLOUR");
    };
    cmd->add_option("--background", st.background,
                    "the background as the picture shows it: black, white, grey, or R,G,B each in [0, 1] (sRGB-encoded values)")
        ->check(colour("--background"));
    cmd->add_option("--tract-colour,--tract-color", st.tracts,
                    "every tractogram's colour: direction (RGB of the local direction), random (one colour per tractogram), or a "
                    "colour (black, white, grey, R,G,B in [0, 1], linear as a scene file's colours)")
        ->check(colour("--tract-colour"));
    cmd->add_option("--buan", st.buan,
                    "BUAN profiles (dipy_horizon's --buan): a .npy of p-values a segment along the bundle, one a tractogram given, in "
                    "order; the points of segments below --buan-threshold drawn in --buan-highlight");
    cmd->add_option("--buan-threshold", st.buan_threshold, "BUAN: p-values below it are highlighted (default 0.05; dipy_horizon's 0.5)")
        ->check(CLI::Range(1e-12, 1.0));
    cmd->add_option("--buan-highlight", st.buan_highlight, "BUAN: the highlight (R,G,B in [0, 1], linear; default red)")
        ->check(colour("--buan-highlight"));
    cmd->add_option("--glass-brain", st.glass_brain,
                    "a glass shell around the data: a surface file (pial, GIFTI), or a volume whose voxels above 0 make one (a brain "
                    "mask); a scene file's surface of \"shader\": \"glass\"");
}

void add_grid_options(CLI::App *cmd, GridOptions &g) {
    cmd->add_option("--grid", g.mode,
                    "several subjects at once: one tile a data file given (files) or a folder of them (folders: a subject's files "
                    "together), each titled by its name, all seen by the same camera (a scene file's \"grid\")")
        ->check(CLI::IsMember({"files", "folders"}));
    cmd->add_option("--grid-columns", g.columns, "the grid's columns (default: about square)")->check(CLI::Range(1, 64));
}

void add_lod_options(CLI::App *cmd, LodOptions &lod) {
    cmd->add_option("--lod-pixels", lod.lod_pixels, "streamline decimation tolerance in pixels (0 = every point)")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 100.0));
    cmd->add_option("--lod-points", lod.lod_points,
                    "tractograms with more points get a proxy of about this many points "
                    "(drawn while the camera moves and first at rest)")
        ->capture_default_str()
        ->check(CLI::Range(1000.0, 1e12));
    cmd->add_option("--lod-proxy", lod.lod_proxy,
                    "the proxy: volume (the streamlines as a volume of their density, colour and direction, ray-marched, under "
                    "the shell's lines), shell (the streamlines' runs nearest the tractogram's outer surface, what a dense "
                    "tractogram shows) or uniform; both computed in the background, a uniform subsample until then")
        ->capture_default_str()
        ->check(CLI::IsMember({"volume", "shell", "uniform"}));
    cmd->add_option("--lod-reproject", lod.lod_reproject,
                    "while the camera moves, the last complete picture drawn again from the new camera (one point per NxN block, at "
                    "its depth) under the proxy, which fills what it did not see")
        ->capture_default_str()
        ->check(CLI::IsMember({"on", "off"}));
    cmd->add_option("--lod-occlusion", lod.lod_occlusion,
                    "full-detail frames of large tractograms drawn brick by brick, nearest first, skipping the bricks hidden "
                    "behind what is drawn (the same picture, a fraction of the fragments); order: the bricks in that order, "
                    "none skipped (a check that skipping changes no pixel)")
        ->capture_default_str()
        ->check(CLI::IsMember({"on", "off", "order"}));
    cmd->add_option("--lod-scale", lod.lod_scale, "the proxy is drawn at 1/N of the size, then upscaled")
        ->capture_default_str()
        ->check(CLI::Range(1, 16));
    cmd->add_option("--lod-volume-scale", lod.lod_volume_scale,
                    "the proxy's fibre volume is ray-marched at down to 1/N of the size (no smaller than the proxy's lines "
                    "need, and its rays at most 1.5 voxels apart), then upscaled under those lines")
        ->capture_default_str()
        ->check(CLI::Range(1, 64));
    cmd->add_option("--gpu-memory", lod.gpu_memory_mb,
                    "MiB of streamline geometry kept in GL buffers; the rest is rebuilt and streamed when drawn")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 1048576.0));
}
}  // namespace

double seconds_since_launch() { return std::chrono::duration<double>(std::chrono::steady_clock::now() - kLaunch).count(); }

core::Registry load_registry(const GlobalOptions &g) {
    core::Registry reg(core::Registry::Options{true, g.plugin_timeout_s, core::default_trial_cache()});
    reg.scan(core::plugin_search_path(g.plugin_dirs));
    for (const auto &r : reg.rejected()) spdlog::debug("rejected {}: {}", r.file, r.reason);
    return reg;
}

}  // namespace hz::host

int main(int argc, char **argv) {
    using namespace hz::host;
    hz::core::install_termination_cleanup();  // no temporary left by ^C, kill or ulimit -f
    auto logger = spdlog::stderr_color_st("horizon");
    logger->set_pattern("%^%l%$: %v");
    spdlog::set_default_logger(logger);
    spdlog::set_level(spdlog::level::warn);

    CLI::App app{"Horizon: cinematic visualization of tractograms, surfaces and volumes"};
    // Global options are taken before or after the command
    // (`horizon plugins --plugin-dir D` as `horizon --plugin-dir D plugins`).
    app.fallthrough();
    app.set_version_flag("--version", std::string("horizon ") + HZ_HOST_VERSION + " (plugin ABI " + std::to_string(HZ_ABI_VERSION_MAJOR) +
                                          "." + std::to_string(HZ_ABI_VERSION_MINOR) + ")");
    app.require_subcommand(1);
    GlobalOptions g;
    app.add_option("--plugin-dir", g.plugin_dirs, "extra plugin directory (searched first; repeatable)");
    app.add_option("--plugin-timeout", g.plugin_timeout_s, "seconds a plugin may take to load before it is rejected")
        ->capture_default_str();
    bool verbose = false;
    app.add_flag("-v,--verbose", verbose, "log plugin loading and decisions");

    bool json = false;
    auto *plugins = app.add_subcommand("plugins", "list every plugin found, or why it was rejected");
    plugins->add_flag("--json", json, "machine-readable output (with every plugin's ABI version and parameter schema)");
    std::string plugin_id;
    plugins->add_option("id", plugin_id, "show one plugin: its description, ABI and parameters");

    ValidateOptions vo;
    auto *validate = app.add_subcommand("validate", "check a plugin file against the ABI contract");
    validate->add_option("plugin", vo.file, "plugin shared object")->required();
    validate->add_flag("--json", vo.json, "machine-readable report");
    validate->add_option("--timeout", vo.timeout_s, "seconds per check before it counts as hung")->capture_default_str();
    validate->add_option("--data", vo.data_files, "sample files for a loader's read checks (repeatable)");
    validate->add_option("--seed", vo.seed, "seed of the randomised checks")->capture_default_str();
    validate->add_flag("--no-gpu", vo.no_gpu,
                       "skip compiling and running a shader's GLSL (without it, a machine with no headless OpenGL fails that check)");

    std::string info_file;
    auto *info = app.add_subcommand("info", "describe a data file");
    info->add_option("file", info_file, "input file")->required();
    info->add_flag("--json", json, "machine-readable output");
    bool info_verify = false;
    info->add_flag("--verify", info_verify,
                   "streamlines: read every coordinate again on the host (finite, bounds as reported) instead of taking the loader's word");

    std::string conv_in, conv_out;
    bool force = false;
    auto *convert = app.add_subcommand("convert", "convert between formats (chosen by extension)");
    convert->add_option("input", conv_in, "input file")->required();
    convert->add_option("output", conv_out, "output file")->required();
    convert->add_flag("-f,--force", force, "replace an existing output file");

    ClusterOptions co;
    auto *cluster =
        app.add_subcommand("cluster", "cluster streamlines with any clustering plugin (QuickBundles, QuickBundlesX: DIPY's exact answers)");
    cluster->add_option("input", co.input, "tractogram")->required();
    cluster
        ->add_option("--algorithm", co.algorithm,
                     "a clustering plugin: its id, or the last part of it (qb, qbx, qbx_merge, ...; see `horizon plugins`)")
        ->capture_default_str();
    cluster->add_option("--param", co.params, "NAME=VALUE, a parameter of the plugin (repeatable; `horizon plugins ID` lists them)")
        ->allow_extra_args(false);
    cluster->add_option("--thresholds", co.thresholds, "MDF thresholds in mm, comma-separated (qb: one)")->delimiter(',');
    cluster->add_option("--nb-points", co.nb_points, "resampling points (default: qb/qbx 12, qbx_merge 20)");
    cluster->add_option("--order", co.order, "processing order: file, shuffle (with --seed), or a text file of indices")
        ->capture_default_str();
    cluster->add_option("--seed", co.seed, "seed of --order shuffle")->capture_default_str();
    cluster->add_option("--mode", co.mode, "exact: DIPY's answers bit for bit; fast: float32 distances (plugins with a 'mode' parameter)")
        ->check(CLI::IsMember({"exact", "fast"}));
    cluster->add_option("--threads", co.threads,
                        "threads (0: all cores; QuickBundlesX searches on up to 2, 1: on one); the result does not depend on it");
    cluster->add_option("--labels", co.labels, "CSV: one row per streamline, one column per level");
    cluster->add_option("--centroids", co.centroids, "write one level's centroids as streamlines");
    cluster->add_option("--level", co.level, "level for --centroids (1 = coarsest; default the finest)");
    cluster->add_option("--out", co.out, "write the tractogram with per-streamline labels");
    cluster->add_flag("-f,--force", co.force, "replace existing outputs");
    cluster->add_flag("--json", co.json, "machine-readable summary");

    FilterOptions fo;
    auto *filter = app.add_subcommand("filter", "select streamlines by include / exclude regions and length (MRtrix3 tckedit's rules)");
    filter->add_option("input", fo.input, "tractogram")->required();
    filter
        ->add_option("--include,--roi", fo.include,
                     "a region each kept streamline must have a vertex in: sphere:X,Y,Z,R, box:X0,Y0,Z0,X1,Y1,Z1 (RAS+ mm) or a "
                     "mask volume (nonzero voxels); repeatable, all must be met")
        ->allow_extra_args(false);
    filter->add_option("--exclude", fo.exclude, "a region no kept streamline may have a vertex in (same forms); repeatable")
        ->allow_extra_args(false);
    filter->add_option("--min-length", fo.min_length, "minimum length in mm (inclusive)");
    filter->add_option("--max-length", fo.max_length, "maximum length in mm (inclusive; 0: none)");
    filter->add_flag("--ends-only", fo.ends_only, "test the regions against the two end points only");
    filter->add_flag("--invert", fo.invert, "keep the streamlines the criteria drop instead");
    filter->add_option("-o,--out", fo.out, "the selected streamlines (.trx, .trk, .tck; per-streamline data and groups carried over)");
    filter->add_option("--ids", fo.ids, "write the selected streamlines' indices (0-based, one per line; - for stdout)");
    filter->add_flag("-f,--force", fo.force, "replace existing outputs (never an input)");
    filter->add_flag("--json", fo.json, "machine-readable summary");

    std::string brdf_shader;
    auto *brdf = app.add_subcommand("brdf", "evaluate shading plugins' CPU references over JSON lines on stdin");
    brdf->add_option("--shader", brdf_shader, "only this shader plugin id (default: route each case by its model)");

    RenderOptions ro;
    auto *render = app.add_subcommand("render", "render data files or a scene file to a PNG, headless (no display needed)");
    render
        ->add_option("inputs", ro.inputs, "data files (tractograms, surfaces, volumes) or one scene file (JSON; see docs/scene-format.md)")
        ->required();
    render->add_option("--view", ro.view, "camera view fitted to the scene (replaces a scene file's camera placement)")
        ->check(CLI::IsMember(named_views()));
    render
        ->add_option("-o,--out", ro.out,
                     "output image: .png, .jpg, .tif (the display picture) or .exr, .hdr (linear radiance before the tone curve, float)")
        ->capture_default_str();
    render->add_option("--size", ro.size, "WIDTHxHEIGHT")->capture_default_str()->check(kSize);
    render->add_option("--samples", ro.samples, "MSAA samples (1 = off; 0 = 4, or 1 above 200k streamline segments)")
        ->capture_default_str();
    add_lod_options(render, ro.lod);
    add_pass_options(render, ro.passes);
    add_annotation_options(render, ro.annotations);
    add_style_options(render, ro.style);
    add_volume_options(render, ro.volumes);
    render->add_flag("--preview", ro.preview, "draw the level-of-detail proxy only: the window's first picture, in a fraction of the time");
    render->add_option("--frames", ro.frames, "draw N frames and report the median time of frames 2..N (benchmarks)")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    render->add_flag("--legend", ro.legend, "list the clusters shown (colour, name, size) over the top left of the picture");
    render->add_option("--slab", ro.slab,
                       "crop the streamlines to a slab AXIS=CENTRE,HALF in mm (e.g. z=10,5), or show them as points where they cross the "
                       "plane: AXIS=CENTRE,points (e.g. z=10,points); replaces a scene file's slab");
    add_grid_options(render, ro.grid);
    render->add_option("--time", ro.time, "the scene file's timeline at this many seconds (its camera, visibility, materials, slices)");
    render->add_flag("--json", ro.json, "timings and counts as JSON");
    render->add_flag("-f,--force", ro.force, "replace an existing output image (never an input)");

    MovieOptions mo;
    auto *movie = app.add_subcommand(
        "movie", "a movie of data files or a scene file (a turntable, or the scene's timeline), headless: .mp4, .webm or frames/%04d.png");
    movie->add_option("inputs", mo.inputs, "data files or one scene file (JSON)")->required();
    movie->add_option("--view", mo.view, "the camera view it starts from (replaces a scene file's camera placement)")
        ->check(CLI::IsMember(named_views()));
    movie->add_option("-o,--out", mo.out, "the movie: .mp4 (H.264), .webm (VP9), or an image sequence with one %d (frames/%04d.png)")
        ->capture_default_str();
    movie->add_option("--size", mo.size, "WIDTHxHEIGHT (even, for a video)")->capture_default_str()->check(kSize);
    movie->add_option("--seconds", mo.seconds,
                      "the movie's length (default: the scene's timeline's duration, else 10; a timeline holds its last state after it)");
    movie->add_option("--fps", mo.fps, "frames a second")->check(CLI::Range(1, 120))->capture_default_str();
    movie
        ->add_option("--degrees", mo.degrees,
                     "the turn about the superior axis over the whole movie (default 360, once round; with a scene's timeline 0: its own "
                     "turntable)")
        ->check(CLI::Range(-3600.0, 3600.0));
    add_grid_options(movie, mo.grid);
    add_lod_options(movie, mo.lod);
    add_pass_options(movie, mo.passes);
    add_annotation_options(movie, mo.annotations);
    add_style_options(movie, mo.style);
    add_volume_options(movie, mo.volumes);
    movie->add_flag("--json", mo.json, "timings as JSON");
    movie->add_flag("-f,--force", mo.force, "replace an existing movie or frames (never an input)");

    ViewOptions vwo;
    auto *view = app.add_subcommand("view", "open the interactive window on data files or a scene file");
    view->add_option("inputs", vwo.inputs, "data files (tractograms, surfaces, volumes) or one scene .json")->required();
    view->add_option("--size", vwo.size, "window size WIDTHxHEIGHT")->capture_default_str()->check(kSize);
    view->add_option("--samples", vwo.samples, "MSAA samples")->capture_default_str();
    view->add_option("--script", vwo.script,
                     "drive the window from a script (wait N (frames), sleep S (seconds), drag, pan, scroll, click X Y [ctrl] [alt], key "
                     "K|ctrl+K, set, "
                     "shader, moving on|off, mark NAME, expand K [streamlines], hide K, repeat [T...], reset, fit, roi "
                     "sphere|box|mask|move|scale|flip|remove ..., "
                     "undo, redo, save PATH [force], press LABEL, screenshot, quit; see docs/rendering.md and docs/quality-control.md)")
        ->check(CLI::ExistingFile);
    view->add_option("--screenshot-dir", vwo.screenshot_dir, "where the S key saves screenshots")
        ->check(CLI::ExistingDirectory)
        ->capture_default_str();
    view->add_option("--view", vwo.view, "initial camera view fitted to the scene (R returns to it)")->check(CLI::IsMember(named_views()));
    auto *explore = view->add_flag("--explore", vwo.explore,
                                   "explore the first tractogram as QuickBundlesX clusters: expand, hide, repeat (paper Fig. 5)");
    view->add_option("--cluster-size-min", vwo.cluster_size_min,
                     "--explore: clusters of fewer streamlines are not shown (dipy_horizon's --cluster_size_thr)")
        ->check(CLI::Range(std::uint64_t(0), std::uint64_t(1) << 50))
        ->needs(explore);
    view->add_option("--cluster-length-min", vwo.cluster_length_min,
                     "--explore: clusters whose centroid is shorter (mm) are not shown (dipy_horizon's --cluster_length_thr)")
        ->check(CLI::Range(0.0, 1e6))
        ->needs(explore);
    view->add_option("--algorithm", vwo.algorithm, "--explore with this clustering plugin (its id or the last part of it)")
        ->capture_default_str();
    view->add_option("--param", vwo.params, "NAME=VALUE, a parameter of the clustering plugin (repeatable)")->allow_extra_args(false);
    view->add_option("--include,--roi", vwo.include,
                     "a region of interest the shown streamlines must meet: sphere:X,Y,Z,R, box:X0,Y0,Z0,X1,Y1,Z1 or a mask file "
                     "(repeatable; the window adds, moves and removes them too; --roi is the same, as dipy_horizon's --roi_images)")
        ->allow_extra_args(false);
    view->add_option(
        "--slab", vwo.slab,
        "crop the streamlines to a slab AXIS=CENTRE,HALF in mm, e.g. z=10,5, or show them as points where they cross the plane: "
        "AXIS=CENTRE,points, e.g. z=10,points (the panel moves it)");
    view->add_option("--exclude", vwo.exclude, "a region the shown streamlines must not meet (same forms; repeatable)")
        ->allow_extra_args(false);
    add_lod_options(view, vwo.lod);
    add_pass_options(view, vwo.passes);
    add_annotation_options(view, vwo.annotations);
    add_style_options(view, vwo.style);
    add_volume_options(view, vwo.volumes);
    view->footer("Keys in the window (scripts: key K, key ctrl+K):\n" + actions_help_text());
    view->add_option("--lod-frame-ms", vwo.lod_frame_ms,
                     "while the camera moves, the proxy's level follows the frame times: coarser when frames take longer than "
                     "this, finer while they take less (levels around --lod-scale and --lod-points: half and twice the size, "
                     "up to 4x the points); 0: that level throughout")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 10000.0));
    view->add_option("--stats", vwo.stats, "write per-frame times and what each frame drew to this JSON file at exit");

    ShaderCheckOptions sco;
    auto *scheck =
        app.add_subcommand("shader-check", "GPU equals CPU: render analytic scenes with shading plugins and compare every pixel");
    scheck->add_option("--shader", sco.shader, "only this shading plugin (id or short name)");
    scheck->add_option("--sets", sco.sets, "parameter sets per shader")->capture_default_str();
    scheck->add_option("--size", sco.size, "image side in pixels")->capture_default_str();
    scheck->add_option("--seed", sco.seed, "seed of the parameter and light sweeps")->capture_default_str();
    scheck->add_option("--rel", sco.rel, "relative tolerance")->capture_default_str();
    scheck->add_option("--abs", sco.abs, "absolute tolerance")->capture_default_str();
    scheck->add_flag("--json", sco.json, "machine-readable report");
    scheck->add_flag("--verbose", sco.verbose, "print the first failing pixels");

    DemoOptions demo_opts;
    auto *demo = app.add_subcommand("demo", "build the synthetic demo scene, cluster it and render demo.png");
    demo->add_option("-o,--out", demo_opts.out_dir, "directory for demo files")->capture_default_str();
    demo->add_option("--streamlines", demo_opts.nb_streamlines, "phantom size")->capture_default_str();
    demo->add_option("--seed", demo_opts.seed, "phantom seed")->capture_default_str();
    demo->add_option("--size", demo_opts.size, "picture size WIDTHxHEIGHT")->capture_default_str()->check(kSize);
    bool no_window = false;
    demo->add_flag("--no-window", no_window, "do not open the window even when a display exists");
    add_pass_options(demo, demo_opts.passes);
    add_annotation_options(demo, demo_opts.annotations);
    add_style_options(demo, demo_opts.style);

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError &e) {
        return app.exit(e);
    }
    if (verbose) spdlog::set_level(spdlog::level::debug);
    if (json || vo.json || co.json || ro.json || fo.json) disable_progress();  // (machine-readable output: no progress line)
    if (const char *t = std::getenv("HORIZON_TRACE"); t && *t == '1') spdlog::set_level(spdlog::level::trace);

    const auto dispatch = [&]() -> int {
        if (*plugins) return cmd_plugins(g, json, plugin_id);
        if (*validate) return cmd_validate(g, vo);
        if (*info) return cmd_info(g, info_file, json, info_verify);
        if (*convert) return cmd_convert(g, conv_in, conv_out, force);
        if (*demo) {
            demo_opts.window = !no_window;
            return cmd_demo(g, demo_opts);
        }
        if (*cluster) return cmd_cluster(g, co);
        if (*filter) return cmd_filter(g, fo);
        if (*brdf) return cmd_brdf(g, brdf_shader);
        if (*render) return cmd_render(g, ro);
        if (*movie) return cmd_movie(g, mo);
        if (*scheck) return cmd_shader_check(g, sco);
        if (*view) return cmd_view(g, vwo);
        return 2;
    };
    int rc = 2;
    try {
        rc = dispatch();
    } catch (const std::bad_alloc &) {
        std::fprintf(stderr, "horizon: error: out of memory (the data do not fit in this machine's memory)\n");
        rc = 1;
    } catch (const std::exception &e) {
        // One line, whatever the names in it hold (a file name may contain a
        // newline or control characters).
        std::string line;
        for (const char *p = e.what(); *p; ++p) {
            const unsigned char c = static_cast<unsigned char>(*p);
            if (c == '\n')
                line += "\\n";
            else if (c < 0x20 || c == 0x7f) {
                char esc[8];
                std::snprintf(esc, sizeof esc, "\\x%02x", c);
                line += esc;
            } else
                line += char(c);
        }
        std::fprintf(stderr, "horizon: error: %s\n", line.c_str());
        rc = 1;
    }
    // What was written to standard output must have arrived: a full disk
    // or a failed pipe is an error (`info > /dev/full` used to exit 0).
    std::cout.flush();
    errno = 0;
    const bool out_failed = std::fflush(stdout) != 0 || std::ferror(stdout) || !std::cout;
    if (out_failed && rc == 0) {
        std::fprintf(stderr, "horizon: error: standard output: %s\n", errno ? std::strerror(errno) : "a write failed");
        rc = 1;
    }
    // (a plugin's destructor that crashes or holds the exit up now is named,
    // and the exit status stays this one)
    hz::core::plugins_at_exit(rc);
    return rc;
}
