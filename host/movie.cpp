// `horizon movie`: a turntable of a scene rendered headless, frame by frame,
// into an MP4 (H.264) or WebM (VP9) through FFmpeg's libraries, or into an
// image sequence (a path with %d, as FRAMES/%04d.png). The paper's
// animations (section 4.1): the camera orbits the scene's target about its
// superior axis, from the scene's own view.
#include "annotations_paint.hpp"
#include "commands.hpp"
#include "progress.hpp"

#include <hz/core/io.hpp>
#include <hz/core/render/annotations.hpp>
#include <hz/core/render/renderer.hpp>

#include <nlohmann/json.hpp>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#ifdef HZ_HAVE_LIBAV
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}
#endif

namespace hz::host {

namespace fs = std::filesystem;
using core::Error;

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

#ifdef HZ_HAVE_LIBAV
std::string av_message(int err) {
    char buf[AV_ERROR_MAX_STRING_SIZE] = {};
    av_strerror(err, buf, sizeof buf);
    return buf;
}

// Frames (8-bit sRGB RGBA, rows top down) encoded into a video file at
// `path` (a temporary, published by the caller): H.264 in MP4 (libx264,
// CRF 18) or VP9 in WebM, yuv420p, BT.601 matrix, `fps` frames a second.
// Throws Error naming `shown` (the output the user asked for).
class VideoWriter {
public:
    VideoWriter(const fs::path &path, const std::string &shown, bool webm, int w, int h, int fps) : shown_(shown), w_(w), h_(h) {
        av_log_set_level(AV_LOG_ERROR);  // (the encoders' statistics are not the user's business)
        auto check = [&](int rc, const char *what) {
            if (rc < 0) throw Error(shown_ + ": " + what + ": " + av_message(rc));
        };
        check(avformat_alloc_output_context2(&oc_, nullptr, webm ? "webm" : "mp4", path.c_str()), "no such container");
        const AVCodec *codec = webm ? avcodec_find_encoder(AV_CODEC_ID_VP9) : avcodec_find_encoder_by_name("libx264");
        if (!codec && !webm) codec = avcodec_find_encoder(AV_CODEC_ID_H264);
        if (!codec) throw Error(shown_ + ": FFmpeg's libraries here have no " + (webm ? "VP9" : "H.264") + " encoder");
        st_ = avformat_new_stream(oc_, nullptr);
        c_ = avcodec_alloc_context3(codec);
        if (!st_ || !c_) throw Error(shown_ + ": out of memory");
        c_->width = w, c_->height = h;
        c_->time_base = AVRational{1, fps};
        c_->framerate = AVRational{fps, 1};
        c_->pix_fmt = AV_PIX_FMT_YUV420P;
        c_->gop_size = fps;
        c_->color_range = AVCOL_RANGE_MPEG;
        c_->colorspace = AVCOL_SPC_SMPTE170M;  // (swscale's default matrix: BT.601)
        c_->color_primaries = AVCOL_PRI_BT709;
        c_->color_trc = AVCOL_TRC_IEC61966_2_1;  // sRGB
        if (oc_->oformat->flags & AVFMT_GLOBALHEADER) c_->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
        if (!webm) {
            av_opt_set(c_->priv_data, "crf", "18", 0);
            av_opt_set(c_->priv_data, "preset", "medium", 0);
        } else {
            av_opt_set(c_->priv_data, "crf", "30", 0);
            c_->bit_rate = 0;
            av_opt_set(c_->priv_data, "deadline", "good", 0);
            av_opt_set(c_->priv_data, "cpu-used", "4", 0);
        }
        check(avcodec_open2(c_, codec, nullptr), "cannot open the encoder");
        check(avcodec_parameters_from_context(st_->codecpar, c_), "encoder parameters");
        st_->time_base = c_->time_base;
        check(avio_open(&oc_->pb, path.c_str(), AVIO_FLAG_WRITE), "cannot write");
        check(avformat_write_header(oc_, nullptr), "cannot write the header");
        frame_ = av_frame_alloc();
        pkt_ = av_packet_alloc();
        if (!frame_ || !pkt_) throw Error(shown_ + ": out of memory");
        frame_->format = c_->pix_fmt, frame_->width = w, frame_->height = h;
        check(av_frame_get_buffer(frame_, 0), "frame buffer");
        sws_ = sws_getContext(w, h, AV_PIX_FMT_RGBA, w, h, AV_PIX_FMT_YUV420P, SWS_BICUBIC, nullptr, nullptr, nullptr);
        if (!sws_) throw Error(shown_ + ": no RGBA to YUV conversion");
    }
    ~VideoWriter() {
        sws_freeContext(sws_);
        av_packet_free(&pkt_);
        av_frame_free(&frame_);
        avcodec_free_context(&c_);
        if (oc_) {
            if (oc_->pb) avio_closep(&oc_->pb);
            avformat_free_context(oc_);
        }
    }
    VideoWriter(const VideoWriter &) = delete;
    VideoWriter &operator=(const VideoWriter &) = delete;

