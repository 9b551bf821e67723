// The OpenGL renderer (see renderer.hpp).
#include <hz/core/io.hpp>
#include <hz/core/render/renderer.hpp>
#include <hz/core/render/decimate.hpp>
#include <hz/core/render/pick.hpp>

#include "colour.hpp"
#include "gl.hpp"
#include "gpu_object.hpp"
#include "image_lighting.hpp"
#include "jobs.hpp"
#include "glsl.hpp"
#include "programs.hpp"
#include "passes/ambient_occlusion.hpp"
#include "passes/antialiasing.hpp"
#include "passes/depth_cue.hpp"
#include "passes/shadow.hpp"
#include "passes/volume_rendering.hpp"
#include "passes/transparency.hpp"
#include "passes/frame_depth.hpp"
#include "reprojection.hpp"
#include "targets.hpp"

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <future>
#include <random>
#include <mutex>
#include <thread>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>
#include <map>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <numeric>
#include <set>
#include <sstream>
#include <unordered_map>

namespace hz::core::render {

namespace {

glm::dvec3 to_dvec3(const Vec3 &v) { return glm::dvec3(v[0], v[1], v[2]); }

// ---------------------------------------------------------------- GL helpers

GLuint compile_shader(GLenum type, const std::string &src, const std::string &what) {
    GLuint s = glCreateShader(type);
    const char *p = src.c_str();
    glShaderSource(s, 1, &p, nullptr);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        GLint len = 0;
        glGetShaderiv(s, GL_INFO_LOG_LENGTH, &len);
        std::string log(std::max(len, 1), '\0');
        glGetShaderInfoLog(s, len, nullptr, log.data());
        glDeleteShader(s);
        // The first line that is an error (Mesa lists warnings first).
        std::string first, line;
        std::istringstream in(log);
        while (std::getline(in, line))
            if (line.find("error") != std::string::npos) {
                first = line;
                break;
            }
        if (first.empty()) first = log.substr(0, log.find('\n'));
        spdlog::debug("{}: GLSL log:\n{}", what, log);
        throw Error(what + ": GLSL compile error in " + glsl_error_where(first));
    }
    return s;
}

GLuint link_program(const std::vector<GLuint> &shaders, const std::string &what) {
    GLuint p = glCreateProgram();
    for (GLuint s : shaders) glAttachShader(p, s);
    glLinkProgram(p);
    for (GLuint s : shaders) {
        glDetachShader(p, s);
        glDeleteShader(s);
    }
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        GLint len = 0;
        glGetProgramiv(p, GL_INFO_LOG_LENGTH, &len);
        std::string log(std::max(len, 1), '\0');
        glGetProgramInfoLog(p, len, nullptr, log.data());
        glDeleteProgram(p);
        throw Error(what + ": GLSL link error: " + log.substr(0, log.find('\n')));
    }
    return p;
}

}  // namespace

using targets::Fbo;
using targets::Tex2dFbo;

const LoadedPlugin *find_shader(const Registry &reg, const std::string &name) {
    if (const LoadedPlugin *p = reg.find(name); p && p->shader()) return p;
    for (const LoadedPlugin *p : reg.of_kind(HZ_KIND_SHADER)) {
        const std::string &id = p->info.id;
        if (id.size() > name.size() && id.compare(id.size() - name.size(), name.size(), name) == 0 &&
            id[id.size() - name.size() - 1] == '.')
            return p;
    }
    return nullptr;
}

std::array<double, 16> view_projection(const View &v, int width, int height) {
    const glm::dmat4 view = glm::lookAt(to_dvec3(v.eye), to_dvec3(v.target), to_dvec3(v.up));
    const glm::dmat4 proj = glm::perspective(glm::radians(v.fov_deg), double(width) / std::max(height, 1), v.near_mm, v.far_mm);
    const glm::dmat4 vp = proj * view;
    std::array<double, 16> out;
    std::memcpy(out.data(), glm::value_ptr(vp), sizeof out);
    return out;
}

// ==================================================================== Impl

struct Renderer::Impl {
    struct Matrices;  // (a frame's camera matrices; below)
    const Registry &reg;
    Scene scene;
    RenderSettings settings;
    // The proxy's levels (proxy_levels of the settings) and the one drawn.
    std::vector<ProxyLevel> levels;
    int level = 0;
    int proxy_scale_now() const { return levels.empty() ? std::max(1, settings.proxy_scale) : levels[std::size_t(level)].scale; }
    double proxy_points_now() const { return levels.empty() ? settings.lod_points : levels[std::size_t(level)].points; }
    std::vector<GpuObject> objects;
    std::map<std::string, std::unique_ptr<Program>> programs;
    std::map<std::string, std::unique_ptr<Program>> aux_programs;  // sky, slices, tonemap by output and curve
    GLuint empty_vao = 0;
    std::unique_ptr<ImageLighting> ibl;  // the environment's lighting
    std::unique_ptr<Reprojection> warp;  // the last complete still, drawn again under the proxy while the camera moves
    // The passes after the geometry (passes/): the frame's depth they read,
    // ambient occlusion, depth cue.
    std::unique_ptr<FrameDepth> frame_depth;
    std::unique_ptr<AmbientOcclusionPass> ao_pass;
    std::unique_ptr<ShadowPass> shadow_pass;
    std::unique_ptr<VolumeRendering> volume_pass;
    std::unique_ptr<DepthCuePass> cue_pass;
    // Anti-aliasing (passes/antialiasing): the edge pass over every frame
    // drawn without multisampling; the sum of a still's jittered frames.
    std::unique_ptr<EdgeAaPass> edge_aa;
    std::unique_ptr<Accumulation> accumulation, accumulation_hdr;  // (the display picture's; the linear one's with hdr_output)
    glm::dvec2 jitter_px{0, 0};                                    // the frame's offset in pixels (matrices(): a jittered frame of a still)
    bool accumulating = false;                                     // drawing the jittered frames of a still: no edge pass on each
    int frame_samples = 1;                                         // MSAA samples of the frame being drawn (begin_frame)
    // Translucent objects, composited in depth order (passes/transparency).
    std::unique_ptr<DepthPeeling> peeling;
    GLuint peel_depth = 0;  // while a layer is drawn: the last layer's depths (objects draw with peel programs)
    bool peeled = false;    // the frame's translucency is composited into `resolved` already
    int peel_layers = 0;    // layers peeled in the last frame
    static constexpr int kMaxPeelLayers = 8;
    static constexpr std::uint64_t kPeelPoints = 4'000'000;
    View frame_view;               // the camera of the frame being drawn (the passes after the geometry)
    int frame_w = 0, frame_h = 0;  // the size of the frame being drawn (a proxy frame's full size)
    Fbo msaa;                      // the HDR path's multisampled RGBA16F target
    Fbo msaa_display;              // the display path's multisampled RGBA8 target
    Tex2dFbo resolved, behind, ldr;
    // The level-of-detail frame: drawn at 1/proxy_scale_now() of the
    // window's size into `lowres` (fewer fragments; each subsample line
    // covers proxy_scale window pixels across, which keeps the picture's
    // coverage), then upscaled (bilinear) into `ldr`.
    Tex2dFbo lowres;
    // In a proxy frame, the fibre volume is ray-marched smaller still (down
    // to 1/settings.volume_scale of the window's size: it is smooth, and its
    // rays are most of a proxy frame's time) into `volres` (premultiplied
    // colour and the depth where each ray became half opaque), then drawn
    // into the proxy's target by `volume_upscale` under the proxy's lines.
    Tex2dFbo volres;
    std::unique_ptr<Program> volume_upscale;
    Tex2dFbo *out_ = &ldr;        // where the frame being drawn ends (ldr, or lowres for the proxy frame)
    bool hdr_frame_full = false;  // the last frame went through `resolved` at full size (read_hdr_image)
    std::unique_ptr<Program> composite;
    // Where shading programs write. Display: tonemapped, sRGB-encoded
    // values straight into the RGBA8 image (one pass, no float target).
    // HDR: linear radiance into RGBA16F, then a tonemapping pass; needed
    // when translucent or refractive objects composite over the opaque
    // image. Debug: the GPU-equals-CPU check's float outputs.
    // Peel: HDR, a depth-peeling layer (passes/transparency.hpp).
    enum class Output { Hdr, Display, Debug, Peel };
    bool display_direct = true;  // the output of the frame being drawn
    FrameStats stats;
    // Every tractogram's GL buffers of streamline chunks, against
    // settings.gpu_memory_mb (the drawables release theirs when they go:
    // ~Impl clears the objects first).
    LineStream stream{settings, stats};
    std::vector<float> depth_scratch;  // (occlusion culling's readbacks)
    int max_samples = 1;
    bool interacting = false;
    std::uint64_t generation = 0;  // bumped by every change to what a frame shows
    std::vector<bool> has_proxy;
    double tol_mm = 0;  // streamline decimation tolerance of the current scene

    void release(GpuObject &o) {
        o.tract.reset();  // (its background work stopped first, then its buffers)
        if (o.vao) glDeleteVertexArrays(1, &o.vao);
        if (o.vbo) glDeleteBuffers(1, &o.vbo);
        if (o.ebo) glDeleteBuffers(1, &o.ebo);
        if (o.moving.vao) glDeleteVertexArrays(1, &o.moving.vao);
        if (o.moving.vbo) glDeleteBuffers(1, &o.moving.vbo);
        if (o.moving.ebo) glDeleteBuffers(1, &o.moving.ebo);
        o.moving = GpuObject::MeshBuffers{};
        if (o.volume_tex) glDeleteTextures(1, &o.volume_tex);
        if (o.colormap_tex) glDeleteTextures(1, &o.colormap_tex);
        o.vao = o.vbo = o.ebo = o.volume_tex = o.colormap_tex = 0;
    }

    GpuObject upload(std::size_t i) {
        const Object &o = scene.objects[i];
        GpuObject g;
        g.index = i;
        if (o.kind == HZ_DATA_STREAMLINES) {
            g.geom = o.render == "tubes" ? Geom::Tube : Geom::Line;
            double finest = 0;  // (the points of the proxy's finest level)
            for (const ProxyLevel &l : levels) finest = std::max(finest, l.points);
            g.tract = std::make_unique<TractogramDrawable>(tract_context(), o, i, g.geom == Geom::Tube, tol_mm, proxy_scale_now(), finest);
            g.uniform_rgba = uniform_colour(*g.tract->lines());
            g.bounds = g.tract->bounds();
            g.segments = g.tract->segments();
            if (const LineData &d = *g.tract->lines(); d.mode == LineData::Mode::Data)
                g.colour_scale = ColourScale{o.name, o.coloring.array, d.colormap, d.range};
            resolve_material(g, o, o.material);
        } else if (o.kind == HZ_DATA_MESH) {
            g.geom = Geom::Mesh;
            upload_mesh(g, o);
            resolve_material(g, o, o.material);
        } else if (o.kind == HZ_DATA_VOLUME) {
            g.slices = true;
            upload_slices(g, o);
        } else {
            throw Error(o.name + ": nothing to draw for this kind of data");
        }
        return g;
    }

    // Whether object `i` is drawn in this frame (visibility and level of detail).
    bool drawn(std::size_t i) const {
        const Object &o = scene.objects[i];
        if (!o.visible) return false;
        if (o.proxy_for) return interacting && *o.proxy_for < scene.objects.size() && scene.objects[*o.proxy_for].visible;
        return !(interacting && i < has_proxy.size() && has_proxy[i]);
    }

    explicit Impl(const Registry &r) : reg(r) {
        glGenVertexArrays(1, &empty_vao);
        glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
        // (what every pass compiles its programs with)
        const auto simple = [this](const std::string &vs, const std::string &fs, const std::string &what) {
            return make_simple(vs, fs, what);
        };
        ibl = std::make_unique<ImageLighting>(simple);
        warp = std::make_unique<Reprojection>(simple);
        ao_pass = std::make_unique<AmbientOcclusionPass>(simple);
        cue_pass = std::make_unique<DepthCuePass>(simple);
        edge_aa = std::make_unique<EdgeAaPass>(simple);
        accumulation = std::make_unique<Accumulation>(simple);
        accumulation_hdr = std::make_unique<Accumulation>(simple);
        peeling = std::make_unique<DepthPeeling>(simple);
        frame_depth = std::make_unique<FrameDepth>();
        volume_pass = std::make_unique<VolumeRendering>(simple);
        shadow_pass = std::make_unique<ShadowPass>(
            [this](const std::string &vs, const std::string &gs, const std::string &fs, const std::string &what) {
                std::vector<GLuint> stages{compile_shader(GL_VERTEX_SHADER, vs, what + " (vertex)")};
                if (!gs.empty()) stages.push_back(compile_shader(GL_GEOMETRY_SHADER, gs, what + " (geometry)"));
                stages.push_back(compile_shader(GL_FRAGMENT_SHADER, fs, what));
                auto p = std::make_unique<Program>();
                p->id = link_program(stages, what);
                return p;
            });
    }

    ~Impl() {
        clear_objects();
        for (auto &[k, p] : programs) glDeleteProgram(p->id);
        for (auto &[k, p] : aux_programs) glDeleteProgram(p->id);
        ibl.reset();
        warp.reset();
        ao_pass.reset();
        shadow_pass.reset();
        volume_pass.reset();
        cue_pass.reset();
        edge_aa.reset();
        accumulation.reset();
        accumulation_hdr.reset();
        peeling.reset();
        frame_depth.reset();
        glDeleteVertexArrays(1, &empty_vao);
        msaa.destroy();
        msaa_display.destroy();
        resolved.destroy();
        behind.destroy();
        ldr.destroy();
        lowres.destroy();
        volres.destroy();
        if (composite) glDeleteProgram(composite->id);
        if (volume_upscale) glDeleteProgram(volume_upscale->id);
    }

    std::unique_ptr<Program> make_simple(const std::string &vs, const std::string &fs, const std::string &what) {
        auto p = std::make_unique<Program>();
        p->id =
            link_program({compile_shader(GL_VERTEX_SHADER, vs, what + " (vertex)"), compile_shader(GL_FRAGMENT_SHADER, fs, what)}, what);
        p->fragment_source = fs;
        return p;
    }

    int tone_curve() const { return scene.tonemap == "aces" ? 0 : scene.tonemap == "reinhard" ? 1 : 2; }

    enum class Aux { Sky, Slices, Tonemap };
    // The host's sky, slice and tonemapping programs for an output and the
    // scene's tone curve, compiled when first needed.
    Program &aux(Aux which, bool display) {
        const int curve = tone_curve();
        const std::string key = std::to_string(int(which)) + (display ? "d" : "h") + std::to_string(curve);
        auto it = aux_programs.find(key);
        if (it != aux_programs.end()) return *it->second;
        std::string fs = "#version 410 core\n#define HZ_TONEMAP " + std::to_string(curve) + "\n";
        if (display) fs += "#define HZ_DISPLAY 1\n";
        fs += glsl::kDisplay;
        std::unique_ptr<Program> p;
        if (which == Aux::Sky)
            p = make_simple(glsl::kFullscreenVS, fs + glsl::kSkyFS, "sky");
        else if (which == Aux::Slices)
            p = make_simple(glsl::kSliceVS, fs + glsl::kSliceFS, "slices");
        else
            p = make_simple(glsl::kFullscreenVS, fs + glsl::kTonemapFS, "tonemap");
        Program &ref = *p;
        aux_programs[key] = std::move(p);
        return ref;
    }

