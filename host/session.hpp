// The window's editing session: the exploration of the paper's Fig. 5
// (Explorer), regions of interest that select streamlines (the rules of
// `horizon filter`), undo / redo of every edit, and saving what is shown.
// GL-free: the window (view.cpp) turns what it holds into scene objects.
#pragma once

#include <hz/core/filter.hpp>
#include <hz/core/render/scene.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <future>
#include <map>
#include <mutex>
#include <memory>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

namespace hz::host {

// QuickBundlesX exploration of a tractogram: shown as the centroids of one
// level (tubes, width by cluster size); "expand" replaces a centroid by its
// children at the next level, or by its streamlines at the last (or straight
// by its streamlines: expand_to_streamlines); "hide" removes a cluster;
// "repeat" re-clusters what is still shown, with thresholds fitted to its
// extent. Every clustering covers a set of streamlines of the tractogram
// (all of them, or what the regions of interest select).
//
// A cluster is named by its path in the tree: "c2.1" is the first child
// (largest first) of the second largest cluster of level 1. Paths do not
// change while clusters are expanded and hidden; a new clustering (repeat,
// regions) gives new ones.
class Explorer {
public:
    // Where expanded streamlines came from: the cluster's path ("c1.3", or a
    // saved name) and its palette entry when it was expanded.
    struct Origin {
        std::string path;
        std::uint64_t colour = 0;
    };
    // Everything an edit changes (what undo restores). Copies share the tree.
    struct State {
        std::shared_ptr<const core::render::ClusterTree> tree;
        std::shared_ptr<const std::vector<std::uint64_t>> subset;  // the streamlines clustered (tree members index it; shared by copies)
        std::vector<std::uint64_t> shown;                          // tree nodes shown, largest first
        std::vector<std::uint64_t> expanded;                       // streamlines shown on their own (ascending)
        // Per expanded streamline (parallel to `expanded`): the cluster it was
        // expanded from, an index into `origins` (0: none, e.g. a saved
        // streamline that was in no cluster).
        std::vector<std::uint32_t> expanded_origin;
        std::shared_ptr<const std::vector<Origin>> origins;  // [0]: none (shared by copies; appended to on expansion)
        std::set<std::uint64_t> selected;                    // tree nodes, all shown
        std::vector<std::uint64_t> colour;                   // per tree node: its palette entry
        std::uint64_t next_colour = 0;
        int rounds = 0;
        std::vector<double> thresholds;                         // of the last clustering (mm per level)
        std::shared_ptr<const std::vector<std::string>> names;  // per tree node: a saved name (restore_saved), or none
        std::uint64_t expanded_id = 0;                          // a new one whenever `expanded` changes (never reused by this Explorer)
    };

    // Clusters every streamline at once unless `cluster_now` is false: then
    // nothing is clustered (no cluster shown) until restore_saved, reset or
    // adopt (Session::apply_in_background). `bounds`: those of every point
    // of `all`, when known (a loader's), else measured when first needed.
    Explorer(const core::Registry &reg, core::Tractogram all, std::string name, core::render::ClusterSpec spec, bool cluster_now = true,
             core::Bounds bounds = {});
    Explorer(const Explorer &) = delete;
    Explorer &operator=(const Explorer &) = delete;
    // The clusters a selection was saved with (Session::prepare_save): per
    // streamline its cluster's index into `names` (-1: a streamline shown on
    // its own), one cluster per name, each drawn as the centroid the
    // clustering plugin gives its streamlines (at most kCentroidSample of
    // them) at a threshold that keeps them together. Expanding a saved
    // cluster shows its streamlines.
    void restore_saved(const std::vector<std::int64_t> &label, const std::vector<std::string> &names) {
        adopt_saved(compute_saved(label, names));
    }
    // The same in two steps: the clusters' tree and centroids (any thread;
    // reads only the tractogram; `task`, may be null, gets the progress and
    // may cancel: then Error), then adopted. At 1M streamlines the first
    // takes about 2 s (each cluster's centroid is a run of the plugin).
    struct Saved {
        std::shared_ptr<const core::render::ClusterTree> tree;
        std::vector<std::uint64_t> subset, alone;
        std::vector<std::string> names;
    };
    Saved compute_saved(const std::vector<std::int64_t> &label, const std::vector<std::string> &names, const hz_task *task = nullptr) const;
    // The streamlines a saved cluster's centroid is computed from, at most
    // (evenly spaced through it; the centroid is a mean of them, drawn).
    static constexpr std::uint64_t kCentroidSample = 20000;
    void adopt_saved(Saved saved);

