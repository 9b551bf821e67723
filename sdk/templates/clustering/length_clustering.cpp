// Template clustering plugin: groups streamlines by arc length in bins of
// `bin_width` mm (one level below the root). Simple, but it honours the
// whole contract: ordering, cancellation, non-finite input, a result that
// stays valid until the next run. Centroids have one point: the centre of
// mass of the cluster's vertices.
#include <hz/cpp/plugin.hpp>

#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <vector>

namespace {

constexpr const char *kId = "org.example.clustering.length";

const hz_param_info kParams[] = {
    {
        .struct_size = sizeof(hz_param_info),
        .type = HZ_PARAM_FLOAT,
        .name = "bin_width",
        .label = "Bin width",
        .group = "",
        .unit = "mm",
        .tooltip = "width of each length bin",
        .flags = 0,
        .components = 1,
        .min_value = {0.1, 0, 0, 0},
        .max_value = {1000, 0, 0, 0},
        .default_value = {10, 0, 0, 0},
        .enum_labels = nullptr,
        .default_array_count = 0,
        .default_array = nullptr,
    },
};

struct Clusterer {
    double bin_width = 10.0;
    // Result storage (valid until the next run/set_param/destroy).
    std::vector<double> thresholds;
    std::vector<int64_t> parent;
    std::vector<uint32_t> level;
    std::vector<float> centroids;
    std::vector<uint64_t> offsets, members;
};

const hz_param_info *HZ_ABI get_param(uint32_t i) { return i < 1 ? &kParams[i] : nullptr; }

hz_status HZ_ABI create(const hz_host *, hz_clusterer **out, hz_error *err) {
    return hz::guard(err, [&] {
        *out = reinterpret_cast<hz_clusterer *>(new Clusterer());
        return HZ_OK;
    });
}

hz_status HZ_ABI set_param(hz_clusterer *c, const char *name, const double *values, uint32_t count, hz_error *err) {
    if (c == nullptr || name == nullptr || values == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "NULL argument");
    if (std::strcmp(name, "bin_width") != 0) return hz::set_errorf(err, HZ_E_NOT_FOUND, "unknown parameter '%s'", name);
    if (count != 1 || !(values[0] >= 0.1 && values[0] <= 1000))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "bin_width must be one value in [0.1, 1000] mm");
    reinterpret_cast<Clusterer *>(c)->bin_width = values[0];
    return HZ_OK;
}

hz_status HZ_ABI run(hz_clusterer *cl, const hz_streamlines_view *in, const uint64_t *ordering, const hz_task *task, hz_error *err) {
    if (cl == nullptr || in == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "NULL argument");
    return hz::guard(err, [&]() -> hz_status {
        Clusterer &c = *reinterpret_cast<Clusterer *>(cl);
        const uint64_t n = in->nb_streamlines;
        std::map<int64_t, uint64_t> bin_to_cluster;  // bin -> cluster index (creation order)
        std::vector<std::vector<uint64_t>> clusters;
        std::vector<std::array<double, 4>> sums;  // x, y, z, count
        for (uint64_t k = 0; k < n; ++k) {
            if ((k & 1023) == 0) {
                if (hz::cancelled(task)) return hz::set_error(err, HZ_E_CANCELLED, "cancelled");
                hz::report(task, double(k) / double(n));
            }
            const uint64_t s = ordering ? ordering[k] : k;
            if (s >= n) throw hz::Error(HZ_E_INVALID_ARGUMENT, "ordering is not a permutation");
            double len = 0;
            std::array<double, 4> sum{};
            // (in->gap: vertices after each streamline that belong to none: 0, or 1
            // since this plugin offers HZ_EXT_DELIMITED_STREAMLINES.)
            const uint64_t end = in->offsets[s + 1] - in->gap;
            for (uint64_t v = in->offsets[s]; v < end; ++v) {
                const float *p = in->positions + 3 * v;
                if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
                    throw hz::Error(HZ_E_FORMAT, "streamline " + std::to_string(s) + " has a non-finite coordinate");
                if (v > in->offsets[s])
                    len += std::sqrt(double(p[0] - p[-3]) * (p[0] - p[-3]) + double(p[1] - p[-2]) * (p[1] - p[-2]) +
                                     double(p[2] - p[-1]) * (p[2] - p[-1]));
                sum[0] += p[0], sum[1] += p[1], sum[2] += p[2], sum[3] += 1;
            }
            const auto bin = static_cast<int64_t>(std::floor(len / c.bin_width));
            auto [it, fresh] = bin_to_cluster.emplace(bin, clusters.size());
            if (fresh) clusters.emplace_back(), sums.push_back({});
            clusters[it->second].push_back(s);
            for (int d = 0; d < 4; ++d) sums[it->second][d] += sum[d];
        }
        const uint64_t k = clusters.size();
        c.thresholds = {c.bin_width};
        c.parent.assign(1 + k, 0);
        c.parent[0] = -1;
        c.level.assign(1 + k, 1);
        c.level[0] = 0;
        c.offsets.assign(1, 0);
        c.members.clear();
        c.centroids.assign(3 * (1 + k), 0.f);
        std::array<double, 4> all{};
        for (uint64_t j = 0; j < k; ++j)
            for (int d = 0; d < 4; ++d) all[d] += sums[j][d];
        // Root: every streamline, in processing order.
        for (const auto &cl_members : clusters) c.members.insert(c.members.end(), cl_members.begin(), cl_members.end());
        c.offsets.push_back(c.members.size());
        for (uint64_t j = 0; j < k; ++j) {
            c.members.insert(c.members.end(), clusters[j].begin(), clusters[j].end());
            c.offsets.push_back(c.members.size());
            for (int d = 0; d < 3; ++d) c.centroids[3 * (1 + j) + d] = sums[j][3] > 0 ? float(sums[j][d] / sums[j][3]) : 0.f;
        }
        for (int d = 0; d < 3; ++d) c.centroids[d] = all[3] > 0 ? float(all[d] / all[3]) : 0.f;
        hz::report(task, 1.0);
        return HZ_OK;
    });
}