    // A snippet that reads the opaque image behind it (drawn after it).
    static bool reads_scene_behind(const char *snippet) { return snippet && std::strstr(snippet, "hz_scene_behind("); }

    // Whether object `o` must be composited in linear radiance over the
    // opaque image: translucent, or a shader that reads hz_scene_behind.
    // Before upload (the shader's snippets for any domain) ...
    bool composited(const Object &o) const {
        if (o.opacity < 1.0) return true;
        if (o.kind == HZ_DATA_VOLUME) return false;
        const LoadedPlugin *p = find_shader(reg, o.material.shader);
        if (!p) return false;
        for (hz_shade_domain d : {HZ_SHADE_LINE, HZ_SHADE_SURFACE})
            if ((p->shader()->domains & d) && reads_scene_behind(p->shader()->glsl_source(d, 410))) return true;
        return false;
    }
    // ... and once uploaded (the snippet it is drawn with).
    bool composited(const GpuObject &g) const { return (!g.dvr && scene.objects[g.index].opacity < 1.0) || g.refractive; }

    // The output of the next frame: display unless something drawn needs
    // the HDR path.
    bool frame_is_direct() const {
        for (const auto &g : objects)
            if (drawn(g.index) && composited(g)) return false;
        return true;
    }

    // The program of `g` for `out`, compiled on first use.
    Program &program_for(const GpuObject &g, Output out) {
        Program *&slot = out == Output::Debug     ? g.debug_program
                         : out == Output::Display ? g.display_program
                         : out == Output::Peel    ? g.peel_program
                                                  : g.program;
        if (!slot) slot = get_program(g, out, g.geom);
        return *slot;
    }
    // The program of the slab's crossings of tractogram `g`.
    Program &point_program_for(const GpuObject &g, Output out) {
        Program *&slot = g.point_programs[int(out)];
        if (!slot) slot = get_program(g, out, Geom::Point);
        return *slot;
    }
    // The program of tractogram `g`'s fibre volume.
    Program &volume_program_for(const GpuObject &g, Output out) {
        Program *&slot = g.volume_programs[int(out)];
        if (!slot) slot = get_program(g, out, Geom::Volume);
        return *slot;
    }

    void clear_objects() {
        for (auto &o : objects) release(o);
        objects.clear();
    }

    // --------------------------------------------------------------- programs

    // Resolves the material of `o` into shader + values; throws Error.
    void resolve_material(GpuObject &g, const Object &o, const Material &m) {
        const LoadedPlugin *p = find_shader(reg, m.shader);
        if (!p) throw Error(o.name + ": material: no shading plugin '" + m.shader + "' (see `horizon plugins`)");
        const hz_shader *sh = p->shader();
        const hz_shade_domain need = g.geom == Geom::Line ? (HZ_SHADE_LINE | HZ_SHADE_SURFACE) : HZ_SHADE_SURFACE;
        if (!(sh->domains & need))
            throw Error(o.name + ": material: shader '" + p->info.id + "' cannot shade " + (g.geom == Geom::Line ? "lines" : "surfaces"));
        g.use_line_domain = g.geom == Geom::Line && (sh->domains & HZ_SHADE_LINE);
        {
            const char *src = sh->glsl_source(g.use_line_domain ? HZ_SHADE_LINE : HZ_SHADE_SURFACE, 410);
            g.refractive = reads_scene_behind(src);
        }
        std::vector<double> values;
        std::set<std::string> known;
        std::string albedo;
        for (uint32_t i = 0; i < sh->param_count; ++i) {
            const hz_param_info *pi = sh->get_param(i);
            known.insert(pi->name);
            if (albedo.empty() && pi->type == HZ_PARAM_COLOR3) albedo = pi->name;
            auto it = m.params.find(pi->name);
            const uint32_t comps = pi->components;
            for (uint32_t c = 0; c < comps; ++c) {
                double v = default_component(pi, c);
                if (it != m.params.end()) {
                    if (it->second.size() != comps && !(pi->type == HZ_PARAM_FLOAT_ARRAY && it->second.size() <= comps))
                        throw Error(o.name + ": material: '" + pi->name + "' takes " + std::to_string(comps) + " value(s)");
                    if (c < it->second.size()) v = it->second[c];
                }
                const double lo = pi->min_value[pi->type == HZ_PARAM_FLOAT_ARRAY ? 0 : c];
                const double hi = pi->max_value[pi->type == HZ_PARAM_FLOAT_ARRAY ? 0 : c];
                if (v < lo || v > hi) {
                    spdlog::warn("{}: material: {} = {} clamped to [{}, {}]", o.name, pi->name, v, lo, hi);
                    v = std::clamp(v, lo, hi);
                }
                values.push_back(v);
            }
        }
        // A colour the material gives explicitly is the colour: the object's
        // colouring (per-vertex colours, orientation, data, clusters) drives
        // the shader's colour parameter only when the material leaves it out.
        if (!albedo.empty() && m.params.count(albedo)) {
            spdlog::debug("{}: material: {} given, so the object's colouring does not drive it", o.name, albedo);
            albedo.clear();
        }
        for (const auto &[k, v] : m.params)
            if (!known.count(k)) {
                std::string list;
                for (const auto &n : known) list += (list.empty() ? "" : ", ") + n;
                throw Error(o.name + ": material: shader '" + p->info.id + "' has no parameter '" + k + "' (it has: " + list + ")");
            }
        g.shader = p;
        g.values = std::move(values);
        g.albedo = albedo;
        g.program = g.display_program = g.debug_program = g.peel_program = nullptr;
        std::fill(std::begin(g.point_programs), std::end(g.point_programs), nullptr);
        std::fill(std::begin(g.volume_programs), std::end(g.volume_programs), nullptr);
        // Compile now (errors surface here) for the output it will most
        // likely be drawn with.
        program_for(g, display_direct ? Output::Display : Output::Hdr);
    }

    std::string fragment_source(const GpuObject &g, Output out, Geom geom) const {
        FragmentSpec f;
        f.shader = g.shader;
        f.geom = geom == Geom::Mesh     ? ProgramGeom::Mesh
                 : geom == Geom::Tube   ? ProgramGeom::Tube
                 : geom == Geom::Point  ? ProgramGeom::Point
                 : geom == Geom::Volume ? ProgramGeom::Volume
                                        : ProgramGeom::Line;
        // (A crossing is drawn as a small sphere: shaded as a surface where
        // the shader can.)
        f.line_domain = g.use_line_domain && !(geom == Geom::Point && (g.shader->shader()->domains & HZ_SHADE_SURFACE));
        f.values = g.values;
        f.albedo = g.albedo;
        f.uniform_rgba = g.uniform_rgba;
        f.refractive = g.refractive;
        f.bake = settings.bake_materials;
        f.output = out == Output::Debug ? ProgramOutput::Debug : out == Output::Display ? ProgramOutput::Display : ProgramOutput::Hdr;
        f.peel = out == Output::Peel;
        f.tone_curve = tone_curve();
        f.env_on = ibl->on;
        f.lights = lights();
        f.shadow_light = scene.shadows.on ? key_light() : -1;
        return fragment_program(f);
    }

    Program *get_program(const GpuObject &g, Output out, Geom geom) {
        const std::string fs = fragment_source(g, out, geom);
        const std::string key = std::to_string(int(geom)) + "\n" + fs;
        auto it = programs.find(key);
        if (it != programs.end()) return it->second.get();
        const std::string what = "shader '" + g.shader->info.id + "'";
        std::vector<GLuint> stages;
        if (geom == Geom::Mesh)
            stages.push_back(compile_shader(GL_VERTEX_SHADER, glsl::kMeshVS, what + " (mesh vertex stage)"));
        else if (geom == Geom::Point)
            stages.push_back(compile_shader(GL_VERTEX_SHADER, glsl::kPointVS, what + " (slab point vertex stage)"));
        else if (geom == Geom::Volume)
            stages.push_back(compile_shader(GL_VERTEX_SHADER, glsl::kVolumeVS, what + " (fibre volume vertex stage)"));
        else if (geom == Geom::Line)
            stages.push_back(compile_shader(GL_VERTEX_SHADER, glsl::kLineVS, what + " (line vertex stage)"));
        else {
            stages.push_back(compile_shader(GL_VERTEX_SHADER, glsl::kTubeVS, what + " (tube vertex stage)"));
            stages.push_back(compile_shader(GL_GEOMETRY_SHADER, glsl::kTubeGS, what + " (tube geometry stage)"));
        }
        stages.push_back(compile_shader(GL_FRAGMENT_SHADER, fs, what));
        spdlog::trace("{}: fragment program:\n{}", what, fs);
        auto p = std::make_unique<Program>();
        p->id = link_program(stages, what);
        p->fragment_source = fs;
        Program *raw = p.get();
        programs[key] = std::move(p);
        return raw;
    }

    void set_material_uniforms(Program &p, const GpuObject &g) {
        const hz_shader *sh = g.shader->shader();
        std::size_t k = 0;
        for (uint32_t i = 0; i < sh->param_count; ++i) {
            const hz_param_info *pi = sh->get_param(i);
            const GLint loc = p.loc(std::string("u_") + pi->name);
            const double *v = g.values.data() + k;
            if (loc >= 0) switch (pi->type) {
                case HZ_PARAM_FLOAT: glUniform1f(loc, float(v[0])); break;
                case HZ_PARAM_INT:
                case HZ_PARAM_ENUM:
                case HZ_PARAM_BOOL: glUniform1i(loc, int(std::lround(v[0]))); break;
                case HZ_PARAM_VEC2: glUniform2f(loc, float(v[0]), float(v[1])); break;
                case HZ_PARAM_VEC3:
                case HZ_PARAM_COLOR3: glUniform3f(loc, float(v[0]), float(v[1]), float(v[2])); break;
                case HZ_PARAM_FLOAT_ARRAY: {
                    std::vector<float> f(v, v + pi->components);
                    glUniform1fv(loc, GLsizei(f.size()), f.data());
                    break;
                }
                default: break;
                }
            k += pi->components;
        }
    }

    // ----------------------------------------------------------------- upload

    // Sets the vertex layout of the bound VAO for the bound buffer.
    // ------------------------------------------------------------ tractograms
    // Each tractogram's level of detail, streaming and culling is its
    // drawable's (tractogram/drawable.hpp); here, what concerns them all.

    TractogramDrawable::Context tract_context() { return {settings, stats, stream}; }

    // The full-detail chunks over bricks of the tractograms whose cut is done
    // (with `wait`, once it is). True if any was adopted (chunk indices changed).
    bool adopt_bricks(bool wait) {
        bool changed = false;
        for (GpuObject &g : objects)
            if (g.tract && g.tract->adopt_bricks(wait)) changed = true;
        return changed;
    }

    bool bricks_pending() const {
        return std::any_of(objects.begin(), objects.end(),
                           [&](const GpuObject &g) { return g.tract && g.tract->bricks_pending() && drawn(g.index); });
    }

    // How many of g's proxy chunks the current level draws: its points,
    // over a fibre volume 3/4 of them (which keeps the frame within its
    // time with the volume's pass); at least one.
    std::size_t drawn_proxy_chunks(const GpuObject &g, bool over) const {
        return g.tract->proxy_chunks_for(proxy_points_now() * (over ? 0.75 : 1.0));
    }

    // Replaces uniform proxies by their shell proxies where these are
    // computed (or, with `wait`, once they are). True if one changed.
    bool adopt_shell_proxies(bool wait) {
        bool changed = false;
        for (GpuObject &g : objects)
            if (g.tract && g.tract->adopt_shell_proxy(wait, proxy_scale_now())) changed = true;
        return changed;
    }

    // A tractogram's proxy is its fibre volume (once computed; for lines,
    // which it models a pixel wide; not with a slab, which it does not crop,
    // nor translucent).
    bool volume_proxy(const GpuObject &g) const {
        return settings.fibre_volume && g.tract && g.tract->has_fibre_volume() && g.geom == Geom::Line && !scene.slab && !composited(g);
    }

    // Uploads the fibre volumes computed since the last call (all of them,
    // waiting, with `wait`). True if one was adopted.
    bool adopt_fibre_volumes(bool wait) {
        bool changed = false;
        for (GpuObject &g : objects)
            if (g.tract && g.tract->adopt_fibre_volume(wait)) changed = true;
        return changed;
    }

    // "Over" blending of display colours by their alpha (the volume's
    // coverage, the lines' over it), the target's alpha accumulated.
    static void blend_over() {
        glEnable(GL_BLEND);
        glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    }

    // How much smaller than a w x h proxy frame g's fibre volume is
    // ray-marched: at most volume_scale / proxy_scale times (and no more
    // than its drawable allows).
    int volume_downscale(const GpuObject &g, const Matrices &m, int w, int h) const {
        return g.tract->volume_downscale(m.view_proj, w, h, settings.volume_scale / proxy_scale_now());
    }

    // The slab shows where streamlines cross its plane (Slab::points).
    bool crossing_mode() const { return scene.slab && scene.slab->points; }
    // Crossings are points of a few pixels, each a quad to llvmpipe (about
    // 0.3 us): above a quarter of lod_points of them, a tractogram's
    // crossings have a proxy too, their first crossing_budget() (the
    // crossings are shuffled: any prefix is a uniform subsample), and are
    // refined chunk by chunk at rest.
    std::uint64_t crossing_budget() const { return std::uint64_t(std::max(1000.0, settings.lod_points / 4)); }
    // A tractogram drawn through its level-of-detail proxy while the
    // camera moves and first at rest.
    bool lod_proxy(const GpuObject &g) const {
        if (!g.tract) return false;
        return crossing_mode() ? g.tract->crossings().total > crossing_budget() : g.tract->has_lod_proxy();
    }

    // Starts computing the crossings of every tractogram whose drawn or
    // pending crossings are not those of the slab's plane. Called whenever
    // the slab or an object changes.
    void schedule_crossings() {
        if (!crossing_mode()) return;
        for (GpuObject &g : objects)
            if (g.tract) g.tract->schedule_crossings(scene.slab->axis, scene.slab->centre);
    }

    // Adopts the crossings computed since the last call (with `wait`, once
    // they are); true if what a frame shows changed.
    bool adopt_crossings(bool wait) {
        bool changed = false;
        for (GpuObject &g : objects)
            if (g.tract && g.tract->adopt_crossings(wait)) changed = true;
        if (changed) ++generation;
        return changed;
    }

