// Streamline geometry on the GPU (line_stream.hpp).
#include "line_stream.hpp"

#include "../jobs.hpp"

#include <algorithm>
#include <thread>

namespace hz::core::render {

namespace {

void draw_strips(GLsizei nb_indices) {
    glEnable(GL_PRIMITIVE_RESTART);
    glPrimitiveRestartIndex(kRestart);
    glDrawElements(GL_LINE_STRIP, nb_indices, GL_UNSIGNED_INT, nullptr);
    glDisable(GL_PRIMITIVE_RESTART);
}

// The vertices of items [a, b) of `pieces`, or of `bricks`' pieces, or of
// the streamlines.
void build_chunk(const LineData &d, const std::vector<Piece> *pieces, const Bricks *bricks, std::uint64_t a, std::uint64_t b, double tol,
                 BuiltLines &out) {
    if (!bricks) {
        build_lines(d, pieces ? pieces->data() : nullptr, a, b, tol, out);
        return;
    }
    std::vector<Piece> p(b - a);  // (at most kBrickChunkPoints / 2 pieces)
    for (std::uint64_t i = a; i < b; ++i) p[i - a] = bricks->pieces[i].piece();
    build_lines(d, p.data(), 0, b - a, tol, out);
}

}  // namespace

LineStream::~LineStream() {
    for (auto &[c, f] : pending_) f.wait();
    pending_.clear();
    if (ring_vao_) glDeleteVertexArrays(1, &ring_vao_);
    if (ring_vbo_) glDeleteBuffers(1, &ring_vbo_);
    if (ring_ebo_) glDeleteBuffers(1, &ring_ebo_);
}

void LineStream::vertex_attributes() {
    const GLsizei st = sizeof(LineVertex);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, st, reinterpret_cast<void *>(0));
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, st, reinterpret_cast<void *>(12));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, st, reinterpret_cast<void *>(16));
    glEnableVertexAttribArray(3);
    glVertexAttribPointer(3, 1, GL_FLOAT, GL_FALSE, st, reinterpret_cast<void *>(20));
}

std::uint64_t LineStream::budget_bytes() const { return std::uint64_t(std::max(0.0, settings_.gpu_memory_mb)) << 20; }

// Records chunk c's draw lists from `b` and keeps its vertices in a GL
// buffer of its own while the budget allows.
void LineStream::adopt(LineChunk &c, BuiltLines &b) {
    c.firsts = std::move(b.firsts);
    c.counts = std::move(b.counts);
    c.segments = b.segments, c.kept = b.kept;
    c.built = true;
    const std::uint64_t vbytes = b.verts.size() * sizeof(LineVertex), ibytes = b.indices.size() * sizeof(std::uint32_t);
    const std::uint64_t bytes = vbytes + ibytes;
    if (resident_bytes_ + bytes > budget_bytes() || b.verts.empty()) return;
    glGenVertexArrays(1, &c.vao);
    glBindVertexArray(c.vao);
    glGenBuffers(1, &c.vbo);
    glBindBuffer(GL_ARRAY_BUFFER, c.vbo);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(vbytes), b.verts.data(), GL_STATIC_DRAW);
    vertex_attributes();
    glGenBuffers(1, &c.ebo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, c.ebo);  // (VAO state)
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(ibytes), b.indices.data(), GL_STATIC_DRAW);
    c.nb_indices = GLsizei(b.indices.size());
    c.bytes = bytes;
    resident_bytes_ += bytes;
}

void LineStream::release(std::vector<LineChunk> &cs) {
    for (LineChunk &c : cs) {
        if (auto it = pending_.find(&c); it != pending_.end()) {
            it->second.wait();
            pending_.erase(it);
        }
        if (c.vao) glDeleteVertexArrays(1, &c.vao);
        if (c.vbo) glDeleteBuffers(1, &c.vbo);
        if (c.ebo) glDeleteBuffers(1, &c.ebo);
        resident_bytes_ -= c.bytes;
        c.vao = c.vbo = c.ebo = 0, c.bytes = 0, c.nb_indices = 0;
    }
    cs.clear();
}

