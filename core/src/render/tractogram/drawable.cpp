// One tractogram on the GPU (drawable.hpp).
#include "drawable.hpp"

#include "../gpu_object.hpp"
#include "../jobs.hpp"

#include <glm/gtc/type_ptr.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <random>
#include <thread>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace hz::core::render {

namespace {

// Points read into a fibre volume, at most (above, every k-th segment of
// every streamline: the density and colours are means over many).
constexpr double kFibrePoints = 64e6;
// The fibre volume's medium, as a fraction of the full frame's line width
// (calibrated on the scale benchmark: the volume's colours are means over
// everything in a voxel, and a thinner medium lets the layers behind the
// outermost show through as the full frame's gaps between lines do).
constexpr double kFibreWidth = 0.5;

// "Over" blending of display colours by their alpha (the volume's
// coverage), the target's alpha accumulated.
void blend_over() {
    glEnable(GL_BLEND);
    glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
}

}  // namespace

// ================================================================ Culling

bool Culling::hidden(const TractogramDrawable &t, const ChunkItem &it, const glm::mat4 &view_proj) const {
    return skip && it.brick != SIZE_MAX && t.brick_hidden(it.brick, tiles, view_proj);
}

bool Culling::drew(const TractogramDrawable &t, const ChunkItem &it) {
    if (!read || it.brick == SIZE_MAX) return false;
    since += t.chunk_points(it.chunk);
    return since >= t.cull_refresh_points();
}

void Culling::refresh(std::vector<float> &scratch, int w, int h) {
    since = 0;
    GLint fbo = 0, samples = 0;
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &fbo);
    glGetIntegerv(GL_SAMPLES, &samples);
    if (samples > 1) {
        read = skip = false;
        return;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, GLuint(fbo));
    scratch.resize(std::size_t(w) * h);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, scratch.data());
    tiles.build(scratch.data(), w, h);
}

void Culling::upcoming(const TractogramDrawable &t, const std::vector<ChunkItem> &items, std::size_t i, const glm::mat4 &view_proj,
                       std::vector<std::size_t> &next) const {
    const std::size_t ahead = cores();
    next.clear();
    for (std::size_t j = i + 1; j < items.size() && next.size() < ahead && items[j].object == items[i].object; ++j)
        if (!hidden(t, items[j], view_proj)) next.push_back(items[j].chunk);
}

// ===================================================== TractogramDrawable

TractogramDrawable::TractogramDrawable(const Context &ctx, const Object &o, std::size_t index, bool tubes, double tol_mm, int proxy_scale,
                                       double finest_points)
    : ctx_(ctx), index_(index), tubes_(tubes) {
    const RenderSettings &settings = ctx_.settings;
    const Tractogram &t = o.data.tractogram;
    const std::uint64_t N = t.nb_streamlines();
    lines_ = line_data(o);
    tol_mm_ = tol_mm;
    streamlines_ = N;
    points_total_ = t.nb_vertices();
    ctx_.stats.points_total += points_total_;
    chunks_ = partition(t, nullptr, N);
    bounds_ = !o.data.bounds.empty ? o.data.bounds : bounds_of(t.positions.data(), t.nb_stored());
    for (float r : lines_->radius) max_radius_mm_ = std::max(max_radius_mm_, r);
    if (settings.occlusion && points_total_ > settings.eager_points && !o.provisional) schedule_bricks(t);
    // The level-of-detail proxy: above `lod_points` input points, the
    // streamlines whose hash falls below lod_points / points (in
    // expectation a uniform subsample: the same density everywhere).
    const double lod = std::max(1.0, settings.lod_points);
    if (double(points_total_) > lod) {
        set_proxy_pieces(std::make_shared<const std::vector<Piece>>(uniform_proxy(t, lod)), proxy_scale);
        if (settings.shell_proxy && !o.provisional) {
            // (as many points as the finest level draws)
            const double most = std::max(lod, finest_points);
            shell_cancel_ = std::make_shared<std::atomic<bool>>(false);
            shell_ = std::async(std::launch::async, [t = t.shared(), b = bounds_, lod = most, cancel = shell_cancel_,
                                                     all = settings.shell_all_cores, index = index_] {
                return timed_job(index, "shell proxy", [&] { return shell_proxy(t, b, lod, *cancel, all); });
            });
        }
        if (!o.provisional) schedule_fibre_volume();
    }
    // Small objects are built now, in parallel (the draw lists are then
    // known: MSAA is chosen from the segment count); large ones chunk by
    // chunk as they are first drawn (a window shows the proxy first).
    if (points_total_ <= settings.eager_points) {
        ctx_.stream.build_all(source(false), chunks_);
        for (const LineChunk &c : chunks_) {
            segments_ += c.segments;
            ctx_.stats.points_kept += c.kept;
        }
    } else {
        segments_ = points_total_;  // (an upper bound until drawn)
    }
    if (has_lod_proxy()) ctx_.stream.build_all(source(true), proxy_chunks_);
}

