// hz.clustering/1 adapter: QuickBundles, QuickBundlesX and Horizon's
// qbx_and_merge in one library (qb_algorithm.hpp holds the algorithms).
#include "parallel.hpp"  // hzio::resize_prefaulted (plugins/common)
#include "qb_algorithm.hpp"

#include <hz/cpp/plugin.hpp>

#include <cmath>
#include <cstring>
#include <memory>
#include <thread>

namespace {

enum class Algo { QB, QBX, Merge };

const double kQbxDefaults[] = {30, 25, 20, 15};
const double kMergeDefaults[] = {40, 30, 25, 20, 15};

constexpr hz_param_info param_float(const char *name, const char *label, const char *tip, double lo, double hi, double def) {
    return {sizeof(hz_param_info), HZ_PARAM_FLOAT, name,           label,   "", "mm",   tip, 0, 1,
            {lo, 0, 0, 0},         {hi, 0, 0, 0},  {def, 0, 0, 0}, nullptr, 0,  nullptr};
}
constexpr hz_param_info param_int(const char *name, const char *label, const char *unit, const char *tip, double lo, double hi,
                                  double def) {
    return {sizeof(hz_param_info), HZ_PARAM_INT,  name,           label,   "", unit,   tip, 0, 1,
            {lo, 0, 0, 0},         {hi, 0, 0, 0}, {def, 0, 0, 0}, nullptr, 0,  nullptr};
}
constexpr hz_param_info param_thresholds(uint32_t n, const double *defs) {
    return {sizeof(hz_param_info),
            HZ_PARAM_FLOAT_ARRAY,
            "thresholds",
            "Thresholds",
            "",
            "mm",
            "MDF distance threshold of each level, coarse to fine",
            0,
            16,
            {0, 0, 0, 0},
            {1e6, 0, 0, 0},
            {15, 0, 0, 0},
            nullptr,
            n,
            defs};
}

const char *const kModeLabels[] = {"exact", "fast", nullptr};
const hz_param_info kModeParam = {sizeof(hz_param_info),
                                  HZ_PARAM_ENUM,
                                  "mode",
                                  "Mode",
                                  "",
                                  "",
                                  "exact: DIPY's answers bit for bit; fast: float32 distances",
                                  0,
                                  1,
                                  {0, 0, 0, 0},
                                  {1, 0, 0, 0},
                                  {0, 0, 0, 0},
                                  kModeLabels,
                                  0,
                                  nullptr};
const hz_param_info kThreadsParam =
    param_int("threads", "Threads", "",
              "threads (0 = all cores): resampling uses them all, the QuickBundlesX search up to 2 (1: the calling thread alone); "
              "results do not depend on it",
              0, 256, 0);

const hz_param_info kQbParams[] = {
    param_float("threshold", "Threshold", "MDF distance below which a streamline joins a cluster", 0, 1e6, 15),
    param_int("nb_points", "Points", "", "points each streamline is resampled to", 2, 1000, 12),
    kThreadsParam,
    kModeParam,
};
const hz_param_info kQbxParams[] = {
    param_thresholds(4, kQbxDefaults),
    param_int("nb_points", "Points", "", "points each streamline is resampled to", 2, 1000, 12),
    kThreadsParam,
    kModeParam,
};
const hz_param_info kMergeParams[] = {
    param_thresholds(5, kMergeDefaults),
    param_int("nb_points", "Points", "", "points each streamline is resampled to", 2, 1000, 20),
    kThreadsParam,
    kModeParam,
};

struct Clusterer {
    Algo algo;
    std::vector<double> thresholds;
    std::uint32_t nb_points;
    unsigned threads = 0;
    qb::Mode mode = qb::Mode::Exact;
    bool has_result = false;
    qb::Tree tree;
};

template <Algo A>
struct Kind;
template <>
struct Kind<Algo::QB> {
    static constexpr const hz_param_info *params = kQbParams;
    static constexpr uint32_t count = 4;
};
template <>
struct Kind<Algo::QBX> {
    static constexpr const hz_param_info *params = kQbxParams;
    static constexpr uint32_t count = 4;
};
template <>
struct Kind<Algo::Merge> {
    static constexpr const hz_param_info *params = kMergeParams;
    static constexpr uint32_t count = 4;
};

template <Algo A>
const hz_param_info *HZ_ABI get_param(uint32_t i) {
    return i < Kind<A>::count ? &Kind<A>::params[i] : nullptr;
}

template <Algo A>
hz_status HZ_ABI create(const hz_host *, hz_clusterer **out, hz_error *err) {
    if (out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "create: NULL output");
    return hz::guard(err, [&] {
        auto c = std::make_unique<Clusterer>();
        c->algo = A;
        if (A == Algo::QB) {
            c->thresholds = {kQbParams[0].default_value[0]};
        } else {
            const hz_param_info &t = Kind<A>::params[0];
            c->thresholds.assign(t.default_array, t.default_array + t.default_array_count);
        }
        c->nb_points = static_cast<std::uint32_t>(Kind<A>::params[1].default_value[0]);
        *out = reinterpret_cast<hz_clusterer *>(c.release());
        return HZ_OK;
    });
}

Clusterer &self(hz_clusterer *c) { return *reinterpret_cast<Clusterer *>(c); }
const Clusterer &self(const hz_clusterer *c) { return *reinterpret_cast<const Clusterer *>(c); }

hz_status HZ_ABI set_param(hz_clusterer *cl, const char *name, const double *v, uint32_t n, hz_error *err) {
    if (cl == nullptr || name == nullptr || (v == nullptr && n > 0))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "set_param: NULL argument");
    Clusterer &c = self(cl);
    c.has_result = false;
    const std::string key = name;
    auto finite_nonneg = [&](double x) { return std::isfinite(x) && x >= 0 && x <= 1e6; };
    if ((key == "threshold" && c.algo == Algo::QB) || (key == "thresholds" && c.algo != Algo::QB)) {
        const uint32_t max = c.algo == Algo::QB ? 1 : 16;
        if (n < 1 || n > max) return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "%s takes 1..%u values", name, max);
        for (uint32_t i = 0; i < n; ++i)
            if (!finite_nonneg(v[i])) return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "%s must be finite, in [0, 1e6] mm", name);
        c.thresholds.assign(v, v + n);
        return HZ_OK;
    }
    if (key == "nb_points") {
        if (n != 1 || !(v[0] >= 2 && v[0] <= 1000) || v[0] != std::floor(v[0]))
            return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "nb_points must be an integer in [2, 1000]");
        c.nb_points = static_cast<std::uint32_t>(v[0]);
        return HZ_OK;
    }
    if (key == "threads") {
        if (n != 1 || !(v[0] >= 0 && v[0] <= 256)) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "threads must be in [0, 256]");
        c.threads = static_cast<unsigned>(v[0]);
        return HZ_OK;
    }
    if (key == "mode") {
        if (n != 1 || !(v[0] == 0 || v[0] == 1)) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "mode must be 0 (exact) or 1 (fast)");
        c.mode = v[0] == 0 ? qb::Mode::Exact : qb::Mode::Fast;
        return HZ_OK;
    }
    return hz::set_errorf(err, HZ_E_NOT_FOUND, "unknown parameter '%s'", name);
}

