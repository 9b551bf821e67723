"""The frame's passes after its geometry, through `horizon render` (headless)
and the window: ambient occlusion and the depth cue, against independent
references where they exist.

The reference for ambient occlusion is the ambient occlusion of a scene
whose answer is known in closed form: an infinitely long cylinder of radius
r resting on a plane. Seen in its cross-section from a point of the plane at
distance d from the cylinder's axis, the cylinder hides the directions
between phi_c - alpha and 90 degrees from the plane's normal (phi_c =
atan(d / r), sin(alpha) = r / sqrt(d^2 + r^2)); for a long cylinder the
cosine-weighted fraction of the hemisphere this hides is (1 - sin(phi_c -
alpha)) / 2: 1/2 where the cylinder touches the plane, 0.2 at d = 2r, 0.06
at d = 4r. A screen-space estimate sees only what is within its radius, so
it is compared by shape: its darkening of the plane must fall with d as the
reference does.
"""
import json
import math
import os
import unittest

import numpy as np
from PIL import Image

from hztest import HORIZON, TempDirTest, run, tck_bytes, xvfb_run


def srgb_to_linear(c):
    c = c / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def reference_occlusion(d, r):
    phi_c = math.atan2(d, r)
    alpha = math.asin(r / math.hypot(d, r))
    return (1 - math.sin(phi_c - alpha)) / 2



def demo_with_and_without(test, off_flag, says, min_darker, what):
    """The demo draws a pass unless OFF_FLAG: it says SAYS when on, and its picture is darker at MIN_DARKER
    pixels at least (WHAT), lighter at none."""
    for args, on in (((), True), ((off_flag,), False)):
        p = run("demo", "--out", test.path(f"demo{len(args)}"), "--streamlines", "300", "--no-window", *args, env={"DISPLAY": ""}, timeout=180)
        test.assertEqual(p.returncode, 0, p.stderr)
        test.assertEqual(says in p.stdout, on, p.stdout)
    a, b = (np.asarray(Image.open(test.path(f"demo{k}/demo.png")).convert("RGB"), dtype=np.float64) for k in (0, 1))
    test.assertGreater((a.sum(2) < b.sum(2) - 6).sum(), min_darker, what)
    test.assertEqual((a.sum(2) > b.sum(2) + 3).sum(), 0)

