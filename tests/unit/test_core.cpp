// The core: data model invariants, child isolation, ELF checks, the
// registry and plugin-driven I/O with the bundled TCK plugin.
#include <hz/core/io.hpp>
#include <hz/core/phantom.hpp>
#include <hz/core/plugin_host.hpp>

#include "label_table.hpp"  // (plugins/loaders/common)

#include <catch2/catch.hpp>

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <chrono>
#include <cmath>
#include <csignal>
#include <fstream>
#include <limits>
#include <set>
#include <thread>

namespace fs = std::filesystem;
using namespace hz::core;

namespace {

fs::path scratch(const std::string &name) {
    const fs::path d = fs::temp_directory_path() / ("hz_unit_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

Registry bundled() {
    Registry r;
    r.scan({HZ_TEST_PLUGIN_DIR});
    return r;
}

// A streamlines dataset of the phantom's first `n` streamlines.
Dataset phantom_dataset(std::uint64_t n) {
    Dataset ds;
    ds.kind = HZ_DATA_STREAMLINES;
    ds.tractogram = make_phantom({.nb_streamlines = n});
    return ds;
}

std::string slurp(const fs::path &p) {
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), {});
}

}  // namespace

TEST_CASE("Tractogram::validate catches broken invariants") {
    Tractogram t = make_phantom({.nb_streamlines = 10});
    CHECK_NOTHROW(t.validate("phantom"));
    t.offsets[3] = t.offsets[2] - 1;
    CHECK_THROWS_WITH(t.validate("x"), Catch::Contains("offsets decrease"));
    Tractogram u = make_phantom({.nb_streamlines = 10});
    u.positions[5] = NAN;
    CHECK_THROWS_WITH(u.validate("x"), Catch::Contains("non-finite"));
}

TEST_CASE("the phantom is deterministic and brain-sized") {
    const Tractogram a = make_phantom({.nb_streamlines = 500, .seed = 3});
    const Tractogram b = make_phantom({.nb_streamlines = 500, .seed = 3});
    REQUIRE(a.nb_vertices() == b.nb_vertices());
    CHECK(std::equal(a.positions.begin(), a.positions.end(), b.positions.begin()));
    const Bounds box = bounds_of(a.positions.data(), a.nb_vertices());
    CHECK(box.max[0] - box.min[0] < 200);
    CHECK(box.max[1] - box.min[1] < 220);
    CHECK(a.nb_streamlines() == 500);
}

TEST_CASE("run_in_child reports output, crashes and hangs") {
    const auto ok = run_in_child([] { return std::string("hello"); }, 5);
    CHECK(ok.exited);
    CHECK(ok.output == "hello");
    const auto crash = run_in_child(
        []() -> std::string {
            std::raise(SIGSEGV);
            return "";
        },
        5);
    CHECK(crash.signal == SIGSEGV);
    CHECK_THAT(crash.describe(), Catch::Contains("SIGSEGV"));
    const auto t0 = std::chrono::steady_clock::now();
    const auto hang = run_in_child(
        []() -> std::string {
            for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
        },
        0.5);
    CHECK(hang.timed_out);
    CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5));
}

TEST_CASE("elf_precheck explains why a file is not a plugin") {
    const fs::path d = scratch("elf");
    std::ofstream(d / "empty.so").close();
    std::ofstream(d / "text.so") << "hello\n";
    CHECK_THAT(*elf_precheck(d / "empty.so"), Catch::Contains("empty"));
    CHECK_THAT(*elf_precheck(d / "text.so"), Catch::Contains("text file"));
    CHECK_FALSE(elf_precheck(fs::path(HZ_TEST_PLUGIN_DIR) / "hz_loader_tck.so").has_value());
    // The same object claiming another CPU architecture.
    std::string so = slurp(fs::path(HZ_TEST_PLUGIN_DIR) / "hz_loader_tck.so");
    so[18] = static_cast<char>(183);  // EM_AARCH64
    so[19] = 0;
    std::ofstream(d / "arm.so", std::ios::binary) << so;
    CHECK_THAT(*elf_precheck(d / "arm.so"), Catch::Contains("AArch64"));
    fs::remove_all(d);
}

