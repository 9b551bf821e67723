#include <hz/core/render/proxy_governor.hpp>

#include <algorithm>
#include <utility>

namespace hz::core::render {
namespace {
// The median of the last n of `v` (n <= v.size()).
double median_of_last(const std::deque<double> &v, std::size_t n) {
    std::vector<double> x(v.end() - std::ptrdiff_t(n), v.end());
    std::nth_element(x.begin(), x.begin() + std::ptrdiff_t(n / 2), x.end());
    return x[n / 2];
}
}  // namespace

ProxyGovernor::ProxyGovernor(double budget_ms, int levels, int start)
    : budget_ms_(budget_ms),
      level_(std::clamp(start, 0, std::max(0, levels - 1))),
      finest_(std::max(0, levels - 1)),
      hold_(std::size_t(std::max(1, levels)), 0),
      next_hold_(std::size_t(std::max(1, levels)), kHoldFrames) {}

int ProxyGovernor::hold(int level) const { return level >= 0 && std::size_t(level) < hold_.size() ? hold_[std::size_t(level)] : 0; }

void ProxyGovernor::set_finest(int level) {
    finest_ = std::clamp(level, 0, int(hold_.size()) - 1);
    if (level_ > finest_) {
        level_ = finest_;
        recent_.clear();
        settle_ = true;
    }
}

int ProxyGovernor::add(double ms) {
    if (!(budget_ms_ > 0)) return level_;
    for (int &h : hold_) h = std::max(0, h - 1);
    if (std::exchange(settle_, false)) return level_;
    recent_.push_back(ms);
    if (recent_.size() > std::size_t(kFastFrames)) recent_.pop_front();
    const auto change = [&](int to) {
        level_ = to;
        recent_.clear();
        settle_ = true;
    };
    if (level_ > 0 && recent_.size() >= std::size_t(kSlowFrames) && median_of_last(recent_, kSlowFrames) > budget_ms_) {
        const std::size_t l = std::size_t(level_);
        hold_[l] = next_hold_[l];
        next_hold_[l] = std::min(2 * next_hold_[l], kMaxHoldFrames);
        change(level_ - 1);
    } else if (level_ < finest_ && recent_.size() >= std::size_t(kFastFrames) &&
               median_of_last(recent_, kFastFrames) < kFastShare * budget_ms_ && hold_[std::size_t(level_ + 1)] == 0) {
        change(level_ + 1);
    }
    return level_;
}

}  // namespace hz::core::render
