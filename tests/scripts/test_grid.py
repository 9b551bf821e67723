"""Several subjects at once: a grid of views with a linked camera (one tile
a cell, each tile the same camera on that cell's objects and those shared
by every cell, its title at the top left), from a scene file ("cell" of
each object, "grid") or from the command line (`--grid files|folders`),
for `render` and `movie`. Tested on DIPY's own multi-subject data: the five
subjects of `minimal_bundles.zip` (Debian's python3-dipy), each tile equal
to that subject rendered alone with the same camera. Malformed grids are
one line naming the scene file, nothing written. On the same bundles, BUAN
profiles (`--buan`): the points of segments below the threshold highlighted."""
import glob
import json
import os
import unittest
import zipfile

import numpy as np
from PIL import Image

from hztest import TempDirTest, run

NO_DISPLAY = {"DISPLAY": ""}
TITLE_ROWS = 24  # (a tile's title is painted over its top rows)


def load(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def bundles_zip():
    import dipy
    return os.path.join(os.path.dirname(dipy.__file__), "data", "files", "minimal_bundles.zip")


class MinimalBundles(TempDirTest):
    """DIPY's minimal_bundles.zip extracted into the test's folder."""

    def setUp(self):
        super().setUp()
        with zipfile.ZipFile(bundles_zip()) as z:
            z.extractall(self.path("mb"))
        self.subjects = sorted(os.path.basename(p) for p in glob.glob(self.path("mb/sub_*")))
        self.camera = {"position": [-250.0, -60.0, 40.0], "target": [0.0, -20.0, 5.0], "up": [0, 0, 1]}


class GridTest(MinimalBundles):
    def objects(self, subjects, cells=True):
        out = []
        for k, sub in enumerate(subjects):
            for b in ("AF_L", "CC_ForcepsMajor", "CST_R"):
                ob = {"type": "streamlines", "file": f"mb/{sub}/{b}.trk", "render": "tubes", "radius": 0.6}
                if cells:
                    ob["cell"] = k
                out.append(ob)
        return out

    def render(self, name, scene, size, *args):
        with open(self.path(name + ".json"), "w") as f:
            json.dump(scene, f)
        p = run("render", self.path(name + ".json"), "-o", self.path(name + ".png"), "--size", size, "--no-aa", "--json", *args,
                env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        return load(self.path(name + ".png")), json.loads(p.stdout)

    def test_tiles_are_each_subject_alone(self):
        """Three subjects in two columns: each tile is that subject's render
        with the same camera; the shared object (a sphere) in every tile; the
        empty sixth... fourth tile the background."""
        subs = self.subjects[:3]
        grid = {"objects": self.objects(subs) + [{"type": "surface", "builtin": "sphere", "name": "shared"}],
                "camera": self.camera, "grid": {"columns": 2, "titles": subs}}
        grid["objects"][-1]["material"] = {"shader": "principled", "params": {"roughness": 0.5}}
        grid["objects"][-1]["opacity"] = 1.0
        grid["objects"][-1]["color"] = [0.3, 0.3, 0.3]
        im, j = self.render("grid", grid, "400x400")
        self.assertEqual((j["grid"]["columns"], j["grid"]["rows"], j["grid"]["titles"]), (2, 2, subs))
        alone = []
        for k, sub in enumerate(subs):
            scene = {"objects": [o for o in self.objects([sub], cells=False)] + [grid["objects"][-1]], "camera": self.camera}
            alone.append(self.render(f"alone{k}", scene, "200x200")[0])
        for k, sub in enumerate(subs):
            with self.subTest(subject=sub):
                r, c = divmod(k, 2)
                tile = im[r * 200:(r + 1) * 200, c * 200:(c + 1) * 200]
                diff = np.abs(tile - alone[k])[TITLE_ROWS:]
                # (the same but for the depth range the camera's planes span, fitted to every subject: a pixel in 100 along edges)
                self.assertLess(diff.mean(), 0.5, sub)
                self.assertLess((diff.max(axis=-1) > 10).mean(), 0.02, sub)
                for j in range(len(subs)):
                    if j != k:
                        self.assertGreater(np.abs(tile - alone[j])[TITLE_ROWS:].mean(), 5 * diff.mean() + 1, f"{sub} against {subs[j]}")
                # Its title: bright text over the tile's top left.
                self.assertGreater(np.abs(tile[:TITLE_ROWS, :80] - alone[k][:TITLE_ROWS, :80]).max(), 100)
        # The subjects differ from each other.
        self.assertGreater(np.abs(im[TITLE_ROWS:200, :200] - im[TITLE_ROWS:200, 200:]).mean(), 1.0)
        # The fourth tile holds no cell: the background.
        self.assertLess(np.abs(im[200:, 200:] - im[200 + 100, 200 + 5]).max(), 2)

    def test_from_the_command_line(self):
        """`--grid folders`: one tile a subject folder (five: three columns,
        two rows), titled by the folder; `--grid files`: one a file."""
        files = sorted(glob.glob(self.path("mb/sub_*/*.trk")))
        out = self.path("cli.png")
        p = run("render", *files, "--grid", "folders", "--view", "left", "-o", out, "--size", "480x320", "--json", env=NO_DISPLAY,
                timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        j = json.loads(p.stdout)
        self.assertEqual((j["grid"]["columns"], j["grid"]["rows"], j["grid"]["titles"]), (3, 2, self.subjects))
        im = load(out)
        for k in range(5):
            r, c = divmod(k, 3)
            tile = im[r * 160 + TITLE_ROWS:(r + 1) * 160, c * 160:(c + 1) * 160]
            self.assertGreater((np.abs(tile - tile[-1, -1]).max(axis=-1) > 30).sum(), 300, f"tile {k}")
        two = files[:2]
        p = run("render", *two, "--grid", "files", "--grid-columns", "1", "-o", self.path("f.png"), "--size", "200x300", "--json",
                env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        j = json.loads(p.stdout)
        self.assertEqual((j["grid"]["columns"], j["grid"]["rows"], j["grid"]["titles"]), (1, 2, [os.path.basename(f) for f in two]))

    def test_movie_of_a_grid(self):
        """A movie's frames are the grid too: frame 0 equals the still."""
        scene = {"objects": self.objects(self.subjects[:2]), "camera": self.camera, "grid": {"titles": self.subjects[:2]}}
        still, _ = self.render("still", scene, "320x160")
        os.mkdir(self.path("f"))
        p = run("movie", self.path("still.json"), "-o", self.path("f/%02d.png"), "--size", "320x160", "--seconds", "1", "--fps", "2",
                "--no-aa", env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertLess(np.abs(load(self.path("f/00.png")) - still).mean(), 0.5)

    def test_bad_grids(self):
        base = {"objects": self.objects(self.subjects[:2]), "camera": self.camera}
        cases = {
            "no_grid": (dict(base), "objects[0].cell: the scene has no \"grid\""),
            "no_cells": ({"objects": self.objects(self.subjects[:1], cells=False), "grid": {}}, "grid: no object has a \"cell\""),
            "titles": (dict(base, grid={"titles": ["a", "b", "c"]}), "grid.titles: 3 titles for 2 cells"),
            "columns": (dict(base, grid={"columns": 0}), "grid.columns"),
            "key": (dict(base, grid={"rows": 2}), "unknown key 'rows'"),
        }
        cases["cell"] = ({"objects": [dict(self.objects(self.subjects[:1])[0], cell=-2)], "grid": {}}, "objects[0].cell")
        self.assert_scene_errors(cases)


if __name__ == "__main__":
    unittest.main()


class BuanTest(MinimalBundles):
    """BUAN profiles (`--buan`, a scene's "buan"; dipy_horizon's --buan): the
    points of the segments whose p-value is below the threshold in the
    highlight colour, the rest as the tractogram is coloured. (Which segment
    each point is in is DIPY's assignment_map: tests/python.)"""

    def marked(self, pvalues, *args):
        np.save(self.path("p.npy"), np.asarray(pvalues) if np.asarray(pvalues).dtype != np.int64 else pvalues)
        out = self.path("b.png")
        p = run("render", self.path("mb/sub_1/AF_L.trk"), "--buan", self.path("p.npy"), "--tract-colour", "0,1,0", "--buan-highlight",
                "1,0,1", "--view", "left", "-o", out, "--size", "240x180", "--force", *args, env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        im = load(out)
        magenta = (im[..., 0] > im[..., 1] + 40) & (im[..., 2] > im[..., 1] + 40)
        green = (im[..., 1] > im[..., 0] + 40) & (im[..., 1] > im[..., 2] + 40)
        return int(magenta.sum()), int(green.sum())

    def test_highlight_below_the_threshold(self):
        none, green_none = self.marked(np.ones(100))
        every, green_every = self.marked(np.zeros(100))
        half, _ = self.marked(np.r_[np.zeros(50), np.ones(50)])
        self.assertEqual(none, 0)
        self.assertGreater(green_none, 300)
        self.assertGreater(every, 300)
        self.assertEqual(green_every, 0)
        self.assertTrue(0.2 * every < half < 0.8 * every, (half, every))
        # The threshold: 0.03 is below the default 0.05, not below 0.01.
        self.assertGreater(self.marked(np.full(100, 0.03))[0], 300)
        self.assertEqual(self.marked(np.full(100, 0.03), "--buan-threshold", "0.01")[0], 0)
        # numpy's other layouts: big-endian float64, float32, a column.
        self.assertEqual(self.marked(np.full(100, 0.9).astype(">f8"))[0], 0)
        self.assertGreater(self.marked(np.full(100, 0.01).astype("<f4"))[0], 300)
        self.assertGreater(self.marked(np.full((100, 1), 0.01))[0], 300)
        # A scene file's "buan" draws the same.
        np.save(self.path("q.npy"), np.r_[np.zeros(50), np.ones(50)])
        scene = {"objects": [{"type": "streamlines", "file": "mb/sub_1/AF_L.trk", "color": [0, 1, 0], "render": "tubes", "radius": 0.3,
                              "buan": {"pvalues": "q.npy", "highlight": [1, 0, 1]}}], "camera": {"view": "left"}}
        with open(self.path("s.json"), "w") as f:
            json.dump(scene, f)
        p = run("render", self.path("s.json"), "-o", self.path("s.png"), "--size", "240x180", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.marked(np.r_[np.zeros(50), np.ones(50)])
        self.assertLess(np.abs(load(self.path("s.png")) - load(self.path("b.png"))).mean(), 0.5)

    def test_bad_profiles(self):
        with open(self.path("text.npy"), "w") as f:
            f.write("0.1 0.2\n")
        np.save(self.path("matrix.npy"), np.zeros((3, 4)))
        np.save(self.path("nan.npy"), np.array([0.1, np.nan]))
        np.save(self.path("ok.npy"), np.zeros(10))
        trk = self.path("mb/sub_1/AF_L.trk")
        for args, name, msg in (
                ([trk, "--buan", self.path("text.npy")], "text.npy", "not a .npy file"),
                ([trk, "--buan", self.path("matrix.npy")], "matrix.npy", "holds 3 x 4 values"),
                ([trk, "--buan", self.path("nan.npy")], "nan.npy", "value 1 is not a number"),
                ([trk, "--buan", self.path("ok.npy"), "--buan", self.path("ok.npy")], "--buan", "2 profiles for 1 tractogram")):
            with self.subTest(case=name):
                p = run("render", *args, "-o", self.path("x.png"), env=NO_DISPLAY, timeout=60)
                self.assert_clean_error(p, name)
                self.assertIn(msg, p.stderr)
                self.assertFalse(os.path.exists(self.path("x.png")))
        self.assert_scene_errors({"clusters": ({"objects": [{"type": "streamlines", "file": trk, "clustering": {"thresholds": [20]},
                                                              "buan": {"pvalues": self.path("ok.npy")}}]},
                                               "a BUAN profile is drawn on the bundle's streamlines, not on clusters")})