TEST_CASE("the registry isolates a crashing init and keeps the good plugins") {
    Registry r;
    r.add_file(fs::path(HZ_TEST_FIXTURE_DIR) / "fx_init_crash.so");
    r.add_file(fs::path(HZ_TEST_FIXTURE_DIR) / "fx_valid.so");
    REQUIRE(r.rejected().size() == 1);
    CHECK_THAT(r.rejected()[0].reason, Catch::Contains("SIGSEGV"));
    REQUIRE(r.plugins().size() == 1);
    CHECK(r.plugins()[0].info.kind == HZ_KIND_SHADER);
}

TEST_CASE("the trial list: files that passed load without a child, in search order, the first id still winning") {
    const fs::path d = fs::temp_directory_path() / ("hz_trials_" + std::to_string(::getpid()));
    fs::remove_all(d);
    fs::create_directories(d / "p");
    for (const char *name : {"a.so", "b.so"})  // one plugin id twice
        fs::copy_file(fs::path(HZ_TEST_FIXTURE_DIR) / "fx_valid.so", d / "p" / name);
    fs::copy_file(fs::path(HZ_TEST_FIXTURE_DIR) / "fx_init_crash.so", d / "p" / "c.so");
    const Registry::Options with_list{true, 10.0, d / "trials.json"};
    bool b_replaced = false;
    auto scan = [&](const Registry::Options &o) {
        auto r = std::make_unique<Registry>(o);
        r->scan({d / "p"});
        REQUIRE(r->plugins().size() == 1);
        CHECK(fs::path(r->plugins()[0].info.file).filename() == "a.so");
        REQUIRE(r->rejected().size() == 2);
        CHECK(fs::path(r->rejected()[0].file).filename() == "b.so");
        // Once b.so is another inode, this process's dlopen() still returns
        // the b.so it loaded before under that name (glibc matches loaded
        // objects by name): not the inode the trial saw, so it is refused
        // where the mapping can be identified (/proc/self/map_files: root),
        // else rejected as the duplicate id it is.
        if (b_replaced)
            CHECK_THAT(r->rejected()[0].reason, Catch::Contains("replaced after its trial") || Catch::Contains("duplicate plugin id"));
        else
            CHECK_THAT(r->rejected()[0].reason, Catch::Contains("duplicate plugin id"));
        CHECK(fs::path(r->rejected()[1].file).filename() == "c.so");
        CHECK_THAT(r->rejected()[1].reason, Catch::Contains("SIGSEGV"));
        return r->trial_loads();
    };
    CHECK(scan(with_list) == 3);
    CHECK(scan(with_list) == 1);  // a and b vouched for; c crashed, so it is tried again
    // a changed: tried again (in a child) while b is loaded at once; a still comes first.
    fs::last_write_time(d / "p" / "a.so", fs::last_write_time(d / "p" / "a.so") + std::chrono::seconds(1));
    CHECK(scan(with_list) == 2);
    CHECK(scan(with_list) == 1);
    // A new file under the same name (another inode) is tried again.
    fs::rename(d / "p" / "b.so", d / "p" / "b2.so");
    fs::copy_file(d / "p" / "b2.so", d / "p" / "b.so");
    fs::remove(d / "p" / "b2.so");
    b_replaced = true;
    CHECK(scan(with_list) == 2);
    CHECK(scan(Registry::Options{true, 10.0, {}}) == 3);  // no list
    fs::remove_all(d);
}

TEST_CASE("search path order: --plugin-dir, HORIZON_PLUGIN_PATH, user dir, bundled") {
    ::setenv("HORIZON_PLUGIN_PATH", "/a:/b", 1);
    ::setenv("XDG_DATA_HOME", "/xdg", 1);
    const auto p = plugin_search_path({"/cli"});
    ::unsetenv("HORIZON_PLUGIN_PATH");
    ::unsetenv("XDG_DATA_HOME");
    REQUIRE(p.size() == 5);
    CHECK(p[0] == "/cli");
    CHECK(p[1] == "/a");
    CHECK(p[2] == "/b");
    CHECK(p[3] == "/xdg/horizon/plugins");
    CHECK(p[4].filename() == "plugins");
}