hz_status HZ_ABI run(hz_clusterer *cl, const hz_streamlines_view *in, const uint64_t *ordering, const hz_task *task, hz_error *err) {
    if (cl == nullptr || in == nullptr || (in->nb_streamlines > 0 && (in->offsets == nullptr || in->positions == nullptr)))
        return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "run: NULL clusterer or input");
    Clusterer &c = self(cl);
    c.has_result = false;
    return hz::guard(err, [&]() -> hz_status {
        try {
            // (gap: 0 or 1, as HZ_EXT_DELIMITED_STREAMLINES allows.)
            if (in->gap > 1) return hz::set_errorf(err, HZ_E_INVALID_ARGUMENT, "run: gap %u (0 or 1 supported)", in->gap);
            const qb::Input input{in->positions, in->offsets, in->nb_streamlines, in->gap};
            std::vector<std::uint64_t> order;  // (empty: file order)
            if (ordering != nullptr) {
                hzio::resize_prefaulted(order, in->nb_streamlines);
                std::copy_n(ordering, in->nb_streamlines, order.begin());
            }
            const unsigned threads = c.threads ? c.threads : std::max(1u, std::thread::hardware_concurrency());
            const qb::CancelFn cancel = [task] { return hz::cancelled(task); };
            const qb::ProgressFn progress = [task](double f) { hz::report(task, f); };
            if (hz::cancelled(task)) throw qb::Cancelled{};
            if (c.algo == Algo::Merge) {
                c.tree = qb::qbx_and_merge(input, c.thresholds, c.nb_points, order, {}, c.mode, threads, cancel, progress);
            } else if (c.algo == Algo::QBX) {
                c.tree = qb::quickbundlesx(input, c.nb_points, c.thresholds, order, c.mode, threads, cancel, progress);
            } else {
                const qb::Features f = qb::extract_features(input, c.nb_points, threads, cancel,
                                                            c.mode == qb::Mode::Exact ? qb::Resampling::Dipy : qb::Resampling::Fast);
                c.tree = qb::quickbundles(f, c.thresholds[0], order, c.mode, cancel, progress);
            }
            c.has_result = true;
            return HZ_OK;
        } catch (const qb::Cancelled &) {
            return hz::set_error(err, HZ_E_CANCELLED, "cancelled");
        } catch (const qb::InputError &e) {
            return hz::set_error(err, HZ_E_FORMAT, e.what());
        }
    });
}

