#include "session.hpp"
#include "commands.hpp"
#include "progress.hpp"

#include <hz/core/io.hpp>
#include <hz/core/params.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>

namespace hz::host {

// ---------------------------------------------------------------- Explorer

Explorer::Explorer(const core::Registry &reg, core::Tractogram all, std::string name, core::render::ClusterSpec spec, bool cluster_now,
                   core::Bounds bounds)
    : reg_(reg), all_(std::move(all)), name_(std::move(name)), spec_(std::move(spec)), all_bounds_(bounds) {
    if (!all_bounds_.empty) std::call_once(bounds_once_, [] {});
    if (cluster_now)
        reset();
    else
        adopt({}, compute({}, spec_.thresholds), nullptr), s_.rounds = 0;
}

const core::Bounds &Explorer::all_bounds() const {
    std::call_once(bounds_once_, [this] {
        if (all_.nb_stored()) all_bounds_ = core::bounds_of(all_.positions.data(), all_.nb_stored());
    });
    return all_bounds_;
}

double Explorer::all_diagonal() const {
    const core::Bounds &b = all_bounds();
    return b.empty ? 0 : std::hypot(b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]);
}

Explorer::Saved Explorer::compute_saved(const std::vector<std::int64_t> &label, const std::vector<std::string> &names,
                                        const hz_task *task) const {
    const std::size_t G = names.size();
    std::vector<std::vector<std::uint64_t>> groups(G);
    Saved out;
    out.names = names;
    for (std::uint64_t s = 0; s < label.size(); ++s) {
        if (label[s] >= 0 && std::size_t(label[s]) < G)
            groups[std::size_t(label[s])].push_back(s);
        else
            out.alone.push_back(s);
    }
    // One level under a root: node 0 the root, node g + 1 saved cluster g.
    auto tree = std::make_shared<core::render::ClusterTree>();
    tree->nb_levels = 1;
    tree->parent.assign(G + 1, 0);
    tree->parent[0] = -1;
    tree->level.assign(G + 1, 1);
    tree->level[0] = 0;
    tree->member_offsets = {0, 0};
    for (std::size_t g = 0; g < G; ++g) {
        for (std::uint64_t s : groups[g]) tree->members.push_back(out.subset.size()), out.subset.push_back(s);
        tree->member_offsets.push_back(tree->members.size());
    }
    // Each cluster's centroid: the plugin's, over its streamlines alone, at
    // a threshold no two of them are apart by (one cluster).
    std::vector<double> huge;
    for (std::size_t l = 0; l < std::max<std::size_t>(1, spec_.thresholds.size()); ++l) huge.push_back(1e4);
    std::uint64_t done = 0;
    for (std::size_t g = 0; g < G; ++g) {
        if (task && task->is_cancelled(task)) throw core::Error("cancelled");
        std::vector<float> c;
        if (!groups[g].empty()) {
            // A centroid is a mean: of a large cluster, over an evenly spaced
            // sample of its streamlines (kCentroidSample; at 10M in 118
            // clusters, the restore took 76 s copying all of them).
            std::vector<std::uint64_t> sample;
            const std::vector<std::uint64_t> &ids = groups[g].size() <= kCentroidSample ? groups[g] : sample;
            for (std::uint64_t k = 0; groups[g].size() > kCentroidSample && k < kCentroidSample; ++k)
                sample.push_back(groups[g][k * groups[g].size() / kCentroidSample]);
            const auto t = core::render::run_clustering(reg_, core::select_streamlines(all_, ids, /*spill=*/true), [&] {
                core::render::ClusterSpec sp = spec_;
                sp.thresholds = huge;
                return sp;
            }());
            tree->nb_points = t.nb_points;
            for (std::uint64_t k = 0; k < t.level.size(); ++k)
                if (t.level[k] == 1) {
                    c.assign(t.centroids.begin() + std::ptrdiff_t(k * t.nb_points * 3),
                             t.centroids.begin() + std::ptrdiff_t((k + 1) * t.nb_points * 3));
                    break;
                }
        }
        if (tree->centroids.empty()) tree->centroids.assign(std::size_t(tree->nb_points) * 3, 0.0f);  // (the root's)
        c.resize(std::size_t(tree->nb_points) * 3, 0.0f);
        tree->centroids.insert(tree->centroids.end(), c.begin(), c.end());
        done += groups[g].size();
        if (task && !out.subset.empty()) task->report(task, double(done) / double(out.subset.size()), nullptr);
    }
    out.tree = std::move(tree);
    return out;
}

void Explorer::adopt_saved(Saved saved) {
    const std::size_t G = saved.names.size();
    s_ = State{};
    s_.tree = std::move(saved.tree);
    s_.subset = std::make_shared<const std::vector<std::uint64_t>>(std::move(saved.subset));
    s_.expanded = std::move(saved.alone);
    s_.expanded_origin.assign(s_.expanded.size(), 0);
    expanded_changed();
    for (std::size_t g = 0; g < G; ++g) s_.shown.push_back(g + 1);
    sort();
    s_.colour.assign(G + 1, 0);
    for (std::size_t g = 0; g < G; ++g) s_.colour[g + 1] = g;  // (as the saved file is coloured in a plain view)
    s_.next_colour = G;
    auto node_names = std::make_shared<std::vector<std::string>>(G + 1);
    for (std::size_t g = 0; g < G; ++g) (*node_names)[g + 1] = std::move(saved.names[g]);
    s_.names = std::move(node_names);
    s_.rounds = 1;
}

std::uint64_t Explorer::at(std::size_t rank) const {
    if (rank >= s_.shown.size())
        throw core::Error("no cluster " + std::to_string(rank) + " (" + std::to_string(s_.shown.size()) + " shown)");
    return s_.shown[rank];
}

void Explorer::sort() {
    std::stable_sort(s_.shown.begin(), s_.shown.end(), [&](std::uint64_t a, std::uint64_t b) { return size(a) > size(b); });
}