class AmbientOcclusionTest(TempDirTest):
    R = 3.0  # the cylinder's radius, mm

    def setUp(self):
        super().setUp()
        # A plane z = 0 of 60 x 60 mm (OBJ, two triangles), a tube of radius
        # R along y resting on it (its axis at z = R), longer than the plane.
        with open(self.path("plane.obj"), "w") as f:
            f.write("v -30 -30 0\nv 30 -30 0\nv 30 30 0\nv -30 30 0\nf 1 2 3\nf 1 3 4\n")
        line = np.stack([np.zeros(81), np.linspace(-40, 40, 81), np.full(81, self.R)], 1).astype(np.float32)
        with open(self.path("tube.tck"), "wb") as f:
            f.write(tck_bytes([line]))

    def scene(self, ao, **extra):
        s = {"camera": {"view": "superior"}, "environment": {"type": "none"},
             "lights": [{"type": "directional", "direction": [0, 0, 1], "space": "world", "intensity": 2.0}],
             "tonemap": "none",
             "objects": [{"type": "surface", "file": "plane.obj", "color": [0.7, 0.7, 0.7], "material": {"shader": "lambert"}},
                         {"type": "streamlines", "file": "tube.tck", "render": "tubes", "radius": self.R,
                          "color": [0.7, 0.7, 0.7], "material": {"shader": "lambert"}}]}
        if ao is not None:
            s["ambient_occlusion"] = ao
        s.update(extra)
        path = self.path("scene.json")
        with open(path, "w") as f:
            json.dump(s, f)
        return path

    def render(self, scene, *args):
        out = self.path("out.png")
        p = run("render", scene, "-o", out, "--size", "600x600", "--force", "--json", *args, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return np.asarray(Image.open(out).convert("RGB"), dtype=np.float64), json.loads(p.stdout)

    def test_darkening_falls_off_as_the_cylinders_true_occlusion(self):
        off, info = self.render(self.scene(None))
        self.assertFalse(info["passes"]["ambient_occlusion"]["on"])
        on, info = self.render(self.scene({"radius": 10, "strength": 1.0}))
        self.assertTrue(info["passes"]["ambient_occlusion"]["on"])
        self.assertGreater(info["passes"]["ambient_occlusion"]["ms"], 0)
        # The same from the command line over the scene file's setting.
        flags, _ = self.render(self.scene(None), "--ao", "--ao-radius", "10", "--ao-strength", "1")
        np.testing.assert_array_equal(flags, on)
        none, _ = self.render(self.scene({"radius": 10, "strength": 1.0}), "--no-ao")
        np.testing.assert_array_equal(none, off)

        # Where the plane is: the picture's columns across the tube (x), the
        # rows of the middle half (y), each column's mean; the tube's axis is
        # the darkest column of the plain picture's tube (its middle).
        lin_off, lin_on = srgb_to_linear(off).mean(2), srgb_to_linear(on).mean(2)
        rows = slice(150, 450)
        ratio = (lin_on[rows] / np.maximum(lin_off[rows], 1e-6)).mean(0)
        lit = lin_off[rows].mean(0)
        plane = np.flatnonzero(lit > 0.05)
        x0, x1 = plane[0], plane[-1]  # the plane's edges: 60 mm
        mm_per_px = 60.0 / (x1 - x0)
        axis = (x0 + x1) / 2.0
        d = (np.arange(600) - axis) * mm_per_px
        # Outside the tube's silhouette, out to 6 radii either side.
        sel = (np.abs(d) > self.R + 2 * mm_per_px) & (np.abs(d) < 6 * self.R) & (lit > 0.05)
        dark = 1 - ratio[sel]
        ref = np.array([reference_occlusion(abs(x), self.R) for x in d[sel]])
        # (The estimate pairs opposite samples, so that planes cancel: an
        # occluder on one side only counts half, 0.1 here against the true
        # 0.5 at the contact. Its shape is what is compared.)
        self.assertGreater(dark.max(), 0.07, "the plane beside the tube is darkened")
        corr = np.corrcoef(dark, ref)[0, 1]
        self.assertGreater(corr, 0.9, f"darkening against the true occlusion: correlation {corr:.3f}")
        # Monotone with distance on each side (within 0.02 of noise).
        for side in (d[sel] < 0, d[sel] > 0):
            order = np.argsort(np.abs(d[sel][side]))
            seq = dark[side][order]
            self.assertTrue(np.all(np.diff(seq) < 0.02), seq.round(3))
        # Far from the tube (beyond twice the radius sampled), nothing changes.
        far = (np.abs(d) > 25) & (lit > 0.05)
        self.assertLess(np.abs(1 - ratio[far]).max(), 0.01)
        # The background is never darkened.
        np.testing.assert_array_equal(on[:, :5], off[:, :5])

    def test_strength_scales_the_darkening(self):
        on1, _ = self.render(self.scene({"radius": 10, "strength": 1.0}))
        on_half, _ = self.render(self.scene({"radius": 10, "strength": 0.5}))
        off, _ = self.render(self.scene(None))
        lin = [srgb_to_linear(x).mean(2)[150:450] for x in (off, on1, on_half)]
        m = lin[0] > 0.05
        d1 = 1 - lin[1][m] / lin[0][m]
        dh = 1 - lin[2][m] / lin[0][m]
        strong = d1 > 0.1
        self.assertGreater(strong.sum(), 500)
        # (1 - 0.5 x occlusion) against (1 - occlusion), through 8-bit sRGB and
        # the encoded blend's power approximation: within a few percent.
        np.testing.assert_allclose(dh[strong], 0.5 * d1[strong], atol=0.04)

    def test_the_window_switches_it_with_o(self):
        """O in the window switches ambient occlusion: the picture darkens
        beside the tube, as `render --ao` draws it, and O again gives back
        the picture without it; --stats times the pass in the frames that
        ran it."""
        scene = self.scene({"on": False, "radius": 10, "strength": 1.0})
        shots = [self.path(f"w{i}.png") for i in range(4)]
        script = self.path("script.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 3", f"screenshot {shots[0]}", "key o", "wait 3", f"screenshot {shots[1]}", "key o", "wait 3",
                               f"screenshot {shots[2]}", "press object 0", "wait 1", "press depth cues", "wait 1",
                               "press ambient occlusion", "wait 3", f"screenshot {shots[3]}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # (Mesa's GLX driver, as in test_render's window tests)
        p = xvfb_run([HORIZON, "view", scene, "--size", "400x400", "--script", script, "--stats", self.path("stats.json")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("ambient occlusion: on", p.stdout)
        a, b, c, d = (np.asarray(Image.open(s).convert("RGB"), dtype=np.float64) for s in shots)
        np.testing.assert_array_equal(a, c)
        # The panel's box does what O does (the panel itself aside: its
        # folded and opened sections differ).
        right = slice(200, 400)
        np.testing.assert_array_equal(d[:, right], b[:, right])
        self.assertGreater((d[:, right].sum(2) < a[:, right].sum(2) - 3).sum(), 500)
        darker = (b.sum(2) < a.sum(2) - 3).sum()
        lighter = (b.sum(2) > a.sum(2) + 3).sum()
        self.assertGreater(darker, 1000)
        self.assertEqual(lighter, 0)
        frames = json.load(open(self.path("stats.json")))["frames"]
        self.assertTrue(any(f.get("ao_ms", 0) > 0 for f in frames))
        # Without a tractogram too (surfaces only: the key's action used to
        # be registered with the streamlines' editing session only).
        with open(self.path("meshes.json"), "w") as f:
            json.dump({"camera": {"view": "superior"}, "objects": [{"type": "surface", "file": "plane.obj"},
                                                                   {"type": "surface", "builtin": "sphere"}]}, f)
        with open(script, "w") as f:
            f.write("\n".join(["wait 3", f"screenshot {shots[0]}", "key o", "wait 3", f"screenshot {shots[1]}", "quit"]) + "\n")
        p = xvfb_run([HORIZON, "view", self.path("meshes.json"), "--size", "400x400", "--script", script], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("ambient occlusion: on", p.stdout)
        a, b = (np.asarray(Image.open(s).convert("RGB"), dtype=np.float64) for s in shots[:2])
        self.assertGreater((b.sum(2) < a.sum(2) - 3).sum(), 200)

    def test_the_keys_are_listed_by_view_help(self):
        p = run("view", "--help")
        self.assertEqual(p.returncode, 0, p.stderr)
        for line in ("  O             occlusion", "  E             expand", "  Ctrl+Shift+Z  redo", "  Ctrl+S        save what is shown"):
            self.assertIn(line, p.stdout)

    def test_moving_frames_darken_as_much_as_the_still(self):
        """While the camera moves, the window draws the last still again
        (reprojected) under the proxy, and the proxy frame runs the pass
        over both: the still must have been kept before its own pass ran,
        or what the camera saw at rest is darkened twice. The darkening of
        a moving frame (against the same frame without the pass) must be
        the still's, not its square."""
        p = run("demo", "--out", self.path("d"), "--streamlines", "600", "--no-window", env={"DISPLAY": ""}, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # (Mesa's GLX driver, as in test_render's window tests)
        means = {}
        for ao in ((), ("--ao", "--ao-radius", "6", "--ao-strength", "1")):
            script = self.path("s.txt")
            rest, moving = self.path(f"rest{len(ao)}.png"), self.path(f"moving{len(ao)}.png")
            with open(script, "w") as f:
                f.write("\n".join(["wait 2", f"screenshot {rest}", "moving on", "wait 2", f"screenshot {moving}", "quit"]) + "\n")
            p = xvfb_run([HORIZON, "view", self.path("d/phantom.tck"), "--size", "480x320", "--lod-points", "4000", "--script", script,
                          *ao], env)
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertIn("level of detail: 600 streamlines", p.stdout)
            for name, path in (("rest", rest), ("moving", moving)):
                lin = srgb_to_linear(np.asarray(Image.open(path).convert("RGB"), dtype=np.float64))
                means[name, bool(ao)] = lin[:, 160:].mean()  # (right of the panel)
        still = means["rest", True] / means["rest", False]
        moving = means["moving", True] / means["moving", False]
        self.assertLess(still, 0.95, "the pass darkens the still")
        self.assertLess(abs(moving - still), 0.5 * (1 - still), f"moving {moving:.3f} against still {still:.3f}")

    def test_the_demo_has_it_unless_told_otherwise(self):
        demo_with_and_without(self, "--no-ao", "ambient occlusion:", 2000, "contact shadows where the tubes meet the cortex and slices")

    def test_bad_settings_are_one_line(self):
        for ao, where in (({"radius": 0}, "ambient_occlusion.radius"), ({"strength": 2}, "ambient_occlusion.strength"),
                          ({"radius": 3, "samples": 4}, "samples"), ("yes", "ambient_occlusion")):
            p = run("render", self.scene(ao), "-o", self.path("x.png"), "--size", "64x64")
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
            self.assertIn("scene.json", p.stderr)
            self.assertIn(where, p.stderr)
            self.assertFalse(os.path.exists(self.path("x.png")))
        for args in (("--ao-radius", "0"), ("--ao-strength", "1.5"), ("--ao", "--no-ao")):
            p = run("render", self.scene(None), "-o", self.path("x.png"), "--size", "64x64", *args)
            self.assertNotEqual(p.returncode, 0, p.stderr)
            self.assertFalse(os.path.exists(self.path("x.png")))


class AntialiasingTest(TempDirTest):
    """Anti-aliasing against an independent reference: the same scene drawn
    at 4x the size without anti-aliasing and averaged over each 4 x 4 block
    (supersampling; tubes, whose width is in millimetres, so that the
    larger picture shows the same geometry; no decimation, which depends on
    the size)."""
    SCENE = {"objects": [{"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 300, "bundles": 6, "seed": 3},
                          "render": "tubes", "radius": 0.4}],
             "camera": {"view": "left"}}

    def render(self, name, size, *args, scene=None):
        with open(self.path("s.json"), "w") as f:
            json.dump(scene or self.SCENE, f)
        out = self.path(name)
        p = run("render", self.path("s.json"), "-o", out, "--size", size, "--lod-pixels", "0", "--force", "--json", *args, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        return np.asarray(Image.open(out).convert("RGB"), dtype=np.float64), json.loads(p.stdout)["passes"]["antialiasing"]

    def test_edges_and_jittered_frames_come_closer_to_supersampling(self):
        ref, _ = self.render("ref.png", "1280x960", "--samples", "1", "--no-aa")
        ref = ref.reshape(240, 4, 320, 4, 3).mean(axis=(1, 3))
        rms = {}
        for name, args in (("off", ("--no-aa",)), ("edge", ()), ("4", ("--aa-frames", "4")), ("16", ("--aa-frames", "16"))):
            im, aa = self.render(f"{name}.png", "320x240", "--samples", "1", *args)
            rms[name] = float(np.sqrt(((im - ref) ** 2).mean()))
            self.assertEqual(aa["edge"], name == "edge", aa)
            self.assertEqual(aa["frames"], int(name) if name.isdigit() else 1, aa)
        # Measured: off 9.9, edge 6.7, 4 frames 5.4, 16 frames 2.3.
        self.assertLess(rms["edge"], 0.8 * rms["off"], rms)
        self.assertLess(rms["4"], rms["edge"], rms)
        self.assertLess(rms["16"], 0.35 * rms["off"], rms)

    def test_the_edge_pass_leaves_flat_regions_and_multisampled_frames_alone(self):
        off, _ = self.render("off.png", "320x240", "--samples", "1", "--no-aa")
        edge, aa = self.render("edge.png", "320x240", "--samples", "1")
        self.assertTrue(aa["edge"])
        # (4-neighbourhoods without contrast: the background, the tubes' flat insides)
        lum = off @ [0.299, 0.587, 0.114] / 255
        pad = np.pad(lum, 1, mode="edge")
        nb = np.stack([pad[1:-1, 1:-1], pad[:-2, 1:-1], pad[2:, 1:-1], pad[1:-1, :-2], pad[1:-1, 2:]])
        flat = nb.max(0) - nb.min(0) < 0.02
        self.assertGreater(flat.sum(), 0.5 * flat.size)
        self.assertLessEqual(np.abs(edge - off)[flat].max(), 1)
        self.assertGreater((np.abs(edge - off).sum(2) > 6).sum(), 500, "edges smoothed")
        msaa, aa = self.render("msaa.png", "320x240", "--samples", "4")
        self.assertFalse(aa["edge"], "a multisampled frame gets no edge pass")
        plain, _ = self.render("msaa_off.png", "320x240", "--samples", "4", "--no-aa")
        np.testing.assert_array_equal(msaa, plain)

    def test_the_window_switches_it_with_g(self):
        with open(self.path("s.json"), "w") as f:
            json.dump(self.SCENE, f)
        shots = [self.path(f"g{i}.png") for i in range(3)]
        with open(self.path("script.txt"), "w") as f:
            f.write("\n".join(["wait 2", f"screenshot {shots[0]}", "key g", "wait 2", f"screenshot {shots[1]}", "key g", "wait 2",
                               f"screenshot {shots[2]}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.path("s.json"), "--size", "400x300", "--samples", "1", "--script", self.path("script.txt"),
                      "--stats", self.path("stats.json")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("anti-aliasing: off", p.stdout)
        self.assertIn("anti-aliasing: on", p.stdout)
        a, b, c = (np.asarray(Image.open(s).convert("RGB"), dtype=np.float64) for s in shots)
        np.testing.assert_array_equal(a, c)
        right = slice(160, 400)  # (the panel aside)
        self.assertGreater((np.abs(a[:, right] - b[:, right]).sum(2) > 6).sum(), 300)
        frames = json.load(open(self.path("stats.json")))["frames"]
        self.assertTrue(any(f["edge_aa"] for f in frames) and not all(f["edge_aa"] for f in frames if f["kind"] != "idle"))

    def test_the_window_at_rest_averages_jittered_frames_as_render_does(self):
        """A still at rest that is cheap to draw gets 8 jittered frames (the
        scene's `frames` where more), one a frame, shown as their average so
        far: the window's picture then equals `render --aa-frames 8`. None
        with anti-aliasing off, nor while moving."""
        with open(self.path("s.json"), "w") as f:
            json.dump(self.SCENE, f)
        shots = [self.path(f"w{i}.png") for i in range(2)]
        with open(self.path("script.txt"), "w") as f:
            f.write("\n".join(["wait 2", f"screenshot {shots[0]}", "mark off", "key g", "wait 2", f"screenshot {shots[1]}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.path("s.json"), "--size", "400x300", "--samples", "1", "--lod-pixels", "0", "--script",
                      self.path("script.txt"), "--stats", self.path("stats.json")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        frames = json.load(open(self.path("stats.json")))["frames"]
        off = next(i for i, f in enumerate(frames) if f["kind"] == "mark")
        acc = [f["aa_frames"] for f in frames[:off] if f["kind"] == "accumulate"]
        self.assertEqual(acc, list(range(1, 9)), "one jittered frame a frame, 8 in all")
        self.assertFalse([f for f in frames[off:] if f["kind"] == "accumulate"], "none with anti-aliasing off")
        window = [np.asarray(Image.open(s).convert("RGB"), dtype=np.float64) for s in shots]
        eight, _ = self.render("r8.png", "400x300", "--samples", "1", "--aa-frames", "8")
        none, _ = self.render("r0.png", "400x300", "--samples", "1", "--no-aa")
        right = slice(160, 400)  # (the panel aside)
        d = lambda a, b: float(np.abs(a[:, right] - b[:, right]).mean())
        self.assertLess(d(window[0], eight), 0.1, "the window's still is render's 8-frame still")
        self.assertGreater(d(window[0], none), 0.5)
        self.assertLess(d(window[1], none), 0.1, "G: neither the edge pass nor jittered frames")
        # The scene's frames where more than 8.
        with open(self.path("s16.json"), "w") as f:
            json.dump({**self.SCENE, "antialiasing": {"frames": 16}}, f)
        with open(self.path("script16.txt"), "w") as f:  # (a screenshot waits for the still's last frame)
            f.write(f"screenshot {self.path('a.png')}\nmoving on\nwait 3\nmoving off\nscreenshot {self.path('b.png')}\nquit\n")
        p = xvfb_run([HORIZON, "view", self.path("s16.json"), "--size", "400x300", "--samples", "1", "--script",
                      self.path("script16.txt"), "--stats", self.path("stats16.json")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        kinds = [(f["kind"], f.get("aa_frames")) for f in json.load(open(self.path("stats16.json")))["frames"]]
        self.assertEqual([n for k, n in kinds if k == "accumulate"], list(range(1, 17)) * 2, "16 at rest, before and after moving")
        moving = [i for i, (k, _) in enumerate(kinds) if k == "moving"]
        self.assertTrue(moving)
        self.assertFalse([k for k, _ in kinds[moving[0]:moving[-1]] if k == "accumulate"], "none while moving")

    def test_bad_settings_are_one_line(self):
        for aa, where in (({"frames": 0}, "antialiasing.frames"), ({"frames": 65}, "antialiasing.frames"),
                          ({"frames": 2.5}, "antialiasing.frames"), ({"samples": 4}, "samples"), ("yes", "antialiasing")):
            with self.subTest(aa=aa):
                with open(self.path("x.json"), "w") as f:
                    json.dump({**self.SCENE, "antialiasing": aa}, f)
                p = run("render", self.path("x.json"), "-o", self.path("x.png"), "--size", "64x64")
                self.assertEqual(p.returncode, 1)
                self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
                self.assertIn(where, p.stderr)
                self.assertFalse(os.path.exists(self.path("x.png")))
        for args in (("--aa-frames", "0"), ("--aa-frames", "65"), ("--aa-frames", "4", "--no-aa")):
            p = run("render", self.path("x.json"), "-o", self.path("x.png"), "--size", "64x64", *args)
            self.assertNotEqual(p.returncode, 0)
            self.assertFalse(os.path.exists(self.path("x.png")))


if __name__ == "__main__":
    unittest.main()


class DepthCueTest(TempDirTest):
    """Five flat squares facing a camera above them, at heights 0 to 40 mm:
    the depth cue mixes each towards the background by strength x (the
    scene's top - its height) / (top - bottom), whatever the camera's
    distance: a closed form of the geometry alone."""
    HEIGHTS = [0.0, 10.0, 20.0, 30.0, 40.0]

    def setUp(self):
        super().setUp()
        with open(self.path("squares.obj"), "w") as f:
            for k, z in enumerate(self.HEIGHTS):
                x0 = -50 + 20 * k
                f.write(f"v {x0} -8 {z}\nv {x0 + 16} -8 {z}\nv {x0 + 16} 8 {z}\nv {x0} 8 {z}\n")
            for k in range(len(self.HEIGHTS)):
                a = 4 * k + 1
                f.write(f"f {a} {a + 1} {a + 2}\nf {a} {a + 2} {a + 3}\n")

    def render(self, cue, *args):
        scene = {"camera": {"view": "superior"}, "environment": {"type": "none"}, "tonemap": "none", "background": [0.05, 0.1, 0.2],
                 "objects": [{"type": "surface", "file": "squares.obj", "color": [0.9, 0.6, 0.3], "material": {"shader": "flat"}}]}
        if cue is not None:
            scene["depth_cue"] = cue
        with open(self.path("s.json"), "w") as f:
            json.dump(scene, f)
        out = self.path("out.png")
        p = run("render", self.path("s.json"), "-o", out, "--size", "500x200", "--force", "--json", *args, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return np.asarray(Image.open(out).convert("RGB"), dtype=np.float64), json.loads(p.stdout)

    def square_centres(self, picture):
        """Each square's centre pixel, found in the picture without the cue
        (columns of the squares' colour, left to right)."""
        lit = np.abs(picture - picture[0, 0]).sum(2).max(0) > 30
        runs, start = [], None
        for x, v in enumerate(list(lit) + [False]):
            if v and start is None:
                start = x
            elif not v and start is not None:
                runs.append((start + x) // 2)
                start = None
        self.assertEqual(len(runs), len(self.HEIGHTS), runs)
        return runs

    def test_fades_linearly_with_depth_across_the_scene(self):
        off, info = self.render(None)
        self.assertFalse(info["passes"]["depth_cue"]["on"])
        for cue, args, strength in (({"strength": 0.8}, (), 0.8), (None, ("--depth-cue",), 0.6), (0.5, (), 0.5),
                                    (None, ("--depth-cue-strength", "1"), 1.0)):
            with self.subTest(cue=cue, args=args):
                on, info = self.render(cue, *args)
                self.assertTrue(info["passes"]["depth_cue"]["on"])
                bg = off[0, 0]
                top, bottom = max(self.HEIGHTS), min(self.HEIGHTS)
                for x, z in zip(self.square_centres(off), self.HEIGHTS):
                    w = strength * (top - z) / (top - bottom)
                    want = (1 - w) * off[100, x] + w * bg
                    np.testing.assert_allclose(on[100, x], want, atol=2.0, err_msg=f"square at {z} mm")
                np.testing.assert_array_equal(on[0, :], off[0, :])  # (the background)
        none, _ = self.render({"strength": 0.8}, "--no-depth-cue")
        np.testing.assert_array_equal(none, off)

    def test_the_window_switches_it_with_f(self):
        with open(self.path("s.json"), "w") as f:
            json.dump({"camera": {"view": "superior"}, "objects": [{"type": "surface", "file": "squares.obj"}]}, f)
        shots = [self.path(f"f{i}.png") for i in range(3)]
        with open(self.path("script.txt"), "w") as f:
            f.write("\n".join(["wait 3", f"screenshot {shots[0]}", "key f", "wait 3", f"screenshot {shots[1]}", "key f", "wait 3",
                               f"screenshot {shots[2]}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # (Mesa's GLX driver, as in test_render's window tests)
        p = xvfb_run([HORIZON, "view", self.path("s.json"), "--size", "400x300", "--script", self.path("script.txt")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("depth cue: on", p.stdout)
        a, b, c = (np.asarray(Image.open(s).convert("RGB"), dtype=np.float64) for s in shots)
        np.testing.assert_array_equal(a, c)
        self.assertGreater((np.abs(a - b).sum(2) > 6).sum(), 1000)

    def test_bad_settings_are_one_line(self):
        for cue, where in ((2, "depth_cue"), ({"strength": -1}, "depth_cue.strength"), ({"fog": 1}, "fog"), ("yes", "depth_cue")):
            with open(self.path("s.json"), "w") as f:
                json.dump({"depth_cue": cue, "objects": [{"type": "surface", "file": "squares.obj"}]}, f)
            p = run("render", self.path("s.json"), "-o", self.path("x.png"), "--size", "64x64")
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
            self.assertIn(where, p.stderr)
            self.assertFalse(os.path.exists(self.path("x.png")))
        p = run("render", self.path("squares.obj"), "-o", self.path("x.png"), "--depth-cue-strength", "3")
        self.assertNotEqual(p.returncode, 0)
        self.assertFalse(os.path.exists(self.path("x.png")))


class ShadowTest(TempDirTest):
    """Shadows of the key light against a ray cast of the same scene: a
    plane z = 0 lit by one directional light at THETA from its normal
    (towards +x), and above it at height H either a tube of radius R along y
    or a sheet of lines along y across x in [-3, 3]. A plane point (x, y, 0)
    is in shadow exactly where its ray towards the light meets the caster:
    for the tube where |x cos(THETA) + H sin(THETA)| < R, for the sheet
    where x + H tan(THETA) lies in [-3, 3]. The plane is seen from above, so
    its columns map linearly onto x (its edges at +-30 mm are found in the
    picture)."""
    H, R, THETA = 12.0, 3.0, math.radians(45)

    def setUp(self):
        super().setUp()
        with open(self.path("plane.obj"), "w") as f:
            f.write("v -30 -30 0\nv 30 -30 0\nv 30 30 0\nv -30 30 0\nf 1 2 3\nf 1 3 4\n")
        line = np.stack([np.zeros(81), np.linspace(-40, 40, 81), np.full(81, self.H)], 1).astype(np.float32)
        with open(self.path("tube.tck"), "wb") as f:
            f.write(tck_bytes([line]))
        sheet = [np.stack([np.full(81, x), np.linspace(-40, 40, 81), np.full(81, self.H)], 1).astype(np.float32)
                 for x in np.arange(-3, 3.0001, 0.025)]
        with open(self.path("sheet.tck"), "wb") as f:
            f.write(tck_bytes(sheet))

    def render(self, caster, to_light, shadows, plane=True, *args):
        objects = []
        grey = {"color": [0.7, 0.7, 0.7], "material": {"shader": "lambert"}}
        if plane:
            objects.append({"type": "surface", "file": "plane.obj", **grey})
        if caster == "tube":
            objects.append({"type": "streamlines", "file": "tube.tck", "render": "tubes", "radius": self.R, **grey})
        elif caster == "sheet":
            objects.append({"type": "streamlines", "file": "sheet.tck", "render": "lines", **grey})
        scene = {"camera": {"view": "superior"}, "environment": {"type": "none"}, "tonemap": "none", "objects": objects,
                 "lights": [{"type": "directional", "direction": list(to_light), "space": "world", "intensity": 1.0}]}
        if shadows is not None:
            scene["shadows"] = shadows
        with open(self.path("s.json"), "w") as f:
            json.dump(scene, f)
        out = self.path("out.png")
        p = run("render", self.path("s.json"), "-o", out, "--size", "400x400", "--force", "--json", *args, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return np.asarray(Image.open(out).convert("RGB"), dtype=np.float64), json.loads(p.stdout)

    def test_shadows_fall_where_a_ray_cast_says(self):
        to_light = (math.sin(self.THETA), 0.0, math.cos(self.THETA))
        for caster in ("tube", "sheet"):
            with self.subTest(caster=caster):
                off, info = self.render(caster, to_light, None)
                self.assertFalse(info["passes"]["shadows"]["on"])
                self.assertEqual(info["passes"]["shadows"]["map"], 0)
                on, info = self.render(caster, to_light, {"strength": 1.0, "softness": 0.5})
                self.assertTrue(info["passes"]["shadows"]["on"])
                self.assertGreater(info["passes"]["shadows"]["ms"], 0)
                edge = np.nonzero(np.abs(off[100] - off[5, 5]).sum(1) > 6)[0]
                c0, c1 = edge[0], edge[-1]
                self.assertGreater(c1 - c0, 200)
                mm = 60.0 / (c1 - c0 + 1)
                # The map: a texel no finer than a pixel of the picture (in
                # steps of 256 texels, at most 2048).
                size, texel = info["passes"]["shadows"]["map"], info["passes"]["shadows"]["texel_mm"]
                self.assertEqual(size % 256, 0)
                self.assertLessEqual(size, 2048)
                self.assertLessEqual(texel, 1.05 * mm)
                self.assertGreater(texel, 0.6 * mm, "a texel much finer than a pixel")
                if caster == "tube":
                    half = self.R / math.cos(self.THETA)
                    lo, hi = -self.H * math.tan(self.THETA) - half, -self.H * math.tan(self.THETA) + half
                else:
                    lo, hi = -3 - self.H * math.tan(self.THETA), 3 - self.H * math.tan(self.THETA)
                checked = 0
                for row in (150, 200, 250):
                    ratio = srgb_to_linear(on[row, :, 0]) / np.maximum(srgb_to_linear(off[row, :, 0]), 1e-6)
                    for c in range(c0 + 2, c1 - 1):
                        x = -30 + (c - c0 + 0.5) * mm
                        if abs(x) < 5:  # (the caster itself, seen from above)
                            continue
                        # Away from the edges by the filter's radius, a
                        # texel and a pixel: lit or in full shadow.
                        if min(abs(x - lo), abs(x - hi)) < 0.5 + texel + 1.5 * mm:
                            continue
                        want = 0.0 if lo < x < hi else 1.0
                        self.assertAlmostEqual(ratio[c], want, delta=0.04, msg=f"{caster}: x = {x:.2f} mm, row {row}")
                        checked += 1
                self.assertGreater(checked, 500)

    def test_strength_scales_the_shadow(self):
        to_light = (math.sin(self.THETA), 0.0, math.cos(self.THETA))
        off, _ = self.render("tube", to_light, None)
        x = -self.H * math.tan(self.THETA)  # the shadow's middle
        edge = np.nonzero(np.abs(off[100] - off[5, 5]).sum(1) > 6)[0]
        c = int(round(edge[0] + (x + 30) / 60.0 * (edge[-1] - edge[0] + 1)))
        for strength, args in ((0.5, ()), (0.75, ("--shadows",)), (0.3, ("--shadow-strength", "0.3"))):
            with self.subTest(strength=strength):
                on, info = self.render("tube", to_light, {"strength": strength} if not args else None, True, *args)
                self.assertTrue(info["passes"]["shadows"]["on"])
                got = srgb_to_linear(on[200, c, 0]) / srgb_to_linear(off[200, c, 0])
                self.assertAlmostEqual(got, 1 - strength, delta=0.03)
        none, info = self.render("tube", to_light, {"strength": 1.0}, True, "--no-shadows")
        self.assertFalse(info["passes"]["shadows"]["on"])
        np.testing.assert_array_equal(none, off)

    def test_nothing_shadows_itself_even_at_grazing_light(self):
        """Acne: what nothing occludes is as lit with shadows as without, for
        a plane, a tube and a sheet of lines, the light from overhead to 88
        degrees off, across and along the lines. A sheet of lines lit at
        grazing angles is the method's limit (its lines' neighbours lie
        within the filter at depths no line's own slope tells): a few
        levels there."""
        for caster, plane in ((None, True), ("tube", False), ("sheet", False)):
            for deg in (0, 45, 80, 88):
                for axis in ("x", "y"):
                    t = math.radians(deg)
                    to_light = (math.sin(t), 0, math.cos(t)) if axis == "x" else (0, math.sin(t), math.cos(t))
                    with self.subTest(caster=caster, deg=deg, axis=axis):
                        off, _ = self.render(caster, to_light, None, plane)
                        on, _ = self.render(caster, to_light, {"strength": 1.0}, plane)
                        worst = np.abs(on - off).max()
                        limit = 8 if caster == "sheet" and deg >= 80 else 4 if deg >= 88 else 1
                        self.assertLessEqual(worst, limit)

    def test_the_window_switches_them_with_l(self):
        to_light = (math.sin(self.THETA), 0.0, math.cos(self.THETA))
        self.render("tube", to_light, None)  # (writes s.json)
        shots = [self.path(f"l{i}.png") for i in range(4)]
        with open(self.path("script.txt"), "w") as f:
            f.write("\n".join(["wait 3", f"screenshot {shots[0]}", "key l", "wait 3", f"screenshot {shots[1]}", "key l", "wait 3",
                               f"screenshot {shots[2]}", "press object 0", "wait 1", "press depth cues", "wait 1", "press shadows",
                               "wait 3", f"screenshot {shots[3]}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.path("s.json"), "--size", "400x400", "--script", self.path("script.txt"),
                      "--stats", self.path("stats.json")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("shadows: on", p.stdout)
        self.assertIn("shadows: off", p.stdout)
        a, b, c, d = (np.asarray(Image.open(s).convert("RGB"), dtype=np.float64) for s in shots)
        np.testing.assert_array_equal(a, c)
        darker = (b.sum(2) < a.sum(2) - 30).sum()  # (the tube's shadow on the plane)
        self.assertGreater(darker, 2000)
        self.assertEqual((b.sum(2) > a.sum(2) + 3).sum(), 0)
        # The panel's box does what L does (the panel aside).
        right = slice(200, 400)
        np.testing.assert_array_equal(d[:, right], b[:, right])
        frames = json.load(open(self.path("stats.json")))["frames"]
        self.assertTrue(any(f.get("shadow_map", 0) >= 256 for f in frames))

    def test_the_windows_still_is_the_full_frames_and_moving_frames_have_them_too(self):
        """With a level-of-detail proxy, the window at rest draws the shadow
        map's full detail in steps before the picture's: the still must be
        the frame drawn without a proxy (every streamline casting). Moving
        frames draw a map of the proxy: shadows too, not none."""
        p = run("demo", "--out", self.path("d"), "--streamlines", "600", "--no-window", env={"DISPLAY": ""}, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        shots = {}
        for name, args in (("proxy", ("--lod-points", "4000", "--shadows", "--shadow-strength", "1")),
                           ("plain", ("--lod-points", "1e9", "--shadows", "--shadow-strength", "1")),
                           ("none", ("--lod-points", "4000"))):
            script = self.path("s.txt")
            rest, moving = self.path(f"rest_{name}.png"), self.path(f"moving_{name}.png")
            with open(script, "w") as f:
                f.write("\n".join(["wait 1", f"screenshot {rest}", "moving on", "wait 2", f"screenshot {moving}", "quit"]) + "\n")
            # (--aa-frames 1: the still without a proxy would be averaged over jittered frames, the refined one not)
            p = xvfb_run([HORIZON, "view", self.path("d/phantom.tck"), "--size", "480x320", "--aa-frames", "1", "--script", script,
                          *args, "--stats", self.path(f"stats_{name}.json")], env)
            self.assertEqual(p.returncode, 0, p.stderr)
            shots[name] = [np.asarray(Image.open(x).convert("RGB"), dtype=np.float64) for x in (rest, moving)]
        np.testing.assert_array_equal(shots["proxy"][0], shots["plain"][0])
        right = slice(160, 480)  # (right of the panel)
        self.assertGreater((shots["proxy"][0][:, right].sum(2) < shots["none"][0][:, right].sum(2) - 15).sum(), 1000)
        self.assertGreater((shots["proxy"][1][:, right].sum(2) < shots["none"][1][:, right].sum(2) - 15).sum(), 300)
        frames = json.load(open(self.path("stats_proxy.json")))["frames"]
        self.assertTrue(any(f["kind"] == "moving" and 0 < f["shadow_map"] < 2048 for f in frames), "a smaller map while moving")

    def test_the_demo_has_them_unless_told_otherwise(self):
        demo_with_and_without(self, "--no-shadows", "shadows:", 1000, "the tubes' and the cortex's shadows")

    def test_bad_settings_are_one_line(self):
        self.render("tube", (0, 0, 1), None)
        for sh, where in ((2, "shadows"), ({"strength": 1.5}, "shadows.strength"), ({"softness": -1}, "shadows.softness"),
                          ({"softness": 80}, "shadows.softness"), ({"bias": 1}, "bias"), ("yes", "shadows")):
            with open(self.path("s.json"), "w") as f:
                json.dump({"shadows": sh, "objects": [{"type": "surface", "file": "plane.obj"}]}, f)
            p = run("render", self.path("s.json"), "-o", self.path("x.png"), "--size", "64x64")
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
            self.assertIn(where, p.stderr)
            self.assertFalse(os.path.exists(self.path("x.png")))
        for args in (("--shadow-strength", "3"), ("--shadow-softness", "-1"), ("--shadows", "--no-shadows")):
            p = run("render", self.path("plane.obj"), "-o", self.path("x.png"), *args)
            self.assertNotEqual(p.returncode, 0)
            self.assertFalse(os.path.exists(self.path("x.png")))


class VolumeRenderingTest(TempDirTest):
    """Direct volume rendering against the emission-absorption integral
    computed here: a 32 mm cube (32^3 voxels of 1 mm, centred on the origin)
    seen from above along its axis, on a black background, with no tone
    curve. A transfer function of opacity a per millimetre and colour c
    gives, along a path of L mm through a homogeneous cube, c (1 - (1 -
    a)^L) exactly; through values that vary, the integral of c T kappa with
    kappa = -ln(1 - a) and T the transmittance, evaluated here with 20,000
    steps."""

    def setUp(self):
        super().setUp()
        import nibabel as nib
        affine = np.eye(4)
        affine[:3, 3] = -15.5
        nib.save(nib.Nifti1Image(np.ones((32, 32, 32), np.float32), affine), self.path("cube.nii.gz"))
        ramp = np.broadcast_to(np.arange(32, dtype=np.float32)[None, None, :], (32, 32, 32)).copy()
        nib.save(nib.Nifti1Image(ramp, affine), self.path("ramp.nii.gz"))
        with open(self.path("plane.obj"), "w") as f:
            f.write("v -40 -40 0\nv 40 -40 0\nv 40 40 0\nv -40 40 0\nf 1 2 3\nf 1 3 4\n")

    def render(self, objects, *args, name="v.png"):
        with open(self.path("s.json"), "w") as f:
            json.dump({"camera": {"view": "superior"}, "environment": {"type": "none"}, "tonemap": "none", "background": [0, 0, 0],
                       "objects": objects}, f)
        out = self.path(name)
        p = run("render", self.path("s.json"), "-o", out, "--size", "301x301", "--force", "--json", *args, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return np.asarray(Image.open(out).convert("RGB"), dtype=np.float64), json.loads(p.stdout)

    def cube(self, a, **extra):
        return {"type": "volume", "file": "cube.nii.gz", "window": [0, 1],
                "transfer": {"colormap": "gray", "opacity": [[0, a], [1, a]], "shade": False}, **extra}

    def centre(self, picture):
        return picture[148:153, 148:153, 0].mean() / 255.0

    def test_a_homogeneous_cube_absorbs_as_beer_lambert(self):
        for a in (0.02, 0.05, 0.2):
            with self.subTest(a=a):
                pic, info = self.render([self.cube(a)])
                self.assertEqual(info["passes"]["volume_rendering"]["volumes"], 1)
                self.assertAlmostEqual(self.centre(pic), 1 - (1 - a) ** 32, delta=1.5 / 255)
                # An opaque black plane through its middle: the rays end there.
                pic, _ = self.render([self.cube(a), {"type": "surface", "file": "plane.obj", "color": [0, 0, 0],
                                                     "material": {"shader": "flat"}}])
                self.assertAlmostEqual(self.centre(pic), 1 - (1 - a) ** 16, delta=1.5 / 255)
        pic, _ = self.render([self.cube(0.05, opacity=0.5)])
        self.assertAlmostEqual(self.centre(pic), 0.5 * (1 - 0.95 ** 32), delta=1.5 / 255)
        # Outside the cube: the background, untouched.
        self.assertEqual(pic[5, 5].max(), 0)

    def test_translucent_objects_in_front_of_and_behind_a_volume(self):
        """A translucent red square (opacity 0.5) above the cube (a = 0.05,
        white) or below it, seen from above: sorted compositing in linear
        light, from the two drawn alone: in front, square over volume; behind,
        volume over square; whatever the scene's order. (Volumes used to be
        composited after every translucent object, over them: a square in
        front showed behind the volume, its green channel 0.91 instead of
        0.67.) The volume's colours are composited as linear light in such a
        frame (as display values in a frame without translucency)."""
        def square(z):
            return {"type": "surface", "file": f"sq{z}.obj", "color": [1, 0, 0], "opacity": 0.5, "material": {"shader": "flat"}}

        for z in (25, -25):
            with open(self.path(f"sq{z}.obj"), "w") as f:
                f.write(f"v -40 -40 {z}\nv 40 -40 {z}\nv 40 40 {z}\nv -40 40 {z}\nf 1 2 3\nf 1 3 4\n")
        # In a linear frame (one with translucency) the white volume adds
        # alpha = 1 - 0.95^32 of white light, premultiplied (Beer-Lambert).
        alpha = 1 - 0.95 ** 32
        v = np.full(3, alpha)
        for z, front in ((25, True), (-25, False)):
            alone, _ = self.render([square(z)], name="square.png")
            sq = srgb_to_linear(alone[148:153, 148:153].mean(axis=(0, 1)))  # (premultiplied by its opacity, over black)
            self.assertAlmostEqual(sq[0], 0.5, delta=0.01)
            want = sq + 0.5 * v if front else v + (1 - alpha) * sq
            want = np.where(want <= 0.0031308, 12.92 * want, 1.055 * np.power(want, 1 / 2.4) - 0.055)
            for order in ("volume first", "square first"):
                with self.subTest(z=z, order=order):
                    objects = [self.cube(0.05), square(z)]
                    pic, info = self.render(objects if order == "volume first" else objects[::-1])
                    self.assertEqual(info["passes"]["volume_rendering"]["volumes"], 1)
                    got = pic[148:153, 148:153].mean(axis=(0, 1)) / 255.0
                    np.testing.assert_allclose(got, want, atol=2.5 / 255, err_msg=f"z {z}, {order}")

    def test_varying_values_follow_the_emission_absorption_integral(self):
        """Values rising from 0 at the bottom slice to 31 at the top, a
        window [0, 31], grey colours and opacity 0.15 x the window fraction
        per mm: seen from above, the bright top first."""
        obj = {"type": "volume", "file": "ramp.nii.gz", "window": [0, 31],
               "transfer": {"colormap": "gray", "opacity": [[0, 0.0], [1, 0.15]], "shade": False}}
        pic, _ = self.render([obj])
        n = 20000
        z = 16 - (np.arange(n) + 0.5) * 32 / n  # top to bottom, mm
        w = np.clip((z + 15.5) / 31.0, 0, 1)  # (voxel centres at -15.5..15.5; clamped beyond)
        kappa = -np.log(1 - 0.15 * w)
        dz = 32 / n
        transmittance = np.exp(-np.concatenate([[0], np.cumsum(kappa * dz)[:-1]]))
        want = float(np.sum(transmittance * (1 - np.exp(-kappa * dz)) * w))
        self.assertAlmostEqual(self.centre(pic), want, delta=2.0 / 255)

    def test_shading_follows_the_surfaces_normal(self):
        """A sphere of radius 20 mm as the level where a distance field
        crosses (values 25 - r, opaque above 5): lit by one light from above
        and seen from above, a pixel at distance rho from the disc's centre
        sees the normal n_z = sqrt(1 - (rho / 20)^2), so shading multiplies
        its colour (a display value, as the data's colours are composited) by
        0.3 + 0.7 n_z (1 at the centre, 0.906 at half the radius, 0.72 at 0.8
        of it); "shade": false leaves it as it is. A light from the side
        instead: 0.3 + 0.7 |n_x|, the ambient third at the centre."""
        import nibabel as nib
        n = 64
        ijk = np.indices((n, n, n)).astype(np.float32) - (n - 1) / 2
        r = np.sqrt((ijk ** 2).sum(axis=0))
        affine = np.eye(4)
        affine[:3, 3] = -(n - 1) / 2
        nib.save(nib.Nifti1Image((25 - r).astype(np.float32), affine), self.path("ball.nii.gz"))

        def ball(shade):
            # (the surface at 91 % of the window: a bright grey, finely quantised)
            return {"type": "volume", "file": "ball.nii.gz", "window": [4, 5.1],
                    "transfer": {"colormap": "gray", "opacity": [[0, 0], [0.899, 0], [0.9, 1], [1, 1]], "shade": shade}}

        def draw(shade, light):
            with open(self.path("s.json"), "w") as f:
                # (from far, through a narrow field: nearly orthographic, so that
                # a pixel's distance from the disc's centre is rho's)
                json.dump({"camera": {"position": [0, 0, 600], "target": [0, 0, 0], "up": [0, 1, 0], "fov": 5}, "environment": {"type": "none"},
                           "tonemap": "none", "background": [0, 0, 0],
                           "lights": [{"type": "directional", "direction": light, "space": "world"}], "objects": [ball(shade)]}, f)
            out = self.path("b.png")
            p = run("render", self.path("s.json"), "-o", out, "--size", "301x301", "--force", timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            return np.asarray(Image.open(out).convert("RGB"), dtype=np.float64)[..., 0] / 255

        flat = draw(False, [0, 0, 1])
        cols = np.nonzero(flat[150] > 0.1)[0]
        centre, radius = (cols[0] + cols[-1]) / 2, (cols[-1] - cols[0] + 1) / 2
        for light, want in (([0, 0, 1], lambda f: math.sqrt(1 - f * f)), ([1, 0, 0], abs)):
            lit = draw(True, light)
            for frac in (-0.8, -0.5, 0.0, 0.5, 0.8):
                x = int(round(centre + frac * radius))
                got = lit[148:153, x].mean() / flat[148:153, x].mean()
                self.assertAlmostEqual(got, 0.3 + 0.7 * want(frac), delta=0.04, msg=f"light {light}, at {frac} of the radius")

    def test_the_windows_still_with_a_proxied_tractogram_has_the_volume(self):
        """A window at rest with a tractogram large enough for a proxy refines
        in steps and keeps its still for the reprojection: the volume must be
        rendered into that still too, which must equal the still of the same
        window without a proxy (the volume was left out of it)."""
        rng = np.random.default_rng(5)
        lines = []
        for _ in range(400):
            a, b = rng.uniform(-30, 30, 3), rng.uniform(-30, 30, 3)
            lines.append(np.linspace(a, b, 40).astype(np.float32))
        with open(self.path("t.tck"), "wb") as f:
            f.write(tck_bytes(lines))
        import nibabel as nib
        ijk = np.indices((32, 32, 32)).astype(np.float32) - 15.5
        affine = np.eye(4)
        affine[:3, 3] = -15.5
        nib.save(nib.Nifti1Image((16 - np.sqrt((ijk ** 2).sum(axis=0))).astype(np.float32), affine), self.path("ball.nii.gz"))
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        shots = {}
        for name, args in (("proxy", ("--lod-points", "2000")), ("plain", ("--lod-points", "1e9")), ("none", ("--lod-points", "2000"))):
            shot = self.path(f"rest_{name}.png")
            with open(self.path("s.txt"), "w") as f:
                f.write("\n".join(["wait 2", f"screenshot {shot}", "quit"]) + "\n")
            files = [self.path("t.tck")] + ([] if name == "none" else [self.path("ball.nii.gz")])
            p = xvfb_run([HORIZON, "view", *files, "--size", "400x300", "--aa-frames", "1", "--script", self.path("s.txt"), *args,
                          *(() if name == "none" else ("--volume-render", "glow"))], env)
            self.assertEqual(p.returncode, 0, p.stderr)
            shots[name] = np.asarray(Image.open(shot).convert("RGB"), dtype=np.float64)
        np.testing.assert_array_equal(shots["proxy"], shots["plain"])
        right = slice(160, 400)
        self.assertGreater((np.abs(shots["proxy"][:, right] - shots["none"][:, right]).sum(2) > 30).sum(), 800, "the volume is there")

    def test_presets_files_and_the_window(self):
        with open(self.path("tf.json"), "w") as f:
            json.dump({"colormap": "hot", "opacity": [[0, 0.1], [1, 0.1]]}, f)
        for transfer in ("mri", "density", "hot", "glow", "tf.json"):
            with self.subTest(transfer=transfer):
                out = self.path("p.png")
                p = run("render", self.path("ramp.nii.gz"), "-o", out, "--size", "160x160", "--force", "--json",
                        "--volume-render", self.path(transfer) if transfer.endswith(".json") else transfer)
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertEqual(json.loads(p.stdout)["passes"]["volume_rendering"]["volumes"], 1)
                pic = np.asarray(Image.open(out).convert("RGB"), dtype=np.float64)
                self.assertGreater((pic.max(2) > 70).sum(), 300)
        # In the window: a volume rendered, moving frames too (small, three times the step).
        shots = [self.path("w0.png"), self.path("w1.png")]
        with open(self.path("script.txt"), "w") as f:
            f.write("\n".join(["wait 2", f"screenshot {shots[0]}", "moving on", "wait 2", f"screenshot {shots[1]}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.path("ramp.nii.gz"), "--volume-render", self.path("tf.json"), "--size", "400x400",
                      "--script", self.path("script.txt"), "--stats", self.path("stats.json")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        for s in shots:
            pic = np.asarray(Image.open(s).convert("RGB"), dtype=np.float64)
            self.assertGreater(pic[200, 300].max(), 40)
        frames = json.load(open(self.path("stats.json")))["frames"]
        self.assertTrue(any(f.get("volume_ms", 0) > 0 for f in frames))
        moving = [f for f in frames if f["kind"] == "moving"]
        self.assertTrue(moving and all(f["proxy"] for f in moving), "moving frames drawn small")

    def test_bad_transfer_functions_are_one_line(self):
        cases = (("bone", "no preset 'bone'"), ({"opacity": [[0, 0.1], [0, 0.2]]}, "opacity[1]: fractions must increase"),
                 ({"opacity": [[0, 1.5]]}, "opacity of one millimetre"), ({"opacity": [[-1, 0.5]]}, "fraction of the window"),
                 ({"opacity": []}, "1 to 256"), ({"colormap": "jet"}, "jet"), ({"shading": True}, "shading"), ({"shade": 1}, "shade"), ("missing.json", "missing.json"),
                 ("bad.json", "bad.json"))
        with open(self.path("bad.json"), "w") as f:
            f.write("{not json")
        for transfer, words in cases:
            with self.subTest(transfer=transfer):
                with open(self.path("s.json"), "w") as f:
                    json.dump({"objects": [{"type": "volume", "file": "cube.nii.gz", "transfer": transfer}]}, f)
                p = run("render", self.path("s.json"), "-o", self.path("x.png"), "--size", "64x64")
                self.assertEqual(p.returncode, 1, p.stderr)
                self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
                self.assertIn(words, p.stderr)
                self.assertFalse(os.path.exists(self.path("x.png")))
        for arg in ("bone", self.path("bad.json"), self.path("missing.json")):
            p = run("render", self.path("cube.nii.gz"), "-o", self.path("x.png"), "--size", "64x64", "--volume-render", arg)
            self.assertEqual(p.returncode, 1, p.stderr)
            self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
            self.assertFalse(os.path.exists(self.path("x.png")))


def linear(v):
    v = np.asarray(v, dtype=np.float64) / 255.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


class TransparencyTest(TempDirTest):
    """Translucent objects composited in depth order (depth peeling), not in
    the order of the scene file: every order of the objects gives the same
    picture, and it is sorted compositing of the objects' own colours
    (each measured alone, opaque), computed here in linear light."""

    def setUp(self):
        super().setUp()
        for k in range(12):  # squares at z = 0, 2, ..., 22, each shifted right
            x0, z = -30 + 2 * k, 2 * k
            with open(self.path(f"sq{k}.obj"), "w") as f:
                f.write(f"v {x0} -20 {z}\nv {x0 + 40} -20 {z}\nv {x0 + 40} 20 {z}\nv {x0} 20 {z}\nf 1 2 3\nf 1 3 4\n")
        with open(self.path("floor.obj"), "w") as f:
            f.write("v -60 -40 -5\nv 60 -40 -5\nv 60 40 -5\nv -60 40 -5\nf 1 2 3\nf 1 3 4\n")

    def square(self, k, colour, opacity):
        return {"type": "surface", "file": f"sq{k}.obj", "color": colour, "opacity": opacity, "material": {"shader": "flat"}}

    def render(self, objects, name="t.png"):
        scene = {"camera": {"position": [0, 0, 250], "target": [0, 0, 0], "up": [0, 1, 0]}, "environment": {"type": "none"},
                 "tonemap": "none", "background": [0.1, 0.1, 0.1], "objects": objects}
        with open(self.path("s.json"), "w") as f:
            json.dump(scene, f)
        p = run("render", self.path("s.json"), "-o", self.path(name), "--size", "300x200", "--force", "--json", timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return np.asarray(Image.open(self.path(name)).convert("RGB"), dtype=np.float64), json.loads(p.stdout)

    def sorted_reference(self, objects, pixel, background):
        """Front (largest z) over the rest, each at its measured colour."""
        out = linear(background)
        for o in sorted(objects, key=lambda o: int(o["file"][2:-4])):  # back to front
            alone, _ = self.render([dict(o, opacity=1.0)], "alone.png")
            out = o["opacity"] * linear(alone[pixel]) + (1 - o["opacity"]) * out
        return np.where(out <= 0.0031308, out * 12.92, 1.055 * out ** (1 / 2.4) - 0.055) * 255

    def test_any_order_gives_sorted_compositing(self):
        colours = [[0.9, 0.1, 0.1], [0.1, 0.9, 0.1], [0.1, 0.1, 0.9]]
        objs = [self.square(k * 5, colours[k], 0.5) for k in range(3)]  # z = 0, 10, 20
        pictures = [self.render([objs[i] for i in order])[0] for order in ((0, 1, 2), (2, 0, 1), (1, 2, 0), (2, 1, 0))]
        for p in pictures[1:]:
            np.testing.assert_array_equal(p, pictures[0])
        first, info = self.render(objs)
        self.assertEqual(info["passes"]["transparency"]["layers"], 3)
        # Where all three overlap (x in [0, 10]): sorted compositing.
        pixel = (100, 160)
        reference = self.sorted_reference(objs, pixel, first[5, 5])
        np.testing.assert_allclose(first[pixel], reference, atol=1.5)
        # Behind an opaque square, a translucent one is hidden.
        opaque = {"type": "surface", "file": "sq11.obj", "color": [0.8, 0.8, 0.8], "material": {"shader": "flat"}}
        hidden, _ = self.render([opaque, self.square(0, [0.9, 0.1, 0.1], 0.5)])
        alone, _ = self.render([opaque])
        np.testing.assert_array_equal(hidden[100, 150], alone[100, 150])

    def test_behind_an_opaque_surface_and_beyond_eight_layers(self):
        """Twelve translucent squares over an opaque floor: the first eight
        layers sorted exactly, the rest in drawing order as one last layer
        (what reaches it is 0.7^8 of the light): within 3/255 of sorted
        compositing, whatever the order."""
        rng = np.random.default_rng(5)
        objs = [self.square(k, [float(x) for x in rng.uniform(0.1, 0.9, 3)], 0.3) for k in range(12)]
        floor = {"type": "surface", "file": "floor.obj", "color": [0.8, 0.8, 0.2], "material": {"shader": "flat"}}
        pixel = (100, 152)  # (x = 1 mm: under all twelve)
        a, info = self.render([floor] + objs)
        self.assertEqual(info["passes"]["transparency"]["layers"], 9)
        b, _ = self.render([objs[i] for i in rng.permutation(12)] + [floor])
        floor_alone, _ = self.render([floor], "floor.png")
        reference = self.sorted_reference(objs, pixel, floor_alone[pixel])
        np.testing.assert_allclose(a[pixel], reference, atol=3.0)
        np.testing.assert_allclose(b[pixel], reference, atol=3.0)

    def test_large_translucent_tractograms_take_one_pass(self):
        """Above 4M translucent streamline points a layer would cost a
        draw of all of them: one pass in drawing order instead."""
        objects = [{"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 70000}, "opacity": 0.5},
                   {"type": "surface", "builtin": "sphere", "opacity": 0.5}]
        _, info = self.render(objects)
        self.assertGreater(info["points_total"], 4_000_000)
        self.assertEqual(info["passes"]["transparency"]["layers"], 1)
        _, info = self.render(objects[1:])
        self.assertEqual(info["passes"]["transparency"]["layers"], 2)
