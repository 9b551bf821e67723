// `horizon render`: draws data files, or a scene file, headlessly (EGL, no X
// server) into a PNG; also the picture of `horizon demo`.
#include "commands.hpp"
#include "legend.hpp"
#include "annotations_paint.hpp"

#include <hz/core/io.hpp>
#include <hz/core/render/context.hpp>
#include <hz/core/render/renderer.hpp>
#include <hz/core/render/annotations.hpp>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <vector>
#include <cstdio>
#include <cctype>
#include <cstring>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <stdlib.h>

namespace hz::host {

namespace {

// Each kind of annotation mark ("colour bar", "orientation R", "scale bar",
// ...) with the box of all its marks (pixels: x0, y0, x1, y1; text by its
// anchor) and their texts: where `render --json` says it drew what.
nlohmann::json annotations_json(const std::vector<core::render::Mark> &marks) {
    std::map<std::string, nlohmann::json> by_role;
    std::vector<std::string> order;
    for (const core::render::Mark &m : marks) {
        auto [it, fresh] = by_role.try_emplace(m.role, nlohmann::json{{"role", m.role}, {"box", {m.x0, m.y0, m.x1, m.y1}}});
        if (fresh) order.push_back(m.role);
        nlohmann::json &e = it->second;
        auto &b = e["box"];
        b[0] = std::min(b[0].get<float>(), std::min(m.x0, m.x1)), b[1] = std::min(b[1].get<float>(), std::min(m.y0, m.y1));
        b[2] = std::max(b[2].get<float>(), std::max(m.x0, m.x1)), b[3] = std::max(b[3].get<float>(), std::max(m.y0, m.y1));
        if (m.kind == core::render::Mark::Kind::Text) e["text"].push_back(m.text);
    }
    nlohmann::json out = nlohmann::json::array();
    for (const auto &role : order) out.push_back(by_role[role]);
    return out;
}

}  // namespace

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

}  // namespace