std::vector<std::uint64_t> Explorer::children(std::uint64_t node) const {
    std::vector<std::uint64_t> kids;
    const auto &parent = s_.tree->parent;
    for (std::uint64_t k = 0; k < parent.size(); ++k)
        if (parent[k] == std::int64_t(node)) kids.push_back(k);
    std::stable_sort(kids.begin(), kids.end(), [&](std::uint64_t a, std::uint64_t b) { return size(a) > size(b); });
    return kids;
}

std::string Explorer::path(std::uint64_t node) const {
    if (s_.names && node < s_.names->size() && !(*s_.names)[node].empty()) return (*s_.names)[node];
    std::vector<std::size_t> ranks;
    for (std::uint64_t n = node; s_.tree->level[n] >= 1;) {
        const std::int64_t p = s_.tree->parent[n];
        std::vector<std::uint64_t> sib;
        if (p >= 0)
            sib = children(std::uint64_t(p));
        else
            for (std::uint64_t k = 0; k < s_.tree->level.size(); ++k)
                if (s_.tree->level[k] == s_.tree->level[n] && s_.tree->parent[k] < 0) sib.push_back(k);
        ranks.push_back(std::size_t(std::find(sib.begin(), sib.end(), n) - sib.begin()) + 1);
        if (p < 0) break;
        n = std::uint64_t(p);
    }
    std::string s = "c";
    for (auto it = ranks.rbegin(); it != ranks.rend(); ++it) s += (it == ranks.rbegin() ? "" : ".") + std::to_string(*it);
    return s;
}

std::size_t Explorer::rank_of(const std::string &what) const {
    if (!what.empty() && what[0] == 'c') {
        for (std::size_t k = 0; k < s_.shown.size(); ++k)
            if (path(s_.shown[k]) == what) return k;
        throw core::Error("no cluster " + what + " is shown");
    }
    std::size_t used = 0;
    unsigned long k = 0;
    try {
        k = std::stoul(what, &used);
    } catch (const std::exception &) {
        used = 0;
    }
    if (used == 0 || used != what.size()) throw core::Error("'" + what + "' is not a cluster (a rank such as 0, or a path such as c2.1)");
    at(k);
    return k;
}

std::string Explorer::summary() const {
    std::string colours;
    for (std::uint64_t node : s_.shown) colours += (colours.empty() ? "" : " ") + std::to_string(s_.colour[node]);
    std::string picked;
    for (std::size_t k = 0; k < s_.shown.size(); ++k)
        if (s_.selected.count(s_.shown[k])) picked += " #" + std::to_string(k);
    std::string thresholds;
    for (double t : s_.thresholds) {
        char b[32];
        std::snprintf(b, sizeof b, "%s%.2f", thresholds.empty() ? "" : " ", t);
        thresholds += b;
    }
    return std::to_string(s_.shown.size()) + " clusters, " + std::to_string(s_.expanded.size()) + " streamlines expanded, " +
           std::to_string(s_.rounds) + " clustering round(s); selected" + (picked.empty() ? " none" : picked) +
           (thresholds.empty() ? "" : "; thresholds " + thresholds + " mm") + "; colours " + colours;
}

void Explorer::toggle(std::size_t rank) {
    const std::uint64_t node = at(rank);
    if (!s_.selected.erase(node)) s_.selected.insert(node);
}

void Explorer::select_all() {
    if (s_.selected.size() == s_.shown.size())
        s_.selected.clear();
    else
        s_.selected = std::set<std::uint64_t>(s_.shown.begin(), s_.shown.end());
}

void Explorer::require_selected() const {
    if (s_.selected.empty()) throw core::Error("no cluster selected (click a centroid)");
}

void Explorer::expand_selected() {
    require_selected();
    for (std::uint64_t node : std::exchange(s_.selected, {})) expand_node(node, false);
}

void Explorer::hide_selected() {
    require_selected();
    for (std::uint64_t node : std::exchange(s_.selected, {})) std::erase(s_.shown, node);
}

void Explorer::select_only(const std::vector<std::size_t> &ranks) {
    s_.selected.clear();
    for (std::size_t k : ranks) s_.selected.insert(at(k));
}

template <class Keep>
void Explorer::keep_expanded(Keep keep) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < s_.expanded.size(); ++i)
        if (keep(s_.expanded[i])) s_.expanded[n] = s_.expanded[i], s_.expanded_origin[n] = s_.expanded_origin[i], ++n;
    s_.expanded.resize(n), s_.expanded_origin.resize(n);
    expanded_changed();
}

void Explorer::keep_selected(const std::vector<std::uint64_t> &streamlines) {
    std::erase_if(s_.shown, [&](std::uint64_t node) { return !s_.selected.count(node); });
    keep_expanded([&](std::uint64_t s) { return std::binary_search(streamlines.begin(), streamlines.end(), s); });
    s_.selected.clear();
}

void Explorer::drop_selected(const std::vector<std::uint64_t> &streamlines) {
    std::erase_if(s_.shown, [&](std::uint64_t node) { return s_.selected.count(node) != 0; });
    keep_expanded([&](std::uint64_t s) { return !std::binary_search(streamlines.begin(), streamlines.end(), s); });
    s_.selected.clear();
}

void Explorer::expand(std::size_t rank) { expand_node(at(rank), false); }
void Explorer::expand_to_streamlines(std::size_t rank) { expand_node(at(rank), true); }

void Explorer::expand_node(std::uint64_t node, bool to_streamlines) {
    s_.selected.erase(node);
    std::erase(s_.shown, node);
    const auto &t = *s_.tree;
    if (!to_streamlines && t.level[node] < t.nb_levels) {
        // The largest child keeps the parent's colour, the others get new ones.
        std::vector<std::uint64_t> kids = children(node);
        std::erase_if(kids, [&](std::uint64_t k) { return !t.kept(k, spec_); });
        for (std::size_t i = 0; i < kids.size(); ++i) s_.colour[kids[i]] = i == 0 ? s_.colour[node] : s_.next_colour++;
        s_.shown.insert(s_.shown.end(), kids.begin(), kids.end());
    } else {
        add_members({node});
    }
    sort();
}