TEST_CASE("opening a TCK reports the scan progress through the task: hz.ext.open-task/1") {
    const Registry reg = bundled();
    const fs::path d = scratch("open-progress");
    Dataset ds = phantom_dataset(60000);
    REQUIRE(ds.tractogram.nb_vertices() > 3u << 20);  // (more than three of the scan's 1M-triple chunks)
    write_dataset(reg, ds, d / "a.tck", false, nullptr);
    Task task;
    std::vector<double> scanning;
    double last = -1;
    bool decreasing = false;
    task.on_progress = [&](double f, const char *msg) {
        if (msg != nullptr && std::string(msg) == "scanning TCK") scanning.push_back(f);
        decreasing |= f < last && msg != nullptr && std::string(msg) == "scanning TCK";
        if (msg != nullptr && std::string(msg) == "scanning TCK") last = f;
    };
    const Dataset back = read_dataset(reg, d / "a.tck", task.get());
    CHECK(back.tractogram.nb_vertices() == ds.tractogram.nb_vertices());
    REQUIRE(!scanning.empty());
    CHECK(std::any_of(scanning.begin(), scanning.end(), [](double f) { return f > 0 && f < 1; }));
    CHECK(!decreasing);
    fs::remove_all(d);
}

TEST_CASE("read and write through the TCK plugin, selection by extension and by content") {
    const Registry reg = bundled();
    REQUIRE(reg.find("org.horizon.loader.tck") != nullptr);
    const fs::path d = scratch("io");
    Dataset ds = phantom_dataset(200);
    ds.metadata = {{"comment", "unit test"}};
    std::vector<std::string> dropped;
    write_dataset(reg, ds, d / "a.tck", false, &dropped);
    CHECK(dropped.empty());
    const Dataset back = read_dataset(reg, d / "a.tck");
    REQUIRE(back.tractogram.nb_vertices() == ds.tractogram.nb_vertices());
    // Our writer aligns the data as MRtrix does: the positions are mapped,
    // each streamline's NaN delimiter in place (gap 1).
    CHECK(back.mapped);
    CHECK(back.tractogram.gap == 1);
    CHECK(back.tractogram.nb_stored() == ds.tractogram.nb_vertices() + ds.tractogram.nb_streamlines());
    for (std::uint64_t s = 0; s < ds.tractogram.nb_streamlines(); ++s) {
        REQUIRE(back.tractogram.size(s) == ds.tractogram.size(s));
        CHECK(std::equal(back.tractogram.positions.data() + 3 * back.tractogram.begin(s),
                         back.tractogram.positions.data() + 3 * back.tractogram.end(s),
                         ds.tractogram.positions.data() + 3 * ds.tractogram.begin(s)));
    }
    const Tractogram flat = back.tractogram.compacted();
    CHECK(flat.gap == 0);
    CHECK(std::equal(flat.positions.begin(), flat.positions.end(), ds.tractogram.positions.begin(), ds.tractogram.positions.end()));
    CHECK(std::equal(flat.offsets.begin(), flat.offsets.end(), ds.tractogram.offsets.begin(), ds.tractogram.offsets.end()));
    CHECK(back.format == "tck Float32LE");

    // A TCK file with a misleading name is still found by its content.
    fs::copy_file(d / "a.tck", d / "misnamed.dat");
    CHECK(read_dataset(reg, d / "misnamed.dat").loader_id == "org.horizon.loader.tck");

    // Atomic writes: no overwrite without force, never the input, nothing left on failure.
    CHECK_THROWS_WITH(write_dataset(reg, ds, d / "a.tck", false, nullptr), Catch::Contains("already exists"));
    CHECK_THROWS_WITH(write_dataset(reg, ds, d / "a.tck", true, nullptr, d / "a.tck"), Catch::Contains("refusing"));
    Dataset bad = read_dataset(reg, d / "a.tck");
    bad.tractogram.positions[4] = INFINITY;
    CHECK_THROWS_WITH(write_dataset(reg, bad, d / "b.tck", false, nullptr), Catch::Contains("non-finite"));
    CHECK_FALSE(fs::exists(d / "b.tck"));
    std::size_t files = 0;
    for ([[maybe_unused]] const auto &e : fs::directory_iterator(d)) ++files;
    CHECK(files == 2);  // a.tck and misnamed.dat: no temporary left behind
    CHECK_THROWS_WITH(write_dataset(reg, ds, d / "x.unknownext", false, nullptr), Catch::Contains("no writer"));
    fs::remove_all(d);
}

