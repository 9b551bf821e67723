// Small tractograms for unit tests: each polyline a flat list of x, y, z.
#pragma once

#include <hz/core/data.hpp>

#include <cstdint>
#include <vector>

inline hz::core::Tractogram polylines(const std::vector<std::vector<float>> &lines) {
    std::vector<float> pos;
    std::vector<std::uint64_t> off{0};
    for (const auto &l : lines) {
        pos.insert(pos.end(), l.begin(), l.end());
        off.push_back(pos.size() / 3);
    }
    hz::core::Tractogram t;
    t.positions = hz::core::Buffer<float>::copy_of(pos);
    t.offsets = hz::core::Buffer<std::uint64_t>::copy_of(off);
    return t;
}
