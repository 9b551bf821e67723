"""`horizon validate`: passes every bundled plugin and the SDK templates,
fails broken fixtures naming the failing check, survives crashes and hangs."""
import glob
import json
import os
import shutil
import subprocess
import unittest

from hztest import BUILD, BUNDLED, FIXTURES, HORIZON, TEMPLATES, TempDirTest, environment, make_tractogram, run


def checks(report):
    return {c["check"]: c for c in report["checks"]}


class ValidateTest(TempDirTest):
    def validate(self, path, *extra, timeout=300):
        p = run("validate", path, "--json", *extra, timeout=timeout)
        return p.returncode, json.loads(p.stdout)

    def samples(self):
        """A small sample file per mesh and image format, for the loader
        checks that read one (--data): written here with nibabel, PIL and by
        hand, not by the plugins under test."""
        import nibabel as nib
        import numpy as np
        v = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [0, 0, 10]], np.float32)
        f = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]], np.int32)
        out = {}
        g = nib.gifti.GiftiImage(darrays=[nib.gifti.GiftiDataArray(v, intent="NIFTI_INTENT_POINTSET"),
                                          nib.gifti.GiftiDataArray(f, intent="NIFTI_INTENT_TRIANGLE")])
        out["gifti"] = self.path("s.surf.gii")
        nib.save(g, out["gifti"])
        out["freesurfer"] = self.path("lh.white")
        nib.freesurfer.write_geometry(out["freesurfer"], v, f)
        out["plyobj"] = self.path("s.obj")
        with open(out["plyobj"], "w") as fh:
            fh.writelines([f"v {a} {b} {c}\n" for a, b, c in v] + [f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f])
        import base64
        import json as js
        buf = v.tobytes() + f.astype(np.uint32).tobytes()
        gltf = {"asset": {"version": "2.0"}, "buffers": [{"uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode(),
                                                          "byteLength": len(buf)}],
                "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 48}],
                "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [10, 10, 10]},
                              {"bufferView": 1, "componentType": 5125, "count": 12, "type": "SCALAR"}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}], "nodes": [{"mesh": 0}],
                "scenes": [{"nodes": [0]}], "scene": 0}
        out["gltf"] = self.path("s.gltf")
        with open(out["gltf"], "w") as fh:
            js.dump(gltf, fh)
        import h5py  # (a PAM5 file, as dipy.io.peaks.save_peaks writes one)
        out["pam5"] = self.path("s.pam5")
        with h5py.File(out["pam5"], "w") as fh:
            fh.attrs["version"] = "0.0.1"
            g = fh.create_group("pam")
            g.create_dataset("peak_dirs", data=np.tile([1.0, 0.0, 0.0], (4, 3, 2, 2, 1)), chunks=True)
            g.create_dataset("peak_values", data=np.linspace(0, 1, 48).reshape(4, 3, 2, 2), chunks=True)
            g.create_dataset("affine", data=np.diag([2.0, 2.0, 2.0, 1.0]))
        # (images: not yet. With a sample PNG three loader checks fail: the
        # validator reads HZ_DATA_IMAGE files through paths written for
        # volumes, "no reader for this kind"; a known gap of the validator.)
        return out

    def test_bundled_plugins_pass(self):
        files = sorted(glob.glob(os.path.join(BUNDLED, "*.so")))
        self.assertGreaterEqual(len(files), 1)
        samples = self.samples()
        # What may be skipped, and why: only checks that do not apply to the
        # plugin (a mesh loader reads no streamlines). A check skipped for
        # any other reason, or a new skip, fails here.
        not_applicable = ("does not offer HZ_EXT_DELIMITED_STREAMLINES", "does not offer HZ_EXT_MAPPED_POSITIONS",
                          "does not offer HZ_EXT_CHECKED_READ", "does not offer HZ_EXT_OPEN_TASK",
                          "does not offer HZ_EXT_WRITE_SELECTION", "does not write streamlines or volumes",
                          "no read_streamlines", "reads neither streamlines nor volumes", "not claimed")
        for f in files:
            with self.subTest(plugin=os.path.basename(f)):
                kind = os.path.basename(f)[len("hz_loader_"):-3] if os.path.basename(f).startswith("hz_loader_") else ""
                extra = ["--data", samples[kind]] if kind in samples else []
                # Each check's time limit raised from 60 s to 240: the PAM5
                # loader reads in a helper process (libhdf5 aborts on some
                # damaged files), and the malformed-input check's 1008 variants
                # are 1008 helpers: 13 s in Release, 32 s under ASan on an
                # idle machine, over 60 under ASan beside the mutation check
                # (stop 64's CI: "hung (killed after the time limit)").
                rc, rep = self.validate(f, *extra, "--timeout", "240", timeout=900)
                failed = [c for c in rep["checks"] if c["status"] not in ("passed", "skipped")]
                self.assertEqual(failed, [])
                self.assertEqual(rc, 0)
                self.assertTrue(rep["ok"])
                allowed = not_applicable + (("no sample file",) if kind == "images" else ())
                odd = [(c["check"], c["reason"]) for c in rep["checks"] if c["status"] == "skipped" and not c["reason"].startswith(allowed)]
                self.assertEqual(odd, [])

    def test_glsl_that_was_not_compiled_is_not_a_pass(self):
        # No headless OpenGL (no EGL vendor): the GPU check fails, unless the
        # author says --no-gpu (then it is reported skipped).
        shader = os.path.join(TEMPLATES, "tpl_lambert_shader.so")
        p = run("validate", shader, "--json", env={"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent.json"}, timeout=300)
        self.assertEqual(p.returncode, 1)
        c = checks(json.loads(p.stdout))["shader-gpu-equals-cpu"]
        self.assertEqual(c["status"], "failed")
        self.assertIn("--no-gpu", c["reason"])
        p = run("validate", shader, "--json", "--no-gpu", env={"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent.json"}, timeout=300)
        self.assertEqual(p.returncode, 0)
        self.assertEqual(checks(json.loads(p.stdout))["shader-gpu-equals-cpu"]["status"], "skipped")

    def test_broken_glsl_fails_at_the_snippets_line(self):
        """Line 3 of the fixture's snippet uses an undeclared name: with
        headless OpenGL (the driver's compiler, in the GPU check) and without
        it (glslang, which needs no GPU) validate fails naming that line of
        the snippet, not a line of the host's assembled program; rendering
        with the shader says the same."""
        shader = os.path.join(FIXTURES, "fx_broken_glsl.so")
        for env, gpu in (({}, True), ({"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent.json"}, False)):
            p = run("validate", shader, "--json", env=env, timeout=300)
            self.assertEqual(p.returncode, 1, p.stderr)
            c = checks(json.loads(p.stdout))
            self.assertEqual(c["shader-glsl-compiles"]["status"], "failed")
            self.assertIn("the plugin's GLSL snippet, line 3:", c["shader-glsl-compiles"]["reason"])
            self.assertIn("not_declared", c["shader-glsl-compiles"]["reason"])
            if gpu:
                self.assertIn("the plugin's GLSL snippet, line 3, column", c["shader-gpu-equals-cpu"]["reason"])
        scene = self.path("scene.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "surface", "builtin": "sphere", "material": {"shader": "org.horizon.test.fixture"}}]}, f)
        p = run("--plugin-dir", os.path.dirname(shader), "render", scene, "-o", self.path("x.png"), env={"HORIZON_PLUGIN_CACHE": "off"}, timeout=120)
        self.assertEqual(p.returncode, 1)
        self.assertIn("the plugin's GLSL snippet, line 3, column", p.stderr)

    def test_every_bundled_shader_compiles_as_strict_glsl(self):
        # glslang holds the programs to GLSL 4.10 as written (Mesa accepts
        # more, e.g. line continuations, which came in 4.20).
        for name in ("hz_shader_classic.so", "hz_shader_glass.so", "hz_shader_principled.so"):
            rc, rep = self.validate(os.path.join(BUNDLED, name))
            self.assertEqual(checks(rep)["shader-glsl-compiles"]["status"], "passed", name)

    def test_bundled_loader_runs_the_loader_checks(self):
        rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_tck.so"))
        c = checks(rep)
        for name in ["loader-probe-purity", "loader-roundtrip", "loader-malformed-survival",
                     "loader-buffer-too-small", "loader-cancel", "exports-only-entry", "loader-writes-selection"]:
            self.assertEqual(c[name]["status"], "passed", name)

    def test_a_short_read_need_not_poll_a_cancelled_task(self):
        """hz_task lets a call of less than ~50 ms of work finish without
        polling: a TCK loader that never polls its task passes loader-cancel
        (it used to fail it), saying why; the bundled one, which returns
        HZ_E_CANCELLED at once, passes it plainly."""
        rc, rep = self.validate(os.path.join(BUILD, "tests", "fixtures", "ignores-task", "fx_tck_ignores_task.so"))
        c = checks(rep)["loader-cancel"]
        self.assertEqual(c["status"], "passed", c)
        self.assertIn("read_streamlines finished its short read", c["reason"])
        self.assertEqual(rc, 0, [x for x in rep["checks"] if x["status"] == "failed"])
        rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_tck.so"))
        c = checks(rep)["loader-cancel"]
        self.assertEqual((c["status"], c["reason"]), ("passed", ""))

    def test_zero_copy_contract_is_checked(self):
        # TRX offers HZ_EXT_MAPPED_POSITIONS: the located bytes, CRC and read_offsets are checked.
        rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_trx.so"))
        self.assertEqual(checks(rep)["loader-locate-positions"]["status"], "passed")
        self.assertIn("maps the plain layout", checks(rep)["loader-locate-positions"]["reason"])
        # TCK maps only when the host accepts the delimited layout: each streamline's
        # bytes and its all-NaN delimiter are checked against a copying read.
        rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_tck.so"))
        c = checks(rep)["loader-locate-positions"]
        self.assertEqual(c["status"], "passed")
        self.assertEqual(c["reason"], "declines the plain layout; maps the delimited layout; vouches for exact bounds")
        # Given a TCK as nibabel writes it (data at byte 67), the loader offers
        # the extent only to a host that accepts unaligned offsets, and flags it.
        import nibabel as nib
        import numpy as np
        rng = np.random.default_rng(2)
        nib_tck = self.path("nib.tck")
        nib.streamlines.save(nib.streamlines.Tractogram([rng.normal(size=(int(rng.integers(2, 30)), 3)).astype(np.float32)
                                                         for _ in range(50)], affine_to_rasmm=np.eye(4)), nib_tck)
        rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_tck.so"), "--data", nib_tck)
        c = checks(rep)["loader-locate-positions"]
        self.assertEqual(c["status"], "passed", c)
        self.assertEqual(c["reason"], "declines the plain layout; declines the delimited layout too; maps an unaligned extent; "
                                      "vouches for exact bounds")
        # TCK and TRK vouch for the positions they copy (HZ_EXT_CHECKED_READ: exact
        # bounds, checked against the validator's own pass); TRX does not offer it and
        # leaves its decoded copies to the host.
        for name, status, reason in (("tck", "passed", "vouches for exact bounds"), ("trk", "passed", "vouches for exact bounds"),
                                     ("trx", "skipped", "does not offer HZ_EXT_CHECKED_READ")):
            rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_%s.so" % name))
            c = checks(rep)["loader-vouched-positions"]
            self.assertEqual(c["status"], status, (name, c))
            self.assertTrue(c["reason"].startswith(reason), (name, c))
        # The same loader vouching for bounds 1 mm too wide fails exactly that check.
        self.assert_fails_only("fx_tck_lying_bounds.so", {
            "loader-locate-positions": "vouches for bounds other than its positions' (x)",
            "loader-vouched-positions": "vouches for bounds other than the positions it wrote (x)"})

    def assert_fails_only(self, fixture, reasons):
        """The validator fails `fixture` on the checks of `reasons` alone, each
        with its reason in its message."""
        rc, rep = self.validate(os.path.join(FIXTURES, fixture))
        self.assertEqual(rc, 1)
        failed = {c["check"]: c["reason"] for c in rep["checks"] if c["status"] == "failed"}
        self.assertEqual(sorted(failed), sorted(reasons), failed)
        for check, reason in reasons.items():
            self.assertIn(reason, failed[check])

    def test_vouch_past_struct_size_fails(self):
        # HZ_EXT_CHECKED_READ: a loader that writes into a check record whose
        # struct_size has no room for it.
        self.assert_fails_only("fx_tck_ignores_sizes.so",
                               {"loader-vouched-positions": "writes a check record whose struct_size has no room for it"})

    def test_writer_ignoring_the_gap_fails(self):
        # HZ_EXT_DELIMITED_STREAMLINES: a loader that offers it but writes the
        # vertex after each streamline as a point. Both checks that give it
        # streamlines with gap 1 fail it: its write() and its
        # write_selection() (HZ_EXT_WRITE_SELECTION), and no other.
        self.assert_fails_only("fx_tck_ignores_gap.so", {"loader-writes-gap": "gap 1 (NaN gap vertices)",
                                                         "loader-writes-selection": "of 42 streamlines (gap 1)"})

    def test_extensions_are_asked_for_only_when_listed(self):
        # A loader serving extension tables its descriptor does not list: the
        # validator fails it, naming the extension; the host never asks for
        # them, so the file reads as through a plain 1.0 loader (a copy,
        # checked by the host), with the same streamlines.
        self.assert_fails_only("fx_tck_unlisted_extensions.so",
                               {"abi-extensions-served": "serves 'hz.ext.mapped-positions/1' without listing it"})
        d = self.path("unlisted")
        os.makedirs(d)
        shutil.copy(os.path.join(FIXTURES, "fx_tck_unlisted_extensions.so"), d)
        plugins = json.loads(run("--plugin-dir", d, "plugins", "--json").stdout)
        listed = {p["id"]: p["interfaces"] for p in plugins["plugins"]}
        self.assertEqual(listed["org.horizon.test.tck-unlisted-extensions"], ["hz.loader/1"])
        self.assertEqual(listed["org.horizon.loader.tck"],
                         ["hz.loader/1", "hz.ext.open-task/1", "hz.ext.checked-read/1", "hz.ext.mapped-positions/1",
                          "hz.ext.delimited-streamlines/1", "hz.ext.write-selection/1"])  # (the SDK adapter's order)
        tck = self.path("x.tck")
        make_tractogram(tck, 300, 5)
        plain = json.loads(run("--plugin-dir", d, "info", tck, "--json").stdout)
        mapped = json.loads(run("info", tck, "--json").stdout)
        self.assertEqual(plain["loader"], "org.horizon.test.tck-unlisted-extensions")
        self.assertFalse(plain["positions_mapped"])
        self.assertEqual(mapped["loader"], "org.horizon.loader.tck")
        self.assertTrue(mapped["positions_mapped"])
        for k in ("nb_streamlines", "nb_vertices", "bbox_ras_mm"):
            self.assertEqual(plain[k], mapped[k], k)

    def test_templates_pass(self):
        for f in sorted(glob.glob(os.path.join(TEMPLATES, "*.so"))):
            with self.subTest(plugin=os.path.basename(f)):
                rc, rep = self.validate(f)
                self.assertEqual(rc, 0, [c for c in rep["checks"] if c["status"] == "failed"])
                # (An extension a template does not offer is not a skip that counts.)
                skipped = [c for c in rep["checks"] if c["status"] == "skipped" and not c["reason"].startswith("does not offer HZ_EXT_")]
                self.assertLessEqual(len(skipped), 1, rep)

    def test_broken_shader_fails_naming_the_checks(self):
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_broken_shader.so"))
        self.assertEqual(rc, 1)
        c = checks(rep)
        self.assertEqual(c["shader-schema-wellformed"]["status"], "failed")
        self.assertIn("default", c["shader-schema-wellformed"]["reason"])
        self.assertEqual(c["shader-reference-finite-nonnegative"]["status"], "failed")
        reason = c["shader-reference-finite-nonnegative"]["reason"]
        self.assertIn("negative", reason)
        # The failure gives its inputs as a case `horizon brdf` reads: run,
        # it gives the same negative value.
        case = reason.split("reproduce with: echo '")[1].split("' | horizon brdf --shader org.horizon.test.fixture")[0]
        d = self.path("one")
        os.mkdir(d)
        # (The same function in a plugin with a sane schema: one whose
        # default breaks its schema is not loaded, the validator aside.)
        shutil.copy(os.path.join(FIXTURES, "fx_negative_shader.so"), d)
        p = subprocess.run([HORIZON, "--plugin-dir", d, "brdf", "--shader", "org.horizon.test.fixture"], input=case + "\n", capture_output=True,
                           text=True, timeout=60, env=environment("brdf", env={"HORIZON_PLUGIN_CACHE": "off"}))
        self.assertEqual(p.returncode, 0, p.stderr)
        value = json.loads(p.stdout)["value"]
        self.assertAlmostEqual(value[0], float(reason.split("negative output ")[1].split(" ")[0]), places=5)
        text = run("validate", os.path.join(FIXTURES, "fx_broken_shader.so"))
        self.assertEqual(text.returncode, 1)
        self.assertIn("failed   shader-schema-wellformed", text.stdout)

    def test_a_snippet_may_read_its_colour_through_hz_albedo(self):
        """hz_shader.h: `#define HZ_ALBEDO u_<name>` names the first colour
        parameter. The validator's check program and a material that gives
        the colour itself used to leave it undefined (issue 53)."""
        so = os.path.join(BUILD, "tests", "fixtures", "albedo", "fx_albedo_shader.so")
        rc, rep = self.validate(so)
        self.assertEqual(rc, 0, [c for c in rep["checks"] if c["status"] == "failed"])
        d = os.path.dirname(so)
        with open(self.path("plane.obj"), "w") as f:
            f.write("v -30 -30 0\nv 30 -30 0\nv 30 30 0\nv -30 30 0\nf 1 2 3\nf 1 3 4\n")
        for params, colour, channel in (({"tint": [0.0, 0.9, 0.0]}, None, 1), ({}, [0.9, 0.0, 0.0], 0)):
            scene = {"camera": {"view": "superior"}, "environment": {"type": "none"}, "tonemap": "none",
                     "lights": [{"type": "directional", "direction": [0, 0, 1], "space": "world", "intensity": 1.0}],
                     "objects": [{"type": "surface", "file": "plane.obj", "material": {"shader": "albedo", "params": params}}]}
            if colour:
                scene["objects"][0]["color"] = colour
            with open(self.path("s.json"), "w") as f:
                json.dump(scene, f)
            p = run("render", self.path("s.json"), "-o", self.path("s.png"), "--size", "64x64", "--force", "--plugin-dir", d)
            self.assertEqual(p.returncode, 0, p.stderr)
            from PIL import Image
            import numpy as np
            px = np.asarray(Image.open(self.path("s.png")).convert("RGB"), dtype=float)[32, 32]
            self.assertEqual(int(np.argmax(px)), channel, px)
            self.assertGreater(px[channel], 150, px)

    def test_gpu_must_equal_cpu(self):
        # The valid fixture passes the pixel comparison; one whose GLSL is a
        # different function than its CPU reference fails exactly that check.
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_valid.so"))
        self.assertEqual(checks(rep)["shader-gpu-equals-cpu"]["status"], "passed", rep)
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_gpu_mismatch.so"))
        self.assertEqual(rc, 1)
        failed = [c["check"] for c in rep["checks"] if c["status"] == "failed"]
        self.assertEqual(failed, ["shader-gpu-equals-cpu"])
        self.assertIn("pixels differ", checks(rep)["shader-gpu-equals-cpu"]["reason"])

    def test_extra_exports_are_reported(self):
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_extra_export.so"))
        self.assertEqual(rc, 1)
        self.assertIn("fixture_leaked_symbol", checks(rep)["exports-only-entry"]["reason"])

    def test_crash_and_hang_do_not_take_the_validator_down(self):
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_init_crash.so"))
        self.assertEqual(rc, 1)
        self.assertEqual(checks(rep)["load"]["status"], "crashed")
        self.assertIn("SIGSEGV", checks(rep)["load"]["reason"])
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_init_hang.so"), "--timeout", "1", timeout=30)
        self.assertEqual(rc, 1)
        self.assertIn("hung", checks(rep)["load"]["reason"])

    def test_non_plugins_fail_cleanly(self):
        junk = self.path("junk.so")
        with open(junk, "wb") as f:
            f.write(b"not an elf file at all\n")
        rc, rep = self.validate(junk)
        self.assertEqual(rc, 1)
        self.assertEqual(checks(rep)["elf"]["status"], "failed")
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_wrong_abi_symbol.so"))
        self.assertEqual(rc, 1)
        self.assertIn("ABI 2", checks(rep)["load"]["reason"])


if __name__ == "__main__":
    unittest.main()