TEST_CASE("delimited positions (a mapped TCK): bounds, delimiter and finiteness checks") {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    // Streamlines of 2, 0 and 1 points, each followed by a NaN triple.
    std::vector<float> p = {1, 2, 3, -4, 5, 6, nan, nan, nan, nan, nan, nan, 7, -8, 9, nan, nan, nan};
    const std::vector<std::uint64_t> off = {0, 3, 4, 6};
    const Bounds b = delimited_bounds(p.data(), 6, off.data(), 3, "x.tck");
    REQUIRE_FALSE(b.empty);
    CHECK(b.min == std::array<double, 3>{-4, -8, 3});
    CHECK(b.max == std::array<double, 3>{7, 5, 9});
    auto bad = p;
    bad[13] = INFINITY;
    CHECK_THROWS_WITH(delimited_bounds(bad.data(), 6, off.data(), 3, "x.tck"),
                      Catch::Equals("x.tck: non-finite coordinate in streamline 2 at point 0"));
    bad = p;
    bad[4] = nan;
    CHECK_THROWS_WITH(delimited_bounds(bad.data(), 6, off.data(), 3, "x.tck"), Catch::Contains("streamline 0 at point 1"));
    bad = p;
    bad[16] = 0;
    CHECK_THROWS_WITH(delimited_bounds(bad.data(), 6, off.data(), 3, "x.tck"),
                      Catch::Equals("x.tck: the delimiter after streamline 2 is not a NaN triple"));
    const std::vector<std::uint64_t> no_delim = {0, 3, 3, 6};
    CHECK_THROWS_WITH(delimited_bounds(p.data(), 6, no_delim.data(), 3, "x.tck"), Catch::Contains("streamline 1 has no delimiter"));
    // The same through a Tractogram: sizes, compaction, and bounds that skip NaN.
    Tractogram t;
    t.positions = Buffer<float>(p.size());
    std::copy(p.begin(), p.end(), t.positions.begin());
    t.offsets = Buffer<std::uint64_t>(off.size());
    std::copy(off.begin(), off.end(), t.offsets.begin());
    t.gap = 1;
    CHECK(t.nb_vertices() == 3);
    CHECK((t.size(0) == 2 && t.size(1) == 0 && t.size(2) == 1));
    CHECK(t.validate("x.tck").max == b.max);
    const Tractogram c = t.compacted();
    CHECK(std::vector<float>(c.positions.begin(), c.positions.end()) == std::vector<float>{1, 2, 3, -4, 5, 6, 7, -8, 9});
    CHECK(std::vector<std::uint64_t>(c.offsets.begin(), c.offsets.end()) == std::vector<std::uint64_t>{0, 2, 2, 3});
    CHECK(bounds_of(t.positions.data(), t.nb_stored()).min == b.min);
    const Tractogram sel = select_streamlines(t, {2, 0});
    CHECK(std::vector<float>(sel.positions.begin(), sel.positions.end()) == std::vector<float>{7, -8, 9, 1, 2, 3, -4, 5, 6});
}

TEST_CASE("a pre-cancelled task stops a read") {
    const Registry reg = bundled();
    const fs::path d = scratch("cancel");
    Dataset ds = phantom_dataset(50);
    write_dataset(reg, ds, d / "a.tck", false, nullptr);
    Task task;
    task.cancel();
    CHECK_THROWS_WITH(read_dataset(reg, d / "a.tck", task.get()), Catch::Contains("cancelled"));
    fs::remove_all(d);
}