hz_status HZ_ABI get_result(const hz_clusterer *cl, hz_cluster_tree_view *out, hz_error *err) {
    if (cl == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "NULL argument");
    const Clusterer &c = *reinterpret_cast<const Clusterer *>(cl);
    if (c.parent.empty()) return hz::set_error(err, HZ_E_BAD_STATE, "run() has not succeeded yet");
    out->nb_levels = 1;
    out->level_thresholds = c.thresholds.data();
    out->nb_nodes = c.parent.size();
    out->parent = c.parent.data();
    out->level = c.level.data();
    out->nb_points = 1;
    out->centroids = c.centroids.data();
    out->member_offsets = c.offsets.data();
    out->members = c.members.data();
    return HZ_OK;
}

void HZ_ABI destroy(hz_clusterer *c) { delete reinterpret_cast<Clusterer *>(c); }

const hz_clustering kClustering = {
    .struct_size = sizeof(hz_clustering),
    .param_count = 1,
    .get_param = get_param,
    .create = create,
    .set_param = set_param,
    .run = run,
    .get_result = get_result,
    .destroy = destroy,
};

// An optional extension (hz_extensions.h): a mapped TCK is clustered as it
// is, NaN delimiters in place, instead of copied without them first.
const hz_ext_delimited_streamlines kDelimited = {
    .struct_size = sizeof(hz_ext_delimited_streamlines),
    .max_gap = 1,
};
const char *const kInterfaces[] = {HZ_INTERFACE_CLUSTERING, HZ_EXT_DELIMITED_STREAMLINES, nullptr};
const hz_plugin_descriptor kDescriptor = {
    .struct_size = sizeof(hz_plugin_descriptor),
    .abi = HZ_ABI_VERSION_INIT,
    .kind = HZ_KIND_CLUSTERING,
    .id = kId,
    .name = "Length bins (template)",
    .version = "1.0.0",
    .vendor = "Example Vendor",
    .description = "Groups streamlines by arc length: a starting point for clustering plugins",
    .license = "MIT",
    .interfaces = kInterfaces,
};

bool HZ_ABI init(const hz_host *, const char *) { return true; }
void HZ_ABI deinit() {}
uint32_t HZ_ABI count() { return 1; }
const hz_plugin_descriptor *HZ_ABI descriptor(uint32_t i) { return i == 0 ? &kDescriptor : nullptr; }
const void *HZ_ABI get_interface(const char *id, const char *iface) {
    if (id == nullptr || iface == nullptr || std::strcmp(id, kId) != 0) return nullptr;
    if (std::strcmp(iface, HZ_INTERFACE_CLUSTERING) == 0) return &kClustering;
    if (std::strcmp(iface, HZ_EXT_DELIMITED_STREAMLINES) == 0) return &kDelimited;
    return nullptr;
}

}  // namespace

HZ_DECLARE_PLUGIN_ENTRY = {
    .struct_size = sizeof(hz_plugin_entry),
    .abi = HZ_ABI_VERSION_INIT,
    .init = init,
    .deinit = deinit,
    .get_plugin_count = count,
    .get_plugin_descriptor = descriptor,
    .get_interface = get_interface,
};
