// Synthetic whole-brain-like tractogram: bundles of smooth curved
// streamlines inside a brain-sized box, for demos, validation and benchmarks.
#pragma once

#include <hz/core/data.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace hz::core {

struct PhantomOptions {
    std::uint64_t nb_streamlines = 2000;
    std::uint32_t nb_bundles = 24;
    double step_mm = 1.0;  // distance between consecutive points
    double min_length_mm = 20.0;
    double max_length_mm = 200.0;
    double bundle_radius_mm = 3.0;  // spread of streamlines around the bundle core
    double stray_fraction = 0.02;   // random curves not belonging to any bundle
    std::uint64_t seed = 1;
};

// Deterministic for a given options struct (same seed, same bits).
Tractogram make_phantom(const PhantomOptions &o);

// The named bundles of make_brain_phantom, in the order of its "bundle"
// values: the corticospinal tracts, arcuate fasciculi, cingula, inferior
// fronto-occipital, uncinate and inferior longitudinal fasciculi of each
// hemisphere (suffix _L or _R), and the corpus callosum (CC).
const std::vector<std::string> &brain_bundle_names();

// A whole-brain-like tractogram of `nb_streamlines` streamlines (points 1 mm
// apart, RAS+ mm, the frame of make_cortex_mesh's brain: about 140 x 180 x
// 120 mm around the origin) in anatomically plausible bundles: each a
// smooth curve through waypoints after the bundle's course in an MNI-like
// space (a sketch for demos and tests, not an atlas), its streamlines
// spread around it and fanning towards their cortical ends. A per-streamline
// array "bundle" holds each one's index into brain_bundle_names().
// Deterministic for a seed.
Tractogram make_brain_phantom(std::uint64_t nb_streamlines, std::uint64_t seed = 1);

// splitmix64 draws, the same on every platform (std::uniform_real_distribution
// is implementation-defined; synthetic data must be identical everywhere).
struct SplitMix64 {
    std::uint64_t s;
    std::uint64_t next() {
        std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    double uniform(double a, double b) { return a + (b - a) * (double(next() >> 11) * 0x1.0p-53); }
    double normal() {
        const double u1 = std::max(uniform(0, 1), 1e-300), u2 = uniform(0, 1);
        return std::sqrt(-2 * std::log(u1)) * std::cos(2 * M_PI * u2);
    }
};

}  // namespace hz::core
