"""Masks and label volumes (a parcellation, FreeSurfer's aseg): each region
its colour from a FreeSurferColorLUT-format table, drawn on slices as its
area and its outline, in 3D as its surface; from scene files ("type":
"labels"), from `--roi-images` (dipy_horizon's) with `--lut`, and in the
window, whose readout names the label under the cursor. Label volumes
written by nibabel; what is drawn read back from the pictures. Malformed
tables, volumes that are not labels and options out of range are each one
line naming the file, nothing written."""
import json
import os
import re
import unittest

import nibabel as nib
import numpy as np
from PIL import Image

from hztest import HORIZON, TempDirTest, run, xvfb_run

NO_DISPLAY = {"DISPLAY": ""}
LUT = """#No. Label Name:                R   G   B   A
0   Unknown                         0   0   0   0
5   Right-Blob                      40  90  230 0
17  Left-Hippocampus                220 216 20  0
"""
YELLOW = np.array([220, 216, 20])
BACKGROUND = np.array([0, 0, 0])


def load(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


class LabelsTest(TempDirTest):
    def setUp(self):
        super().setUp()
        # 40^3 voxels of 2 mm: a box of label 17 through the centre (16 voxels
        # a side), a ball of label 5 in a corner; a T1-like volume beside it.
        lab = np.zeros((40, 40, 40), np.int16)
        lab[12:28, 12:28, 12:28] = 17
        i, j, k = np.indices(lab.shape)
        lab[(i - 6) ** 2 + (j - 32) ** 2 + (k - 20) ** 2 <= 16] = 5
        self.labels = lab
        self.affine = np.diag([2.0, 2.0, 2.0, 1.0])
        self.affine[:3, 3] = [-39, -39, -39]
        nib.save(nib.Nifti1Image(lab, self.affine), self.path("aseg.nii.gz"))
        nib.save(nib.Nifti1Image(np.full(lab.shape, 500, np.float32), self.affine), self.path("t1.nii.gz"))
        with open(self.path("lut.txt"), "w") as f:
            f.write(LUT)

    def render(self, name, objects, size="320x320", camera=None):
        with open(self.path(name + ".json"), "w") as f:
            json.dump({"objects": objects, "camera": camera or {"view": "superior"}, "background": [0, 0, 0]}, f)
        p = run("render", self.path(name + ".json"), "-o", self.path(name + ".png"), "--size", size, "--no-aa", "--force", env=NO_DISPLAY,
                timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return load(self.path(name + ".png"))

    def near(self, im, colour, tol=3):
        return np.all(np.abs(im - colour) <= tol, axis=-1)

    def test_areas_and_outlines_on_slices(self):
        """The box's area at `fill` over what is behind it, its border opaque
        and about two pixels wide; over a slice of the same plane
        listed before or after it."""
        base = {"type": "labels", "file": "aseg.nii.gz", "lut": "lut.txt", "x": None, "y": None, "z": 0}
        full = self.render("full", [dict(base, fill=1.0)])
        ring = self.render("ring", [dict(base, fill=0.0)])
        h, w, _ = full.shape
        np.testing.assert_allclose(full[h // 2, w // 2], YELLOW, atol=2)
        np.testing.assert_allclose(ring[h // 2, w // 2], BACKGROUND, atol=2)
        filled, outline = self.near(full, YELLOW).sum(), self.near(ring, YELLOW).sum()
        self.assertGreater(filled, 2000)
        # The outline: along the box's four sides (its side about sqrt(filled)
        # pixels), one to three pixels wide.
        side = np.sqrt(filled)
        self.assertGreater(outline, 4 * side * 1.0)
        self.assertLess(outline, 4 * side * 3.0)
        ys, xs = np.nonzero(self.near(ring, YELLOW))
        self.assertLess(np.abs(ys - h / 2).min(), side / 2 + 3)  # (no pixel of it inside, away from the sides)
        inner = (np.abs(ys - h / 2) < side / 2 - 4) & (np.abs(xs - w / 2) < side / 2 - 4)
        self.assertEqual(int(inner.sum()), 0)
        # The ball of label 5 in its colour, too.
        self.assertGreater(self.near(full, [40, 90, 230]).sum(), 50)
        # Half fill over a grey slice of the same plane: the blend, whichever comes first.
        grey = {"type": "slices", "file": "t1.nii.gz", "x": None, "y": None, "z": 0, "window": [0, 1000]}
        for order in ("labels first", "slices first"):
            with self.subTest(order=order):
                objs = [dict(base, fill=0.5), grey] if order == "labels first" else [grey, dict(base, fill=0.5)]
                im = self.render("half", objs)
                # (the grey slice: 500 of 0..1000, sRGB 128; blended half and half in the display's values)
                np.testing.assert_allclose(im[h // 2, w // 2], 0.5 * YELLOW + 0.5 * 128, atol=4)
        # Only the labels listed.
        only = self.render("only", [dict(base, fill=1.0, labels=[5])])
        self.assertEqual(int(self.near(only, YELLOW).sum()), 0)
        self.assertGreater(self.near(only, [40, 90, 230]).sum(), 50)

    def test_surfaces(self):
        """Each region's surface in its colour, lit: the box seen from above
        covers the centre in a yellow hue, the ball in blue; the slices hidden
        by x, y, z null."""
        im = self.render("surf", [{"type": "labels", "file": "aseg.nii.gz", "lut": "lut.txt", "surfaces": True, "x": None, "y": None,
                                   "z": None}])
        h, w, _ = im.shape
        c = im[h // 2, w // 2]
        self.assertGreater(c[0], 2 * c[2] + 10, c)  # (yellow: red and green well above blue)
        self.assertGreater(c[1], 2 * c[2] + 10, c)
        blue = (im[..., 2] > im[..., 0] + 40) & (im[..., 2] > im[..., 1] + 20)
        self.assertGreater(int(blue.sum()), 50)
        # The built-in segmentation of the demo's brain: its ventricles' surfaces.
        im = self.render("aseg", [{"type": "labels", "builtin": "aseg", "labels": [4, 43], "surfaces": True, "x": None, "y": None,
                                   "z": None}])
        purple = (im[..., 2] > im[..., 1] + 40) & (im[..., 0] > im[..., 1])
        self.assertGreater(int(purple.sum()), 500)

    def test_roi_images(self):
        """`--roi-images` (dipy_horizon's): a mask NIfTI's surface in 3D in
        the first label's colour; with --lut the table's; slices only with
        --no-label-surfaces, filled as --label-fill says."""
        mask = (self.labels == 17).astype(np.uint8)
        nib.save(nib.Nifti1Image(mask * 17, self.affine), self.path("mask17.nii.gz"))
        out = self.path("roi.png")
        p = run("render", self.path("mask17.nii.gz"), "--roi-images", "--lut", self.path("lut.txt"), "--view", "superior", "-o", out,
                "--size", "240x240", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        im = load(out)
        c = im[120, 120]
        self.assertGreater(min(c[0], c[1]), 2 * c[2] + 10, c)
        p = run("render", self.path("mask17.nii.gz"), "--roi-images", "--lut", self.path("lut.txt"), "--no-label-surfaces",
                "--label-fill", "1", "--background", "black", "--view", "superior", "-o", out, "--size", "240x240", "--force",
                env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        np.testing.assert_allclose(load(out)[120, 120], YELLOW, atol=2)

    def test_surfaces_of_volumes_and_the_glass_brain(self):
        """A scene's surface from a volume file: the boundary of its voxels
        above "above" (the box alone above 10, box and ball above 0);
        `--glass-brain MASK` adds that surface as glass around the data."""
        def triangles(scene, *args):
            with open(self.path("v.json"), "w") as f:
                json.dump(scene, f)
            p = run("render", self.path("v.json"), "-o", self.path("v.png"), "--size", "160x160", "--json", "--force", *args,
                    env=NO_DISPLAY, timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            return json.loads(p.stdout)["triangles"], load(self.path("v.png"))

        box, _ = triangles({"objects": [{"type": "surface", "file": "aseg.nii.gz", "above": 10}]})
        both, _ = triangles({"objects": [{"type": "surface", "file": "aseg.nii.gz"}]})
        self.assertGreater(box, 1000)
        self.assertGreater(both, box * 1.1)
        inner = {"objects": [{"type": "labels", "file": "aseg.nii.gz", "labels": [5], "surfaces": True, "x": None, "y": None,
                              "z": None}], "camera": {"view": "superior"}}
        shell, _ = triangles({"objects": [{"type": "surface", "file": "t1.nii.gz"}]})  # (every voxel above 0: the grid's box)
        alone, im0 = triangles(inner)
        glass, im1 = triangles(inner, "--glass-brain", self.path("t1.nii.gz"))
        self.assertEqual(glass - alone, shell)
        self.assertGreater(np.abs(im1 - im0).mean(), 0.5)  # (clear glass: its edges and highlights)
        p = run("render", self.path("aseg.nii.gz"), "--glass-brain", self.path("lut.txt"), "-o", self.path("x.png"), env=NO_DISPLAY)
        self.assert_clean_error(p, "lut.txt")
        self.assertFalse(os.path.exists(self.path("x.png")))

    def test_the_label_under_the_cursor(self):
        """The window's readout: the voxel, its label and the label's name."""
        with open(self.path("w.json"), "w") as f:
            json.dump({"objects": [{"type": "labels", "file": "aseg.nii.gz", "lut": "lut.txt", "x": None, "y": None, "z": 0}],
                       "camera": {"view": "superior"}}, f)
        script = self.path("p.txt")
        with open(script, "w") as f:
            f.write("wait 1\nprobe 160 160\nquit\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.path("w.json"), "--size", "320x320", "--script", script], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        line = [l for l in p.stdout.splitlines() if l.startswith("probe ")]
        self.assertEqual(len(line), 1, p.stdout)
        m = re.search(r"voxel \((\d+), (\d+), (\d+)\) = (-?\d+) (\S+)", line[0])
        self.assertIsNotNone(m, line[0])
        i, j, k = (int(m.group(n)) for n in (1, 2, 3))
        self.assertEqual(int(m.group(4)), self.labels[i, j, k])
        self.assertEqual((int(m.group(4)), m.group(5)), (17, "Left-Hippocampus"))

    def test_bad_input(self):
        """One line naming the file and what is wrong, nothing written."""
        nib.save(nib.Nifti1Image(np.full((4, 4, 4), 0.5, np.float32), np.eye(4)), self.path("float.nii.gz"))
        tables = {"short.txt": "17 Left 1 2\n", "bright.txt": "17 Left 1 2 300 0\n", "twice.txt": "1 a 1 1 1 0\n1 b 2 2 2 0\n",
                  "empty.txt": "# nothing\n"}
        for name, text in tables.items():
            with open(self.path(name), "w") as f:
                f.write(text)
        base = {"type": "labels", "file": "aseg.nii.gz"}
        cases = {
            "float": ({"type": "labels", "file": "float.nii.gz"}, "voxel (0, 0, 0) holds 0.500000: not a label"),
            "short": (dict(base, lut="short.txt"), "short.txt: line 1: expected INDEX NAME R G B [A], not 4 fields"),
            "bright": (dict(base, lut="bright.txt"), "bright.txt: line 1: R G B must be whole numbers in 0..255, not '300'"),
            "twice": (dict(base, lut="twice.txt"), "twice.txt: line 2: label 1 is listed twice"),
            "empty": (dict(base, lut="empty.txt"), "empty.txt: no label"),
            "missing": (dict(base, lut="none.txt"), "none.txt: no such file"),
            "absent": (dict(base, labels=[3]), "label 3 (3) is not in the volume"),
            "fill": (dict(base, fill=2), "fill"),
            "smoothing": (dict(base, smoothing=1.5), "expected a whole number of iterations"),
            "nothing": (dict(base, fill=0, outline=False), "nothing to draw"),
            "key": (dict(base, colour="red"), "unknown key 'colour'"),
            "above_none": ({"type": "surface", "file": "aseg.nii.gz", "above": 100}, "no voxel above 100"),
            "above_mesh": ({"type": "surface", "builtin": "sphere", "above": 1}, "'above' and 'smoothing' make a surface from a volume"),
        }
        self.assert_scene_errors({name: ({"objects": [ob]}, msg) for name, (ob, msg) in cases.items()})
        p = run("render", self.path("t1.nii.gz"), "--lut", self.path("lut.txt"), "-o", self.path("x.png"), env=NO_DISPLAY)
        self.assert_clean_error(p, "--lut")
        self.assertIn("no label volume", p.stderr)
        p = run("render", self.path("float.nii.gz"), "--roi-images", "-o", self.path("x.png"), env=NO_DISPLAY)
        self.assert_clean_error(p, "float")
        self.assertIn("float.nii.gz", p.stderr)
        self.assertFalse(os.path.exists(self.path("x.png")))


if __name__ == "__main__":
    unittest.main()