    bool computing_crossings() const {
        return std::any_of(objects.begin(), objects.end(), [](const GpuObject &g) { return g.tract && g.tract->computing_crossings(); });
    }

    // ------------------------------------------------------------------ frame

    struct Matrices {
        glm::mat4 view_proj;
        glm::dmat4 inv_view_proj;
        glm::dvec3 right, up, back;
    };

    // (moved by jitter_px on the picture: one of a still's jittered frames)
    Matrices matrices(const View &v, int w, int h) const {
        Matrices m;
        const glm::dvec3 eye = to_dvec3(v.eye), target = to_dvec3(v.target);
        glm::dvec3 up = to_dvec3(v.up);
        const glm::dmat4 view = glm::lookAt(eye, target, up);
        glm::dmat4 vp = glm::make_mat4(view_projection(v, w, h).data());  // (what picking projects with)
        if (jitter_px != glm::dvec2(0, 0))
            vp = glm::translate(glm::dmat4(1.0), glm::dvec3(2.0 * jitter_px.x / w, 2.0 * jitter_px.y / h, 0.0)) * vp;
        m.view_proj = glm::mat4(vp);
        m.inv_view_proj = glm::inverse(vp);
        m.right = glm::dvec3(view[0][0], view[1][0], view[2][0]);
        m.up = glm::dvec3(view[0][1], view[1][1], view[2][1]);
        m.back = glm::dvec3(view[0][2], view[1][2], view[2][2]);
        return m;
    }

    std::vector<Light> lights() const {
        if (!scene.lights.empty()) return scene.lights;
        // Three-point rig, camera space.
        Light key, fill, rim;
        key.direction = {-0.5, 0.55, 0.65}, key.intensity = 1.6, key.color = {1.0, 0.96, 0.9};
        fill.direction = {0.7, 0.1, 0.5}, fill.intensity = 0.35, fill.color = {0.85, 0.9, 1.0};
        rim.direction = {0.1, 0.6, -0.8}, rim.intensity = 1.0;
        return {key, fill, rim};
    }

    // The key light, whose shadows Scene::shadows draws: the first
    // directional light of the (at most 8) the programs light with, -1 if none.
    int key_light() const {
        const std::vector<Light> ls = lights();
        for (std::size_t i = 0; i < ls.size() && i < 8; ++i)
            if (ls[i].type != "point" && glm::length(to_dvec3(ls[i].direction)) > 1e-300) return int(i);
        return -1;
    }
    // Its direction towards the light in the world, for camera `m`.
    glm::dvec3 key_light_direction(const Matrices &m) const {
        const Light l = lights()[std::size_t(key_light())];
        glm::dvec3 d = to_dvec3(l.direction);
        if (l.camera_space) d = d.x * m.right + d.y * m.up + d.z * m.back;
        return glm::normalize(d);
    }

    void bind_lights(Program &p, const Matrices &m, const View &v, std::size_t max_lights) {
        std::vector<Light> ls = lights();
        if (ls.size() > max_lights) ls.resize(max_lights);
        std::vector<float> vec, rad;
        for (const Light &l : ls) {
            glm::dvec3 d = l.type == "point" ? to_dvec3(l.position) : to_dvec3(l.direction);
            if (l.camera_space) {
                d = d.x * m.right + d.y * m.up + d.z * m.back;
                if (l.type == "point") d += to_dvec3(v.eye);
            }
            // Directional: the unit vector the programs use as is (a zero
            // direction lights nothing).
            if (l.type != "point") d = glm::length(d) > 1e-300 ? glm::normalize(d) : glm::dvec3(0.0);
            vec.insert(vec.end(), {float(d.x), float(d.y), float(d.z), l.type == "point" ? 1.0f : 0.0f});
            rad.insert(rad.end(), {float(l.color[0] * l.intensity), float(l.color[1] * l.intensity), float(l.color[2] * l.intensity)});
        }
        if (ls.empty()) {
            vec = {0, 0, 1, 0};
            rad = {0, 0, 0};
        }
        {
            glUniform4fv(p.loc("hz_light_vec[0]"), GLsizei(vec.size() / 4), vec.data());
            glUniform3fv(p.loc("hz_light_radiance[0]"), GLsizei(rad.size() / 3), rad.data());
        }
    }