// Starts building chunks [i, i + ahead) of `cs` that are not resident on
// other threads (bounded: `ahead` chunks of at most kChunkPoints each).
void LineStream::prefetch(const LineSource &s, std::vector<LineChunk> &cs, std::size_t i, std::size_t ahead) {
    for (std::size_t k = i; k < cs.size() && k < i + ahead; ++k) {
        LineChunk &c = cs[k];
        if (c.vbo || pending_.count(&c)) continue;
        pending_.emplace(&c, std::async(std::launch::async, [this, s, a = c.a, b = c.b] {
            auto out = spare_lines();
            build_chunk(*s.lines, s.pieces.get(), s.bricks.get(), a, b, s.tol_mm, *out);
            return out;
        }));
    }
}

// Chunk c's vertices: from its prefetch, or built now.
std::shared_ptr<BuiltLines> LineStream::take(const LineSource &s, LineChunk &c) {
    if (auto it = pending_.find(&c); it != pending_.end()) {
        auto b = it->second.get();
        pending_.erase(it);
        return b;
    }
    auto b = spare_lines();
    build_chunk(*s.lines, s.pieces.get(), s.bricks.get(), c.a, c.b, s.tol_mm, *b);
    return b;
}

std::shared_ptr<BuiltLines> LineStream::spare_lines() {
    std::unique_ptr<BuiltLines> b;
    {
        std::lock_guard<std::mutex> lock(spare_mutex_);
        if (!spare_.empty()) b = std::move(spare_.back()), spare_.pop_back();
    }
    if (!b) b = std::make_unique<BuiltLines>();
    return std::shared_ptr<BuiltLines>(b.release(), [this](BuiltLines *p) {
        std::lock_guard<std::mutex> lock(spare_mutex_);
        if (spare_.size() < 8)
            spare_.emplace_back(p);
        else
            delete p;
    });
}

void LineStream::build_all(const LineSource &s, std::vector<LineChunk> &cs) {
    for (std::size_t k = 0; k < cs.size(); ++k) {
        prefetch(s, cs, k, cores());
        auto b = take(s, cs[k]);
        adopt(cs[k], *b);
    }
}

void LineStream::draw(const LineSource &s, std::vector<LineChunk> &cs, std::size_t k, const std::vector<std::size_t> *next) {
    LineChunk &c = cs[k];
    if (!c.vbo) {
        if (next)
            for (std::size_t j : *next) prefetch(s, cs, j, 1);
        else
            prefetch(s, cs, k + 1, cores());
        std::shared_ptr<BuiltLines> b = take(s, c);
        const bool first = !c.built;
        if (first) adopt(c, *b);
        if (!c.vbo && !b->verts.empty()) {
            if (!first) c.firsts = std::move(b->firsts), c.counts = std::move(b->counts);
            if (!ring_vao_) {
                glGenVertexArrays(1, &ring_vao_);
                glBindVertexArray(ring_vao_);
                glGenBuffers(1, &ring_vbo_);
                glBindBuffer(GL_ARRAY_BUFFER, ring_vbo_);
                vertex_attributes();
                glGenBuffers(1, &ring_ebo_);
                glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ring_ebo_);
            }
            glBindVertexArray(ring_vao_);
            glBindBuffer(GL_ARRAY_BUFFER, ring_vbo_);
            // A new store each time (orphaning): the driver keeps the
            // previous one until the draws that read it are done.
            glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(b->verts.size() * sizeof(LineVertex)), b->verts.data(), GL_STREAM_DRAW);
            glBufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(b->indices.size() * sizeof(std::uint32_t)), b->indices.data(), GL_STREAM_DRAW);
            draw_strips(GLsizei(b->indices.size()));
            stats_.streamed_points += c.kept;
            c.firsts.clear(), c.counts.clear();
            c.firsts.shrink_to_fit(), c.counts.shrink_to_fit();
            count(c, s.proxy);
            return;
        }
    }
    if (c.vbo) {
        glBindVertexArray(c.vao);
        draw_strips(c.nb_indices);
    }
    count(c, s.proxy);
}

void LineStream::skip(LineChunk &c) {
    if (auto it = pending_.find(&c); it != pending_.end()) {
        it->second.wait();
        pending_.erase(it);
    }
}

void LineStream::count(const LineChunk &c, bool proxy) {
    stats_.segments_drawn += c.segments;
    stats_.points_drawn += c.kept;
    stats_.streamlines_drawn += c.starts != UINT64_MAX ? c.starts : c.counts.empty() ? c.b - c.a : c.counts.size();
    ++stats_.chunks_drawn;
    if (proxy) stats_.proxy = true;
}

}  // namespace hz::core::render
