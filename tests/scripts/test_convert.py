"""`horizon convert`: exact round trips, atomic writes, the input never
touched, and clean failures that leave nothing behind."""
import hashlib
import json
import os
import unittest

import numpy as np

from hztest import TempDirTest, random_streamlines, run, tck_bytes


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


class ConvertTest(TempDirTest):
    def make_input(self, name="a.tck", datatype="Float32LE"):
        rng = np.random.default_rng(3)
        sl = random_streamlines(100, rng) + [np.zeros((0, 3))]
        f = self.path(name)
        with open(f, "wb") as fh:
            fh.write(tck_bytes(sl, datatype, header_extra=[("command_history", "tckgen x"), ("roi", "")]))
        return f

    def test_roundtrip_is_exact(self):
        a = self.make_input()
        b, c = self.path("b.tck"), self.path("c.tck")
        self.assertEqual(run("convert", a, b).returncode, 0)
        self.assertEqual(run("convert", b, c).returncode, 0)
        self.assertEqual(digest(b), digest(c))  # a fixed point: byte-identical
        # Same data and header entries as the original.
        ia = run("info", a, "--json").stdout
        ib = run("info", b, "--json").stdout
        import json
        ja, jb = json.loads(ia), json.loads(ib)
        for k in ["nb_streamlines", "nb_vertices", "nb_empty_streamlines", "bbox_ras_mm"]:
            self.assertEqual(ja[k], jb[k], k)
        self.assertIn(["command_history", "tckgen x"], jb["header"])
        self.assertIn(["roi", ""], jb["header"])

    def test_mapped_tck_written_with_its_delimiters_skipped(self):
        # Horizon's own TCK (data on a multiple of 4 bytes) is mapped with its
        # NaN delimiters in place; the TCK, TRK and TRX writers take it as it
        # is (hz.ext.delimited-streamlines/1) and skip them. All must hold the
        # same streamlines, the empty one included.
        import nibabel as nib
        b = self.path("b.tck")
        self.assertEqual(run("convert", self.make_input(), b).returncode, 0)
        with open(b, "rb") as fh:
            offset = int(fh.read(4096).split(b"file: . ")[1].split()[0])
        self.assertEqual(offset % 4, 0)
        # (nibabel skips an empty TCK streamline; `horizon info` counts it.)
        want = [x for x in nib.streamlines.load(b).streamlines if len(x)]
        for ext in ("tck", "trk", "trx"):
            out = self.path("out." + ext)
            p = run("convert", b, out)
            self.assertEqual(p.returncode, 0, p.stderr)
            if ext == "trx":  # (read back through a TCK: nibabel reads no TRX)
                back = self.path("trx_back.tck")
                self.assertEqual(run("convert", out, back).returncode, 0)
                out = back
            got = [x for x in nib.streamlines.load(out).streamlines if len(x)]
            info = json.loads(run("info", out, "--json").stdout)
            self.assertEqual((info["nb_streamlines"], info["nb_empty_streamlines"]), (len(want) + 1, 1), ext)
            self.assertEqual(len(got), len(want), ext)
            for s, (x, y) in enumerate(zip(want, got)):
                self.assertEqual(x.shape, y.shape, (ext, s))
                np.testing.assert_allclose(y, x, atol=1e-3 if ext == "trk" else 0, err_msg=f"{ext} streamline {s}")

    def test_big_endian_and_float64_convert_to_the_same_data(self):
        a32 = self.make_input("le.tck")
        b64 = self.make_input("be64.tck", "Float64BE")
        o1, o2 = self.path("o1.tck"), self.path("o2.tck")
        self.assertEqual(run("convert", a32, o1).returncode, 0)
        self.assertEqual(run("convert", b64, o2).returncode, 0)
        with open(o1, "rb") as f1, open(o2, "rb") as f2:
            d1, d2 = f1.read(), f2.read()
        self.assertEqual(d1[d1.index(b"END\n"):], d2[d2.index(b"END\n"):])

    def test_input_never_touched_and_no_overwrite_without_force(self):
        a = self.make_input()
        before = (digest(a), os.stat(a).st_mtime_ns)
        out = self.path("out.tck")
        with open(out, "w") as f:
            f.write("precious")
        p = run("convert", a, out)
        self.assert_clean_error(p, "out.tck")
        self.assertIn("--force", p.stderr)
        with open(out) as f:
            self.assertEqual(f.read(), "precious")
        self.assertEqual(run("convert", a, out, "--force").returncode, 0)
        self.assertNotEqual(digest(out), hashlib.sha256(b"precious").hexdigest())
        p = run("convert", a, a, "--force")
        self.assert_clean_error(p, "a.tck")
        self.assertEqual((digest(a), os.stat(a).st_mtime_ns), before)

    def test_failures_leave_no_output(self):
        a = self.make_input()
        bad = self.path("bad.tck")
        with open(a, "rb") as f:
            data = f.read()
        with open(bad, "wb") as f:
            f.write(data[:-20])  # truncated input
        cases = [
            (bad, self.path("o.tck"), "bad.tck"),
            (a, self.path("o.unknown"), "o.unknown"),
            (a, self.path("missing_dir/o.tck"), "o.tck"),
            (self.path("nope.tck"), self.path("o.tck"), "nope.tck"),
        ]
        for src, dst, named in cases:
            with self.subTest(dst=dst):
                self.assert_clean_error(run("convert", src, dst), named)
                self.assertFalse(os.path.exists(dst))
        self.assertEqual(sorted(os.listdir(self.tmp)), ["a.tck", "bad.tck"])  # no temporaries left

    def test_demo_runs(self):
        out = self.path("demo")
        p = run("demo", "--out", out, "--streamlines", "300")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("streamlines:   300", p.stdout)
        self.assertTrue(os.path.isfile(os.path.join(out, "phantom.tck")))


if __name__ == "__main__":
    unittest.main()
