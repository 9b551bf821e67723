// Chooses the level-of-detail proxy's level (Renderer::set_proxy_level) from
// the times of a window's moving frames, so that they stay within a budget
// on whatever machine and window size: a coarser level as soon as frames
// are slow, a finer one tried while they are fast, and a finer level that
// proved too slow not tried again for a while (twice as long each time it
// fails: it costs a few slow frames each time).
// Threading: one thread (the window's).
#pragma once

#include <deque>
#include <vector>

namespace hz::core::render {

class ProxyGovernor {
public:
    // `budget_ms`: a moving frame's time to stay within (0: the level never
    // changes); `levels`: how many there are (Renderer::proxy_level_count);
    // `start`: the first level (clamped to them).
    ProxyGovernor(double budget_ms, int levels, int start);

    // A moving frame drawn at level() took `ms` (all of it: the drawing,
    // the panel, the swap). Returns the level for the next moving frame:
    //   - one coarser when the median of the last 5 frames at this level is
    //     over the budget (most of them are: not a spike or two);
    //   - one finer when the median of the last 8 is under 0.8 x the budget
    //     and that level is not on hold;
    //   - else the same.
    // The first frame after a change is not counted (it may rebuild the
    // proxy for its new size). A level left for being slow is on hold for
    // the next kHoldFrames moving frames, twice that after each further
    // failure (up to kMaxHoldFrames).
    int add(double ms);
    // The finest level it may step up to (clamped to the levels; at first
    // the finest there is). Lowering it below level() moves there at once.
    // The window caps its top level, full detail, this way until a still
    // image has shown that full detail fits the budget.
    void set_finest(int level);
    int finest() const { return finest_; }
    int level() const { return level_; }
    // Moving frames before `level` may be tried again (0: it may).
    int hold(int level) const;

    static constexpr int kSlowFrames = 5, kFastFrames = 8, kHoldFrames = 45, kMaxHoldFrames = 1440;
    static constexpr double kFastShare = 0.8;

private:
    double budget_ms_;
    int level_;
    int finest_;
    bool settle_ = false;                // the next frame is the first at a new level
    std::deque<double> recent_;          // the last frames at this level
    std::vector<int> hold_, next_hold_;  // per level: frames left on hold, the next hold
};

}  // namespace hz::core::render
