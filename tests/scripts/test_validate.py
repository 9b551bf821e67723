"""`horizon validate`: passes every bundled plugin and the SDK templates,
fails broken fixtures naming the failing check, survives crashes and hangs."""
import glob
import json
import os
import unittest

from hztest import BUNDLED, FIXTURES, TEMPLATES, TempDirTest, run


def checks(report):
    return {c["check"]: c for c in report["checks"]}


class ValidateTest(TempDirTest):
    def validate(self, path, *extra, timeout=300):
        p = run("validate", path, "--json", *extra, timeout=timeout)
        return p.returncode, json.loads(p.stdout)

    def test_bundled_plugins_pass(self):
        files = sorted(glob.glob(os.path.join(BUNDLED, "*.so")))
        self.assertGreaterEqual(len(files), 1)
        for f in files:
            with self.subTest(plugin=os.path.basename(f)):
                rc, rep = self.validate(f)
                failed = [c for c in rep["checks"] if c["status"] not in ("passed", "skipped")]
                self.assertEqual(failed, [])
                self.assertEqual(rc, 0)
                self.assertTrue(rep["ok"])

    def test_bundled_loader_runs_the_loader_checks(self):
        rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_tck.so"))
        c = checks(rep)
        for name in ["loader-probe-purity", "loader-roundtrip", "loader-malformed-survival",
                     "loader-buffer-too-small", "loader-cancel", "exports-only-entry"]:
            self.assertEqual(c[name]["status"], "passed", name)

    def test_zero_copy_contract_is_checked(self):
        # TRX offers locate_positions (ABI 1.4): the located bytes, CRC and offsets-only read are checked.
        rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_trx.so"))
        self.assertEqual(checks(rep)["loader-locate-positions"]["status"], "passed")
        self.assertIn("maps the plain layout", checks(rep)["loader-locate-positions"]["reason"])
        # TCK (ABI 1.5) maps only when the host accepts the delimited layout: each streamline's
        # bytes and its all-NaN delimiter are checked against a copying read.
        rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_tck.so"))
        c = checks(rep)["loader-locate-positions"]
        self.assertEqual(c["status"], "passed")
        self.assertEqual(c["reason"], "declines the plain layout; maps the delimited layout; vouches for exact bounds")
        # (ABI 1.9) Given a TCK as nibabel writes it (data at byte 67), the loader offers
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
        # (ABI 1.7) TCK and TRK vouch for the positions they copy (exact bounds, checked
        # against the validator's own pass); TRX leaves its decoded copies to the host.
        for name, reason in (("tck", "vouches for exact bounds"), ("trk", "vouches for exact bounds"),
                             ("trx", "does not vouch; the host checks what it wrote")):
            rc, rep = self.validate(os.path.join(BUNDLED, "hz_loader_%s.so" % name))
            c = checks(rep)["loader-vouched-positions"]
            self.assertEqual(c["status"], "passed", (name, c))
            self.assertTrue(c["reason"].startswith(reason), (name, c))
        # (ABI 1.6) The same loader vouching for bounds 1 mm too wide fails exactly that check.
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_tck_lying_bounds.so"))
        self.assertEqual(rc, 1)
        failed = {c["check"]: c["reason"] for c in rep["checks"] if c["status"] == "failed"}
        self.assertEqual(sorted(failed), ["loader-locate-positions", "loader-vouched-positions"], failed)
        self.assertIn("vouches for bounds other than its positions' (x)", failed["loader-locate-positions"])
        self.assertIn("vouches for bounds other than the positions it wrote (x)", failed["loader-vouched-positions"])

    def assert_fails_only(self, fixture, check, reason):
        """The validator fails `fixture` on `check` alone, with `reason` in its message."""
        rc, rep = self.validate(os.path.join(FIXTURES, fixture))
        self.assertEqual(rc, 1)
        failed = {c["check"]: c["reason"] for c in rep["checks"] if c["status"] == "failed"}
        self.assertEqual(list(failed), [check], failed)
        self.assertIn(reason, failed[check])

    def test_vouch_past_struct_size_fails(self):
        # ABI 1.7: a loader that writes through hz_streamlines_dst.check for a
        # host whose struct ends before it (or into a check record too small).
        self.assert_fails_only("fx_tck_ignores_sizes.so", "loader-vouched-positions",
                               "writes through `check` for a host whose struct ends before it")

    def test_writer_ignoring_the_gap_fails(self):
        # ABI 1.8: a loader that declares HZ_LOADER_WRITES_GAP but writes the
        # vertex after each streamline as a point.
        self.assert_fails_only("fx_tck_ignores_gap.so", "loader-writes-gap", "gap 1 (NaN gap vertices)")

    def test_templates_pass(self):
        for f in sorted(glob.glob(os.path.join(TEMPLATES, "*.so"))):
            with self.subTest(plugin=os.path.basename(f)):
                rc, rep = self.validate(f)
                self.assertEqual(rc, 0, [c for c in rep["checks"] if c["status"] == "failed"])
                self.assertEqual(sum(c["status"] == "skipped" for c in rep["checks"]) <= 1, True, rep)

    def test_broken_shader_fails_naming_the_checks(self):
        rc, rep = self.validate(os.path.join(FIXTURES, "fx_broken_shader.so"))
        self.assertEqual(rc, 1)
        c = checks(rep)
        self.assertEqual(c["shader-schema-wellformed"]["status"], "failed")
        self.assertIn("default", c["shader-schema-wellformed"]["reason"])
        self.assertEqual(c["shader-reference-finite-nonnegative"]["status"], "failed")
        self.assertIn("negative", c["shader-reference-finite-nonnegative"]["reason"])
        text = run("validate", os.path.join(FIXTURES, "fx_broken_shader.so"))
        self.assertEqual(text.returncode, 1)
        self.assertIn("failed   shader-schema-wellformed", text.stdout)

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
