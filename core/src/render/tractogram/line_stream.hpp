// Streamline geometry on the GPU, every tractogram's together (private to
// the renderer): chunks of vertices built on other threads, kept in GL
// buffers of their own while the memory budget allows, else streamed
// through one ring buffer each time they are drawn.
//
// All calls on the thread that owns the GL context. The chunks a call names
// belong to a TractogramDrawable (drawable.hpp), which releases them here
// before it goes.
#pragma once

#include "../gl.hpp"
#include "line_geometry.hpp"

#include <hz/core/render/renderer.hpp>

#include <cstdint>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

namespace hz::core::render {

// Where a chunk's vertices come from: runs of points of `lines`' streamlines
// (`pieces` given: the proxy's pieces; `bricks` given: the bricks' pieces;
// neither: whole streamlines), decimated to `tol_mm`. `proxy`: the chunks
// are the level-of-detail proxy's (counted so in FrameStats).
struct LineSource {
    std::shared_ptr<LineData> lines;
    std::shared_ptr<const std::vector<Piece>> pieces;
    std::shared_ptr<const Bricks> bricks;
    double tol_mm = 0;
    bool proxy = false;
};

class LineStream {
public:
    // `settings.gpu_memory_mb` bounds the resident geometry (read at each
    // adoption); draws are counted into `stats`. Both outlive the stream.
    LineStream(const RenderSettings &settings, FrameStats &stats) : settings_(settings), stats_(stats) {}
    ~LineStream();
    LineStream(const LineStream &) = delete;
    LineStream &operator=(const LineStream &) = delete;

    // Builds every chunk of `cs` now (on every core) and keeps each within
    // the budget: a small object's full detail, a proxy.
    void build_all(const LineSource &s, std::vector<LineChunk> &cs);
    // Draws chunk k of `cs` with the bound program: from its GL buffer, or
    // built (or taken from its prefetch), kept when the budget allows, else
    // streamed. `next`: the chunks drawn after it, in order (else k + 1,
    // k + 2, ...), built ahead on other threads.
    void draw(const LineSource &s, std::vector<LineChunk> &cs, std::size_t k, const std::vector<std::size_t> *next = nullptr);
    // Chunk c is skipped (hidden): its prefetch, if any, is waited for and dropped.
    void skip(LineChunk &c);
    // Frees the GL buffers of `cs` (waiting for their builds) and empties it.
    void release(std::vector<LineChunk> &cs);

    // The vertex layout of LineVertex for the bound vertex array.
    static void vertex_attributes();

private:
    void adopt(LineChunk &c, BuiltLines &b);
    void prefetch(const LineSource &s, std::vector<LineChunk> &cs, std::size_t i, std::size_t ahead);
    std::shared_ptr<BuiltLines> take(const LineSource &s, LineChunk &c);
    std::shared_ptr<BuiltLines> spare_lines();
    void count(const LineChunk &c, bool proxy);
    std::uint64_t budget_bytes() const;

    const RenderSettings &settings_;
    FrameStats &stats_;
    std::uint64_t resident_bytes_ = 0;  // in GL buffers, all chunks together
    GLuint ring_vao_ = 0, ring_vbo_ = 0, ring_ebo_ = 0;
    // Chunks being built on other threads, by chunk.
    std::map<const LineChunk *, std::future<std::shared_ptr<BuiltLines>>> pending_;
    // Vertex buffers of built chunks are reused (a fresh 6 MB block for
    // every chunk would be faulted in, page by page, each time): a chunk's
    // BuiltLines goes back to the pool when its last user drops it.
    std::mutex spare_mutex_;
    std::vector<std::unique_ptr<BuiltLines>> spare_;
};

}  // namespace hz::core::render
