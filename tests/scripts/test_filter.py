"""`horizon filter`: streamline selection by include / exclude regions and
length, checked two ways on a realistic generated tractogram:
- against an independent numpy implementation of the documented rules
  (always run);
- against MRtrix3 tckedit 3.0 on the same files and regions (the `mrtrix3`
  package; reported as skipped where it is not installed).
Plus what a user meets: per-streamline data and groups carried over, bad
regions, an empty selection, outputs that would replace an input.
"""
import json
import os
import shutil
import subprocess
import tempfile
import unittest

import numpy as np

from hztest import make_tractogram, run

TCKEDIT = shutil.which("tckedit")
N = 20000


def load(path):
    import nibabel as nib
    return list(nib.streamlines.load(path).streamlines)


def lengths_f32(streamlines):
    """tckedit's length: float32 segment norms ((dx^2 + dy^2) + dz^2),
    summed in vertex order in float32 (np.cumsum is sequential)."""
    out = np.empty(len(streamlines), np.float32)
    for i, s in enumerate(streamlines):
        s = np.asarray(s, np.float32)
        if len(s) == 0:
            out[i] = np.nan
            continue
        d = np.diff(s, axis=0)
        seg = np.sqrt((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2])
        out[i] = np.cumsum(np.concatenate([[np.float32(0)], seg]), dtype=np.float32)[-1]
    return out


class Region:
    """The reference's regions: which vertices of an (n, 3) float32 array lie inside."""

    def __init__(self, spec, mask=None):
        self.spec = spec
        if spec.startswith("sphere:"):
            v = np.array([float(x) for x in spec[7:].split(",")])
            self.c, self.r = v[:3].astype(np.float32), np.float32(v[3])
            self.kind = "sphere"
        elif spec.startswith("box:"):
            v = np.array([float(x) for x in spec[4:].split(",")]).reshape(2, 3)
            self.lo, self.hi = v.min(0).astype(np.float32), v.max(0).astype(np.float32)
            self.kind = "box"
        else:
            import nibabel as nib
            img = nib.load(spec)
            self.data = np.asarray(img.dataobj) != 0
            self.inv = np.linalg.inv(img.affine)
            self.kind = "mask"

    def inside(self, pts):
        if self.kind == "sphere":
            d = self.c - pts
            return (d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) + d[:, 2] * d[:, 2] <= self.r * self.r
        if self.kind == "box":
            return np.all((pts >= self.lo) & (pts <= self.hi), axis=1)
        # float32, ((m0 x + m1 y) + m2 z) + t, rounded half away from zero (tckedit's)
        m = self.inv[:3].astype(np.float32)
        v = ((m[:, 0] * pts[:, :1] + m[:, 1] * pts[:, 1:2]) + m[:, 2] * pts[:, 2:3]) + m[:, 3]
        t = np.trunc(v)
        v = (t + (v - t >= 0.5) - (v - t <= -0.5)).astype(np.int64)
        ok = np.all((v >= 0) & (v < np.array(self.data.shape[:3])), axis=1)
        hit = np.zeros(len(pts), bool)
        hit[ok] = self.data[v[ok, 0], v[ok, 1], v[ok, 2]]
        return hit


def reference(streamlines, include=(), exclude=(), min_length=0.0, max_length=np.inf, ends_only=False, invert=False):
    inc, exc = [Region(s) for s in include], [Region(s) for s in exclude]
    lens = lengths_f32(streamlines)
    keep = []
    for i, s in enumerate(streamlines):
        if len(s) == 0:
            continue
        pts = np.asarray(s, np.float32)
        if ends_only:
            pts = pts[[0, -1]]
        ok = all(r.inside(pts).any() for r in inc) and not any(r.inside(pts).any() for r in exc)
        ok = ok and np.float32(min_length) <= lens[i] <= np.float32(max_length)
        if ok != invert:
            keep.append(i)
    return keep


class FilterTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="hz_filter_")
        cls.tck = os.path.join(cls.tmp, "brain.tck")
        make_tractogram(cls.tck, N, 5)
        cls.streamlines = load(cls.tck)
        # A mask on its own grid: 2 mm voxels, rotated 20 degrees about z
        # and shifted, an ellipsoid in the right hemisphere.
        import nibabel as nib
        a = np.deg2rad(20)
        aff = np.eye(4)
        aff[:3, :3] = 2.0 * np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        aff[:3, 3] = [-70, -90, -60]
        ijk = np.stack(np.meshgrid(np.arange(80), np.arange(100), np.arange(70), indexing="ij"), -1).reshape(-1, 3)
        xyz = ijk @ aff[:3, :3].T + aff[:3, 3]
        blob = (((xyz - [30, -10, 10]) / [18, 30, 20]) ** 2).sum(1) <= 1
        cls.mask = os.path.join(cls.tmp, "mask.nii.gz")
        nib.save(nib.Nifti1Image(blob.reshape(80, 100, 70).astype(np.uint8), aff), cls.mask)
        # The same mask stored inverted and scaled back: raw 0 inside, 1
        # outside, value = raw - 1 (scl_inter -1): only a reader that applies
        # the scaling finds the blob (nibabel's dataobj does; so does tckedit).
        scaled = nib.Nifti1Image((~blob).reshape(80, 100, 70).astype(np.uint8), aff)
        scaled.header.set_slope_inter(1, -1)
        scaled.header.set_data_dtype(np.uint8)
        cls.scaled_mask = os.path.join(cls.tmp, "scaled_mask.nii")
        nib.save(scaled, cls.scaled_mask)
        assert (np.asarray(nib.load(cls.scaled_mask).dataobj.get_unscaled()) != 0).sum() == (~blob).sum()
        s0, s1 = cls.streamlines[0], cls.streamlines[1]
        # Regions where the data are (the generator's brain: semi-axes 65, 85, 60 mm).
        cls.cases = {
            "one sphere": dict(include=["sphere:10,-20,15,12"]),
            # The two ends of one streamline's bundle, less what passes near
            # another streamline's middle.
            "two spheres and an exclusion": dict(include=[cls.sphere(s0[0], 8), cls.sphere(s0[-1], 8)],
                                                 exclude=[cls.sphere(s1[len(s1) // 2], 10)]),
            "sphere and lengths": dict(include=["sphere:0,0,0,20"], min_length=80, max_length=180),
            "mask": dict(include=[cls.mask], exclude=["sphere:-20,0,-10,12"]),
            "lengths only": dict(min_length=120),
            "ends only": dict(include=["sphere:40,10,30,25"], ends_only=True),
            # (the exclusion is tested at the ends only too: streamlines
            # that pass through it but end elsewhere are kept)
            "ends only with an exclusion": dict(include=["sphere:40,10,30,35"], exclude=["sphere:30,-10,20,25"], ends_only=True),
            "mask with scl_inter": dict(include=[cls.scaled_mask]),
            "inverted": dict(include=["sphere:10,-20,15,12"], invert=True),
        }

    @staticmethod
    def sphere(c, r):
        return "sphere:" + ",".join(f"{x:.3f}" for x in c) + f",{r}"

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def path(self, name):
        return os.path.join(self.tmp, name)

    def horizon_args(self, c):
        args = []
        for s in c.get("include", []):
            args += ["--include", s]
        for s in c.get("exclude", []):
            args += ["--exclude", s]
        if "min_length" in c:
            args += ["--min-length", c["min_length"]]
        if "max_length" in c:
            args += ["--max-length", c["max_length"]]
        if c.get("ends_only"):
            args.append("--ends-only")
        if c.get("invert"):
            args.append("--invert")
        return args

    def horizon_ids(self, c, source=None):
        p = run("filter", source or self.tck, *self.horizon_args(c), "--ids", "-")
        self.assertEqual(p.returncode, 0, p.stderr)
        return [int(x) for x in p.stdout.split()]

    def test_matches_the_numpy_reference(self):
        for name, c in self.cases.items():
            with self.subTest(name):
                want = reference(self.streamlines, **c)
                got = self.horizon_ids(c)
                self.assertGreater(len(want), 20, f"{name}: the case selects too little to test anything")
                self.assertLess(len(want), N - 20, name)
                self.assertEqual(got, want)

    def test_matches_tckedit(self):
        if TCKEDIT is None:
            self.skipTest("tckedit (package mrtrix3) is not installed")
        for k, (name, c) in enumerate(self.cases.items()):
            with self.subTest(name):
                ours, theirs = self.path(f"h{k}.tck"), self.path(f"m{k}.tck")
                p = run("filter", self.tck, *self.horizon_args(c), "-o", ours)
                self.assertEqual(p.returncode, 0, p.stderr)
                args = [TCKEDIT, self.tck, theirs, "-quiet", "-force"]
                for s in c.get("include", []):
                    args += ["-include", s.split(":", 1)[1] if s.startswith("sphere:") else s]
                for s in c.get("exclude", []):
                    args += ["-exclude", s.split(":", 1)[1] if s.startswith("sphere:") else s]
                if "min_length" in c:
                    args += ["-minlength", str(c["min_length"])]
                if "max_length" in c:
                    args += ["-maxlength", str(c["max_length"])]
                if c.get("ends_only"):
                    args.append("-ends_only")
                if c.get("invert"):
                    args.append("-inverse")
                m = subprocess.run(args, capture_output=True, text=True, timeout=300)
                self.assertEqual(m.returncode, 0, m.stderr)
                a, b = load(ours), load(theirs)
                self.assertEqual(len(a), len(b))
                self.assertGreater(len(a), 20)
                for x, y in zip(a, b):
                    np.testing.assert_array_equal(x, y)

    def test_box_and_trk_input(self):
        # Boxes (Horizon's own), through a TRK (voxmm on disk): the selection
        # is made in RAS+ mm whatever the format.
        trk = self.path("brain.trk")
        self.assertEqual(run("convert", self.tck, trk).returncode, 0)
        c = dict(include=["box:-10,-30,0,25,5,40"], exclude=["box:-60,-80,-60,-40,80,60"])
        want = reference(self.streamlines, **c)
        self.assertGreater(len(want), 20)
        self.assertEqual(self.horizon_ids(c, source=trk), want)

    def test_carries_per_streamline_data_and_groups(self):
        trx = self.path("labelled.trx")
        p = run("cluster", self.tck, "--thresholds", "30,20", "--out", trx)
        self.assertEqual(p.returncode, 0, p.stderr)
        out = self.path("picked.trx")
        p = run("filter", trx, "--include", "sphere:10,-20,15,12", "-o", out, "--json")
        self.assertEqual(p.returncode, 0, p.stderr)
        summary = json.loads(p.stdout)
        want = reference(self.streamlines, include=["sphere:10,-20,15,12"])
        self.assertEqual(summary["selected"], len(want))
        self.assertEqual(summary["nb_streamlines"], N)
        full, part = self.read_trx(trx), self.read_trx(out)
        # Positions: exactly the selected streamlines.
        self.assertEqual(len(part["offsets"]), len(want))
        for j, i in enumerate(want[:200]):
            np.testing.assert_array_equal(part["streamline"](j), full["streamline"](i))
        # Per-streamline labels: the selected rows.
        for name, values in full["dps"].items():
            np.testing.assert_array_equal(part["dps"][name], values[want], err_msg=name)
        # Groups: narrowed to the kept streamlines, renumbered; empty ones dropped.
        where = {old: new for new, old in enumerate(want)}
        expect = {}
        for g, members in full["groups"].items():
            kept = sorted(where[m] for m in members if m in where)
            if kept:
                expect[g] = kept
        self.assertEqual({g: sorted(m.tolist()) for g, m in part["groups"].items()}, expect)
        self.assertIn("horizon_filter", part["header"])

    def test_lengths_exactly_at_the_bounds(self):
        """Streamlines whose length is exactly --min-length or --max-length
        (steps of (0.3, 0.4, 0) scaled to 0.5 mm and whole (3, 4, 0) steps:
        exact in float32) are kept: both bounds are inclusive, as tckedit's;
        one ulp beyond them is not."""
        from hztest import tck_bytes
        steps = {"half": np.float32([0.3, 0.4, 0.0]), "five": np.float32([3.0, 4.0, 0.0])}
        sl = []
        for n in range(1, 61):  # 0.5 .. 30 mm in 0.5 mm steps, then 5 .. 300 mm
            sl.append(np.arange(n + 1, dtype=np.float32)[:, None] * steps["half"] + np.float32([1, 2, 3]))
            sl.append(np.arange(n + 1, dtype=np.float32)[:, None] * steps["five"] - np.float32([7, 0, 1]))
        lens = lengths_f32(sl)
        self.assertIn(np.float32(10), lens)
        self.assertIn(np.float32(20), lens)
        path = self.path("exact.tck")
        with open(path, "wb") as f:
            f.write(tck_bytes(sl))
        for lo, hi in ((10, 20), (10, 10), (np.nextafter(np.float32(10), np.float32(11)), 20), (5, np.nextafter(np.float32(20), np.float32(0)))):
            with self.subTest(min_length=lo, max_length=hi):
                want = [i for i, x in enumerate(lens) if np.float32(lo) <= x <= np.float32(hi)]
                self.assertEqual(want, reference(sl, min_length=lo, max_length=hi))
                p = run("filter", path, "--min-length", repr(float(lo)), "--max-length", repr(float(hi)), "--ids", "-")
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertEqual([int(x) for x in p.stdout.split()], want)
                if TCKEDIT is not None:
                    out = self.path("exact_m.tck")
                    m = subprocess.run([TCKEDIT, path, out, "-quiet", "-force", "-minlength", repr(float(lo)), "-maxlength", repr(float(hi))],
                                       capture_output=True, text=True, timeout=60)
                    self.assertEqual(m.returncode, 0, m.stderr)
                    self.assertEqual(len(load(out)), len(want))

    def test_carries_per_vertex_data_of_the_selection(self):
        """Per-point scalars and per-streamline properties of a TRK (written
        by nibabel) through a filter into TRK and TRX: exactly the selected
        streamlines' rows, in order. (The writers read the selected
        streamlines and their rows where they lie, hz.ext.write-selection/1.)"""
        import nibabel as nib
        from nibabel.streamlines.trk import TrkFile
        sl = [np.asarray(s, np.float32) for s in self.streamlines[:4000]]
        rng = np.random.default_rng(11)
        fa = [rng.random((len(s), 1)).astype(np.float32) for s in sl]
        curv = [rng.random((len(s), 2)).astype(np.float32) for s in sl]
        length = rng.random((len(sl), 1)).astype(np.float32)
        t = nib.streamlines.Tractogram(sl, data_per_point={"fa": fa, "curv": curv}, data_per_streamline={"length": length},
                                       affine_to_rasmm=np.eye(4))
        src = self.path("scalars.trk")
        hdr = {nib.streamlines.Field.VOXEL_TO_RASMM: np.diag([2.0, 2.0, 2.0, 1.0]), nib.streamlines.Field.VOXEL_SIZES: (2, 2, 2),
               nib.streamlines.Field.DIMENSIONS: (90, 108, 90)}
        TrkFile(t, header=hdr).save(src)
        region = "sphere:10,-20,15,20"
        want = reference(sl, include=[region])
        self.assertGreater(len(want), 50)
        self.assertLess(len(want), len(sl) - 50)
        out_trk, out_trx = self.path("scalars_picked.trk"), self.path("scalars_picked.trx")
        for out in (out_trk, out_trx):
            p = run("filter", src, "--include", region, "-o", out)
            self.assertEqual(p.returncode, 0, p.stderr)
        back = nib.streamlines.load(out_trk).tractogram
        self.assertEqual(len(back.streamlines), len(want))
        for j, i in enumerate(want):
            np.testing.assert_allclose(back.streamlines[j], sl[i], atol=1e-3)
            np.testing.assert_array_equal(back.data_per_point["fa"][j], fa[i])
            np.testing.assert_array_equal(back.data_per_point["curv"][j], curv[i])
        np.testing.assert_array_equal(back.data_per_streamline["length"], length[want])
        x = self.read_trx(out_trx)
        z = __import__("zipfile").ZipFile(out_trx)
        dpv = {n[4:].split(".")[0]: n for n in z.namelist() if n.startswith("dpv/")}
        self.assertEqual(sorted(dpv), ["curv", "fa"])
        fa_back = np.frombuffer(z.read(dpv["fa"]), np.float32)
        curv_back = np.frombuffer(z.read(dpv["curv"]), np.float32).reshape(-1, 2)
        np.testing.assert_array_equal(fa_back, np.concatenate([fa[i][:, 0] for i in want]))
        np.testing.assert_array_equal(curv_back, np.concatenate([curv[i] for i in want]))
        np.testing.assert_array_equal(x["dps"]["length"], length[want, 0])
        for j, i in enumerate(want):
            np.testing.assert_allclose(x["streamline"](j), sl[i], atol=1e-3)

    def read_trx(self, path):
        import zipfile
        z = zipfile.ZipFile(path)
        header = json.loads(z.read("header.json"))
        names = z.namelist()
        pos_name = next(n for n in names if n.startswith("positions."))
        off_name = next(n for n in names if n.startswith("offsets."))
        pos = np.frombuffer(z.read(pos_name), dtype=np.dtype(pos_name.split(".")[-1])).reshape(-1, 3)
        offs = np.frombuffer(z.read(off_name), dtype=np.dtype(off_name.split(".")[-1])).astype(np.int64)
        offs = offs[:header["NB_STREAMLINES"]]
        bounds = np.append(offs, len(pos))
        dps = {}
        for n in names:
            if n.startswith("dps/"):
                base, dt = n[4:].rsplit(".", 1)
                dps[base] = np.frombuffer(z.read(n), dtype=np.dtype(dt))
        groups = {}
        for n in names:
            if n.startswith("groups/"):
                base, dt = n[7:].rsplit(".", 1)
                groups[base] = np.frombuffer(z.read(n), dtype=np.dtype(dt))
        return dict(header=header, offsets=offs, dps=dps, groups=groups,
                    streamline=lambda i: pos[bounds[i]:bounds[i + 1]])

    def test_bad_regions_fail_before_any_work(self):
        out = self.path("never.tck")
        text = self.path("notes.txt")
        with open(text, "w") as f:
            f.write("not a volume\n")
        empty = self.path("empty.nii.gz")
        import nibabel as nib
        nib.save(nib.Nifti1Image(np.zeros((4, 4, 4), np.uint8), np.eye(4)), empty)
        for spec, words in [("sphere:1,2,3", "3 numbers"), ("sphere:1,2,3,-4", "radius"), ("sphere:1,2,x,4", "not a number"),
                            ("box:0,0,0,10,10,0", "flat"), ("ball:1,2,3,4", "no such file"), (text, "notes.txt"),
                            (empty, "empty")]:
            with self.subTest(spec):
                p = run("filter", self.tck, "--include", spec, "-o", out)
                self.assertEqual(p.returncode, 1, p.stderr)
                lines = p.stderr.strip().splitlines()
                self.assertEqual(len(lines), 1, p.stderr)
                self.assertIn(words, lines[0])
                self.assertFalse(os.path.exists(out))

    def test_options_before_the_input(self):
        # Repeatable options take one value each: the input may come after them.
        c = dict(include=["sphere:10,-20,15,12", "sphere:0,0,0,30"])
        p = run("filter", "--include", c["include"][0], "--include", c["include"][1], self.tck, "--ids", "-")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual([int(x) for x in p.stdout.split()], reference(self.streamlines, **c))
        # --roi (as dipy_horizon users type it) is --include.
        p = run("filter", "--roi", c["include"][0], "--roi", c["include"][1], self.tck, "--ids", "-")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual([int(x) for x in p.stdout.split()], reference(self.streamlines, **c))

    def test_region_outside_the_data(self):
        out = self.path("outside.tck")
        # An include region away from every streamline (voxel coordinates
        # given for mm, say): an error naming both, nothing written.
        p = run("filter", self.tck, "--include", "sphere:500,500,500,5", "-o", out)
        self.assertEqual(p.returncode, 1)
        self.assertIn("lies outside", p.stderr)
        self.assertIn("brain.tck", p.stderr)
        self.assertFalse(os.path.exists(out))
        # An exclude region there changes nothing: a warning, every streamline kept.
        p = run("filter", self.tck, "--exclude", "sphere:500,500,500,5", "-o", out, "--json")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("warning", p.stderr)
        self.assertEqual(json.loads(p.stdout)["selected"], N)

    def test_empty_selection_writes_an_empty_file(self):
        out = self.path("none.tck")
        p = run("filter", self.tck, "--min-length", 10000, "-o", out)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("no streamline selected", p.stderr)
        self.assertEqual(len(load(out)), 0)

    def test_never_over_the_input(self):
        copy = self.path("input.tck")
        shutil.copy(self.tck, copy)
        with open(copy, "rb") as f:
            before = f.read()
        for args in (["-o", copy], ["-o", copy, "--force"]):
            p = run("filter", copy, "--min-length", 50, *args)
            self.assertEqual(p.returncode, 1)
            self.assertIn("refusing to overwrite the input", p.stderr)
        # Nor over the mask it reads.
        p = run("filter", copy, "--include", self.mask, "-o", self.mask, "--force")
        self.assertEqual(p.returncode, 1)
        with open(copy, "rb") as f:
            self.assertEqual(f.read(), before)
        # An existing output needs --force.
        out = self.path("exists.tck")
        with open(out, "w") as f:
            f.write("keep me")
        p = run("filter", copy, "--min-length", 50, "-o", out)
        self.assertEqual(p.returncode, 1)
        self.assertIn("already exists", p.stderr)
        with open(out) as f:
            self.assertEqual(f.read(), "keep me")
        p = run("filter", copy, "--min-length", 300, "--max-length", 200, "-o", out, "--force")
        self.assertEqual(p.returncode, 1)
        self.assertIn("above --max-length", p.stderr)


if __name__ == "__main__":
    unittest.main()
