// `horizon shader-check`: the GPU equals the CPU. Renders analytic scenes (a
// sphere, a plane seen at grazing angles, tubes and lines, including a
// degenerate streamline) with every shading plugin over parameter sweeps,
// through the same program assembly as `render`, and compares every covered
// pixel's GPU value with the plugin's CPU reference evaluated at exactly the
// GPU's shading inputs (n, l, v, t are extra float32 render targets).
//
// Tolerance, per pixel and channel: |gpu - cpu| <= max(rel * |cpu|, abs,
// 8 * sens), rel = 2e-3, abs = 1e-4 (sr^-1 or radiance factor), where sens
// is the largest change of the CPU value when n, l, v, t are perturbed by
// 2^-21 relative (what a float32 evaluation cannot avoid near sharp peaks).
// Any NaN, Inf or negative GPU value fails.
#include "commands.hpp"

#include <hz/core/render/context.hpp>
#include <hz/core/render/renderer.hpp>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <random>

namespace hz::host {

namespace {

using core::render::Vec3;

core::Tractogram curves() {
    // A helix (tube), a straight line along the view axis (degenerate
    // silhouette), and a streamline with repeated points (zero tangents).
    std::vector<float> p;
    std::vector<std::uint64_t> off = {0};
    for (int i = 0; i <= 120; ++i) {
        const double t = i / 120.0 * 4 * M_PI;
        p.insert(p.end(), {float(-28 + 4 * t), float(14 * std::cos(t)), float(14 * std::sin(t) - 5)});
    }
    off.push_back(p.size() / 3);
    for (int i = 0; i <= 40; ++i) p.insert(p.end(), {float(30 - i * 1.5), 25.0f, 25.0f});
    off.push_back(p.size() / 3);
    for (int i = 0; i <= 30; ++i) {
        const float x = float(-30 + 2 * (i / 2));  // pairs of identical points
        p.insert(p.end(), {x, -25.0f, 22.0f + 0.02f * x * x});
    }
    off.push_back(p.size() / 3);
    core::Tractogram t;
    t.positions = core::Buffer<float>(p.size());
    std::copy(p.begin(), p.end(), t.positions.begin());
    t.offsets = core::Buffer<std::uint64_t>(off.size());
    std::copy(off.begin(), off.end(), t.offsets.begin());
    return t;
}

struct SetResult {
    std::uint64_t pixels = 0, failures = 0, nonfinite = 0, negative = 0;
    double max_rel = 0, max_err_over_tol = 0;
};

}  // namespace

ShaderGpuResult check_shader_gpu(const core::Registry &reg, const core::LoadedPlugin *sp, const ShaderCheckOptions &o, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> U(0, 1);
    const int W = o.size, H = o.size;
    const hz_shader *sh = sp->shader();
    const bool surface = sh->domains & HZ_SHADE_SURFACE, line = sh->domains & HZ_SHADE_LINE;
    SetResult total;
    int sets = 0;
    for (int set = 0; set < o.sets; ++set) {
        // Parameters: defaults first, then random values with exact 0 / max
        // often enough to exercise the HZ_ZERO_ specialisation.
        core::render::Material mat;
        mat.shader = sp->info.id;
        std::array<double, 3> albedo{0.8, 0.8, 0.8};
        std::string albedo_name;
        for (uint32_t i = 0; i < sh->param_count; ++i) {
            const hz_param_info *pi = sh->get_param(i);
            if (pi->type == HZ_PARAM_COLOR3 && albedo_name.empty()) {
                albedo_name = pi->name;
                for (int c = 0; c < 3; ++c) albedo[c] = set == 0 ? pi->default_value[c] : std::round(U(rng) * 255.0) / 255.0;
                continue;
            }
            if (set == 0) continue;
            std::vector<double> v;
            for (uint32_t c = 0; c < pi->components && pi->type != HZ_PARAM_FLOAT_ARRAY; ++c) {
                const double lo = pi->min_value[c], hi = pi->max_value[c], u = U(rng);
                double x = (pi->flags & HZ_PARAM_FLAG_LOG_SCALE) && lo > 0 ? lo * std::pow(hi / lo, U(rng)) : lo + (hi - lo) * U(rng);
                if (u < 0.2)
                    x = lo;
                else if (u < 0.3)
                    x = hi;
                if (pi->type == HZ_PARAM_INT || pi->type == HZ_PARAM_ENUM || pi->type == HZ_PARAM_BOOL) x = std::round(x);
                v.push_back(x);
            }
            if (!v.empty()) mat.params[pi->name] = v;
        }
        for (int c = 0; c < 3; ++c) albedo[c] = std::round(albedo[c] * 255.0) / 255.0;

        // Values for the CPU: the schema defaults overridden like the renderer does.
        std::vector<double> values;
        for (uint32_t i = 0; i < sh->param_count; ++i) {
            const hz_param_info *pi = sh->get_param(i);
            auto it = mat.params.find(pi->name);
            for (uint32_t c = 0; c < pi->components; ++c) {
                double v = pi->type == HZ_PARAM_FLOAT_ARRAY ? (c < pi->default_array_count ? pi->default_array[c] : pi->default_value[0])
                                                            : pi->default_value[c];
                if (pi->name == albedo_name)
                    v = albedo[c];
                else if (it != mat.params.end() && c < it->second.size())
                    v = it->second[c];
                values.push_back(v);
            }
        }
        if (o.verbose) {
            std::fprintf(stderr, "  %s set %d values:", sp->info.id.c_str(), set);
            for (double x : values) std::fprintf(stderr, " %.9g", x);
            std::fprintf(stderr, "\n");
        }
        const double az = 2 * M_PI * U(rng), el = std::asin(2 * U(rng) - 1);
        const double cam_z = 12 + 20 * U(rng);  // low elevation: grazing on the plane
        SetResult res;
        for (int pass = 0; pass < 2; ++pass) {
            if (pass == 0 && !surface) continue;
            core::render::Scene scene;
            scene.environment.type = "none";
            auto add = [&](core::render::Object ob) {
                ob.material = mat;
                ob.coloring.mode = "solid";
                ob.coloring.color = albedo;
                scene.objects.push_back(std::move(ob));
            };
            if (pass == 0) {
                core::render::Object s;
                s.name = "sphere";
                s.kind = s.data.kind = HZ_DATA_MESH;
                s.data.mesh = core::render::make_sphere_mesh(20, 96, 48);
                add(std::move(s));
                core::render::Object pl;  // a plane seen almost edge-on
                pl.name = "plane";
                pl.kind = pl.data.kind = HZ_DATA_MESH;
                pl.data.mesh.vertices = core::Buffer<float>{-60, -45, -24, 60, -45, -24, 60, 45, -24, -60, 45, -24};
                pl.data.mesh.faces = core::Buffer<std::uint32_t>{0, 1, 2, 0, 2, 3};
                add(std::move(pl));
                core::render::Object tb;
                tb.name = "tubes";
                tb.kind = tb.data.kind = HZ_DATA_STREAMLINES;
                tb.data.tractogram = curves();
                tb.render = "tubes";
                tb.radius_mm = 2.5;
                add(std::move(tb));
            }
            if (pass == 1) {
                core::render::Object ln;
                ln.name = "lines";
                ln.kind = ln.data.kind = HZ_DATA_STREAMLINES;
                ln.data.tractogram = curves();
                for (std::size_t i = 0; i < ln.data.tractogram.positions.size(); i += 3) ln.data.tractogram.positions[i + 2] += 8.0f;
                ln.render = "lines";
                add(std::move(ln));
            }
            core::render::Light L;
            L.type = "directional";
            L.camera_space = false;
            L.direction = {std::cos(el) * std::cos(az) - 0.5, std::cos(el) * std::sin(az) - 0.6, std::sin(el) + 0.4};
            scene.lights = {L};
            scene.camera.position = Vec3{-25, -140, cam_z};
            scene.camera.target = Vec3{0, 0, 0};
            scene.camera.up = {0, 0, 1};
            scene.camera.fov_deg = 34;
            const core::render::View view = core::render::fit_view(scene, scene.camera, 1.0);
            core::render::Renderer r(reg);
            core::render::RenderSettings rs;
            rs.width = W, rs.height = H, rs.samples = 1, rs.lod_pixels = 0;
            rs.bake_materials = set % 2 == 1;  // both program forms: uniforms and baked constants
            r.set_scene(std::move(scene), view, rs);
            const auto out = r.render_debug(view, W, H);

            for (int y = 0; y < H; ++y)
                for (int x = 0; x < W; ++x) {
                    const std::size_t px = (std::size_t(y) * W + x) * 4;
                    if (out[0].rgba[px + 3] != 1.0f) continue;  // not covered
                    ++res.pixels;
                    const float *gv = &out[0].rgba[px];
                    hz_shade_point p{};
                    p.struct_size = sizeof p;
                    const float *n = &out[1].rgba[px], *l = &out[2].rgba[px], *v = &out[3].rgba[px], *t = &out[4].rgba[px];
                    // Which domain did the GPU use? Line objects with a LINE-capable model.
                    // Pass 1 draws only lines, shaded in the LINE domain when
                    // the model has one (else as surfaces, view-facing normal).
                    p.domain = pass == 1 && line ? HZ_SHADE_LINE : HZ_SHADE_SURFACE;
                    for (int k = 0; k < 3; ++k) p.n[k] = n[k], p.l[k] = l[k], p.v[k] = v[k], p.t[k] = t[k];
                    const float bx = n[1] * t[2] - n[2] * t[1], by = n[2] * t[0] - n[0] * t[2], bz = n[0] * t[1] - n[1] * t[0];
                    p.b[0] = bx, p.b[1] = by, p.b[2] = bz;
                    double ref[3];
                    if (sh->eval_reference(&p, values.data(), uint32_t(values.size()), ref) != HZ_OK) continue;
                    // Sensitivity to float32 rounding of the inputs.
                    double sens[3] = {0, 0, 0};
                    for (int trial = 0; trial < 6; ++trial) {
                        hz_shade_point q = p;
                        for (double *a : {q.n, q.l, q.v, q.t})
                            for (int k = 0; k < 3; ++k) a[k] *= 1.0 + (U(rng) * 2 - 1) * std::ldexp(1.0, -21);
                        double alt[3];
                        if (sh->eval_reference(&q, values.data(), uint32_t(values.size()), alt) == HZ_OK)
                            for (int k = 0; k < 3; ++k) sens[k] = std::max(sens[k], std::abs(alt[k] - ref[k]));
                    }
                    bool fail = false;
                    for (int k = 0; k < 3; ++k) {
                        if (!std::isfinite(gv[k])) {
                            ++res.nonfinite;
                            fail = true;
                            continue;
                        }
                        if (gv[k] < 0) ++res.negative, fail = true;
                        const double err = std::abs(double(gv[k]) - ref[k]);
                        const double tol = std::max({o.rel * std::abs(ref[k]), o.abs, 8 * sens[k]});
                        res.max_err_over_tol = std::max(res.max_err_over_tol, err / tol);
                        if (std::abs(ref[k]) > 1e-3) res.max_rel = std::max(res.max_rel, err / std::abs(ref[k]));
                        if (err > tol) fail = true;
                    }
                    if (fail) {
                        if (res.failures < 3 && o.verbose)
                            std::fprintf(stderr, "  %s set %d pixel (%d,%d): gpu [%g %g %g] cpu [%g %g %g] n.l %.3g n.v %.3g\n",
                                         sp->info.id.c_str(), set, x, y, gv[0], gv[1], gv[2], ref[0], ref[1], ref[2],
                                         n[0] * l[0] + n[1] * l[1] + n[2] * l[2], n[0] * v[0] + n[1] * v[1] + n[2] * v[2]);
                        ++res.failures;
                    }
                }
        }
        ++sets;
        total.pixels += res.pixels;
        total.failures += res.failures;
        total.nonfinite += res.nonfinite;
        total.negative += res.negative;
        total.max_rel = std::max(total.max_rel, res.max_rel);
        total.max_err_over_tol = std::max(total.max_err_over_tol, res.max_err_over_tol);
    }
    ShaderGpuResult r;
    r.sets = sets;
    r.pixels = total.pixels, r.failures = total.failures, r.nonfinite = total.nonfinite, r.negative = total.negative;
    r.max_rel = total.max_rel, r.max_err_over_tol = total.max_err_over_tol;
    r.ok = total.failures == 0 && total.pixels > 0;
    return r;
}

int cmd_shader_check(const GlobalOptions &g, const ShaderCheckOptions &o) {
    const core::Registry reg = load_registry(g);
    std::vector<const core::LoadedPlugin *> shaders;
    if (o.shader.empty())
        shaders = reg.of_kind(HZ_KIND_SHADER);
    else if (const auto *p = core::render::find_shader(reg, o.shader))
        shaders.push_back(p);
    else
        throw core::Error("no shading plugin '" + o.shader + "'");
    auto ctx = core::render::make_headless_context();
    nlohmann::json report = nlohmann::json::array();
    bool all_ok = true;
    if (!o.json)
        std::printf("%-40s %5s %9s %7s %7s %7s %10s %10s\n", "shader", "sets", "pixels", "fail", "nan", "neg", "max rel", "max e/tol");
    std::uint64_t seed = o.seed;
    for (const core::LoadedPlugin *sp : shaders) {
        const ShaderGpuResult t = check_shader_gpu(reg, sp, o, seed++);
        all_ok = all_ok && t.ok;
        if (o.json)
            report.push_back({{"shader", sp->info.id},
                              {"sets", t.sets},
                              {"pixels", t.pixels},
                              {"failures", t.failures},
                              {"nonfinite", t.nonfinite},
                              {"negative", t.negative},
                              {"max_rel", t.max_rel},
                              {"max_err_over_tol", t.max_err_over_tol},
                              {"ok", t.ok}});
        else
            std::printf("%-40s %5d %9llu %7llu %7llu %7llu %10.2e %10.3f %s\n", sp->info.id.c_str(), t.sets, (unsigned long long)t.pixels,
                        (unsigned long long)t.failures, (unsigned long long)t.nonfinite, (unsigned long long)t.negative, t.max_rel,
                        t.max_err_over_tol, t.ok ? "ok" : "FAIL");
    }
    if (o.json)
        std::cout << nlohmann::json{{"tolerance", {{"rel", o.rel}, {"abs", o.abs}, {"sens_factor", 8}}}, {"shaders", report}}.dump(2)
                  << "\n";
    return all_ok ? 0 : 1;
}

}  // namespace hz::host
