"""Timelines (a scene file's "timeline", the paper's scripted animations):
keyframes of the camera, of objects' visibility, opacity, material
parameters and slice positions, of a volume's window. `render --time T` draws the instant T, which equals the
same scene written without a timeline at the values the documented rule
gives (computed here: linear spans, the camera's offset on the great
circle); `movie` plays it, each frame the instant k / fps. Keyframes out of
order, unknown objects or parameters and times past the end are each one
line naming the scene file, nothing written."""
import copy
import json
import os
import unittest

import numpy as np
from PIL import Image

from hztest import HORIZON, TempDirTest, run, xvfb_run

NO_DISPLAY = {"DISPLAY": ""}
SIZE = "200x150"


def load(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def slerp(p, q, s):
    p, q = p / np.linalg.norm(p), q / np.linalg.norm(q)
    angle = np.arccos(np.clip(p @ q, -1, 1))
    if angle < 1e-9:
        return p
    perp = q - np.cos(angle) * p
    perp /= np.linalg.norm(perp)
    return np.cos(s * angle) * p + np.sin(s * angle) * perp


class TimelineTest(TempDirTest):
    EYE0, TARGET0 = np.array([0.0, -260.0, 40.0]), np.array([0.0, 0.0, 10.0])
    EYE1, TARGET1 = np.array([300.0, 0.0, 0.0]), np.array([10.0, -10.0, 0.0])

    def base(self):
        return {
            "objects": [
                {"type": "surface", "builtin": "sphere", "name": "ball",
                 "material": {"shader": "principled", "params": {"roughness": 0.2, "metallic": 0.0}}},
                {"type": "slices", "builtin": "head", "name": "head", "x": None, "y": None, "z": 0, "window": [0, 1200]},
            ],
            "camera": {"position": list(self.EYE0), "target": list(self.TARGET0), "up": [0, 0, 1]},
        }

    def timeline(self):
        s = self.base()
        s["timeline"] = {"duration": 4, "easing": "linear", "keyframes": [
            {"time": 2, "camera": {"position": list(self.EYE1), "target": list(self.TARGET1), "up": [0, 0, 1]},
             "objects": {"ball": {"params": {"roughness": 0.8, "metallic": 1.0}, "opacity": 0.5},
                         "head": {"z": 40, "window": [200, 800]}}},
            {"time": 3, "objects": {"ball": {"visible": False}}},
        ]}
        return s

    def render(self, name, scene, *args):
        with open(self.path(name + ".json"), "w") as f:
            json.dump(scene, f)
        p = run("render", self.path(name + ".json"), "-o", self.path(name + ".png"), "--size", SIZE, "--no-aa", *args, env=NO_DISPLAY,
                timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return load(self.path(name + ".png"))

    def still(self, name, s, eye, target, up=(0, 0, 1)):
        """The scene without a timeline, at roughness/metallic/opacity/z/window `s`, seen from eye."""
        scene = self.base()
        scene["objects"][0]["material"]["params"] = {"roughness": 0.2 + s * 0.6, "metallic": s}
        scene["objects"][0]["opacity"] = 1 - 0.5 * s
        scene["objects"][1]["z"] = 40 * s
        scene["objects"][1]["window"] = [200 * s, 1200 - 400 * s]
        scene["camera"] = {"position": list(eye), "target": list(target), "up": list(up)}
        return self.render(name, scene)

    def camera_at(self, s):
        target = self.TARGET0 + s * (self.TARGET1 - self.TARGET0)
        d0, d1 = self.EYE0 - self.TARGET0, self.EYE1 - self.TARGET1
        length = np.linalg.norm(d0) + s * (np.linalg.norm(d1) - np.linalg.norm(d0))
        direction = slerp(d0, d1, s)
        up = np.array([0.0, 0.0, 1.0])
        up = up - (up @ direction) * direction
        return target + length * direction, target, up / np.linalg.norm(up)

    def assert_same(self, got, want, what):
        self.assertLess(np.abs(got - want).mean(), 0.25, what)
        self.assertLess((np.abs(got - want).max(axis=-1) > 8).mean(), 0.002, what)

    def test_instants_are_the_rule(self):
        """--time T: the keyframe's values at its time, the linear mix half-way,
        the camera turned half-way on the great circle; visibility a step."""
        tl = self.timeline()
        for t in (0.0, 1.0, 2.0, 2.5):
            with self.subTest(t=t):
                s = min(t / 2, 1.0)
                eye, target, up = self.camera_at(s)
                got = self.render(f"t{t}", tl, "--time", str(t))
                want = self.still(f"s{t}", s, eye, target, up)
                self.assert_same(got, want, f"t = {t}")
        # The ball hidden from 3 s: only the slice is left.
        hidden = self.render("t3", tl, "--time", "3")
        scene = self.base()
        scene["objects"][0]["visible"] = False
        scene["objects"][1]["z"] = 40
        scene["objects"][1]["window"] = [200, 800]
        scene["camera"] = {"position": list(self.EYE1), "target": list(self.TARGET1), "up": [0, 0, 1]}
        self.assert_same(hidden, self.render("s3", scene), "t = 3")
        self.assertGreater(np.abs(hidden - self.render("t29", tl, "--time", "2.9")).mean(), 1.0)
        # Smooth easing (the default): a quarter of the way in time is smoothstep(0.25) of the values.
        smooth = copy.deepcopy(tl)
        del smooth["timeline"]["easing"]
        s = 0.25 * 0.25 * (3 - 2 * 0.25)
        eye, target, up = self.camera_at(s)
        self.assert_same(self.render("e", smooth, "--time", "0.5"), self.still("se", s, eye, target, up), "smooth")

    def test_movie_plays_the_timeline(self):
        """Frame k of a movie is the instant k / fps; the length is the
        timeline's unless --seconds says; no turntable unless asked."""
        with open(self.path("m.json"), "w") as f:
            json.dump(self.timeline(), f)
        os.mkdir(self.path("f"))
        p = run("movie", self.path("m.json"), "-o", self.path("f/%02d.png"), "--size", SIZE, "--fps", "2", "--no-aa", "--json",
                env=NO_DISPLAY, timeout=300)
        self.assertEqual(p.returncode, 0, p.stderr)
        j = json.loads(p.stdout)
        self.assertEqual((j["frames"], j["degrees"], j["timeline"]), (8, 0, True))
        self.assertEqual(len(os.listdir(self.path("f"))), 8)
        for k in (1, 5):
            want = self.render(f"r{k}", self.timeline(), "--time", str(k / 2))
            self.assert_same(load(self.path(f"f/{k:02d}.png")), want, f"frame {k}")

    def test_the_window_goes_to_an_instant(self):
        """The window's `time T` (its Timeline slider): the instant's objects
        and camera, as `render --time T` draws them; the ball hidden from 3 s."""
        with open(self.path("w.json"), "w") as f:
            json.dump(self.timeline(), f)
        with open(self.path("s.txt"), "w") as f:
            f.write(f"time 1\nscreenshot {self.path('a.png')}\ntime 3.5\nscreenshot {self.path('b.png')}\nquit\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.path("w.json"), "--size", SIZE, "--script", self.path("s.txt")], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        a, b = load(self.path("a.png")), load(self.path("b.png"))
        for got, t in ((a, "1"), (b, "3.5")):
            with self.subTest(t=t):
                want = self.render("r" + t, self.timeline(), "--time", t)
                others = self.render("o" + t, self.timeline(), "--time", "3.5" if t == "1" else "1")
                self.assertLess(np.abs(got - want).mean(), 0.3 * np.abs(got - others).mean())

    def test_bad_timelines(self):
        def with_timeline(**changes):
            s = self.timeline()
            s["timeline"].update(changes)
            return s

        keys = self.timeline()["timeline"]["keyframes"]
        cases = {
            "order": (with_timeline(keyframes=[keys[1], keys[0]]), "timeline.keyframes[1].time: 2.000000 s is not after the previous"),
            "same": (with_timeline(keyframes=[keys[0], dict(keys[1], time=2)]), "is not after the previous keyframe's"),
            "negative": (with_timeline(keyframes=[dict(keys[0], time=-1)]), "timeline.keyframes[0].time"),
            "object": (with_timeline(keyframes=[{"time": 1, "objects": {"bal": {"visible": True}}}]), "no object named 'bal'"),
            "param": (with_timeline(keyframes=[{"time": 1, "objects": {"ball": {"params": {"rough": 1}}}}]), "rough"),
            "volume": (with_timeline(keyframes=[{"time": 1, "objects": {"head": {"params": {"roughness": 1}}}}]), "it has no material"),
            "slices": (with_timeline(keyframes=[{"time": 1, "objects": {"ball": {"z": 1}}}]), "'ball' has no slices"),
            "opacity": (with_timeline(keyframes=[{"time": 1, "objects": {"ball": {"opacity": 1.5}}}]), "objects.ball.opacity"),
            "window": (with_timeline(keyframes=[{"time": 1, "objects": {"ball": {"window": [0, 1]}}}]), "'ball' has no intensity window"),
            "range": (with_timeline(keyframes=[{"time": 1, "objects": {"head": {"window": [5, 1]}}}]), "with high > low"),
            "duration": (with_timeline(duration=1), "timeline.duration: 1.000000 s ends before the last keyframe"),
            "empty": (with_timeline(keyframes=[]), "timeline.keyframes: expected a non-empty array"),
            "key": (with_timeline(speed=2), "unknown key 'speed'"),
            "easing": (with_timeline(easing="bounce"), "timeline.easing"),
        }
        self.assert_scene_errors(cases)
        with open(self.path("t.json"), "w") as f:
            json.dump(self.timeline(), f)
        p = run("render", self.path("t.json"), "--time", "5", "-o", self.path("x.png"), env=NO_DISPLAY)
        self.assert_clean_error(p, "t.json")
        self.assertIn("timeline lasts 4", p.stderr)
        with open(self.path("n.json"), "w") as f:
            json.dump(self.base(), f)
        p = run("render", self.path("n.json"), "--time", "1", "-o", self.path("x.png"), env=NO_DISPLAY)
        self.assert_clean_error(p, "n.json")
        self.assertIn("has no timeline", p.stderr)
        self.assertFalse(os.path.exists(self.path("x.png")))


if __name__ == "__main__":
    unittest.main()