TEST_CASE("zero-copy TRX positions: mapped copy-on-write, checked, and the file never changes") {
    const Registry reg = bundled();
    REQUIRE(reg.find("org.horizon.loader.trx") != nullptr);
    const fs::path d = scratch("zerocopy");
    Dataset ds = phantom_dataset(300);
    write_dataset(reg, ds, d / "a.trx", false, nullptr);
    const std::string before = slurp(d / "a.trx");

    Dataset back = read_dataset(reg, d / "a.trx");
    REQUIRE(back.mapped);  // Horizon's writer aligns the stored positions for this
    Tractogram &t = back.tractogram;
    REQUIRE(t.nb_vertices() == ds.tractogram.nb_vertices());
    CHECK(std::equal(t.positions.begin(), t.positions.end(), ds.tractogram.positions.begin()));
    const Bounds b = bounds_of(ds.tractogram.positions.data(), ds.tractogram.nb_vertices());
    CHECK(back.bounds.min == b.min);
    CHECK(back.bounds.max == b.max);

    // Writing through the view copies that page only; the file is untouched.
    t.positions[0] = 1234.5f;
    Buffer<float> moved = std::move(t.positions);
    CHECK(t.positions.empty());
    CHECK(moved[0] == 1234.5f);
    CHECK(slurp(d / "a.trx") == before);
    CHECK(read_dataset(reg, d / "a.trx").tractogram.positions[0] == ds.tractogram.positions[0]);

    // A flipped bit inside the stored positions fails the zip CRC, named.
    std::string corrupt = before;
    corrupt[64 + 4 * 1000] ^= 0x01;  // the positions start at byte 64
    std::ofstream(d / "c.trx", std::ios::binary) << corrupt;
    CHECK_THROWS_WITH(read_dataset(reg, d / "c.trx"), Catch::Contains("c.trx") && Catch::Contains("CRC-32"));
    fs::remove_all(d);
}

TEST_CASE("a deferred Buffer is filled once, on first access, for every view, from any thread") {
    std::atomic<int> calls{0};
    Buffer<float> b = Buffer<float>::deferred(1000, [&calls](float *dst) {
        ++calls;
        for (int i = 0; i < 1000; ++i) dst[i] = float(i);
    });
    CHECK(b.size() == 1000);
    CHECK(b.pending());
    CHECK(calls == 0);
    const Buffer<float> view = b.shared();
    Buffer<float> moved = std::move(b);
    CHECK(moved.pending());
    CHECK(calls == 0);
    // Two threads race for the first access: one fill, one array.
    const float *seen[2] = {nullptr, nullptr};
    std::thread t1([&] { seen[0] = view.data(); });
    std::thread t2([&] { seen[1] = moved.data(); });
    t1.join();
    t2.join();
    CHECK(calls == 1);
    CHECK(seen[0] == seen[1]);
    CHECK(reinterpret_cast<std::uintptr_t>(seen[0]) % alignof(float) == 0);
    CHECK_FALSE(view.pending());
    CHECK(moved[999] == 999.0f);
    moved[0] = 5.0f;  // writable, and the views see it
    CHECK(view[0] == 5.0f);
    CHECK(calls == 1);
    CHECK(Buffer<float>::deferred(0, [](float *) { FAIL("no fill for an empty buffer"); }).data() == nullptr);
}