void Explorer::expand_selected_to_streamlines() {
    require_selected();
    const std::vector<std::uint64_t> nodes(s_.selected.begin(), s_.selected.end());
    s_.selected.clear();
    for (std::uint64_t node : nodes) std::erase(s_.shown, node);
    add_members(nodes);  // (at once: a merge per cluster is seconds at 10M streamlines)
}

void Explorer::add_members(const std::vector<std::uint64_t> &nodes) {
    // (expanded stays ascending: every streamline expanded is the
    // tractogram itself, not a copy)
    const auto &t = *s_.tree;
    const auto &subset = *s_.subset;
    // Each node's origin: its path and colour now.
    auto origins = s_.origins ? std::make_shared<std::vector<Origin>>(*s_.origins) : std::make_shared<std::vector<Origin>>(1);
    std::vector<std::uint32_t> origin_of(nodes.size());
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        origin_of[i] = std::uint32_t(origins->size());
        origins->push_back({path(nodes[i]), s_.colour[nodes[i]]});
    }
    s_.origins = std::move(origins);
    std::uint64_t count = 0;
    for (std::uint64_t node : nodes) count += t.member_offsets[node + 1] - t.member_offsets[node];
    const std::uint64_t N = all_.nb_streamlines();
    if (count * 8 < N) {  // a few: sorted, then merged
        std::vector<std::pair<std::uint64_t, std::uint32_t>> add;
        add.reserve(count);
        for (std::size_t i = 0; i < nodes.size(); ++i)
            for (std::uint64_t m = t.member_offsets[nodes[i]]; m < t.member_offsets[nodes[i] + 1]; ++m)
                add.emplace_back(subset[t.members[m]], origin_of[i]);
        std::sort(add.begin(), add.end());
        std::vector<std::uint64_t> ids;
        std::vector<std::uint32_t> from;
        ids.reserve(s_.expanded.size() + add.size()), from.reserve(s_.expanded.size() + add.size());
        std::size_t a = 0, b = 0;
        while (a < s_.expanded.size() || b < add.size()) {
            if (b == add.size() || (a < s_.expanded.size() && s_.expanded[a] < add[b].first))
                ids.push_back(s_.expanded[a]), from.push_back(s_.expanded_origin[a]), ++a;
            else
                ids.push_back(add[b].first), from.push_back(add[b].second), ++b;
        }
        s_.expanded = std::move(ids), s_.expanded_origin = std::move(from);
    } else {  // many (select all, then X: ten million): marked, then listed in order
        constexpr std::uint32_t kNot = ~std::uint32_t(0);
        std::vector<std::uint32_t> mark(N, kNot);
        for (std::size_t i = 0; i < s_.expanded.size(); ++i) mark[s_.expanded[i]] = s_.expanded_origin[i];
        for (std::size_t i = 0; i < nodes.size(); ++i)
            for (std::uint64_t m = t.member_offsets[nodes[i]]; m < t.member_offsets[nodes[i] + 1]; ++m)
                mark[subset[t.members[m]]] = origin_of[i];
        const std::size_t total = s_.expanded.size() + count;
        s_.expanded.clear(), s_.expanded_origin.clear();
        s_.expanded.reserve(total), s_.expanded_origin.reserve(total);
        for (std::uint64_t s = 0; s < N; ++s)
            if (mark[s] != kNot) s_.expanded.push_back(s), s_.expanded_origin.push_back(mark[s]);
    }
    expanded_changed();
}

void Explorer::hide(std::size_t rank) {
    const std::uint64_t node = at(rank);
    s_.selected.erase(node);
    std::erase(s_.shown, node);
}

core::Bounds Explorer::extent(const std::vector<std::uint64_t> &ids) const {
    core::Bounds b;
    const float *p = all_.positions.data();
    for (std::uint64_t s : ids)
        for (std::uint64_t v = all_.begin(s); v < all_.end(s); ++v)
            for (int i = 0; i < 3; ++i) {
                if (b.empty || p[v * 3 + i] < b.min[i]) b.min[i] = p[v * 3 + i];
                if (b.empty || p[v * 3 + i] > b.max[i]) b.max[i] = p[v * 3 + i];
                if (i == 2) b.empty = false;
            }
    return b;
}

bool Explorer::takes_thresholds() const {
    const core::LoadedPlugin *p = core::find_clustering(reg_, spec_.algorithm);
    if (p == nullptr) return false;
    for (const core::ParamSpec &s : core::schema_of(*p))
        if (s.name == "thresholds" || s.name == "threshold") return true;
    return false;
}

Explorer::Plan Explorer::plan_repeat(std::vector<double> thresholds) const {
    Plan p;
    p.subset = shown_streamlines();
    if (p.subset.empty()) throw core::Error("nothing is shown to cluster again");
    // Scaled thresholds only for a plugin that takes them: any other (the
    // SDK's template among them) runs again on what is shown with the
    // parameters it has (issue 53: repeat failed for every plugin without a
    // `thresholds` parameter).
    if (thresholds.empty() && !s_.thresholds.empty() && all_diagonal() > 0 && takes_thresholds()) {
        // A bundle isolated from a whole brain would be one cluster at the
        // whole brain's thresholds: scale them by its extent.
        const core::Bounds b = extent(p.subset);
        const double scale = std::min(1.0, std::hypot(b.max[0] - b.min[0], b.max[1] - b.min[1], b.max[2] - b.min[2]) / all_diagonal());
        for (double t : s_.thresholds) thresholds.push_back(std::max(1.0, t * scale));
        // Relative to the first clustering's thresholds, not the last ones.
        if (!spec_.thresholds.empty() && spec_.thresholds.size() == thresholds.size())
            for (std::size_t i = 0; i < thresholds.size(); ++i) thresholds[i] = std::max(1.0, spec_.thresholds[i] * scale);
    }
    p.thresholds = std::move(thresholds);
    // Each streamline's colour now, so that the new clusters can keep them.
    p.colour_of.assign(all_.nb_streamlines(), kNoColour);
    const auto &t = *s_.tree;
    for (std::uint64_t node : s_.shown)
        for (std::uint64_t m = t.member_offsets[node]; m < t.member_offsets[node + 1]; ++m)
            p.colour_of[(*s_.subset)[t.members[m]]] = s_.colour[node];
    return p;
}

