"""The quality-control loop in the window (under Xvfb, driven by --script):
regions of interest placed, moved, resized, flipped and removed; undo and
redo; Ctrl+click on a streamline; saving what is shown (Ctrl+S and `save`)
and reopening it; the exploration's cluster paths, expansion straight to
streamlines, thresholds fitted on repeat. What was saved is checked against
what was shown and against `horizon filter` on the same regions.
"""
import json
import os
import re
import shutil
import unittest
import zipfile

import numpy as np

from hztest import HORIZON, TempDirTest, run
from test_render import NO_DISPLAY, load, xvfb_run


def streamlines(path):
    import nibabel as nib
    return list(nib.streamlines.load(path).streamlines)


def trx_parts(path):
    z = zipfile.ZipFile(path)
    header = json.loads(z.read("header.json"))
    groups, dps = {}, {}
    pos_name = next(n for n in z.namelist() if n.startswith("positions."))
    off_name = next(n for n in z.namelist() if n.startswith("offsets."))
    pos = np.frombuffer(z.read(pos_name), dtype=np.dtype(pos_name.rsplit(".", 1)[1])).reshape(-1, 3)
    offs = np.frombuffer(z.read(off_name), dtype=np.dtype(off_name.rsplit(".", 1)[1])).astype(np.int64)[:header["NB_STREAMLINES"]]
    bounds = np.append(offs, len(pos))
    header["streamlines"] = [pos[bounds[i]:bounds[i + 1]] for i in range(len(offs))]
    for n in z.namelist():
        if n.startswith("groups/"):
            base, dt = n[7:].rsplit(".", 1)
            groups[base] = np.frombuffer(z.read(n), dtype=np.dtype(dt))
        elif n.startswith("dps/"):
            base, dt = n[4:].rsplit(".", 1)
            dps[base] = np.frombuffer(z.read(n), dtype=np.dtype(dt))
    # (The TRX writer stores metadata values that are JSON as JSON.)
    for k in ("horizon_rois", "horizon_clusters"):
        if isinstance(header.get(k), str):
            header[k] = json.loads(header[k])
    return header, groups, dps


