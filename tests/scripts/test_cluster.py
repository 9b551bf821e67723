"""`horizon cluster` against DIPY 1.6 (python3-dipy): the same labels at
every level and the same float32 centroids, bit for bit, for the same
processing order; plus the cases where clustering methods break."""
import os
import struct
import re
import unittest

import nibabel as nib
import numpy as np
from dipy.segment.bundles import qbx_and_merge
from dipy.segment.clustering import QuickBundles, QuickBundlesX

from hztest import TempDirTest, random_streamlines, run, run_json, tck_bytes


def dipy_labels(clusters, n):
    ref = np.full(n, -1, np.int64)
    for i, c in enumerate(clusters):
        ref[np.asarray(c.indices)] = i
    return ref


class ClusterVsDipyTest(TempDirTest):
    @classmethod
    def setUpClass(cls):
        import tempfile
        cls.data = tempfile.mkdtemp(prefix="hz_cluster_")
        p = run("demo", "--out", cls.data, "--streamlines", "3000")
        assert p.returncode == 0, p.stderr
        cls.tck = os.path.join(cls.data, "phantom.tck")
        cls.sl = [s.astype(np.float32) for s in nib.streamlines.load(cls.tck).streamlines]
        cls.n = len(cls.sl)
        cls.order = np.random.default_rng(5).permutation(cls.n)
        cls.order_file = os.path.join(cls.data, "order.txt")
        np.savetxt(cls.order_file, cls.order, fmt="%d")

    @classmethod
    def tearDownClass(cls):
        import shutil
        shutil.rmtree(cls.data, ignore_errors=True)

    def ours(self, *args, level=None):
        labels, cents = self.path("l.csv"), self.path("c.tck")
        extra = ["--level", str(level)] if level is not None else []
        p = run("cluster", self.tck, "--labels", labels, "--centroids", cents, "--force", *args, *extra)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(labels) as f:
            header = f.readline().strip().split(",")
        lab = np.loadtxt(labels, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
        self.assertTrue(np.array_equal(lab[:, 0], np.arange(self.n)))
        return header, lab, list(nib.streamlines.load(cents).streamlines)

    def test_mapped_and_copied_tck_cluster_alike(self):
        # demo writes its TCK aligned, as MRtrix does: mapped with the NaN delimiters
        # in place, which the plugin skips (hz.ext.delimited-streamlines/1); every DIPY comparison in this
        # class therefore runs on the mapped path.
        self.assertTrue(run_json("info", self.tck, "--json")["positions_mapped"])
        # The same streamlines with the data at an offset that is not a multiple of 4
        # (as nibabel writes them): mapped, and copied to aligned memory when the
        # clustering plugin is handed them (HZ_EXTENT_UNALIGNED).
        for pad in range(4):
            f = self.path("unaligned.tck")
            with open(f, "wb") as fh:
                fh.write(tck_bytes(self.sl, pad=pad))
            if run_json("info", f, "--json")["positions_copied_on_use"]:
                break
        else:
            self.fail("no unaligned variant")
        for mode in ("exact", "fast"):
            with self.subTest(mode=mode):
                got = []
                for src in (self.tck, f):
                    labels = self.path(f"{mode}_{len(got)}.csv")
                    p = run("cluster", src, "--algorithm", "qbx", "--mode", mode, "--labels", labels, "--force")
                    self.assertEqual(p.returncode, 0, p.stderr)
                    got.append(np.loadtxt(labels, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2))
                np.testing.assert_array_equal(got[0], got[1])

    def assert_same_centroids(self, dipy_clusters, ours):
        self.assertEqual(len(dipy_clusters), len(ours))
        for a, b in zip(dipy_clusters, ours):
            self.assertTrue(np.array_equal(a.centroid, b), "centroids differ bitwise")

    def test_qbx_every_level_file_and_given_order(self):
        for order in (None, self.order):
            with self.subTest(order="file" if order is None else "permutation"):
                ref = QuickBundlesX([30, 25, 20, 15]).cluster(self.sl, ordering=order)
                args = ["--algorithm", "qbx"] + ([] if order is None else ["--order", self.order_file])
                for level in (1, 2, 3, 4):
                    header, lab, cents = self.ours(*args, level=level)
                    self.assertEqual(header, ["streamline", "30", "25", "20", "15"])
                    np.testing.assert_array_equal(lab[:, level], dipy_labels(ref.get_clusters(level), self.n))
                    self.assert_same_centroids(ref.get_clusters(level), cents)

    def test_qb(self):
        for thr in (10.0, 15.0, 30.0):
            with self.subTest(threshold=thr):
                ref = QuickBundles(thr).cluster(self.sl, ordering=self.order)
                header, lab, cents = self.ours("--algorithm", "qb", "--thresholds", str(thr), "--order", self.order_file)
                np.testing.assert_array_equal(lab[:, 1], dipy_labels(ref, self.n))
                self.assert_same_centroids(ref, cents)

    def test_nb_points_and_thresholds(self):
        ref = QuickBundlesX([20, 10], metric="MDF_12points").cluster(self.sl)
        _, lab, _ = self.ours("--algorithm", "qbx", "--thresholds", "20,10")
        np.testing.assert_array_equal(lab[:, 2], dipy_labels(ref.get_clusters(2), self.n))
        from dipy.segment.featurespeed import ResampleFeature
        from dipy.segment.metric import AveragePointwiseEuclideanMetric
        metric = AveragePointwiseEuclideanMetric(ResampleFeature(nb_points=20))
        ref = QuickBundles(12.0, metric=metric).cluster(self.sl)
        _, lab, cents = self.ours("--algorithm", "qb", "--thresholds", "12", "--nb-points", "20")
        np.testing.assert_array_equal(lab[:, 1], dipy_labels(ref, self.n))
        self.assert_same_centroids(ref, cents)

    def test_qbx_and_merge(self):
        order = self.order

        class GivenOrder:  # DIPY draws both orders from rng.choice: give ours
            calls = 0

            def choice(self, n, k, replace=False):
                GivenOrder.calls += 1
                return order if GivenOrder.calls == 1 else np.arange(n)

        ref = qbx_and_merge(self.sl, [40, 30, 25, 20, 15], nb_pts=20, rng=GivenOrder())
        header, lab, cents = self.ours("--algorithm", "qbx_merge", "--order", self.order_file)
        self.assertEqual(header, ["streamline", "15"])
        np.testing.assert_array_equal(lab[:, 1], dipy_labels(ref, self.n))
        self.assert_same_centroids(ref, cents)

    def test_shuffle_is_reproducible(self):
        _, a, _ = self.ours("--algorithm", "qbx", "--order", "shuffle", "--seed", "3")
        _, b, _ = self.ours("--algorithm", "qbx", "--order", "shuffle", "--seed", "3")
        _, c, _ = self.ours("--algorithm", "qbx", "--order", "shuffle", "--seed", "4")
        np.testing.assert_array_equal(a, b)
        self.assertFalse(np.array_equal(a, c))  # processing order matters, and is documented


    def test_fast_mode_agrees_with_dipy(self):
        """--mode fast (float32 resampling and distances): its labels at every
        level equal DIPY's on at least 99.9 % of the streamlines (the issue's
        bar; rounding may only decide near-ties), and where a cluster has the
        same members its centroid is DIPY's to float32 rounding."""
        cases = [("qbx", QuickBundlesX([30, 25, 20, 15]).cluster(self.sl, ordering=self.order), (1, 2, 3, 4)),
                 ("qb", QuickBundles(15.0).cluster(self.sl, ordering=self.order), (1,))]
        for algo, ref, levels in cases:
            for level in levels:
                with self.subTest(algorithm=algo, level=level):
                    clusters = ref.get_clusters(level) if algo == "qbx" else ref
                    _, lab, cents = self.ours("--algorithm", algo, "--order", self.order_file, "--mode", "fast", level=level)
                    want = dipy_labels(clusters, self.n)
                    self.assertGreaterEqual((lab[:, level] == want).mean(), 0.999)
                    for i, c in enumerate(clusters):
                        members = np.flatnonzero(lab[:, level] == i)
                        if i < len(cents) and np.array_equal(members, np.sort(np.asarray(c.indices))):
                            np.testing.assert_allclose(cents[i], c.centroid, rtol=0, atol=1e-3)

    def test_fast_resampling_matches_dipy(self):
        """Threshold 0 makes every streamline its own cluster, so fast mode's
        centroids are its resampled streamlines (seeded in either orientation):
        they are DIPY's set_number_of_points to float32 rounding, including a
        100,000-point streamline and streamlines with repeated points."""
        from dipy.tracking.streamline import set_number_of_points
        rng = np.random.default_rng(11)
        sl = random_streamlines(200, rng, 2, 300, scale=90)
        t = np.linspace(0, 1, 100_000, dtype=np.float32)
        sl.append((np.stack([t * 150, np.sin(t * 30) * 20, np.cos(t * 7) * 40], axis=1) + 500).astype(np.float32))
        sl.append(np.repeat(sl[0], 3, axis=0))  # zero-length segments (the same points as sl[0])
        f = self.path("r.tck")
        with open(f, "wb") as fh:
            fh.write(tck_bytes(sl))
        sl = [s.astype(np.float32) for s in nib.streamlines.load(f).streamlines]
        for nb in (12, 20, 33):
            with self.subTest(nb_points=nb):
                cents = self.path("c.tck")
                p = run("cluster", f, "--algorithm", "qb", "--thresholds", "0", "--nb-points", str(nb), "--mode", "fast",
                        "--labels", self.path("l.csv"), "--centroids", cents, "--force")
                self.assertEqual(p.returncode, 0, p.stderr)
                lab = np.loadtxt(self.path("l.csv"), delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
                ours = list(nib.streamlines.load(cents).streamlines)
                for i, s in enumerate(sl):
                    want = set_number_of_points(s, nb)
                    got = ours[lab[i, 1]]
                    err = min(np.abs(got - want).max(), np.abs(got[::-1] - want).max())
                    self.assertLess(err, 1e-5 * max(1.0, np.abs(want).max()), f"streamline {i}")


class ClusterEdgeCasesTest(TempDirTest):
    def write(self, name, sl):
        f = self.path(name)
        with open(f, "wb") as fh:
            fh.write(tck_bytes(sl))
        return f

    def labels(self, f, *args):
        out = self.path("l.csv")
        p = run("cluster", f, "--labels", out, "--force", *args)
        self.assertEqual(p.returncode, 0, p.stderr)
        return np.loadtxt(out, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)

    def test_empty_and_single(self):
        lab = self.labels(self.write("empty.tck", []), "--algorithm", "qbx")
        self.assertEqual(lab.size, 0)
        lab = self.labels(self.write("one.tck", [np.arange(12, dtype=np.float32).reshape(4, 3)]), "--algorithm", "qbx")
        np.testing.assert_array_equal(lab, [[0, 0, 0, 0, 0]])

    def test_a_shortcut_and_param_for_the_same_parameter_are_refused(self):
        f = self.write("r.tck", random_streamlines(20, np.random.default_rng(9), 5, 30))
        p = run("cluster", f, "--algorithm", "qbx", "--nb-points", "12", "--param", "nb_points=20", "--labels", self.path("l.csv"))
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("--param nb_points and a shortcut option", p.stderr)
        self.assertIn("both set nb_points: give one", p.stderr)
        self.assertFalse(os.path.exists(self.path("l.csv")))

    def test_degenerate_streamlines(self):
        sl = [np.array([[1, 2, 3]], np.float32), np.tile(np.float32([5, 5, 5]), (4, 1)),
              np.arange(30, dtype=np.float32).reshape(10, 3)]
        f = self.write("degenerate.tck", sl)
        for algo in ("qb", "qbx", "qbx_merge"):
            lab = self.labels(f, "--algorithm", algo)
            self.assertEqual(lab.shape[0], 3)

    def test_identical_and_flipped(self):
        rng = np.random.default_rng(1)
        base = random_streamlines(20, rng, 10, 40, scale=60)
        sl = base + [s[::-1] for s in base] + [s.copy() for s in base]
        lab = self.labels(self.write("flip.tck", sl), "--algorithm", "qbx")
        for level in range(1, 5):
            np.testing.assert_array_equal(lab[:20, level], lab[20:40, level])
            np.testing.assert_array_equal(lab[:20, level], lab[40:, level])
        lab = self.labels(self.write("flip.tck", sl), "--algorithm", "qb", "--thresholds", "5")
        np.testing.assert_array_equal(lab[:20, 1], lab[20:40, 1])

    def test_threshold_extremes(self):
        rng = np.random.default_rng(2)
        f = self.write("r.tck", random_streamlines(50, rng, 5, 30))
        lab = self.labels(f, "--algorithm", "qb", "--thresholds", "0")
        self.assertEqual(len(set(lab[:, 1])), 50)  # every streamline its own cluster
        lab = self.labels(f, "--algorithm", "qbx", "--thresholds", "0")
        self.assertEqual(len(set(lab[:, 1])), 50)
        lab = self.labels(f, "--algorithm", "qbx", "--thresholds", "1e6,1e5")
        self.assertEqual(set(lab[:, 1]), {0})
        self.assertEqual(set(lab[:, 2]), {0})

    def test_join_at_exactly_the_threshold_as_dipy(self):
        """A streamline joins a cluster whose centroid is exactly `threshold`
        away (distance <= threshold, not <): duplicates at threshold 0, and
        parallel straight lines exactly 4 mm apart (12 equally spaced points:
        resampling keeps them, the distance is exactly 4 in float32), compared
        with DIPY's labels at every level."""
        line = np.array([[i, 0, 0] for i in range(12)], np.float32)
        sl = []
        for k in range(6):
            base = line + np.float32(100 * k)
            sl += [base, base.copy(), base + np.array([0, 4, 0], np.float32), base + np.array([0, 0, 9], np.float32)]
        f = self.write("edge.tck", sl)
        sl = [s.astype(np.float32) for s in nib.streamlines.load(f).streamlines]
        for thresholds in ([4.0, 0.0], [9.0, 4.0, 0.0]):
            with self.subTest(thresholds=thresholds):
                lab = self.labels(f, "--algorithm", "qbx", "--thresholds", ",".join(map(str, thresholds)))
                tree = QuickBundlesX(thresholds).cluster(sl)
                for level in range(1, len(thresholds) + 1):
                    np.testing.assert_array_equal(lab[:, level], dipy_labels(tree.get_clusters(level), len(sl)), f"level {level}")
                zero = len(thresholds)  # the last level (threshold 0): duplicates share a cluster
                self.assertEqual(lab[0, zero], lab[1, zero])
                self.assertNotEqual(lab[0, zero], lab[2, zero])
                self.assertEqual(lab[0, zero - 1], lab[2, zero - 1], "4 mm apart joins at threshold 4")
        for t in (0.0, 4.0):
            lab = self.labels(f, "--algorithm", "qb", "--thresholds", str(t))
            np.testing.assert_array_equal(lab[:, 1], dipy_labels(QuickBundles(t).cluster(sl), len(sl)), f"qb {t}")

    def test_far_coordinates_and_a_huge_streamline(self):
        rng = np.random.default_rng(3)
        far = [s + np.float32(1e6) for s in random_streamlines(30, rng, 5, 20)]
        lab = self.labels(self.write("far.tck", far), "--algorithm", "qbx")
        self.assertEqual(lab.shape, (30, 5))
        t = np.linspace(0, 1, 10_000_000, dtype=np.float32)
        huge = np.stack([t * 100, np.sin(t * 20) * 10, t * 0], axis=1)
        lab = self.labels(self.write("huge.tck", [huge, huge[::-1].copy()]), "--algorithm", "qbx")
        np.testing.assert_array_equal(lab[0], lab[1] * [0, 1, 1, 1, 1])

    def test_extreme_scales_match_dipy(self):
        """Coordinates near 1e20 mm (squared distances overflow float32, so the
        pruning bounds become infinite) and near 1e-30 mm (they underflow to 0):
        the labels and the centroids, whose first member's orientation comes from
        the nearest too-far cluster, are still DIPY's, bit for bit."""
        rng = np.random.default_rng(4)
        for scale in (1e20, 1e-30):
            with self.subTest(scale=scale):
                sl = [(s * np.float32(scale)).astype(np.float32) for s in random_streamlines(40, rng, 2, 30, scale=5)]
                f = self.write("x.tck", sl)
                sl = [s.astype(np.float32) for s in nib.streamlines.load(f).streamlines]
                cents = self.path("c.tck")
                for algo, ref in (("qbx", QuickBundlesX([30, 25, 20, 15]).cluster(sl).get_clusters(4)),
                                  ("qb", QuickBundles(15.0).cluster(sl))):
                    lab = self.labels(f, "--algorithm", algo, "--centroids", cents)
                    np.testing.assert_array_equal(lab[:, -1], dipy_labels(ref, len(sl)))
                    ours = list(nib.streamlines.load(cents).streamlines)
                    self.assertEqual(len(ref), len(ours))
                    self.assert_extreme_centroids(ref, ours, scale, algo)

    def assert_extreme_centroids(self, ref, ours, scale, algo):
        for a, b in zip(ref, ours):
            self.assertTrue(np.array_equal(a.centroid, b), f"{algo}: centroids differ bitwise")

    def test_bad_input_fails_cleanly(self):
        f = self.write("nan.tck", [np.array([[0, 0, 0], [1, 1, 1]], np.float32)])
        inf = self.write("inf.tck", [np.array([[0, 0, 0], [1, 1, 1]], np.float32)])
        with open(inf, "r+b") as fh:  # turn one coordinate into +Inf (not a delimiter: TCK rejects it)
            data = fh.read()
            offset = int(re.search(rb"file: \. (\d+)", data).group(1))
            fh.seek(offset + 4)  # y of the first point
            fh.write(struct.pack("<f", float("inf")))
        p = run("cluster", inf, "--labels", self.path("l.csv"))
        self.assert_clean_error(p, "inf.tck")
        self.assertIn("NaN/Inf", p.stderr)
        self.assertFalse(os.path.exists(self.path("l.csv")))
        p = run("cluster", self.path("nope.tck"), "--labels", self.path("l.csv"))
        self.assert_clean_error(p, "nope.tck")
        self.assertFalse(os.path.exists(self.path("l.csv")))
        p = run("cluster", f, "--labels", self.path("l.csv"), "--thresholds", "-3")
        self.assert_clean_error(p, "thresholds")
        bad_order = self.path("order.txt")
        with open(bad_order, "w") as fh:
            fh.write("0 0\n")
        p = run("cluster", f, "--labels", self.path("l.csv"), "--order", bad_order)
        self.assert_clean_error(p, "order.txt")


if __name__ == "__main__":
    unittest.main()


class ClusterEdgeCasesFastTest(ClusterEdgeCasesTest):
    """The same cases in fast mode (float32 resampling and distances)."""

    def labels(self, f, *args):
        return super().labels(f, *args, "--mode", "fast")

    def assert_extreme_centroids(self, ref, ours, scale, algo):
        """Near 1e20 mm and near 1e-30 mm float32 squares overflow and
        underflow: fast mode resamples such streamlines with DIPY's double
        arithmetic, and its labels are still DIPY's (checked by the test). Its
        distances are float32 (infinite or zero there), so which orientation
        seeds or joins a cluster is a tie: at 1e20 mm (every streamline its own
        cluster) the centroids are DIPY's in one orientation or the other; at
        1e-30 mm (one cluster) the members' orientations are arbitrary, and only
        the labels are checked."""
        if scale < 1:
            return
        for a, b in zip(ref, ours):
            err = min(np.abs(b - a.centroid).max(), np.abs(b[::-1] - a.centroid).max())
            self.assertLessEqual(err, 1e-5 * np.abs(a.centroid).max(), algo)

    def test_bad_input_fails_cleanly(self):
        f = self.write("inf.tck", [np.array([[0, 0, 0], [1, 1, 1]], np.float32)])
        with open(f, "r+b") as fh:
            data = fh.read()
            fh.seek(data.index(b"END\n") + 4 + 4)
            fh.write(np.float32(np.inf).tobytes())
        p = run("cluster", f, "--labels", self.path("l.csv"), "--mode", "fast")
        self.assert_clean_error(p, "inf.tck")
        self.assertFalse(os.path.exists(self.path("l.csv")))


class TreeFigureTest(TempDirTest):
    """The QuickBundlesX tree as a figure (paper Fig. 4): several levels'
    centroids drawn together, each subtree in its colour, chosen subtrees."""

    def render(self, level, extra=None, **settings):
        import json
        scene = {"objects": [{"type": "streamlines", "builtin": "brain_bundles", "phantom": {"streamlines": 3000},
                              "clustering": {"thresholds": [30, 20, 10], "level": level, **(extra or {})}, **settings}],
                 "camera": {"view": "left"}, "environment": {"type": "none"}, "tonemap": "none", "background": [0, 0, 0],
                 "antialiasing": {"on": False}}
        with open(self.path("s.json"), "w") as f:
            json.dump(scene, f)
        p = run("render", self.path("s.json"), "-o", self.path("s.png"), "--size", "480x360", "--force", "--json", env={"DISPLAY": ""},
                timeout=180)
        return p

    def drawn(self, level, extra=None, **settings):
        import json
        p = self.render(level, extra, **settings)
        self.assertEqual(p.returncode, 0, p.stderr)
        return json.loads(p.stdout)["streamlines_drawn"]

    def test_levels_together_and_subtrees(self):
        n = [self.drawn(level) for level in (1, 2, 3)]
        self.assertTrue(n[0] < n[1] < n[2], n)
        self.assertEqual(self.drawn([1, 2, 3]), sum(n))
        self.assertEqual(self.drawn([3, 1, -2]), sum(n), "levels in any order, -2 the one above the finest")
        one = self.drawn([1, 2, 3], {"subtrees": [0]})
        self.assertTrue(1 < one < sum(n), one)
        self.assertEqual(self.drawn([1], {"subtrees": [0, 2]}), 2)
        # Each subtree one colour (flat shading, no tone curve): a subtree's three levels are all of its hue
        # (each pixel's colour over its brightest channel; edges blend with the black background only).
        from PIL import Image
        hues = []
        for k in (0, 1):
            self.drawn([1, 2, 3], {"subtrees": [k]}, material="flat")
            pic = np.asarray(Image.open(self.path("s.png")).convert("RGB")).reshape(-1, 3).astype(float)
            pic = pic[pic.max(axis=1) > 60]
            hue = pic / pic.max(axis=1, keepdims=True)
            median = np.median(hue, axis=0)
            self.assertGreater((np.abs(hue - median).max(axis=1) < 0.08).mean(), 0.97, f"subtree {k}: one colour")
            hues.append(median)
        self.assertGreater(np.abs(hues[0] - hues[1]).max(), 0.2, "two subtrees, two colours")
        p = self.render([1, 2], {"subtrees": [n[0]]})
        self.assertEqual(p.returncode, 1)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
        self.assertIn(f"level 1 has {n[0]} clusters drawn", p.stderr)
