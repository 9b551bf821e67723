// BUAN (bundle analytics; Chandio et al., Sci Rep 10:17149, 2020): a
// bundle's profile along its length, one value a segment ("disk") of its
// model centroid, such as the p-values of a group comparison; drawn as
// dipy_horizon --buan draws it: the points of the segments whose p-value is
// below a threshold in a highlight colour.
#pragma once

#include <hz/core/data.hpp>

#include <cstdint>
#include <filesystem>
#include <vector>

namespace hz::core::render {

// The values of a numpy `.npy` file holding one vector (or an array of one
// row or column): float64, float32 or integers, either byte order, C or
// Fortran order (numpy's format, versions 1 to 3). At most 2^20 values.
// Throws Error naming the file ("pvals.npy: not a .npy file", "... holds 3
// x 4 values: one vector, one value a segment").
std::vector<double> read_npy_vector(const std::filesystem::path &path);

// The segment of each point of `bundle` (in storage order, one a vertex):
// dipy.stats.analysis.assignment_map(bundle, bundle, n). The bundle's
// streamlines resampled to n points evenly spaced along their length are
// clustered by QuickBundles with the average pointwise distance at 85 mm
// (each streamline as it is or reversed, whichever is nearer, as DIPY's
// QuickBundles compares them), and each point gets the index of the nearest point of
// the centroids, laid end to end (k x n: indices from n on where
// QuickBundles found more than one cluster). n in 1..100000.
std::vector<std::uint32_t> buan_segments(const Tractogram &bundle, std::uint32_t n);

}  // namespace hz::core::render