@unittest.skipUnless(shutil.which("xvfb-run") or os.environ.get("CI"), "xvfb-run is not installed")
class SelectionWindowTest(TempDirTest):
    def setUp(self):
        super().setUp()
        p = run("demo", "--out", self.path("d"), "--streamlines", "2000", "--no-window", env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.tck = self.path("d/phantom.tck")

    def window(self, name, lines, *args, source=None):
        script = self.path(name + ".txt")
        with open(script, "w") as f:
            f.write("\n".join(lines) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # (see test_render)
        return xvfb_run([HORIZON, "view", source or self.tck, *args, "--size", "480x320", "--script", script,
                         "--screenshot-dir", self.tmp], env)

    @staticmethod
    def roi_lines(p):
        """The `roi: ` lines (the state after each edit), without their timing."""
        return [re.sub(r" \([\d.]+ ms\)$", "", l[len("roi: "):]) for l in p.stdout.splitlines() if re.match(r"roi: \d+ regions, ", l)]

    @staticmethod
    def selected(line):
        m = re.match(r"(\d+) regions, (\d+) of (\d+) streamlines selected", line)
        return int(m.group(1)), int(m.group(2)), int(m.group(3))

    def filter_ids(self, *args):
        p = run("filter", self.tck, *args, "--ids", "-")
        self.assertEqual(p.returncode, 0, p.stderr)
        return [int(x) for x in p.stdout.split()]

    def test_regions_undo_redo_and_save(self):
        p = self.window("edit", [
            "wait 2", f"screenshot {self.path('all.png')}",
            "roi sphere 0 0 0 15",                      # 1
            "wait 2", f"screenshot {self.path('one.png')}",
            "roi sphere 20 0 0 8 exclude",              # 2
            "roi move 0 5 0 0",                         # 3
            "roi scale 0 1.5",                          # 4
            "undo", "undo", "redo",                     # back to 2, then 3
            f"save {self.path('sel.trx')}", f"save {self.path('sel.tck')}",
            "key ctrl+z",                               # 2
            "key ctrl+s",                               # horizon-selection-1.trx
            "key ctrl+shift+z",                         # 3 again
            "roi flip 1", "roi remove 0",               # 5, 6: an exclude region alone
            "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        states = self.roi_lines(p)
        self.assertEqual(len(states), 11, states)
        self.assertEqual([self.selected(s)[0] for s in states], [1, 2, 2, 2, 2, 2, 2, 2, 2, 2, 1])
        # undo returns exactly to an earlier state, redo to the undone one:
        # states 1..4 are the edits; then undo (3), undo (2), redo (3),
        # ctrl+z (2), ctrl+shift+z (3), flip, remove.
        self.assertEqual(states[4], states[2])
        self.assertEqual(states[5], states[1])
        self.assertEqual(states[6], states[2])
        self.assertEqual(states[7], states[1])
        self.assertEqual(states[8], states[2])
        self.assertNotEqual(states[3], states[2])
        self.assertIn("#0 include sphere:5,0,0,15; #1 exclude sphere:20,0,0,8", states[2])
        self.assertIn("#0 include sphere:20,0,0,8", states[-1])
        # What was saved is what was shown: `horizon filter` with the same
        # regions gives the same streamlines, coordinates and order.
        want = self.filter_ids("--include", "sphere:5,0,0,15", "--exclude", "sphere:20,0,0,8")
        self.assertEqual(self.selected(states[2])[1], len(want))
        got = streamlines(self.path("sel.tck"))
        full = streamlines(self.tck)
        self.assertEqual(len(got), len(want))
        for s, i in zip(got, want):
            np.testing.assert_array_equal(s, full[i])
        header, _, _ = trx_parts(self.path("sel.trx"))
        self.assertEqual(header["horizon_rois"],
                         [{"include": True, "spec": "sphere:5,0,0,15"}, {"include": False, "spec": "sphere:20,0,0,8"}])
        self.assertEqual(header["NB_STREAMLINES"], len(want))
        # Ctrl+S saved the state shown then (state 2).
        ctrl_s = self.path("horizon-selection-1.trx")
        self.assertTrue(os.path.exists(ctrl_s), p.stdout)
        self.assertEqual(trx_parts(ctrl_s)[0]["NB_STREAMLINES"], self.selected(states[1])[1])
        # The picture changed with the selection.
        self.assertGreater(np.abs(load(self.path("all.png")) - load(self.path("one.png"))).mean(), 1.0)
        # Reopening the saved file restores its regions.
        p = self.window("reopen", ["wait 1", "quit"], source=self.path("sel.trx"))
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertTrue(self.roi_lines(p)[0].startswith(f"2 regions, {len(want)} of {len(want)} streamlines selected"), p.stdout)

    def test_ctrl_click_places_a_sphere_on_a_streamline(self):
        p = self.window("shot", ["wait 2", f"screenshot {self.path('s.png')}", "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        img = load(self.path("s.png"))
        bright = img.sum(axis=-1) > 250
        ys, xs = np.nonzero(bright)
        self.assertGreater(len(xs), 100)
        # The brightest pixel near the middle of the picture: on a streamline.
        order = np.argsort((xs - 240) ** 2 + (ys - 160) ** 2)
        x, y = int(xs[order[0]]), int(ys[order[0]])
        p = self.window("click", ["wait 2", f"click {x} {y} ctrl", "click 1 1 ctrl", "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        states = self.roi_lines(p)
        self.assertEqual(len(states), 1, p.stdout)
        n, kept, total = self.selected(states[0])
        self.assertEqual(n, 1)
        self.assertGreater(kept, 0, "the sphere sits on the streamline under the click")
        self.assertLess(kept, total)
        self.assertIn("nothing under (1, 1)", p.stdout)

    def test_ctrl_click_on_a_surface(self):
        # A surface in front of the streamlines takes the click: the sphere
        # sits on it, nearer the eye (the left view looks along +x) than
        # where the same click meets a streamline with the surface hidden.
        centres = {}
        for visible in (True, False):
            scene = self.path(f"surface_{visible}.json")
            with open(scene, "w") as f:
                json.dump({"objects": [{"type": "surface", "builtin": "cortex", "visible": visible},
                                       {"type": "streamlines", "file": self.tck}]}, f)
            p = self.window(f"surface_{visible}", ["wait 2", "click 240 160 ctrl", "quit"], source=scene)
            self.assertEqual(p.returncode, 0, p.stderr)
            m = re.search(r"#0 include sphere:([-\d.e]+),([-\d.e]+),([-\d.e]+),5", p.stdout)
            self.assertIsNotNone(m, p.stdout)
            centres[visible] = [float(x) for x in m.groups()]
        self.assertLess(centres[True][0], centres[False][0] - 3.0, centres)

    def test_exploration_paths_regions_and_save(self):
        p = self.window("explore", [
            "wait 1",
            # (the left uncinate fasciculus of the demo's phantom, between its
            # two ends: one compact bundle among long ones)
            "roi sphere -29 27 -30 10",
            "roi sphere -14 57 -12 10",
            "expand c1",
            "expand c1.1 streamlines",
            "repeat",
            f"save {self.path('ex.trx')}",
            "quit"], "--explore")
        self.assertEqual(p.returncode, 0, p.stderr)
        states = [l[len("explore: "):] for l in p.stdout.splitlines() if l.startswith("explore: ")]
        counts = [tuple(map(int, re.match(r"(\d+) clusters, (\d+) streamlines expanded, (\d+) clustering", s).groups())) for s in states]
        region = counts[2]
        self.assertEqual(region[2], 3, "each region re-clusters what it selects")
        self.assertGreater(counts[4][1], 0, "expand ... streamlines: a cluster's streamlines at once")
        kept = self.selected(self.roi_lines(p)[1])[1]
        self.assertLess(kept, 2000)
        # repeat, with thresholds fitted to the selection's extent (the whole
        # brain's scaled by the ratio of the diagonals of their boxes, at
        # least 1 mm): at least as many clusters as the whole brain's
        # thresholds give the same streamlines.
        self.assertEqual(counts[-1][2], 4)
        self.assertGreaterEqual(counts[-1][0], region[0])
        header, groups, dps = trx_parts(self.path("ex.trx"))
        thresholds = [[float(x) for x in re.search(r"; thresholds ([\d. ]+) mm", s).group(1).split()] for s in states]
        self.assertEqual(thresholds[2], thresholds[0], "a region clusters with the whole brain's thresholds")
        diagonal = lambda pts: float(np.linalg.norm(pts.max(0) - pts.min(0)))
        scale = min(1.0, diagonal(np.concatenate(header["streamlines"])) / diagonal(np.concatenate(streamlines(self.tck))))
        self.assertLess(scale, 0.6)
        np.testing.assert_allclose(thresholds[-1], [max(1.0, t * scale) for t in thresholds[0]], atol=0.011)
        names = header["horizon_clusters"]
        self.assertEqual(len(names), counts[-1][0])
        self.assertEqual(sorted(groups), sorted(n.replace(".", "_") for n in names))
        n = header["NB_STREAMLINES"]
        labels = dps["horizon_cluster"]
        self.assertEqual(len(labels), n)
        for g, name in enumerate(names):
            np.testing.assert_array_equal(np.sort(groups[name.replace(".", "_")]), np.nonzero(labels == g)[0])
        # Every saved streamline is one the region selects.
        want = self.filter_ids("--include", "sphere:-29,27,-30,10", "--include", "sphere:-14,57,-12,10")
        self.assertEqual(len(want), kept)
        full = streamlines(self.tck)
        got = header["streamlines"]
        keys = {full[i].tobytes() for i in want}
        self.assertTrue(all(s.astype(np.float32).tobytes() in keys for s in got))
        # Reopened with --explore, the file shows its clusters as saved, by
        # their saved names: no new clustering.
        first = names[0]
        p = self.window("reopen_ex", ["wait 1", f"expand {first} streamlines", "quit"], "--explore", source=self.path("ex.trx"))
        self.assertEqual(p.returncode, 0, p.stderr)
        again = [tuple(map(int, re.match(r"(\d+) clusters, (\d+) streamlines expanded, (\d+) clustering", l[len("explore: "):]).groups()))
                 for l in p.stdout.splitlines() if l.startswith("explore: ")]
        self.assertEqual(again[0], (len(names), int((labels < 0).sum()), 1))
        self.assertEqual(again[1][:2], (len(names) - 1, int((labels < 0).sum()) + len(groups[first.replace(".", "_")])))

    def test_fig5_sequence_keeps_each_streamlines_cluster_through_x_and_save(self):
        """The paper's Fig. 5 end to end (issue 53): expand, hide, cluster
        again, hide, select all, X (every cluster to its streamlines), a
        stroke's delete and its undo, fit, save. Each saved streamline keeps
        the path of the cluster it was expanded from (a TRX group per path,
        read back here with zipfile and numpy, and its index per streamline);
        the file reopens as those clusters, and `render --legend` lists them."""
        out = self.path("fig5.trx")
        p = self.window("fig5", [
            "wait 1",
            "expand c1",
            "hide c2",
            "repeat",
            "hide c3",
            f"screenshot {self.path('clusters.png')}",
            "key a", "key x",
            f"screenshot {self.path('expanded.png')}",
            "stroke 200 100 280 220", "picked delete", "undo",
            "fit",
            f"screenshot {self.path('fitted.png')}",
            f"save {out}",
            "quit"], "--explore")
        self.assertEqual(p.returncode, 0, p.stderr)
        states = [l[len("explore: "):] for l in p.stdout.splitlines() if l.startswith("explore: ")]
        counts = [tuple(map(int, re.match(r"(\d+) clusters, (\d+) streamlines expanded, (\d+) clustering", s).groups())) for s in states]
        before_x = next(c for c in reversed(counts) if c[0] > 0)  # (the clusters shown when all were selected)
        after_x = counts[-1]
        self.assertEqual(after_x[0], 0, "X took every cluster to its streamlines")
        self.assertGreater(after_x[1], 100)
        self.assertIn("fit: ", p.stdout)
        # Fitted: what is shown fills the view, centred (its box's centre on the view's axis).
        ys, xs = np.nonzero(np.abs(load(self.path("fitted.png")) - load(self.path("fitted.png"))[0, 0]).sum(-1) > 40)
        self.assertLess(abs((xs.min() + xs.max()) / 2 - 240), 40)
        self.assertLess(abs((ys.min() + ys.max()) / 2 - 160), 40)
        self.assertGreater(max((xs.max() - xs.min()) / 480, (ys.max() - ys.min()) / 320), 0.6)
        header, groups, dps = trx_parts(out)
        n = header["NB_STREAMLINES"]
        self.assertEqual(n, after_x[1], "the undo brought the deleted streamlines back")
        names = header["horizon_clusters"]
        self.assertEqual(len(names), before_x[0], "one group per cluster the streamlines came from")
        self.assertTrue(all(re.fullmatch(r"c\d+(\.\d+)*", x) for x in names), names)
        labels = dps["horizon_cluster"]
        self.assertTrue((labels >= 0).all(), "every streamline came from a cluster")
        members = np.concatenate([groups[x.replace(".", "_")] for x in names])
        np.testing.assert_array_equal(np.sort(members), np.arange(n), "the groups are a partition of the file's streamlines")
        for g, x in enumerate(names):
            np.testing.assert_array_equal(np.sort(groups[x.replace(".", "_")]), np.nonzero(labels == g)[0])
        # Each group is one cluster: its streamlines lie together (their mean
        # distance to the group's mean shape is well below the spread of the whole).
        def resampled(s, k=12):
            t = np.linspace(0, len(s) - 1, k)
            return np.array([s[int(np.floor(a))] * (1 - (a % 1)) + s[min(int(np.floor(a)) + 1, len(s) - 1)] * (a % 1) for a in t])
        shapes = np.array([resampled(s) for s in header["streamlines"]])
        flip = np.linalg.norm(shapes - shapes[:, ::-1], axis=(1, 2))  # (orientation does not matter)
        spread = lambda ss: float(np.mean(np.linalg.norm(ss - ss.mean(0), axis=2)))
        within = np.mean([spread(shapes[labels == g]) for g in range(len(names)) if (labels == g).sum() > 2])
        self.assertGreater(float(flip.max()), 0)
        self.assertLess(within, 0.8 * spread(shapes))
        # The streamlines expanded are drawn in their clusters' colours (not by
        # direction): the colours of the picture after X are those of the
        # centroids before it.
        hues = lambda im: {tuple(c) for c in (im[::4, 170::4].reshape(-1, 3) // 32 * 32).astype(int) if c.max() - c.min() > 64}
        a, b = hues(load(self.path("clusters.png"))), hues(load(self.path("expanded.png")))
        self.assertGreater(len(a & b), 0.5 * len(b), (len(a), len(b), len(a & b)))
        # Reopened with --explore: those clusters, by name, nothing expanded.
        p = self.window("fig5_reopen", ["wait 1", "quit"], "--explore", source=out)
        self.assertEqual(p.returncode, 0, p.stderr)
        again = re.match(r"(\d+) clusters, (\d+) streamlines expanded, (\d+) clustering",
                         next(l[len("explore: "):] for l in p.stdout.splitlines() if l.startswith("explore: ")))
        self.assertEqual(tuple(map(int, again.groups())), (len(names), 0, 1))
        p = run("render", out, "--legend", "-o", self.path("legend.png"), "--size", "480x320")
        self.assertEqual(p.returncode, 0, p.stderr)
        # V / fit on what is left of a whole brain after hiding all but its
        # smallest cluster: it then fills the view, centred; before, it did not.
        lines = ["wait 1"] + ["hide 0"] * 11 + [f"screenshot {self.path('small.png')}", "fit", f"screenshot {self.path('small_fit.png')}",
                                                 "quit"]
        p = self.window("fit", lines, "--explore")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertTrue(p.stdout.splitlines()[-1].startswith("explore: 1 clusters") or "explore: 1 clusters" in p.stdout, p.stdout)

        def box(name):
            im = load(self.path(name))
            ys, xs = np.nonzero(np.abs(im - im[0, 0]).sum(-1) > 40)
            return (xs.min() + xs.max()) / 2 - 240, (ys.min() + ys.max()) / 2 - 160, max((xs.max() - xs.min()) / 480, (ys.max() - ys.min()) / 320)
        before, after = box("small.png"), box("small_fit.png")
        # (the picture's box is centred on the 3D box's centre only up to the
        # shape's asymmetry: measured 22, 7 px; before the fit -117, 59 px, 0.23 of the view)
        self.assertLess(abs(after[0]) + abs(after[1]), 50, after)
        self.assertGreater(after[2], 0.6, after)
        self.assertGreater(abs(before[0]) + abs(before[1]), 2 * (abs(after[0]) + abs(after[1])), (before, after))
        self.assertLess(before[2], 0.5 * after[2])

    def test_cluster_size_and_length_cut_offs(self):
        """dipy_horizon's --cluster_size_thr and --cluster_length_thr: in the
        window (--explore) and in a scene file's clustering, clusters of
        fewer streamlines, or with a shorter centroid, are not shown; the
        counts against `horizon cluster`'s labels of the same tractogram."""
        import csv
        labels = self.path("labels.csv")
        p = run("cluster", self.tck, "--labels", labels)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(labels) as f:
            level1 = [int(r[1]) for r in list(csv.reader(f))[1:]]
        sizes = np.bincount(level1)
        want = int((sizes >= 100).sum())
        self.assertTrue(0 < want < len(sizes), sizes)
        first = lambda p: tuple(map(int, re.match(r"(\d+) clusters", next(
            l[len("explore: "):] for l in p.stdout.splitlines() if l.startswith("explore: "))).groups()))[0]
        p = self.window("cut_size", ["wait 1", f"save {self.path('big.trx')}", "quit"], "--explore", "--cluster-size-min", "100")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(first(p), want)
        header, groups, _ = trx_parts(self.path("big.trx"))
        self.assertTrue(all(len(g) >= 100 for g in groups.values()), [len(g) for g in groups.values()])
        p = self.window("cut_length", ["wait 1", f"save {self.path('long.trx')}", "quit"], "--explore", "--cluster-length-min", "150")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertTrue(0 < first(p) < len(sizes), first(p))
        header, groups, dps = trx_parts(self.path("long.trx"))
        length = lambda s: float(np.linalg.norm(np.diff(s, axis=0), axis=1).sum())
        for g in groups.values():  # (a centroid is its members' mean shape: about their length)
            self.assertGreater(np.median([length(header["streamlines"][i]) for i in g]), 0.8 * 150)
        # A scene file's clustering: the clusters drawn.
        scene = self.path("cut.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": self.tck, "clustering": {"level": 1, "min_size": 100}}]}, f)
        p = run("render", scene, "-o", self.path("cut.png"), "--size", "160x120", "--json", env=NO_DISPLAY)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(json.loads(p.stdout)["streamlines_drawn"], want)
        p = self.window("cut_bad", ["quit"], "--cluster-size-min", "10")
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("--cluster-size-min requires --explore", p.stderr)

    def test_stroke_picks_keeps_and_deletes(self):
        # A stroke across the middle of the view picks the streamlines it
        # crosses (drawn lighter); delete removes them, keep keeps only them;
        # both undo. A stroke over empty space picks nothing.
        p = self.window("stroke", [
            "wait 2", f"screenshot {self.path('s0.png')}",
            "stroke 200 100 280 220", "wait 2", f"screenshot {self.path('s1.png')}",
            "picked delete",
            "undo",
            "picked keep",
            f"save {self.path('kept.tck')}",
            "roi sphere 0 0 0 30",           # regions do not bring deleted streamlines back
            "undo", "undo",
            "stroke 2 2 20 4",
            "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        states = [re.match(r"(\d+) regions, (\d+) of (\d+) streamlines selected, (\d+) picked, (\d+) deleted", l).groups()
                  for l in self.roi_lines(p)]
        states = [tuple(map(int, st)) for st in states]
        picked = states[0][3]
        self.assertGreater(picked, 20)
        self.assertLess(picked, 1900)  # (across the middle of a brain: most bundles, not all)
        self.assertEqual(states[1][1:], (2000 - picked, 2000, 0, picked))      # delete
        self.assertEqual(states[2][1:], (2000, 2000, picked, 0))               # undo
        self.assertEqual(states[3][1:], (picked, 2000, 0, 2000 - picked))      # keep
        self.assertLessEqual(states[4][1], picked)                             # a region over what is kept
        self.assertEqual(states[4][4], 2000 - picked)
        self.assertEqual(states[6][1:], (2000, 2000, picked, 0))               # undo twice
        self.assertEqual(states[7][3], 0, "a stroke over empty space picks nothing")
        self.assertEqual(len(streamlines(self.path("kept.tck"))), picked)
        # The picked streamlines are drawn lighter.
        a, b = load(self.path("s0.png")), load(self.path("s1.png"))
        self.assertGreater(b.mean(), a.mean() + 0.5)
        # Over an exploration, a stroke selects the clusters whose centroids it crosses.
        p = self.window("stroke_ex", ["wait 1", "stroke 200 100 280 220", "picked delete", "quit"], "--explore")
        self.assertEqual(p.returncode, 0, p.stderr)
        m = re.search(r"stroke: 0 streamlines picked, (\d+) clusters selected", p.stdout)
        self.assertIsNotNone(m, p.stdout)
        selected = int(m.group(1))
        self.assertGreater(selected, 0)
        counts = [int(re.match(r"(\d+) clusters", l[len("explore: "):]).group(1)) for l in p.stdout.splitlines() if l.startswith("explore: ")]
        self.assertEqual(counts[-1], counts[0] - selected)

    def test_slab_crops_the_streamlines(self):
        # Seen from the left (the default view), a slab along z keeps a
        # horizontal band of the picture; along x, a cross-section.
        p = self.window("slab", ["wait 2", f"screenshot {self.path('a.png')}", "slab z 0 4", "wait 2", f"screenshot {self.path('b.png')}",
                                 "slab x 10 3", "wait 2", f"screenshot {self.path('c.png')}", "slab off", "wait 2",
                                 f"screenshot {self.path('d.png')}", "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        def drawn_of(path):
            img = load(path)
            return np.abs(img - img[-1, -1]).sum(axis=-1) > 30  # (differs from the background in the corner)
        drawn = {k: drawn_of(self.path(k + ".png")) for k in "abcd"}
        rows = {k: np.nonzero(v.any(axis=1))[0] for k, v in drawn.items()}
        self.assertLess(np.ptp(rows["b"]), 0.25 * np.ptp(rows["a"]), "a z slab is a thin band seen from the side")
        self.assertGreater(drawn["c"].sum(), 50)
        self.assertLess(drawn["c"].sum(), 0.6 * drawn["a"].sum())
        np.testing.assert_array_equal(drawn["d"], drawn["a"])
        # The same in a scene file, headless.
        scene = self.path("slab.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": self.tck}], "slab": {"axis": "z", "centre": 0, "half": 4}}, f)
        self.assertEqual(run("render", scene, "-o", self.path("r.png"), "--size", "480x320").returncode, 0)
        r = drawn_of(self.path("r.png"))
        self.assertLess(np.ptp(np.nonzero(r.any(axis=1))[0]), 0.25 * np.ptp(rows["a"]))
        for bad in ["z=1", "w=1,2", "z=1,0", "z=1,2,3"]:
            p = run("view", self.tck, "--slab", bad)
            self.assertEqual(p.returncode, 1, bad)
            self.assertIn("--slab", p.stderr)

    def test_slab_points_where_streamlines_cross(self):
        # Each streamline shown only where it crosses the plane z = 0: as many
        # points as the streamlines' sign changes in z (numpy on the file
        # nibabel reads), seen from the side a thin band at the plane's
        # height, the same from the window, the command line and a scene file.
        pts = streamlines(self.tck)
        expected = sum(int(np.count_nonzero((s[1:, 2] < 0) != (s[:-1, 2] < 0))) for s in pts)
        self.assertGreater(expected, 100)
        p = run("render", self.tck, "--slab", "z=0,points", "-o", self.path("p.png"), "--size", "480x320", "--json")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(json.loads(p.stdout)["slab_crossings"], expected)
        p = run("render", self.tck, "-o", self.path("all.png"), "--size", "480x320")
        self.assertEqual(p.returncode, 0, p.stderr)
        def drawn_of(path):
            img = load(path)
            return np.abs(img - img[-1, -1]).sum(axis=-1) > 30
        pts_img, all_img = drawn_of(self.path("p.png")), drawn_of(self.path("all.png"))
        rows = np.nonzero(pts_img.any(axis=1))[0]
        self.assertLess(np.ptp(rows), 0.2 * np.ptp(np.nonzero(all_img.any(axis=1))[0]), "seen from the side, the crossings are a band")
        self.assertGreater(pts_img.sum(), 200)
        # From above: spread over the tractogram's cross-section, not a line.
        p = run("render", self.tck, "--slab", "z=0,points", "--view", "superior", "-o", self.path("s.png"), "--size", "480x320")
        self.assertEqual(p.returncode, 0, p.stderr)
        s_img = drawn_of(self.path("s.png"))
        self.assertGreater(np.ptp(np.nonzero(s_img.any(axis=1))[0]), 5 * np.ptp(rows))
        # A scene file's slab draws the same picture.
        scene = self.path("points.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": self.tck}],
                       "slab": {"axis": "z", "centre": 0, "show": "points", "point_size": 5}}, f)
        p = run("render", scene, "-o", self.path("scene.png"), "--size", "480x320")
        self.assertEqual(p.returncode, 0, p.stderr)
        np.testing.assert_array_equal(load(self.path("scene.png")), load(self.path("p.png")))
        # The window: the script's slab command, then back to cropping.
        p = self.window("slabpts", ["wait 2", "slab z 0 points", "wait 2", f"screenshot {self.path('w.png')}", "slab z 0 4", "wait 2",
                                    f"screenshot {self.path('wc.png')}", "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        w, wc = drawn_of(self.path("w.png")), drawn_of(self.path("wc.png"))
        self.assertGreater(w.sum(), 200)
        self.assertLess(np.ptp(np.nonzero(w.any(axis=1))[0]), 0.2 * np.ptp(np.nonzero(all_img.any(axis=1))[0]))
        self.assertLess(w.sum(), wc.sum(), "points cover less than the cropped streamlines")
        # Bad specs: one line naming what is wrong, nothing drawn.
        for bad in ["z=0,pointz", "z=points", "q=0,points"]:
            p = run("render", self.tck, "--slab", bad, "-o", self.path("bad.png"))
            self.assertEqual(p.returncode, 1, bad)
            self.assertIn("--slab", p.stderr)
            self.assertFalse(os.path.exists(self.path("bad.png")))
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": self.tck}], "slab": {"axis": "z", "centre": 0, "show": "dots"}}, f)
        p = run("render", scene, "-o", self.path("bad.png"))
        self.assertEqual(p.returncode, 1)
        self.assertIn("slab.show", p.stderr)

    def test_scene_file_regions(self):
        # A scene file's streamlines with regions and a length bound draw
        # exactly what `horizon filter` writes with the same regions.
        out = self.path("f.tck")
        p = run("filter", self.tck, "--include", "sphere:0,0,0,15", "--exclude", "sphere:20,0,0,8", "--min-length", 60, "-o", out)
        self.assertEqual(p.returncode, 0, p.stderr)
        scenes = {"regions": {"type": "streamlines", "file": self.tck, "include": "sphere:0,0,0,15", "exclude": ["sphere:20,0,0,8"],
                              "min_length": 60, "render": "lines"},
                  "filtered": {"type": "streamlines", "file": out, "render": "lines"}}
        for name, ob in scenes.items():
            with open(self.path(name + ".json"), "w") as f:
                json.dump({"objects": [ob], "camera": {"view": "superior"}}, f)
            p = run("render", self.path(name + ".json"), "-o", self.path(name + ".png"), "--size", "320x240")
            self.assertEqual(p.returncode, 0, p.stderr)
        np.testing.assert_array_equal(load(self.path("regions.png")), load(self.path("filtered.png")))
        # A mask named relative to the scene file (in a folder of its own,
        # not the working directory): the selection `filter` makes with it.
        import nibabel as nib
        os.makedirs(self.path("sub/masks"))
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = -40
        ijk = np.stack(np.meshgrid(*[np.arange(41)] * 3, indexing="ij"), -1)
        ball = ((ijk * 2.0 - 40 - [5, 0, 0]) ** 2).sum(-1) <= 12 ** 2
        nib.save(nib.Nifti1Image(ball.astype(np.uint8), aff), self.path("sub/masks/ball.nii.gz"))
        p = run("filter", self.tck, "--include", self.path("sub/masks/ball.nii.gz"), "-o", self.path("m.tck"))
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertNotEqual(os.path.getsize(self.path("m.tck")), os.path.getsize(out))
        for name, ob in {"sub/masked": {"type": "streamlines", "file": self.tck, "include": "masks/ball.nii.gz", "render": "lines"},
                         "mfiltered": {"type": "streamlines", "file": self.path("m.tck"), "render": "lines"}}.items():
            with open(self.path(name + ".json"), "w") as f:
                json.dump({"objects": [ob], "camera": {"view": "superior"}}, f)
            p = run("render", self.path(name + ".json"), "-o", self.path(name + ".png"), "--size", "320x240")
            self.assertEqual(p.returncode, 0, p.stderr)
        np.testing.assert_array_equal(load(self.path("sub/masked.png")), load(self.path("mfiltered.png")))
        # A region that selects nothing, or a bad one, names the object.
        for ob, words in [({"include": "sphere:500,500,500,5"}, "no streamline is selected"), ({"include": "sphere:1,2"}, "objects[0].include[0]")]:
            with open(self.path("bad.json"), "w") as f:
                json.dump({"objects": [{"type": "streamlines", "file": self.tck, **ob}]}, f)
            p = run("render", self.path("bad.json"), "-o", self.path("bad.png"))
            self.assertEqual(p.returncode, 1)
            self.assertIn(words, p.stderr)

    def test_render_legend(self):
        # `render --legend` lists the clusters over the top left of the
        # picture and changes nothing else; a picture without clusters says so.
        scene = self.path("clusters.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": self.tck, "clustering": {"level": 1}, "color": {"mode": "cluster"}}],
                       "camera": {"view": "superior"}}, f)
        for name, extra in [("plain", []), ("legend", ["--legend"])]:
            p = run("render", scene, "-o", self.path(name + ".png"), "--size", "640x480", *extra)
            self.assertEqual(p.returncode, 0, p.stderr)
        a, b = load(self.path("plain.png")), load(self.path("legend.png"))
        changed = np.abs(a - b).sum(axis=-1) > 0
        ys, xs = np.nonzero(changed)
        self.assertGreater(len(ys), 1000)
        self.assertLess(xs.max(), 320, "the legend stays in the top left")
        self.assertLess(ys.min(), 20)
        # One swatch per cluster: rows of 11x11 squares of one colour each.
        box = b[ys.min():ys.max() + 1, xs.min():xs.max() + 1]
        swatch_col = box[:, 8 + 5]  # (the box's padding, then the middle of the swatches)
        colours = {tuple(c) for c in swatch_col if c.max() - c.min() > 60}
        self.assertGreaterEqual(len(colours), 5)
        p = run("render", self.tck, "--legend", "-o", self.path("none.png"))
        self.assertEqual(p.returncode, 1)
        self.assertIn("--legend: nothing in the picture is coloured by cluster", p.stderr)
        self.assertFalse(os.path.exists(self.path("none.png")))

    def test_command_line_regions_and_bad_input(self):
        # --include / --exclude as `filter` takes them.
        p = self.window("cli", ["wait 1", "quit"], "--include", "sphere:0,0,0,15", "--exclude", "sphere:20,0,0,8")
        self.assertEqual(p.returncode, 0, p.stderr)
        want = self.filter_ids("--include", "sphere:0,0,0,15", "--exclude", "sphere:20,0,0,8")
        self.assertEqual(self.selected(self.roi_lines(p)[0])[:2], (2, len(want)))
        # A bad region on the command line: one line, before the window.
        p = run("view", self.tck, "--include", "sphere:1,2,3")
        self.assertEqual(p.returncode, 1)
        self.assertIn("sphere:1,2,3", p.stderr)
        # In a script: the line is named; nothing is changed.
        for lines, words in [(["roi sphere 1 2 3"], "line 1: roi sphere needs 4 numbers"),
                             (["roi remove 3"], "line 1: no region 3"),
                             (["roi sphere 0 0 0 10 maybe"], "neither include nor exclude"),
                             ([f"save {self.tck} force"], "refusing to overwrite the input"),
                             (["save /nonexistent-dir/kept.trx"], "line 1: /nonexistent-dir/kept.trx: directory /nonexistent-dir does not exist"),
                             # (written on a thread, where creating the file fails: it still fails the script)
                             (["save /proc/kept.trx"], "/proc/kept.trx: writing the zip archive failed")]:
            with self.subTest(lines[0]):
                with open(self.tck, "rb") as f:
                    before = f.read()
                p = self.window("bad", lines + ["quit"])
                self.assertEqual(p.returncode, 1, p.stdout)
                self.assertIn(words, p.stderr)
                with open(self.tck, "rb") as f:
                    self.assertEqual(f.read(), before)
        # An include region away from the data: nothing selected, said so, the window goes on.
        p = self.window("far", ["roi sphere 500 500 500 5", "wait 1", "undo", "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        states = self.roi_lines(p)
        self.assertEqual(self.selected(states[0])[1], 0)
        self.assertEqual(self.selected(states[1])[:2], (0, 2000))


if __name__ == "__main__":
    unittest.main()