TractogramDrawable::~TractogramDrawable() {
    // Background work stops first (its futures' ends are waited for: an
    // abandoned cut of 10M streamlines into bricks kept a replace_object
    // waiting 39 s).
    for (auto *c : {&brick_cancel_, &shell_cancel_, &crossing_cancel_, &fibre_cancel_})
        if (*c) **c = true;
    if (brick_job_.valid()) brick_job_.wait();
    if (shell_.valid()) shell_.wait();
    if (crossing_job_.valid()) crossing_job_.wait();
    if (fibre_job_.valid()) fibre_job_.wait();
    release_crossings(crossings_);
    ctx_.stream.release(chunks_);
    ctx_.stream.release(proxy_chunks_);
    if (fibre_tex_[0]) glDeleteTextures(3, fibre_tex_);
}

LineSource TractogramDrawable::source(bool proxy) const {
    LineSource s;
    s.lines = lines_;
    s.pieces = proxy ? proxy_ : nullptr;
    s.bricks = proxy ? nullptr : bricks_;
    s.tol_mm = proxy ? proxy_tol_mm_ : tol_mm_;
    s.proxy = proxy;
    return s;
}

// ------------------------------------------------------------ full detail

void TractogramDrawable::draw_chunk(std::size_t k, const std::vector<std::size_t> *next) {
    ctx_.stream.draw(source(false), chunks_, k, next);
}

void TractogramDrawable::cull_chunk(std::size_t k) {
    LineChunk &c = chunks_[k];
    ctx_.stream.skip(c);
    ++ctx_.stats.culled_chunks;
    ctx_.stats.culled_points += c.points;
    ctx_.stats.culled_streamlines += c.starts;
}

void TractogramDrawable::draw_full(std::size_t object, const View &v, const glm::mat4 &view_proj, int w, int h, bool cull,
                                   std::vector<float> &scratch) {
    if (!bricks_) {
        for (std::size_t k = 0; k < chunks_.size(); ++k) draw_chunk(k);
        return;
    }
    const auto items = brick_sequence(object, v);
    // (occlusion_skip off: the depth read back all the same, nothing
    // skipped: the check that skipping changes no pixel)
    Culling c;
    c.read = cull, c.skip = cull && ctx_.settings.occlusion_skip;
    std::vector<std::size_t> next;
    for (std::size_t i = 0; i < items.size(); ++i) {
        if (c.hidden(*this, items[i], view_proj)) {
            cull_chunk(items[i].chunk);
            continue;
        }
        c.upcoming(*this, items, i, view_proj, next);
        draw_chunk(items[i].chunk, &next);
        if (c.drew(*this, items[i])) c.refresh(scratch, w, h);
    }
}

// ----------------------------------------------------------------- bricks

// Starts cutting the streamlines into bricks on a background thread
// (RenderSettings::occlusion), at the finest grid whose pieces fit the
// budget (chosen on that thread too: a sample of the streamlines cut at
// each grid, 0.1-0.2 s at 1M); none: drawn in streamline order.
void TractogramDrawable::schedule_bricks(const Tractogram &t) {
    const RenderSettings &settings = ctx_.settings;
    const std::uint64_t max_pieces = std::uint64_t(std::max(0.0, settings.brick_memory_mb) * 1048576.0 / sizeof(BrickPiece));
    brick_cancel_ = std::make_shared<std::atomic<bool>>(false);
    brick_job_ = std::async(std::launch::async, [t = t.shared(), b = bounds_, cancel = brick_cancel_, window = !settings.shell_all_cores,
                                                 index = index_, grid = settings.brick_grid, max_pieces, mb = settings.brick_memory_mb] {
        // In a window below the frames' priority (its threads inherit it):
        // on two cores, frames moved while it ran took 33-40 ms instead of
        // 24-28; a window at rest waits for it, idle.
        if (window) setpriority(PRIO_PROCESS, id_t(syscall(SYS_gettid)), 10);
        const int side = brick_side_for(t, b, std::min(8, grid), grid, max_pieces);
        if (side == 0) {
            spdlog::debug("renderer: object {}: no bricks within {} MB, drawn in streamline order", index, mb);
            return Bricks{};
        }
        return timed_job(index, fmt::format("cut into bricks, {} along the longest side", side),
                         [&] { return bricks_of(t, b, side, cores(), *cancel); });
    });
}