    const core::Tractogram &all() const { return all_; }
    const State &state() const { return s_; }
    void restore(State s) { s_ = std::move(s); }
    const std::vector<std::uint64_t> &shown() const { return s_.shown; }
    std::uint64_t size(std::uint64_t node) const { return s_.tree->size(node); }
    std::uint32_t level(std::uint64_t node) const { return s_.tree->level[node]; }
    std::uint64_t colour(std::uint64_t node) const { return s_.colour[node]; }
    std::string path(std::uint64_t node) const;
    std::string summary() const;
    bool is_selected(std::size_t rank) const { return s_.selected.count(at(rank)) != 0; }
    std::size_t nb_selected() const { return s_.selected.size(); }
    // The rank of a cluster given as a rank ("3") or a path ("c2.1"); throws Error.
    std::size_t rank_of(const std::string &what) const;

    void toggle(std::size_t rank);
    void select_all();
    void expand_selected();
    void hide_selected();
    // Selects exactly the clusters shown at `ranks` (a stroke's crossings).
    void select_only(const std::vector<std::size_t> &ranks);
    // Hides every cluster not selected and keeps, of the expanded
    // streamlines, those in `streamlines` (ascending): what a stroke crossed.
    void keep_selected(const std::vector<std::uint64_t> &streamlines);
    // Hides the selected clusters and drops the expanded streamlines in
    // `streamlines` (ascending).
    void drop_selected(const std::vector<std::uint64_t> &streamlines);
    const std::vector<std::uint64_t> &expanded() const { return s_.expanded; }  // (ascending)
    // Equal ids: the same expanded streamlines (the window rebuilds their
    // object, which may hold millions, only when this changes).
    std::uint64_t expanded_id() const { return s_.expanded_id; }
    void expand(std::size_t rank);
    void expand_to_streamlines(std::size_t rank);
    // Every selected cluster shown as its streamlines (X); throws Error when
    // none is selected.
    void expand_selected_to_streamlines();
    void hide(std::size_t rank);
    // Clusters again what is shown; thresholds (mm per level) given, or
    // when empty the last ones scaled by the extent of what is shown
    // against the whole tractogram's (at least 1 mm each).
    void repeat(std::vector<double> thresholds = {});
    // The first clustering of `ids` (every streamline when null).
    void reset(const std::vector<std::uint64_t> *ids = nullptr);
    // What repeat or reset clusters: the streamlines, the thresholds, and
    // for a repeat each streamline's colour now (per streamline of all(),
    // kNoColour where none) for the new clusters to keep; empty for a
    // reset (new colours). Any thread, while nothing edits the
    // exploration; plan_repeat throws Error when nothing is shown.
    struct Plan {
        std::vector<std::uint64_t> subset;
        std::vector<double> thresholds;
        std::vector<std::uint64_t> colour_of;
    };
    static constexpr std::uint64_t kNoColour = ~std::uint64_t(0);
    // The clustering plugin has a thresholds (or threshold) parameter.
    bool takes_thresholds() const;
    Plan plan_repeat(std::vector<double> thresholds) const;
    Plan plan_reset(const std::vector<std::uint64_t> *ids) const;
    bool anything_shown() const { return !s_.shown.empty() || !s_.expanded.empty(); }
    // The same in two steps: the tree (any thread; reads only the
    // tractogram; `task`, may be null, gets the progress and may cancel:
    // then Error), then adopted (colours from `before`, a Plan's colour_of,
    // where given, as repeat does; new ones otherwise).
    std::shared_ptr<const core::render::ClusterTree> compute(const std::vector<std::uint64_t> &subset,
                                                             const std::vector<double> &thresholds, const hz_task *task = nullptr) const;
    std::shared_ptr<const core::render::ClusterTree> compute_first(const std::vector<std::uint64_t> &subset,
                                                                   const hz_task *task = nullptr) const {
        return compute(subset, spec_.thresholds, task);
    }
    // The whole tractogram's bounding box (its diagonal scales a repeat's
    // thresholds; the object of every streamline expanded is given it):
    // the constructor's, or measured once, on the first call (any thread; a
    // pass over every point: seconds at 10M streamlines).
    const core::Bounds &all_bounds() const;
    double all_diagonal() const;
    void adopt(std::vector<std::uint64_t> subset, std::shared_ptr<const core::render::ClusterTree> tree,
               const std::vector<std::uint64_t> *before);

