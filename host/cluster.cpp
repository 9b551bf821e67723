// `horizon cluster`: runs a clustering plugin over a tractogram and writes
// per-level labels (CSV), optionally one level's centroids and the labelled
// tractogram.
#include "commands.hpp"
#include "progress.hpp"

#include <hz/core/cluster_tree.hpp>
#include <hz/core/io.hpp>
#include <hz/core/params.hpp>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <optional>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <numeric>
#include <random>
#include <sstream>
#include <unistd.h>

namespace hz::host {

namespace fs = std::filesystem;

namespace {

std::string fmt_threshold(double t) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", t);
    return buf;
}

// A reproducible permutation: Fisher-Yates over std::mt19937_64 (whose
// output sequence the C++ standard fixes), so the same seed gives the same
// order on every platform.
std::vector<std::uint64_t> shuffled(std::uint64_t n, std::uint64_t seed) {
    std::vector<std::uint64_t> o(n);
    std::iota(o.begin(), o.end(), 0);
    std::mt19937_64 rng(seed);
    for (std::uint64_t i = n; i > 1; --i) std::swap(o[i - 1], o[rng() % i]);
    return o;
}

struct ClusterRun {
    hz_cluster_tree_view view{};
    const hz_clustering *table = nullptr;
    hz_clusterer *obj = nullptr;
    ~ClusterRun() {
        if (obj) table->destroy(obj);
    }
};

}  // namespace

