// `horizon validate`: a conformance checker for plugin files, in the manner
// of clap-validator and pluginval. Every check runs in a forked child that
// loads the plugin afresh, so a crash or a hang is reported as that check's
// result instead of taking the validator down.
#include "commands.hpp"

#include <hz/core/render/context.hpp>

#include <hz/core/data.hpp>
#include <hz/core/io.hpp>
#include <hz/core/phantom.hpp>

#include <boost/dll/library_info.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <iostream>
#include <random>
#include <set>
#include <sys/mman.h>
#include <unistd.h>
#include "validate_checks.hpp"

namespace hz::host {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using namespace validation;

std::vector<Check> catalogue() {
    std::vector<Check> c;
    // Library level.
    c.push_back({"exports-only-entry", 0, "the library exports only hz_plugin_entry_v*", [](const Ctx &x) {
                     boost::dll::library_info info(x.module.file());
                     std::vector<std::string> extra;
                     for (const auto &s : info.symbols())
                         if (s.rfind("hz_plugin_entry_v", 0) != 0 && !s.empty() && s != "_init" && s != "_fini") extra.push_back(s);
                     if (!extra.empty())
                         return fail(std::to_string(extra.size()) + " extra exported symbols, e.g. '" + extra[0] +
                                     "' (build with -fvisibility=hidden and the SDK's version script)");
                     return pass();
                 }});
    c.push_back({"init-deinit-cycle", 0, "deinit() then init() again works and descriptors stay the same", [](const Ctx &x) {
                     const hz_plugin_entry &e = x.module.entry();
                     const uint32_t n0 = e.get_plugin_count();
                     e.deinit();
                     if (!e.init(core::host_services(), x.module.file().c_str())) return fail("second init() returned false");
                     if (e.get_plugin_count() != n0) return fail("plugin count changed across init/deinit/init");
                     return pass();
                 }});
    c.push_back({"interface-unknown-ids", 0, "unknown interface and plugin ids give NULL", [](const Ctx &x) {
                     const hz_plugin_entry &e = x.module.entry();
                     if (e.get_interface(x.plugin.id.c_str(), "hz.nonexistent/1") != nullptr) return fail("unknown interface id resolved");
                     if (e.get_interface((x.plugin.id + "x1").c_str(), x.plugin.interfaces[0].c_str()) != nullptr)
                         return fail("plugin id with trailing garbage resolved");
                     if (e.get_plugin_descriptor(e.get_plugin_count()) != nullptr) return fail("descriptor index out of range is not NULL");
                     for (const auto &i : x.plugin.interfaces)
                         if (e.get_interface(x.plugin.id.c_str(), i.c_str()) == nullptr)
                             return fail("declared interface '" + i + "' does not resolve");
                     return pass();
                 }});
    c.push_back(
        {"abi-extensions-served", 0,
         "each extension the plugin lists (hz_extensions.h) is served whole: its table, struct_size and functions", [](const Ctx &x) {
             const hz_plugin_entry &e = x.module.entry();
             // The extensions this host knows: the smallest table and
             // the kinds that may offer each.
             struct Known {
                 const char *id;
                 std::size_t size;
                 std::vector<hz_plugin_kind> kinds;
             };
             const Known known[] = {
                 {HZ_EXT_MAPPED_POSITIONS, sizeof(hz_ext_mapped_positions), {HZ_KIND_LOADER}},
                 {HZ_EXT_CHECKED_READ, sizeof(hz_ext_checked_read), {HZ_KIND_LOADER}},
                 {HZ_EXT_DELIMITED_STREAMLINES, sizeof(hz_ext_delimited_streamlines), {HZ_KIND_LOADER, HZ_KIND_CLUSTERING}},
                 {HZ_EXT_OPEN_TASK, sizeof(hz_ext_open_task), {HZ_KIND_LOADER}},
                 {HZ_EXT_WRITE_SELECTION, sizeof(hz_ext_write_selection), {HZ_KIND_LOADER}},
             };
             std::vector<std::string> offered, unknown;
             for (std::size_t i = 1; i < x.plugin.interfaces.size(); ++i) {
                 const std::string &id = x.plugin.interfaces[i];
                 const Known *k = nullptr;
                 for (const Known &c : known)
                     if (id == c.id) k = &c;
                 if (k == nullptr) {
                     unknown.push_back(id);
                     continue;
                 }
                 if (std::find(k->kinds.begin(), k->kinds.end(), x.plugin.kind) == k->kinds.end())
                     return fail("lists '" + id + "', an extension for another kind of plugin than " +
                                 core::plugin_kind_name(x.plugin.kind));
                 const void *t = e.get_interface(x.plugin.id.c_str(), id.c_str());
                 if (t == nullptr) return fail("lists '" + id + "' but get_interface() gives NULL for it");
                 const std::uint32_t size = *static_cast<const std::uint32_t *>(t);
                 if (size < k->size)
                     return fail("'" + id + "' table struct_size " + std::to_string(size) + " < " + std::to_string(k->size));
                 if (id == HZ_EXT_MAPPED_POSITIONS) {
                     const auto *m = static_cast<const hz_ext_mapped_positions *>(t);
                     if (!m->locate_positions || !m->read_offsets) return fail("'" + id + "' table with a NULL function");
                 } else if (id == HZ_EXT_OPEN_TASK) {
                     if (!static_cast<const hz_ext_open_task *>(t)->open) return fail("'" + id + "' table with a NULL function");
                 } else if (id == HZ_EXT_WRITE_SELECTION) {
                     if (!static_cast<const hz_ext_write_selection *>(t)->write_selection)
                         return fail("'" + id + "' table with a NULL function");
                 } else if (id == HZ_EXT_CHECKED_READ) {
                     if (!static_cast<const hz_ext_checked_read *>(t)->read_streamlines_checked)
                         return fail("'" + id + "' table with a NULL function");
                 } else if (id == HZ_EXT_DELIMITED_STREAMLINES) {
                     if (static_cast<const hz_ext_delimited_streamlines *>(t)->max_gap != 1)
                         return fail("'" + id + "' max_gap " +
                                     std::to_string(static_cast<const hz_ext_delimited_streamlines *>(t)->max_gap) + " (1 expected)");
                 }
                 offered.push_back(id);
             }
             // A served extension the descriptor does not list is never asked for.
             for (const Known &k : known)
                 if (std::find(x.plugin.interfaces.begin(), x.plugin.interfaces.end(), k.id) == x.plugin.interfaces.end() &&
                     e.get_interface(x.plugin.id.c_str(), k.id) != nullptr)
                     return fail(std::string("serves '") + k.id +
                                 "' without listing it in its descriptor's interfaces (no host asks for it)");
             std::string why = offered.empty() ? "offers none (the core table alone)" : "offers";
             for (const auto &id : offered) why += " " + id;
             if (!unknown.empty()) {
                 why += "; ids this host does not know, ignored:";
                 for (const auto &id : unknown) why += " " + id;
             }
             return pass(why);
         }});
    add_loader_checks(c);
    add_shader_checks(c);
    add_clustering_checks(c);
    return c;
}

struct Result {
    std::string check, plugin, status, reason;
};

}  // namespace