    void add(const core::render::Image &im) {
        if (av_frame_make_writable(frame_) < 0) throw Error(shown_ + ": frame buffer");
        const std::uint8_t *src[1] = {im.rgba.data()};
        const int stride[1] = {4 * w_};
        sws_scale(sws_, src, stride, 0, h_, frame_->data, frame_->linesize);
        frame_->pts = next_++;
        encode(frame_);
    }
    void finish() {
        encode(nullptr);
        const int rc = av_write_trailer(oc_);
        if (rc < 0) throw Error(shown_ + ": cannot write the trailer: " + av_message(rc));
        if (avio_closep(&oc_->pb) < 0) throw Error(shown_ + ": write error");
    }

private:
    void encode(AVFrame *f) {
        int rc = avcodec_send_frame(c_, f);
        if (rc < 0) throw Error(shown_ + ": encoding: " + av_message(rc));
        while ((rc = avcodec_receive_packet(c_, pkt_)) == 0) {
            av_packet_rescale_ts(pkt_, c_->time_base, st_->time_base);
            pkt_->stream_index = st_->index;
            rc = av_interleaved_write_frame(oc_, pkt_);
            if (rc < 0) throw Error(shown_ + ": cannot write: " + av_message(rc));
        }
        if (rc != AVERROR(EAGAIN) && rc != AVERROR_EOF) throw Error(shown_ + ": encoding: " + av_message(rc));
    }
    std::string shown_;
    int w_, h_;
    AVFormatContext *oc_ = nullptr;
    AVStream *st_ = nullptr;
    AVCodecContext *c_ = nullptr;
    AVFrame *frame_ = nullptr;
    AVPacket *pkt_ = nullptr;
    SwsContext *sws_ = nullptr;
    std::int64_t next_ = 0;
};
#endif

// The camera of frame k: the scene's view turned by `degrees` * k / n about
// the superior axis (RAS z) through its target.
std::string frame_path(const std::string &pattern, int k) {
    char buf[4096];
    std::snprintf(buf, sizeof buf, pattern.c_str(), k);
    return buf;
}

}  // namespace

TimelinePlayer::TimelinePlayer(core::render::Renderer &r, const core::render::View &start, double aspect) : r_(r) {
    const core::render::Scene &s = r.scene();
    if (!s.timeline) throw Error("the scene has no timeline");
    start_ = core::render::timeline_start(
        s, start,
        [&](std::size_t i, int axis) {
            const auto ext = r.volume_extent(i);
            return ext ? (ext->box.min[axis] + ext->box.max[axis]) / 2 : 0.0;
        },
        [&](std::size_t i) -> std::optional<std::array<double, 2>> {
            const core::render::Object &o = s.objects[i];
            const auto ext = r.volume_extent(i);
            if (!ext || !core::render::shows_value_slices(o) || o.labels) return std::nullopt;
            return ext->window;
        });
    keys_ = core::render::keyframe_views(s, *s.timeline, aspect);
}

double TimelinePlayer::duration() const { return r_.scene().timeline->duration; }