    void bind_environment(Program &p, bool on) {
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_CUBE_MAP, on && ibl->spec_cube ? ibl->spec_cube : ibl->black_cube);
        glActiveTexture(GL_TEXTURE1);
        glBindTexture(GL_TEXTURE_CUBE_MAP, on && ibl->diff_cube ? ibl->diff_cube : ibl->black_cube);
        glActiveTexture(GL_TEXTURE2);
        glBindTexture(GL_TEXTURE_2D, ibl->lut_tex);
        glActiveTexture(GL_TEXTURE3);
        glBindTexture(GL_TEXTURE_2D, behind.tex ? behind.tex : ibl->black_tex);
        glUniform1i(p.loc("hz_env_specular_map"), 0);
        glUniform1i(p.loc("hz_env_diffuse_map"), 1);
        glUniform1i(p.loc("hz_env_lut"), 2);
        glUniform1i(p.loc("hz_behind"), 3);
        glUniform1f(p.loc("hz_env_intensity"), on && ibl->on ? float(scene.environment.intensity) : 0.0f);
        glUniform1f(p.loc("hz_env_max_lod"), float(ImageLighting::spec_levels - 1));
        glUniformMatrix3fv(p.loc("hz_env_rotation"), 1, GL_FALSE, glm::value_ptr(ibl->rotation));
    }

    // Which of a tractogram's geometry draw_object draws: every chunk, the
    // level-of-detail proxy, or none (the program is bound and its uniforms
    // set for the caller to draw chunks itself).
    // (Volume: the fibre volume, drawn before the proxy's lines; see
    // volume_proxy.)
    enum class LinesPart { Full, Proxy, Volume, None };
    // The part of a tractogram drawn in this frame: its proxy while
    // interacting (when it has one), else all of it.
    LinesPart part_for(const GpuObject &g) const { return interacting && lod_proxy(g) ? LinesPart::Proxy : LinesPart::Full; }

    // The slab's two clip planes (hz_clip) of streamline program p; (0, 0, 0,
    // 1) each without a slab: never clipped.
    void set_slab_planes(Program &p) const {
        GLfloat planes[8] = {0, 0, 0, 1, 0, 0, 0, 1};
        if (scene.slab) {
            const Slab &sl = *scene.slab;
            planes[sl.axis] = 1, planes[3] = float(sl.half - sl.centre);       // x - (c - h) >= 0
            planes[4 + sl.axis] = -1, planes[7] = float(sl.half + sl.centre);  // (c + h) - x >= 0
        }
        glUniform4fv(p.loc("hz_clip"), 2, planes);
    }

    void draw_object(GpuObject &g, const Object &o, const Matrices &m, const View &v, bool debug, int w, int h,
                     LinesPart lines = LinesPart::Full) {
        if (g.slices) {
            if (debug || g.dvr) return;  // (a volume rendered: by the pass after the geometry, draw_volumes)
            set_clipping(false);
            Program *slice = &aux(Aux::Slices, display_direct);
            glUseProgram(slice->id);
            glUniform1f(slice->loc("hz_exposure"), float(scene.exposure));
            glUniformMatrix4fv(slice->loc("hz_view_proj"), 1, GL_FALSE, glm::value_ptr(m.view_proj));
            glUniformMatrix4fv(slice->loc("u_ras_to_tex"), 1, GL_FALSE, glm::value_ptr(g.ras_to_tex));
            glUniform2f(slice->loc("u_window"), float(g.window[0]), float(g.window[1]));
            glUniform1f(slice->loc("u_opacity"), float(o.opacity));
            glUniform1f(slice->loc("u_clip_below"), o.clip_below ? float(*o.clip_below) : -INFINITY);
            glUniform1i(slice->loc("u_rgb"), g.rgb ? 1 : 0);
            glUniform1i(slice->loc("u_labels"), g.labels ? 1 : 0);
            if (g.labels) {
                const LabelOptions &lo = o.labels->options;
                glUniform1f(slice->loc("u_fill"), float(lo.fill));
                glUniform1f(slice->loc("u_outline_px"), lo.outline ? 2.0f : 0.0f);
                glUniform3f(slice->loc("u_dims"), float(o.labels->dims[0]), float(o.labels->dims[1]), float(o.labels->dims[2]));
            }
            bind_sampler(*slice, "u_volume", 4, GL_TEXTURE_3D, g.volume_tex);
            bind_sampler(*slice, "u_colormap", 5, GL_TEXTURE_2D, g.colormap_tex);
            glBindVertexArray(g.vao);
            // Labels: blended over what is drawn (their areas are
            // translucent), in front of slices in the same planes.
            const GLboolean blending = glIsEnabled(GL_BLEND);
            if (g.labels) {
                glEnable(GL_BLEND);
                glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
                glEnable(GL_POLYGON_OFFSET_FILL);
                glPolygonOffset(-1.0f, -4.0f);
            }
            glDrawArrays(GL_TRIANGLES, 0, g.slice_vertices);
            if (g.labels) {
                glDisable(GL_POLYGON_OFFSET_FILL);
                if (!blending) glDisable(GL_BLEND);
            }
            stats.triangles_drawn += g.triangles;
            return;
        }
        // The slab's crossings stand for a tractogram's lines or tubes; its
        // fibre volume for its proxy.
        const bool points = g.geom != Geom::Mesh && crossing_mode();
        const bool volume = lines == LinesPart::Volume;
        const Output out = debug ? Output::Debug : peel_depth ? Output::Peel : display_direct ? Output::Display : Output::Hdr;
        Program &p = volume ? volume_program_for(g, out) : points ? point_program_for(g, out) : program_for(g, out);
        glUseProgram(p.id);
        glUniform1f(p.loc("hz_exposure"), float(scene.exposure));
        glUniformMatrix4fv(p.loc("hz_view_proj"), 1, GL_FALSE, glm::value_ptr(m.view_proj));
        glUniform3f(p.loc("hz_eye"), float(v.eye[0]), float(v.eye[1]), float(v.eye[2]));
        glUniform3f(p.loc("hz_tangent_hint"), 0.0f, 0.0f, 1.0f);
        glUniform1f(p.loc("hz_opacity"), float(o.opacity));
        glUniform2f(p.loc("hz_viewport"), float(w), float(h));
        // The slab crops streamlines (two clip planes); the state stays for
        // the object's chunks drawn after this call and is reset by the
        // next object and at the end of the frame.
        if (points) {
            const double px = std::max(1.0, scene.slab->point_px * (out_ == &lowres ? 1.0 / proxy_scale_now() : 1.0));
            glUniform1f(p.loc("hz_point_px"), float(px));
            glUniform1f(p.loc("hz_point_lift"), 0.5f);  // mm
        } else if (g.geom != Geom::Mesh) {
            set_slab_planes(p);
        }
        set_clipping(g.geom != Geom::Mesh && !points && !volume && scene.slab.has_value());
        {
            const glm::mat3 rot(glm::vec3(m.right.x, m.up.x, m.back.x), glm::vec3(m.right.y, m.up.y, m.back.y),
                                glm::vec3(m.right.z, m.up.z, m.back.z));
            glUniformMatrix3fv(p.loc("hz_view_rotation"), 1, GL_FALSE, glm::value_ptr(rot));
        }
        bind_lights(p, m, v, debug ? 1 : 8);
        bind_environment(p, !debug);
        set_material_uniforms(p, g);
        if (out == Output::Peel) bind_sampler(p, "hz_peel_depth", 9, GL_TEXTURE_2D, peel_depth);
        if (!debug && shadow_drawn) shadow_pass->bind(p, 10, ShadowParams{scene.shadows.strength, scene.shadows.softness_mm});
        if (volume) {
            g.tract->draw_fibre_volume(p, m.view_proj, m.inv_view_proj, v.fov_deg, frame_h, debug, w, h, empty_vao);
            return;
        }
        if (points) {
            if (lines == LinesPart::Full)
                g.tract->draw_crossings(0, g.tract->crossings().vaos.size());
            else if (lines == LinesPart::Proxy)
                g.tract->draw_crossings(0, g.tract->crossings().vaos.size(), crossing_budget());
            return;
        }
        glBindVertexArray(g.vao);
        if (g.geom == Geom::Mesh) {
            stats.triangles_drawn += draw_triangles(g);
        } else if (lines == LinesPart::Proxy) {
            // Over the fibre volume, the shell's lines are what a full frame
            // shows of the outermost streamlines, each covering 1/scale of
            // the proxy's pixel it crosses (it is a full-size pixel wide).
            const bool over = volume_proxy(g) && !debug;
            if (over) {
                glUniform1f(p.loc("hz_opacity"), float(o.opacity / proxy_scale_now()));
                blend_over();
            }
            const std::size_t n = drawn_proxy_chunks(g, over);
            for (std::size_t k = 0; k < n; ++k) g.tract->draw_proxy_chunk(k);
            if (over) glDisable(GL_BLEND);
        } else if (lines == LinesPart::Full) {
            g.tract->draw_full(std::size_t(&g - objects.data()), v, m.view_proj, w, h, settings.occlusion && !debug && !composited(g),
                               depth_scratch);
        }
    }

    static void ensure_fbo(Fbo &f, int w, int h, int samples, GLenum color_format) {
        if (f.fbo && (f.width != w || f.height != h || f.samples != samples)) f.destroy();
        if (f.fbo) return;
        f.width = w, f.height = h, f.samples = samples;
        glGenFramebuffers(1, &f.fbo);
        glBindFramebuffer(GL_FRAMEBUFFER, f.fbo);
        glGenRenderbuffers(1, &f.color);
        glBindRenderbuffer(GL_RENDERBUFFER, f.color);
        glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples > 1 ? samples : 0, color_format, w, h);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, f.color);
        glGenRenderbuffers(1, &f.depth);
        glBindRenderbuffer(GL_RENDERBUFFER, f.depth);
        glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples > 1 ? samples : 0, GL_DEPTH_COMPONENT24, w, h);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, f.depth);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE) return;
        if (samples > 1) {
            // Too large for multisampling (e.g. 16384x16384 x 4 samples):
            // the same picture without MSAA rather than none.
            spdlog::warn("{}x{} with {} samples does not fit: drawn without multisampling", w, h, samples);
            f.destroy();
            ensure_fbo(f, w, h, 1, color_format);
            f.samples = samples;  // (what was asked: no new attempt each frame)
            return;
        }
        throw Error("renderer: " + std::to_string(w) + "x" + std::to_string(h) + " does not fit in the GL driver's memory");
    }

    // Chooses the frame's output and makes its targets; returns the
    // framebuffer the scene is drawn into. The finished image is always
    // in `ldr` (RGBA8) after finish_frame().
    GLuint begin_frame(int w, int h) {
        const int samples = std::clamp(settings.samples, 1, std::max(1, max_samples));
        frame_samples = samples;
        display_direct = frame_is_direct() && !settings.hdr_output;
        peeled = false, volumes_peeled = false;
        hdr_frame_full = !display_direct && out_ == &ldr;
        out_->ensure(w, h, GL_RGBA8, GL_RGBA, GL_UNSIGNED_BYTE);
        if (!display_direct) {
            ensure_fbo(msaa, w, h, samples, GL_RGBA16F);
            resolved.ensure(w, h, GL_RGBA16F, GL_RGBA, GL_FLOAT);
            return msaa.fbo;
        }
        if (samples > 1) {
            ensure_fbo(msaa_display, w, h, samples, GL_RGBA8);
            return msaa_display.fbo;
        }
        out_->ensure_depth();
        return out_->fbo;
    }

    // GL_CLIP_DISTANCE0/1: on only while streamlines are drawn with a slab
    // (a program that does not write clip distances must not meet them).
    bool clipping = false;
    void set_clipping(bool on) {
        if (on == clipping) return;
        for (GLenum c : {GLenum(GL_CLIP_DISTANCE0), GLenum(GL_CLIP_DISTANCE1)}) on ? glEnable(c) : glDisable(c);
        clipping = on;
    }

    // Ends the geometry of a frame drawn into `target`: its picture into
    // out_ (resolved, tonemapped where it went through the HDR path). With
    // `complete` (the frame's geometry is all drawn, not a step of a
    // progressive frame), the passes that read the whole frame run first,
    // on linear radiance where there is some.
    void finish_frame(GLuint target, int w, int h, bool complete = false) {
        set_clipping(false);
        // (drawn into out_ directly only on the display path)
        if (target != out_->fbo && !peeled) {  // (with translucency, `resolved` holds the composite already)
            glBindFramebuffer(GL_READ_FRAMEBUFFER, target);
            glBindFramebuffer(GL_DRAW_FRAMEBUFFER, display_direct ? out_->fbo : resolved.fbo);
            glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
        }
        if (complete) after_geometry(display_direct ? out_->fbo : resolved.fbo, target, w, h, display_direct);
        if (!display_direct) tonemap_to(out_->fbo, w, h);
        if (complete) smooth_edges(w, h);
    }

    // What runs over a frame once its geometry is all drawn, on the picture
    // in `colour_fbo` (display values if `encoded`, else linear radiance)
    // with the depth of `depth_fbo`: the passes after the geometry, then the
    // volumes rendered (whose rays end at that depth).
    void after_geometry(GLuint colour_fbo, GLuint depth_fbo, int w, int h, bool encoded) {
        passes_after_geometry(colour_fbo, depth_fbo, w, h, encoded);
        draw_volumes(colour_fbo, depth_fbo, w, h, encoded);
    }

    // The edge pass over the finished picture in out_ (display values), for
    // a frame drawn without multisampling, unless it is one of a still's
    // jittered frames (their average is the anti-aliasing) or the frame's
    // linear picture is kept (hdr_output: the display picture stays its
    // tonemapped image).
    void smooth_edges(int w, int h) {
        if (!scene.antialiasing.on || frame_samples > 1 || accumulating || settings.hdr_output) return;
        if (settings.time_passes) glFinish();
        const auto t0 = Clock::now();
        edge_aa->apply(out_->fbo, w, h, empty_vao);
        stats.edge_aa = true;
        if (settings.time_passes) glFinish(), stats.aa_ms += ms_since(t0);
    }

    // The volumes rendered (Object::transfer) over the picture in
    // `colour_fbo` (display values if `encoded`, else linear radiance), each
    // ray ending at the depth of `depth_fbo`: after the passes that read the
    // opaque geometry's depth (ambient occlusion does not darken what lies
    // in front of what it darkens), in scene order. A moving (proxy) frame
    // marches with three times the step (its cheap form: about 1.5 voxels).
    bool volumes_peeled = false;  // the frame's volumes were marched between its translucent layers
    bool any_volume_rendered() const {
        return std::any_of(objects.begin(), objects.end(), [&](const GpuObject &g) { return g.dvr && drawn(g.index); });
    }
    // The ray-marching parameters of volume object g in a frame of camera m.
    VolumeRayParams volume_params(const GpuObject &g, const Matrices &m) const {
        VolumeRayParams p;
        p.inv_view_proj = glm::mat4(m.inv_view_proj);
        p.eye = glm::vec3(float(frame_view.eye[0]), float(frame_view.eye[1]), float(frame_view.eye[2]));
        p.ras_to_tex = g.ras_to_tex;
        p.window = glm::vec2(float(g.window[0]), float(g.window[1]));
        p.step_mm = float(g.step_mm * (out_ == &lowres ? 3.0 : 1.0));
        p.opacity = float(scene.objects[g.index].opacity);
        p.volume_tex = g.volume_tex, p.transfer_tex = g.colormap_tex;
        p.tone_curve = tone_curve(), p.exposure = float(scene.exposure);
        p.shade = scene.objects[g.index].transfer && scene.objects[g.index].transfer->shade;
        if (p.shade) {  // (the key light, else from the camera)
            const glm::dvec3 l = key_light() >= 0 ? key_light_direction(m) : m.back;
            p.to_light = glm::vec3(float(l.x), float(l.y), float(l.z));
        }
        return p;
    }
    void draw_volumes(GLuint colour_fbo, GLuint depth_fbo, int w, int h, bool encoded) {
        if (volumes_peeled || !any_volume_rendered()) return;
        if (settings.time_passes) glFinish();
        const auto t0 = Clock::now();
        frame_depth->resolve(depth_fbo, w, h);
        const Matrices m = matrices(frame_view, w, h);
        for (const GpuObject &g : objects) {
            if (!g.dvr || !drawn(g.index)) continue;
            volume_pass->apply(colour_fbo, *frame_depth, volume_params(g, m), empty_vao, encoded);
            ++stats.volumes_rendered;
        }
        opaque_state();
        if (settings.time_passes) glFinish(), stats.volume_ms += ms_since(t0);
    }
    // The volumes between two translucent layers (window depths `near`,
    // `far`), into the bound accumulation: DepthPeeling's `between`.
    void draw_volume_segments(GLuint near, GLuint far, const Matrices &m) {
        if (settings.time_passes) glFinish();
        const auto t0 = Clock::now();
        for (const GpuObject &g : objects)
            if (g.dvr && drawn(g.index)) volume_pass->apply_segment(near, far, volume_params(g, m), empty_vao);
        if (settings.time_passes) glFinish(), stats.volume_ms += ms_since(t0);
    }
    bool any_pass_after_geometry() const { return scene.ambient_occlusion.on || scene.depth_cue.on; }

    // The passes after the geometry over the picture in `colour_fbo`
    // (display values if `encoded`, else linear radiance), from the depth of
    // `depth_fbo`, resolved once for all of them: ambient occlusion (fewer
    // samples in a proxy frame, the moving picture's cheap form; the full
    // count in a still), then the depth cue (which fades what ambient
    // occlusion darkened, as distance does).
    void passes_after_geometry(GLuint colour_fbo, GLuint depth_fbo, int w, int h, bool encoded) {
        if (!any_pass_after_geometry()) return;
        if (scene.ambient_occlusion.on) ao_pass->prepare();  // (the programs compiled outside the timing)
        if (scene.depth_cue.on) cue_pass->prepare();
        // Timed only on request (a sync before and after: a GPU's pipeline
        // stalls; llvmpipe's GL_TIME_ELAPSED counts its command recording,
        // not its rasterisation, so a timer query would say 0.03 ms).
        if (settings.time_passes) glFinish();
        auto t0 = Clock::now();
        frame_depth->resolve(depth_fbo, w, h);
        if (scene.ambient_occlusion.on) {
            AoParams p;
            p.radius_mm = scene.ambient_occlusion.radius_mm;
            p.strength = scene.ambient_occlusion.strength;
            p.pairs = out_ == &lowres ? 6 : 16;
            p.fov_deg = frame_view.fov_deg, p.near_mm = frame_view.near_mm, p.far_mm = frame_view.far_mm;
            ao_pass->apply(colour_fbo, *frame_depth, p, empty_vao, encoded);
            if (settings.time_passes) glFinish(), stats.ao_ms += ms_since(t0), t0 = Clock::now();
        }
        if (scene.depth_cue.on) {
            DepthCueParams p;
            p.strength = scene.depth_cue.strength;
            p.near_mm = frame_view.near_mm, p.far_mm = frame_view.far_mm;
            std::tie(p.from_mm, p.to_mm) = scene_depth_range(frame_view);
            if (encoded) {
                p.background = background_value();
            } else {
                for (int k = 0; k < 3; ++k) p.background[std::size_t(k)] = float(scene.background[std::size_t(k)]);
            }
            cue_pass->apply(colour_fbo, *frame_depth, p, empty_vao);
            if (settings.time_passes) glFinish(), stats.depth_cue_ms += ms_since(t0);
        }
    }

    // The nearest and farthest depth of the visible objects' box from
    // camera `v` (along its view axis), the depth cue's range; the box kept
    // while what is shown stays the same (generation).
    Bounds cue_bounds;
    std::uint64_t cue_bounds_generation = ~std::uint64_t(0);
    std::pair<double, double> scene_depth_range(const View &v) {
        if (cue_bounds_generation != generation) cue_bounds = scene_bounds(scene), cue_bounds_generation = generation;
        if (cue_bounds.empty) return {v.near_mm, v.far_mm};
        const glm::dvec3 eye = to_dvec3(v.eye), ahead = glm::normalize(to_dvec3(v.target) - eye);
        double lo = INFINITY, hi = -INFINITY;
        for (int c = 0; c < 8; ++c) {
            const glm::dvec3 q((c & 1) ? cue_bounds.max[0] : cue_bounds.min[0], (c & 2) ? cue_bounds.max[1] : cue_bounds.min[1],
                               (c & 4) ? cue_bounds.max[2] : cue_bounds.min[2]);
            const double z = glm::dot(q - eye, ahead);
            lo = std::min(lo, z), hi = std::max(hi, z);
        }
        return {std::max(lo, v.near_mm), std::max(hi, v.near_mm + 1e-3)};
    }

    // The scene's background as the frame's output stores it.
    std::array<float, 3> background_value() const {
        std::array<float, 3> c{float(scene.background[0]), float(scene.background[1]), float(scene.background[2])};
        if (!display_direct) return c;
        for (float &x : c) {
            double v = std::max(0.0, double(x)) * scene.exposure;
            const int curve = tone_curve();
            if (curve == 0)
                v = (v * (2.51 * v + 0.03)) / (v * (2.43 * v + 0.59) + 0.14);
            else if (curve == 1)
                v = v / (1.0 + v);
            v = std::clamp(v, 0.0, 1.0);
            x = float(v <= 0.0031308 ? v * 12.92 : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055);
        }
        return c;
    }

    // Clears `target` to the background (and the environment, when shown)
    // and sets the state of the opaque pass.
    void clear_and_sky(const Matrices &m, GLuint target, int w, int h) {
        glBindFramebuffer(GL_FRAMEBUFFER, target);
        glViewport(0, 0, w, h);
        const auto bg = background_value();
        glClearColor(bg[0], bg[1], bg[2], 1.0f);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        if (ibl->on && scene.environment.visible) {
            glDisable(GL_DEPTH_TEST);
            Program *sky = &aux(Aux::Sky, display_direct);
            glUseProgram(sky->id);
            glUniform1f(sky->loc("hz_exposure"), float(scene.exposure));
            const glm::mat4 inv(m.inv_view_proj);
            glUniformMatrix4fv(sky->loc("u_inv_view_proj"), 1, GL_FALSE, glm::value_ptr(inv));
            glUniformMatrix3fv(sky->loc("u_rotation"), 1, GL_FALSE, glm::value_ptr(ibl->rotation));
            glUniform1f(sky->loc("u_intensity"), float(scene.environment.intensity));
            glActiveTexture(GL_TEXTURE0);
            glBindTexture(GL_TEXTURE_CUBE_MAP, ibl->env_cube);
            glUniform1i(sky->loc("u_env"), 0);
            glBindVertexArray(empty_vao);
            glDrawArrays(GL_TRIANGLES, 0, 3);
        }
        opaque_state();
    }

    static void opaque_state() {
        glEnable(GL_DEPTH_TEST);
        glDepthFunc(GL_LESS);
        glDepthMask(GL_TRUE);
        glDisable(GL_BLEND);
        glDisable(GL_CULL_FACE);
    }

    // How far the camera may turn from the last still for it to be drawn
    // again (Reprojection::usable): less when a tractogram's proxy is its
    // fibre volume, which alone is closer to the full frame sooner.
    double reprojection_turn_deg() const {
        for (const auto &g : objects)
            if (drawn(g.index) && volume_proxy(g)) return Reprojection::kMaxTurnOverVolumeDeg;
        return Reprojection::kMaxTurnDeg;
    }

    // g's fibre volume into the proxy frame's `target` (w x h): directly, or
    // ray-marched volume_downscale() times smaller into volres and drawn from
    // there (bilinear colour, each pixel at the nearest depth of the four
    // texels it reads), blended over what is drawn and depth-tested.
    void draw_volume_proxy(GpuObject &g, const Object &o, const Matrices &m, const View &v, GLuint target, int w, int h) {
        const int k = volume_downscale(g, m, w, h);
        if (k < 2) {
            draw_object(g, o, m, v, false, w, h, LinesPart::Volume);
            return;
        }
        const int vw = std::max(1, (w + k - 1) / k), vh = std::max(1, (h + k - 1) / k);
        volres.ensure(vw, vh, GL_RGBA16F, GL_RGBA, GL_FLOAT);
        volres.ensure_depth_texture();
        glBindFramebuffer(GL_FRAMEBUFFER, volres.fbo);
        glViewport(0, 0, vw, vh);
        glClearColor(0, 0, 0, 0);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        opaque_state();
        // (The same matrices: volres covers what the target does.)
        draw_object(g, o, m, v, false, vw, vh, LinesPart::Volume);
        if (!volume_upscale)
            volume_upscale = make_simple(glsl::kFullscreenVS, R"glsl(#version 410 core
in vec2 v_uv;
uniform sampler2D u_colour, u_depth;
out vec4 o;
void main() {
    vec2 uv = v_uv;
    vec4 c = texture(u_colour, uv);
    if (c.a < 1.0 / 255.0) discard;
    ivec2 sz = textureSize(u_depth, 0);
    vec2 q = uv * vec2(sz) - 0.5;
    ivec2 i0 = clamp(ivec2(floor(q)), ivec2(0), sz - 1), i1 = clamp(i0 + 1, ivec2(0), sz - 1);
    float d = min(min(texelFetch(u_depth, i0, 0).r, texelFetch(u_depth, ivec2(i1.x, i0.y), 0).r),
                  min(texelFetch(u_depth, ivec2(i0.x, i1.y), 0).r, texelFetch(u_depth, i1, 0).r));
    gl_FragDepth = d;
    o = c;
}
)glsl",
                                         "fibre volume upscale");
        glBindFramebuffer(GL_FRAMEBUFFER, target);
        glViewport(0, 0, w, h);
        opaque_state();
        glEnable(GL_BLEND);
        glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);  // premultiplied
        glUseProgram(volume_upscale->id);
        bind_sampler(*volume_upscale, "u_colour", 0, GL_TEXTURE_2D, volres.tex);
        bind_sampler(*volume_upscale, "u_depth", 1, GL_TEXTURE_2D, volres.depth_tex);
        glBindVertexArray(empty_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        opaque_state();
    }

    // The key light's shadow map for a frame from camera `m` (Scene::shadows),
    // kept while neither the light's direction, what is shown nor the
    // detail drawn changes: every opaque caster drawn into it, depth only;
    // tractograms as this frame draws them (their proxy while the camera
    // moves, into a map as much smaller as the proxy frame), and in full
    // over bricks nearest the light first, those hidden behind what is
    // drawn skipped (they change no depth of the map). The frame's counters
    // are the camera's: those of the map are not kept.
    // With `defer` (a progressive frame), the full detail of tractograms
    // with a level-of-detail proxy is not drawn but listed there, for the
    // steps to draw (shadow_step); the map is then complete once they have.
    bool shadow_drawn = false;
    struct ShadowKey {
        std::uint64_t generation = ~std::uint64_t(0);
        glm::dvec3 to_light{0.0};
        int size = 0;
        bool proxy = false;
        bool operator==(const ShadowKey &) const = default;
    } shadow_key, shadow_pending;
    // The map's size: a texel no finer than the frame's pixel at the
    // target (at most kShadowMapSize, or its share of a proxy frame), so that a line casts a shadow as wide as it is
    // drawn (a finer map drew 1M lines' shadows half as wide as the lines,
    // and at twice the cost: thin lines leave the map's tiles open, and
    // occlusion culling in the light's view then skips less); a multiple of
    // 256 texels, so that a small zoom keeps the map.
    static constexpr int kShadowMapSize = 2048;
    int shadow_map_size(double extent_mm, int frame_h, bool proxy) const {
        const int cap = proxy ? std::max(256, kShadowMapSize / proxy_scale_now()) : kShadowMapSize;
        const double dist = glm::length(to_dvec3(frame_view.eye) - to_dvec3(frame_view.target));
        const double px_mm = 2.0 * dist * std::tan(glm::radians(frame_view.fov_deg) / 2) / std::max(frame_h, 1);
        const double need = px_mm > 0 ? extent_mm / px_mm : double(cap);
        return std::clamp(int(std::ceil(std::min(need, double(cap)) / 256.0)) * 256, 256, cap);
    }
    void draw_shadow_map(const Matrices &m, int frame_h, std::vector<ChunkItem> *defer = nullptr) {
        shadow_drawn = false;
        stats.shadow_ms = 0, stats.shadow_map = 0, stats.shadow_texel_mm = 0;
        if (!scene.shadows.on || key_light() < 0) return;
        if (cue_bounds_generation != generation) cue_bounds = scene_bounds(scene), cue_bounds_generation = generation;
        if (cue_bounds.empty) return;
        const bool proxy = out_ == &lowres;
        const glm::dvec3 to_light = key_light_direction(m);
        const ShadowView sv = fit_shadow_view(to_light, cue_bounds);
        const ShadowKey key{generation, to_light, shadow_map_size(sv.extent_mm, frame_h, proxy), proxy};
        shadow_drawn = true;
        stats.shadow_map = key.size;
        stats.shadow_texel_mm = sv.extent_mm / key.size;
        if (key == shadow_key) return;
        shadow_key = ShadowKey{};
        if (settings.time_passes) glFinish();
        const auto t0 = Clock::now();
        const FrameStats keep = stats;
        const glm::mat4 vp(sv.view_proj);
        shadow_pass->begin(sv, key.size);
        for (auto &g : objects) {
            if (!casts_shadow(g)) continue;
            bind_caster(g);
            if (g.geom == Geom::Mesh) {
                draw_triangles(g);
            } else if (part_for(g) == LinesPart::Proxy) {
                const std::size_t n = drawn_proxy_chunks(g, false);
                for (std::size_t k = 0; k < n; ++k) g.tract->draw_proxy_chunk(k);
            } else if (defer && lod_proxy(g)) {
                const std::size_t oi = std::size_t(&g - objects.data());
                if (g.tract->over_bricks())
                    for (const ChunkItem &it : g.tract->brick_sequence(oi, shadow_light_view())) defer->push_back(it);
                else
                    for (std::size_t k = 0; k < g.tract->chunk_count(); ++k) defer->push_back({oi, k, SIZE_MAX});
            } else {
                g.tract->draw_full(std::size_t(&g - objects.data()), shadow_light_view(), vp, key.size, key.size, settings.occlusion,
                                   depth_scratch);
            }
        }
        set_clipping(false);
        shadow_pass->end();
        if (settings.time_passes) glFinish();
        stats = keep;
        stats.shadow_ms = settings.time_passes ? ms_since(t0) : 0.0;
        stats.shadow_map = key.size;
        stats.shadow_texel_mm = sv.extent_mm / key.size;
        if (defer && !defer->empty())
            shadow_pending = key, shadow_drawn = false;  // (the frame's objects wait for the rest)
        else
            shadow_key = key;
    }
    // Whether object g is drawn into the shadow map: opaque surfaces and
    // streamlines drawn as lines or tubes (not the slab's crossings).
    bool casts_shadow(const GpuObject &g) const {
        return !g.slices && drawn(g.index) && !composited(g) && !(g.geom != Geom::Mesh && crossing_mode());
    }
    // The light's camera: for ordering bricks nearest it first.
    View shadow_light_view() const {
        View lv = frame_view;
        const ShadowView &sv = shadow_pass->view();
        for (int k = 0; k < 3; ++k) lv.eye[std::size_t(k)] = sv.eye[k], lv.target[std::size_t(k)] = sv.target[k];
        return lv;
    }
    // Binds the caster program of g for the map being drawn.
    // Mesh g's triangles (its vertex array bound): its level of detail
    // (GpuObject::moving: ODF glyphs) while interacting. Returns how many.
    std::uint64_t draw_triangles(const GpuObject &g) const {
        if (interacting && g.moving.vao) {
            glBindVertexArray(g.moving.vao);
            glDrawElements(GL_TRIANGLES, g.moving.index_count, GL_UNSIGNED_INT, nullptr);
            return g.moving.triangles;
        }
        glDrawElements(GL_TRIANGLES, g.index_count, GL_UNSIGNED_INT, nullptr);
        return g.triangles;
    }

    void bind_caster(const GpuObject &g) {
        const ShadowView &sv = shadow_pass->view();
        Program &p = shadow_pass->caster(g.geom);
        glUseProgram(p.id);
        const glm::mat4 vp(sv.view_proj);
        glUniformMatrix4fv(p.loc("hz_view_proj"), 1, GL_FALSE, glm::value_ptr(vp));
        glUniform3f(p.loc("hz_eye"), float(sv.eye.x), float(sv.eye.y), float(sv.eye.z));
        if (g.geom != Geom::Mesh) set_slab_planes(p);
        set_clipping(g.geom != Geom::Mesh && scene.slab.has_value());
        glBindVertexArray(g.vao);
    }

    void draw_scene(const View &v, int w, int h) {
        const Matrices m = matrices(v, w, h);
        frame_view = v;
        draw_shadow_map(m, h);
        const GLuint target = begin_frame(w, h);
        clear_and_sky(m, target, w, h);
        // A proxy frame: the last complete still first, reprojected; the
        // proxy then fills what it did not see.
        if (out_ == &lowres && display_direct && settings.reproject &&
            warp->usable(generation, frame_w, frame_h, to_dvec3(v.eye), to_dvec3(v.target), reprojection_turn_deg())) {
            // (one point per block of the scale it was captured at)
            warp->draw(m.view_proj, to_dvec3(v.eye), 1.5 * warp->scale() / proxy_scale_now(), 2.0);
            stats.reprojected_points = warp->points();
            opaque_state();
        }
        // Pass 1: opaque. Pass 2: refractive objects, which composite the
        // opaque image behind them themselves. Pass 3: blended translucency.
        bool later = false;
        for (auto &g : objects) {
            const Object &o = scene.objects[g.index];
            if (!drawn(g.index) || g.labels) continue;
            if (composited(g)) {
                later = true;
                continue;
            }
            const LinesPart part = part_for(g);
            if (part == LinesPart::Proxy) g.tract->sync_proxy_scale(proxy_scale_now());
            if (part == LinesPart::Proxy && volume_proxy(g)) draw_volume_proxy(g, o, m, v, target, w, h);
            draw_object(g, o, m, v, false, w, h, part);
        }
        // Label slices after the rest of the opaque picture, which they
        // blend over (translucent ones with the translucent slices).
        for (auto &g : objects)
            if (g.labels && drawn(g.index) && !composited(g)) draw_object(g, scene.objects[g.index], m, v, false, w, h);
        if (later) {
            behind.ensure(w, h, GL_RGBA16F, GL_RGBA, GL_FLOAT);
            glBindFramebuffer(GL_READ_FRAMEBUFFER, msaa.fbo);
            glBindFramebuffer(GL_DRAW_FRAMEBUFFER, behind.fbo);
            glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
            glBindFramebuffer(GL_FRAMEBUFFER, msaa.fbo);
            for (auto &g : objects) {
                const Object &o = scene.objects[g.index];
                if (drawn(g.index) && g.refractive && o.opacity >= 1.0) draw_object(g, o, m, v, false, w, h, part_for(g));
            }
            // Translucent slices: blended in scene order over what is
            // drawn (behind every translucent surface and tractogram).
            glEnable(GL_BLEND);
            glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
            glDepthMask(GL_FALSE);
            for (auto &g : objects)
                if (g.slices && drawn(g.index) && scene.objects[g.index].opacity < 1.0)
                    draw_object(g, scene.objects[g.index], m, v, false, w, h, part_for(g));
            glDepthMask(GL_TRUE);
            glDisable(GL_BLEND);
            // Translucent surfaces and tractograms: in depth order, whatever
            // their order in the scene (depth peeling, over the opaque
            // picture resolved into `resolved`).
            const bool any = std::any_of(objects.begin(), objects.end(), [&](const GpuObject &g) {
                return !g.slices && drawn(g.index) && scene.objects[g.index].opacity < 1.0;
            });
            if (any) {
                // A layer costs a draw of every translucent object: above
                // kPeelPoints translucent streamline points, one pass in
                // drawing order instead (a translucent 1M-streamline
                // tractogram took 171 s for 9 layers on llvmpipe).
                std::uint64_t points = 0;
                for (const auto &g : objects)
                    if (g.tract && drawn(g.index) && scene.objects[g.index].opacity < 1.0) points += g.tract->points();
                const int most = points > kPeelPoints ? 0 : kMaxPeelLayers;
                glBindFramebuffer(GL_READ_FRAMEBUFFER, msaa.fbo);
                glBindFramebuffer(GL_DRAW_FRAMEBUFFER, resolved.fbo);
                glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_NEAREST);
                // Volumes rendered: marched between the layers, so that a
                // translucent object in front of one is in front of it.
                std::function<void(GLuint, GLuint)> between;
                if (any_volume_rendered()) between = [&](GLuint near, GLuint far) { draw_volume_segments(near, far, m); };
                peel_layers = peeling->composite(
                    msaa.fbo, resolved.fbo, w, h, most,
                    [&](GLuint previous) {
                        peel_depth = previous;
                        for (auto &g : objects) {
                            const Object &o = scene.objects[g.index];
                            if (!g.slices && drawn(g.index) && o.opacity < 1.0) draw_object(g, o, m, v, false, w, h, part_for(g));
                        }
                        peel_depth = 0;
                    },
                    empty_vao, between);
                peeled = true;
                if (between) {
                    volumes_peeled = true;
                    for (const GpuObject &g : objects) stats.volumes_rendered += g.dvr && drawn(g.index);
                }
                stats.transparency_layers = peel_layers;
                glBindFramebuffer(GL_FRAMEBUFFER, msaa.fbo);
                opaque_state();
            }
        }
        finish_frame(target, w, h, /*complete=*/true);
    }

    // Progressive drawing (the window at rest): the first step draws
    // everything small and the proxies of large tractograms; each later step
    // adds full-detail chunks over it, with depth testing, within a time
    // budget. A proxy's streamlines are drawn again at full detail with the
    // same geometry, so the finished image is the full frame's.
    struct Refine {
        bool active = false;
        View view;
        int w = 0, h = 0;
        GLuint target = 0;
        Matrices m;
        std::vector<ChunkItem> items;  // to draw, from `next` on
        std::size_t next = 0;
        int step = 0;
        Culling culling;
        // The shadow map's full detail still to draw (draw_shadow_map's
        // `defer`), before everything else: the frame's objects read it.
        std::vector<ChunkItem> shadow_items;
        std::size_t shadow_next = 0;
        Culling shadow_culling;
    } refine;

    // The window's still, jittered frames of it averaged at rest
    // (RenderSettings::rest_aa_frames): `done` of `frames` in `accumulation`.
    struct RestAa {
        bool active = false;
        View view;
        int w = 0, h = 0, frames = 0, done = 0;
    } rest_aa;

    // Jittered frame `i` (jitter_offset) of a still from camera v, drawn
    // without the edge pass (the frames' average is the anti-aliasing).
    void jittered_frame(const View &v, int w, int h, int i) {
        struct Reset {
            Impl &I;
            ~Reset() { I.jitter_px = {0, 0}, I.accumulating = false; }
        } reset{*this};
        accumulating = true;
        const std::array<double, 2> j = jitter_offset(i);
        jitter_px = {j[0], j[1]};
        frame(v, w, h);
    }

    void reset_counters() {
        stats.segments_drawn = stats.triangles_drawn = stats.points_drawn = stats.streamlines_drawn = 0;
        stats.chunks_drawn = stats.streamed_points = stats.crossings_drawn = stats.reprojected_points = stats.volumes_drawn = 0;
        stats.volume_rays = 0;
        stats.ao_ms = stats.depth_cue_ms = stats.shadow_ms = stats.volume_ms = stats.aa_ms = 0;
        stats.edge_aa = false;
        stats.aa_frames = 1;
        stats.volumes_rendered = 0;
        stats.transparency_layers = 0;
        stats.culled_chunks = stats.culled_points = stats.culled_streamlines = 0;
        stats.proxy = false;
        stats.refine_step = 0;
        stats.refine_remaining = 0;
    }

    // Whether a moving frame is drawn small and upscaled (proxy_frame): a
    // tractogram with a level-of-detail proxy, or a volume rendered (its
    // rays are the frame's cost: 0.7 s for 256^3 at 1280x720 on llvmpipe).
    bool moving_frame_small() const {
        return any_lod_proxy() || std::any_of(objects.begin(), objects.end(), [&](const GpuObject &g) { return g.dvr && drawn(g.index); });
    }

    bool any_lod_proxy() const {
        return std::any_of(objects.begin(), objects.end(), [&](const GpuObject &g) { return drawn(g.index) && lod_proxy(g); });
    }

    // A frame: at the window's size, or, when a tractogram drawn has a
    // level-of-detail proxy and the camera moves, the proxy frame (at
    // 1/proxy_scale of the size into lowres, upscaled into ldr).
    void frame(const View &v, int w, int h) {
        if (interacting && moving_frame_small())
            proxy_frame(v, w, h);
        else
            draw_scene(v, w, h);
    }

    // (upscaled into ldr, or with `to_window` straight into the window's
    // framebuffer 0: one full-size copy less per moving frame)
    void proxy_frame(const View &v, int w, int h, bool to_window = false) {
        frame_w = w, frame_h = h;
        const int s = proxy_scale_now();
        stats.proxy_level = level;
        const int pw = std::max(1, (w + s - 1) / s), ph = std::max(1, (h + s - 1) / s);
        lowres.ensure(pw, ph, GL_RGBA8, GL_RGBA, GL_UNSIGNED_BYTE);
        lowres.ensure_depth();
        const bool was = interacting;
        interacting = true;
        out_ = &lowres;
        try {
            draw_scene(v, pw, ph);
            stats.proxy = true;  // (drawn small: a proxy of the frame, whatever it drew)
        } catch (...) {
            out_ = &ldr, interacting = was;
            throw;
        }
        out_ = &ldr;
        interacting = was;
        if (!to_window) ldr.ensure(w, h, GL_RGBA8, GL_RGBA, GL_UNSIGNED_BYTE);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, lowres.fbo);
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, to_window ? 0 : ldr.fbo);
        glBlitFramebuffer(0, 0, pw, ph, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_LINEAR);
        if (to_window) glBindFramebuffer(GL_FRAMEBUFFER, 0);
    }

    // The window's picture while refining: the full-detail image drawn so
    // far over the upscaled proxy frame, by coverage (the refinement target
    // is cleared to alpha 0).
    void present_composite(int w, int h) {
        if (!composite)
            composite = make_simple(glsl::kFullscreenVS, R"glsl(#version 410 core
in vec2 v_uv;
uniform sampler2D u_full, u_proxy;
out vec4 o;
void main() {
    vec4 f = texture(u_full, v_uv);
    o = vec4(mix(texture(u_proxy, v_uv).rgb, f.rgb, f.a), 1.0);
}
)glsl",
                                    "refinement composite");
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        glViewport(0, 0, w, h);
        glDisable(GL_DEPTH_TEST);
        glDisable(GL_BLEND);
        glUseProgram(composite->id);
        bind_sampler(*composite, "u_full", 0, GL_TEXTURE_2D, ldr.tex);
        bind_sampler(*composite, "u_proxy", 1, GL_TEXTURE_2D, lowres.tex);
        glBindVertexArray(empty_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    }

    void begin_progressive(const View &v, int w, int h, bool at_once) {
        refine = Refine{};
        reset_counters();
        if (!any_lod_proxy() || !frame_is_direct()) {  // nothing to refine, or composited objects: one full frame
            draw_scene(v, w, h);
            return;
        }
        adopt_bricks(false);
        if (at_once && !bricks_pending()) {  // no proxy picture: every step now (the still, captured as by the steps)
            start_refinement(v, w, h);
            refine.active = true;
            progressive_step(1e9);
            return;
        }
        // The first picture: the proxy frame (lowres); then the full-detail
        // image, cleared to alpha 0, gets everything without a proxy now and
        // the tractograms' chunks step by step.
        proxy_frame(v, w, h);
        const FrameStats first = stats;
        start_refinement(v, w, h);
        stats.proxy = true;
        stats.points_drawn += first.points_drawn, stats.streamlines_drawn += first.streamlines_drawn;
        stats.segments_drawn += first.segments_drawn, stats.chunks_drawn += first.chunks_drawn;
        stats.crossings_drawn += first.crossings_drawn;
        stats.reprojected_points = first.reprojected_points;
        refine.active = !refine.items.empty() || !refine.shadow_items.empty();
        refine.step = 1;
        stats.refine_remaining = refine.items.size() + refine.shadow_items.size();
    }

    // The full-detail image of a progressive frame from camera v: cleared
    // (alpha 0 where the proxy frame shows through), everything without a
    // proxy drawn now, and the items the steps draw: the chunks of the
    // tractograms with one, over bricks nearest first.
    void start_refinement(const View &v, int w, int h) {
        refine.view = v, refine.w = w, refine.h = h;
        refine.m = matrices(v, w, h);
        frame_view = v;
        refine.items.clear(), refine.next = 0;
        refine.culling = Culling{};
        refine.shadow_items.clear(), refine.shadow_next = 0;
        refine.shadow_culling = Culling{};
        draw_shadow_map(refine.m, h, &refine.shadow_items);
        refine.shadow_culling.read = refine.shadow_culling.skip = settings.occlusion && settings.occlusion_skip;
        refine.target = begin_frame(w, h);
        clear_and_sky(refine.m, refine.target, w, h);
        glClearColor(0, 0, 0, 0);  // (alpha only: the background colour stays)
        glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_TRUE);
        if (!(ibl->on && scene.environment.visible)) glClear(GL_COLOR_BUFFER_BIT);
        glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
        if (refine.shadow_items.empty()) queue_refinement();
    }

    // The progressive frame's objects, once its shadow map is complete:
    // everything without a proxy drawn now, the chunks of the others listed
    // for the steps.
    void queue_refinement() {
        const View &v = refine.view;
        const int w = refine.w, h = refine.h;
        glBindFramebuffer(GL_FRAMEBUFFER, refine.target);
        glViewport(0, 0, w, h);
        opaque_state();
        for (auto &g : objects) {
            if (!drawn(g.index)) continue;
            const std::size_t oi = std::size_t(&g - objects.data());
            if (!lod_proxy(g))
                draw_object(g, scene.objects[g.index], refine.m, v, false, w, h, LinesPart::Full);
            else if (!crossing_mode() && g.tract->over_bricks())
                for (const ChunkItem &it : g.tract->brick_sequence(oi, v)) refine.items.push_back(it);
            else
                for (std::size_t k = 0, n = crossing_mode() ? g.tract->crossings().vaos.size() : g.tract->chunk_count(); k < n; ++k)
                    refine.items.push_back({oi, k, SIZE_MAX});
        }
        finish_frame(refine.target, w, h, /*complete=*/refine.items.empty());
        refine.culling.read = refine.culling.skip = settings.occlusion && settings.occlusion_skip && !crossing_mode();
    }

    // Draws the progressive frame's shadow map items (nearest the light
    // first, the hidden ones skipped) until `budget_ms` from t0 have passed
    // (at least one group); true once the map is complete.
    bool shadow_step(Clock::time_point t0, double budget_ms) {
        const FrameStats keep = stats;
        const auto ts = Clock::now();
        shadow_pass->resume();
        const glm::mat4 vp(shadow_pass->view().view_proj);
        const int size = shadow_pass->size();
        Culling &c = refine.shadow_culling;
        std::size_t bound = SIZE_MAX;
        std::vector<std::size_t> next;
        std::uint64_t group = 0;
        bool due = false;
        while (refine.shadow_next < refine.shadow_items.size()) {
            const ChunkItem it = refine.shadow_items[refine.shadow_next++];
            GpuObject &g = objects[it.object];
            if (c.hidden(*g.tract, it, vp)) {
                g.tract->cull_chunk(it.chunk);
                continue;
            }
            if (it.object != bound) bind_caster(g), bound = it.object;
            c.upcoming(*g.tract, refine.shadow_items, refine.shadow_next - 1, vp, next);
            g.tract->draw_chunk(it.chunk, &next);
            group += g.tract->chunk_points(it.chunk);
            due = c.drew(*g.tract, it) || due;
            if (group < TractogramDrawable::kBrickChunkPoints / 2 && refine.shadow_next < refine.shadow_items.size()) continue;
            glFinish();
            group = 0;
            if (due) c.refresh(depth_scratch, size, size), due = false;
            if (ms_since(t0) > budget_ms) break;
        }
        set_clipping(false);
        shadow_pass->end();
        stats = keep;
        stats.shadow_ms = settings.time_passes ? ms_since(ts) : 0.0;
        if (refine.shadow_next < refine.shadow_items.size()) return false;
        refine.shadow_items.clear(), refine.shadow_next = 0;
        shadow_key = shadow_pending, shadow_drawn = true;
        return true;
    }

    // One more step of the progressive frame, of about `budget_ms` (at
    // least one chunk); true once the frame is complete.
    bool progressive_step(double budget_ms) {
        if (!refine.active) return true;
        reset_counters();
        const auto t0 = Clock::now();
        // Objects still being cut into bricks are waited for, a step's time
        // at a time, before their first chunk (in bricks, the hidden ones
        // are skipped: the still completes far sooner).
        if (refine.next == 0 && bricks_pending()) {
            for (GpuObject &g : objects)
                if (g.tract) g.tract->wait_bricks(budget_ms / 2);
            if (!adopt_bricks(false) && bricks_pending()) {
                stats.refine_remaining = refine.items.size();
                return false;
            }
            start_refinement(refine.view, refine.w, refine.h);
        }
        if (!refine.shadow_items.empty()) {
            if (!shadow_step(t0, budget_ms)) {
                stats.refine_step = ++refine.step;
                stats.refine_remaining = refine.items.size() + refine.shadow_items.size() - refine.shadow_next;
                return false;
            }
            queue_refinement();
        }
        glBindFramebuffer(GL_FRAMEBUFFER, refine.target);
        glViewport(0, 0, refine.w, refine.h);
        opaque_state();
        std::size_t bound = SIZE_MAX;
        std::vector<std::size_t> next;
        Culling &c = refine.culling;
        // Timed (glFinish) in groups of at least half a brick's chunk:
        // bricks at the data's edges make many small ones.
        auto tg = Clock::now();
        std::uint64_t group = 0;
        bool due = false;  // (the depth, to be read back after the group)
        while (refine.next < refine.items.size()) {
            const ChunkItem it = refine.items[refine.next];
            GpuObject &g = objects[it.object];
            if (c.hidden(*g.tract, it, refine.m.view_proj)) {
                g.tract->cull_chunk(it.chunk);
                ++refine.next;
                continue;
            }
            if (it.object != bound) {
                draw_object(g, scene.objects[g.index], refine.m, refine.view, false, refine.w, refine.h, LinesPart::None);
                bound = it.object;
            }
            if (crossing_mode()) {
                g.tract->draw_crossings(it.chunk, it.chunk + 1);
                group += kChunkPoints;
            } else {
                c.upcoming(*g.tract, refine.items, refine.next, refine.m.view_proj, next);
                g.tract->draw_chunk(it.chunk, &next);
                group += g.tract->chunk_points(it.chunk);
                due = c.drew(*g.tract, it) || due;
            }
            ++refine.next;
            if (group < TractogramDrawable::kBrickChunkPoints / 2 && refine.next < refine.items.size()) continue;
            glFinish();
            group = 0;
            if (due) c.refresh(depth_scratch, refine.w, refine.h), due = false;
            // (the next group is taken to cost as much as this one)
            if (ms_since(t0) + ms_since(tg) > budget_ms) break;
            tg = Clock::now();
        }
        // The still is kept for the reprojection before the passes after the
        // geometry run over it: a proxy frame runs them again over all it
        // draws, the reprojected still included (ambient occlusion twice
        // darkened what the camera had seen at rest while it moved).
        const bool done = refine.next >= refine.items.size();
        const bool capture = done && settings.reproject && display_direct;
        finish_frame(refine.target, refine.w, refine.h, /*complete=*/done && !capture);
        stats.refine_step = ++refine.step;
        stats.refine_remaining = refine.items.size() - refine.next;
        if (done) {
            refine.active = false;
            if (settings.reproject) capture_still();
            if (capture) after_geometry(out_->fbo, refine.target, refine.w, refine.h, true), smooth_edges(refine.w, refine.h);
        }
        return !refine.active;
    }

    // Keeps the complete still (ldr, and the depth of the frame's target)
    // for the reprojection of the next proxy frames (in blocks of the base
    // level's scale, whatever the level: drawn larger or smaller at others).
    void capture_still() {
        if (!display_direct) return warp->clear();
        GLuint depth_fbo = refine.target;
        if (refine.target != ldr.fbo) {  // (multisampled: its depth resolved into ldr's)
            ldr.ensure_depth();
            glBindFramebuffer(GL_READ_FRAMEBUFFER, refine.target);
            glBindFramebuffer(GL_DRAW_FRAMEBUFFER, ldr.fbo);
            glBlitFramebuffer(0, 0, refine.w, refine.h, 0, 0, refine.w, refine.h, GL_DEPTH_BUFFER_BIT, GL_NEAREST);
            depth_fbo = ldr.fbo;
        }
        warp->capture(ldr.fbo, depth_fbo, refine.w, refine.h, refine.m.inv_view_proj, std::max(1, settings.proxy_scale), generation,
                      to_dvec3(refine.view.eye), to_dvec3(refine.view.target));
    }

    void tonemap_to(GLuint fbo, int w, int h) {
        glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        glViewport(0, 0, w, h);
        glDisable(GL_DEPTH_TEST);
        glDisable(GL_BLEND);
        Program *tonemap = &aux(Aux::Tonemap, false);
        glUseProgram(tonemap->id);
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_2D, resolved.tex);
        glUniform1i(tonemap->loc("u_hdr"), 0);
        glUniform1f(tonemap->loc("hz_exposure"), float(scene.exposure));
        glBindVertexArray(empty_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    }
};