int cmd_validate(const GlobalOptions &, const ValidateOptions &o) {
    std::vector<Result> results;
    auto emit = [&](Result r) {
        if (!o.json)
            std::printf("%-8s %-36s %s%s%s\n", r.status.c_str(), r.check.c_str(), r.plugin.empty() ? "" : ("[" + r.plugin + "] ").c_str(),
                        r.reason.c_str(), "");
        results.push_back(std::move(r));
    };
    const fs::path file = fs::absolute(o.file);
    if (!o.json) std::printf("Validating %s\n\n", file.c_str());

    // 1. Static checks and the load in a child.
    bool loaded = false;
    std::vector<std::pair<std::string, hz_plugin_kind>> plugins;
    if (auto why = core::elf_precheck(file)) {
        emit({"elf", "", "failed", *why});
    } else {
        emit({"elf", "", "passed", ""});
        const auto r = core::run_in_child(
            [&]() -> std::string {
                try {
                    core::Module m(file);
                    json j = json::array();
                    for (const auto &p : m.plugins()) j.push_back({p.id, p.kind});
                    return json{{"ok", true}, {"plugins", j}}.dump();
                } catch (const std::exception &e) {
                    return json{{"ok", false}, {"reason", e.what()}}.dump();
                }
            },
            o.timeout_s);
        const json j = json::parse(r.output, nullptr, false);
        if (r.timed_out || r.signal != 0 || j.is_discarded()) {
            emit({"load", "", "crashed", r.describe() + " while loading or in init()"});
        } else if (!j["ok"].get<bool>()) {
            emit({"load", "", "failed", j["reason"].get<std::string>()});
        } else {
            loaded = true;
            for (const auto &p : j["plugins"]) plugins.emplace_back(p[0].get<std::string>(), p[1].get<hz_plugin_kind>());
            emit({"load", "", "passed", std::to_string(plugins.size()) + " plugin(s), descriptors and core interfaces valid"});
        }
    }

    // 2. Every check of the catalogue, each in its own child.
    if (loaded) {
        const auto checks = catalogue();
        const fs::path scratch_root = fs::temp_directory_path() / ("horizon-validate-" + std::to_string(::getpid()));
        for (std::size_t pi = 0; pi < plugins.size(); ++pi) {
            const auto &[id, kind] = plugins[pi];
            for (const auto &chk : checks) {
                if (chk.kind != 0 && chk.kind != kind) continue;
                if (chk.kind == 0 && pi > 0) continue;  // library checks once per file
                const fs::path scratch = scratch_root / (id + "-" + chk.name);
                fs::create_directories(scratch);
                const auto r = core::run_in_child(
                    [&]() -> std::string {
                        spdlog::set_level(spdlog::level::err);  // plugins' warnings on malformed input are expected
                        core::Module m(file);
                        for (const auto &p : m.plugins())
                            if (p.id == id) {
                                Ctx ctx{m, p, o, scratch};
                                Outcome out;
                                try {
                                    out = chk.fn(ctx);
                                } catch (const std::exception &e) {
                                    out = fail(std::string("exception escaped the plugin or check: ") + e.what());
                                }
                                return json{{"status", out.status}, {"reason", out.reason}}.dump();
                            }
                        return json{{"status", "failed"}, {"reason", "plugin vanished on reload"}}.dump();
                    },
                    o.timeout_s);
                std::error_code ec;
                fs::remove_all(scratch, ec);
                const json j = json::parse(r.output, nullptr, false);
                if (r.timed_out || r.signal != 0 || j.is_discarded() || !j.contains("status"))
                    emit({chk.name, id, "crashed", r.describe()});
                else
                    emit({chk.name, id, j["status"].get<std::string>(), j["reason"].get<std::string>()});
            }
        }
        std::error_code ec;
        fs::remove_all(scratch_root, ec);
    }

    int failed = 0, passed = 0, skipped = 0;
    for (const auto &r : results) {
        if (r.status == "passed")
            ++passed;
        else if (r.status == "skipped")
            ++skipped;
        else
            ++failed;
    }
    if (o.json) {
        json j;
        j["file"] = file.string();
        j["checks"] = json::array();
        for (const auto &r : results)
            j["checks"].push_back({{"check", r.check}, {"plugin", r.plugin}, {"status", r.status}, {"reason", r.reason}});
        j["summary"] = {{"passed", passed}, {"failed", failed}, {"skipped", skipped}};
        j["ok"] = failed == 0;
        std::cout << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
    } else {
        std::printf("\n%d passed, %d failed, %d skipped: %s\n", passed, failed, skipped, failed ? "FAIL" : "OK");
    }
    return failed == 0 ? 0 : 1;
}

}  // namespace hz::host