void TractogramDrawable::wait_bricks(double ms) const {
    if (brick_job_.valid()) brick_job_.wait_for(std::chrono::duration<double, std::milli>(ms));
}

bool TractogramDrawable::adopt_bricks(bool wait) {
    if (!brick_job_.valid()) return false;
    if (!wait && brick_job_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
    auto br = std::make_shared<Bricks>(brick_job_.get());
    if (br->empty()) return false;
    use_bricks(std::move(br));
    return true;
}

void TractogramDrawable::use_bricks(std::shared_ptr<const Bricks> br) {
    ctx_.stream.release(chunks_);
    std::vector<LineChunk> chunks;
    std::vector<std::size_t> first(br->box.size() + 1, 0);
    for (std::size_t k = 0; k < br->box.size(); ++k) {
        first[k] = chunks.size();
        const std::uint64_t a = br->begin[k], n = br->begin[k + 1] - a;
        for (LineChunk &c : partition(br->pieces.data() + a, n, kBrickChunkPoints)) {
            c.a += a, c.b += a;
            c.starts = 0;
            for (std::uint64_t i = c.a; i < c.b; ++i) c.starts += br->pieces[i].first() == 0;
            chunks.push_back(std::move(c));
        }
    }
    first.back() = chunks.size();
    chunks_ = std::move(chunks);
    brick_chunks_ = std::move(first);
    bricks_ = std::move(br);
}

std::vector<ChunkItem> TractogramDrawable::brick_sequence(std::size_t object, const View &v) const {
    const glm::dvec3 eye(v.eye[0], v.eye[1], v.eye[2]);
    const glm::dvec3 ahead = glm::normalize(glm::dvec3(v.target[0], v.target[1], v.target[2]) - eye);
    std::vector<std::pair<double, std::size_t>> order;
    for (std::size_t b = 0; b < bricks_->box.size(); ++b) {
        const auto &x = bricks_->box[b];
        if (brick_chunks_[b] == brick_chunks_[b + 1]) continue;
        const glm::dvec3 centre(0.5 * (double(x[0]) + x[3]), 0.5 * (double(x[1]) + x[4]), 0.5 * (double(x[2]) + x[5]));
        order.emplace_back(glm::dot(centre - eye, ahead), b);
    }
    std::sort(order.begin(), order.end());
    std::vector<ChunkItem> seq;
    seq.reserve(chunks_.size());
    for (const auto &[d, b] : order)
        for (std::size_t k = brick_chunks_[b]; k < brick_chunks_[b + 1]; ++k) seq.push_back({object, k, b});
    return seq;
}

bool TractogramDrawable::brick_hidden(std::size_t b, const DepthTiles &tiles, const glm::mat4 &view_proj) const {
    // (a line's fragments lie within half a pixel of it, and their depth
    // is interpolated between its points: 1.5 px and 1 mm of slack)
    return !tiles.empty() && tiles.hidden(bricks_->box[b], max_radius_mm_ * tubes_ + 1.0f, view_proj, 1.5f);
}

// ------------------------------------------------------------------ proxy

// The proxy's lines: `pieces` (outermost first, or in hash order: any
// prefix is the shell or uniform subsample of a smaller budget), in chunks
// small enough that a level draws about its share of them.
void TractogramDrawable::set_proxy_pieces(std::shared_ptr<const std::vector<Piece>> pieces, int proxy_scale) {
    ctx_.stream.release(proxy_chunks_);
    proxy_ = std::move(pieces);
    proxy_tol_mm_ = tol_mm_ * proxy_scale;
    const std::uint64_t chunk = std::max<std::uint64_t>(1024, std::uint64_t(ctx_.settings.lod_points / 16));
    proxy_chunks_ = partition(*lines_->t, proxy_->data(), proxy_->size(), chunk);
}

void TractogramDrawable::sync_proxy_scale(int proxy_scale) {
    if (!proxy_ || proxy_tol_mm_ == tol_mm_ * proxy_scale) return;
    const auto t0 = Clock::now();
    set_proxy_pieces(proxy_, proxy_scale);
    ctx_.stream.build_all(source(true), proxy_chunks_);
    spdlog::debug("renderer: object {}: proxy decimated again for 1/{} of the size: {:.0f} ms", index_, proxy_scale, ms_since(t0));
}

std::size_t TractogramDrawable::proxy_chunks_for(double target) const {
    if (proxy_chunks_.empty()) return 0;
    std::size_t k = 1;
    for (double before = double(proxy_chunks_[0].points);
         k < proxy_chunks_.size() && before + 0.5 * double(proxy_chunks_[k].points) < target; ++k)
        before += double(proxy_chunks_[k].points);
    return k;
}

void TractogramDrawable::draw_proxy_chunk(std::size_t k) { ctx_.stream.draw(source(true), proxy_chunks_, k); }

bool TractogramDrawable::adopt_shell_proxy(bool wait, int proxy_scale) {
    if (!shell_.valid()) return false;
    if (!wait && shell_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
    std::vector<Piece> pieces = shell_.get();
    if (pieces.empty()) return false;
    set_proxy_pieces(std::make_shared<const std::vector<Piece>>(std::move(pieces)), proxy_scale);
    ctx_.stream.build_all(source(true), proxy_chunks_);
    return true;
}

// ----------------------------------------------------------- fibre volume

// Starts computing the fibre volume on a background thread
// (settings.fibre_volume; lines with a level-of-detail proxy).
void TractogramDrawable::schedule_fibre_volume() {
    const RenderSettings &settings = ctx_.settings;
    if (!settings.fibre_volume || !settings.shell_proxy || !has_lod_proxy() || !lines_ || tubes_) return;
    fibre_cancel_ = std::make_shared<std::atomic<bool>>(false);
    // (each thread sums into a grid of its own, 48 MB at 128 voxels: at most 4)
    const unsigned threads = settings.shell_all_cores ? std::clamp(std::thread::hardware_concurrency(), 1u, 4u) : 1u;
    fibre_job_ = std::async(
        std::launch::async, [d = lines_, b = bounds_, grid = settings.fibre_grid, cancel = fibre_cancel_, threads, index = index_] {
            // In a window (one thread) below the frames' priority: on two
            // cores it slowed the moving frames beside it from 25 to 42 ms;
            // the shell is the proxy until it is done.
            if (threads == 1) setpriority(PRIO_PROCESS, id_t(syscall(SYS_gettid)), 10);
            return timed_job(index, "fibre volume", [&] { return fibre_volume(*d, b, grid, kFibrePoints, threads, *cancel); });
        });
}

bool TractogramDrawable::adopt_fibre_volume(bool wait) {
    if (!fibre_job_.valid()) return false;
    if (!wait && fibre_job_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
    FibreVolume fv = fibre_job_.get();
    if (fv.empty()) return false;
    if (fibre_tex_[0]) glDeleteTextures(3, fibre_tex_);
    glGenTextures(3, fibre_tex_);
    // colour x density (linear), direction (linear), skip (fetched)
    const GLenum formats[3] = {GL_RGBA16F, GL_RGBA8, GL_R8};
    const GLenum layouts[3] = {GL_RGBA, GL_RGBA, GL_RED};
    const void *texels[3] = {fv.colour_density.data(), fv.direction.data(), fv.skip.data()};
    for (int k = 0; k < 3; ++k) {
        glBindTexture(GL_TEXTURE_3D, fibre_tex_[k]);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTexImage3D(GL_TEXTURE_3D, 0, GLint(formats[k]), fv.dim[0], fv.dim[1], fv.dim[2], 0, layouts[k],
                     k == 0 ? GL_FLOAT : GL_UNSIGNED_BYTE, texels[k]);
        const GLint filter = k == 2 ? GL_NEAREST : GL_LINEAR;
        glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MIN_FILTER, filter);
        glTexParameteri(GL_TEXTURE_3D, GL_TEXTURE_MAG_FILTER, filter);
        for (GLenum w : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R}) glTexParameteri(GL_TEXTURE_3D, w, GL_CLAMP_TO_EDGE);
    }
    glBindTexture(GL_TEXTURE_3D, 0);
    fibre_dim_ = fv.dim, fibre_origin_ = fv.origin, fibre_voxel_mm_ = fv.voxel_mm;
    return true;
}

NdcRect TractogramDrawable::fibre_box_ndc(const glm::mat4 &view_proj) const {
    NdcRect r;
    for (int c = 0; c < 8 && !r.all; ++c) {
        glm::dvec4 x(0, 0, 0, 1);
        for (int i = 0; i < 3; ++i) x[i] = fibre_origin_[i] + ((c >> i) & 1) * double(fibre_dim_[i]) * fibre_voxel_mm_;
        const glm::dvec4 q = glm::dmat4(view_proj) * x;
        if (!(q.w > 1e-6)) r.all = true;
        const glm::dvec2 n(q.x / q.w, q.y / q.w);
        r.lo = glm::min(r.lo, n), r.hi = glm::max(r.hi, n);
    }
    return r;
}

// (At 1280x800, a whole brain seen whole: 2; in a 640x400 window: 1, the
// proxy's own size.)
int TractogramDrawable::volume_downscale(const glm::mat4 &view_proj, int w, int h, int most) const {
    int k = std::max(1, most);
    const NdcRect r = fibre_box_ndc(view_proj);
    if (r.all) return k;
    const double span_px = std::max((r.hi.x - r.lo.x) * 0.5 * w, (r.hi.y - r.lo.y) * 0.5 * h);
    const double voxels = std::max({fibre_dim_[0], fibre_dim_[1], fibre_dim_[2]});
    while (k > 1 && span_px / k * 1.5 < voxels) --k;
    return k;
}

void TractogramDrawable::draw_fibre_volume(Program &p, const glm::mat4 &view_proj, const glm::dmat4 &inv_view_proj, double fov_deg,
                                           int full_h, bool debug, int w, int h, GLuint empty_vao) {
    glUniformMatrix4fv(p.loc("hz_inv_view_proj"), 1, GL_FALSE, glm::value_ptr(glm::mat4(inv_view_proj)));
    glUniform3f(p.loc("hz_vol_origin"), fibre_origin_[0], fibre_origin_[1], fibre_origin_[2]);
    glUniform3f(p.loc("hz_vol_dim"), float(fibre_dim_[0]), float(fibre_dim_[1]), float(fibre_dim_[2]));
    glUniform1f(p.loc("hz_vol_voxel"), fibre_voxel_mm_);
    const double frame_h = std::max(1, full_h);
    glUniform1f(p.loc("hz_px_angle"), float(kFibreWidth * 2.0 * std::tan(glm::radians(fov_deg) / 2) / frame_h));
    bind_sampler(p, "hz_vol_colour", 6, GL_TEXTURE_3D, fibre_tex_[0]);
    bind_sampler(p, "hz_vol_tangent", 7, GL_TEXTURE_3D, fibre_tex_[1]);
    bind_sampler(p, "hz_vol_skip", 8, GL_TEXTURE_3D, fibre_tex_[2]);
    if (!debug) blend_over();
    // Only the pixels the grid's box covers march.
    const auto [lo, hi, all] = fibre_box_ndc(view_proj);
    const int x0 = all ? 0 : std::clamp(int(std::floor((lo.x * 0.5 + 0.5) * w)) - 1, 0, w);
    const int x1 = all ? w : std::clamp(int(std::ceil((hi.x * 0.5 + 0.5) * w)) + 1, 0, w);
    const int y0 = all ? 0 : std::clamp(int(std::floor((lo.y * 0.5 + 0.5) * h)) - 1, 0, h);
    const int y1 = all ? h : std::clamp(int(std::ceil((hi.y * 0.5 + 0.5) * h)) + 1, 0, h);
    if (x1 > x0 && y1 > y0) {
        glEnable(GL_SCISSOR_TEST);
        glScissor(x0, y0, x1 - x0, y1 - y0);
        glBindVertexArray(empty_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glDisable(GL_SCISSOR_TEST);
        ctx_.stats.volume_rays += std::uint64_t(x1 - x0) * std::uint64_t(y1 - y0);
    }
    if (!debug) glDisable(GL_BLEND);
    ctx_.stats.proxy = true;
    ++ctx_.stats.volumes_drawn;
}

// --------------------------------------------------------- slab crossings

void TractogramDrawable::release_crossings(Crossings &c) {
    if (!c.vaos.empty()) glDeleteVertexArrays(GLsizei(c.vaos.size()), c.vaos.data());
    if (!c.vbos.empty()) glDeleteBuffers(GLsizei(c.vbos.size()), c.vbos.data());
    c = Crossings{};
}

void TractogramDrawable::draw_crossings(std::size_t k0, std::size_t k1, std::uint64_t limit) {
    const Crossings &c = crossings_;
    glEnable(GL_PROGRAM_POINT_SIZE);
    for (std::size_t k = k0; k < k1 && k < c.vaos.size() && limit > 0; ++k) {
        const GLsizei n = GLsizei(std::min<std::uint64_t>(std::uint64_t(c.counts[k]), limit));
        glBindVertexArray(c.vaos[k]);
        glDrawArrays(GL_POINTS, 0, n);
        ctx_.stats.crossings_drawn += std::uint64_t(n);
        limit -= std::uint64_t(n);
    }
    glDisable(GL_PROGRAM_POINT_SIZE);
}

void TractogramDrawable::schedule_crossings(int axis, double centre) {
    const auto same = [&](const Crossings &c) { return c.axis == axis && c.centre == centre && c.lines == lines_.get(); };
    if (same(crossings_) && !crossing_job_.valid()) return;
    if (crossing_job_.valid() && same(crossing_next_)) return;
    if (crossing_cancel_) *crossing_cancel_ = true;
    crossing_cancel_ = std::make_shared<std::atomic<bool>>(false);
    crossing_next_ = Crossings{};
    crossing_next_.axis = axis, crossing_next_.centre = centre, crossing_next_.lines = lines_.get();
    crossing_job_ = std::async(std::launch::async, [d = lines_, axis, centre, cancel = crossing_cancel_] {
        std::mutex m;
        std::vector<std::pair<std::uint64_t, std::vector<LineVertex>>> parts;
        parallel_ranges(d->t->nb_streamlines(), 4096, [&](std::uint64_t from, std::uint64_t to) {
            std::vector<LineVertex> mine;
            slab_crossings(*d, axis, centre, from, to, mine, cancel.get());
            std::lock_guard<std::mutex> lock(m);
            parts.emplace_back(from, std::move(mine));
        });
        std::vector<LineVertex> all;
        if (*cancel) return all;
        std::sort(parts.begin(), parts.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
        std::size_t total = 0;
        for (const auto &p : parts) total += p.second.size();
        all.reserve(total);
        for (const auto &p : parts) all.insert(all.end(), p.second.begin(), p.second.end());
        // (shuffled, the same way every time: the proxy is a prefix)
        std::mt19937_64 rng(0x5eed);
        std::shuffle(all.begin(), all.end(), rng);
        return all;
    });
}

bool TractogramDrawable::adopt_crossings(bool wait) {
    if (!crossing_job_.valid()) return false;
    if (!wait && crossing_job_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
    std::vector<LineVertex> v = crossing_job_.get();
    if (*crossing_cancel_) return false;
    release_crossings(crossings_);
    crossings_ = crossing_next_;
    for (std::size_t a = 0; a < v.size(); a += kCrossingChunk) {
        const std::size_t n = std::min<std::size_t>(kCrossingChunk, v.size() - a);
        GLuint vao = 0, vbo = 0;
        glGenVertexArrays(1, &vao);
        glBindVertexArray(vao);
        glGenBuffers(1, &vbo);
        glBindBuffer(GL_ARRAY_BUFFER, vbo);
        glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(n * sizeof(LineVertex)), v.data() + a, GL_STATIC_DRAW);
        LineStream::vertex_attributes();
        crossings_.vaos.push_back(vao), crossings_.vbos.push_back(vbo), crossings_.counts.push_back(GLsizei(n));
    }
    crossings_.total = v.size();
    return true;
}

}  // namespace hz::core::render