// ================================================================ Renderer

Renderer::Renderer(const Registry &reg) : impl_(std::make_unique<Impl>(reg)) {}
Renderer::~Renderer() = default;

const Scene &Renderer::scene() const { return impl_->scene; }
const FrameStats &Renderer::stats() const { return impl_->stats; }

std::string Renderer::gl_description() const {
    const auto *ver = reinterpret_cast<const char *>(glGetString(GL_VERSION));
    const auto *ren = reinterpret_cast<const char *>(glGetString(GL_RENDERER));
    return std::string("OpenGL ") + (ver ? ver : "?") + ", " + (ren ? ren : "?");
}

void Renderer::set_scene(Scene scene, const View &view, const RenderSettings &settings) {
    Impl &I = *impl_;
    const auto t0 = Clock::now();
    I.refine.active = false;
    ++I.generation;
    I.clear_objects();
    I.scene = std::move(scene);
    I.settings = settings;
    if (settings.proxy_levels) {
        I.levels = render::proxy_levels(settings.proxy_scale, settings.lod_points);
        I.level = render::proxy_base_level(settings.proxy_scale, settings.lod_points);
    } else {
        I.levels = {ProxyLevel{std::clamp(settings.proxy_scale, 1, 16), std::max(1.0, settings.lod_points)}};
        I.level = 0;
    }
    I.ibl->on = I.scene.environment.type != "none";  // programs are specialised on it
    I.display_direct =
        std::none_of(I.scene.objects.begin(), I.scene.objects.end(), [&](const Object &o) { return o.visible && I.composited(o); });
    I.has_proxy.assign(I.scene.objects.size(), false);
    for (const auto &o : I.scene.objects)
        if (o.proxy_for && *o.proxy_for < I.has_proxy.size()) I.has_proxy[*o.proxy_for] = true;
    I.stats = FrameStats{};
    // Decimation tolerance: `lod_pixels` at the distance of the target.
    const double dist = glm::length(to_dvec3(view.eye) - to_dvec3(view.target));
    const double px_mm = 2.0 * dist * std::tan(glm::radians(view.fov_deg) / 2) / std::max(settings.height, 1);
    const double tol = settings.lod_pixels > 0 ? settings.lod_pixels * px_mm : 0.0;
    I.tol_mm = tol;
    for (std::size_t i = 0; i < I.scene.objects.size(); ++i) I.objects.push_back(I.upload(i));
    if (I.settings.samples <= 0) {
        std::uint64_t segments = 0;
        for (const auto &g : I.objects) segments += g.segments;
        I.settings.samples = segments > 200000 ? 1 : 4;
    }
    I.stats.samples = std::clamp(I.settings.samples, 1, std::max(1, I.max_samples));
    glFinish();
    I.schedule_crossings();
    I.stats.upload_ms = ms_since(t0);
    I.stats.environment_ms = I.ibl->build(I.reg, I.scene.environment);
}