Explorer::Plan Explorer::plan_reset(const std::vector<std::uint64_t> *ids) const {
    Plan p;
    if (ids)
        p.subset = *ids;
    else {
        p.subset.resize(all_.nb_streamlines());
        std::iota(p.subset.begin(), p.subset.end(), 0);
    }
    p.thresholds = spec_.thresholds;
    return p;
}

void Explorer::repeat(std::vector<double> thresholds) {
    Plan p = plan_repeat(std::move(thresholds));
    auto tree = compute(p.subset, p.thresholds);
    adopt(std::move(p.subset), std::move(tree), &p.colour_of);
}

void Explorer::reset(const std::vector<std::uint64_t> *ids) {
    Plan p = plan_reset(ids);
    auto tree = compute(p.subset, p.thresholds);
    adopt(std::move(p.subset), std::move(tree), nullptr);
}

// QuickBundlesX (fast mode) over the streamlines `subset` of all_; shows
// the first level. With `before` (streamline -> colour id), each new
// cluster, largest first, takes the colour most of its streamlines had,
// unless a larger one took it already; the rest get new colours.
std::shared_ptr<const core::render::ClusterTree> Explorer::compute(const std::vector<std::uint64_t> &subset,
                                                                   const std::vector<double> &thresholds, const hz_task *task) const {
    core::render::ClusterSpec spec = spec_;
    spec.thresholds = thresholds;
    auto tree = std::make_shared<core::render::ClusterTree>();
    // Every streamline (the first clustering): the tractogram itself, not a
    // copy of it (at 1M streamlines, 2 GB).
    const std::uint64_t n = all_.nb_streamlines();
    const bool everything =
        subset.size() == n && n > 0 && subset.front() == 0 && subset.back() == n - 1 &&
        std::adjacent_find(subset.begin(), subset.end(), [](std::uint64_t a, std::uint64_t b) { return b != a + 1; }) == subset.end();
    if (everything)
        *tree = core::render::run_clustering(reg_, all_, spec, task);
    else if (!subset.empty())  // (a large copy in a temporary file's pages: 9M streamlines of 10M are 17 GB)
        *tree = core::render::run_clustering(reg_, core::select_streamlines(all_, subset, /*spill=*/true), spec, task);
    else {
        tree->parent = {-1}, tree->level = {0}, tree->member_offsets = {0, 0};
    }
    return tree;
}

void Explorer::adopt(std::vector<std::uint64_t> subset, std::shared_ptr<const core::render::ClusterTree> tree,
                     const std::vector<std::uint64_t> *before) {
    if (before == nullptr) s_.next_colour = 0;  // (a first clustering)
    s_.names.reset();
    s_.tree = tree;
    s_.thresholds = tree->thresholds;
    s_.subset = std::make_shared<const std::vector<std::uint64_t>>(std::move(subset));
    s_.shown.clear();
    s_.selected.clear();
    s_.expanded.clear(), s_.expanded_origin.clear();
    s_.origins.reset();
    expanded_changed();
    for (std::uint64_t k = 0; k < tree->level.size(); ++k)
        if (tree->level[k] == 1 && tree->kept(k, spec_)) s_.shown.push_back(k);  // (the cut-offs: --cluster-size-min, ...)
    sort();
    s_.colour.assign(tree->level.size(), 0);
    std::set<std::uint64_t> taken;
    for (std::uint64_t node : s_.shown) {
        std::uint64_t pick = s_.next_colour;
        if (before != nullptr) {
            std::map<std::uint64_t, std::uint64_t> votes;
            for (std::uint64_t m = tree->member_offsets[node]; m < tree->member_offsets[node + 1]; ++m)
                if (const std::uint64_t c = (*before)[(*s_.subset)[tree->members[m]]]; c != kNoColour) ++votes[c];
            std::uint64_t best = 0;
            for (const auto &[c, n] : votes)
                if (n > best && !taken.count(c)) best = n, pick = c;
        }
        if (pick == s_.next_colour) ++s_.next_colour;
        taken.insert(pick);
        s_.colour[node] = pick;
    }
    ++s_.rounds;
}

std::vector<std::uint64_t> Explorer::shown_streamlines(std::vector<std::string> *cluster_of) const {
    // (streamline, its path's index + 1: the clusters shown's, then the
    // expanded streamlines' origins'; 0: none)
    std::vector<std::pair<std::uint64_t, std::size_t>> all;
    const auto &t = *s_.tree;
    const std::size_t K = s_.shown.size();
    for (std::size_t i = 0; i < s_.expanded.size(); ++i)
        all.emplace_back(s_.expanded[i], s_.expanded_origin[i] == 0 ? 0 : K + s_.expanded_origin[i]);
    for (std::size_t k = 0; k < K; ++k)
        for (std::uint64_t m = t.member_offsets[s_.shown[k]]; m < t.member_offsets[s_.shown[k] + 1]; ++m)
            all.emplace_back((*s_.subset)[t.members[m]], k + 1);
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end(), [](const auto &a, const auto &b) { return a.first == b.first; }), all.end());
    std::vector<std::uint64_t> ids(all.size());
    std::vector<std::string> paths;
    if (cluster_of) {
        for (std::uint64_t node : s_.shown) paths.push_back(path(node));
        if (s_.origins)
            for (std::size_t o = 1; o < s_.origins->size(); ++o) paths.push_back((*s_.origins)[o].path);
        cluster_of->assign(all.size(), "");
    }
    for (std::size_t i = 0; i < all.size(); ++i) {
        ids[i] = all[i].first;
        if (cluster_of && all[i].second) (*cluster_of)[i] = paths[all[i].second - 1];
    }
    return ids;
}