int cmd_cluster(const GlobalOptions &g, const ClusterOptions &o) {
    const core::Registry reg = load_registry(g);
    const core::LoadedPlugin *plugin = core::find_clustering(reg, o.algorithm);
    const std::string id = plugin->info.id;
    // Every parameter through the plugin's schema, before any work: the
    // shortcuts (--thresholds, --nb-points, --threads, --mode) and --param.
    const std::vector<core::ParamSpec> schema = core::schema_of(*plugin);
    std::map<std::string, std::vector<double>> settings;
    if (!o.thresholds.empty()) core::apply_shortcut(schema, id, "--thresholds", {"thresholds", "threshold"}, o.thresholds, settings);
    if (o.nb_points) core::apply_shortcut(schema, id, "--nb-points", {"nb_points"}, {double(o.nb_points)}, settings);
    if (o.threads) core::apply_shortcut(schema, id, "--threads", {"threads"}, {double(o.threads)}, settings);
    if (!o.mode.empty()) core::apply_shortcut(schema, id, "--mode", {"mode"}, {o.mode == "fast" ? 1.0 : 0.0}, settings);
    for (auto &[name, v] : core::parse_param_items(schema, id, o.params)) {
        // (a shortcut and --param for the same parameter: neither silently wins)
        if (settings.count(name))
            throw core::Error("--param " + name + " and a shortcut option (--thresholds, --nb-points, --threads, --mode) both set " + name +
                              ": give one");
        settings[name] = std::move(v);
    }
    if (o.labels.empty() && o.centroids.empty() && o.out.empty())
        throw core::Error("nothing to write: give --labels, --centroids or --out");
    // Fail on unwritable targets, and on outputs that would replace an input
    // or exist without --force, before the work.
    // (The ordering file is an input too: `--order F --labels F --force`
    // must not replace it.)
    std::vector<std::string> inputs{o.input};
    if (o.order != "file" && o.order != "shuffle") inputs.push_back(o.order);
    check_outputs({o.labels, o.centroids, o.out}, inputs, o.force);
    if (!o.centroids.empty()) core::loader_for_write(reg, o.centroids);
    if (!o.out.empty()) core::loader_for_write(reg, o.out);

    const auto t0 = std::chrono::steady_clock::now();
    std::optional<Progress> reading(std::in_place, "reading " + o.input, !o.json);
    const core::Dataset ds = core::read_dataset(reg, o.input, reading->task());
    if (ds.kind != HZ_DATA_STREAMLINES) throw core::Error(o.input + ": not a tractogram");
    // (A plugin that does not take delimiters (HZ_EXT_DELIMITED_STREAMLINES) gets a mapped TCK without
    // them: copied here, while reading.)
    const core::Tractogram t = plugin->streamlines_for(ds.tractogram);
    // Taking the view makes the positions of an unaligned TCK (nibabel's
    // layout) aligned now: that copy is part of reading, not of clustering.
    const hz_streamlines_view view = t.view();
    // A TCK read in place maps its positions lazily: they are made resident
    // now, as part of reading, so that the clustering starts from data in
    // memory (as DIPY's does from nibabel's arrays) and its clock measures
    // clustering rather than the page faults of a first read. The same time
    // end to end (4.81 s at 5M streamlines either way); 0.064 -> 0.060 s of
    // clustering at 100k.
    core::make_resident(view.positions, view.nb_vertices * 3 * sizeof(float));
    reading.reset();
    const auto t1 = std::chrono::steady_clock::now();

    ClusterRun run;
    run.table = plugin->clustering();
    hz_error err{};
    err.struct_size = sizeof err;
    if (plugin->call("create", "", [&] { return run.table->create(core::host_services(), &run.obj, &err); }) != HZ_OK)
        throw core::Error(id + ": " + err.message);
    for (const auto &[name, v] : settings)
        if (plugin->call("set_param", "", [&] {
                return run.table->set_param(run.obj, name.c_str(), v.data(), static_cast<uint32_t>(v.size()), &err);
            }) != HZ_OK)
            throw core::Error(id + ": parameter " + name + ": " + err.message);
    std::vector<std::uint64_t> order;
    if (o.order == "shuffle") {
        order = shuffled(t.nb_streamlines(), o.seed);
    } else if (o.order != "file") {  // a text file of streamline indices
        // (At most 24 bytes per index: a line of 20 digits and its end.)
        std::istringstream in(core::read_small_file(o.order, 24 * (t.nb_streamlines() + 1) + 4096, "ordering file"));
        std::uint64_t i;
        while (order.size() <= t.nb_streamlines() && in >> i) order.push_back(i);
        if (!in.eof() && order.size() <= t.nb_streamlines()) throw core::Error(o.order + ": not a list of integers");
        if (order.size() != t.nb_streamlines())
            throw core::Error(o.order + ": holds " + std::to_string(order.size()) + " indices for " + std::to_string(t.nb_streamlines()) +
                              " streamlines");
    }
    hz_status st;
    {
        Progress clustering("clustering " + std::to_string(t.nb_streamlines()) + " streamlines (" + o.algorithm + ")", !o.json);
        st = plugin->call("run", o.input,
                          [&] { return run.table->run(run.obj, &view, order.empty() ? nullptr : order.data(), clustering.task(), &err); });
    }
    if (st != HZ_OK) throw core::Error(o.input + ": " + id + ": " + err.message);
    run.view.struct_size = sizeof run.view;
    if (plugin->call("get_result", "", [&] { return run.table->get_result(run.obj, &run.view, &err); }) != HZ_OK)
        throw core::Error(id + ": " + err.message);
    const auto tc = std::chrono::steady_clock::now();
    core::check_cluster_tree(run.view, t.nb_streamlines(), id);
    const auto t2 = std::chrono::steady_clock::now();
    spdlog::debug("{}: its tree checked in {:.1f} ms", id, std::chrono::duration<double, std::milli>(t2 - tc).count());
    const hz_cluster_tree_view &v = run.view;

    // Labels: per level, the index of the cluster among that level's nodes.
    const std::uint64_t n = t.nb_streamlines();
    std::vector<std::vector<std::int64_t>> labels(v.nb_levels, std::vector<std::int64_t>(n, -1));
    std::vector<std::uint64_t> first_of_level(v.nb_levels + 2, v.nb_nodes), count_of_level(v.nb_levels + 1, 0);
    for (std::uint64_t k = 0; k < v.nb_nodes; ++k) {
        const uint32_t l = v.level[k];
        if (first_of_level[l] == v.nb_nodes) first_of_level[l] = k;
        ++count_of_level[l];
        if (l == 0) continue;
        for (std::uint64_t m = v.member_offsets[k]; m < v.member_offsets[k + 1]; ++m)
            labels[l - 1][v.members[m]] = static_cast<std::int64_t>(k - first_of_level[l]);
    }
    if (!o.labels.empty()) {
        std::string csv = "streamline";
        for (uint32_t l = 0; l < v.nb_levels; ++l) {
            csv += ',';
            csv += fmt_threshold(v.level_thresholds[l]);
        }
        csv += "\n";
        csv.reserve(csv.size() + n * (8 + 6 * v.nb_levels));
        for (std::uint64_t s = 0; s < n; ++s) {
            csv += std::to_string(s);
            for (uint32_t l = 0; l < v.nb_levels; ++l) {
                csv += ',';
                csv += std::to_string(labels[l][s]);
            }
            csv += "\n";
        }
        core::write_text_atomic(o.labels, csv, o.force);
    }
    if (!o.centroids.empty()) {
        const uint32_t level = o.level < 0 ? v.nb_levels : static_cast<uint32_t>(o.level);
        if (level > v.nb_levels)
            throw core::Error("--level " + std::to_string(level) + ": the tree has levels 0.." + std::to_string(v.nb_levels));
        core::Dataset c;
        c.kind = HZ_DATA_STREAMLINES;
        const std::uint64_t K = count_of_level[level], P = v.nb_points, k0 = first_of_level[level];
        c.tractogram.positions = core::Buffer<float>(K * P * 3);
        c.tractogram.offsets = core::Buffer<std::uint64_t>(K + 1);
        core::DataArray sizes;
        sizes.name = "cluster_size";
        sizes.attach = HZ_ATTACH_STREAMLINE;
        sizes.dtype = HZ_DTYPE_U32;
        sizes.count = K;
        sizes.bytes = core::Buffer<std::byte>(K * 4);
        std::string size_list;
        for (std::uint64_t k = 0; k < K; ++k) {
            std::copy_n(v.centroids + (k0 + k) * P * 3, P * 3, c.tractogram.positions.data() + k * P * 3);
            c.tractogram.offsets[k] = k * P;
            const auto sz = static_cast<std::uint32_t>(v.member_offsets[k0 + k + 1] - v.member_offsets[k0 + k]);
            std::memcpy(sizes.bytes.data() + 4 * k, &sz, 4);
            if (k) size_list += ' ';
            size_list += std::to_string(sz);
        }
        c.tractogram.offsets[K] = K * P;
        c.tractogram.arrays.push_back(std::move(sizes));
        c.tractogram.reference = t.reference;
        c.tractogram.reference_dims = t.reference_dims;
        c.metadata = {{"horizon_clustering", id},
                      {"horizon_level", std::to_string(level)},
                      {"horizon_threshold", level ? fmt_threshold(v.level_thresholds[level - 1]) : "root"},
                      {"horizon_cluster_sizes", size_list}};
        std::vector<std::string> dropped;
        core::write_dataset(reg, c, o.centroids, o.force, &dropped, o.input);
        for (const auto &d : dropped)
            if (d.find("cluster_size") == std::string::npos)  // the sizes are in the header instead
                std::fprintf(stderr, "horizon: warning: %s: dropped %s\n", o.centroids.c_str(), d.c_str());
    }
    if (!o.out.empty()) {
        core::Dataset out;
        out.kind = HZ_DATA_STREAMLINES;
        out.metadata = ds.metadata;
        out.tractogram.positions = t.positions.shared();
        out.tractogram.offsets = t.offsets.shared();
        out.tractogram.gap = t.gap;
        out.tractogram.reference = t.reference;
        out.tractogram.reference_dims = t.reference_dims;
        // Per level: the labels as per-streamline data, and every cluster as
        // a named group of streamline indices (TRX groups).
        for (uint32_t l = 0; l < v.nb_levels; ++l) {
            std::string thr = fmt_threshold(v.level_thresholds[l]);
            std::replace(thr.begin(), thr.end(), '.', 'p');  // TRX names cannot hold dots
            const std::string prefix = "level" + std::to_string(l + 1) + "_" + thr + "mm";
            core::DataArray a;
            a.name = "cluster_" + prefix;
            a.attach = HZ_ATTACH_STREAMLINE;
            a.dtype = HZ_DTYPE_I64;
            a.count = n;
            a.bytes = core::Buffer<std::byte>(n * 8);
            std::memcpy(a.bytes.data(), labels[l].data(), n * 8);
            out.tractogram.arrays.push_back(std::move(a));
        }
        for (std::uint64_t k = 0; k < v.nb_nodes; ++k) {
            const uint32_t l = v.level[k];
            if (l == 0) continue;
            std::string thr = fmt_threshold(v.level_thresholds[l - 1]);
            std::replace(thr.begin(), thr.end(), '.', 'p');
            core::DataArray g;
            g.name = "level" + std::to_string(l) + "_" + thr + "mm_cluster" + std::to_string(k - first_of_level[l]);
            g.attach = HZ_ATTACH_GROUP;
            g.dtype = HZ_DTYPE_U64;
            g.count = v.member_offsets[k + 1] - v.member_offsets[k];
            g.bytes = core::Buffer<std::byte>(g.count * 8);
            std::memcpy(g.bytes.data(), v.members + v.member_offsets[k], g.count * 8);
            out.tractogram.arrays.push_back(std::move(g));
        }
        std::vector<std::string> dropped;
        core::write_dataset(reg, out, o.out, o.force, &dropped, o.input);
        for (const auto &d : dropped) std::fprintf(stderr, "horizon: warning: %s: dropped %s\n", o.out.c_str(), d.c_str());
    }

    const double read_s = std::chrono::duration<double>(t1 - t0).count();
    const double cluster_s = std::chrono::duration<double>(t2 - t1).count();
    // Standard output holds the labels (--labels -): the report goes to stderr.
    std::FILE *report = o.labels == "-" ? stderr : stdout;
    if (o.json) {
        nlohmann::json j;
        j["input"] = o.input;
        j["algorithm"] = id;
        j["nb_streamlines"] = n;
        j["read_s"] = read_s;
        j["cluster_s"] = cluster_s;
        j["levels"] = nlohmann::json::array();
        for (uint32_t l = 0; l < v.nb_levels; ++l)
            j["levels"].push_back({{"threshold", v.level_thresholds[l]}, {"clusters", count_of_level[l + 1]}});
        std::fprintf(report, "%s\n", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace).c_str());
    } else {
        std::fprintf(report, "%s: %llu streamlines, %s (read %.3f s, clustered %.3f s)\n", o.input.c_str(), (unsigned long long)n,
                     plugin->info.name.c_str(), read_s, cluster_s);
        for (uint32_t l = 0; l < v.nb_levels; ++l)
            std::fprintf(report, "  level %u  threshold %6s mm  %8llu clusters\n", l + 1, fmt_threshold(v.level_thresholds[l]).c_str(),
                         (unsigned long long)count_of_level[l + 1]);
    }
    return 0;
}

}  // namespace hz::host