    // The streamlines shown (clusters' members and expanded ones), ascending,
    // and for each its cluster's path: an expanded streamline's is the path
    // of the cluster it was expanded from ("" if none).
    std::vector<std::uint64_t> shown_streamlines(std::vector<std::string> *cluster_of = nullptr) const;

    core::render::Object centroids_object() const;
    // The expanded streamlines' object: of expanded() (the tractogram itself
    // when every streamline is expanded, else a copy), or drawing `t`, the
    // streamlines expanded() at some time, copied on another thread
    // (`bounds`: t's when known, else empty; `ids`: the streamlines t holds).
    // Coloured by the cluster each came from (its colour then, as a
    // per-streamline "cluster_id"), or by direction where one came from none.
    core::render::Object streamlines_object() const;
    core::render::Object streamlines_object(core::Tractogram t, const core::Bounds &bounds, const std::vector<std::uint64_t> &ids) const;

private:
    std::uint64_t at(std::size_t rank) const;
    void sort();
    std::vector<std::uint64_t> children(std::uint64_t node) const;
    void expand_node(std::uint64_t node, bool to_streamlines);
    void require_selected() const;  // throws Error when no cluster is selected
    // Adds the members of `nodes` to expanded (kept ascending), each with
    // its node as its origin.
    void add_members(const std::vector<std::uint64_t> &nodes);
    // Keeps the expanded streamlines for which keep(streamline) is true (and their origins).
    template <class Keep>
    void keep_expanded(Keep keep);
    void expanded_changed() { s_.expanded_id = ++last_expanded_id_; }
    core::Bounds extent(const std::vector<std::uint64_t> &ids) const;

    const core::Registry &reg_;
    core::Tractogram all_;
    std::string name_;
    core::render::ClusterSpec spec_;
    mutable std::once_flag bounds_once_;
    mutable core::Bounds all_bounds_;
    State s_;
    std::uint64_t last_expanded_id_ = 0;
};

// Regions of interest over one tractogram, with undo / redo and saving.
// Either plain (the window shows the streamlines the regions select) or
// over an Explorer (the regions select what is clustered).
class Session {
public:
    struct State {
        std::vector<core::Roi> rois;
        std::shared_ptr<const std::vector<std::uint64_t>> kept;  // what the regions select, less the deleted (ascending; shared by copies)
        std::shared_ptr<const std::vector<std::uint64_t>> picked, deleted;  // a stroke's streamlines; those deleted by hand
        std::unique_ptr<Explorer::State> explore;
        State() = default;
        State(const State &o)
            : rois(o.rois),
              kept(o.kept),
              picked(o.picked),
              deleted(o.deleted),
              explore(o.explore ? std::make_unique<Explorer::State>(*o.explore) : nullptr) {}
        State &operator=(const State &o) {
            rois = o.rois, kept = o.kept, picked = o.picked, deleted = o.deleted;
            explore = o.explore ? std::make_unique<Explorer::State>(*o.explore) : nullptr;
            return *this;
        }
    };

    // `inputs` name the files the window opened (saving never replaces
    // one); `ex` (may be null) is the exploration over `all`.
    Session(const core::Registry &reg, core::Tractogram all, std::vector<std::string> inputs, std::unique_ptr<Explorer> ex);
    ~Session();
    Session(const Session &) = delete;
    Session &operator=(const Session &) = delete;

