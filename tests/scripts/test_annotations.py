"""Annotations over a picture, through `horizon render` (headless) and the
window: a colour bar for every object coloured through a colormap, the
orientation of the patient's axes, a scale bar.

Each is checked against a reference computed here, not by the renderer:
the colour bar's rows against matplotlib's own table of the colormap, the
orientation triad's letters against the camera's basis built from its
position, target and up (a standard look-at), and the scale bar's length in
pixels against the pinhole camera's millimetres per pixel at the target's
depth.
"""
import json
import math
import os
import unittest

import nibabel as nib
import numpy as np
from matplotlib import colormaps
from PIL import Image

from hztest import HORIZON, TempDirTest, run, xvfb_run


def look_at_basis(eye, target, up):
    back = np.asarray(eye, float) - np.asarray(target, float)
    back /= np.linalg.norm(back)
    right = np.cross(np.asarray(up, float), back)
    right /= np.linalg.norm(right)
    return right, np.cross(back, right), back


class AnnotationTest(TempDirTest):
    def setUp(self):
        super().setUp()
        # A 20^3 volume of values 0..100 (1 mm voxels, centred at the origin).
        data = np.linspace(0, 100, 20 ** 3, dtype=np.float32).reshape(20, 20, 20)
        affine = np.diag([1.0, 1.0, 1.0, 1.0])
        affine[:3, 3] = -10
        nib.save(nib.Nifti1Image(data, affine), self.path("v.nii.gz"))
        with open(self.path("plane.obj"), "w") as f:
            f.write("v -30 -30 0\nv 30 -30 0\nv 30 30 0\nv -30 30 0\nf 1 2 3\nf 1 3 4\n")

    def scene(self, annotations, camera=None, objects=None):
        s = {"camera": camera or {"view": "superior"}, "environment": {"type": "none"},
             "objects": objects or [{"type": "slices", "file": "v.nii.gz", "name": "FA", "colormap": "viridis", "window": [0, 100]}]}
        if annotations is not None:
            s["annotations"] = annotations
        path = self.path("scene.json")
        with open(path, "w") as f:
            json.dump(s, f)
        return path

    def render(self, scene, *args, size="600x400"):
        out = self.path("out.png")
        p = run("render", scene, "-o", out, "--size", size, "--force", "--json", *args, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        info = json.loads(p.stdout)
        return np.asarray(Image.open(out).convert("RGB"), dtype=np.float64), {a["role"]: a for a in info["annotations"]}

    def test_colour_bar_rows_are_the_colormaps_table(self):
        for name in ("viridis", "inferno", "hot", "coolwarm", "gray"):
            objects = [{"type": "slices", "file": "v.nii.gz", "name": "FA", "colormap": name, "window": [0, 100]}]
            im, marks = self.render(self.scene({"colour_bar": True}, objects=objects))
            x0, y0, x1, y1 = marks["colour bar"]["box"]
            self.assertGreater(y1 - y0, 100, marks)
            self.assertEqual(marks["colour bar label"]["text"], ["100", "50", "0"])
            self.assertEqual(marks["colour bar title"]["text"], ["FA"])
            x = int(round((x0 + x1) / 2))
            rows = np.arange(int(round(y0)), int(round(y1)))
            t = 1.0 - (rows - y0 + 0.5) / (y1 - y0)  # (the top row is the range's upper end)
            table = colormaps[name](np.arange(colormaps[name].N))[:, :3]  # (its entries, linearly between)
            positions = np.linspace(0, 1, len(table))
            reference = np.stack([np.interp(t, positions, table[:, i]) for i in range(3)], 1) * 255.0
            error = np.abs(im[rows, x] - reference).max()
            self.assertLess(error, 3.0, f"{name}: {error:.1f}/255 from matplotlib's table")
        # Nothing of it without the annotation.
        plain, marks = self.render(self.scene(None))
        self.assertEqual(marks, {})
        self.assertGreater(np.abs(im[rows, x] - plain[rows, x]).max(), 50)

    def test_the_orientation_triad_follows_the_camera(self):
        """Each letter lies where the camera's basis puts its axis: R (+x),
        A (+y), S (+z) from the triad's centre, their opposites across it."""
        cameras = [({"view": "superior"}, None), ({"view": "left"}, None), ({"view": "anterior"}, None),
                   ({"position": [120, -150, 90], "target": [0, 0, 0], "up": [0, 0, 1]}, None)]
        for camera, _ in cameras:
            im, marks = self.render(self.scene({"orientation": True}, camera=camera))
            info = json.loads(run("render", self.path("scene.json"), "-o", self.path("o.png"), "--size", "600x400", "--force",
                                  "--json").stdout)
            view = {"superior": ([0, 0, 1], [0, 1, 0]), "left": ([-1, 0, 0], [0, 0, 1]), "anterior": ([0, 1, 0], [0, 0, 1])}
            if "view" in camera:
                direction, up = view[camera["view"]]
                eye, target = np.asarray(direction, float), np.zeros(3)
            else:
                eye, target, up = np.asarray(camera["position"], float), np.asarray(camera["target"], float), camera["up"]
            right, upv, back = look_at_basis(eye, target, up)
            centre = None
            for letter, axis in (("R", [1, 0, 0]), ("A", [0, 1, 0]), ("S", [0, 0, 1])):
                pos = np.asarray(marks[f"orientation {letter}"]["box"][:2])
                opposite = np.asarray(marks[f"orientation {'LPI'['RAS'.index(letter)]}"]["box"][:2])
                mid = (pos + opposite) / 2
                centre = mid if centre is None else centre
                np.testing.assert_allclose(mid, centre, atol=0.5)
                expected = np.array([np.dot(axis, right), -np.dot(axis, upv)])  # (picture y grows downwards)
                got = pos - mid
                length = np.linalg.norm(got)
                if np.linalg.norm(expected) > 0.2:
                    self.assertGreater(length, 5, (camera, letter, marks))
                    cos = np.dot(got, expected) / (length * np.linalg.norm(expected))
                    self.assertGreater(cos, 0.99, (camera, letter, got, expected))
                else:  # (an axis along the view: its letters near the centre)
                    self.assertLess(length, 12, (camera, letter, got))
                # The letter is painted there: its colour under its anchor.
                x, y = (int(round(c)) for c in pos)
                patch = im[y - 6:y + 7, x - 5:x + 6]
                if letter == "R":
                    self.assertTrue(((patch[..., 0] > 150) & (patch[..., 1] < 140)).any(), (camera, patch.max((0, 1))))
            del info

    def test_scale_bar_measures_millimetres_at_the_target(self):
        for distance, mm in ((300.0, 20), (600.0, 50)):
            camera = {"position": [0, 0, distance], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 30}
            objects = [{"type": "surface", "file": "plane.obj"}]
            im, marks = self.render(self.scene({"scale_bar": True}, camera=camera, objects=objects))
            self.assertEqual(marks["scale bar label"]["text"], [f"{mm} mm"])
            mm_per_px = 2 * distance * math.tan(math.radians(15)) / 400
            x0, y0, x1, y1 = marks["scale bar"]["box"]
            self.assertAlmostEqual(x1 - x0, mm / mm_per_px, delta=0.01)
            # Its pixels in the picture: a white run as long.
            row = im[int(round((y0 + y1) / 2) - 1)]
            white = np.flatnonzero(row.min(1) > 200)
            self.assertGreater(white.size, 0)
            self.assertAlmostEqual(white.max() - white.min() + 1, mm / mm_per_px, delta=1.5)

    def test_command_line_flags_replace_the_scene_files(self):
        _, marks = self.render(self.scene(None), "--annotations")
        self.assertIn("colour bar", marks)
        self.assertIn("orientation R", marks)
        self.assertIn("scale bar", marks)
        _, marks = self.render(self.scene(True))  # (a scene file's true: all three)
        self.assertTrue({"colour bar", "orientation R", "scale bar"} <= set(marks), marks)
        _, marks = self.render(self.scene(True), "--no-annotations")
        self.assertEqual(marks, {})
        _, marks = self.render(self.scene({"colour_bar": True}), "--scale-bar")
        self.assertEqual({m.split()[0] for m in marks}, {"colour", "scale"})
        _, marks = self.render(self.scene(None), "--color-bar")
        self.assertEqual({m.split()[0] for m in marks}, {"colour"})
        # A colour bar asked for alone over nothing colormapped: drawn without
        # it, and said why (one line); with the other annotations, silently.
        plane = [{"type": "surface", "file": "plane.obj"}]
        p = run("render", self.scene(None, objects=plane), "-o", self.path("p.png"), "--colour-bar", "--force")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(p.stderr.strip(), 'warning: colour bar: nothing in the picture is coloured through a colormap '
                         '(a "color" of mode "data", or a volume)')
        p = run("render", self.scene(None, objects=plane), "-o", self.path("p.png"), "--annotations", "--force")
        self.assertEqual((p.returncode, p.stderr), (0, ""))

    def test_the_window_switches_them_with_n(self):
        # (a surface first: its open section of material controls makes the
        # panel's first height room for the annotations' section below)
        scene = self.scene({"scale_bar": True}, objects=[
            {"type": "surface", "file": "plane.obj"},
            {"type": "slices", "file": "v.nii.gz", "name": "FA", "colormap": "viridis", "window": [0, 100]}])
        shots = [self.path(f"w{i}.png") for i in range(4)]
        script = self.path("script.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 3", f"screenshot {shots[0]}", "key n", "wait 2", f"screenshot {shots[1]}", "key n", "wait 2",
                               f"screenshot {shots[2]}", "press object 0", "wait 1", "press annotations", "wait 1", "press orientation", "wait 2",
                               f"screenshot {shots[3]}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # (Mesa's GLX driver, as in test_render's window tests)
        p = xvfb_run([HORIZON, "view", scene, "--size", "600x400", "--script", script], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("annotations: off", p.stdout)
        a, b, c, d = (np.asarray(Image.open(s).convert("RGB"), dtype=np.float64) for s in shots)
        # The scale bar the scene file asks for, as `render` draws it.
        ref, marks = self.render(scene)
        x0, y0, x1, y1 = (int(round(v)) for v in marks["scale bar"]["box"])
        np.testing.assert_array_equal(a[y0:y1, x0:x1], ref[y0:y1, x0:x1])
        # N takes it away; N again brings it back.
        self.assertGreater(np.abs(a[y0:y1, x0:x1] - b[y0:y1, x0:x1]).max(), 100)
        np.testing.assert_array_equal(a, c)
        # The panel's box adds the orientation, bottom left.
        corner = (slice(300, 400), slice(0, 110))
        self.assertGreater((np.abs(d[corner] - a[corner]).sum(2) > 30).sum(), 50)

    def test_a_section_opened_below_the_panels_first_height_is_usable(self):
        """The panel grows to what it shows: with only a slices object (a
        short first panel), its annotations section, opened, can be used
        (it was clipped at the panel's first height)."""
        shots = [self.path(f"p{i}.png") for i in range(2)]
        with open(self.path("script.txt"), "w") as f:
            f.write("\n".join(["wait 3", "press annotations", "wait 1", f"screenshot {shots[0]}", "press orientation", "wait 2",
                               f"screenshot {shots[1]}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # (Mesa's GLX driver, as in test_render's window tests)
        p = xvfb_run([HORIZON, "view", self.scene(None), "--size", "600x400", "--script", self.path("script.txt")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        a, b = (np.asarray(Image.open(s).convert("RGB"), dtype=np.float64) for s in shots)
        corner = (slice(300, 400), slice(0, 110))
        self.assertGreater((np.abs(b[corner] - a[corner]).sum(2) > 30).sum(), 50)

    def test_bad_annotations_are_one_line(self):
        for value, where in (("yes", "annotations"), ({"colorbar": True}, "colorbar"), ({"scale_bar": 1}, "annotations.scale_bar")):
            p = run("render", self.scene(value), "-o", self.path("x.png"), "--size", "64x64")
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
            self.assertIn(where, p.stderr)
            self.assertFalse(os.path.exists(self.path("x.png")))
        p = run("render", self.scene(True), "-o", self.path("x.exr"), "--size", "64x64")
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("annotations are drawn on a display picture", p.stderr)
        self.assertFalse(os.path.exists(self.path("x.exr")))
        p = run("render", self.scene(None), "-o", self.path("x.png"), "--annotations", "--no-annotations")
        self.assertNotEqual(p.returncode, 0)
        self.assertFalse(os.path.exists(self.path("x.png")))


if __name__ == "__main__":
    unittest.main()
