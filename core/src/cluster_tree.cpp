#include <hz/core/cluster_tree.hpp>
#include <hz/core/data.hpp>

#include <cmath>
#include <limits>
#include <vector>

namespace hz::core {

void check_cluster_tree(const hz_cluster_tree_view &v, std::uint64_t n, const std::string &plugin_id) {
    auto fail = [&](const std::string &what) { throw Error(plugin_id + ": returned a broken cluster tree: " + what); };
    const std::string node = "node ";
    if (v.nb_levels < 1 || v.nb_levels > kMaxClusterLevels)
        fail(std::to_string(v.nb_levels) + " levels below the root (1 to " + std::to_string(kMaxClusterLevels) + ")");
    if (v.nb_nodes < 1) fail("no root node");
    if (!v.parent || !v.level || !v.member_offsets || !v.level_thresholds) fail("a NULL array");
    if (n > 0 && !v.members) fail("NULL members");
    if (v.nb_points > kMaxCentroidPoints) fail(std::to_string(v.nb_points) + " points per centroid");
    if (v.nb_points > 0 && !v.centroids) fail("NULL centroids");
    // Every level partitions the input, the root's included: the member
    // lists hold exactly this many indices (which also bounds every read
    // below by what the counts say).
    const std::uint64_t levels = std::uint64_t(v.nb_levels) + 1;
    if (n > 0 && levels > std::numeric_limits<std::uint64_t>::max() / n) fail("too many members");
    if (v.nb_nodes > n * v.nb_levels + 1) fail(std::to_string(v.nb_nodes) + " nodes for " + std::to_string(n) + " streamlines");
    if (v.member_offsets[0] != 0) fail("member_offsets[0] is not 0");
    if (v.member_offsets[v.nb_nodes] != n * levels)
        fail(std::to_string(v.member_offsets[v.nb_nodes]) + " members in all, for " + std::to_string(n) + " streamlines in " +
             std::to_string(levels) + " levels (the root's included)");
    if (v.parent[0] != -1 || v.level[0] != 0) fail("node 0 is not the root (parent -1, level 0)");
    if (v.member_offsets[1] != n) fail("the root does not hold every streamline");
    for (std::uint32_t l = 0; l < v.nb_levels; ++l)
        if (!std::isfinite(v.level_thresholds[l])) fail("level " + std::to_string(l + 1) + "'s threshold is not finite");
    for (std::uint64_t k = 1; k < v.nb_nodes; ++k) {
        const std::string at = node + std::to_string(k);
        if (v.member_offsets[k + 1] < v.member_offsets[k]) fail("member_offsets decrease at " + at);
        if (v.member_offsets[k + 1] == v.member_offsets[k]) fail(at + " is an empty cluster");
        if (v.level[k] < v.level[k - 1]) fail(at + " comes after a node of a deeper level (nodes are ordered by level)");
        if (v.level[k] > v.nb_levels) fail(at + " is at level " + std::to_string(v.level[k]) + " of " + std::to_string(v.nb_levels));
        const std::int64_t p = v.parent[k];
        if (p < 0 || std::uint64_t(p) >= k) fail(at + " has parent " + std::to_string(p) + " (a node before it)");
        if (v.level[p] + 1 != v.level[k]) fail(at + " is not one level below its parent");
    }
    // `owner[s]`: the node of the level being checked that holds streamline
    // s, or (before it is seen at this level) the one of the level above.
    constexpr std::uint64_t kNone = std::numeric_limits<std::uint64_t>::max();
    std::vector<std::uint64_t> owner(n, kNone);
    for (std::uint64_t m = 0; m < n; ++m) {
        const std::uint64_t s = v.members[m];
        if (s >= n) fail("the root holds index " + std::to_string(s) + " of " + std::to_string(n) + " streamlines");
        if (owner[s] == 0) fail("the root holds streamline " + std::to_string(s) + " twice");
        owner[s] = 0;
    }
    for (std::uint64_t k = 1; k < v.nb_nodes; ++k) {
        const std::string at = node + std::to_string(k);
        const std::uint64_t p = std::uint64_t(v.parent[k]);
        for (std::uint64_t m = v.member_offsets[k]; m < v.member_offsets[k + 1]; ++m) {
            const std::uint64_t s = v.members[m];
            if (s >= n) fail(at + " holds index " + std::to_string(s) + " of " + std::to_string(n) + " streamlines");
            if (owner[s] != p) {
                if (v.level[owner[s]] == v.level[k])
                    fail("streamline " + std::to_string(s) + " is twice in level " + std::to_string(v.level[k]) + " (nodes " +
                         std::to_string(owner[s]) + " and " + std::to_string(k) + ")");
                if (v.level[owner[s]] + 1 < v.level[k])
                    fail("streamline " + std::to_string(s) + " is in no cluster of level " + std::to_string(v.level[k] - 1));
                fail(at + " holds streamline " + std::to_string(s) + ", which its parent (node " + std::to_string(p) + ") lacks");
            }
            owner[s] = k;
        }
    }
    // (Each level holds n members, none twice: every streamline is in one
    // cluster of each level.)
    if (v.nb_points > 0) {
        const float *c = v.centroids;
        for (std::uint64_t i = 0, e = v.nb_nodes * v.nb_points * 3; i < e; ++i)
            if (!std::isfinite(c[i]))
                fail("a centroid coordinate of node " + std::to_string(i / (std::uint64_t(v.nb_points) * 3)) + " is not finite");
    }
}

}  // namespace hz::core