core::render::Object Explorer::centroids_object() const {
    core::render::Object o;
    o.name = name_ + ": QuickBundlesX centroids";
    o.kind = o.data.kind = HZ_DATA_STREAMLINES;
    core::Tractogram &t = o.data.tractogram;
    const std::uint64_t K = s_.shown.size(), P = s_.tree->nb_points;
    t.positions = core::Buffer<float>(K * P * 3);
    t.offsets = core::Buffer<std::uint64_t>(K + 1);
    std::vector<float> sizes(K), ids(K), picked(K);  // a cluster's colour id, stable while others change
    for (std::uint64_t i = 0; i < K; ++i) {
        std::copy_n(s_.tree->centroids.data() + s_.shown[i] * P * 3, P * 3, t.positions.data() + i * P * 3);
        t.offsets[i] = i * P;
        sizes[i] = float(size(s_.shown[i]));
        ids[i] = float(s_.colour[s_.shown[i]]);
        picked[i] = s_.selected.count(s_.shown[i]) ? 1.0f : 0.0f;
    }
    t.offsets[K] = K * P;
    t.arrays.push_back(core::f32_array("cluster_size", HZ_ATTACH_STREAMLINE, sizes));
    t.arrays.push_back(core::f32_array("cluster_id", HZ_ATTACH_STREAMLINE, ids));
    t.arrays.push_back(core::f32_array("highlight", HZ_ATTACH_STREAMLINE, picked));
    o.render = "tubes";
    o.radius_mm = 1.0;
    o.clustering = spec_;
    o.coloring.mode = "cluster";
    return o;
}

core::render::Object Explorer::streamlines_object() const {
    // Every streamline: the tractogram as it is; else a copy, which a large
    // one keeps in a temporary file's pages rather than anonymous memory
    // (a million streamlines expanded out of ten million: 2 GB).
    // (The bounds: a pass over ten million streamlines' points is seconds
    // of the window's time.)
    if (s_.expanded.size() == all_.nb_streamlines()) return streamlines_object(all_.shared(), all_bounds(), s_.expanded);
    return streamlines_object(core::select_streamlines(all_, s_.expanded, true), core::Bounds{}, s_.expanded);
}

core::render::Object Explorer::streamlines_object(core::Tractogram t, const core::Bounds &bounds,
                                                  const std::vector<std::uint64_t> &ids) const {
    core::render::Object o;
    o.name = name_ + ": expanded streamlines";
    o.kind = o.data.kind = HZ_DATA_STREAMLINES;
    o.data.tractogram = std::move(t);
    o.data.bounds = bounds;
    o.render = "lines";
    o.coloring.mode = "direction";
    // Each by the cluster it came from, in that cluster's colour (as the
    // centroids are drawn), where every one came from one.
    const std::uint64_t n = o.data.tractogram.nb_streamlines();
    if (n == 0 || ids.size() != n || !s_.origins) return o;
    std::vector<float> colour(n);
    for (std::uint64_t i = 0; i < n; ++i) {
        const auto it = std::lower_bound(s_.expanded.begin(), s_.expanded.end(), ids[i]);
        const std::uint32_t from = it != s_.expanded.end() && *it == ids[i] ? s_.expanded_origin[std::size_t(it - s_.expanded.begin())] : 0;
        if (from == 0) return o;
        colour[i] = float((*s_.origins)[from].colour);
    }
    o.data.tractogram.arrays.push_back(core::f32_array("cluster_id", HZ_ATTACH_STREAMLINE, colour));
    o.coloring.mode = "cluster";
    return o;
}

// ----------------------------------------------------------------- Session

Session::Session(const core::Registry &reg, core::Tractogram all, std::vector<std::string> inputs, std::unique_ptr<Explorer> ex)
    : reg_(reg), all_(std::move(all)), inputs_(std::move(inputs)), ex_(std::move(ex)) {
    auto every = std::make_shared<std::vector<std::uint64_t>>(all_.nb_streamlines());
    std::iota(every->begin(), every->end(), 0);
    kept_ = std::move(every);
}

void Session::prepare_index() {
    if (grid_future_.valid() || all_.nb_streamlines() < 100000) return;
    grid_future_ = std::async(std::launch::async, [this] {
                       return std::make_shared<const core::StreamlineGrid>(core::StreamlineGrid::of(all_, 6.0, 1, &grid_cancel_));
                   }).share();
}

Session::~Session() {
    grid_cancel_ = true;  // (the grid build stops early; a selection in progress is waited for)
    if (pending_.valid()) pending_.wait();
    if (grid_future_.valid()) grid_future_.wait();
}

Session::State Session::snapshot() const {
    State s;
    s.rois = rois_;
    s.kept = kept_;
    s.picked = picked_, s.deleted = deleted_;
    if (ex_) s.explore = std::make_unique<Explorer::State>(ex_->state());
    return s;
}

void Session::restore(const State &s) {
    rois_ = s.rois;
    kept_ = s.kept;
    picked_ = s.picked, deleted_ = s.deleted;
    if (ex_ && s.explore) ex_->restore(*s.explore);
}

void Session::record() {
    settle();
    undo_.push_back(snapshot());
    redo_backup_ = std::exchange(redo_, {});
}

void Session::rollback() {
    if (undo_.empty()) return;
    restore(undo_.back());
    undo_.pop_back();
    redo_ = std::exchange(redo_backup_, {});
}

bool Session::undo() {
    settle();
    if (undo_.empty()) return false;
    redo_.push_back(snapshot());
    restore(undo_.back());
    undo_.pop_back();
    return true;
}

bool Session::redo() {
    settle();
    if (redo_.empty()) return false;
    undo_.push_back(snapshot());
    restore(redo_.back());
    redo_.pop_back();
    return true;
}

core::Roi &Session::roi(std::size_t k) {
    if (k >= rois_.size()) throw core::Error("no region " + std::to_string(k) + " (" + std::to_string(rois_.size()) + " placed)");
    return rois_[k];
}

void Session::add_roi(core::Roi r) { rois_.push_back(std::move(r)); }