    Explorer *explorer() { return ex_.get(); }
    const core::Tractogram &all() const { return all_; }
    const std::vector<core::Roi> &rois() const { return rois_; }
    const std::vector<std::uint64_t> &kept() const { return *kept_; }
    // The same list, shared (it never changes: an edit makes a new one).
    std::shared_ptr<const std::vector<std::uint64_t>> kept_shared() const { return kept_; }
    double last_filter_ms() const { return filter_ms_; }

    // Every edit: record() before it (the state undo returns to); an edit
    // that failed half-way: rollback() (back to the recorded state, which
    // leaves the undo and redo lists as they were).
    void record();
    void rollback();
    bool undo();
    bool redo();
    std::size_t undo_depth() const { return undo_.size(); }

    // Region edits (then apply()). k: the region's index; throws Error.
    void add_roi(core::Roi r);
    void move_roi(std::size_t k, const std::array<double, 3> &centre);
    void resize_roi(std::size_t k, double factor);
    void flip_roi(std::size_t k);
    void remove_roi(std::size_t k);
    // Starts building the spatial index in the background (one thread),
    // for a tractogram of 100k streamlines or more: the window calls it a
    // second after its first frame, so that the first region placed does
    // not wait for it (without it, the first region builds it).
    void prepare_index();
    // Selects the streamlines the regions keep and, over an exploration,
    // clusters them again (the first clustering of the selection) unless
    // `recluster` is false (the exploration's clusters stay: a saved file
    // reopened with its clusters).
    void apply(bool recluster = true);
    // The same on a thread of its own (the window stays interactive):
    // poll() adopts the result once it is there (true then: show it
    // again); settle() waits for it. Every other call that reads or edits
    // the selection settles first. Over an exploration the clustering runs
    // behind a Progress ("clustering N streamlines"): current_progress()
    // shows it, and stop() or cancel_progress() stops it (the selection
    // then stays the last one made). `recluster`: as apply's.
    void apply_in_background(bool recluster = true);
    // Explorer::repeat (`thresholds` as there) or, with `reset`,
    // Explorer::reset of what the regions select, the same way: on a
    // thread of its own, poll() adopts, stop() stops it. Throws Error when
    // nothing is shown to cluster again.
    void recluster_in_background(std::vector<double> thresholds, bool reset);
    // Explorer::restore_saved (`label`, `names` as there), then, when there
    // are regions, apply(false), the same way: on a thread of its own behind
    // a Progress ("restoring N saved clusters"), poll() adopts, stop() stops
    // it (nothing is then clustered: Reset clusters again).
    void restore_in_background(std::vector<std::int64_t> label, std::vector<std::string> names);
    // Waits until the spatial index is built (started if it was not).
    void wait_for_index() {
        if (!grid_future_.valid()) prepare_index();
        if (grid_future_.valid()) grid_future_.wait();
    }
    // The spatial index when it is built (nullptr while it is not).
    const core::StreamlineGrid *grid_if_ready() const {
        return grid_future_.valid() && grid_future_.wait_for(std::chrono::seconds(0)) == std::future_status::ready
                   ? grid_future_.get().get()
                   : nullptr;
    }
    bool poll();
    void settle();
    // Stops the selection or clustering in progress (cancel_progress: the
    // clustering plugin sees its task cancelled) and waits for it; true
    // when it stopped before its end (nothing is adopted either way).
    bool stop();
    bool selecting() const;

    // Streamline selection by a stroke across the view. pick: the shown
    // streamlines among `ids` become the picked ones (over an exploration:
    // the expanded streamlines; its clusters are picked with
    // Explorer::select_only). keep_picked: everything shown but what is
    // picked is deleted (over an exploration: the clusters not selected are
    // hidden); delete_picked: what is picked is deleted (or hidden);
    // invert_picked: the other shown streamlines become the picked ones.
    // Deleted streamlines stay out of the selection whatever the regions do
    // (until undone).
    const std::vector<std::uint64_t> &picked() const { return *picked_; }
    std::uint64_t nb_deleted() const { return deleted_->size(); }
    void pick(std::vector<std::uint64_t> ids);
    void keep_picked();
    void delete_picked();
    void invert_picked();