TEST_CASE("a TCK whose data start at an unaligned offset is mapped, and copied only when used") {
    const Registry reg = bundled();
    const fs::path d = scratch("unaligned");
    Dataset ds = phantom_dataset(200);
    write_dataset(reg, ds, d / "a.tck", false, nullptr);
    // Our writer aligns the data; shift them by one byte as nibabel's offset 67 does.
    std::string s = slurp(d / "a.tck");
    const std::size_t at = s.find("file: . ");
    REQUIRE(at != std::string::npos);
    const std::size_t offset = std::stoull(s.substr(at + 8));
    REQUIRE(offset % 4 == 0);
    std::string head = s.substr(0, offset), body = s.substr(offset);
    const std::string old_field = "file: . " + std::to_string(offset), new_field = "file: . " + std::to_string(offset + 1);
    REQUIRE(old_field.size() == new_field.size());
    head.replace(head.find(old_field), old_field.size(), new_field);
    std::ofstream(d / "u.tck", std::ios::binary) << head << ' ' << body;

    Dataset back = read_dataset(reg, d / "u.tck");
    CHECK(back.mapped);
    CHECK(back.unaligned);
    const Tractogram &t = back.tractogram;
    CHECK(t.gap == 1);
    // Nothing has read the floats yet (except where the host checks every
    // loader's claims itself: Debug and sanitizer builds, HZ_VERIFY_PLUGIN_CLAIMS).
#ifndef HZ_VERIFY_PLUGIN_CLAIMS
    CHECK(t.positions.pending());
#endif
    const Bounds b = bounds_of(ds.tractogram.positions.data(), ds.tractogram.nb_vertices());
    CHECK(back.bounds.min == b.min);  // (vouched for by the loader's scan)
    CHECK(back.bounds.max == b.max);
    const Tractogram c = t.compacted();  // the first use copies
    CHECK_FALSE(t.positions.pending());
    REQUIRE(c.positions.size() == ds.tractogram.positions.size());
    CHECK(std::equal(c.positions.begin(), c.positions.end(), ds.tractogram.positions.begin()));
    CHECK(slurp(d / "u.tck").size() == s.size() + 1);
    fs::remove_all(d);
}

TEST_CASE("labels without a colour get distinct colours no other label has, even past the generated hues") {
    // 3000 labels, a third with colours of their own (which stay), the rest
    // without: more than the few hundred distinct generated hues.
    std::vector<hzlabel::Entry> table;
    for (std::int32_t i = 0; i < 3000; ++i) {
        hzlabel::Entry e;
        e.index = i;
        e.name = "label";  // (one name for all: an annotation tells labels apart by colour)
        e.coloured = i % 3 == 0;
        e.r = i % 256, e.g = i / 256 % 256, e.b = 7;
        table.push_back(e);
    }
    // One given colour is exactly what label 1 would be generated.
    const auto g1 = hzlabel::generated_rgb(1);
    table[3].r = g1[0], table[3].g = g1[1], table[3].b = g1[2];
    std::vector<hzlabel::Entry> again = table;
    hzlabel::assign_colours(table);
    hzlabel::assign_colours(again);
    std::set<std::uint32_t> seen;
    for (std::size_t i = 0; i < table.size(); ++i) {
        CHECK(table[i].rgb() == again[i].rgb());  // deterministic
        if (table[i].coloured) CHECK(table[i].rgb() == std::array<std::int32_t, 3>{table[i].r, table[i].g, table[i].b});
        seen.insert(table[i].packed());
    }
    CHECK(seen.size() == table.size());
    CHECK(table[1].rgb() != g1);
    CHECK(table[2].rgb() == hzlabel::generated_rgb(2));  // free: its own generated colour
}

TEST_CASE("make_resident maps a file's pages without changing them, at any offset and size") {
    // 40 MiB: more than one part of the parallel populate; read back through
    // a private mapping of the file at unaligned offsets and lengths.
    const fs::path file = fs::temp_directory_path() / ("hz_resident_" + std::to_string(::getpid()) + ".bin");
    std::vector<std::uint32_t> values(10u << 20);
    for (std::size_t i = 0; i < values.size(); ++i) values[i] = static_cast<std::uint32_t>(i * 2654435761u);
    {
        std::ofstream out(file, std::ios::binary);
        out.write(reinterpret_cast<const char *>(values.data()), std::streamsize(values.size() * 4));
    }
    const int fd = ::open(file.c_str(), O_RDONLY);
    REQUIRE(fd >= 0);
    const std::size_t bytes = values.size() * 4;
    void *base = ::mmap(nullptr, bytes, PROT_READ, MAP_PRIVATE, fd, 0);
    ::close(fd);
    REQUIRE(base != MAP_FAILED);
    const auto *p = static_cast<const unsigned char *>(base);
    make_resident(nullptr, 0);
    make_resident(p + 3, 0);
    make_resident(p + 4093, 7);  // (across a page boundary)
    make_resident(p + 1, bytes - 1);
    CHECK(std::memcmp(base, values.data(), bytes) == 0);
    ::munmap(base, bytes);
    fs::remove(file);
}