void Renderer::set_material(std::size_t object, const Material &m) {
    Impl &I = *impl_;
    for (auto &g : I.objects)
        if (g.index == object && !g.slices) {
            I.resolve_material(g, I.scene.objects[object], m);
            I.scene.objects[object].material = m;
            ++I.generation;
            return;
        }
    throw Error("object " + std::to_string(object) + " has no material");
}

void Renderer::replace_object(std::size_t i, Object o) {
    Impl &I = *impl_;
    if (i >= I.scene.objects.size()) throw Error("no object " + std::to_string(i));
    if (o.kind != I.scene.objects[i].kind) throw Error(o.name + ": replace_object cannot change the kind of data");
    ++I.generation;
    I.refine.active = false;
    for (auto &g : I.objects)  // (its chunks' builds read the object's data)
        if (g.index == i) I.release(g);
    I.scene.objects[i] = std::move(o);
    for (auto &g : I.objects)
        if (g.index == i) {
            GpuObject fresh = I.upload(i);
            I.release(g);
            g = std::move(fresh);
            I.schedule_crossings();
            return;
        }
}

void Renderer::set_interacting(bool on) { impl_->interacting = on; }
void Renderer::set_proxy_level(int level) {
    Impl &I = *impl_;
    if (!I.levels.empty()) I.level = std::clamp(level, 0, int(I.levels.size()) - 1);
}
int Renderer::proxy_level() const { return impl_->level; }
int Renderer::proxy_level_count() const { return int(impl_->levels.size()); }
const std::vector<ProxyLevel> &Renderer::proxy_levels() const { return impl_->levels; }