void write_image(const core::Registry &reg, const core::render::Image &im, const fs::path &path, bool force) {
    core::Dataset ds;
    ds.kind = HZ_DATA_IMAGE;
    ds.volume.dtype = HZ_DTYPE_U8;
    ds.volume.dims = {3, std::uint64_t(im.width), std::uint64_t(im.height)};
    ds.volume.voxels = core::Buffer<std::byte>(std::size_t(im.width) * im.height * 3);
    for (std::size_t i = 0; i < std::size_t(im.width) * im.height; ++i) std::memcpy(ds.volume.voxels.data() + i * 3, &im.rgba[i * 4], 3);
    std::vector<std::string> dropped;
    if (path != "-") {
        core::write_dataset(reg, ds, path, force, &dropped);
        return;
    }
    // Standard output: a PNG written to a private temporary folder, then copied.
    char dir_template[] = "/tmp/horizon-stdout-XXXXXX";
    const char *dir = ::mkdtemp(dir_template);
    if (dir == nullptr) throw core::Error(std::string("standard output: cannot create a temporary folder: ") + std::strerror(errno));
    const fs::path png = fs::path(dir) / "image.png";
    struct Cleanup {
        fs::path d;
        ~Cleanup() {
            std::error_code ec;
            fs::remove_all(d, ec);
        }
    } cleanup{dir};
    core::write_dataset(reg, ds, png, true, &dropped);
    std::ifstream in(png, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (std::fwrite(bytes.data(), 1, bytes.size(), stdout) != bytes.size() || std::fflush(stdout) != 0)
        throw core::Error(std::string("standard output: write failed: ") + std::strerror(errno));
}

// A linear float picture (.exr, .hdr): RGB float32 through the images loader.
void write_float_image(const core::Registry &reg, const core::render::FloatImage &im, const fs::path &path, bool force) {
    core::Dataset ds;
    ds.kind = HZ_DATA_IMAGE;
    ds.volume.dtype = HZ_DTYPE_F32;
    ds.volume.dims = {3, std::uint64_t(im.width), std::uint64_t(im.height)};
    ds.volume.voxels = core::Buffer<std::byte>(std::size_t(im.width) * im.height * 3 * sizeof(float));
    for (std::size_t i = 0; i < std::size_t(im.width) * im.height; ++i)
        std::memcpy(ds.volume.voxels.data() + i * 3 * sizeof(float), &im.rgba[i * 4], 3 * sizeof(float));
    std::vector<std::string> dropped;
    core::write_dataset(reg, ds, path, force, &dropped);
}

std::pair<int, int> parse_size(const std::string &s) {
    int w = 0, h = 0;
    char x = 0, extra = 0;
    if (std::sscanf(s.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X') || w < 16 || h < 16 || w > 16384 || h > 16384)
        throw core::Error("--size " + s + ": expected WIDTHxHEIGHT between 16x16 and 16384x16384");
    return {w, h};
}

int render_scene(const core::Registry &reg, core::render::Scene scene, const RenderOptions &o, std::unique_ptr<core::render::GlContext> ctx,
                 double ctx_ms) {
    const auto [w, h] = parse_size(o.size);
    const auto t0 = Clock::now();
    if (!ctx) ctx = core::render::make_headless_context(), ctx_ms = ms_since(t0);
    core::render::Renderer r(reg);
    core::render::RenderSettings rs;
    rs.width = w, rs.height = h;
    rs.samples = o.samples;
    o.lod.apply(rs);
    if (!o.preview) rs.shell_proxy = false;  // a full-detail frame draws no proxy
    if (o.preview) rs.occlusion = false;     // and a proxy frame no full detail
    rs.shell_all_cores = true;               // --preview waits for it
    rs.bake_materials = true;                // a scene file's materials do not change while it renders
    rs.time_passes = true;                   // (a headless frame ends in a glFinish anyway)
    // .exr and .hdr: the linear radiance before the tone curve (float), not
    // the display picture.
    std::string ext = fs::path(o.out).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    rs.hdr_output = ext == ".exr" || ext == ".hdr";
    if (rs.hdr_output && o.preview) throw core::Error("--preview draws a display picture: write it as .png, .jpg or .tif, not " + ext);
    if (rs.hdr_output && o.legend) throw core::Error("--legend draws on a display picture: write it as .png, .jpg or .tif, not " + ext);
    if (rs.hdr_output && scene.annotations.any())
        throw core::Error("annotations are drawn on a display picture: write it as .png, .jpg or .tif, not " + ext);
    // A picture of nothing is an error, not a blank PNG with exit status 0.
    const bool something = std::any_of(scene.objects.begin(), scene.objects.end(), [](const core::render::Object &ob) {
        if (!ob.visible) return false;
        const core::Dataset &d = ob.data;
        if (d.kind == HZ_DATA_STREAMLINES) return d.tractogram.nb_vertices() > 0;
        if (d.kind == HZ_DATA_MESH) return d.mesh.nb_faces() > 0;
        return true;
    });
    const GridLayout grid = grid_layout(scene, w, h);
    if (grid.on() && rs.hdr_output) throw core::Error("a grid is drawn as a display picture: write it as .png, .jpg or .tif, not " + ext);
    if (grid.on() && o.preview) throw core::Error("--preview draws one view, not a grid");
    rs.width = grid.tile_w, rs.height = grid.tile_h;  // (each frame a tile: the level of detail of its pixels)
    core::render::View view = core::render::fit_view(scene, scene.camera, double(grid.tile_w) / grid.tile_h);
    if (o.time) {
        const std::string of = o.scene.empty() ? std::string("the scene") : o.scene;
        if (!scene.timeline) throw core::Error("--time: " + of + " has no timeline");
        if (!(*o.time >= 0 && *o.time <= scene.timeline->duration))
            throw core::Error("--time " + std::to_string(*o.time) + ": " + of + "'s timeline lasts " +
                              std::to_string(scene.timeline->duration) + " s");
    }
    try {
        if (!something && !o.time) throw core::Error("nothing to draw: the scene's objects are empty or hidden");
        r.set_scene(std::move(scene), view, rs);
        if (o.time) view = TimelinePlayer(r, view, double(grid.tile_w) / grid.tile_h).at(*o.time);  // (the scene at that instant)
    } catch (const core::Error &e) {
        if (o.scene.empty()) throw;
        throw core::Error(o.scene + ": " + e.what());  // name the scene file
    }
    r.set_interacting(o.preview);
    if (o.preview) r.update_proxies(true);  // the proxy the window shows once computed
    core::render::Image tiles;              // (a grid: its tiles, each its own frame)
    if (grid.on())
        tiles = render_picture(r, grid, view, w, h);
    else
        r.render(view, w, h);
    const double first_ms = r.stats().draw_ms;  // includes the GL driver's shader compilation
    std::vector<double> frames;
    for (int i = 1; i < o.frames && !grid.on(); ++i) {
        r.render(view, w, h);
        frames.push_back(r.stats().draw_ms);
    }
    std::sort(frames.begin(), frames.end());
    const double frame_ms = frames.empty() ? first_ms : frames[frames.size() / 2];
    if (rs.hdr_output) {
        const core::render::FloatImage hdr = r.read_hdr_image();
        const auto tw = Clock::now();
        write_float_image(reg, hdr, o.out, o.force);
        if (!o.json)
            std::printf("Wrote %s (%dx%d, linear radiance before the tone curve) in %.0f ms (write %.0f)\n", o.out.c_str(), w, h,
                        ms_since(t0), ms_since(tw));
        else
            std::cout << nlohmann::json{{"output", o.out},
                                        {"width", w},
                                        {"height", h},
                                        {"hdr", true},
                                        {"frame_ms", frame_ms},
                                        {"first_frame_ms", first_ms},
                                        {"total_ms", ms_since(t0)}}
                             .dump(2)
                      << "\n";
        return 0;
    }
    core::render::Image im = grid.on() ? std::move(tiles) : r.read_image();
    if (o.legend) {
        const std::vector<LegendEntry> entries = cluster_legend(r.scene());
        if (entries.empty())
            throw core::Error(
                "--legend: nothing in the picture is coloured by cluster (a scene's \"clustering\" or \"color\": "
                "{\"mode\": \"cluster\"}, or a selection the window saved)");
        draw_legend(im, entries);
    }
    // The annotations over the picture, laid out as the window lays them out.
    std::vector<core::render::Mark> marks;
    if (r.scene().annotations.any()) {
        const std::vector<core::render::ColourScale> scales = r.colour_scales();
        const core::render::Annotations &a = r.scene().annotations;
        if (a.colour_bar && !a.orientation && !a.scale_bar && scales.empty())  // (asked for alone: say why there is none)
            spdlog::warn("colour bar: nothing in the picture is coloured through a colormap (a \"color\" of mode \"data\", or a volume)");
        marks = core::render::layout_annotations(r.scene().annotations, scales, view, w, h);
        paint_marks(im, marks);
    }
    const auto tw = Clock::now();
    write_image(reg, im, o.out, o.force);
    const double write_ms = ms_since(tw);
    const auto &s = r.stats();
    if (o.out == "-") return 0;  // (standard output holds the picture)
    if (o.json) {
        nlohmann::json j = {
            {"output", o.out},
            {"width", w},
            {"height", h},
            {"gl", r.gl_description()},
            {"context_ms", ctx_ms},
            {"upload_ms", s.upload_ms},
            {"environment_ms", s.environment_ms},
            {"first_frame_ms", first_ms},
            {"frame_ms", frame_ms},
            {"frame_ms_min", frames.empty() ? first_ms : frames.front()},
            {"frames", o.frames},
            {"readback_ms", s.readback_ms},
            {"write_ms", write_ms},
            {"total_ms", ms_since(t0)},
            {"segments", s.segments_drawn},
            {"triangles", s.triangles_drawn},
            {"samples", s.samples},
            {"points_total", s.points_total},
            {"points_drawn", s.points_drawn},
            {"streamlines_drawn", s.streamlines_drawn},
            {"streamed_points", s.streamed_points},
            {"slab_crossings", s.crossings_drawn},
            {"fibre_volumes", s.volumes_drawn},
            {"fibre_volume_rays", s.volume_rays},
            {"culled_chunks", s.culled_chunks},
            {"culled_points", s.culled_points},
            {"proxy", s.proxy},
            {"passes",
             {{"ambient_occlusion", {{"on", r.scene().ambient_occlusion.on}, {"ms", s.ao_ms}}},
              {"depth_cue", {{"on", r.scene().depth_cue.on}, {"ms", s.depth_cue_ms}}},
              {"shadows", {{"on", r.scene().shadows.on}, {"ms", s.shadow_ms}, {"map", s.shadow_map}, {"texel_mm", s.shadow_texel_mm}}},
              {"volume_rendering", {{"volumes", s.volumes_rendered}, {"ms", s.volume_ms}}},
              {"transparency", {{"layers", s.transparency_layers}}},
              {"antialiasing", {{"on", r.scene().antialiasing.on}, {"edge", s.edge_aa}, {"frames", s.aa_frames}, {"ms", s.aa_ms}}}}},
            {"points_kept", s.points_drawn}};
        j["annotations"] = annotations_json(marks);
        if (grid.on())
            j["grid"] = {{"columns", grid.columns}, {"rows", grid.rows}, {"titles", r.scene().grid->titles}, {"cells", grid.cells}};
        std::cout << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
    } else {
        std::printf("Wrote %s (%dx%d) in %.0f ms: context %.0f, upload %.0f, environment %.0f, first frame %.0f, read %.0f, write %.0f\n",
                    o.out.c_str(), w, h, ms_since(t0), ctx_ms, s.upload_ms, s.environment_ms, first_ms, s.readback_ms, write_ms);
        if (o.frames > 1) std::printf("  %d frames: median %.1f ms/frame\n", o.frames, frame_ms);
        if (r.scene().ambient_occlusion.on) std::printf("  ambient occlusion: %.1f ms\n", s.ao_ms);
        if (r.scene().depth_cue.on) std::printf("  depth cue: %.1f ms\n", s.depth_cue_ms);
        if (r.scene().shadows.on)
            std::printf("  shadows: %.1f ms (a %dx%d map, %.3f mm a texel)\n", s.shadow_ms, s.shadow_map, s.shadow_map, s.shadow_texel_mm);
        if (s.volumes_rendered) std::printf("  volume rendering: %.1f ms (%d volumes)\n", s.volume_ms, s.volumes_rendered);
        if (s.aa_frames > 1) std::printf("  anti-aliasing: %d jittered frames averaged\n", s.aa_frames);
        if (s.edge_aa) std::printf("  anti-aliasing: edges smoothed (%.1f ms)\n", s.aa_ms);
        if (s.crossings_drawn)
            std::printf("  slab crossings drawn: %llu (where the streamlines cross the plane)\n", (unsigned long long)s.crossings_drawn);
        else if (s.points_total)
            std::printf("  streamline points drawn: %llu of %llu (decimated at %.2f px%s)\n", (unsigned long long)s.points_drawn,
                        (unsigned long long)s.points_total, o.lod.lod_pixels,
                        s.volumes_drawn ? "; the level-of-detail proxy over its fibre volume"
                        : s.proxy       ? "; the level-of-detail proxy"
                                        : "");
    }
    return 0;
}

int cmd_render(const GlobalOptions &g, const RenderOptions &o) {
    const core::Registry reg = load_registry(g);
    if (o.out == "-" && o.json) throw core::Error("-o - and --json both write to standard output: choose one");
    if (o.out != "-") core::loader_for_write(reg, o.out, HZ_DATA_IMAGE);  // fail on an unwritable target before the work
    // Never over an input (a NIfTI pair's other half included), and over an
    // existing file only with --force: checked before any work.
    check_outputs({o.out}, o.inputs, o.force);
    RenderOptions opts = o;
    if (is_scene_file(o.inputs)) opts.scene = o.inputs[0];
    const std::optional<core::render::Slab> slab = o.slab.empty() ? std::nullopt : std::optional(parse_slab(o.slab));
    // (the GL context first: a machine that has none is told before the files are read)
    const auto t0 = Clock::now();
    auto ctx = core::render::make_headless_context();
    const double ctx_ms = ms_since(t0);
    core::render::Scene scene = scene_from_inputs(reg, o.inputs, o.view, "render");
    o.passes.apply(scene);
    o.annotations.apply(scene);
    o.style.apply(scene);
    o.style.add_glass_brain(reg, scene);
    o.volumes.apply(scene);
    o.grid.apply(scene);
    // Every file the scene file named is an input too (its environment map,
    // meshes, overlays, masks): checked once it is known, before anything
    // is written.
    if (!scene.files.empty()) check_outputs({o.out}, scene.files, o.force);
    if (slab) scene.slab = slab;
    try {
        return render_scene(reg, std::move(scene), opts, std::move(ctx), ctx_ms);
    } catch (const core::Error &e) {
        if (opts.scene.empty() && o.inputs.size() == 1) throw core::Error(o.inputs[0] + ": " + e.what());
        throw;
    }
}

}  // namespace hz::host