hz_status HZ_ABI get_result(const hz_clusterer *cl, hz_cluster_tree_view *out, hz_error *err) {
    if (cl == nullptr || out == nullptr) return hz::set_error(err, HZ_E_INVALID_ARGUMENT, "get_result: NULL argument");
    const Clusterer &c = self(cl);
    if (!c.has_result) return hz::set_error(err, HZ_E_BAD_STATE, "no result: run() has not succeeded since the last change");
    const qb::Tree &t = c.tree;
    out->nb_levels = static_cast<uint32_t>(t.thresholds.size());
    out->level_thresholds = t.thresholds.data();
    out->nb_nodes = t.nb_nodes();
    out->parent = t.parent.data();
    out->level = t.level.data();
    out->nb_points = t.nb_points;
    out->centroids = t.centroids.data();
    out->member_offsets = t.member_offsets.data();
    out->members = t.members.data();
    return HZ_OK;
}

void HZ_ABI destroy(hz_clusterer *c) { delete reinterpret_cast<Clusterer *>(c); }

template <Algo A>
constexpr hz_clustering make_table() {
    return {
        .struct_size = sizeof(hz_clustering),
        .param_count = Kind<A>::count,
        .get_param = get_param<A>,
        .create = create<A>,
        .set_param = set_param,
        .run = run,
        .get_result = get_result,
        .destroy = destroy,
    };
}
const hz_clustering kTables[] = {make_table<Algo::QB>(), make_table<Algo::QBX>(), make_table<Algo::Merge>()};

// Every algorithm takes a mapped TCK as it is (HZ_EXT_DELIMITED_STREAMLINES).
const hz_ext_delimited_streamlines kDelimited = {
    .struct_size = sizeof(hz_ext_delimited_streamlines),
    .max_gap = 1,
};
const char *const kInterfaces[] = {HZ_INTERFACE_CLUSTERING, HZ_EXT_DELIMITED_STREAMLINES, nullptr};
const hz_plugin_descriptor kDescriptors[] = {
    {
        .struct_size = sizeof(hz_plugin_descriptor),
        .abi = HZ_ABI_VERSION_INIT,
        .kind = HZ_KIND_CLUSTERING,
        .id = "org.horizon.clustering.qb",
        .name = "QuickBundles",
        .version = "1.0.0",
        .vendor = "Horizon",
        .description = "QuickBundles (Garyfallidis 2012), DIPY 1.6's exact labels and centroids",
        .license = "MIT",
        .interfaces = kInterfaces,
    },
    {
        .struct_size = sizeof(hz_plugin_descriptor),
        .abi = HZ_ABI_VERSION_INIT,
        .kind = HZ_KIND_CLUSTERING,
        .id = "org.horizon.clustering.qbx",
        .name = "QuickBundlesX",
        .version = "1.0.0",
        .vendor = "Horizon",
        .description = "QuickBundlesX (Garyfallidis 2016): a tree of centroids, one level per threshold; DIPY 1.6 exact",
        .license = "MIT",
        .interfaces = kInterfaces,
    },
    {
        .struct_size = sizeof(hz_plugin_descriptor),
        .abi = HZ_ABI_VERSION_INIT,
        .kind = HZ_KIND_CLUSTERING,
        .id = "org.horizon.clustering.qbx_merge",
        .name = "QBX and merge",
        .version = "1.0.0",
        .vendor = "Horizon",
        .description = "Horizon's qbx_and_merge: QuickBundlesX, then the last level's centroids merged",
        .license = "MIT",
        .interfaces = kInterfaces,
    },
};

bool HZ_ABI init(const hz_host *, const char *) { return true; }
void HZ_ABI deinit() {}
uint32_t HZ_ABI count() { return 3; }
const hz_plugin_descriptor *HZ_ABI descriptor(uint32_t i) { return i < 3 ? &kDescriptors[i] : nullptr; }
const void *HZ_ABI get_interface(const char *id, const char *iface) {
    if (id == nullptr || iface == nullptr) return nullptr;
    for (int i = 0; i < 3; ++i)
        if (std::strcmp(id, kDescriptors[i].id) == 0) {
            if (std::strcmp(iface, HZ_INTERFACE_CLUSTERING) == 0) return &kTables[i];
            if (std::strcmp(iface, HZ_EXT_DELIMITED_STREAMLINES) == 0) return &kDelimited;
        }
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