std::vector<ProxyLevel> proxy_levels(int scale, double points) {
    const ProxyLevel base{std::clamp(scale, 1, 16), std::max(1.0, points)};
    std::vector<ProxyLevel> out;
    // Coarser: twice the scale (at most 16), then half the points.
    ProxyLevel l = base;
    for (int i = 0; i < 2; ++i) {
        if (i == 0 && l.scale * 2 <= 16)
            l.scale *= 2;
        else
            l.points /= 2;
        out.insert(out.begin(), l);
    }
    out.push_back(base);
    // Finer: half the scale (down to 1) and twice the points in turn, up
    // to 4 x the base's points.
    l = base;
    for (int i = 0;; ++i) {
        if (i % 2 == 0 && l.scale > 1)
            l.scale /= 2;
        else if (l.points * 2 <= 4 * base.points)
            l.points *= 2;
        else
            break;
        out.push_back(l);
    }
    return out;
}
int proxy_base_level(int, double) { return 2; }

bool Renderer::update_proxies(bool wait) {
    const bool crossings = impl_->adopt_crossings(wait);
    const bool volumes = impl_->adopt_fibre_volumes(wait);
    return impl_->adopt_shell_proxies(wait) || crossings || volumes;
}

bool Renderer::computing() const { return impl_->computing_crossings(); }

void Renderer::set_slab(std::optional<Slab> slab) {
    if (slab != impl_->scene.slab) ++impl_->generation;
    impl_->scene.slab = slab;
    impl_->schedule_crossings();
}

void Renderer::set_exposure(double e) {
    const double x = std::clamp(e, 1e-4, 1e4);
    if (x != impl_->scene.exposure) ++impl_->generation;
    impl_->scene.exposure = x;
}

void Renderer::set_ambient_occlusion(const AmbientOcclusion &ao) {
    check_ambient_occlusion(ao);
    AmbientOcclusion &now = impl_->scene.ambient_occlusion;
    if (ao.on != now.on || ao.radius_mm != now.radius_mm || ao.strength != now.strength) ++impl_->generation;
    now = ao;
}

void Renderer::set_depth_cue(const DepthCue &cue) {
    check_depth_cue(cue);
    DepthCue &now = impl_->scene.depth_cue;
    if (cue.on != now.on || cue.strength != now.strength) ++impl_->generation;
    now = cue;
}

void Renderer::set_shadows(const Shadows &sh) {
    check_shadows(sh);
    Impl &I = *impl_;
    Shadows &now = I.scene.shadows;
    if (sh.on != now.on || sh.strength != now.strength || sh.softness_mm != now.softness_mm) ++I.generation;
    if (sh.on != now.on)  // (the lit programs read the map or not: each object's are compiled again when next drawn)
        for (GpuObject &g : I.objects) {
            g.program = g.display_program = g.debug_program = g.peel_program = nullptr;
            std::fill(std::begin(g.point_programs), std::end(g.point_programs), nullptr);
            std::fill(std::begin(g.volume_programs), std::end(g.volume_programs), nullptr);
        }
    now = sh;
}

void Renderer::set_annotations(const Annotations &a) { impl_->scene.annotations = a; }

void Renderer::set_antialiasing(const Antialiasing &aa) {
    check_antialiasing(aa);
    Antialiasing &now = impl_->scene.antialiasing;
    if (aa.on != now.on || aa.frames != now.frames) ++impl_->generation;
    now = aa;
}

void Renderer::set_bake_materials(bool bake) {
    Impl &I = *impl_;
    if (I.settings.bake_materials == bake) return;
    I.settings.bake_materials = bake;
    spdlog::debug("renderer: {} material programs", bake ? "baked" : "uniform");
    // Each object picks up its program for the new form when next drawn
    // (compiled then, or found among the programs already built).
    for (GpuObject &g : I.objects) {
        g.program = g.display_program = g.debug_program = g.peel_program = nullptr;
        std::fill(std::begin(g.point_programs), std::end(g.point_programs), nullptr);
        std::fill(std::begin(g.volume_programs), std::end(g.volume_programs), nullptr);
    }
}

void Renderer::set_visible(std::size_t object, bool visible) {
    if (object < impl_->scene.objects.size() && impl_->scene.objects[object].visible != visible) {
        impl_->scene.objects[object].visible = visible;
        ++impl_->generation;
    }
}

void Renderer::set_opacity(std::size_t object, double opacity) {
    Impl &I = *impl_;
    if (object >= I.scene.objects.size()) throw Error("opacity: no object " + std::to_string(object));
    if (!(opacity >= 0.0 && opacity <= 1.0))
        throw Error("opacity: " + I.scene.objects[object].name + ": " + std::to_string(opacity) + " is not in [0, 1]");
    if (I.scene.objects[object].opacity != opacity) {
        I.scene.objects[object].opacity = opacity;
        ++I.generation;
    }
}

namespace {
GpuObject &volume_object(std::vector<GpuObject> &objects, const Scene &scene, std::size_t object, const char *what) {
    if (object >= scene.objects.size()) throw Error(std::string(what) + ": no object " + std::to_string(object));
    for (GpuObject &g : objects)
        if (g.index == object && g.slices) return g;
    throw Error(std::string(what) + ": " + scene.objects[object].name + " is not a volume");
}
}  // namespace

namespace {
// A glyph object's slice position along `axis`: NaN the middle of `box`;
// throws Error naming the object for one not finite or outside the box.
std::optional<double> slice_position(const std::string &name, const Bounds &box, int axis, std::optional<double> p) {
    if (p && std::isnan(*p)) p = (box.min[axis] + box.max[axis]) / 2;
    if (p && !std::isfinite(*p)) throw Error("slices: " + name + ": a position is not a finite number");
    if (p && (*p < box.min[axis] || *p > box.max[axis]))
        throw Error("slices: " + name + ": " + std::string(1, char('x' + axis)) + " = " + std::to_string(*p) +
                    " mm is outside the volume (" + std::to_string(box.min[axis]) + " to " + std::to_string(box.max[axis]) + ")");
    return p;
}
}  // namespace

void Renderer::set_slices(std::size_t object, std::optional<double> x, std::optional<double> y, std::optional<double> z) {
    Impl &I = *impl_;
    if (object < I.scene.objects.size() && glyph_grid(I.scene.objects[object])) {
        // ODF and tensor glyphs: those of the voxels on the new slices, built again.
        const Object &o = I.scene.objects[object];
        const Bounds box = *glyph_grid(o);
        const std::optional<double> p[3] = {slice_position(o.name, box, 0, x), slice_position(o.name, box, 1, y),
                                            slice_position(o.name, box, 2, z)};
        Mesh m = *glyph_mesh(o, p[0], p[1], p[2]);
        auto moving = moving_glyph_mesh(o, p[0], p[1], p[2]);
        for (auto &g : I.objects)  // (its upload reads the object's data: gone first)
            if (g.index == object) I.release(g);
        Object moved = std::move(I.scene.objects[object]);
        moved.slice_x = p[0], moved.slice_y = p[1], moved.slice_z = p[2];
        moved.data.mesh = std::move(m);
        moved.moving_mesh = std::move(moving);
        replace_object(object, std::move(moved));
        return;
    }
    if (object < I.scene.objects.size() && I.scene.objects[object].peaks) {
        // Peak glyphs: the segments of the voxels on the new slices, built
        // again (a slice of peaks is tens of thousands of segments: a few ms).
        const Object &o = I.scene.objects[object];
        const PeakField &f = *o.peaks;
        if (f.options.whole) throw Error("slices: " + o.name + " shows the peaks of the whole volume, not slices");
        const Bounds box = peak_grid_box(f);
        const std::optional<double> p[3] = {slice_position(o.name, box, 0, x), slice_position(o.name, box, 1, y),
                                            slice_position(o.name, box, 2, z)};
        Tractogram t = peak_lines(f, p[0], p[1], p[2]);
        for (auto &g : I.objects)  // (its drawable reads the object's data: gone first)
            if (g.index == object) I.release(g);
        Object moved = std::move(I.scene.objects[object]);  // (the same field, colouring and material; new segments)
        moved.slice_x = p[0], moved.slice_y = p[1], moved.slice_z = p[2];
        moved.data.bounds = peak_bounds(f, t);
        moved.data.tractogram = std::move(t);
        replace_object(object, std::move(moved));
        return;
    }
    GpuObject &g = volume_object(I.objects, I.scene, object, "slices");
    Object &o = I.scene.objects[object];
    if (o.transfer) throw Error("slices: " + o.name + " is rendered by ray-marching, not as slices");
    // (NaN: the middle of the volume along that axis, as a scene's default)
    std::optional<double> p[3] = {x, y, z};
    for (int a = 0; a < 3; ++a) {
        if (p[a] && std::isnan(*p[a])) p[a] = (g.bounds.min[a] + g.bounds.max[a]) / 2;
        if (p[a] && !std::isfinite(*p[a])) throw Error("slices: " + o.name + ": a position is not a finite number");
    }
    Object moved;  // (checked and built before anything changes)
    moved.name = o.name, moved.slice_x = p[0], moved.slice_y = p[1], moved.slice_z = p[2];
    upload_slice_quads(g, moved);
    o.slice_x = p[0], o.slice_y = p[1], o.slice_z = p[2];
    ++I.generation;
}

void Renderer::set_window(std::size_t object, double lo, double hi) {
    Impl &I = *impl_;
    GpuObject &g = volume_object(I.objects, I.scene, object, "window");
    if (g.labels) throw Error("window: " + I.scene.objects[object].name + " is a label volume: its colours are its labels'");
    if (!(std::isfinite(lo) && std::isfinite(hi) && hi > lo))
        throw Error("window: " + I.scene.objects[object].name + ": [" + std::to_string(lo) + ", " + std::to_string(hi) +
                    "] is not a range (finite, high > low)");
    g.window = {lo, hi};
    I.scene.objects[object].window = std::array<double, 2>{lo, hi};
    if (g.colour_scale) g.colour_scale->range = {lo, hi};
    ++I.generation;
}

