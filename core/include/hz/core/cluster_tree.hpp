// What a clustering plugin returns is checked before the host reads it: a
// tree whose member indices, levels or parents break the contract of
// hz_clustering.h would otherwise be written past the host's arrays (a label
// per streamline and level) or drawn as a broken tree without a word.
#pragma once

#include <hz/hz_clustering.h>

#include <cstdint>
#include <string>

namespace hz::core {

// The most levels below the root a clustering may return (QuickBundlesX
// uses one per threshold: a handful). Bounds the host's label tables.
constexpr std::uint32_t kMaxClusterLevels = 64;
// The most points per centroid (QuickBundles resamples to 12 or 20).
constexpr std::uint32_t kMaxCentroidPoints = 1u << 16;

// Checks the result `v` of a clustering of `nb_streamlines` streamlines
// against hz_cluster_tree_view's contract, in O(nb_streamlines x levels +
// nodes) time and one array of nb_streamlines node ids:
//  - the pointers the host reads are set, 1 <= nb_levels <= kMaxClusterLevels,
//    nb_points <= kMaxCentroidPoints, thresholds and centroids finite;
//  - node 0 is the root (parent -1, level 0, every streamline);
//  - nodes are ordered by level; every other node is one level below its
//    parent, which comes before it; member_offsets never decrease;
//  - every level's members partition the input: each index below
//    nb_streamlines, each streamline in exactly one non-empty cluster of the
//    level, and within its parent's members.
// Throws Error "PLUGIN_ID: returned a broken cluster tree: WHAT" (one line).
// Reads only what the view's counts say the plugin's arrays hold.
void check_cluster_tree(const hz_cluster_tree_view &v, std::uint64_t nb_streamlines, const std::string &plugin_id);

}  // namespace hz::core
