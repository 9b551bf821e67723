// `horizon filter`: streamline selection by include / exclude regions
// (spheres, boxes, mask volumes) and length, for batch quality control; the
// semantics are MRtrix3 tckedit's (core/filter.hpp says where they differ).
#include "commands.hpp"
#include "progress.hpp"

#include <hz/core/filter.hpp>
#include <hz/core/io.hpp>
#include <hz/core/io.hpp>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <optional>

namespace hz::host {

namespace {

std::string bounds_text(const core::Bounds &b) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "[%.1f, %.1f] x [%.1f, %.1f] x [%.1f, %.1f] mm", b.min[0], b.max[0], b.min[1], b.max[1], b.min[2],
                  b.max[2]);
    return buf;
}

bool disjoint(const core::Bounds &a, const core::Bounds &b) {
    for (int i = 0; i < 3; ++i)
        if (a.max[i] < b.min[i] || b.max[i] < a.min[i]) return true;
    return false;
}

}  // namespace

int cmd_filter(const GlobalOptions &g, const FilterOptions &o) {
    const core::Registry reg = load_registry(g);
    if (o.min_length < 0 || o.max_length < 0) throw core::Error("--min-length and --max-length must be >= 0");
    if (o.max_length > 0 && o.min_length > o.max_length)
        throw core::Error("--min-length " + std::to_string(o.min_length) + " is above --max-length " + std::to_string(o.max_length));
    // Every input named (masks included) and every output checked before any work.
    std::vector<std::string> inputs{o.input};
    for (const auto *list : {&o.include, &o.exclude})
        for (const std::string &s : *list)
            if (s.rfind("sphere:", 0) != 0 && s.rfind("box:", 0) != 0) inputs.push_back(s);
    check_outputs({o.out, o.ids}, inputs, o.force);
    if (!o.out.empty()) core::loader_for_write(reg, o.out);
    if (o.out.empty() && o.ids.empty()) throw core::Error("nothing to write: give -o OUT (a tractogram) or --ids FILE");

    core::FilterSpec spec;
    for (const std::string &s : o.include) spec.rois.push_back(core::parse_roi(reg, s, true));
    for (const std::string &s : o.exclude) spec.rois.push_back(core::parse_roi(reg, s, false));
    spec.min_length = o.min_length;
    if (o.max_length > 0) spec.max_length = o.max_length;
    spec.ends_only = o.ends_only;
    spec.invert = o.invert;

    const auto t0 = std::chrono::steady_clock::now();
    std::optional<Progress> reading(std::in_place, "reading " + o.input, !o.json);
    const core::Dataset ds = core::read_dataset(reg, o.input, reading->task());
    reading.reset();
    if (ds.kind != HZ_DATA_STREAMLINES)
        throw core::Error(o.input + ": a " + std::string(core::kind_name(ds.kind)) + " file; filter selects streamlines");
    const core::Tractogram &t = ds.tractogram;
    // A region that cannot meet the data is a mistake (a sphere in voxel
    // coordinates, a mask of another subject): an include region selects
    // nothing, an exclude region does nothing.
    if (!ds.bounds.empty)
        for (const core::Roi &r : spec.rois)
            if (disjoint(r.bounds(), ds.bounds)) {
                const std::string what = std::string(r.include ? "include" : "exclude") + " ROI " + r.spec() + " (" +
                                         bounds_text(r.bounds()) + ") lies outside " + o.input + " (" + bounds_text(ds.bounds) + ")";
                if (r.include && !spec.invert) throw core::Error(what + ": no streamline can pass");
                std::fprintf(stderr, "horizon: warning: %s\n", what.c_str());
            }
    const auto t1 = std::chrono::steady_clock::now();
    // (One pass: per-streamline boxes would cost a pass of their own; they
    // pay off when the same tractogram is filtered again and again, as the
    // window does while a region is dragged.)
    const std::vector<std::uint64_t> kept = core::filter_streamlines(t, spec);
    const auto t2 = std::chrono::steady_clock::now();
    if (kept.empty()) std::fprintf(stderr, "horizon: warning: %s: no streamline selected (%s)\n", o.input.c_str(), spec.describe().c_str());

    if (!o.out.empty()) {
        core::Dataset out;
        out.kind = HZ_DATA_STREAMLINES;
        out.metadata = ds.metadata;
        out.metadata.emplace_back("horizon_filter", spec.describe());
        // The input itself, with the streamlines kept (increasing): the
        // writer reads them where they lie (hz.ext.write-selection/1), or
        // write_dataset copies them out first. Every streamline kept: no
        // selection at all.
        out.tractogram = t.shared();
        std::vector<std::string> dropped;
        core::write_dataset(reg, out, o.out, o.force, &dropped, o.input, nullptr, kept.size() == t.nb_streamlines() ? nullptr : &kept);
        for (const auto &d : dropped) std::fprintf(stderr, "horizon: warning: %s: dropped %s\n", o.out.c_str(), d.c_str());
    }
    if (!o.ids.empty()) {
        std::string text;
        text.reserve(kept.size() * 8);
        for (std::uint64_t s : kept) text += std::to_string(s) + "\n";
        core::write_text_atomic(o.ids, text, o.force);
    }
    const auto t3 = std::chrono::steady_clock::now();
    const auto secs = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
    std::FILE *report = o.ids == "-" ? stderr : stdout;
    if (o.json) {
        nlohmann::json j;
        j["input"] = o.input;
        j["output"] = o.out;
        j["filter"] = spec.describe();
        j["nb_streamlines"] = t.nb_streamlines();
        j["selected"] = kept.size();
        j["read_s"] = secs(t0, t1);
        j["filter_s"] = secs(t1, t2);
        j["write_s"] = secs(t2, t3);
        std::fprintf(report, "%s\n", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace).c_str());
    } else {
        std::fprintf(report, "%s: %llu of %llu streamlines selected (%s) -> %s (read %.2f s, filtered %.2f s, written %.2f s)\n",
                     o.input.c_str(), (unsigned long long)kept.size(), (unsigned long long)t.nb_streamlines(), spec.describe().c_str(),
                     o.out.empty() ? o.ids.c_str() : o.out.c_str(), secs(t0, t1), secs(t1, t2), secs(t2, t3));
    }
    return 0;
}

}  // namespace hz::host