core::render::View TimelinePlayer::at(double t) {
    const core::render::TimelineState st = core::render::timeline_at(*r_.scene().timeline, start_, keys_, t);
    for (std::size_t i = 0; i < st.objects.size(); ++i) {
        const core::render::ObjectState &now = st.objects[i];
        const core::render::Object &o = r_.scene().objects[i];
        if (now.visible != o.visible) r_.set_visible(i, now.visible);
        if (now.opacity != o.opacity) r_.set_opacity(i, now.opacity);
        if (now.window && (!o.window || *o.window != *now.window)) r_.set_window(i, (*now.window)[0], (*now.window)[1]);
        const std::optional<double> p[3] = {o.slice_x, o.slice_y, o.slice_z};
        bool moved = false;
        for (int a = 0; a < 3; ++a) {
            const auto &q = now.slices[std::size_t(a)];
            moved = moved || p[a].has_value() != q.has_value() || (p[a] && q && !(*p[a] == *q));
        }
        if (moved) r_.set_slices(i, now.slices[0], now.slices[1], now.slices[2]);
        bool changed = false;
        core::render::Material m = o.material;
        for (const auto &[name, v] : now.params) {
            auto it = m.params.find(name);
            if (it == m.params.end() || it->second != v) m.params[name] = v, changed = true;
        }
        if (changed) r_.set_material(i, m);
    }
    return st.view;
}

