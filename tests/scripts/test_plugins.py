"""`horizon plugins`: discovery, and rejection of everything that is not a
good plugin, each with a one-line reason naming the file."""
import json
import os
import shutil
import struct
import subprocess
import time
import unittest

from hztest import BUILD, BUNDLED, FIXTURES, HORIZON, TEMPLATES, TempDirTest, environment, run, run_json

BUNDLED_IDS = {"org.horizon.loader.tck", "org.horizon.loader.trk", "org.horizon.loader.trx", "org.horizon.loader.nifti", "org.horizon.loader.mgh",
               "org.horizon.loader.pam5",
               "org.horizon.shader.lambert", "org.horizon.shader.blinn_phong", "org.horizon.shader.line_stalling",
               "org.horizon.loader.gifti", "org.horizon.loader.freesurfer", "org.horizon.shader.principled", "org.horizon.clustering.qb",
               "org.horizon.clustering.qbx", "org.horizon.clustering.qbx_merge"}


class PluginsTest(TempDirTest):
    def test_bundled_plugins_are_listed(self):
        j = run_json("plugins", "--json")
        ids = {p["id"] for p in j["plugins"]}
        self.assertTrue(BUNDLED_IDS <= ids, ids)
        for p in j["plugins"]:
            self.assertEqual(p["status"], "loaded")
            self.assertTrue(os.path.isfile(p["file"]))
            self.assertIn(p["kind"], ("loader", "shader", "clustering"))
            self.assertRegex(p["version"], r"^\d+\.\d+\.\d+")
        self.assertEqual(j["rejected"], [])
        text = run("plugins")
        self.assertEqual(text.returncode, 0)
        self.assertIn("org.horizon.loader.tck", text.stdout)

    def test_trial_list(self):
        """A plugin file whose trial load passed is loaded without a new one
        while it and the host are unchanged; a crashing one is tried every
        time; a changed file is tried again; a spoiled list is ignored."""
        lst = self.path("cache/trials.json")
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(TEMPLATES, "tpl_lambert_shader.so"), d)
        shutil.copy(os.path.join(FIXTURES, "fx_init_crash.so"), d)
        files = sum(os.path.isfile(os.path.join(BUNDLED, f)) for f in os.listdir(BUNDLED)) + 2
        env = {"HORIZON_PLUGIN_CACHE": lst}

        def listing(e=env):
            j = run_json("--plugin-dir", d, "plugins", "--json", env=e)
            return j, sorted(p["id"] for p in j["plugins"]), sorted((r["file"], r["reason"]) for r in j["rejected"])

        first, ids, rejected = listing()
        self.assertEqual(first["trial_loads"], files)
        self.assertEqual(first["trial_list"], lst)
        self.assertIn("org.example.shader.lambert", ids)
        self.assertEqual([os.path.basename(f) for f, _ in rejected], ["fx_init_crash.so"])
        with open(lst) as f:
            listed = {e["file"] for e in json.load(f)["passed"]}
        self.assertIn(os.path.join(d, "tpl_lambert_shader.so"), listed)
        self.assertNotIn(os.path.join(d, "fx_init_crash.so"), listed)

        again, ids2, rejected2 = listing()
        self.assertEqual(again["trial_loads"], 1)  # the crashing one only
        self.assertEqual((ids2, rejected2), (ids, rejected))

        lambert = os.path.join(d, "tpl_lambert_shader.so")
        st = os.stat(lambert)
        os.utime(lambert, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
        changed, ids3, _ = listing()
        self.assertEqual(changed["trial_loads"], 2)
        self.assertEqual(ids3, ids)

        for junk in (b"", b"{not json", b'{"format": "horizon-plugin-trials", "version": 1, "passed": [{"file": 3}, 7]}'):
            with open(lst, "wb") as f:
                f.write(junk)
            spoiled, ids4, rejected4 = listing()
            self.assertEqual(spoiled["trial_loads"], files)
            self.assertEqual((ids4, rejected4), (ids, rejected))

        off, ids5, _ = listing({"HORIZON_PLUGIN_CACHE": "off"})
        self.assertEqual(off["trial_loads"], files)
        self.assertIsNone(off["trial_list"])
        self.assertEqual(ids5, ids)
        text = run("--plugin-dir", d, "plugins", env=env).stdout
        self.assertIn("trial list", text)
        self.assertIn(lst, text)

    def test_trial_list_cap_gone_files_and_default_place(self):
        """The list keeps at most 256 entries (the newest), drops the entries
        of files that are gone, and lives in $XDG_CACHE_HOME/horizon (else
        ~/.cache/horizon) unless HORIZON_PLUGIN_CACHE says otherwise."""
        def stamp(path):
            st = os.stat(path)
            return [st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns]
        lst = self.path("trials.json")
        fakes = self.path("fakes")
        os.mkdir(fakes)
        entries = []
        for i in range(300):  # files that exist and are unchanged, as a real entry's are
            f = os.path.join(fakes, f"p{i:03}.so")
            with open(f, "w") as fh:
                fh.write("x")
            entries.append({"file": f, "stamp": stamp(f), "deps": [], "host": os.path.realpath(HORIZON), "host_stamp": stamp(HORIZON)})
        gone = os.path.join(fakes, "gone.so")
        entries.insert(250, {**entries[0], "file": gone})
        with open(lst, "w") as fh:
            json.dump({"format": "horizon-plugin-trials", "version": 2, "passed": entries}, fh)
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(TEMPLATES, "tpl_lambert_shader.so"), d)  # one new trial: the list is written again
        run_json("--plugin-dir", d, "plugins", "--json", env={"HORIZON_PLUGIN_CACHE": lst})
        with open(lst) as fh:
            kept = [e["file"] for e in json.load(fh)["passed"]]
        self.assertEqual(len(kept), 256)
        self.assertNotIn(gone, kept)
        # This command tried the lambert template and the bundled plugins
        # (not on the list): they are the newest; the oldest fakes go.
        new = [f for f in kept if not f.startswith(fakes)]
        self.assertIn(os.path.join(d, "tpl_lambert_shader.so"), new)
        fakes_kept = [f for f in kept if f.startswith(fakes)]
        self.assertEqual(fakes_kept, [e["file"] for e in entries if e["file"] != gone][300 - (256 - len(new)):])
        self.assertEqual(kept[-len(new):], new, "the new entries come last")
        # The default place.
        for env, where in (({"XDG_CACHE_HOME": self.path("xdg")}, self.path("xdg/horizon/plugin-trials.json")),
                           ({"XDG_CACHE_HOME": "", "HOME": self.path("home")}, self.path("home/.cache/horizon/plugin-trials.json"))):
            e = environment("plugins", env=env)
            e.pop("HORIZON_PLUGIN_CACHE")
            p = subprocess.run([HORIZON, "plugins", "--json"], capture_output=True, text=True, timeout=120, env=e)
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertEqual(json.loads(p.stdout)["trial_list"], where)
            self.assertTrue(os.path.isfile(where), where)

    def test_trial_list_is_invalidated_by_a_new_horizon(self):
        """Entries were vouched for by one build of `horizon`: another (an
        upgrade; here the same file with a new modification time) tries every
        plugin again, and entries of a host that is gone are dropped."""
        prefix = self.path("prefix")
        os.makedirs(os.path.join(prefix, "bin"))
        os.makedirs(os.path.join(prefix, "lib", "horizon"))
        os.symlink(BUNDLED, os.path.join(prefix, "lib", "horizon", "plugins"))
        exe = os.path.join(prefix, "bin", "horizon")
        shutil.copy2(HORIZON, exe)
        lst = self.path("trials.json")
        env = {**os.environ, "HORIZON_PLUGIN_CACHE": lst, "XDG_DATA_HOME": "/nonexistent-xdg"}
        env.pop("HORIZON_PLUGIN_PATH", None)

        def trials():
            p = subprocess.run([exe, "plugins", "--json"], capture_output=True, text=True, timeout=120, env=env)
            self.assertEqual(p.returncode, 0, p.stderr)
            return json.loads(p.stdout)["trial_loads"]

        files = sum(os.path.isfile(os.path.join(BUNDLED, f)) for f in os.listdir(BUNDLED))
        self.assertEqual(trials(), files)
        self.assertEqual(trials(), 0)
        st = os.stat(exe)
        os.utime(exe, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))
        self.assertEqual(trials(), files, "a changed horizon trusts no earlier trial")
        self.assertEqual(trials(), 0)

    def test_version_and_global_options_after_the_command(self):
        p = run("--version")
        self.assertEqual(p.returncode, 0)
        self.assertRegex(p.stdout, r"^horizon \d+\.\d+\.\d+ \(plugin ABI 1\.\d+\)")
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(TEMPLATES, "tpl_lambert_shader.so"), d)
        j = run_json("plugins", "--json", "--plugin-dir", d)
        self.assertIn("org.example.shader.lambert", {p["id"] for p in j["plugins"]})

    def test_schemas_are_listed(self):
        j = run_json("plugins", "--json")
        by_id = {p["id"]: p for p in j["plugins"]}
        for p in j["plugins"]:
            self.assertRegex(p["abi"], r"^1\.\d+$")
        qbx = {s["name"]: s for s in by_id["org.horizon.clustering.qbx"]["parameters"]}
        self.assertEqual(qbx["thresholds"]["type"], "float_array")
        self.assertEqual(qbx["thresholds"]["default"], [30, 25, 20, 15])
        self.assertEqual(qbx["mode"]["choices"], ["exact", "fast"])
        principled = {s["name"] for s in by_id["org.horizon.shader.principled"]["parameters"]}
        self.assertTrue({"roughness", "sheen", "clearcoat_gloss", "base_color"} <= principled)
        self.assertNotIn("parameters", by_id["org.horizon.loader.tck"])
        one = run_json("plugins", "qbx", "--json")
        self.assertEqual(one["id"], "org.horizon.clustering.qbx")
        text = run("plugins", "org.horizon.clustering.qbx").stdout
        self.assertIn("--param NAME=VALUE", text)
        self.assertRegex(text, r"mode +enum +exact\|fast +default exact")
        self.assertNotEqual(run("plugins", "no.such.plugin").returncode, 0)

    def tck_and_template(self, lines, template):
        """`lines` written to t.tck, and a plugin folder holding the SDK
        template `template`: their paths."""
        from hztest import tck_bytes
        tck = self.path("t.tck")
        with open(tck, "wb") as f:
            f.write(tck_bytes(lines))
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(TEMPLATES, template), d)
        return tck, d

    def test_a_third_party_clustering_plugin_runs_from_cluster(self):
        import numpy as np
        rng = np.random.default_rng(3)
        lines = [np.cumsum(rng.normal(size=(int(rng.integers(5, 80)), 3)), axis=0) for _ in range(200)]
        tck, d = self.tck_and_template(lines, "tpl_length_clustering.so")
        labels = self.path("l.csv")
        p = run("cluster", tck, "--algorithm", "length", "--param", "bin_width=20", "--labels", labels, "--plugin-dir", d)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("Length bins", p.stdout)
        rows = np.loadtxt(labels, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
        self.assertEqual(rows.shape, (200, 2))
        # Its parameters are checked against its own schema, before any work.
        p = run("cluster", tck, "--algorithm", "org.example.clustering.length", "--param", "bin_width=0", "--labels", labels, "--force",
                "--plugin-dir", d)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("bin_width: 0 is outside [0.1, 1000]", p.stderr)
        p = run("cluster", tck, "--algorithm", "length", "--thresholds", "5", "--labels", labels, "--force", "--plugin-dir", d)
        self.assertIn("has no such parameter", p.stderr)
        p = run("cluster", tck, "--algorithm", "length", "--param", "width=3", "--labels", labels, "--force", "--plugin-dir", d)
        self.assertIn("it has: bin_width", p.stderr)
        p = run("cluster", tck, "--algorithm", "nope", "--labels", labels, "--force")
        self.assertIn("no clustering plugin has this id", p.stderr)

    def test_a_third_party_writer_gets_a_copy_of_the_selection(self):
        """`filter` into a format whose writer (the SDK's CSV template) does
        not offer hz.ext.write-selection/1: the selected streamlines are
        copied for it first, and written exactly; when that copy fits
        nowhere (no temporary file, no memory reported), one line names the
        output and says why, exit 1, nothing written."""
        import numpy as np
        rng = np.random.default_rng(5)
        lines = [np.cumsum(rng.normal(size=(int(rng.integers(5, 40)), 3)), axis=0).astype(np.float32) for _ in range(300)]
        tck, d = self.tck_and_template(lines, "tpl_csv_loader.so")
        out = self.path("picked.csv")
        p = run("--plugin-dir", d, "filter", tck, "--min-length", "30", "-o", out, "--json")
        self.assertEqual(p.returncode, 0, p.stderr)
        want = [i for i, s in enumerate(lines) if np.linalg.norm(np.diff(s, axis=0), axis=1).sum() >= 30]
        self.assertEqual(json.loads(p.stdout)["selected"], len(want))
        self.assertGreater(len(want), 20)
        self.assertLess(len(want), 280)
        back = json.loads(run("--plugin-dir", d, "info", out, "--json").stdout)
        self.assertEqual((back["nb_streamlines"], back["nb_vertices"]), (len(want), sum(len(lines[i]) for i in want)))
        os.remove(out)
        env = {"HORIZON_SPILL_DIR": "off", "HORIZON_SPILL_MIN_BYTES": "0", "HORIZON_MEMORY_AVAILABLE_MB": "0"}
        p = run("--plugin-dir", d, "filter", tck, "--min-length", "30", "-o", out, env=env)
        self.assertEqual(p.returncode, 1, p.stderr)
        line = p.stderr.strip()
        self.assertNotIn("\n", line)
        self.assertIn(f"{out}: the streamlines to write, copied first for ", line)
        self.assertIn("no temporary file (HORIZON_SPILL_DIR=off)", line)
        self.assertFalse(os.path.exists(out))

    def test_a_third_party_clustering_plugin_in_scenes_and_explore(self):
        import numpy as np
        rng = np.random.default_rng(4)
        tck, d = self.tck_and_template([np.cumsum(rng.normal(size=(int(rng.integers(5, 80)), 3)), axis=0) for _ in range(100)],
                                       "tpl_length_clustering.so")
        scene = {"objects": [{"type": "streamlines", "file": tck, "clustering": {"algorithm": "length", "params": {"bin_width": 5}}}]}
        for params, ok, where in (({"bin_width": 5}, True, None), ({"bin_width": -1}, False, "objects[0].clustering.params.bin_width"),
                                  ({"width": 1}, False, "it has: bin_width")):
            scene["objects"][0]["clustering"]["params"] = params
            with open(self.path("s.json"), "w") as f:
                json.dump(scene, f)
            p = run("render", self.path("s.json"), "-o", self.path("s.png"), "--size", "64x48", "--force", "--plugin-dir", d, timeout=120)
            self.assertEqual(p.returncode == 0, ok, p.stderr)
            if where:
                self.assertIn(where, p.stderr)
        # Repeat (C) runs any plugin again on what is shown, with its own
        # parameters: the template has no `thresholds` (issue 53: it failed).
        from hztest import xvfb_run
        with open(self.path("rep.txt"), "w") as f:
            f.write("wait 2\nexpand 0\nwait 2\nkey c\nwait 5\nquit\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # (Mesa's GLX driver, as in test_render's window tests)
        p = xvfb_run([HORIZON, "view", tck, "--explore", "--algorithm", "length", "--plugin-dir", d, "--script", self.path("rep.txt"),
                      "--size", "480x320"], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertNotIn("failed", p.stderr)
        self.assertIn("2 clustering round(s)", p.stdout)
        # view --explore checks the plugin and its parameters before opening anything.
        p = run("view", tck, "--explore", "--algorithm", "length", "--param", "bin_width=0", "--plugin-dir", d)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("bin_width: 0 is outside", p.stderr)
        p = run("view", tck, "--explore", "--algorithm", "nope")
        self.assertIn("no clustering plugin has this id", p.stderr)

    def test_a_broken_cluster_tree_is_refused_not_read(self):
        """A clustering plugin's result is checked against the tree's
        contract before the host reads it (issue 53: a member index past
        the input made `cluster` write past its label table and exit 0).
        Each lie is one line naming the plugin and what is wrong, exit 1,
        nothing written; from `cluster` and from a scene alike. The honest
        tree passes, with the labels its rule gives (index mod 2, mod 4)."""
        import numpy as np
        rng = np.random.default_rng(6)
        lines = [np.cumsum(rng.normal(size=(int(rng.integers(5, 30)), 3)), axis=0) for _ in range(40)]
        tck, _ = self.tck_and_template(lines, "tpl_length_clustering.so")
        d = os.path.join(BUILD, "tests", "fixtures", "clustering-lies")
        labels = self.path("l.csv")
        p = run("cluster", tck, "--algorithm", "clustering-lies", "--labels", labels, "--plugin-dir", d)
        self.assertEqual(p.returncode, 0, p.stderr)
        rows = np.loadtxt(labels, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
        np.testing.assert_array_equal(rows[:, 1], np.arange(40) % 2)
        np.testing.assert_array_equal(rows[:, 2], np.arange(40) % 4)
        os.remove(labels)
        whats = {1: "node 3 holds index 40 of 40 streamlines", 2: "streamline 4 is twice in level 2",
                 3: "node 6 is at level 3 of 2", 4: "node 3 holds streamline 1, which its parent (node 1) lacks",
                 5: "1073741824 levels below the root (1 to 64)", 6: "119 members in all, for 40 streamlines in 3 levels",
                 7: "node 3 has parent 5 (a node before it)"}
        for lie, what in whats.items():
            with self.subTest(lie=lie):
                p = run("cluster", tck, "--algorithm", "clustering-lies", "--param", f"lie={lie}", "--labels", labels, "--plugin-dir", d)
                self.assertEqual(p.returncode, 1, p.stderr)
                line = p.stderr.strip()
                self.assertNotIn("\n", line)
                self.assertIn("org.horizon.test.clustering-lies: returned a broken cluster tree: " + what, line)
                self.assertFalse(os.path.exists(labels))
        scene = {"objects": [{"type": "streamlines", "file": tck,
                              "clustering": {"algorithm": "clustering-lies", "params": {"lie": 4}}}]}
        with open(self.path("s.json"), "w") as f:
            json.dump(scene, f)
        p = run("render", self.path("s.json"), "-o", self.path("s.png"), "--size", "64x48", "--plugin-dir", d, timeout=120)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("returned a broken cluster tree: node 3 holds streamline 1", p.stderr)
        self.assertFalse(os.path.exists(self.path("s.png")))

    def test_an_exception_out_of_a_plugin_names_the_plugin_the_call_and_the_file(self):
        """A C++ plugin that lets an exception cross the ABI is named with
        its file, the call and the data file, in one line (issue 53: the
        user saw `horizon: error: stof`): a loader's open(), a clustering's
        run() from `cluster` and from a scene."""
        import numpy as np
        data = self.path("x.throws")
        with open(data, "w") as f:
            f.write("anything")
        d = os.path.join(BUILD, "tests", "fixtures", "loader-throws")
        p = run("--plugin-dir", d, "info", data)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertEqual(p.stderr.strip(), f"horizon: error: {data}: the plugin org.horizon.test.loader-throws "
                         f"({os.path.join(d, 'fx_loader_throws.so')}) let a C++ exception out of open() (exceptions must not cross the "
                         "ABI; report it to its author): stof")
        rng = np.random.default_rng(7)
        tck, _ = self.tck_and_template([np.cumsum(rng.normal(size=(10, 3)), axis=0) for _ in range(20)], "tpl_length_clustering.so")
        d = os.path.join(BUILD, "tests", "fixtures", "clustering-lies")
        p = run("cluster", tck, "--algorithm", "clustering-lies", "--param", "lie=8", "--labels", self.path("l.csv"), "--plugin-dir", d)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
        self.assertIn(f"{tck}: the plugin org.horizon.test.clustering-lies (", p.stderr)
        self.assertIn("let a C++ exception out of run()", p.stderr)
        self.assertTrue(p.stderr.strip().endswith(": stoi"), p.stderr)
        self.assertFalse(os.path.exists(self.path("l.csv")))
        with open(self.path("s.json"), "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": tck, "clustering": {"algorithm": "clustering-lies", "params": {"lie": 8}}}]}, f)
        p = run("render", self.path("s.json"), "-o", self.path("s.png"), "--size", "64x48", "--plugin-dir", d, timeout=120)
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("let a C++ exception out of run()", p.stderr)

    def test_an_init_that_changes_the_working_directory_changes_nothing(self):
        """Relative paths are the user's: a plugin whose init() moves the
        working directory (here to /) must not send inputs and outputs
        elsewhere (issue 53); the host puts it back and names the plugin."""
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(FIXTURES, "fx_init_chdir.so"), d)
        work = self.path("work")
        os.mkdir(work)
        import numpy as np
        from hztest import tck_bytes
        with open(os.path.join(work, "in.tck"), "wb") as f:
            f.write(tck_bytes([np.arange(30, dtype=np.float32).reshape(10, 3)]))
        p = subprocess.run([HORIZON, "--plugin-dir", d, "convert", "in.tck", "out.trk"], cwd=work, capture_output=True, text=True, timeout=60,
                           env=environment("convert", env={"HORIZON_PLUGIN_CACHE": "off"}))
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertTrue(os.path.exists(os.path.join(work, "out.trk")))
        self.assertFalse(os.path.exists("/out.trk"))
        self.assertIn("fx_init_chdir.so: init() changed the working directory; it was put back", p.stderr)

    def test_a_default_outside_its_own_schema_is_refused_at_load(self):
        # fx_broken_shader's gain defaults to 2 in [0, 1]: `--param gain=2`
        # is refused, so the default must be too (issue 53), with the reason
        # in `horizon plugins`; the validator still examines it.
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(FIXTURES, "fx_broken_shader.so"), d)
        rep = run_json("plugins", "--json", "--plugin-dir", d)
        self.assertNotIn("org.horizon.test.fixture", [q["id"] for q in rep["plugins"]])
        why = [r["reason"] for r in rep["rejected"] if r["file"].endswith("fx_broken_shader.so")]
        self.assertEqual(len(why), 1, rep["rejected"])
        self.assertIn("org.horizon.test.fixture: the default of parameter gain breaks its own schema: gain: 2 is outside [0, 1]", why[0])

    def test_a_crash_after_the_trial_names_the_plugin(self):
        # The plugin loads and passes its trial, then crashes when called:
        # the command still dies (nothing is known about its state), but
        # says which plugin did it.
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(FIXTURES, "fx_eval_crash.so"), d)
        case = json.dumps({"id": "a", "model": "fixture", "params": {"gain": 0.5}, "N": [0, 0, 1], "L": [0, 0, 1], "V": [0, 0, 1]})
        from hztest import environment
        p = subprocess.run([HORIZON, "--plugin-dir", d, "brdf", "--shader", "org.horizon.test.fixture"], input=case + "\n",
                           capture_output=True, text=True, timeout=60, env=environment("brdf"))
        self.assertEqual(p.returncode, -11, p.stderr)
        self.assertIn("the plugin " + os.path.join(d, "fx_eval_crash.so") + " crashed (SIGSEGV)", p.stderr)

    def misbehaving(self, name, *args, timeout=60):
        """Runs horizon with the SDK's C loader template misbehaving after its
        trial load as `name` (tests/fixtures/plugins/misbehaving_loader.c)
        alone in a plugin folder, no trial list, a 2 s plugin timeout."""
        d = os.path.join(BUILD, "tests", "fixtures", "misbehaving", name)
        self.assertTrue(os.path.isdir(d), d)
        env = {**os.environ, "HORIZON_PLUGIN_CACHE": "off"}
        p = run("--plugin-dir", d, "--plugin-timeout", "2", *args, timeout=timeout, env=env)
        return p, os.path.join(d, f"fx_{name}.so")

    def tck_without_extension(self):
        """A TCK named data.bin: no loader claims it by extension, so every
        loader's probe() is asked."""
        path = self.path("data.bin")
        with open(path, "wb") as f:
            f.write(b"mrtrix tracks\ncount: 1\ndatatype: Float32LE\nfile: . 64\nEND\n".ljust(64, b" "))
            f.write(struct.pack("<12f", 0, 0, 0, 1, 0, 0, 2, 0, 0, float("nan"), float("nan"), float("nan")))
            f.write(struct.pack("<3f", float("inf"), float("inf"), float("inf")))
        return path

    def test_a_probe_that_crashes_or_hangs_is_named_and_the_others_still_asked(self):
        """probe() after the trial, on a file no extension claims: the plugin
        whose probe crashes or does not return within the plugin timeout is
        named in one warning and not asked again; the TCK loader still
        recognises the file (it used to kill the command with SIGSEGV, or
        hang it for ever)."""
        data = self.tck_without_extension()
        for name, what in (("probe_crash", "crashed (SIGSEGV) in probe()"), ("probe_hang", "did not return from probe() within 2 s")):
            with self.subTest(name=name):
                t0 = time.monotonic()
                p, so = self.misbehaving(name, "info", data, "--json")
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertLess(time.monotonic() - t0, 30)
                self.assertEqual(json.loads(p.stdout)["nb_streamlines"], 1)
                lines = p.stderr.strip().splitlines()
                self.assertEqual(len(lines), 1, p.stderr)
                self.assertIn(f"data.bin: the plugin org.example.loader.hzt ({so}) {what}: not asked again", lines[0])
                p, _ = self.misbehaving(name, "plugins", "--json")
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertIn("org.example.loader.hzt", [x["id"] for x in json.loads(p.stdout)["plugins"]])

    def test_a_crash_in_a_later_get_interface_rejects_the_plugin_and_every_command_goes_on(self):
        """get_interface() that crashes on its second call in a process (the
        trial load makes one): the host's load survives it, rejects the
        plugin with the call named (`horizon plugins` says so), and every
        command goes on without it."""
        p, so = self.misbehaving("interface_crash", "plugins", "--json")
        self.assertEqual(p.returncode, 0, p.stderr)
        rejected = {r["file"]: r["reason"] for r in json.loads(p.stdout)["rejected"]}
        self.assertIn("crashed (SIGSEGV) in get_interface()", rejected.get(so, ""), rejected)
        p, _ = self.misbehaving("interface_crash", "info", self.tck_without_extension(), "--json")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(json.loads(p.stdout)["nb_streamlines"], 1)
        # Vouched for by the trial list (it behaved then), it crashes in this
        # process: rejected, and forgotten by the list (tried again next time).
        lst = self.path("trials.json")
        calm = {"HORIZON_PLUGIN_CACHE": lst, "HZ_FIXTURE_CALM": "1"}
        for env, want in ((calm, 1), ({**calm, "HZ_FIXTURE_CALM": ""}, 0), (calm, 1)):
            p = run("--plugin-dir", os.path.dirname(so), "plugins", "--json", env=env)
            self.assertEqual(p.returncode, 0, p.stderr)
            rep = json.loads(p.stdout)
            self.assertEqual(so in [x["file"] for x in rep["plugins"]], bool(want), rep["rejected"])
        self.assertEqual(rep["trial_loads"], 1, "tried again after its crash, not taken on the list's word")

    def test_tables_too_short_for_what_they_hold(self):
        """A descriptor or a loader table whose struct_size is below the 1.0
        layout is rejected with the reason in `horizon plugins`; an
        extension table too short for its function is not used (its function
        crashes): the loader still reads, through its core table."""
        for name, reason in (("short_descriptor", "struct_size too small"), ("short_table", "table struct_size 8 <")):
            with self.subTest(name=name):
                p, so = self.misbehaving(name, "plugins", "--json")
                self.assertEqual(p.returncode, 0, p.stderr)
                rep = json.loads(p.stdout)
                self.assertNotIn(so, [x["file"] for x in rep["plugins"]])
                rejected = {r["file"]: r["reason"] for r in rep["rejected"]}
                self.assertIn(reason, rejected.get(so, ""), rejected)
        data = self.path("two.hzt")
        with open(data, "w") as f:
            f.write("hzt 1\n3\n0 0 0\n1 0 0\n2 0.5 0\n2\n-1 -2 -3\n4 5 6\n")
        p, so = self.misbehaving("short_extension", "info", data, "--json")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(json.loads(p.stdout)["nb_streamlines"], 2)
        out = self.path("two.tck")
        p, _ = self.misbehaving("short_extension", "convert", data, out)
        self.assertEqual(p.returncode, 0, p.stderr)
        import nibabel as nib
        import numpy as np
        got = list(nib.streamlines.load(out).streamlines)
        np.testing.assert_array_equal(got[0], [[0, 0, 0], [1, 0, 0], [2, 0.5, 0]])
        np.testing.assert_array_equal(got[1], [[-1, -2, -3], [4, 5, 6]])

    def test_a_destructor_that_crashes_or_hangs_at_exit_keeps_the_commands_status(self):
        """A plugin's destructor at exit that crashes or never returns: the
        command's output and exit status stand, with one warning naming the
        plugin (a finished command used to die of SIGSEGV, or never end)."""
        data = self.tck_without_extension()
        for name, what in (("exit_crash", "crashed (SIGSEGV) at exit"), ("exit_hang", "did not let the process end")):
            with self.subTest(name=name):
                t0 = time.monotonic()
                p, so = self.misbehaving(name, "info", data, "--json")
                self.assertLess(time.monotonic() - t0, 30)
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertEqual(json.loads(p.stdout)["nb_streamlines"], 1)
                self.assertEqual(p.stderr.strip().splitlines(), [p.stderr.strip()])
                self.assertIn(f"warning: the plugin {so} {what}", p.stderr)
                p, _ = self.misbehaving(name, "info", self.path("missing.tck"))
                self.assertEqual(p.returncode, 1, "a failed command's status stands too")
                self.assertIn("missing.tck: no such file", p.stderr)
                self.assertIn(f"the plugin {so} {what}", p.stderr)

    def test_a_changed_library_of_a_plugin_is_tried_again(self):
        """The trial list vouches for a plugin with the libraries it needs as
        they were: after an upgrade of one (here its own library, swapped
        for a build that crashes) the plugin is tried again and rejected,
        instead of loaded untried into the host, which it would kill."""
        lst = self.path("trials.json")
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(FIXTURES, "fx_dep.so"), d)
        deps = os.path.join(os.path.dirname(FIXTURES), "deps")
        lib = os.path.join(d, "libhzfxdep.so.1")
        shutil.copy(os.path.join(deps, "libhzfxdep_ok.so"), lib)
        env = {"HORIZON_PLUGIN_CACHE": lst}

        def listing():
            return run_json("--plugin-dir", d, "plugins", "--json", env=env)

        first = listing()
        self.assertIn("org.horizon.test.fixture", {p["id"] for p in first["plugins"]})
        with open(lst) as f:
            entry = next(e for e in json.load(f)["passed"] if e["file"] == os.path.join(d, "fx_dep.so"))
        self.assertIn(lib, [dep for dep, _ in entry["deps"]])
        self.assertTrue(any(os.path.basename(dep).startswith("libc.so") for dep, _ in entry["deps"]), entry["deps"])
        self.assertEqual(listing()["trial_loads"], 0)
        os.replace(shutil.copy(os.path.join(deps, "libhzfxdep_crash.so"), lib + ".new"), lib)
        again = listing()
        self.assertEqual(again["trial_loads"], 1)
        self.assertNotIn("org.horizon.test.fixture", {p["id"] for p in again["plugins"]})
        self.assertEqual([(r["file"], "SIGSEGV" in r["reason"]) for r in again["rejected"]], [(os.path.join(d, "fx_dep.so"), True)])

    def test_a_plugin_replaced_after_its_trial_is_not_loaded(self):
        """The file's trial load renames another plugin (one that crashes in
        init) over it before the host loads it: the host loads only the inode
        the trial saw, so it refuses the replacement with a reason, and the
        next command tries the new file (and rejects it)."""
        d = self.path("plugins")
        os.mkdir(d)
        target = os.path.join(d, "fx_replaces_itself.so")
        shutil.copy(os.path.join(FIXTURES, "fx_replaces_itself.so"), target)
        replacement = self.path("replacement.so")
        shutil.copy(os.path.join(FIXTURES, "fx_init_crash.so"), replacement)
        env = {"HORIZON_PLUGIN_CACHE": "off", "HZ_FIXTURE_REPLACEMENT": replacement}
        p = run("--plugin-dir", d, "plugins", "--json", env=env)
        self.assertEqual(p.returncode, 0, p.stderr)
        j = json.loads(p.stdout)
        self.assertFalse(os.path.exists(replacement), "the trial did not replace the file")
        self.assertNotIn("org.horizon.test.fixture", {q["id"] for q in j["plugins"]})
        self.assertEqual([(r["file"], "replaced after its trial" in r["reason"]) for r in j["rejected"]], [(target, True)], j["rejected"])
        j = run_json("--plugin-dir", d, "plugins", "--json", env=env)
        self.assertEqual([(r["file"], "SIGSEGV" in r["reason"]) for r in j["rejected"]], [(target, True)], j["rejected"])

    def test_an_init_that_forks_changes_nothing(self):
        """A plugin whose init() forks (both processes return true) comes
        before one that crashes in init: the forked trial process must not
        report, or the reports shift and the crashing plugin is loaded; nor
        may a process forked in the host go on as a second command."""
        d = self.path("plugins")
        os.mkdir(d)
        shutil.copy(os.path.join(FIXTURES, "fx_init_forks.so"), os.path.join(d, "a_forks.so"))
        shutil.copy(os.path.join(FIXTURES, "fx_init_crash.so"), os.path.join(d, "b_crashes.so"))
        for cache in ("off", self.path("trials.json"), self.path("trials.json")):
            p = run("--plugin-dir", d, "plugins", "--json", env={"HORIZON_PLUGIN_CACHE": cache})
            self.assertEqual(p.returncode, 0, p.stderr)
            j = json.loads(p.stdout)  # one document: no second host printed one
            self.assertIn("org.horizon.test.fixture", {q["id"] for q in j["plugins"] if q["file"].endswith("a_forks.so")})
            self.assertEqual([(os.path.basename(r["file"]), "SIGSEGV" in r["reason"]) for r in j["rejected"]], [("b_crashes.so", True)])

    def test_plugins_in_sub_folders(self):
        """One level of sub-folders is searched (a plugin shipped as a folder);
        a sub-folder's libraries that are not plugins are its own, not
        reported; deeper folders and other files are not looked at."""
        d = self.path("plugins")
        bundle = os.path.join(d, "lambert")
        os.makedirs(os.path.join(bundle, "deeper"))
        shutil.copy(os.path.join(TEMPLATES, "tpl_lambert_shader.so"), bundle)
        shutil.copy(os.path.join(FIXTURES, "fx_no_entry.so"), os.path.join(bundle, "libprivate.so"))
        shutil.copy(os.path.join(FIXTURES, "fx_valid.so"), os.path.join(bundle, "deeper"))
        for name in ("LICENSE.txt", "README.md"):
            with open(os.path.join(bundle, name), "w") as f:
                f.write("text\n")
        shutil.copy(os.path.join(FIXTURES, "fx_no_entry.so"), d)
        j = run_json("--plugin-dir", d, "plugins", "--json")
        mine = [p for p in j["plugins"] if p["file"].startswith(d)]
        self.assertEqual([(p["id"], p["file"]) for p in mine], [("org.example.shader.lambert", os.path.join(bundle, "tpl_lambert_shader.so"))])
        self.assertEqual([r["file"] for r in j["rejected"]], [os.path.join(d, "fx_no_entry.so")])

    def assert_hzt_round_trip(self, plugin_dir, env, text):
        """`text` as x.hzt, converted to x.tck and back to y.hzt through the
        .hzt loader in `plugin_dir`: the same text."""
        with open(self.path("x.hzt"), "w") as f:
            f.write(text)
        for a, b in (("x.hzt", "x.tck"), ("x.tck", "y.hzt")):
            p = run("--plugin-dir", plugin_dir, "convert", self.path(a), self.path(b), env=env)
            self.assertEqual(p.returncode, 0, p.stderr)
        with open(self.path("y.hzt")) as f:
            self.assertEqual(f.read(), text)

    def test_plugins_built_against_abi_1_0(self):
        """The SDK's loader and shader templates as first published, built
        against the ABI 1.0 headers (tests/abi/v1_0): this host (1.x, x > 0)
        loads them (their tables are shorter: fields appended since are read
        only where struct_size covers them), reads and writes through the
        loader, draws with the shader, and validate passes both. (A plugin
        of a future major is refused with its reason: test_bad_plugin_dir.)"""
        d = self.path("old")
        os.mkdir(d)
        for name in ("abi10_text_loader.so", "abi10_lambert_shader.so"):
            shutil.copy(os.path.join(BUILD, "tests", "abi10", name), d)
        env = {"HORIZON_PLUGIN_CACHE": "off"}
        j = run_json("--plugin-dir", d, "plugins", "--json", env=env)
        old = {p["id"]: (p["abi"], p["status"]) for p in j["plugins"] if p["file"].startswith(d)}
        self.assertEqual(old, {"org.example.loader.hzt": ("1.0", "loaded"), "org.example.shader.lambert": ("1.0", "loaded")})
        self.assertEqual(j["rejected"], [])
        self.assert_hzt_round_trip(d, env, "hzt 1\n3\n1 2 3\n2 3.5 4\n3 4 5\n2\n0 0 0\n1 1 1\n")
        scene = self.path("s.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "surface", "builtin": "sphere", "material": {"shader": "org.example.shader.lambert"}}]}, f)
        p = run("--plugin-dir", d, "render", scene, "-o", self.path("s.png"), "--size", "64x48", env={**env, "DISPLAY": ""}, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        for name in ("abi10_text_loader.so", "abi10_lambert_shader.so"):
            p = run("validate", os.path.join(d, name), timeout=300)
            self.assertEqual(p.returncode, 0, p.stdout)

    def test_a_loader_built_against_abi_1_9(self):
        """The SDK's C loader template as released with ABI 1.9 (tests/abi/v1_9),
        whose tables carry what 1.10 moved into extensions (a locate_positions
        slot, HZ_LOADER_WRITES_GAP, hz_streamlines_dst.check): this host loads
        it, reads and writes through it, and gives it what a plain loader gets
        (gap 0: a mapped TCK is copied without its delimiters first); validate
        passes it."""
        d = self.path("v19")
        os.mkdir(d)
        shutil.copy(os.path.join(BUILD, "tests", "abi19", "abi19_text_loader.so"), d)
        env = {"HORIZON_PLUGIN_CACHE": "off"}
        j = run_json("--plugin-dir", d, "plugins", "--json", env=env)
        old = {p["id"]: (p["abi"], p["status"], p["interfaces"]) for p in j["plugins"] if p["file"].startswith(d)}
        self.assertEqual(old, {"org.example.loader.hzt": ("1.9", "loaded", ["hz.loader/1"])})
        # hzt -> TCK (ours, mapped when read back: delimiters in place) -> hzt.
        self.assert_hzt_round_trip(d, env, "hzt 1\n3\n1 2 3\n2 3.5 4\n3 4 5\n0\n2\n0 0 0\n1 1 1\n")
        self.assertTrue(run_json("info", self.path("x.tck"), "--json")["positions_mapped"])
        p = run("validate", os.path.join(d, "abi19_text_loader.so"), timeout=300)
        self.assertEqual(p.returncode, 0, p.stdout)

    def test_a_1_9_source_built_against_today_s_sdk(self):
        """Source compatibility within major 1: the 1.9 loader template's
        source, unchanged, built against today's headers (its 1.9 names only
        deprecated: tests/abi/check_source.py checks the warnings), is a
        plugin of today's ABI that loads, reads and writes, and passes
        validate."""
        d = self.path("v19src")
        os.mkdir(d)
        shutil.copy(os.path.join(BUILD, "tests", "abi19src", "abi19src_text_loader.so"), d)
        env = {"HORIZON_PLUGIN_CACHE": "off"}
        j = run_json("--plugin-dir", d, "plugins", "--json", env=env)
        mine = {p["id"]: (p["abi"].split(".")[0], p["status"]) for p in j["plugins"] if p["file"].startswith(d)}
        self.assertEqual(mine, {"org.example.loader.hzt": ("1", "loaded")})
        self.assert_hzt_round_trip(d, env, "hzt 1\n3\n1 2 3\n2 3.5 4\n3 4 5\n0\n2\n0 0 0\n1 1 1\n")
        p = run("validate", os.path.join(d, "abi19src_text_loader.so"), timeout=300)
        self.assertEqual(p.returncode, 0, p.stdout)

    def test_a_trial_list_that_is_not_a_file_is_not_used(self):
        # A FIFO would block every command; a folder made every command fail.
        fifo, folder = self.path("fifo"), self.path("folder")
        os.mkfifo(fifo)
        os.mkdir(folder)
        for where in (fifo, folder):
            j = run_json("plugins", "--json", env={"HORIZON_PLUGIN_CACHE": where}, timeout=30)
            self.assertTrue(BUNDLED_IDS <= {p["id"] for p in j["plugins"]})
        self.assertTrue(os.path.isdir(folder))

    def test_a_world_writable_folder_is_not_loaded(self):
        d = self.path("open")
        os.mkdir(d)
        shutil.copy(os.path.join(TEMPLATES, "tpl_lambert_shader.so"), d)
        os.chmod(d, 0o777)
        j = run_json("--plugin-dir", d, "plugins", "--json")
        self.assertNotIn("org.example.shader.lambert", {p["id"] for p in j["plugins"]})
        self.assertTrue(any("world-writable" in r["reason"] and r["file"].endswith("tpl_lambert_shader.so") for r in j["rejected"]), j["rejected"])
        os.chmod(d, 0o755)
        j = run_json("--plugin-dir", d, "plugins", "--json")
        self.assertIn("org.example.shader.lambert", {p["id"] for p in j["plugins"]})

    def test_bad_plugin_dir(self):
        d = self.path("plugins")
        os.mkdir(d)
        open(os.path.join(d, "empty.so"), "wb").close()
        with open(os.path.join(d, "text.so"), "w") as f:
            f.write("not a plugin\n")
        with open(os.path.join(d, "readme.txt"), "w") as f:
            f.write("This directory holds plugins.\n")
        with open(os.path.join(d, "random.so"), "wb") as f:
            f.write(os.urandom(4096) .replace(b"\x7fELF", b"xxxx"))
        for name in ["fx_no_entry", "fx_wrong_abi_symbol", "fx_wrong_abi_field", "fx_init_crash", "fx_init_throws"]:
            shutil.copy(os.path.join(FIXTURES, name + ".so"), d)
        # A good object patched to claim another CPU architecture (e_machine = AArch64).
        arm = os.path.join(d, "arm64.so")
        shutil.copy(os.path.join(TEMPLATES, "tpl_lambert_shader.so"), arm)
        with open(arm, "r+b") as f:
            f.seek(18)
            f.write(bytes([183, 0]))
        shutil.copy(os.path.join(TEMPLATES, "tpl_length_clustering.so"), d)
        # Not candidates: a hidden leftover (it must not shadow anything) and
        # files that are not NAME.so (a licence beside a plugin).
        shutil.copy(os.path.join(FIXTURES, "fx_init_crash.so"), os.path.join(d, ".tpl_lambert_shader.so.old"))
        with open(os.path.join(d, "LICENSE.txt"), "w") as f:
            f.write("MIT\n")
        # A world-writable plugin file is not loaded.
        shutil.copy(os.path.join(TEMPLATES, "tpl_lambert_shader.so"), os.path.join(d, "open.so"))
        os.chmod(os.path.join(d, "open.so"), 0o666)

        p = run("--plugin-dir", d, "plugins", "--json")
        self.assertEqual(p.returncode, 0, p.stderr)
        import json
        j = json.loads(p.stdout)
        reasons = {os.path.basename(r["file"]): r["reason"] for r in j["rejected"]}
        for name in ("readme.txt", "LICENSE.txt", ".tpl_lambert_shader.so.old"):
            self.assertNotIn(name, reasons)
        expect = {
            "open.so": "world-writable",
            "empty.so": "empty",
            "random.so": "not a shared object",
            "text.so": "text file",
            "fx_no_entry.so": "no 'hz_plugin_entry_v1'",
            "fx_wrong_abi_symbol.so": "ABI 2",
            "fx_wrong_abi_field.so": "ABI 2",
            "fx_init_crash.so": "crashed (signal SIGSEGV)",
            "fx_init_throws.so": "threw a C++ exception",
            "arm64.so": "AArch64",
        }
        for name, needle in expect.items():
            self.assertIn(name, reasons, f"{name} not rejected: {j}")
            self.assertIn(needle, reasons[name])
            self.assertNotIn("\n", reasons[name])
        ids = {p["id"] for p in j["plugins"]}
        self.assertIn("org.example.clustering.length", ids)
        self.assertTrue(BUNDLED_IDS <= ids)
        # Text output: one line per rejected file, naming it.
        t = run("--plugin-dir", d, "plugins")
        self.assertEqual(t.returncode, 0)
        for name in expect:
            self.assertEqual(sum(1 for l in t.stdout.splitlines() if name in l and ":" in l), 1, name)

    def test_plugin_path_variable_and_user_dir(self):
        d = self.path("env")
        os.mkdir(d)
        shutil.copy(os.path.join(TEMPLATES, "tpl_hzt_loader.so"), d)
        j = run_json("plugins", "--json", env={"HORIZON_PLUGIN_PATH": "/does/not/exist:" + d})
        self.assertIn("org.example.loader.hzt", {p["id"] for p in j["plugins"]})
        user = self.path("xdg")
        os.makedirs(os.path.join(user, "horizon", "plugins"))
        shutil.copy(os.path.join(TEMPLATES, "tpl_lambert_shader.so"), os.path.join(user, "horizon", "plugins"))
        j = run_json("plugins", "--json", env={"HZ_TEST_XDG": user})
        self.assertIn("org.example.shader.lambert", {p["id"] for p in j["plugins"]})

    def test_first_dir_wins_for_duplicate_ids(self):
        d = self.path("dup")
        os.mkdir(d)
        shutil.copy(os.path.join(BUNDLED, "hz_loader_tck.so"), os.path.join(d, "my_tck.so"))
        j = run_json("--plugin-dir", d, "plugins", "--json")
        tck = [p for p in j["plugins"] if p["id"] == "org.horizon.loader.tck"]
        self.assertEqual(len(tck), 1)
        self.assertTrue(tck[0]["file"].endswith("my_tck.so"))
        self.assertTrue(any("duplicate plugin id" in r["reason"] for r in j["rejected"]))

    def test_hanging_init_is_rejected_after_the_timeout(self):
        d = self.path("hang")
        os.mkdir(d)
        shutil.copy(os.path.join(FIXTURES, "fx_init_hang.so"), d)
        j = run_json("--plugin-dir", d, "--plugin-timeout", "1", "plugins", "--json", timeout=30)
        self.assertIn("hung", j["rejected"][0]["reason"])
        # The files after it (the bundled dir) are still tried and loaded: one
        # child trial-loads them all in turn, and a new one goes on after a hang.
        self.assertEqual(len(j["rejected"]), 1, j["rejected"])
        self.assertTrue(BUNDLED_IDS <= {p["id"] for p in j["plugins"]})


if __name__ == "__main__":
    unittest.main()