void Session::move_roi(std::size_t k, const std::array<double, 3> &c) {
    core::Roi &r = roi(k);
    if (r.shape == core::Roi::Shape::Mask) throw core::Error("region " + std::to_string(k) + " is a mask: it cannot move");
    if (r.shape == core::Roi::Shape::Sphere)
        r.center = c;
    else
        for (int i = 0; i < 3; ++i) {
            const double half = (r.hi[i] - r.lo[i]) / 2;
            r.lo[i] = c[i] - half, r.hi[i] = c[i] + half;
        }
}

void Session::resize_roi(std::size_t k, double factor) {
    core::Roi &r = roi(k);
    if (!(factor > 0) || !std::isfinite(factor)) throw core::Error("a region's size factor must be > 0");
    if (r.shape == core::Roi::Shape::Mask) throw core::Error("region " + std::to_string(k) + " is a mask: it cannot be resized");
    if (r.shape == core::Roi::Shape::Sphere)
        r.radius = std::max(0.1, r.radius * factor);
    else
        for (int i = 0; i < 3; ++i) {
            const double c = (r.lo[i] + r.hi[i]) / 2, half = std::max(0.05, (r.hi[i] - r.lo[i]) / 2 * factor);
            r.lo[i] = c - half, r.hi[i] = c + half;
        }
}

void Session::flip_roi(std::size_t k) { roi(k).include = !roi(k).include; }

void Session::remove_roi(std::size_t k) {
    roi(k);
    rois_.erase(rois_.begin() + std::ptrdiff_t(k));
}

std::vector<std::uint64_t> Session::select(const std::vector<core::Roi> &rois, const std::vector<std::uint64_t> &deleted,
                                           const std::shared_future<std::shared_ptr<const core::StreamlineGrid>> &grid_future) const {
    std::vector<std::uint64_t> kept;
    if (rois.empty()) {
        kept.resize(all_.nb_streamlines());
        std::iota(kept.begin(), kept.end(), 0);
    } else {
        std::shared_ptr<const core::StreamlineGrid> grid = grid_future.valid() ? grid_future.get() : nullptr;
        // (the session is closing: its grid was stopped, and a scan without
        // it would take a second a million streamlines; nothing is adopted)
        if (grid_cancel_.load()) return {};
        if (!grid) grid = std::make_shared<const core::StreamlineGrid>(core::StreamlineGrid::of(all_));
        core::FilterSpec f;
        f.rois = rois;
        kept = core::filter_streamlines(all_, f, nullptr, nullptr, grid.get());
    }
    if (!deleted.empty()) std::erase_if(kept, [&](std::uint64_t s) { return std::binary_search(deleted.begin(), deleted.end(), s); });
    return kept;
}

void Session::ensure_grid_future() {
    if (!grid_future_.valid() && !rois_.empty()) {  // (no background build started: one now, on every core, waited for)
        std::promise<std::shared_ptr<const core::StreamlineGrid>> made;
        made.set_value(std::make_shared<const core::StreamlineGrid>(core::StreamlineGrid::of(all_)));
        grid_future_ = made.get_future().share();
    }
}

void Session::start_grid() {
    if (!grid_future_.valid() && !rois_.empty()) {  // (on every core: a selection waits for it)
        grid_future_ = std::async(std::launch::async, [this] {
                           return std::make_shared<const core::StreamlineGrid>(core::StreamlineGrid::of(all_, 6.0, 0, &grid_cancel_));
                       }).share();
    }
}