void Renderer::set_volume_index(std::size_t object, std::uint64_t index) {
    Impl &I = *impl_;
    GpuObject &g = volume_object(I.objects, I.scene, object, "volume");
    Object &o = I.scene.objects[object];
    if ((g.rgb || g.labels) && index != 0)
        throw Error("volume: " + o.name + " is a " + (g.labels ? "label" : "colour") + " volume: it has no series to index");
    if (g.rgb || g.labels) return;
    const std::uint64_t before = o.volume_index;
    o.volume_index = index;
    std::vector<float> f;
    try {
        f = volume_values(o);
    } catch (...) {
        o.volume_index = before;
        throw;
    }
    const Volume &v = o.data.volume;
    glBindTexture(GL_TEXTURE_3D, g.volume_tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexSubImage3D(GL_TEXTURE_3D, 0, 0, 0, 0, GLsizei(v.dims[0]), GLsizei(v.dims[1]), GLsizei(v.dims[2]), GL_RED, GL_FLOAT, f.data());
    ++I.generation;
}

std::optional<Renderer::VolumeExtent> Renderer::volume_extent(std::size_t object) const {
    if (object < impl_->scene.objects.size())
        if (const auto box = glyph_grid(impl_->scene.objects[object])) return VolumeExtent{*box, 1, {0, 1}};
    if (object < impl_->scene.objects.size() && impl_->scene.objects[object].peaks) {
        const PeakField &f = *impl_->scene.objects[object].peaks;
        return VolumeExtent{peak_grid_box(f), 1, {0, f.max_amplitude > 0 ? f.max_amplitude : 1}};
    }
    for (const GpuObject &g : impl_->objects)
        if (g.index == object && g.slices) return VolumeExtent{g.bounds, volume_count(impl_->scene.objects[object].data.volume), g.window};
    return std::nullopt;
}

View Renderer::fit_view(const Camera &c, double aspect) const { return render::fit_view(impl_->scene, c, aspect); }

Bounds scene_bounds(const Scene &s) {
    Bounds b;
    auto add = [&](const Bounds &o) {
        if (o.empty) return;
        for (int k = 0; k < 3; ++k) {
            b.min[k] = b.empty ? o.min[k] : std::min(b.min[k], o.min[k]);
            b.max[k] = b.empty ? o.max[k] : std::max(b.max[k], o.max[k]);
        }
        b.empty = false;
    };
    for (const Object &o : s.objects) {
        if (!o.visible) continue;
        // (the bounds read_dataset computed while validating, when known: a
        // tractogram's positions are not scanned again)
        if (o.kind == HZ_DATA_STREAMLINES)
            add(!o.data.bounds.empty ? o.data.bounds : bounds_of(o.data.tractogram.positions.data(), o.data.tractogram.nb_stored()));
        else if (o.kind == HZ_DATA_MESH)  // (ODF and tensor glyphs: the grid's, whatever the slices show)
            add(glyph_grid(o) && !o.data.bounds.empty ? o.data.bounds : bounds_of(o.data.mesh.vertices.data(), o.data.mesh.nb_vertices()));
        else if (o.kind == HZ_DATA_VOLUME && o.data.volume.dims.size() >= 3) {
            const Volume &v = o.data.volume;
            float corners[24];
            for (int c = 0; c < 8; ++c) {
                const double ijk[3] = {(c & 1) ? v.dims[0] - 0.5 : -0.5, (c & 2) ? v.dims[1] - 0.5 : -0.5,
                                       (c & 4) ? v.dims[2] - 0.5 : -0.5};
                for (int r = 0; r < 3; ++r)
                    corners[c * 3 + r] = float(v.voxel_to_ras[r * 4] * ijk[0] + v.voxel_to_ras[r * 4 + 1] * ijk[1] +
                                               v.voxel_to_ras[r * 4 + 2] * ijk[2] + v.voxel_to_ras[r * 4 + 3]);
            }
            add(bounds_of(corners, 8));
        }
    }
    return b;
}

View fit_view(const Scene &scene, const Camera &c, double aspect) {
    const Bounds b = scene_bounds(scene);
    glm::dvec3 lo(-50), hi(50);
    if (!b.empty) lo = glm::dvec3(b.min[0], b.min[1], b.min[2]), hi = glm::dvec3(b.max[0], b.max[1], b.max[2]);
    const glm::dvec3 center = (lo + hi) * 0.5, half = glm::max((hi - lo) * 0.5, glm::dvec3(1e-3));
    View v;
    v.fov_deg = c.fov_deg;
    glm::dvec3 dir(-1, 0, 0), up(0, 0, 1);
    if (c.view == "right")
        dir = {1, 0, 0};
    else if (c.view == "anterior")
        dir = {0, 1, 0};
    else if (c.view == "posterior")
        dir = {0, -1, 0};
    else if (c.view == "superior")
        dir = {0, 0, 1}, up = {0, 1, 0};
    else if (c.view == "inferior")
        dir = {0, 0, -1}, up = {0, 1, 0};
    glm::dvec3 target = c.target ? to_dvec3(*c.target) : center;
    if (c.position) dir = glm::normalize(to_dvec3(*c.position) - target);
    if (c.position || c.target) up = to_dvec3(c.up);
    if (glm::length(glm::cross(dir, up)) < 1e-9) up = std::abs(up.z) > 0.5 ? glm::dvec3(0, 1, 0) : glm::dvec3(0, 0, 1);
    // Distance at which the box's extent across the view fits the frustum.
    const glm::dvec3 right = glm::normalize(glm::cross(-dir, up)), upv = glm::cross(right, -dir);
    const glm::dvec3 ah = glm::abs(half);
    const double hw = glm::dot(glm::abs(right), ah), hh = glm::dot(glm::abs(upv), ah), hd = glm::dot(glm::abs(dir), ah);
    const double ty = std::tan(glm::radians(c.fov_deg) / 2), tx = ty * aspect;
    const double dist = (std::max(hw / tx, hh / ty) * 1.08 + hd) / c.zoom;
    glm::dvec3 eye = c.position ? to_dvec3(*c.position) : target + dir * dist;
    v.eye = {eye.x, eye.y, eye.z};
    v.target = {target.x, target.y, target.z};
    v.up = {up.x, up.y, up.z};
    const double radius = glm::length(half);
    const double d = glm::length(eye - center);
    v.far_mm = d + radius * 2.0;
    v.near_mm = std::max(v.far_mm * 1e-4, d - radius * 2.0);
    return v;
}

void Renderer::render(const View &view, int width, int height) {
    Impl &I = *impl_;
    const auto t0 = Clock::now();
    I.rest_aa.active = false;
    I.adopt_crossings(true);  // (an offscreen frame shows the slab's crossings once computed)
    if (!I.interacting) I.adopt_bricks(true);
    I.refine.active = false;
    I.reset_counters();
    const int frames = I.scene.antialiasing.on && !I.interacting ? I.scene.antialiasing.frames : 1;
    if (frames <= 1) {
        I.frame(view, width, height);
    } else {
        // A still of jittered frames, averaged (the stats: the last frame's,
        // the passes' milliseconds summed).
        double ao = 0, cue = 0, vol = 0, shadow = 0;
        for (int i = 0; i < frames; ++i) {
            I.reset_counters();
            I.jittered_frame(view, width, height, i);
            const bool hdr = I.hdr_frame_full;
            if (i == 0) {
                I.accumulation->begin(width, height);
                if (hdr) I.accumulation_hdr->begin(width, height);
            }
            I.accumulation->add(I.ldr.tex, 1.0 / frames, I.empty_vao);
            if (hdr) I.accumulation_hdr->add(I.resolved.tex, 1.0 / frames, I.empty_vao);
            ao += I.stats.ao_ms, cue += I.stats.depth_cue_ms, vol += I.stats.volume_ms, shadow += I.stats.shadow_ms;
        }
        I.accumulation->resolve(I.ldr.fbo, I.empty_vao);
        if (I.hdr_frame_full) I.accumulation_hdr->resolve(I.resolved.fbo, I.empty_vao);
        I.stats.aa_frames = frames;
        I.stats.ao_ms = ao, I.stats.depth_cue_ms = cue, I.stats.volume_ms = vol, I.stats.shadow_ms = shadow;
    }
    glFinish();
    I.stats.draw_ms = ms_since(t0);
}

void Renderer::render_to_window(const View &view, int width, int height) {
    Impl &I = *impl_;
    const auto t0 = Clock::now();
    I.rest_aa.active = false;
    I.refine.active = false;
    I.reset_counters();
    if (I.interacting && I.moving_frame_small()) {
        I.proxy_frame(view, width, height, /*to_window=*/true);
    } else {
        I.frame(view, width, height);
        present(width, height);
    }
    I.stats.draw_ms = ms_since(t0);
}

void Renderer::begin_progressive(const View &view, int width, int height, bool at_once) {
    Impl &I = *impl_;
    const auto t0 = Clock::now();
    I.rest_aa.active = false;
    I.begin_progressive(view, width, height, at_once);
    glFinish();
    I.stats.draw_ms = ms_since(t0);
    // (a still complete at once, and cheap: its jittered frames follow. Cheap
    // by what was drawn, not by the clock: the same scene decides the same
    // way under any load, so the window's picture is reproducible.)
    const int frames = std::max(I.settings.rest_aa_frames, I.scene.antialiasing.frames);
    const bool cheap = I.stats.points_drawn + I.stats.triangles_drawn <= RenderSettings::kRestAaMaxPrimitives &&
                       std::uint64_t(width) * std::uint64_t(height) <= RenderSettings::kRestAaMaxPixels && I.stats.volumes_rendered == 0;
    if (!I.refine.active && !I.interacting && I.scene.antialiasing.on && I.settings.rest_aa_frames > 1 && cheap)
        I.rest_aa = {true, view, width, height, frames, 0};
}

bool Renderer::accumulating() const { return impl_->rest_aa.active; }

bool Renderer::accumulate_step() {
    Impl &I = *impl_;
    Impl::RestAa &a = I.rest_aa;
    if (!a.active) return true;
    const auto t0 = Clock::now();
    I.reset_counters();
    I.jittered_frame(a.view, a.w, a.h, a.done);
    if (a.done == 0) I.accumulation->begin(a.w, a.h);
    I.accumulation->add(I.ldr.tex, 1.0, I.empty_vao);
    ++a.done;
    I.accumulation->resolve(I.ldr.fbo, I.empty_vao, 1.0 / a.done);
    // (the average of a few frames is rougher than the edge pass's still)
    if (a.done < 4) I.smooth_edges(a.w, a.h);
    glFinish();
    I.stats.draw_ms = ms_since(t0);
    I.stats.aa_frames = a.done;
    a.active = a.done < a.frames;
    return !a.active;
}

bool Renderer::progressive_step(double budget_ms) {
    Impl &I = *impl_;
    const auto t0 = Clock::now();
    const bool done = I.progressive_step(budget_ms);
    I.stats.draw_ms = ms_since(t0);
    return done;
}

bool Renderer::refining() const { return impl_->refine.active; }

void Renderer::present(int width, int height) {
    Impl &I = *impl_;
    if (I.refine.active && I.lowres.fbo) {
        I.present_composite(width, height);
        return;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, I.ldr.fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

std::uint64_t Renderer::generation() const { return impl_->generation; }

std::vector<ColourScale> Renderer::colour_scales() const {
    std::vector<ColourScale> out;
    for (const auto &g : impl_->objects) {
        const Object &o = impl_->scene.objects[g.index];
        if (g.colour_scale && o.visible && !o.proxy_for) out.push_back(*g.colour_scale);
    }
    return out;
}

std::uint64_t Renderer::streamlines_with_proxy() const {
    std::uint64_t n = 0;
    for (const auto &g : impl_->objects)
        if (impl_->lod_proxy(g)) n += g.tract->streamlines();
    return n;
}

namespace {
// RGBA8 pixels of the bound read framebuffer, rows flipped to top-first.
Image read_pixels(int w, int h) {
    Image im;
    im.width = w, im.height = h;
    im.rgba.resize(std::size_t(w) * h * 4);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    std::vector<std::uint8_t> tmp(im.rgba.size());
    glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, tmp.data());
    const std::size_t row = std::size_t(w) * 4;
    for (int y = 0; y < h; ++y) std::memcpy(&im.rgba[y * row], &tmp[(h - 1 - y) * row], row);
    return im;
}
}  // namespace

Image Renderer::read_image() {
    Impl &I = *impl_;
    const auto t0 = Clock::now();
    glBindFramebuffer(GL_READ_FRAMEBUFFER, I.ldr.fbo);
    Image im = read_pixels(I.ldr.width, I.ldr.height);
    I.stats.readback_ms = ms_since(t0);
    return im;
}

FloatImage Renderer::read_hdr_image() {
    Impl &I = *impl_;
    if (!I.hdr_frame_full || I.resolved.width != I.ldr.width || I.resolved.height != I.ldr.height)
        throw Error("renderer: the last frame has no full-size HDR image (RenderSettings::hdr_output, not the proxy)");
    const auto t0 = Clock::now();
    FloatImage im;
    im.width = I.resolved.width, im.height = I.resolved.height;
    const std::size_t row = std::size_t(im.width) * 4;
    std::vector<float> flipped(row * std::size_t(im.height));
    glBindFramebuffer(GL_READ_FRAMEBUFFER, I.resolved.fbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, im.width, im.height, GL_RGBA, GL_FLOAT, flipped.data());
    im.rgba.resize(flipped.size());
    const float exposure = float(I.scene.exposure);
    for (int y = 0; y < im.height; ++y) {
        const float *src = flipped.data() + std::size_t(im.height - 1 - y) * row;
        float *dst = im.rgba.data() + std::size_t(y) * row;
        for (std::size_t x = 0; x < row; x += 4) {
            for (int k = 0; k < 3; ++k) dst[x + k] = std::isfinite(src[x + k]) ? std::max(0.0f, src[x + k]) * exposure : 0.0f;
            dst[x + 3] = 1.0f;
        }
    }
    I.stats.readback_ms = ms_since(t0);
    return im;
}

Image Renderer::read_window_image(int width, int height) {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    glReadBuffer(GL_BACK);
    return read_pixels(width, height);
}

std::array<FloatImage, 5> Renderer::render_debug(const View &view, int w, int h) {
    Impl &I = *impl_;
    for (auto &g : I.objects)
        if (!g.slices) I.program_for(g, Impl::Output::Debug);
    GLuint fbo = 0, depth = 0, tex[5] = {};
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glGenTextures(5, tex);
    for (int i = 0; i < 5; ++i) {
        glBindTexture(GL_TEXTURE_2D, tex[i]);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, w, h, 0, GL_RGBA, GL_FLOAT, nullptr);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + i, GL_TEXTURE_2D, tex[i], 0);
    }
    glGenRenderbuffers(1, &depth);
    glBindRenderbuffer(GL_RENDERBUFFER, depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, w, h);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    const GLenum bufs[5] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2, GL_COLOR_ATTACHMENT3, GL_COLOR_ATTACHMENT4};
    glDrawBuffers(5, bufs);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) throw Error("renderer: incomplete debug framebuffer");
    glViewport(0, 0, w, h);
    glClearColor(0, 0, 0, 0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    const Impl::Matrices m = I.matrices(view, w, h);
    for (auto &g : I.objects)
        if (!g.slices && I.scene.objects[g.index].visible) I.draw_object(g, I.scene.objects[g.index], m, view, true, w, h);
    std::array<FloatImage, 5> out;
    std::vector<float> tmp(std::size_t(w) * h * 4);
    for (int i = 0; i < 5; ++i) {
        glReadBuffer(GL_COLOR_ATTACHMENT0 + i);
        glReadPixels(0, 0, w, h, GL_RGBA, GL_FLOAT, tmp.data());
        out[i].width = w, out[i].height = h;
        out[i].rgba.resize(tmp.size());
        const std::size_t row = std::size_t(w) * 4;
        for (int y = 0; y < h; ++y) std::memcpy(&out[i].rgba[y * row], &tmp[(h - 1 - y) * row], row * 4);
    }
    glDeleteTextures(5, tex);
    glDeleteRenderbuffers(1, &depth);
    glDeleteFramebuffers(1, &fbo);
    return out;
}

std::string Renderer::program_source(std::size_t object) const {
    for (const auto &g : impl_->objects)
        if (g.index == object && !g.slices) {
            const Program *p = impl_->display_direct ? g.display_program : g.program;
            if (!p) p = g.display_program ? g.display_program : g.program;
            if (p) return p->fragment_source;
        }
    return {};
}

}  // namespace hz::core::render