int cmd_movie(const GlobalOptions &g, const MovieOptions &o) {
    const core::Registry reg = load_registry(g);
    const auto [w, h] = parse_size(o.size);
    std::string ext = fs::path(o.out).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    const bool sequence = o.out.find('%') != std::string::npos;
    const bool webm = ext == ".webm";
    // What is wrong with the command itself: before any file is read.
    if (o.seconds && !(*o.seconds > 0 && *o.seconds <= 3600))
        throw core::Error("--seconds: between 0 and 3600, not " + std::to_string(*o.seconds));
    // (a timeline's duration is known once the scene is read: the frames'
    // names are checked again then)
    int n = int(std::lround(o.seconds.value_or(10) * o.fps));
    if (n < 1) throw core::Error("--seconds x --fps makes no frame");
    std::vector<std::string> outputs;
    if (sequence) {
        // (one %d conversion: %d, %4d, %04d)
        const std::size_t p = o.out.find('%');
        std::size_t q = p + 1;
        while (q < o.out.size() && std::isdigit(static_cast<unsigned char>(o.out[q]))) ++q;
        if (q >= o.out.size() || o.out[q] != 'd' || o.out.find('%', q) != std::string::npos)
            throw core::Error(o.out + ": an image sequence's name holds one %d (e.g. frames/%04d.png)");
        core::loader_for_write(reg, frame_path(o.out, 0), HZ_DATA_IMAGE);
        for (int k = 0; k < n; ++k) outputs.push_back(frame_path(o.out, k));
    } else {
        if (ext != ".mp4" && ext != ".webm")
            throw core::Error(o.out + ": a movie is .mp4 (H.264), .webm (VP9) or an image sequence (frames/%04d.png)");
#ifndef HZ_HAVE_LIBAV
        throw core::Error(o.out +
                          ": this horizon was built without FFmpeg's libraries (libavcodec-dev, libavformat-dev, libswscale-dev): "
                          "write an image sequence (frames/%04d.png) instead");
#endif
        if (w % 2 || h % 2) throw core::Error("--size " + o.size + ": a video's width and height are even (yuv420p)");
        outputs.push_back(o.out);
    }
    const fs::path folder = fs::path(outputs[0]).parent_path();
    if (!folder.empty() && !fs::is_directory(folder)) throw core::Error(outputs[0] + ": no such folder " + folder.string());
    check_outputs(outputs, o.inputs, o.force);
    const auto t0 = Clock::now();
    auto ctx = core::render::make_headless_context();
    core::render::Scene scene = scene_from_inputs(reg, o.inputs, o.view, "movie");
    o.passes.apply(scene);
    o.annotations.apply(scene);
    o.style.apply(scene);
    o.style.add_glass_brain(reg, scene);
    o.volumes.apply(scene);
    o.grid.apply(scene);
    const GridLayout grid = grid_layout(scene, w, h);
    const bool timeline = scene.timeline.has_value();
    if (timeline && !o.seconds) {
        n = int(std::lround(scene.timeline->duration * o.fps));
        if (n < 1) throw core::Error("the timeline's " + std::to_string(scene.timeline->duration) + " s at --fps makes no frame");
        if (sequence) {
            outputs.clear();
            for (int k = 0; k < n; ++k) outputs.push_back(frame_path(o.out, k));
            check_outputs(outputs, o.inputs, o.force);
        }
    }
    if (!scene.files.empty()) check_outputs(outputs, scene.files, o.force);
    const double degrees = o.degrees.value_or(timeline ? 0.0 : 360.0);
    bool animates_materials = false;
    if (timeline)
        for (const auto &k : scene.timeline->keyframes)
            for (const auto &[i, ok] : k.objects) animates_materials = animates_materials || !ok.params.empty();
    core::render::Renderer r(reg);
    core::render::RenderSettings rs;
    rs.width = grid.tile_w, rs.height = grid.tile_h;  // (each frame a tile: the level of detail of its pixels)
    o.lod.apply(rs);
    rs.shell_proxy = false;
    rs.shell_all_cores = true;
    rs.bake_materials = !animates_materials;  // (a program a value: not for values that change every frame)
    const core::render::View view = core::render::fit_view(scene, scene.camera, double(grid.tile_w) / grid.tile_h);
    const std::string scene_name = is_scene_file(o.inputs) ? o.inputs[0] : std::string();
    try {
        r.set_scene(std::move(scene), view, rs);
    } catch (const core::Error &e) {
        if (scene_name.empty()) throw;
        throw core::Error(scene_name + ": " + e.what());
    }
    std::optional<TimelinePlayer> player;
    if (timeline) player.emplace(r, view, double(grid.tile_w) / grid.tile_h);
    const double setup_ms = ms_since(t0);
#ifdef HZ_HAVE_LIBAV
    std::unique_ptr<core::TemporaryFile> tmp;
    std::unique_ptr<VideoWriter> video;
    if (!sequence) {
        core::remove_stale_temporaries(o.out);
        tmp = std::make_unique<core::TemporaryFile>(core::temporary_path(o.out));
        video = std::make_unique<VideoWriter>(tmp->path(), o.out, webm, w, h, o.fps);
    }
#endif
    std::vector<double> frame_ms;
    {
        Progress progress("rendering " + fs::path(o.out).filename().string(), !o.json);
        const hz_task *task = progress.task();
        for (int k = 0; k < n; ++k) {
            const auto tf = Clock::now();
            const double t = double(k) / o.fps;
            const core::render::View vk = core::render::turn_view(player ? player->at(t) : view, degrees * k / n);
            core::render::Image im = render_picture(r, grid, vk, w, h);
            if (r.scene().annotations.any())
                paint_marks(im, core::render::layout_annotations(r.scene().annotations, r.colour_scales(), vk, w, h));
            if (sequence) {
                write_image(reg, im, outputs[std::size_t(k)], o.force);
            } else {
#ifdef HZ_HAVE_LIBAV
                video->add(im);
#endif
            }
            frame_ms.push_back(ms_since(tf));
            task->report(task, double(k + 1) / n, nullptr);
            if (task->is_cancelled(task)) throw core::Error(o.out + ": cancelled");
        }
#ifdef HZ_HAVE_LIBAV
        if (video) {
            video->finish();
            video.reset();
            core::publish(*tmp, o.out, o.force);
        }
#endif
    }
    std::vector<double> sorted = frame_ms;
    std::sort(sorted.begin(), sorted.end());
    const double median = sorted[sorted.size() / 2];
    if (o.json) {
        std::cout << nlohmann::json{{"output", o.out},
                                    {"frames", n},
                                    {"fps", o.fps},
                                    {"width", w},
                                    {"height", h},
                                    {"degrees", degrees},
                                    {"timeline", timeline},
                                    {"setup_ms", setup_ms},
                                    {"frame_ms_median", median},
                                    {"frame_ms_max", sorted.back()},
                                    {"total_ms", ms_since(t0)}}
                         .dump(2)
                  << "\n";
    } else {
        std::printf(
            "Wrote %s: %d frames of %dx%d at %d fps (%.1f s, %s%.0f-degree turn) in %.1f s: %.0f ms a frame (median; slowest "
            "%.0f), %.1f s to load and set up\n",
            o.out.c_str(), n, w, h, o.fps, double(n) / o.fps, timeline ? "the scene's timeline and a " : "a ", degrees, ms_since(t0) / 1000,
            median, sorted.back(), setup_ms / 1000);
    }
    return 0;
}

}  // namespace hz::host