void Session::apply(bool recluster) {
    settle();
    const auto t0 = std::chrono::steady_clock::now();
    ensure_grid_future();
    std::vector<std::uint64_t> kept = select(rois_, *deleted_, grid_future_);
    if (ex_ && !recluster) {
        adopt_kept(std::move(kept));
        filter_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        return;
    }
    std::shared_ptr<const core::render::ClusterTree> tree = ex_ ? ex_->compute_first(kept) : nullptr;
    adopt(std::move(kept), std::move(tree));
    filter_ms_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void Session::adopt_kept(std::vector<std::uint64_t> kept) {
    kept_ = std::make_shared<const std::vector<std::uint64_t>>(std::move(kept));
    picked_ = std::make_shared<const std::vector<std::uint64_t>>();
}

void Session::adopt(std::vector<std::uint64_t> kept, std::shared_ptr<const core::render::ClusterTree> tree) {
    adopt_kept(std::move(kept));
    if (ex_) ex_->adopt(*kept_, std::move(tree), nullptr);
}

void Session::apply_in_background(bool recluster) {
    settle();
    const auto t0 = std::chrono::steady_clock::now();
    start_grid();
    pending_ = std::async(std::launch::async, [this, rois = rois_, deleted = deleted_, grid = grid_future_, t0, recluster] {
        Pending p;
        p.kept = select(rois, *deleted, grid);
        p.keep_clusters = ex_ && !recluster;
        if (ex_ && recluster) {
            Progress progress("clustering " + std::to_string(p.kept.size()) + " streamlines", true);
            p.tree = ex_->compute_first(p.kept, progress.task());
            (void)ex_->all_bounds();  // (measured here, the first time, rather than at the first repeat)
        }
        p.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        return p;
    });
}

void Session::recluster_in_background(std::vector<double> thresholds, bool reset) {
    settle();
    if (!ex_) throw core::Error("nothing is being explored");
    if (!reset && !ex_->anything_shown()) throw core::Error("nothing is shown to cluster again");
    const auto t0 = std::chrono::steady_clock::now();
    pending_ = std::async(std::launch::async, [this, thresholds = std::move(thresholds), reset, kept = kept_, t0] {
        Pending p;
        p.plan = std::make_unique<Explorer::Plan>(reset ? ex_->plan_reset(kept.get()) : ex_->plan_repeat(thresholds));
        Progress progress("clustering " + std::to_string(p.plan->subset.size()) + " streamlines", true);
        p.tree = ex_->compute(p.plan->subset, p.plan->thresholds, progress.task());
        p.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        return p;
    });
}

void Session::restore_in_background(std::vector<std::int64_t> label, std::vector<std::string> names) {
    settle();
    if (!ex_) throw core::Error("nothing is being explored");
    const auto t0 = std::chrono::steady_clock::now();
    start_grid();
    pending_ = std::async(std::launch::async, [this, label = std::move(label), names = std::move(names), rois = rois_, deleted = deleted_,
                                               grid = grid_future_, t0] {
        Pending p;
        {
            Progress progress("restoring " + std::to_string(names.size()) + " saved clusters", true);
            p.saved = std::make_unique<Explorer::Saved>(ex_->compute_saved(label, names, progress.task()));
        }
        p.selected = !rois.empty();
        if (p.selected) p.kept = select(rois, *deleted, grid), p.keep_clusters = true;
        p.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        return p;
    });
}

bool Session::stop() {
    if (!pending_.valid()) return false;
    cancel_progress();
    try {
        (void)pending_.get();
        return false;
    } catch (const std::exception &) {  // (the plugin's "cancelled")
        return true;
    }
}

bool Session::selecting() const { return pending_.valid(); }

bool Session::poll() {
    if (!pending_.valid() || pending_.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
    settle();
    return true;
}

void Session::settle() {
    if (!pending_.valid()) return;
    try {
        Pending p = pending_.get();
        if (p.saved) ex_->adopt_saved(std::move(*p.saved));
        if (!p.selected) return;
        if (p.plan) {
            ex_->adopt(std::move(p.plan->subset), std::move(p.tree), p.plan->colour_of.empty() ? nullptr : &p.plan->colour_of);
            return;
        }
        if (p.keep_clusters)
            adopt_kept(std::move(p.kept));
        else
            adopt(std::move(p.kept), std::move(p.tree));
        filter_ms_ = p.ms;
    } catch (const std::exception &e) {  // (the selection shown stays the last one made)
        std::fprintf(stderr, "horizon: the selection or clustering failed: %s\n", e.what());
    }
}

void Session::pick(std::vector<std::uint64_t> ids) {
    settle();
    std::sort(ids.begin(), ids.end());
    std::vector<std::uint64_t> expanded, out;
    if (ex_) {  // (kept_ is ascending; the expanded streamlines are in the order they were expanded)
        expanded = ex_->expanded();
        std::sort(expanded.begin(), expanded.end());
    }
    const std::vector<std::uint64_t> &pool = ex_ ? expanded : *kept_;
    std::set_intersection(ids.begin(), ids.end(), pool.begin(), pool.end(), std::back_inserter(out));
    picked_ = std::make_shared<const std::vector<std::uint64_t>>(std::move(out));
}

void Session::require_picked() const {
    if (ex_ ? picked_->empty() && ex_->nb_selected() == 0 : picked_->empty())
        throw core::Error(ex_ ? "nothing picked (draw a stroke across streamlines or centroids: Ctrl+drag)"
                              : "nothing picked (draw a stroke across streamlines: Ctrl+drag)");
}

void Session::delete_shown(const std::vector<std::uint64_t> &gone) {
    std::vector<std::uint64_t> kept, deleted;
    std::set_difference(kept_->begin(), kept_->end(), gone.begin(), gone.end(), std::back_inserter(kept));
    std::set_union(deleted_->begin(), deleted_->end(), gone.begin(), gone.end(), std::back_inserter(deleted));
    deleted_ = std::make_shared<const std::vector<std::uint64_t>>(std::move(deleted));
    kept_ = std::make_shared<const std::vector<std::uint64_t>>(std::move(kept));
    picked_ = std::make_shared<const std::vector<std::uint64_t>>();
}

void Session::keep_picked() {
    require_picked();
    if (ex_) {
        ex_->keep_selected(*picked_);
        picked_ = std::make_shared<const std::vector<std::uint64_t>>();
        return;
    }
    std::vector<std::uint64_t> others;
    std::set_difference(kept_->begin(), kept_->end(), picked_->begin(), picked_->end(), std::back_inserter(others));
    delete_shown(others);
}

void Session::delete_picked() {
    require_picked();
    if (ex_) {
        ex_->drop_selected(*picked_);
        picked_ = std::make_shared<const std::vector<std::uint64_t>>();
        return;
    }
    delete_shown(*picked_);
}

void Session::invert_picked() {
    std::vector<std::uint64_t> pool = ex_ ? ex_->expanded() : *kept_, out;
    std::sort(pool.begin(), pool.end());
    std::set_difference(pool.begin(), pool.end(), picked_->begin(), picked_->end(), std::back_inserter(out));
    picked_ = std::make_shared<const std::vector<std::uint64_t>>(std::move(out));
    if (ex_) {
        std::vector<std::size_t> others;
        for (std::size_t k = 0; k < ex_->shown().size(); ++k)
            if (!ex_->is_selected(k)) others.push_back(k);
        ex_->select_only(others);
    }
}

std::vector<std::uint64_t> Session::shown(std::vector<std::string> *cluster_of) const {
    if (ex_) return ex_->shown_streamlines(cluster_of);
    if (cluster_of) cluster_of->assign(kept_->size(), "");
    return *kept_;
}

Session::SaveJob Session::prepare_save(const std::string &path, bool force) {
    settle();
    check_outputs({path}, inputs_, force);
    core::loader_for_write(reg_, path);
    std::vector<std::string> cluster_of;
    SaveJob job;
    job.ids = shown(&cluster_of);
    const std::vector<std::uint64_t> &ids = job.ids;
    core::Dataset &out = job.out;
    out.kind = HZ_DATA_STREAMLINES;
    // The whole tractogram and the streamlines shown (increasing): the
    // writer reads those where they lie (hz.ext.write-selection/1), or
    // write_dataset copies them out first (bounded memory whatever is saved).
    // The arrays added here are indexed like the whole tractogram too.
    out.tractogram = all_.shared();
    // Clusters: a TRX group per cluster shown (named by its path, which
    // TRX names cannot hold dots of), and each streamline's group index as
    // per-streamline data (-1: a streamline in no cluster). An expanded
    // streamline keeps the path of the cluster it was expanded from.
    std::vector<std::string> names;
    std::map<std::string, std::vector<std::uint64_t>> members;  // (renumbered to the file's streamlines as they are written)
    std::vector<std::int32_t> label(ex_ ? all_.nb_streamlines() : 0, -1);
    for (std::size_t i = 0; i < ids.size(); ++i)
        if (!cluster_of[i].empty()) {
            auto [it, added] = members.try_emplace(cluster_of[i]);
            if (added) names.push_back(cluster_of[i]);
            it->second.push_back(ids[i]);
        }
    std::sort(names.begin(), names.end(),
              [&](const std::string &a, const std::string &b) { return members[a].size() > members[b].size(); });
    for (std::size_t g = 0; g < names.size(); ++g) {
        for (std::uint64_t s : members[names[g]]) label[s] = std::int32_t(g);
        std::string gname = names[g];
        std::replace(gname.begin(), gname.end(), '.', '_');
        core::DataArray a{gname, HZ_ATTACH_GROUP,          HZ_DTYPE_U64,
                          1,     members[names[g]].size(), core::Buffer<std::byte>(members[names[g]].size() * 8)};
        std::memcpy(a.bytes.data(), members[names[g]].data(), members[names[g]].size() * 8);
        out.tractogram.arrays.push_back(std::move(a));
    }
    if (ex_) {
        core::DataArray a{
            "horizon_cluster", HZ_ATTACH_STREAMLINE, HZ_DTYPE_I32, 1, label.size(), core::Buffer<std::byte>(label.size() * 4)};
        std::memcpy(a.bytes.data(), label.data(), label.size() * 4);
        out.tractogram.arrays.push_back(std::move(a));
    }
    nlohmann::json rois = nlohmann::json::array();
    for (const core::Roi &r : rois_) rois.push_back({{"spec", r.spec()}, {"include", r.include}});
    out.metadata.emplace_back("horizon_source", inputs_.empty() ? std::string() : inputs_[0]);
    out.metadata.emplace_back("horizon_rois", rois.dump());
    if (ex_) out.metadata.emplace_back("horizon_clusters", nlohmann::json(names).dump());
    job.path = path;
    job.force = force;
    job.protect = inputs_.empty() ? std::string() : inputs_[0];
    job.line = "saved " + std::to_string(ids.size()) + " streamlines";
    if (ex_) job.line += " in " + std::to_string(names.size()) + " clusters";
    job.line += ", " + std::to_string(rois_.size()) + " regions -> " + path;
    return job;
}

std::string Session::write_save(SaveJob &job) const {
    std::vector<std::string> dropped;
    core::write_dataset(reg_, job.out, job.path, job.force, &dropped, job.protect, nullptr, &job.ids);
    std::string line = job.line;
    for (const auto &d : dropped) line += " (dropped " + d + ")";
    return line;
}

std::vector<core::Roi> Session::rois_from_metadata(const core::Registry &reg,
                                                   const std::vector<std::pair<std::string, std::string>> &metadata) {
    std::vector<core::Roi> out;
    for (const auto &[k, v] : metadata) {
        if (k != "horizon_rois") continue;
        const nlohmann::json j = nlohmann::json::parse(v, nullptr, false);
        if (!j.is_array()) throw core::Error("horizon_rois: not a JSON list");
        for (const auto &e : j) {
            if (!e.is_object() || !e.contains("spec") || !e["spec"].is_string()) throw core::Error("horizon_rois: an entry without a spec");
            out.push_back(core::parse_roi(reg, e["spec"].get<std::string>(), e.value("include", true)));
        }
    }
    return out;
}

core::Tractogram Session::roi_wires(bool include) const {
    std::vector<float> pts;
    std::vector<std::uint64_t> offs{0};
    auto add_line = [&](const std::vector<std::array<double, 3>> &line) {
        for (const auto &p : line) pts.insert(pts.end(), {float(p[0]), float(p[1]), float(p[2])});
        offs.push_back(pts.size() / 3);
    };
    for (const core::Roi &r : rois_) {
        if (r.include != include) continue;
        const core::Bounds b = r.bounds();
        if (r.shape == core::Roi::Shape::Sphere) {
            for (int axis = 0; axis < 3; ++axis) {
                std::vector<std::array<double, 3>> circle;
                for (int k = 0; k <= 48; ++k) {
                    const double a = 2 * M_PI * k / 48;
                    std::array<double, 3> p = r.center;
                    p[(axis + 1) % 3] += r.radius * std::cos(a);
                    p[(axis + 2) % 3] += r.radius * std::sin(a);
                    circle.push_back(p);
                }
                add_line(circle);
            }
        } else {  // a box, or a mask's bounds
            const auto &lo = r.shape == core::Roi::Shape::Box ? r.lo : b.min;
            const auto &hi = r.shape == core::Roi::Shape::Box ? r.hi : b.max;
            for (int axis = 0; axis < 3; ++axis)
                for (int c = 0; c < 4; ++c) {
                    std::array<double, 3> p0, p1;
                    const int u = (axis + 1) % 3, w = (axis + 2) % 3;
                    p0[axis] = lo[axis], p1[axis] = hi[axis];
                    p0[u] = p1[u] = (c & 1) ? hi[u] : lo[u];
                    p0[w] = p1[w] = (c & 2) ? hi[w] : lo[w];
                    add_line({p0, p1});
                }
        }
    }
    core::Tractogram t;
    t.positions = core::Buffer<float>::copy_of(pts);
    t.offsets = core::Buffer<std::uint64_t>::copy_of(offs);
    return t;
}

std::string Session::summary() const {
    std::string s = std::to_string(rois_.size()) + " regions, " + std::to_string(kept_->size()) + " of " +
                    std::to_string(all_.nb_streamlines()) + " streamlines selected, " + std::to_string(picked_->size()) + " picked, " +
                    std::to_string(deleted_->size()) + " deleted";
    for (std::size_t k = 0; k < rois_.size(); ++k)
        s += "; #" + std::to_string(k) + " " + (rois_[k].include ? "include " : "exclude ") + rois_[k].spec();
    return s;
}

}  // namespace hz::host
