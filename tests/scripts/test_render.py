"""The renderer through its real entry points: `horizon render` (headless
EGL, no X server), `horizon shader-check` (GPU equals CPU), `horizon view`
(the window, under Xvfb, with scripted input) and `horizon demo`."""
import json
import os
import subprocess
import re
import shutil
import unittest

import numpy as np
from PIL import Image

from hztest import HORIZON, SOURCE, TempDirTest, run, run_json, tck_bytes, xvfb_run

GOLDEN = os.path.join(SOURCE, "tests", "golden")
NO_DISPLAY = {"DISPLAY": ""}


def load(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def read_rgbe(path):
    """A Radiance .hdr picture (RGBE; flat or run-length scanlines), as
    float RGB rows top to bottom: an independent reader (the format of
    Greg Ward's Graphics Gems II chapter, as OpenImageIO writes it)."""
    with open(path, "rb") as f:
        data = f.read()
    pos = 0
    first = True
    while True:
        nl = data.index(b"\n", pos)
        line, pos = data[pos:nl], nl + 1
        if first:
            assert line.startswith(b"#?"), line
            first = False
        if line == b"":
            break
    nl = data.index(b"\n", pos)
    res, pos = data[pos:nl].split(), nl + 1
    assert res[0] == b"-Y" and res[2] == b"+X", res
    h, w = int(res[1]), int(res[3])
    px = np.zeros((h, w, 4), np.uint8)
    for y in range(h):
        if 8 <= w < 32768 and data[pos] == 2 and data[pos + 1] == 2 and (data[pos + 2] << 8 | data[pos + 3]) == w:
            pos += 4
            for c in range(4):
                x = 0
                while x < w:
                    n = data[pos]
                    pos += 1
                    if n > 128:
                        px[y, x:x + n - 128, c] = data[pos]
                        pos += 1
                        x += n - 128
                    else:
                        px[y, x:x + n, c] = np.frombuffer(data[pos:pos + n], np.uint8)
                        pos += n
                        x += n
        else:
            px[y] = np.frombuffer(data[pos:pos + 4 * w], np.uint8).reshape(w, 4)
            pos += 4 * w
    e = px[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    return px[..., :3] * scale[..., None]


def write_rgbe(path, rgb):
    """Float RGB (rows top to bottom) as a flat Radiance .hdr file."""
    h, w, _ = rgb.shape
    m = rgb.max(axis=2)
    e = np.where(m > 1e-32, np.floor(np.log2(np.maximum(m, 1e-32))) + 1, 0).astype(np.int32)
    scale = np.where(m > 1e-32, np.ldexp(1.0, 8 - e), 0.0)
    out = np.zeros((h, w, 4), np.uint8)
    out[..., :3] = np.clip(rgb * scale[..., None], 0, 255).astype(np.uint8)
    out[..., 3] = np.where(m > 1e-32, e + 128, 0)
    with open(path, "wb") as f:
        f.write(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {h} +X {w}\n".encode() + out.tobytes())


def aces_display(v):
    """The default tone curve (Narkowicz's ACES fit) and sRGB encoding, in 0..255."""
    t = np.clip((v * (2.51 * v + 0.03)) / (v * (2.43 * v + 0.59) + 0.14), 0, 1)
    return 255 * np.where(t <= 0.0031308, t * 12.92, 1.055 * np.power(t, 1 / 2.4) - 0.055)


def golden_scenes():
    """Small deterministic scenes whose pictures are stored in tests/golden."""
    return {
        "tubes_principled": {
            "objects": [{"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 300, "bundles": 6, "seed": 3},
                         "render": "tubes", "radius": 0.8, "material": {"shader": "principled", "params": {"roughness": 0.3, "clearcoat": 1}}}],
            "camera": {"view": "superior"}},
        "surface_slices_glass": {
            "objects": [{"type": "slices", "builtin": "head", "z": -10, "clip_below": 1},
                        {"type": "surface", "builtin": "cortex", "color": [0.9, 0.95, 1.0],
                         "material": {"shader": "glass", "params": {"thickness": 3, "ior": 1.45}}}],
            "camera": {"view": "left", "zoom": 1.1}, "environment": {"type": "studio", "visible": True}},
        "lines_stalling": {
            "objects": [{"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 400, "bundles": 5, "seed": 9},
                         "render": "lines", "material": "line_stalling"}],
            "camera": {"view": "anterior"}, "environment": {"type": "none"}},
    }


def render_scene(test, scene, name, *extra, size="200x150"):
    path = test.path(name + ".json")
    with open(path, "w") as f:
        json.dump(scene, f)
    out = test.path(name + ".png")
    p = run("render", path, "-o", out, "--size", size, "--json", *extra, env=NO_DISPLAY, timeout=120)
    test.assertEqual(p.returncode, 0, p.stderr)
    return out, json.loads(p.stdout)


class RenderTest(TempDirTest):
    def test_background_and_tract_colour_flags(self):
        """--background shows exactly the colour asked (whatever the tone
        curve and exposure: the radiance they map to it); --tract-colour
        colours every tractogram (a colour, one each at random, or back to
        direction); a bad colour is one line before any work."""
        lines = [np.array([[x, y, z] for x in np.linspace(-30, 30, 40)], np.float32) for y in (-6, 0, 6) for z in (-4, 4)]
        for name, shift in (("a.tck", 0), ("b.tck", 40)):
            with open(self.path(name), "wb") as f:
                f.write(tck_bytes([l + [0, shift, 0] for l in lines]))
        for bg, want in (("white", (255, 255, 255)), ("grey", (128, 128, 128)), ("0.2,0.4,0.6", (51, 102, 153))):
            for tonemap, exposure in (("aces", 1.0), ("reinhard", 2.0), ("none", 0.5)):
                with self.subTest(bg=bg, tonemap=tonemap):
                    out, _ = render_scene(self, {"objects": [{"type": "streamlines", "file": self.path("a.tck")}], "tonemap": tonemap,
                                                 "exposure": exposure}, f"bg_{tonemap}_{bg}", "--background", bg)
                    np.testing.assert_allclose(load(out)[0, 0], want, atol=1)
        red, _ = render_scene(self, {"objects": [{"type": "streamlines", "file": self.path("a.tck"), "render": "tubes", "radius": 1}]},
                              "red", "--tract-colour", "1,0,0", "--background", "black")
        px = load(red).reshape(-1, 3)
        px = px[px.sum(1) > 60]
        self.assertGreater(len(px), 100)
        # (lit red tubes: their highlights go towards white, the rest is red)
        self.assertGreater(float((px[:, 0] > 2 * px[:, 1] + 10).mean()), 0.7, "red, as asked")
        scene = {"objects": [{"type": "streamlines", "file": self.path(n), "render": "tubes", "radius": 1, "color": [0.5, 0.5, 0.5]}
                             for n in ("a.tck", "b.tck")], "camera": {"view": "superior"}}
        two, _ = render_scene(self, scene, "random", "--tract-colour", "random", "--background", "black", size="320x240")
        im = load(two)
        hue = lambda part: tuple(np.round(part[part.sum(1) > 60].mean(0) / max(part[part.sum(1) > 60].mean(0).max(), 1), 1))
        top, bottom = im[:120].reshape(-1, 3), im[120:].reshape(-1, 3)  # (b.tck lies 40 mm anterior: the top half, seen from above)
        self.assertNotEqual(hue(top), hue(bottom), "one colour per tractogram")
        grey, _ = render_scene(self, scene, "grey", "--background", "black", size="320x240")
        g = load(grey).reshape(-1, 3)
        g = g[g.sum(1) > 60]
        self.assertLess(float(np.abs(g[:, 0] - g[:, 2]).mean()), 3, "the scene's grey without the flag")
        for flag, value in (("--background", "nope"), ("--background", "1,1"), ("--tract-colour", "2,0,0"), ("--tract-colour", "rainbow")):
            with self.subTest(flag=flag, value=value):
                p = run("render", self.path("a.tck"), flag, value, "-o", self.path("bad.png"), env=NO_DISPLAY)
                self.assertNotEqual(p.returncode, 0)
                self.assertIn(f"{flag}: '{value}' is not a colour", p.stderr)
                self.assertFalse(os.path.exists(self.path("bad.png")))

    def test_non_pbr_models_show_their_colours_without_the_tone_curve(self):
        """A model that asks to be shown as it is (hz_shader.display, ABI
        1.12: the bundled flat and Blinn-Phong) is not washed out by the
        scene's default ACES curve: flat shading of colour (0.8, 0.3, 0.2) is
        that colour's sRGB encoding on screen, through the display path and
        through the HDR path (a translucent object); a physically based model
        (Lambert) still goes through the curve."""
        want = [round(255 * (1.055 * c ** (1 / 2.4) - 0.055)) for c in (0.8, 0.3, 0.2)]  # (231, 149, 124)

        def median(shader, opacity=1.0, tonemap=None):
            scene = {"objects": [{"type": "surface", "builtin": "cortex", "color": [0.8, 0.3, 0.2], "opacity": opacity,
                                  "material": {"shader": shader}}], "background": [0, 0, 0], "camera": {"view": "left"}}
            if tonemap:
                scene["tonemap"] = tonemap
            out, _ = render_scene(self, scene, f"{shader}_{opacity}_{tonemap}", "--no-aa", size="160x120")
            im = load(out).reshape(-1, 3)
            return np.median(im[im.sum(1) > 30], axis=0)

        np.testing.assert_allclose(median("flat"), want, atol=1)
        np.testing.assert_allclose(median("flat", opacity=0.999), want, atol=2)
        lambert = median("lambert"), median("lambert", tonemap="none")
        self.assertGreater(float(np.abs(lambert[0] - lambert[1]).max()), 10, lambert)
        blinn = median("blinn_phong"), median("blinn_phong", tonemap="none")
        np.testing.assert_allclose(blinn[0], blinn[1], atol=1)

    def test_headless_render_of_builtin_scene(self):
        scene = {"objects": [
            {"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 500}, "render": "tubes"},
            {"type": "surface", "builtin": "cortex"},
            {"type": "slices", "builtin": "head"}]}
        out, stats = render_scene(self, scene, "s", size="320x200")
        im = load(out)
        self.assertEqual(im.shape, (200, 320, 3))
        bg = im[0, 0]
        covered = np.mean(np.any(np.abs(im - bg) > 10, axis=2))
        self.assertGreater(covered, 0.15, "the scene should fill a good part of the frame")
        self.assertIn("OpenGL", stats["gl"])
        self.assertGreater(stats["triangles"], 1000)
        self.assertGreater(stats["segments"], 1000)

    def test_a_bad_size_is_refused_before_anything_is_read(self):
        # One line about --size (not about the data, which are not even read:
        # a file that does not exist is not the error), for each command.
        for cmd in (["render", self.path("absent.tck"), "-o", self.path("x.png")], ["view", self.path("absent.tck")],
                    ["demo", "--out", self.path("d"), "--no-window"]):
            for size in ("100x", "8x8", "20000x100", "640x400x2"):
                with self.subTest(cmd=cmd[0], size=size):
                    p = run(*cmd, "--size", size, env=NO_DISPLAY)
                    self.assertNotEqual(p.returncode, 0)
                    self.assertEqual(p.stderr.splitlines()[0],
                                     f"--size: expected WIDTHxHEIGHT between 16x16 and 16384x16384, not '{size}'")
        self.assertFalse(os.path.exists(self.path("d")))

    def test_a_gpu_that_is_not_there_is_refused_before_reading(self):
        # HORIZON_GPU=N picks the N-th GPU EGL device (from 0) and nothing
        # else: one that is not there (no machine's EGL lists 99; this one's
        # may list none) or a malformed number is one line about it, before
        # the input is read (here a broken file, which is not the error).
        bad = self.path("broken.tck")
        with open(bad, "wb") as f:
            f.write(b"mrtrix tracks\nfile: . 99999\nEND\n")
        out = self.path("x.png")
        for value, error in (("99", r"HORIZON_GPU=99: no such GPU \(this machine's EGL has \d+ GPU devices?\)"),
                             ("first", r"HORIZON_GPU='first' is not a GPU's number \(0 for the first\)")):
            with self.subTest(value=value):
                p = run("render", bad, "-o", out, env={**NO_DISPLAY, "HORIZON_GPU": value})
                self.assertEqual(p.returncode, 1, p.stderr)
                self.assertRegex(p.stderr.strip(), "^horizon: error: " + error + "$")
                self.assertFalse(os.path.exists(out))
        # Unset or empty: as before (llvmpipe here), and the broken file is the error.
        p = run("render", bad, "-o", out, env={**NO_DISPLAY, "HORIZON_GPU": ""})
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn(f"{bad}: data offset 99999 is past the end of the file", p.stderr)

    def test_an_output_in_a_missing_directory_is_refused_before_reading(self):
        # Named with its directory, before the input is read (here it does
        # not even exist: that is not the error reported).
        out = self.path("nodir/x")
        for cmd in (["render", self.path("absent.tck"), "-o", out + ".png"], ["convert", self.path("absent.tck"), out + ".trx"],
                    ["filter", self.path("absent.tck"), "--include", "sphere:0,0,0,5", "-o", out + ".tck"]):
            with self.subTest(cmd=cmd[0]):
                p = run(*cmd, env=NO_DISPLAY)
                self.assertEqual(p.returncode, 1, p.stderr)
                self.assertEqual(p.stderr.strip(), f"horizon: error: {cmd[-1]}: directory {self.path('nodir')} does not exist")

    def test_shading_model_changes_the_picture(self):
        base = {"objects": [{"type": "surface", "builtin": "cortex", "material": {"shader": "principled"}}], "camera": {"view": "right"}}
        a, _ = render_scene(self, base, "a")
        base["objects"][0]["material"] = {"shader": "blinn_phong", "params": {"shininess": 64}}
        b, _ = render_scene(self, base, "b")
        base["objects"][0]["material"] = "flat"
        c, _ = render_scene(self, base, "c")
        ia, ib, ic = load(a), load(b), load(c)
        self.assertGreater(np.mean(np.abs(ia - ib)), 1.0)
        # Flat shading: one colour over the whole surface (up to edge antialiasing).
        surf = np.any(np.abs(ic - ic[0, 0]) > 10, axis=2)
        colours = ic[surf]
        near = np.all(np.abs(colours - np.median(colours, axis=0)) <= 2, axis=1)
        self.assertGreater(near.mean(), 0.9, "flat: all but the edge pixels have the surface's one colour")
        self.assertLess(np.median(np.abs(colours - np.median(colours, axis=0))), 1.0)

    def test_data_colouring_and_cluster_tubes(self):
        scene = {"objects": [{"type": "surface", "builtin": "cortex", "color": {"mode": "data", "array": "sulc", "colormap": "coolwarm"}},
                             {"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 800},
                              "clustering": {"algorithm": "qbx", "level": 1}, "color": "cluster"}]}
        out, stats = render_scene(self, scene, "d")
        im = load(out)
        self.assertGreater(len(np.unique(im.reshape(-1, 3), axis=0)), 500)

    def test_an_explicit_base_color_is_the_colour(self):
        """The object's colouring drives the shader's colour parameter only
        when the material leaves it out: an explicit base_color wins (it was
        silently ignored), on a surface and on streamlines coloured by
        direction alike."""
        shots = iter(range(100))

        def centre(obj, params):
            scene = {"objects": [{**obj, "material": {"shader": "principled", "params": params}}], "camera": {"view": "anterior"}}
            im = load(render_scene(self, scene, f"bc{next(shots)}")[0])
            fg = np.any(np.abs(im - im[0, 0]) > 12, axis=2)
            return im[fg].mean(axis=0)
        for obj in ({"type": "surface", "builtin": "sphere"},
                    {"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 200}, "color": "direction", "render": "tubes"}):
            plain = centre(obj, {"roughness": 0.5})
            red = centre(obj, {"roughness": 0.5, "base_color": [0.9, 0.02, 0.02]})
            self.assertGreater(red[0], 3 * red[1], (obj["type"], red))
            self.assertGreater(red[0], 3 * red[2], (obj["type"], red))
            self.assertLess(plain[0], 3 * plain[1] + 10, (obj["type"], plain))

    def test_linear_pictures_exr_and_hdr(self):
        """`render -o x.hdr` / `x.exr` write the linear radiance before the
        tone curve (float), not the display picture: read back with an
        independent RGBE reader and put through the tone curve, the .hdr is
        the .png of the same frame within RGBE's precision. The .exr holds
        the same frame (OpenEXR magic, float RGB of the size asked)."""
        scene = {"objects": [{"type": "surface", "builtin": "sphere", "material": {"shader": "principled", "params": {"roughness": 0.4}}}],
                 "camera": {"view": "anterior"}}
        # (the edge anti-aliasing pass smooths display pictures only)
        png, _ = render_scene(self, scene, "lin", "--samples", "1", "--no-aa")
        hdr, j = render_scene(self, scene, "lin_hdr", "--samples", "1", "--frames", "3")
        # (render_scene names its output .png: write the .hdr and .exr by hand)
        path = self.path("lin.json")
        p = run("render", path, "-o", self.path("lin.hdr"), "--size", "200x150", "--samples", "1", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("linear radiance", p.stdout)
        radiance = read_rgbe(self.path("lin.hdr"))
        shown = load(png)
        self.assertEqual(radiance.shape, shown.shape)
        self.assertGreater(radiance.max(), 0.2)
        fg = np.any(np.abs(shown - shown[0, 0]) > 12, axis=2)
        self.assertGreater(fg.mean(), 0.1)
        diff = np.abs(aces_display(radiance) - shown)
        self.assertLess(np.percentile(diff[fg], 99), 1.5)  # (observed 0.8; RGBE keeps 8 bits of mantissa)
        self.assertLess(diff.max(), 2.5)
        self.assertLess(diff.mean(), 0.6)
        p = run("render", path, "-o", self.path("lin.exr"), "--size", "200x150", "--samples", "1", "--json", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertTrue(json.loads(p.stdout)["hdr"])
        with open(self.path("lin.exr"), "rb") as f:
            self.assertEqual(f.read(4), bytes([0x76, 0x2F, 0x31, 0x01]))
        info = run_json("info", self.path("lin.exr"), "--json")
        self.assertIn("200", json.dumps(info))
        # --frames: the frames drawn and their median time.
        self.assertEqual(j["frames"], 3)
        self.assertGreater(j["frame_ms"], 0)
        self.assertLessEqual(j["frame_ms_min"], j["frame_ms"])
        # What a linear picture cannot hold is refused before any work.
        for extra, words in ((["--preview"], "--preview"), (["--legend"], "--legend")):
            p = run("render", path, "-o", self.path("no.exr"), *extra, env=NO_DISPLAY, timeout=60)
            self.assert_clean_error(p, ".exr")
            self.assertIn(words, p.stderr)
            self.assertFalse(os.path.exists(self.path("no.exr")))

    def test_environment_maps_from_hdr_and_exr(self):
        # A Radiance .hdr sky (bright blue above, dim orange below), written
        # here, lights a metal sphere: blue above; an .exr map (a linear
        # render of that lit sphere) is read as well and changes the picture.
        env = np.zeros((32, 64, 3))
        env[:16] = (0.3, 0.6, 4.0)
        env[16:] = (1.5, 0.6, 0.2)
        write_rgbe(self.path("sky.hdr"), env)
        scene = {"objects": [{"type": "surface", "builtin": "sphere", "material": {"shader": "principled", "params": {"metallic": 1, "roughness": 0.1}}}],
                 "environment": {"path": "sky.hdr", "intensity": 1.0}, "lights": [], "camera": {"view": "anterior"}}
        a, _ = render_scene(self, scene, "env_hdr")
        ia = load(a)
        surf = np.any(np.abs(ia - ia[0, 0]) > 10, axis=2)
        top = ia[:60][surf[:60]]
        self.assertGreater(top[:, 2].mean(), top[:, 0].mean() + 20, "the metal reflects the blue sky above")
        path = self.path("env_hdr.json")
        p = run("render", path, "-o", self.path("sky.exr"), "--size", "128x64", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        scene["environment"] = {"path": "sky.exr", "intensity": 1.0}
        b, _ = render_scene(self, scene, "env_exr")
        self.assertGreater(np.mean(np.abs(load(b) - ia)), 2.0)

    def test_environment_from_an_image_file(self):
        # An equirectangular PNG: blue sky above, orange ground below.
        env = np.zeros((64, 128, 3), np.uint8)
        env[:32] = (60, 120, 255)
        env[32:] = (255, 120, 40)
        Image.fromarray(env).save(self.path("env.png"))
        scene = {"objects": [{"type": "surface", "builtin": "cortex", "material": {"shader": "principled", "params": {"metallic": 1, "roughness": 0.1}}}],
                 "environment": {"path": "env.png", "intensity": 1.0}, "lights": [], "camera": {"view": "anterior"}}
        a, _ = render_scene(self, scene, "env_file")
        scene["environment"] = {"type": "studio"}
        b, _ = render_scene(self, scene, "env_studio")
        ia = load(a)
        self.assertGreater(np.mean(np.abs(ia - load(b))), 2.0)
        surf = np.any(np.abs(ia - ia[0, 0]) > 10, axis=2)
        top, bottom = ia[:75][surf[:75]], ia[75:][surf[75:]]
        self.assertGreater(top[:, 2].mean(), top[:, 0].mean(), "the metal reflects the blue sky above")

    def test_render_real_files(self):
        p = run("demo", "--out", self.path("demo"), "--streamlines", "300", env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertTrue(os.path.exists(self.path("demo/demo.png")))
        self.assertEqual(load(self.path("demo/demo.png")).shape, (720, 1280, 3))
        scene = {"objects": [{"type": "streamlines", "file": "demo/phantom.tck", "render": "lines"},
                             {"type": "streamlines", "file": "demo/qbx_centroids_level1.tck", "render": "tubes", "radius": 1.5,
                              "color": {"mode": "solid", "value": [1, 0.8, 0.2]}}]}
        out, stats = render_scene(self, scene, "files")
        expected = sum(run_json("info", self.path(f), "--json")["nb_vertices"] for f in ("demo/phantom.tck", "demo/qbx_centroids_level1.tck"))
        self.assertEqual(stats["points_total"], expected)
        self.assertGreater(stats["segments"], 100)

    def make_surface_with_thickness(self):
        """A FreeSurfer sphere-like surface and a thickness overlay that varies with z (nibabel writes both)."""
        import nibabel.freesurfer as fsio
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 40, endpoint=False), np.linspace(0.1, np.pi - 0.1, 20))
        verts = (np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], -1).reshape(-1, 3) * 60).astype(np.float32)
        faces = []
        for i in range(19):
            for j in range(40):
                a, b, c, d = i * 40 + j, i * 40 + (j + 1) % 40, (i + 1) * 40 + j, (i + 1) * 40 + (j + 1) % 40
                faces += [[a, c, b], [b, c, d]]
        fsio.write_geometry(self.path("lh.white"), verts, np.array(faces, np.int32))
        fsio.write_morph_data(self.path("lh.thickness"), (1.5 + verts[:, 2] / 40).astype(np.float32))
        fsio.write_morph_data(self.path("short.thickness"), np.ones(10, np.float32))

    def test_surface_overlays(self):
        """A curv overlay from its own file colours the surface it names."""
        self.make_surface_with_thickness()
        plain, _ = render_scene(self, {"objects": [{"type": "surface", "file": "lh.white"}], "camera": {"view": "left"}}, "plain")
        scene = {"objects": [{"type": "surface", "file": "lh.white", "overlays": ["lh.thickness"]}], "camera": {"view": "left"}}
        coloured, _ = render_scene(self, scene, "coloured")
        a, b = load(plain), load(coloured)
        self.assertGreater(np.mean(np.abs(a - b)), 5.0, "the overlay colours the surface")
        # viridis runs from purple to yellow: thickness grows with z, so the
        # top of the surface and its bottom get different colours.
        fg = np.abs(b - b[0, 0]).sum(axis=2) > 30
        ys = np.nonzero(fg.any(axis=1))[0]
        third = (ys[-1] - ys[0]) // 3
        top = b[ys[0]:ys[0] + third][fg[ys[0]:ys[0] + third]].mean(axis=0)
        bottom = b[ys[-1] - third:ys[-1]][fg[ys[-1] - third:ys[-1]]].mean(axis=0)
        self.assertGreater(top[1] - bottom[1], 30, f"top {top}, bottom {bottom}")
        bad = {"objects": [{"type": "surface", "file": "lh.white", "overlays": ["short.thickness"]}]}
        path = self.path("bad_overlay.json")
        with open(path, "w") as f:
            json.dump(bad, f)
        p = run("render", path, "-o", self.path("bad.png"), env=NO_DISPLAY)
        self.assert_clean_error(p, "bad_overlay.json")
        self.assertIn("short.thickness: has values for 10 vertices, the surface has 800", p.stderr)
        alone = {"objects": [{"type": "surface", "file": "lh.thickness"}]}
        with open(self.path("alone.json"), "w") as f:
            json.dump(alone, f)
        p = run("render", self.path("alone.json"), "-o", self.path("alone.png"), env=NO_DISPLAY)
        self.assert_clean_error(p, "alone.json")
        self.assertIn("per-vertex values only", p.stderr)

    def test_render_data_files_without_a_scene_file(self):
        """`horizon render FILES`: the scene `view` builds from data files, drawn headlessly."""
        p = run("demo", "--out", self.path("demo"), "--streamlines", "300", "--no-window", env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)

        def render(*args):
            out = self.path("r%d.png" % len(os.listdir(self.tmp)))
            p = run("render", *args, "-o", out, "--size", "200x150", env=NO_DISPLAY, timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            return load(out)

        # A tractogram alone draws what the equivalent scene file draws.
        tck = self.path("demo/phantom.tck")
        with open(self.path("same.json"), "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": tck, "render": "tubes", "radius": 0.3, "color": "direction"}]}, f)
        direct = render(tck)
        np.testing.assert_array_equal(direct, render(self.path("same.json")))
        self.assertGreater(direct.std(), 5.0)
        # --view fits another named view, for data files and scene files alike.
        top = render(tck, "--view", "superior")
        self.assertGreater(np.mean(np.abs(top - direct)), 0.5)
        np.testing.assert_array_equal(top, render(self.path("same.json"), "--view", "superior"))
        # A surface and its overlay file: the overlay colours the surface named before it.
        self.make_surface_with_thickness()
        plain, coloured = render(self.path("lh.white")), render(self.path("lh.white"), self.path("lh.thickness"))
        self.assertGreater(np.mean(np.abs(plain - coloured)), 5.0)
        # Bad input: one line naming the file, no picture.
        for args, name, why in [((self.path("lh.thickness"),), "lh.thickness", "need their surface"),
                                ((self.path("missing.tck"),), "missing.tck", "no such file")]:
            out = self.path("bad.png")
            p = run("render", *args, "-o", out, env=NO_DISPLAY)
            self.assert_clean_error(p, name)
            self.assertIn(why, p.stderr)
            self.assertFalse(os.path.exists(out))
        p = run("render", tck, "--view", "sideways", "-o", self.path("bad.png"), env=NO_DISPLAY)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("sideways", p.stderr)

    def test_surface_annotation_colours(self):
        """An annotation (lh.aparc.annot) colours the surface by its labels' colours: the upper half red, the lower
        half blue, unlabeled vertices the surface's own grey."""
        import nibabel.freesurfer as fsio
        self.make_surface_with_thickness()
        verts, _ = fsio.read_geometry(self.path("lh.white"))
        labels = np.where(verts[:, 2] > 0, 1, 2).astype(np.int32)
        ctab = np.array([[25, 5, 25, 0, 0], [255, 0, 0, 0, 0], [0, 0, 255, 0, 0]], np.int32)
        fsio.write_annot(self.path("lh.aparc.annot"), labels, ctab, [b"unknown", b"upper", b"lower"])
        scene = {"objects": [{"type": "surface", "file": "lh.white", "overlays": ["lh.aparc.annot"],
                              "material": {"shader": "flat"}}], "camera": {"view": "left"}}
        out, _ = render_scene(self, scene, "annot")
        b = load(out)
        fg = np.abs(b - b[0, 0]).sum(axis=2) > 30
        ys = np.nonzero(fg.any(axis=1))[0]
        third = (ys[-1] - ys[0]) // 3
        top = b[ys[0]:ys[0] + third][fg[ys[0]:ys[0] + third]].mean(axis=0)
        bottom = b[ys[-1] - third:ys[-1]][fg[ys[-1] - third:ys[-1]]].mean(axis=0)
        self.assertGreater(top[0], 200, f"top {top}")
        self.assertLess(top[2], 40, f"top {top}")
        self.assertGreater(bottom[2], 200, f"bottom {bottom}")
        self.assertLess(bottom[0], 40, f"bottom {bottom}")

    def test_decimation_keeps_the_picture(self):
        scene = {"objects": [{"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 2000}, "render": "lines"}]}
        full, s0 = render_scene(self, scene, "full", "--lod-pixels", "0", size="400x300")
        lod, s1 = render_scene(self, scene, "lod", "--lod-pixels", "0.5", size="400x300")
        self.assertLess(s1["points_kept"], 0.6 * s0["points_kept"])
        # Sub-pixel shifts of 1-pixel lines: compare 4x4 block means.
        blocks = lambda im: im.reshape(75, 4, 100, 4, 3).mean(axis=(1, 3))
        diff = np.abs(blocks(load(full)) - blocks(load(lod)))
        self.assertLess(np.mean(diff), 2.0)

    def test_unaligned_tck_renders_as_its_aligned_copy(self):
        """A TCK as nibabel writes it (data at byte 67: mapped, its floats copied to
        aligned memory when the renderer first reads them) draws the same picture as
        the same streamlines in Horizon's aligned layout."""
        import nibabel as nib
        rng = np.random.default_rng(5)
        sl = [(np.cumsum(rng.normal(size=(int(rng.integers(2, 40)), 3)), 0) * 3).astype(np.float32) for _ in range(300)]
        nib_tck, ours = self.path("nib.tck"), self.path("ours.tck")
        nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), nib_tck)
        self.assertTrue(run_json("info", nib_tck, "--json")["positions_copied_on_use"])
        self.assertEqual(run("convert", nib_tck, ours).returncode, 0)
        self.assertFalse(run_json("info", ours, "--json")["positions_copied_on_use"])
        pictures = []
        for f in (nib_tck, ours):
            scene = {"objects": [{"type": "streamlines", "file": f, "render": "tubes"}]}
            pictures.append(load(render_scene(self, scene, os.path.basename(f))[0]))
        self.assertGreater(pictures[0].std(), 1.0)  # (something was drawn)
        np.testing.assert_array_equal(pictures[0], pictures[1])

    def test_bad_scenes_fail_cleanly(self):
        cases = {
            "syntax.json": ("{ not json", "not valid JSON"),
            "unknown_key.json": ({"objects": [{"type": "surface", "builtin": "cortex", "colour": [1, 0, 0]}]}, "unknown key 'colour'"),
            "bad_shader.json": ({"objects": [{"type": "surface", "builtin": "cortex", "material": "nonesuch"}]}, "no shading plugin 'nonesuch'"),
            "bad_param.json": ({"objects": [{"type": "surface", "builtin": "cortex", "material": {"shader": "principled", "params": {"shine": 1}}}]},
                               "has no parameter 'shine'"),
            "missing.json": ({"objects": [{"type": "streamlines", "file": "missing.tck"}]}, "missing.tck"),
            "kind.json": ({"objects": [{"type": "surface", "builtin": "phantom"}]}, "builtin 'phantom' is a tractogram"),
            "line_model.json": ({"objects": [{"type": "surface", "builtin": "cortex", "material": "line_stalling"}]}, "cannot shade surfaces"),
        }
        for name, (content, needle) in cases.items():
            path = self.path(name)
            with open(path, "w") as f:
                f.write(content if isinstance(content, str) else json.dumps(content))
            out = self.path(name + ".png")
            p = run("render", path, "-o", out, env=NO_DISPLAY)
            self.assert_clean_error(p, name)
            self.assertIn(needle, p.stderr)
            self.assertFalse(os.path.exists(out), name)

    def test_golden_images(self):
        """Small scenes against stored pictures; regenerate only with
        tests/golden/regenerate.sh after checking the new pictures."""
        for name, scene in golden_scenes().items():
            out, _ = render_scene(self, scene, name)
            ref = os.path.join(GOLDEN, name + ".png")
            self.assertTrue(os.path.exists(ref), f"missing {ref}: run tests/golden/regenerate.sh")
            a, b = load(out), load(ref)
            self.assertEqual(a.shape, b.shape, name)
            # Over the foreground only (the pixels either picture draws: a
            # mean over a mostly empty frame hides any change), with a
            # tolerance near the noise: rebuilds and driver rounding differ
            # by 0.07/255 on average there, at most 3 levels; doubling the
            # roughness of tubes_principled gives 7.1, dropping its clearcoat
            # 2.6 with 7 % of the pixels off by more than 6 levels.
            bg = b[0, 0]
            fg = (np.abs(b - bg).max(axis=2) > 3) | (np.abs(a - bg).max(axis=2) > 3)
            self.assertGreater(fg.mean(), 0.05, f"{name}: the scene draws almost nothing")
            diff = np.abs(a - b).max(axis=2)[fg]
            self.assertLess(diff.mean(), 0.6, f"{name}: mean foreground difference {diff.mean():.2f}/255")
            self.assertLess(np.mean(diff > 6), 0.005, f"{name}: {100 * np.mean(diff > 6):.1f} % of the foreground differs by more than 6/255")


class SlicerTest(TempDirTest):
    """The slicer (issue 55): a 4D series (40 x 48 x 36 voxels of 2 mm, 3
    volumes, each a different pattern) shown as slices. `--volume-index N`
    and a scene's "volume_index" show the N-th volume; one past the last is
    a one-line error. In the window, `slice`, `window` and `volume` (the
    panel's sliders do the same) give the picture `render` draws of the scene
    with those positions, window and volume."""

    def setUp(self):
        super().setUp()
        import nibabel as nib
        i, j, k = np.meshgrid(np.arange(40), np.arange(48), np.arange(36), indexing="ij")
        vols = [i * 5.0, j * 5.0, ((i // 4 + j // 4 + k // 4) % 2) * 200.0]
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-40, -48, -36]
        nib.save(nib.Nifti1Image(np.stack(vols, -1).astype(np.float32), aff), self.path("series.nii.gz"))

    def scene(self, name, **keys):
        ob = {"type": "slices", "file": "series.nii.gz", "x": None, "y": None, "z": 0, "window": [0, 240], **keys}
        with open(self.path(name), "w") as f:
            json.dump({"objects": [ob], "camera": {"view": "superior"}, "environment": {"type": "none"}}, f)
        return self.path(name)

    def render(self, scene, out, *args):
        p = run("render", scene, "-o", self.path(out), "--size", "320x240", "--force", *args, env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return load(self.path(out))

    def test_volume_index_of_a_series(self):
        first = self.render(self.scene("s.json"), "v0.png")
        flag = self.render(self.scene("s.json"), "v2f.png", "--volume-index", "2")
        key = self.render(self.scene("k.json", volume_index=2), "v2k.png")
        np.testing.assert_array_equal(flag, key)
        self.assertGreater(np.abs(first - flag).mean(), 10, "another volume, another picture")
        # Volume 0 rises along x (columns), volume 2 is a checkerboard of 8 mm.
        row = first[120, 90:230, 0]
        self.assertGreater(np.corrcoef(np.arange(len(row)), row)[0, 1], 0.95)
        self.assertGreater(len(np.unique(key[120, 90:230, 0] > 128)), 1)
        p = run("render", self.scene("s.json"), "-o", self.path("x.png"), "--volume-index", "3", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 1)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
        self.assertIn("volume_index 3, but the file holds 3 volumes (0 to 2)", p.stderr)
        self.assertFalse(os.path.exists(self.path("x.png")))

    def test_colour_volumes(self):
        """A colour map (a 4th dimension of 3 values a voxel: a colour-FA
        map) shown in colour: 8-bit values as they are (255 is full), the
        same in float 0..1 with "rgb": true or --rgb; without it a float one
        is a series (its first volume, grey). The pixel at a region's centre
        is the voxel's colour exactly (display values: no tone curve)."""
        import nibabel as nib
        rgb = np.zeros((20, 24, 10, 3), np.uint8)
        rgb[:10, :, :, 0] = 255
        rgb[10:, :12, :, 1] = 200
        rgb[10:, 12:, :, 2] = 128
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-20, -24, -10]
        nib.save(nib.Nifti1Image(rgb, aff), self.path("rgb.nii.gz"))
        nib.save(nib.Nifti1Image(rgb.astype(np.float32) / 255, aff), self.path("rgbf.nii.gz"))

        def scene(name, file, **keys):
            with open(self.path(name), "w") as f:
                json.dump({"objects": [{"type": "slices", "file": file, "x": None, "y": None, "z": 0, **keys}],
                           "camera": {"view": "superior"}, "environment": {"type": "none"}}, f)
            return self.path(name)

        byte = self.render(scene("b.json", "rgb.nii.gz"), "b.png")
        flt = self.render(scene("f.json", "rgbf.nii.gz", rgb=True), "f.png")
        flag = self.render(scene("g.json", "rgbf.nii.gz"), "g.png", "--rgb")
        grey = self.render(scene("h.json", "rgbf.nii.gz"), "h.png")
        np.testing.assert_array_equal(byte, flt)
        np.testing.assert_array_equal(flt, flag)
        # The regions' centres, from the affine: x < 0 red; x > 0: y < 0 green, y > 0 blue (superior view: y up).
        box = np.argwhere(np.abs(byte - byte[2, 2]).sum(axis=-1) > 30)
        (r0, c0), (r1, c1) = box.min(axis=0), box.max(axis=0)
        at = lambda fx, fy: byte[int(r0 + (1 - fy) * (r1 - r0)), int(c0 + fx * (c1 - c0))]
        np.testing.assert_array_equal(at(0.25, 0.5), [255, 0, 0])
        np.testing.assert_array_equal(at(0.75, 0.25), [0, 200, 0])
        np.testing.assert_array_equal(at(0.75, 0.75), [0, 0, 128])
        inside = grey[r0 + 2:r1 - 1, c0 + 2:c1 - 1].astype(float)
        self.assertLess(np.abs(inside - inside[..., :1]).max(), 1, "a float series is grey")
        nib.save(nib.Nifti1Image(np.ones((8, 8, 8), np.float32), aff), self.path("plain.nii.gz"))
        p = run("render", scene("bad.json", "plain.nii.gz", rgb=True), "-o", self.path("x.png"), env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 1)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
        self.assertIn("4th dimension must hold 3 or 4 values per voxel, not none (a 3D volume)", p.stderr)
        self.assertFalse(os.path.exists(self.path("x.png")))

    @unittest.skipUnless(shutil.which("xvfb-run") or os.environ.get("CI"), "xvfb-run is not installed")
    def test_the_window_moves_slices_window_and_volume(self):
        script = self.path("s.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", f"screenshot {self.path('w0.png')}", "slice 0 z 10", "window 0 20 120", "volume 0 1",
                               "slice 0 x -4", "wait 1", f"screenshot {self.path('w1.png')}", "slice 0 x off", "window 0 0 0",
                               "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.scene("s.json"), "--size", "320x240", "--aa-frames", "1", "--script", script], env)
        self.assertNotEqual(p.returncode, 0, "window 0 0 0 is not a range: the script stops there")
        self.assertIn("window", p.stderr)
        self.assertIn("is not a range", p.stderr)
        before = self.render(self.scene("s.json"), "r0.png", "--aa-frames", "1")
        after = self.render(self.scene("a.json", z=10, x=-4, window=[20, 120], volume_index=1), "r1.png", "--aa-frames", "1")
        w0, w1 = load(self.path("w0.png")), load(self.path("w1.png"))
        self.assertLess((np.abs(w0 - before).sum(axis=-1) > 30).mean(), 0.005)
        self.assertLess((np.abs(w1 - after).sum(axis=-1) > 30).mean(), 0.005)
        self.assertGreater(np.abs(w0 - w1).mean(), 5)

    @unittest.skipUnless(shutil.which("xvfb-run") or os.environ.get("CI"), "xvfb-run is not installed")
    def test_the_value_under_the_cursor(self):
        """`probe X Y` (the panel's readout at the cursor): the slice's point
        under a window point, its voxel (the affine's inverse, rounded, as
        nibabel computes it here) and the value there in the volume shown."""
        import re
        import nibabel as nib
        script = self.path("p.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", "probe 160 120", "probe 200 100", "volume 0 1", "probe 120 150", "probe 3 3", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.scene("s.json"), "--size", "320x240", "--script", script], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        img = nib.load(self.path("series.nii.gz"))
        data, inv = np.asarray(img.dataobj), np.linalg.inv(img.affine)
        lines = [l for l in p.stdout.splitlines() if l.startswith("probe ")]
        self.assertEqual(len(lines), 4, p.stdout)
        self.assertTrue(lines[3].endswith(": no slice"), lines[3])
        for line, vol in zip(lines[:3], (0, 0, 1)):
            m = re.search(r"voxel \((\d+), (\d+), (\d+)\) = ([-\d.e+]+) at \(([-\d.]+), ([-\d.]+), ([-\d.]+)\) mm", line)
            self.assertIsNotNone(m, line)
            ijk = [int(m.group(k)) for k in (1, 2, 3)]
            xyz = np.array([float(m.group(k)) for k in (5, 6, 7)])
            self.assertAlmostEqual(xyz[2], 0.0, places=3)  # (on the axial slice z = 0)
            want = inv[:3, :3] @ xyz + inv[:3, 3]
            self.assertTrue(np.all(np.abs(want - ijk) <= 0.5 + 0.06), f"{line}: voxel {want}")  # (the printed point has 0.1 mm)
            self.assertEqual(float(m.group(4)), float(data[ijk[0], ijk[1], ijk[2], vol]), line)

    @unittest.skipUnless(shutil.which("xvfb-run") or os.environ.get("CI"), "xvfb-run is not installed")
    def test_the_2d_view_of_a_slice(self):
        """The window's 2D view (`view2d I AXIS`, the slicer's "2D view"
        button): the plane at the object's slice, a pixel a voxel of the
        finest size over the volume's box, each the voxel nearest its centre
        through the window, neurological (right on the right; sagittal from
        the left). Computed here from nibabel's data and affine, for a
        volume whose voxel axes are permuted and flipped against the world's.
        A click on it (`click2d`) moves the other slices shown to that point;
        a word it does not know stops the script with one line."""
        import nibabel as nib
        i, j, k = np.meshgrid(np.arange(40), np.arange(48), np.arange(36), indexing="ij")
        data = (i * 5.0 + (j % 7) * 3 + (k // 3) * 2).astype(np.float32)
        aff = np.array([[0, -2.0, 0, 47], [2.0, 0, 0, -40], [0, 0, 2.0, -36], [0, 0, 0, 1]])
        nib.save(nib.Nifti1Image(data, aff), self.path("perm.nii.gz"))
        shots = {n: self.path(n + ".png") for n in ("axial", "coronal", "sagittal", "clicked")}
        script = self.path("v.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", "view2d 0 z", f"save2d {shots['axial']}", "slice 0 y 10", "view2d 0 coronal",
                               f"save2d {shots['coronal']}", "click2d 30.5 10.5", "slice 0 x 7", "view2d 0 x",
                               f"save2d {shots['sagittal']}", "view2d 0 z", f"save2d {shots['clicked']}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.scene("p.json", file="perm.nii.gz"), "--size", "320x240", "--script", script], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        inv = np.linalg.inv(aff)
        corners = np.array([[a, b, c, 1] for a in (-0.5, 39.5) for b in (-0.5, 47.5) for c in (-0.5, 35.5)]) @ aff.T
        lo, hi = corners[:, :3].min(axis=0), corners[:, :3].max(axis=0)

        def expected(axis, position):
            u, v, sign = {0: (1, 2, -1), 1: (0, 2, 1), 2: (0, 1, 1)}[axis]
            w, h = int(np.ceil((hi[u] - lo[u]) / 2 - 1e-9)), int(np.ceil((hi[v] - lo[v]) / 2 - 1e-9))
            cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
            world = np.zeros((h, w, 3))
            world[..., axis] = position
            world[..., u] = lo[u] + cols * 2 if sign > 0 else hi[u] - cols * 2
            world[..., v] = hi[v] - rows * 2
            ijk = world @ inv[:3, :3].T + inv[:3, 3]
            ijk = np.sign(ijk) * np.floor(np.abs(ijk) + 0.5)
            inside = np.all((ijk >= 0) & (ijk < np.array(data.shape)), axis=-1)
            at = np.where(inside[..., None], ijk, 0).astype(int)
            grey = np.clip(data[at[..., 0], at[..., 1], at[..., 2]] / 240.0, 0, 1) * 255
            tie = inside & (grey - np.floor(grey) == 0.5)  # (an exact half: float32's rounding may go either way)
            return np.where(inside, np.floor(grey + 0.5), 0), tie

        for name, axis, position in (("axial", 2, 0.0), ("coronal", 1, 10.0), ("sagittal", 0, 7.0), ("clicked", 2, 14.0)):
            with self.subTest(view=name):
                got = np.asarray(Image.open(shots[name]).convert("RGB"), dtype=float)
                want, tie = expected(axis, position)
                self.assertEqual(got.shape[:2], want.shape)
                self.assertTrue(np.all(got[..., 0] == got[..., 2]), "grey")
                np.testing.assert_array_equal(got[..., 0][~tie], want[~tie], name)
                self.assertLessEqual(np.abs(got[..., 0] - want)[tie].max(initial=0), 1, name)
        bad = self.path("b.txt")
        with open(bad, "w") as f:
            f.write("wait 1\nview2d 0 w\nquit\n")
        p = xvfb_run([HORIZON, "view", self.scene("p.json", file="perm.nii.gz"), "--size", "320x240", "--script", bad], env)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("view2d: 'w' is not x, y, z, sagittal, coronal or axial", p.stderr)

    @unittest.skipUnless(shutil.which("xvfb-run") or os.environ.get("CI"), "xvfb-run is not installed")
    def test_the_colour_under_the_cursor(self):
        """A colour volume's readout is its three values there (8-bit, and
        float with "rgb": true), as nibabel reads them at the voxel printed."""
        import re
        import nibabel as nib
        rng = np.random.default_rng(3)
        rgb = rng.integers(0, 256, size=(12, 10, 5, 3)).astype(np.uint8)
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-11, -9, -4]
        nib.save(nib.Nifti1Image(rgb, aff), self.path("rgb.nii.gz"))
        nib.save(nib.Nifti1Image(rgb.astype(np.float32) / 255, aff), self.path("rgbf.nii.gz"))
        script = self.path("p.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", "probe 160 120", "probe 200 90", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        for name, keys, want in (("rgb.nii.gz", {}, rgb.astype(float)), ("rgbf.nii.gz", {"rgb": True}, rgb.astype(np.float32) / 255)):
            with self.subTest(file=name):
                p = xvfb_run([HORIZON, "view", self.scene("c.json", file=name, window=[0, 1], **keys), "--size", "320x240", "--script", script],
                             env)
                self.assertEqual(p.returncode, 0, p.stderr)
                lines = [l for l in p.stdout.splitlines() if l.startswith("probe ")]
                self.assertEqual(len(lines), 2, p.stdout)
                for line in lines:
                    m = re.search(r"voxel \((\d+), (\d+), (\d+)\) = \(([-\d.e+]+), ([-\d.e+]+), ([-\d.e+]+)\)", line)
                    self.assertIsNotNone(m, line)
                    i, j, k = (int(m.group(n)) for n in (1, 2, 3))
                    np.testing.assert_allclose([float(m.group(n)) for n in (4, 5, 6)], want[i, j, k], rtol=1e-5, err_msg=line)


class MovieTest(TempDirTest):
    """`horizon movie`: a turntable (the camera turned about the superior
    axis through its target) to an image sequence, .mp4 and .webm. Frame k
    of N is the scene seen from its camera turned by 360 k / N degrees, as
    a scene file with that camera computed here renders it; the videos are
    what FFmpeg's own ffprobe and ffmpeg (Debian's ffmpeg) read back."""

    def setUp(self):
        super().setUp()
        p = run("demo", "--out", self.path("d"), "--streamlines", "400", "--no-window", env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.tck = self.path("d/phantom.tck")
        self.eye, self.target = np.array([0.0, 300.0, 20.0]), np.array([0.0, -10.0, 5.0])

    def scene(self, name, eye):
        with open(self.path(name), "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": self.tck, "render": "lines"}],
                       "camera": {"position": list(eye), "target": list(self.target), "up": [0, 0, 1]}}, f)
        return self.path(name)

    def turned(self, deg):
        a = np.radians(deg)
        d = self.eye - self.target
        return self.target + [d[0] * np.cos(a) - d[1] * np.sin(a), d[0] * np.sin(a) + d[1] * np.cos(a), d[2]]

    def still(self, name, eye):
        p = run("render", self.scene(name + ".json", eye), "-o", self.path(name + ".png"), "--size", "160x120", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return load(self.path(name + ".png"))

    def test_frames_are_the_turned_camera(self):
        os.mkdir(self.path("f"))
        p = run("movie", self.scene("s.json", self.eye), "-o", self.path("f/%03d.png"), "--size", "160x120", "--seconds", "1", "--fps",
                "4", "--json", env=NO_DISPLAY, timeout=300)
        self.assertEqual(p.returncode, 0, p.stderr)
        j = json.loads(p.stdout)
        self.assertEqual((j["frames"], j["fps"]), (4, 4))
        self.assertGreater(j["frame_ms_median"], 0)
        self.assertEqual(sorted(os.listdir(self.path("f"))), ["000.png", "001.png", "002.png", "003.png"])
        for k in range(4):
            want = self.still(f"r{k}", self.turned(90 * k))
            got = load(self.path(f"f/{k:03d}.png"))
            self.assertLess((np.abs(got - want).sum(axis=-1) > 30).mean(), 0.002, f"frame {k}")
        self.assertGreater(np.abs(load(self.path("f/000.png")) - load(self.path("f/001.png"))).mean(), 2)

    @unittest.skipUnless(shutil.which("ffprobe") or os.environ.get("CI"), "ffprobe (Debian's ffmpeg) is not installed")
    def test_videos_read_back_by_ffmpeg(self):
        first = self.still("r0", self.eye)
        for ext, codec in ((".mp4", "h264"), (".webm", "vp9")):
            with self.subTest(ext=ext):
                out = self.path("m" + ext)
                p = run("movie", self.scene("s.json", self.eye), "-o", out, "--size", "160x120", "--seconds", "1", "--fps", "12",
                        env=NO_DISPLAY, timeout=300)
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertIn("12 frames of 160x120 at 12 fps", p.stdout)
                self.assertEqual(p.stderr.strip(), "", "the encoders' chatter is not shown")
                q = subprocess.run(["ffprobe", "-v", "error", "-count_frames", "-show_entries",
                                    "stream=codec_name,width,height,pix_fmt,r_frame_rate,nb_read_frames", "-of", "json", out],
                                   capture_output=True, text=True, timeout=60)
                self.assertEqual(q.returncode, 0, q.stderr)
                st = json.loads(q.stdout)["streams"][0]
                self.assertEqual((st["codec_name"], st["width"], st["height"], st["pix_fmt"], st["r_frame_rate"], st["nb_read_frames"]),
                                 (codec, 160, 120, "yuv420p", "12/1", "12"))
                png = self.path("first" + ext + ".png")
                q = subprocess.run(["ffmpeg", "-v", "error", "-y", "-i", out, "-frames:v", "1", png], capture_output=True, text=True, timeout=60)
                self.assertEqual(q.returncode, 0, q.stderr)
                # Lossy (4:2:0 halves the colour of 1-pixel lines): the
                # background within 3 levels, most pixels within 3, the
                # mean within 8 (frames a quarter turn apart differ by 12).
                got = load(png)
                np.testing.assert_allclose(got[2:20, 2:20].mean(axis=(0, 1)), first[2:20, 2:20].mean(axis=(0, 1)), atol=3)
                self.assertLessEqual(np.median(np.abs(got - first)), 3)
                self.assertLess(np.abs(got - first).mean(), 8.0)

    def test_bad_movies_are_one_line_and_write_nothing(self):
        scene = self.scene("s.json", self.eye)
        for args, words in ((["-o", self.path("odd.mp4"), "--size", "161x120"], "even"),
                            (["-o", self.path("m.avi")], ".mp4 (H.264), .webm (VP9) or an image sequence"),
                            (["-o", self.path("none/m.mp4")], "no such folder"),
                            (["-o", self.path("f_%d_%d.png")], "one %d"),
                            (["-o", self.path("m.mp4"), "--seconds", "0"], "--seconds"),
                            (["-o", scene.replace(".json", ".mp4"), "--fps", "500"], "--fps")):
            with self.subTest(args=args):
                before = sorted(os.listdir(self.tmp))
                p = run("movie", scene, *args, env=NO_DISPLAY, timeout=120)
                self.assertNotEqual(p.returncode, 0)
                self.assertIn(words, p.stderr.strip().splitlines()[0])  # (the command line's own checks add a hint line)
                self.assertEqual(sorted(os.listdir(self.tmp)), before)
        with open(self.path("keep.mp4"), "w") as f:
            f.write("keep me")
        p = run("movie", scene, "-o", self.path("keep.mp4"), "--size", "160x120", "--seconds", "0.5", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 1)
        self.assertIn("--force", p.stderr)
        with open(self.path("keep.mp4")) as f:
            self.assertEqual(f.read(), "keep me")


class FibreAnisotropyTest(TempDirTest):
    """The paper's Fig. 7: a corpus-callosum-like bundle (1500 arcs across
    the midline) lit by the default rig, with the principled model's
    `anisotropic` at 0 and at 1. At 1 the fibres shine as hair does: a
    highlight where the tangent is nearly perpendicular to the half vector,
    which along the arc comes and goes: bright and dark bands along the
    bundle. Measured as the contrast of the bundle's mean brightness along
    it ((max - min) / mean over the columns of its middle 80 %), which must
    grow: lines, grey 0.056 -> 0.233 and direction-coloured 0.086 -> 2.42;
    direction-coloured tubes 0.43 -> 0.83 (grey tubes barely change: their
    highlight is white on a light surface)."""

    def setUp(self):
        super().setUp()
        from hztest import tck_bytes
        rng = np.random.default_rng(1)
        arcs = []
        for _ in range(1500):
            y, dz, w = rng.uniform(-30, 30), rng.normal(0, 2.0), rng.uniform(0.9, 1.1)
            x = np.linspace(-45, 45, 91) * w
            arcs.append(np.stack([x, np.full_like(x, y), 20 + 25 * (1 - (x / 45) ** 2) + dz], 1).astype(np.float32))
        with open(self.path("cc.tck"), "wb") as f:
            f.write(tck_bytes(arcs))

    def banding(self, render, grey, anisotropic):
        o = {"type": "streamlines", "file": "cc.tck", "render": render,
             "material": {"shader": "principled", "params": {"anisotropic": anisotropic, "roughness": 0.35, "specular": 0.5}}}
        if render == "tubes":
            o["radius"] = 0.3
        if grey:
            o["color"] = [0.7, 0.7, 0.7]
        with open(self.path("s.json"), "w") as f:
            json.dump({"objects": [o], "camera": {"view": "anterior"}}, f)
        p = run("render", self.path("s.json"), "-o", self.path("s.png"), "--size", "640x400", "--force", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        a = load(self.path("s.png"))
        lum = a @ [0.2126, 0.7152, 0.0722]
        fg = np.abs(a - a[0, 0]).sum(axis=2) > 30
        cols = np.array([lum[fg[:, x], x].mean() for x in range(a.shape[1]) if fg[:, x].sum() >= 15])
        cols = cols[len(cols) // 10:len(cols) - len(cols) // 10]
        return (cols.max() - cols.min()) / cols.mean()

    def test_anisotropic_fibres_band_along_the_bundle(self):
        for render, grey, factor in (("lines", True, 2.5), ("lines", False, 3.0), ("tubes", False, 1.5)):
            with self.subTest(render=render, grey=grey):
                plain, shining = self.banding(render, grey, 0.0), self.banding(render, grey, 1.0)
                self.assertGreater(shining, factor * plain, f"{render}: contrast {plain:.3f} -> {shining:.3f}")


class ShaderCheckTest(unittest.TestCase):
    def test_gpu_equals_cpu_for_every_shader(self):
        j = run_json("shader-check", "--json", "--sets", "6", "--size", "128", env=NO_DISPLAY, timeout=600)
        ids = {s["shader"]: s for s in j["shaders"]}
        for sid in ("principled", "lambert", "blinn_phong", "blinn_phong_brdf", "line_stalling", "line_mallo_diffuse", "flat", "glass"):
            s = ids["org.horizon.shader." + sid]
            self.assertTrue(s["ok"], s)
            self.assertGreater(s["pixels"], 1000, s)
            self.assertEqual(s["nonfinite"], 0)
            self.assertEqual(s["negative"], 0)

    def test_the_check_fails_when_tolerances_are_impossible(self):
        p = run("shader-check", "--shader", "principled", "--sets", "2", "--size", "64", "--rel", "1e-9", "--abs", "1e-12",
                env=NO_DISPLAY, timeout=300)
        self.assertEqual(p.returncode, 1, p.stdout)
        self.assertIn("FAIL", p.stdout)


# Skipped on a user's machine without xvfb-run; in CI (CI set) a missing
# xvfb-run fails every window test instead (the bootstrap installs it).
@unittest.skipUnless(shutil.which("xvfb-run") or os.environ.get("CI"), "xvfb-run is not installed")
class WindowTest(TempDirTest):
    def demo_400(self):
        """The 400-streamline phantom the exploration tests open (in d/)."""
        p = run("demo", "--out", self.path("d"), "--streamlines", "400", "--no-window", env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)

    def window(self, name, lines, *args, size="480x320"):
        """`horizon view d/phantom.tck ARGS` under Xvfb, driven by a script of `lines`: the process."""
        script = self.path(name + ".txt")
        with open(script, "w") as f:
            f.write("\n".join(lines) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # see test_window_under_xvfb_with_scripted_input
        return xvfb_run([HORIZON, "view", self.path("d/phantom.tck"), *args, "--size", size, "--script", script], env)

    def explore(self, name, lines):
        """The window with --explore: the process and the states it printed (the `explore: ` lines, without that prefix)."""
        p = self.window(name, lines, "--explore")
        return p, [l[len("explore: "):] for l in p.stdout.splitlines() if l.startswith("explore:")]

    def test_window_under_xvfb_with_scripted_input(self):
        scene = self.path("scene.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "surface", "builtin": "cortex"},
                                   {"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 300}, "render": "tubes"}]}, f)
        script = self.path("script.txt")
        with open(script, "w") as f:
            f.write("\n".join([
                "wait 2", f"screenshot {self.path('v0.png')}",
                "drag 300 200 500 230", "wait 1", f"screenshot {self.path('v1.png')}",
                "scroll 4", "wait 1", f"screenshot {self.path('v2.png')}",
                "shader 0 flat", "wait 1", f"screenshot {self.path('v3.png')}",
                "key s", "wait 1", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            # glfwTerminate unloads Mesa's GLX driver before LeakSanitizer
            # runs, so the driver's own allocations cannot be attributed to
            # it (tests/lsan.supp); leak checking stays on everywhere else.
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", scene, "--size", "640x400", "--script", script, "--screenshot-dir", self.tmp], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        shots = [load(self.path(f"v{i}.png")) for i in range(4)]
        for s in shots:
            self.assertEqual(s.shape, (400, 640, 3))
        self.assertGreater(np.mean(np.abs(shots[0] - shots[1])), 1.0, "orbit changes the view")
        self.assertGreater(np.mean(np.abs(shots[1] - shots[2])), 1.0, "zoom changes the view")
        self.assertGreater(np.mean(np.abs(shots[2] - shots[3])), 0.5, "switching the shading model changes the picture")
        self.assertTrue(os.path.exists(self.path("horizon-screenshot-1.png")), "the S key saves a screenshot")

    def test_a_script_line_that_does_not_parse_is_an_error(self):
        """Every word of a script line is checked: a missing or malformed
        argument, a word left over, an unknown modifier or key stop the
        script with one line naming the script and its line (not the data,
        which are fine), where a typo used to do nothing or something else
        (`drag 1 2` read two numbers that were never given)."""
        self.demo_400()
        cases = {"foo 1 2": "unknown command 'foo'",
                 "drag 10 20": "drag needs X1",
                 "drag 10 20 30 y": "drag: 'y' is not a number (Y1)",
                 "wait 1.5": "wait: '1.5' is not a number of frames",
                 "click 10 20 ctlr": "'ctlr' is not a modifier (ctrl, alt, shift)",
                 "key 5": "key: '5' is not a key (a letter or esc)",
                 "quit now": "quit: unexpected 'now'",
                 "resize 400": "resize needs a height in pixels",
                 "resize 0 300": "resize: the size must be at least 1x1",
                 f"screenshot {self.path('none/x.png')}": f"{self.path('none/x.png')}: directory {self.path('none')} does not exist"}
        for k, (line, error) in enumerate(cases.items()):
            with self.subTest(line=line):
                p = self.window(f"bad{k}", ["wait 1", line, "quit"])
                self.assertEqual(p.returncode, 1, p.stderr)
                self.assertEqual(p.stderr.strip(), f"horizon: error: {self.path(f'bad{k}.txt')}: line 2: {error}")
        # The line named is the file's: after a comment, a blank line and
        # Windows line ends (which, like spaces around a command, are not
        # part of it: the commands before run).
        p = self.window("crlf", ["# a comment", "", "  wait 1  \r", "mark here\r", "drag 10 20\r", "quit\r"])
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertEqual(p.stderr.strip(), f"horizon: error: {self.path('crlf.txt')}: line 5: drag needs X1")
        # A script that is not there: refused before any window opens.
        p = xvfb_run([HORIZON, "view", self.path("d/phantom.tck"), "--script", self.path("none.txt")], os.environ)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn(f"--script: File does not exist: {self.path('none.txt')}", p.stderr)

    def test_a_screenshot_that_cannot_be_written_leaves_the_window_open(self):
        """S where the screenshot cannot be written (here a folder is in the
        way of its name): one line naming the file, and the window goes on
        (the next S writes); a --screenshot-dir that does not exist, or a
        --stats file in a folder that does not exist, is refused before any
        window opens."""
        self.demo_400()
        shots = self.path("shots")
        os.makedirs(os.path.join(shots, "horizon-screenshot-1.png"))
        p = self.window("shot_blocked", ["wait 1", "key s", "wait 2", "key s", "wait 2", "quit"], "--screenshot-dir", shots)
        self.assertEqual(p.returncode, 0, p.stderr)
        lines = [l for l in p.stderr.splitlines() if l.startswith("horizon:")]
        self.assertEqual(len(lines), 1, p.stderr)
        self.assertIn(os.path.join(shots, "horizon-screenshot-1.png"), lines[0])
        self.assertEqual(load(os.path.join(shots, "horizon-screenshot-2.png")).shape, (320, 480, 3))
        p = self.window("shot_nowhere", ["quit"], "--screenshot-dir", self.path("nonexistent"))
        self.assertNotEqual(p.returncode, 0)
        self.assertIn(f"--screenshot-dir: Directory does not exist: {self.path('nonexistent')}", p.stderr)
        self.assertNotIn("first frame", p.stdout)
        # So is a --stats file (written at exit) in a folder that does not exist.
        p = self.window("stats_nowhere", ["quit"], "--stats", self.path("nonexistent/s.json"))
        self.assertEqual(p.returncode, 1)
        self.assertEqual(p.stderr.strip(), f"horizon: error: {self.path('nonexistent/s.json')}: directory {self.path('nonexistent')} does not exist")
        self.assertNotIn("first frame", p.stdout)

    def test_window_reset_pan_visibility_and_repeat_key(self):
        """R goes back to the view the window opened with (after an orbit and
        after a pan, exactly); a pan moves the picture; an object's
        'visible' box hides it and shows it again, exactly as before; C in
        the exploration clusters again what is shown."""
        scene = self.path("scene.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "surface", "builtin": "sphere"},
                                   {"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 200}, "render": "tubes"}]}, f)
        shot = lambda i: f"screenshot {self.path(f'k{i}.png')}"
        script = self.path("keys.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", shot(0), "drag 200 150 320 170", "wait 1", shot(1), "key r", "wait 1", shot(2),
                               "pan 200 150 260 190", "wait 1", shot(3), "key r", "wait 1", shot(4),
                               "press object 0", "wait 1", "press object 1", "wait 1", "press visible 1", "wait 1", shot(5),
                               "press visible 1", "wait 1", shot(6), "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # see test_window_under_xvfb_with_scripted_input
        p = xvfb_run([HORIZON, "view", scene, "--size", "480x320", "--script", script], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        k = [load(self.path(f"k{i}.png")) for i in range(7)]
        self.assertGreater(np.mean(np.abs(k[0] - k[1])), 1.0, "the orbit turns the view")
        np.testing.assert_array_equal(k[2], k[0], "R after an orbit: the opening view")
        self.assertGreater(np.mean(np.abs(k[0] - k[3])), 1.0, "the pan moves the picture")
        # A pan moves the picture without turning it: the sphere's silhouette
        # (not the tubes) is shifted, not reshaped.
        np.testing.assert_array_equal(k[4], k[0], "R after a pan: the opening view")
        self.assertGreater(np.mean(np.abs(k[0] - k[5])), 1.0, "hiding the streamlines changes the picture")
        np.testing.assert_array_equal(k[6], k[0], "shown again: the same picture")
        # C: the exploration's repeat, from the keyboard.
        self.demo_400()
        p, states = self.explore("c", ["wait 1", "expand 0", "wait 1", "key c", "wait 1", "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        import re
        runs = [int(re.findall(r"(\d+) clustering", st)[0]) for st in states]
        self.assertEqual(runs[0], 1)
        self.assertEqual(runs[-1], 2, states)

    def test_window_bakes_materials_once_the_panel_is_left_alone(self):
        """Editing a material switches the window's programs to uniforms (no compile per slider value); once the
        values stay put they are baked into constants; both forms draw the same picture."""
        scene = self.path("scene.json")
        with open(scene, "w") as f:
            json.dump({"objects": [{"type": "surface", "builtin": "sphere", "color": [0.8, 0.5, 0.4]}],
                       "camera": {"position": [0, -58, 0], "target": [0, 0, 0], "fov": 60}}, f)
        script = self.path("script.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 2", "set 0 roughness 0.3", "set 0 metallic 0.2", "wait 1",
                               f"screenshot {self.path('uniform.png')}", "sleep 1.5", "wait 2",
                               f"screenshot {self.path('baked.png')}", "wait 1", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # see test_window_under_xvfb_with_scripted_input
        p = xvfb_run([HORIZON, "-v", "view", scene, "--size", "320x240", "--script", script], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        log = p.stderr
        self.assertIn("renderer: uniform material programs", log)
        self.assertGreater(log.rfind("renderer: baked material programs"), log.find("renderer: uniform material programs"))
        a, b = load(self.path("uniform.png")), load(self.path("baked.png"))
        self.assertGreater(a.std(), 10.0, "a lit sphere")
        self.assertLessEqual(np.abs(a - b).max(), 2.0, "baked constants draw what the uniforms draw")

    def test_view_surface_and_overlay_files(self):
        """`horizon view lh.white lh.thickness`: the overlay colours the surface before it."""
        RenderTest.make_surface_with_thickness(self)
        import nibabel.freesurfer as fsio
        verts, _ = fsio.read_geometry(self.path("lh.white"))
        fsio.write_annot(self.path("lh.aparc.annot"), np.where(verts[:, 2] > 0, 1, 0).astype(np.int32),
                         np.array([[0, 0, 255, 0, 0], [255, 0, 0, 0, 0]], np.int32), [b"lower", b"upper"])
        shots = {}
        for name, files in (("plain", ["lh.white"]), ("overlay", ["lh.white", "lh.thickness"]),
                            ("annot", ["lh.white", "lh.aparc.annot"])):
            script = self.path(name + ".txt")
            with open(script, "w") as f:
                f.write(f"wait 1\nscreenshot {self.path(name + '.png')}\nquit\n")
            env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
            if "ASAN_OPTIONS" in env:
                env["ASAN_OPTIONS"] += ":detect_leaks=0"
            p = xvfb_run([HORIZON, "view", *[self.path(x) for x in files], "--size", "320x240", "--script", script], env)
            self.assertEqual(p.returncode, 0, p.stderr)
            shots[name] = load(self.path(name + ".png"))
        self.assertGreater(np.mean(np.abs(shots["plain"] - shots["overlay"])), 5.0)
        # The annotation shows its label colours: strongly red and strongly blue pixels, no green.
        a = shots["annot"].reshape(-1, 3).astype(float)
        self.assertGreater(np.sum((a[:, 0] > 150) & (a[:, 2] < 60)), 500, "red label")
        self.assertGreater(np.sum((a[:, 2] > 150) & (a[:, 0] < 60)), 500, "blue label")
        # (read once the window is open, behind its progress panel: the
        # error comes from there, the window closes, nothing else is shown)
        p = xvfb_run([HORIZON, "view", self.path("lh.thickness")], env)
        self.assert_clean_error(p, "lh.thickness")
        self.assertIn("need their surface", p.stderr)
        # A file that cannot be read: one line, naming it once.
        p = xvfb_run([HORIZON, "view", self.path("missing.tck")], env)
        self.assert_clean_error(p, "missing.tck")
        self.assertEqual(p.stderr.count("missing.tck"), 1, p.stderr)

    def test_level_of_detail_while_moving(self):
        # A tractogram above --lod-points is drawn as a subsample of its
        # streamlines (at 1/--lod-scale of the size) while the camera moves;
        # at rest the proxy comes first, then full detail in steps, and the
        # finished still image is exactly the one drawn without a proxy.
        p = run("demo", "--out", self.path("d"), "--streamlines", "600", "--no-window", env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        script = self.path("lod.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", f"screenshot {self.path('rest.png')}", "moving on", "wait 1",
                               f"screenshot {self.path('moving.png')}", "moving off", "wait 1",
                               f"screenshot {self.path('rest2.png')}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # see test_window_under_xvfb_with_scripted_input
        stats = self.path("stats.json")
        p = xvfb_run([HORIZON, "view", self.path("d/phantom.tck"), "--size", "480x320", "--aa-frames", "1", "--lod-points", "4000", "--script", script,
                      "--stats", stats], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("level of detail: 600 streamlines", p.stdout)
        rest, moving, rest2 = (load(self.path(n)) for n in ("rest.png", "moving.png", "rest2.png"))
        self.assertGreater(np.mean(np.abs(rest - moving)), 0.5, "the proxy is drawn while moving")
        np.testing.assert_array_equal(rest, rest2)
        frames = json.load(open(stats))["frames"]
        moving_frames = [f for f in frames if f["kind"] == "moving"]
        self.assertTrue(moving_frames and all(f["proxy"] and f["streamlines"] < 600 for f in moving_frames))
        self.assertTrue(any(f["kind"] in ("refine", "complete") and f["step"] > 0 for f in frames), "refined in steps")
        # Without a proxy (--lod-points above the size) the same still image.
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", f"screenshot {self.path('plain.png')}", "quit"]) + "\n")
        p = xvfb_run([HORIZON, "view", self.path("d/phantom.tck"), "--size", "480x320", "--aa-frames", "1", "--lod-points", "1e9", "--script", script],
                     env)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertNotIn("level of detail:", p.stdout)
        np.testing.assert_array_equal(load(self.path("plain.png")), rest)

    def phantom_600(self):
        """The 600-streamline phantom (d/phantom.tck; as tubes, the demo's
        default) and a scene of it as lines (lines.json): the window's
        environment."""
        p = run("demo", "--out", self.path("d"), "--streamlines", "600", "--no-window", env=NO_DISPLAY, timeout=180)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(self.path("lines.json"), "w") as f:
            json.dump({"objects": [{"type": "streamlines", "file": self.path("d/phantom.tck"), "render": "lines"}]}, f)
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"  # see test_window_under_xvfb_with_scripted_input
        return env

    def test_proxy_level_follows_the_moving_frame_times(self):
        # While the camera moves, the proxy's level follows the frames' times
        # (--lod-frame-ms): within a budget no frame meets, down to the
        # cheapest level; within one every frame meets, up to the finest,
        # which draws more of the proxy at a larger size and looks more like
        # the still image, and then to full detail, since the still image
        # took less than the budget (the picture is then the still's); with 0,
        # the base level (--lod-scale, --lod-points) alone throughout.
        env = self.phantom_600()
        runs = {}
        for budget in ("0.5", "10000", "0"):
            script, stats = self.path(f"gov{budget}.txt"), self.path(f"gov{budget}.json")
            shot = self.path(f"gov{budget}.png")
            with open(script, "w") as f:
                # (the last moving frame's picture: a screenshot while moving)
                f.write("\n".join(["wait 1", f"screenshot {self.path('rest.png')}", "moving on", "wait 60", f"screenshot {shot}",
                                   "moving off", "wait 1", "quit"]) + "\n")
            # (without the reprojected still, which would hide the proxy's level)
            p = xvfb_run([HORIZON, "view", self.path("lines.json"), "--size", "480x320", "--lod-points", "4000", "--lod-reproject",
                          "off", "--lod-frame-ms", budget, "--script", script, "--stats", stats], env)
            self.assertEqual(p.returncode, 0, p.stderr)
            with open(stats) as fh:
                j = json.load(fh)
            # (with 0, the base level alone)
            self.assertEqual(j["proxy_levels"], [[4, 4000]] if budget == "0" else
                             [[8, 2000], [8, 4000], [4, 4000], [2, 4000], [2, 8000], [1, 8000], [1, 16000]])
            moving = [f for f in j["frames"] if f["kind"] == "moving"]
            self.assertGreater(len(moving), 50)
            if budget == "10000":
                # (the top level, full detail: moving frames that draw no proxy, the last ones)
                full = [f["proxy"] for f in moving].index(False)
                self.assertTrue(all(not f["proxy"] and f["streamlines"] == 600 for f in moving[full:]), moving)
                self.assertGreater(len(moving) - full, 5)
                moving = moving[:full]
                np.testing.assert_array_equal(load(shot), load(self.path("rest.png")))
                # ... and at rest again the still at once, without the proxy's picture first
                last = max(i for i, f in enumerate(j["frames"]) if f["kind"] == "moving")
                after = [f for f in j["frames"][last + 1:] if f["kind"] != "still"]
                self.assertEqual([(f["kind"], f["proxy"]) for f in after[:1]], [("complete", False)], after)
            self.assertTrue(all(f["proxy"] for f in moving))
            runs[budget] = ([f["proxy_level"] for f in moving], [f["points"] for f in moving], load(shot))
        down, up, fixed = runs["0.5"][0], runs["10000"][0], runs["0"][0]
        self.assertEqual(down[0], 2)
        self.assertTrue(all(a >= b for a, b in zip(down, down[1:])), down)
        self.assertEqual(down[-20:], [0] * 20, down)
        self.assertTrue(all(a <= b for a, b in zip(up, up[1:])), up)
        self.assertEqual(up[-8:], [6] * 8, up)
        self.assertEqual(set(fixed), {0}, fixed)
        # Full detail only once a still image has shown what it costs: moving
        # from the first frame, within the same budget, the proxy's finest level at most.
        with open(script, "w") as f:
            f.write("\n".join(["moving on", "wait 60", "moving off", "quit"]) + "\n")
        p = xvfb_run([HORIZON, "view", self.path("lines.json"), "--size", "480x320", "--lod-points", "4000", "--lod-reproject", "off",
                      "--lod-frame-ms", "10000", "--script", script, "--stats", stats], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(stats) as fh:
            early = [f for f in json.load(fh)["frames"] if f["kind"] == "moving"]
        self.assertGreater(len(early), 50)
        self.assertTrue(all(f["proxy"] for f in early), early)
        self.assertEqual(early[-1]["proxy_level"], 6)
        # ... and measured at the window's size: resized while moving at full
        # detail, back to the proxy's finest level, and at rest a still refined
        # from the proxy again (until one at the new size has been timed).
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", "moving on", "wait 60", "resize 400 300", "wait 15", "moving off", "wait 1", "quit"]) + "\n")
        p = xvfb_run([HORIZON, "view", self.path("lines.json"), "--size", "480x320", "--lod-points", "4000", "--lod-reproject", "off",
                      "--lod-frame-ms", "10000", "--script", script, "--stats", stats], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(stats) as fh:
            j = json.load(fh)
        self.assertEqual(j["window"], [400, 300])
        moving = [f for f in j["frames"] if f["kind"] == "moving"]
        self.assertTrue(any(not f["proxy"] for f in moving[:60]), moving)
        self.assertTrue(all(f["proxy"] and f["proxy_level"] == 6 for f in moving[-10:]), moving)
        last = max(i for i, f in enumerate(j["frames"]) if f["kind"] == "moving")
        after = [f for f in j["frames"][last + 1:] if f["kind"] != "still"]
        self.assertEqual([(f["kind"], f["proxy"]) for f in after[:1]], [("refine", True)], after)
        # Each level draws its share of the proxy: the finest more points than the base, the cheapest fewer.
        points = lambda k, level: [p for l, p in zip(*runs[k][:2]) if l == level]
        self.assertGreater(min(points("10000", 6)), 1.5 * max(points("0", 0)))
        self.assertLess(max(points("0.5", 0)), max(points("0", 0)))
        # ... and looks more like the still image (compared at 1/4 of the size, as bench/ does).
        rest = load(self.path("rest.png"))
        down4 = lambda a: a[:320 // 4 * 4, :480].reshape(80, 4, 120, 4, -1).mean(axis=(1, 3))
        err = {k: np.mean(np.abs(down4(runs[k][2]) - down4(rest))) for k in runs}
        self.assertLess(err["10000"], err["0"], err)
        self.assertLess(err["0"], err["0.5"], err)

    def test_moving_frames_reproject_the_last_still(self):
        # Once a still image is complete, the frames drawn while the camera
        # moves draw it again from their camera (one point per 4x4 block at
        # its depth) under the proxy: closer to the still than the proxy
        # alone; and not once the camera has turned more than 15 degrees
        # (3 over a fibre volume, which alone is closer to the still sooner).
        env = self.phantom_600()
        errors, reprojected, volumes = {}, {}, {}
        # (600 streamlines are drawn as tubes, which keep the shell; the fibre volume models lines: lines.json)
        for proxy in ("shell", "volume"):
            for mode in ("on", "off"):
                script, stats = self.path(mode + ".txt"), self.path(mode + ".json")
                with open(script, "w") as f:
                    # (0.008 rad per dragged pixel: 5 px 2.3 degrees, 45 px more 23 degrees in all)
                    f.write("\n".join(["wait 1", f"screenshot {self.path('rest.png')}", "moving on", "wait 1",
                                       f"screenshot {self.path('m0_' + mode + '.png')}", "drag 240 160 245 160", "wait 1", "mark small",
                                       "drag 245 160 290 160", "wait 1", "mark turned", "wait 2", "mark large", "moving off", "quit"]) + "\n")
                data = self.path("d/phantom.tck") if proxy == "shell" else self.path("lines.json")
                p = xvfb_run([HORIZON, "view", data, "--size", "480x320", "--lod-points", "4000", "--lod-proxy", proxy,
                              "--lod-reproject", mode, "--script", script, "--stats", stats], env)
                self.assertEqual(p.returncode, 0, p.stderr)
                # (at a quarter of the size, as bench/ compares level-of-detail pictures: both are drawn at 1/4)
                down = lambda a: a[:320 // 4 * 4, :480].reshape(80, 4, 120, 4, -1).mean(axis=(1, 3))
                errors[proxy, mode] = np.mean(np.abs(down(load(self.path("m0_" + mode + ".png"))) - down(load(self.path("rest.png")))))
                frames = json.load(open(stats))["frames"]
                marks = [f["t"] for f in frames if f["kind"] == "mark"]
                moving = [f for f in frames if f["kind"] == "moving"]
                reprojected[proxy, mode] = ([f["reprojected"] for f in moving if f["t"] < marks[0]],
                                            [f["reprojected"] for f in moving if marks[1] < f["t"] < marks[2]])
                volumes[proxy, mode] = [f["fibre_volumes"] for f in moving]
            small, large = reprojected[proxy, "on"]
            self.assertTrue(small and all(r > 50 for r in small), (proxy, small))
            self.assertTrue(large and all(r == 0 for r in large), (proxy, large))
            self.assertTrue(all(r == 0 for r in reprojected[proxy, "off"][0] + reprojected[proxy, "off"][1]))
        # The fibre volume is drawn where asked (it is computed while the still refines).
        self.assertTrue(all(n == 1 for n in volumes["volume", "on"] + volumes["volume", "off"]), volumes)
        self.assertTrue(all(n == 0 for n in volumes["shell", "on"] + volumes["shell", "off"]), volumes)
        # Measured: shell (tubes) 3.6 against 12.3; volume (lines) 3.7 against 5.5 (the volume alone is closer already).
        self.assertLess(errors["shell", "on"], 0.6 * errors["shell", "off"], errors)
        self.assertLess(errors["volume", "on"], 0.85 * errors["volume", "off"], errors)

    def test_idle_window_draws_nothing(self):
        # Once the still image is complete, a window with no input draws no
        # frame at all (and sleeps in glfwWaitEvents: little CPU time).
        self.demo_400()
        script = self.path("idle.txt")
        with open(script, "w") as f:
            f.write(f"screenshot {self.path('idle.png')}\nmark idle\nsleep 2\nquit\n")  # (a screenshot waits for the complete still)
        stats = self.path("idle.json")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", self.path("d/phantom.tck"), "--size", "320x240", "--script", script, "--stats", stats], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(stats) as f:
            frames = json.load(f)["frames"]
        self.assertEqual(frames[0]["kind"], "complete")
        start = next(f["t"] for f in frames if f["kind"] == "mark")
        during = [f for f in frames if start + 0.2 < f["t"] < start + 1.8]
        self.assertEqual(during, [], "no frame while idle")

    def test_view_starts_at_a_named_view(self):
        # `view --view V` opens at the view `render --view V` draws, the
        # views looking straight down or up included (the window's z-up orbit
        # takes its roll from the fitted view's up vector there).
        self.demo_400()
        shots = {}
        for v in ("superior", "inferior", "left"):
            # (--aa-frames 1: the window's still at rest, else averaged over 8 jittered frames, is then render's)
            p = self.window(v, ["wait 1", f"screenshot {self.path('w_' + v + '.png')}", "quit"], "--view", v, "--aa-frames", "1",
                            size="320x240")
            self.assertEqual(p.returncode, 0, p.stderr)
            p = run("render", self.path("d/phantom.tck"), "--view", v, "--size", "320x240", "-o", self.path("r_" + v + ".png"),
                    env=NO_DISPLAY, timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            window, headless = load(self.path("w_" + v + ".png")), load(self.path("r_" + v + ".png"))
            differ = np.abs(window - headless).sum(axis=-1) > 30
            self.assertLess(differ.mean(), 0.005, f"{v}: the window shows the view render draws")
            shots[v] = window
        self.assertGreater(np.mean(np.abs(shots["superior"] - shots["left"])), 1.0)
        self.assertGreater(np.mean(np.abs(shots["superior"] - shots["inferior"])), 1.0)

    def test_explore_expand_hide_repeat(self):
        # Paper Fig. 5: QuickBundlesX centroids; expand the largest cluster
        # down to its streamlines, hide one, cluster again what is shown.
        self.demo_400()
        lines = ["wait 1", f"screenshot {self.path('e0.png')}"] + ["expand 0"] * 40 + \
                ["wait 1", f"screenshot {self.path('e1.png')}", "hide 0", "repeat", "wait 1", f"screenshot {self.path('e2.png')}", "quit"]
        p, states = self.explore("ex", lines)
        self.assertEqual(p.returncode, 0, p.stderr)
        import re
        parsed = [tuple(map(int, re.findall(r"(\d+) clusters, (\d+) streamlines expanded, (\d+) clustering", l)[0])) for l in states]
        colours = [l.split("colours", 1)[1].split() for l in states]
        self.assertEqual(parsed[0][1:], (0, 1))
        self.assertTrue(any(e > 0 for _, e, _ in parsed), "expanding reaches the streamlines of a last-level cluster")
        self.assertEqual(parsed[-1][2], 2, "repeat clusters again")
        self.assertEqual(parsed[-2][0], parsed[-3][0] - 1, "hide removes a cluster")
        # Colours are stable: expanding keeps the other clusters' colours, and
        # after repeat most clusters keep the colour their streamlines had.
        self.assertEqual(len(set(colours[0])), len(colours[0]), "one colour per cluster")
        before, after = set(colours[-2]), colours[-1]
        kept = sum(c in before for c in after)
        self.assertGreaterEqual(kept, min(len(after), len(before)) * 0.5, f"colours before {colours[-2]}, after {after}")
        self.assertEqual(len(set(after)), len(after), "one colour per cluster after repeat")
        shots = [load(self.path(f"e{i}.png")) for i in range(3)]
        self.assertGreater(np.mean(np.abs(shots[0] - shots[1])), 0.5)
        self.assertGreater(np.mean(np.abs(shots[1] - shots[2])), 0.5)

    def test_explore_every_cluster_to_streamlines(self):
        # One small cluster shown as its streamlines, then every other one
        # at once (A, X): all 400 streamlines expanded, each once, whichever
        # way they are added (a few are sorted in; many are marked).
        self.demo_400()
        p, states = self.explore("all_x", ["wait 1", "expand 5 streamlines", "wait 1", "key a", "key x", "wait 1", "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        import re
        parsed = [tuple(map(int, re.findall(r"(\d+) clusters, (\d+) streamlines expanded, (\d+) clustering", l)[0])) for l in states]
        self.assertTrue(0 < parsed[1][1] < 50, parsed)
        self.assertEqual(parsed[-1], (0, 400, 1), states[-1])

    def test_explore_panel_buttons(self):
        # The panel's buttons, clicked through Dear ImGui's input (`press`):
        # A selects every cluster, "Expand selected" replaces each by its
        # children, "Hide selected" hides them all, "Repeat" on an empty view
        # says why it cannot, "Reset" goes back to the first clustering.
        self.demo_400()
        p, states = self.explore("buttons", ["wait 1", "key a", "wait 1", "press Expand selected", "wait 1", "key a", "wait 1",
                                     "press Hide selected", "wait 1", f"screenshot {self.path('empty.png')}",
                                     "press Repeat: cluster what is shown", "wait 1", "press Reset", "wait 1", "quit"])
        self.assertEqual(p.returncode, 0, p.stderr)
        import re
        counts = [int(re.match(r"(\d+) clusters", st).group(1)) for st in states]
        n0 = counts[0]
        self.assertEqual(len(states), 6, states)
        self.assertIn("selected none", states[0])
        self.assertEqual(states[1].count("#"), n0, "A selects every cluster")
        self.assertGreater(counts[2], n0, "Expand selected: every selected cluster replaced by its children")
        self.assertIn("selected none", states[2])
        self.assertEqual(counts[4], 0, "Hide selected: every selected cluster hidden")
        self.assertIn("nothing is shown to cluster again", p.stderr)
        self.assertEqual(counts[5], n0, "Reset: the first clustering again")
        self.assertTrue(os.path.getsize(self.path("empty.png")) > 0, "an empty view still draws")
        # A button that is not on the panel (nothing selected): the script's line is named.
        p, _ = self.explore("absent", ["wait 1", "press Hide selected", "quit"])
        self.assertEqual(p.returncode, 1)
        self.assertIn("line 2: no button 'Hide selected' on the panel", p.stderr)

    def test_explore_pick_hide_expand(self):
        # Picking in the window: a click on a centroid selects its cluster
        # (drawn lighter), H hides the selection, E expands it.
        self.demo_400()

        def view(name, lines):
            p, states = self.explore(name, lines + ["quit"])
            self.assertEqual(p.returncode, 0, p.stderr)
            return states

        def changed(a, b):
            return np.abs(load(self.path(a)) - load(self.path(b))).sum(axis=-1) > 0.1

        def inner_pixel(mask):
            # A pixel of the mask whose 5x5 neighbourhood is all in it (the middle of a tube).
            core = mask.copy()
            for dy in range(-2, 3):
                for dx in range(-2, 3):
                    core &= np.roll(np.roll(mask, dy, axis=0), dx, axis=1)
            ys, xs = np.nonzero(core)
            self.assertGreater(len(xs), 0)
            i = len(xs) // 2
            return int(xs[i]), int(ys[i])

        # A selects every cluster: the pixels that change are the centroids'.
        states = view("all", ["wait 1", f"screenshot {self.path('a.png')}", "key a", "wait 1", f"screenshot {self.path('b.png')}"])
        self.assertIn("selected none", states[0])
        self.assertNotIn("selected none", states[-1])
        centroids = changed("a.png", "b.png")
        x, y = inner_pixel(centroids)
        n0 = int(states[0].split()[0])

        states = view("hide", ["wait 1", f"click {x} {y}", "wait 1", f"screenshot {self.path('c.png')}", "click 2 2", "key h", "wait 1",
                               f"screenshot {self.path('d.png')}", "key h"])
        picked = [l for l in states if l.startswith("picked #")]
        self.assertEqual(len(picked), 1, states)
        rank = picked[0].split()[1]
        self.assertIn(f"selected {rank};", states[2], "exactly the clicked cluster is selected")
        self.assertIn("no centroid under (2, 2)", states, "a click on the background picks nothing")
        lit = changed("a.png", "c.png")
        self.assertTrue(lit[y, x], "the clicked pixel is drawn lighter: the cluster picked is the one drawn there")
        self.assertFalse((lit & ~centroids).any(), "only centroid pixels change")
        self.assertLess(lit.sum(), centroids.sum(), "one cluster of several")
        self.assertTrue(states[-1].startswith(f"{n0 - 1} clusters"), states[-1])
        self.assertIn("selected none", states[-1])
        gone = changed("a.png", "d.png")
        # (Other tubes may change a little too: radii follow the median cluster size.)
        self.assertGreater((lit & gone).sum(), 0.9 * lit.sum(), "H hides the cluster that was lit")

        # E: the picked cluster is replaced by its children (or its streamlines).
        x2, y2 = inner_pixel(centroids & ~lit)
        states = view("expand", ["wait 1", f"click {x2} {y2}", "key e", "wait 1"])
        picked = [l for l in states if l.startswith("picked #")]
        self.assertEqual(len(picked), 1, states)
        level = int(picked[0].split("level ")[1].split(",")[0])
        size = int(picked[0].split(", ")[1].split()[0])
        clusters, expanded = (int(v) for v in re.findall(r"(\d+) clusters, (\d+) streamlines expanded", states[-1])[0])
        if level < 4:
            self.assertGreaterEqual(clusters, n0, states[-1])
        else:
            self.assertEqual((clusters, expanded), (n0 - 1, size))
        self.assertIn("selected none", states[-1])

    def test_no_display_points_to_render(self):
        # Without a display, `view` names the `render` command for the same inputs.
        p = run("view", "whatever.json", env=NO_DISPLAY)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("`horizon render whatever.json -o out.png`", p.stderr)
        p = run("view", "a.tck", "lh.white", env=NO_DISPLAY)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("`horizon render a.tck lh.white -o out.png`", p.stderr)


if __name__ == "__main__":
    unittest.main()
