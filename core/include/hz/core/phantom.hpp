// Synthetic whole-brain-like tractogram: bundles of smooth curved
// streamlines inside a brain-sized box, for demos, validation and benchmarks.
#pragma once

#include <hz/core/data.hpp>

#include <cstdint>

namespace hz::core {

struct PhantomOptions {
    std::uint64_t nb_streamlines = 2000;
    std::uint32_t nb_bundles = 24;
    double step_mm = 1.0;           // distance between consecutive points
    double min_length_mm = 20.0;
    double max_length_mm = 200.0;
    double bundle_radius_mm = 3.0;  // spread of streamlines around the bundle core
    double stray_fraction = 0.02;   // random curves not belonging to any bundle
    std::uint64_t seed = 1;
};

// Deterministic for a given options struct (same seed, same bits).
Tractogram make_phantom(const PhantomOptions &o);

}  // namespace hz::core