    // The streamlines shown now: kept (plain) or the exploration's.
    std::vector<std::uint64_t> shown(std::vector<std::string> *cluster_of = nullptr) const;
    // Writes what is shown to `path` (any streamline format; TRX holds a
    // group per shown cluster, the cluster paths as per-streamline data and
    // the regions in its header). Never over the input. Returns one line.
    // In two parts, so that a window writes on a thread: prepare_save()
    // takes what is shown now (and checks the target) on the calling
    // thread; write_save() writes it, on any thread, reading nothing of the
    // session but its tractogram, which never changes.
    struct SaveJob {
        core::Dataset out;               // the whole tractogram, with arrays indexed like it
        std::vector<std::uint64_t> ids;  // the streamlines shown, increasing
        std::string path, protect, line;
        bool force = false;
    };
    SaveJob prepare_save(const std::string &path, bool force);
    std::string write_save(SaveJob &job) const;
    // The regions found in a saved file's metadata ("horizon_rois"): what
    // reopening it restores.
    static std::vector<core::Roi> rois_from_metadata(const core::Registry &reg,
                                                     const std::vector<std::pair<std::string, std::string>> &metadata);

    // The regions as wire figures (three great circles a sphere, twelve
    // edges a box): include regions, then exclude ones.
    core::Tractogram roi_wires(bool include) const;
    std::string summary() const;

private:
    State snapshot() const;
    std::vector<std::uint64_t> select(const std::vector<core::Roi> &rois, const std::vector<std::uint64_t> &deleted,
                                      const std::shared_future<std::shared_ptr<const core::StreamlineGrid>> &grid) const;
    // The selection `kept`, nothing picked; adopt: over an exploration,
    // clustered as `tree` too.
    void adopt_kept(std::vector<std::uint64_t> kept);
    void adopt(std::vector<std::uint64_t> kept, std::shared_ptr<const core::render::ClusterTree> tree);
    void ensure_grid_future();
    // Throws Error when a stroke has picked nothing (no cluster selected either).
    void require_picked() const;
    // Plain view: the streamlines `gone` (ascending, among those shown) leave
    // the selection and join the deleted ones; nothing stays picked.
    void delete_shown(const std::vector<std::uint64_t> &gone);
    void restore(const State &s);
    core::Roi &roi(std::size_t k);
    void start_grid();  // the regions' spatial index, on a thread, if not started yet

    const core::Registry &reg_;
    core::Tractogram all_;
    std::vector<std::string> inputs_;
    std::unique_ptr<Explorer> ex_;
    // The spatial index (prepare_index, or the first region).
    std::atomic<bool> grid_cancel_{false};
    std::shared_future<std::shared_ptr<const core::StreamlineGrid>> grid_future_;
    // A selection in progress (apply_in_background).
    struct Pending {
        std::vector<std::uint64_t> kept;
        std::shared_ptr<const core::render::ClusterTree> tree;
        double ms = 0;
        std::unique_ptr<Explorer::Plan> plan;    // (a repeat or reset: the selection stays)
        bool keep_clusters = false;              // (apply_in_background(false): the exploration stays)
        std::unique_ptr<Explorer::Saved> saved;  // (restore_in_background; `kept` too if `selected`)
        bool selected = true;
    };
    std::future<Pending> pending_;
    std::vector<core::Roi> rois_;
    std::shared_ptr<const std::vector<std::uint64_t>> kept_;  // (undo's copies share it)
    std::shared_ptr<const std::vector<std::uint64_t>> picked_ = std::make_shared<const std::vector<std::uint64_t>>();
    std::shared_ptr<const std::vector<std::uint64_t>> deleted_ = std::make_shared<const std::vector<std::uint64_t>>();
    double filter_ms_ = 0;
    std::vector<State> undo_, redo_, redo_backup_;
};

}  // namespace hz::host
