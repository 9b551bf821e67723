"""Glyphs and connectomes. Peaks and ODFs: DIPY's PAM5 files read as DIPY reads them
(dipy.io.peaks.load_peaks), MRtrix3-style peak NIfTIs (3 values a peak), both
drawn as peak glyphs on slices or through the whole volume, from data files,
scene files and the window's slicer; ODFs from SH coefficients (DIPY's and
MRtrix3's bases, written by DIPY's sf_to_sh) drawn as glyphs of their shape;
diffusion tensors (DIPY's symmetric-matrix NIfTI, FSL's and MRtrix3's orders)
as ellipsoids in DIPY's color_fa; connectomes from BrainNet Viewer's and
CSV files, edges above the threshold as numpy counts them, as thick as their
weights; malformed and hostile PAM5 files, volumes of the wrong layout and
connectome files that disagree each one line, nothing written."""
import json
import os
import shutil
import unittest

import h5py
import nibabel as nib
import numpy as np
from PIL import Image

from hztest import HORIZON, TempDirTest, run, run_json, xvfb_run

NO_DISPLAY = {"DISPLAY": ""}


def load(path):
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def scene_errors(test, cases):
    """Each scene of one object `ob` fails to render with one line naming
    the scene file and holding `msg`, nothing written."""
    for name, (ob, msg) in cases.items():
        with test.subTest(case=name):
            with open(test.path(name), "w") as f:
                json.dump({"objects": [ob]}, f)
            p = run("render", test.path(name), "-o", test.path("x.png"), env=NO_DISPLAY, timeout=60)
            test.assert_clean_error(p, name)
            test.assertIn(msg, p.stderr)
            test.assertFalse(os.path.exists(test.path("x.png")))


def random_peaks(rng, shape, n):
    """Unit directions and values, some voxels without peaks (values 0)."""
    dirs = rng.normal(size=shape + (n, 3))
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    vals = rng.random(shape + (n,))
    vals[rng.random(shape + (n,)) < 0.2] = 0
    dirs[vals == 0] = 0
    return dirs, vals


def save_pam5(path, dirs, vals, affine):
    """Through DIPY's own writer."""
    from dipy.core.sphere import Sphere
    from dipy.direction.peaks import PeaksAndMetrics
    from dipy.io.peaks import save_peaks
    pam = PeaksAndMetrics()
    pam.affine = affine
    pam.peak_dirs, pam.peak_values = dirs, vals
    pam.peak_indices = np.zeros(vals.shape, int)
    pam.shm_coeff, pam.odf = None, None
    pam.sphere = Sphere(xyz=np.eye(3))
    pam.B = np.zeros((3, 1))
    pam.total_weight, pam.ang_thr = 0.5, 60.0
    pam.gfa, pam.qa = np.zeros(vals.shape[:3]), np.zeros(vals.shape)
    save_peaks(path, pam)


def pam5_by_hand(path, dirs, vals, affine=None, version="0.0.1", compress=False, fixed=False, **extra):
    """Written with h5py directly: gzip-compressed chunks, a fixed-length
    version string (which DIPY's reader refuses), or whatever a case needs."""
    with h5py.File(path, "w") as f:
        if version is not None:
            f.attrs["version"] = np.bytes_(version) if fixed else version
        g = f.create_group("pam")
        kw = {"compression": "gzip", "chunks": True} if compress else {}
        if dirs is not None:
            g.create_dataset("peak_dirs", data=dirs, **kw)
        if vals is not None:
            g.create_dataset("peak_values", data=vals, **kw)
        if affine is not None:
            g.create_dataset("affine", data=affine)
        for k, v in extra.items():
            g.create_dataset(k, data=v)


def oblique(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    a = np.eye(4)
    a[:3, :3] = q @ np.diag([1.5, 2.0, 2.5])
    a[:3, 3] = rng.normal(size=3) * 20
    return a


class PeaksTest(TempDirTest):
    def convert(self, src, name):
        out = self.path(name)
        p = run("convert", src, out, "--force")
        self.assertEqual(p.returncode, 0, p.stderr)
        return nib.load(out)

    def render(self, src, out, *args, size="320x240"):
        p = run("render", src, "-o", self.path(out), "--size", size, "--force", "--json", *args, env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return load(self.path(out)), json.loads(p.stdout)

    def test_pam5_reads_as_dipy_does(self):
        """DIPY's writer (float64, an oblique affine) and h5py by hand (float32,
        gzip chunks, a fixed-length version): `info` gives the extents and
        affine dipy.io.peaks.load_peaks gives, and the volume converted to
        NIfTI is its peak_dirs x peak_values, 3 values a peak. A fixed-length
        version string (h5py's bytes; DIPY 1.6 refuses it) reads the same."""
        from dipy.io.peaks import load_peaks
        rng = np.random.default_rng(5)
        for name, writer, dtype in (("dipy.pam5", save_pam5, np.float64), ("hand.pam5", pam5_by_hand, np.float32)):
            with self.subTest(file=name):
                dirs, vals = random_peaks(rng, (7, 6, 5), 4)
                aff = oblique(rng)
                f = self.path(name)
                if writer is save_pam5:
                    save_pam5(f, dirs, vals, aff)
                else:
                    pam5_by_hand(f, dirs.astype(dtype), vals.astype(dtype), aff, compress=True,
                                 peak_indices=np.zeros(vals.shape, np.int32), sphere_vertices=np.eye(3), B=np.zeros((3, 1)),
                                 total_weight=[0.5], ang_thr=[60.0], gfa=np.zeros(vals.shape[:3]), qa=np.zeros(vals.shape))
                ref = load_peaks(f)
                info = run_json("info", f, "--json")
                self.assertEqual(info["dims"], [7, 6, 5, 12])
                np.testing.assert_allclose(np.array(info["affine"]), ref.affine, atol=1e-5)
                self.assertIn("pam5", info["format"])
                want = (ref.peak_dirs * ref.peak_values[..., None]).reshape(7, 6, 5, 12)
                ours = self.convert(f, name + ".nii.gz")
                np.testing.assert_allclose(ours.get_fdata(), want, rtol=1e-6, atol=1e-7)
                np.testing.assert_allclose(ours.affine, ref.affine, atol=1e-5)
                if writer is pam5_by_hand:
                    pam5_by_hand(self.path("fixed.pam5"), dirs.astype(dtype), vals.astype(dtype), aff, fixed=True)
                    np.testing.assert_array_equal(self.convert(self.path("fixed.pam5"), "fixed.nii.gz").get_fdata(), ours.get_fdata())

    def test_pam5_and_its_nifti_draw_the_same_glyphs(self):
        """A PAM5 file and the same peaks as an MRtrix3-style NIfTI (--peaks)
        render the same picture; the glyphs drawn are exactly the peaks of
        the voxels on the three centre slices (counted here with numpy)."""
        rng = np.random.default_rng(6)
        dirs, vals = random_peaks(rng, (12, 10, 8), 3)
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-11, -9, -7]
        save_pam5(self.path("p.pam5"), dirs, vals, aff)
        nib.save(nib.Nifti1Image((dirs * vals[..., None]).reshape(12, 10, 8, 9).astype(np.float32), aff), self.path("p.nii.gz"))
        a, sa = self.render(self.path("p.pam5"), "a.png")
        b, sb = self.render(self.path("p.nii.gz"), "b.png", "--peaks")
        np.testing.assert_array_equal(a, b)
        # The slices through the grid's centre (RAS 0, 0, 0 mm -> voxel 5.5, 4.5, 3.5), the upper voxel on a boundary.
        i, j, k = 6, 5, 4
        on = np.zeros((12, 10, 8), bool)
        on[i], on[:, j], on[:, :, k] = True, True, True
        self.assertEqual(sa["streamlines_drawn"], int(((vals > 0) & on[..., None]).sum()))
        self.assertGreater(np.abs(a - a[2, 2]).sum(axis=-1).max(), 100, "glyphs drawn")
        # The whole volume: every peak.
        _, sw = self.render(self.path("p.pam5"), "w.png", "--peaks-whole")
        self.assertEqual(sw["streamlines_drawn"], int((vals > 0).sum()))
        # A threshold drops the short ones.
        _, st = self.render(self.path("p.pam5"), "t.png", "--peaks-whole", "--peak-threshold", "0.5")
        self.assertEqual(st["streamlines_drawn"], int((vals >= 0.5 * vals.max()).sum()))

    def test_glyphs_are_coloured_by_direction_and_placed_by_the_affine(self):
        """One axial slice of peaks seen from above: left half along x (red),
        right half along y (green); the glyphs lie where the affine puts the
        voxels (the same picture for a grid shifted by the affine and the
        camera target moved alike)."""
        vol = np.zeros((16, 16, 1, 3), np.float32)
        vol[:8, :, 0, 0] = 1
        vol[8:, :, 0, 1] = 1
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-15, -15, 0]
        nib.save(nib.Nifti1Image(vol, aff), self.path("xy.nii.gz"))
        scene = {"objects": [{"type": "peaks", "file": "xy.nii.gz", "z": 0, "scale": 0.8}],
                 "camera": {"view": "superior"}, "environment": {"type": "none"}, "background": [0, 0, 0]}
        with open(self.path("s.json"), "w") as f:
            json.dump(scene, f)
        img, stats = self.render(self.path("s.json"), "s.png")
        self.assertEqual(stats["streamlines_drawn"], 256)
        lit = img.sum(axis=-1) > 60
        cols = np.nonzero(lit.any(axis=0))[0]
        mid = (cols.min() + cols.max()) // 2
        left, right = img[:, :mid][lit[:, :mid]], img[:, mid + 1:][lit[:, mid + 1:]]
        self.assertGreater(left[:, 0].mean(), 3 * max(left[:, 1].mean(), left[:, 2].mean()), "x peaks are red")
        self.assertGreater(right[:, 1].mean(), 3 * max(right[:, 0].mean(), right[:, 2].mean()), "y peaks are green")
        # Coloured by amplitude through a colormap instead: a data colouring of the "amplitude" array.
        scene["objects"][0]["color"] = {"mode": "data", "array": "amplitude", "colormap": "hot"}
        with open(self.path("d.json"), "w") as f:
            json.dump(scene, f)
        d, _ = self.render(self.path("d.json"), "d.png")
        self.assertGreater(np.abs(d - img).mean(), 0.5)

    def test_scene_keys_and_wrong_layouts(self):
        """A scene's peaks object: unknown keys, 'whole' with slices, a
        volume of 4 values a voxel, a 3D volume: one line each naming the
        scene file, nothing written."""
        nib.save(nib.Nifti1Image(np.ones((4, 4, 4, 4), np.float32), np.eye(4)), self.path("four.nii.gz"))
        nib.save(nib.Nifti1Image(np.ones((4, 4, 4), np.float32), np.eye(4)), self.path("flat.nii.gz"))
        nib.save(nib.Nifti1Image(np.ones((4, 4, 4, 3), np.float32), np.eye(4)), self.path("ok.nii.gz"))
        cases = {
            "four.json": ({"type": "peaks", "file": "four.nii.gz"}, "4 values a voxel"),
            "flat.json": ({"type": "peaks", "file": "flat.nii.gz"}, "4th dimension"),
            "both.json": ({"type": "peaks", "file": "ok.nii.gz", "whole": True, "z": 0}, "not both"),
            "key.json": ({"type": "peaks", "file": "ok.nii.gz", "window": [0, 1]}, "window"),
            "scale.json": ({"type": "peaks", "file": "ok.nii.gz", "scale": 0}, "scale"),
        }
        scene_errors(self, cases)
        p = run("render", self.path("four.nii.gz"), "--peaks", "-o", self.path("x.png"), env=NO_DISPLAY, timeout=60)
        self.assert_clean_error(p, "four.nii.gz")
        self.assertIn("multiple of 3", p.stderr)

    def test_malformed_pam5(self):
        """Not HDF5, truncated, another HDF5 file, a wrong version, missing or
        mismatched datasets, text for numbers, bad affines, absurd extents
        (a chunked dataset of 2^60 voxels in a few KB), a damaged compressed
        chunk, a global heap that crashes HDF5 itself: one line naming the
        file, no output, no large allocation, no crash."""
        rng = np.random.default_rng(7)
        dirs, vals = random_peaks(rng, (5, 4, 3), 2)
        good = self.path("good.pam5")
        pam5_by_hand(good, dirs, vals, np.eye(4), compress=True)
        with open(good, "rb") as fh:
            blob = fh.read()
        cases = {}

        def make(name, **kw):
            args = dict(dirs=dirs, vals=vals, affine=np.eye(4))
            args.update(kw)
            pam5_by_hand(self.path(name), args.pop("dirs"), args.pop("vals"), **args)
            cases[name] = None
        with open(self.path("text.pam5"), "w") as fh:
            fh.write("version 0.0.1\n")
        cases["text.pam5"] = None
        with open(self.path("truncated.pam5"), "wb") as fh:
            fh.write(blob[:len(blob) // 3])
        cases["truncated.pam5"] = None
        damaged = bytearray(blob)
        for i in range(len(blob) - 400, len(blob) - 40):  # (inside the last compressed chunks)
            damaged[i] ^= 0x5A
        with open(self.path("damaged.pam5"), "wb") as fh:
            fh.write(bytes(damaged))
        cases["damaged.pam5"] = None
        # The version string's object in HDF5's global heap claiming 2^39 bytes more than it holds: HDF5 1.10
        # itself copies past its buffer (SIGSEGV; h5py too), which must stay in the reader's child process.
        heap = bytearray(blob)
        at = heap.find(b"GCOL")
        self.assertGreaterEqual(at, 0, "h5py stores a variable-length version in the global heap")
        heap[at + 28] = 0x90  # (the 5th byte of the first object's 8-byte size)
        with open(self.path("heap.pam5"), "wb") as fh:
            fh.write(bytes(heap))
        cases["heap.pam5"] = None
        p = run("info", self.path("heap.pam5"), timeout=20)
        self.assertIn("the HDF5 library crashed reading the file: a damaged file", p.stderr)
        make("no_version.pam5", version=None)
        make("version_2.pam5", version="2.0.0")
        make("number_version.pam5", version=np.int64(1))
        make("no_values.pam5", vals=None)
        make("no_dirs.pam5", dirs=None)
        make("rank4_dirs.pam5", dirs=dirs[..., 0, :])
        make("dirs_of_2.pam5", dirs=dirs[..., :2])
        make("mismatch.pam5", vals=vals[:4])
        make("values_larger.pam5", vals=np.concatenate([vals, vals[:1]]))  # (readable, plane by plane, but not the same voxels)
        make("text_dirs.pam5", dirs=np.array([b"x"] * 5 * 4 * 3 * 2 * 3).reshape(5, 4, 3, 2, 3))
        make("affine_3x3.pam5", affine=np.eye(3))
        make("singular_affine.pam5", affine=np.zeros((4, 4)))
        make("nan_affine.pam5", affine=np.full((4, 4), np.nan))
        make("zero_extent.pam5", dirs=np.zeros((0, 4, 3, 2, 3)), vals=np.zeros((0, 4, 3, 2)))
        with h5py.File(self.path("absurd.pam5"), "w") as f:
            f.attrs["version"] = "0.0.1"
            g = f.create_group("pam")
            g.create_dataset("peak_dirs", shape=(2 ** 20, 2 ** 20, 2 ** 20, 5, 3), dtype="f4", chunks=(1, 1, 1, 5, 3))
            g.create_dataset("peak_values", shape=(2 ** 20, 2 ** 20, 2 ** 20, 5), dtype="f4", chunks=(1, 1, 1, 5))
        cases["absurd.pam5"] = None
        with h5py.File(self.path("large.pam5"), "w") as f:  # (within the reader's bounds, beyond the memory: the host says so)
            f.attrs["version"] = "0.0.1"
            g = f.create_group("pam")
            g.create_dataset("peak_dirs", shape=(4096, 4096, 4096, 5, 3), dtype="f4", chunks=(1, 1, 1, 5, 3))
            g.create_dataset("peak_values", shape=(4096, 4096, 4096, 5), dtype="f4", chunks=(1, 1, 1, 5))
        cases["large.pam5"] = None
        with h5py.File(self.path("other.pam5"), "w") as f:
            f.create_dataset("x", data=np.arange(10))
        cases["other.pam5"] = None
        for name in cases:
            with self.subTest(case=name):
                f = self.path(name)
                p = run("info", f, timeout=20)
                self.assert_clean_error(p, name)
                self.assertNotIn("move it out", p.stderr, "the file is damaged, not the plugin")
                self.assert_clean_error(run("convert", f, self.path("x.nii"), timeout=20), name)
                self.assertFalse(os.path.exists(self.path("x.nii")))
                p = run("render", f, "-o", self.path("x.png"), env=NO_DISPLAY, timeout=60)
                self.assert_clean_error(p, name)
                self.assertFalse(os.path.exists(self.path("x.png")))

    @unittest.skipUnless(shutil.which("xvfb-run") or os.environ.get("CI"), "xvfb-run is not installed")
    def test_the_window_moves_the_peaks_slices(self):
        """The slicer's `slice I z MM` on a peaks object: the glyphs of that
        slice, as a render of a scene file with that slice draws them; a
        position outside the grid is one line naming the object."""
        rng = np.random.default_rng(8)
        dirs, vals = random_peaks(rng, (10, 10, 6), 2)
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-9, -9, -5]
        save_pam5(self.path("p.pam5"), dirs, vals, aff)

        def scene(name, **keys):
            with open(self.path(name), "w") as f:
                json.dump({"objects": [{"type": "peaks", "file": "p.pam5", **keys}], "camera": {"view": "superior"},
                           "environment": {"type": "none"}}, f)
            return self.path(name)
        script = self.path("s.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", "slice 0 z 3", "slice 0 x off", "slice 0 y off", "wait 1",
                               f"screenshot {self.path('w.png')}", "slice 0 z 500", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", scene("v.json"), "--size", "320x240", "--aa-frames", "1", "--script", script], env)
        self.assertNotEqual(p.returncode, 0, "z = 500 mm is outside the grid: the script stops there")
        self.assertIn("outside the volume", p.stderr)
        want, _ = self.render(scene("r.json", z=3), "r.png", "--aa-frames", "1")
        other, _ = self.render(scene("o.json", z=-3), "o.png", "--aa-frames", "1")
        w = load(self.path("w.png"))
        self.assertLess((np.abs(w - want).sum(axis=-1) > 30).mean(), 0.005)
        self.assertGreater((np.abs(w - other).sum(axis=-1) > 30).mean(), 0.01)


def lobes_sh(shape, direction_of, basis, order=8, legacy=True, sharpness=6):
    """SH coefficients (DIPY's sf_to_sh) of ODFs of one lobe along
    direction_of(x, y, z) a voxel."""
    import warnings
    from dipy.data import get_sphere
    from dipy.reconst.shm import sf_to_sh
    sphere = get_sphere("repulsion724")
    sf = np.zeros(shape + (len(sphere.vertices),))
    for ijk in np.ndindex(shape):
        d = np.asarray(direction_of(*ijk), float)
        sf[ijk] = np.exp(sharpness * ((sphere.vertices @ (d / np.linalg.norm(d))) ** 2 - 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sf_to_sh(sf, sphere, sh_order=order, basis_type=basis, legacy=legacy).astype(np.float32)


class OdfTest(TempDirTest):
    def render(self, src, out, *args, size="400x300"):
        p = run("render", src, "-o", self.path(out), "--size", size, "--force", "--json", *args, env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return load(self.path(out)), json.loads(p.stdout)

    def test_glyphs_show_each_odfs_lobe_in_its_basis(self):
        """One axial slice of single-lobe ODFs, along x on the left and y on
        the right, seen from above: left glyphs long across and red, right
        ones long upwards and green, each as long as the voxel is wide (scale
        1) or half (scale 0.5); the same ODFs written in tournier07, in
        MRtrix3's basis and in descoteaux07 without legacy draw the same
        picture with the matching --sh-basis."""
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-11, -11, 0]
        along = lambda x, y, z: (1, 0, 0) if x < 6 else (0, 1, 0)
        cases = {"d.nii.gz": ("descoteaux07", True, ()), "t.nii.gz": ("tournier07", True, ("--sh-basis", "tournier07")),
                 "m.nii.gz": ("tournier07", False, ("--sh-basis", "mrtrix3")),
                 "n.nii.gz": ("descoteaux07", False, ("--sh-not-legacy",))}
        pictures = {}
        for name, (basis, legacy, flags) in cases.items():
            nib.save(nib.Nifti1Image(lobes_sh((12, 12, 1), along, basis, legacy=legacy), aff), self.path(name))
            pictures[name], stats = self.render(self.path(name), name + ".png", "--odfs", "--view", "superior", *flags)
        ref = pictures["d.nii.gz"]
        for name, pic in pictures.items():
            self.assertLess(np.abs(pic - ref).max(), 40, name)
            self.assertLess((np.abs(pic - ref).sum(axis=-1) > 30).mean(), 0.002, name)
        background = ref[2, 2]
        lit = np.abs(ref - background).sum(axis=-1) > 60
        cols = np.nonzero(lit.any(axis=0))[0]
        mid = (cols.min() + cols.max()) // 2
        left, right = ref[:, :mid][lit[:, :mid]], ref[:, mid + 1:][lit[:, mid + 1:]]
        self.assertGreater(left[:, 0].mean(), 1.3 * max(left[:, 1].mean(), left[:, 2].mean()), "x lobes are red")
        self.assertGreater(right[:, 1].mean(), 1.3 * max(right[:, 0].mean(), right[:, 2].mean()), "y lobes are green")

        def lengths(pic):
            """The glyphs of one row on the left: their widths over the spacing of their centres."""
            on = np.abs(pic - background).sum(axis=-1) > 60
            rows = np.nonzero(on[:, :mid].any(axis=1))[0]
            best = max(rows, key=lambda r: on[r, :mid].sum())
            runs, start = [], None
            for c, v in enumerate(np.append(on[best, :mid], False)):
                if v and start is None:
                    start = c
                elif not v and start is not None:
                    runs.append((start, c))
                    start = None
            return runs
        runs = lengths(ref)
        self.assertGreaterEqual(len(runs), 4, runs)
        centres = np.array([(a + b) / 2 for a, b in runs])
        spacing = np.median(np.diff(centres))
        widths = np.array([b - a for a, b in runs])
        self.assertAlmostEqual(np.median(widths) / spacing, 1.0, delta=0.2)
        half, _ = self.render(self.path("d.nii.gz"), "h.png", "--odfs", "--view", "superior", "--odf-scale", "0.5")
        hw = np.array([b - a for a, b in lengths(half)])
        self.assertAlmostEqual(np.median(hw) / spacing, 0.5, delta=0.15)

    def test_scene_odfs_and_wrong_layouts(self):
        """A scene's odfs object (basis, sphere, normalise); 7 values a voxel,
        an unknown basis, a 3D volume: one line each, nothing written; the
        window's slicer moves the glyphs as a scene file with that slice draws
        them."""
        aff = np.eye(4)
        nib.save(nib.Nifti1Image(lobes_sh((6, 6, 4), lambda x, y, z: (x, y + 1, z), "descoteaux07", order=4), aff), self.path("o.nii.gz"))
        nib.save(nib.Nifti1Image(np.ones((4, 4, 4, 7), np.float32), aff), self.path("seven.nii.gz"))
        nib.save(nib.Nifti1Image(np.ones((4, 4, 4), np.float32), aff), self.path("flat.nii.gz"))
        cases = {
            "seven.json": ({"type": "odfs", "file": "seven.nii.gz"}, "not the coefficients of an even-order SH series"),
            "basis.json": ({"type": "odfs", "file": "o.nii.gz", "basis": "mrtrix"}, "basis"),
            "flat.json": ({"type": "odfs", "file": "flat.nii.gz"}, "4th dimension"),
            "norm.json": ({"type": "odfs", "file": "o.nii.gz", "normalise": "sum"}, "normalise"),
        }
        scene_errors(self, cases)
        p = run("render", self.path("seven.nii.gz"), "--odfs", "-o", self.path("x.png"), env=NO_DISPLAY, timeout=60)
        self.assert_clean_error(p, "seven.nii.gz")

        def scene(name, **keys):
            with open(self.path(name), "w") as f:
                json.dump({"objects": [{"type": "odfs", "file": "o.nii.gz", "sphere": 1, **keys}], "camera": {"view": "superior"},
                           "environment": {"type": "none"}}, f)
            return self.path(name)
        a, sa = self.render(scene("a.json", z=1), "a.png")
        b, _ = self.render(scene("b.json", z=1, normalise="none"), "b.png")
        self.assertGreater(np.abs(a - b).mean(), 0.5, "normalise changes the glyphs")
        if not (shutil.which("xvfb-run") or os.environ.get("CI")):
            return
        script = self.path("s.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", "slice 0 z 2", "wait 1", f"screenshot {self.path('w.png')}", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        p = xvfb_run([HORIZON, "view", scene("v.json", z=1), "--size", "400x300", "--aa-frames", "1", "--script", script], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        want, _ = self.render(scene("r.json", z=2), "r.png", "--aa-frames", "1")
        w = load(self.path("w.png"))
        self.assertLess((np.abs(w - want).sum(axis=-1) > 30).mean(), 0.01)
        self.assertGreater((np.abs(w - a).sum(axis=-1) > 30).mean(), 0.01)

    def test_odfs_while_moving_are_drawn_on_the_icosahedron(self):
        """Level of detail for ODF glyphs in the window (issue 55): while the
        camera moves, the field a level coarser (a glyph for each 2 x 2 x 2
        voxels, their mean ODF) is drawn on the icosahedron (20 triangles
        instead of the default sphere's 320), and at rest every glyph again;
        after the slicer moves the glyphs too."""
        sh = lobes_sh((40, 40, 3), lambda x, y, z: (x, y + 1, z), "descoteaux07", order=8)
        sh[:10, :, 2] = 0  # (no glyph: the slice z = 2 has 1200)
        nib.save(nib.Nifti1Image(sh, np.eye(4)), self.path("o8.nii.gz"))
        with open(self.path("odf.json"), "w") as f:
            json.dump({"objects": [{"type": "odfs", "file": "o8.nii.gz", "z": 1}], "camera": {"view": "superior"},
                       "environment": {"type": "none"}}, f)
        script = self.path("s.txt")
        with open(script, "w") as f:
            f.write("\n".join(["wait 1", "drag 100 100 250 140", "sleep 1", "wait 2", "mark sliced", "slice 0 z 2", "wait 1",
                               "drag 100 100 250 140", "sleep 1", "wait 2", "quit"]) + "\n")
        env = {**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"}
        if "ASAN_OPTIONS" in env:
            env["ASAN_OPTIONS"] += ":detect_leaks=0"
        stats = self.path("stats.json")
        p = xvfb_run([HORIZON, "view", self.path("odf.json"), "--size", "400x300", "--script", script, "--stats", stats], env)
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(stats) as f:
            frames = json.load(f)["frames"]
        cut = next(i for i, f in enumerate(frames) if f.get("kind") == "mark")
        # (z = 1: 40 x 40 glyphs, the coarser field's 20 x 20; z = 2 has none
        # for x < 10: 30 x 40, the coarser 15 x 20)
        for part, glyphs, coarser in ((frames[:cut], 40 * 40, 20 * 20), (frames[cut + 1:], 30 * 40, 15 * 20)):
            moving = [f["triangles"] for f in part if f["kind"] == "moving"]
            still = [f["triangles"] for f in part if f["kind"] == "complete"]
            self.assertTrue(moving and still, part)
            self.assertEqual(set(moving), {coarser * 20})
            self.assertEqual(set(still), {glyphs * 320})


def srgb8(c):
    c = np.clip(c, 0, 1)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055) * 255


class TensorTest(TempDirTest):
    def test_ellipsoids_in_dipys_colours_and_every_order(self):
        """Random tensors written as DIPY writes them (a symmetric-matrix
        NIfTI, 5D) seen from above with flat shading and no tone curve: each
        glyph's centre pixel is DIPY's color_fa of its voxel; the same tensors
        in FSL's and MRtrix3's orders (--tensor-order) draw the same picture;
        a wrong count and an unknown order are one line, nothing written."""
        from scipy import ndimage
        from dipy.io.utils import nifti1_symmat
        from dipy.reconst.dti import color_fa, decompose_tensor, fractional_anisotropy, lower_triangular
        rng = np.random.default_rng(10)
        X, Y = 8, 6
        D = np.zeros((X, Y, 1, 3, 3))
        for ijk in np.ndindex(X, Y, 1):
            q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
            D[ijk] = q @ np.diag(np.sort(rng.uniform(0.2, 2, 3))[::-1] * 1e-3) @ q.T
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-7, -5, 0]
        lt = lower_triangular(D)
        nib.save(nifti1_symmat(lt, aff), self.path("dipy.nii.gz"))
        xx, xy, yy, xz, yz, zz = (lt[..., k] for k in range(6))
        nib.save(nib.Nifti1Image(np.stack([xx, xy, xz, yy, yz, zz], -1).astype(np.float32), aff), self.path("fsl.nii.gz"))
        nib.save(nib.Nifti1Image(np.stack([xx, yy, zz, xy, xz, yz], -1).astype(np.float32), aff), self.path("mrtrix3.nii.gz"))
        evals, evecs = decompose_tensor(D)
        want = color_fa(fractional_anisotropy(evals), evecs)[:, :, 0]

        def render(name, *flags):
            with open(self.path(name + ".json"), "w") as f:
                json.dump({"objects": [{"type": "tensors", "file": name + ".nii.gz", "z": 0, "material": "flat", "scale": 0.6}],
                           "camera": {"view": "superior"}, "environment": {"type": "none"}, "tonemap": "none",
                           "background": [0, 0, 0], "antialiasing": {"on": False}}, f)
            p = run("render", self.path(name + ".json"), "-o", self.path(name + ".png"), "--size", "640x480", *flags, env=NO_DISPLAY,
                    timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            return load(self.path(name + ".png"))
        pic = render("dipy")
        for order in ("fsl", "mrtrix3"):
            np.testing.assert_array_equal(render(order, "--tensor-order", order), pic, err_msg=order)
        labels, n = ndimage.label(pic.sum(axis=-1) > 0)
        self.assertEqual(n, X * Y)
        centres = sorted(ndimage.center_of_mass(np.ones(labels.shape), labels, range(1, n + 1)))  # (top row first)
        errors = []
        for j in range(Y):
            row = sorted(centres[j * X:(j + 1) * X], key=lambda c: c[1])
            for i, (r, c) in enumerate(row):
                errors.append(np.abs(pic[int(round(r)), int(round(c))] - srgb8(want[i, Y - 1 - j])).max())
        self.assertLess(np.median(errors), 2, errors)
        self.assertLess(max(errors), 8, errors)
        nib.save(nib.Nifti1Image(np.ones((3, 3, 3, 5), np.float32), aff), self.path("five.nii.gz"))
        scene_errors(self, {
            "five.json": ({"type": "tensors", "file": "five.nii.gz"}, "5 values a voxel"),
            "order.json": ({"type": "tensors", "file": "dipy.nii.gz", "order": "afni"}, "order"),
        })
        p = run("render", self.path("five.nii.gz"), "--tensors", "-o", self.path("x.png"), env=NO_DISPLAY, timeout=60)
        self.assert_clean_error(p, "five.nii.gz")
        self.assertFalse(os.path.exists(self.path("x.png")))


class ConnectomeTest(TempDirTest):
    def scene(self, name, ob, **settings):
        with open(self.path(name), "w") as f:
            json.dump({"objects": [ob], "camera": {"view": "superior"}, "environment": {"type": "none"}, **settings}, f)
        return self.path(name)

    def render(self, scene, out):
        p = run("render", scene, "-o", self.path(out), "--size", "400x300", "--force", "--json", env=NO_DISPLAY, timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        return load(self.path(out)), json.loads(p.stdout)

    def test_brainnet_and_csv_files(self):
        """BrainNet Viewer's .node (comments, labels, '-') and .edge files: the
        edges drawn are those of |weight| above the threshold (numpy's count;
        an asymmetric matrix counts each pair once); the same network as CSV
        files (a header row, commas) draws the same picture."""
        rng = np.random.default_rng(11)
        N = 10
        ang = np.linspace(0, 2 * np.pi, N, endpoint=False)
        xyz = np.c_[40 * np.cos(ang), 60 * np.sin(ang), 5 * np.sin(3 * ang)]
        W = rng.normal(size=(N, N))
        W[3, 7], W[7, 3] = 0.1, -2.5  # (asymmetric: the larger magnitude)
        with open(self.path("a.node"), "w") as f:
            f.write("# x y z colour size label\n")
            for i, (x, y, z) in enumerate(xyz):
                f.write(f"{x:.3f}\t{y:.3f}\t{z:.3f}\t{i % 3 + 1}\t{1 + i % 2}\t{'-' if i == 0 else 'N%d' % i}\n")
        np.savetxt(self.path("a.edge"), W, fmt="%.5f", delimiter="\t")
        with open(self.path("a.csv"), "w") as f:
            f.write("x,y,z,colour,size\n")
            for i, (x, y, z) in enumerate(xyz):
                f.write(f"{x:.3f},{y:.3f},{z:.3f},{i % 3 + 1},{1 + i % 2}\n")
        np.savetxt(self.path("w.csv"), W, fmt="%.5f", delimiter=",")
        Wr = np.round(W, 5)
        pair = np.maximum(np.abs(Wr), np.abs(Wr.T))[np.triu_indices(N, 1)]
        for threshold in (0.0, 0.7, 1.5):
            with self.subTest(threshold=threshold):
                a, sa = self.render(self.scene("b.json", {"type": "connectome", "nodes": "a.node", "edges": "a.edge", "threshold": threshold}), "b.png")
                self.assertEqual(sa["streamlines_drawn"], int((pair > threshold).sum()))
                c, _ = self.render(self.scene("c.json", {"type": "connectome", "nodes": "a.csv", "edges": "w.csv", "threshold": threshold}), "c.png")
                np.testing.assert_array_equal(a, c)
        _, nodes_only = self.render(self.scene("n.json", {"type": "connectome", "nodes": "a.node"}), "n.png")
        self.assertEqual(nodes_only["streamlines_drawn"], 0)
        # From the command line: `render a.node a.edge` is that scene's connectome.
        with open(self.path("d.json"), "w") as f:
            json.dump({"objects": [{"type": "connectome", "nodes": "a.node", "edges": "a.edge"}]}, f)
        scene, _ = self.render(self.path("d.json"), "d.png")
        p = run("render", self.path("a.node"), self.path("a.edge"), "-o", self.path("f.png"), "--size", "400x300", env=NO_DISPLAY,
                timeout=120)
        self.assertEqual(p.returncode, 0, p.stderr)
        np.testing.assert_array_equal(load(self.path("f.png")), scene)

    def test_sizes_and_weights_set_spheres_and_tubes(self):
        """Two nodes of sizes 1 and 3 (node_scale 2: radii 2 and 6 mm) and two
        edges of weights 1 and 0.25 (edge_radius 2): the spheres' and the
        tubes' widths on the picture in those ratios."""
        with open(self.path("s.node"), "w") as f:
            f.write("-40 0 0 1 1 a\n40 0 0 1 3 b\n-40 50 0 1 0.01 c\n40 50 0 1 0.01 d\n")
        W = np.zeros((4, 4))
        W[0, 1] = W[1, 0] = 1.0
        W[2, 3] = W[3, 2] = 0.25
        np.savetxt(self.path("s.edge"), W)
        pic, stats = self.render(self.scene("s.json", {"type": "connectome", "nodes": "s.node", "edges": "s.edge", "node_scale": 2,
                                                       "edge_radius": 2, "material": "flat"}, background=[0, 0, 0]), "s.png")
        self.assertEqual(stats["streamlines_drawn"], 2)
        lit = pic.sum(axis=-1) > 20
        w = pic.shape[1]
        # Tubes: their thickness in the middle column (y = 0 lower, y = 50 upper in the superior view).
        runs = np.nonzero(lit[:, w // 2])[0]
        groups = np.split(runs, np.nonzero(np.diff(runs) > 1)[0] + 1)
        self.assertEqual(len(groups), 2, groups)
        thin, thick = sorted(len(g) for g in groups)
        self.assertAlmostEqual(thick / thin, 4, delta=1.2)
        # Spheres: the tallest lit run of any column in each half (the tubes across them are thinner).
        def tallest(half):
            best = 0
            for col in half.T:
                ys = np.nonzero(col)[0]
                if len(ys):
                    best = max(best, max(len(g) for g in np.split(ys, np.nonzero(np.diff(ys) > 1)[0] + 1)))
            return best
        self.assertAlmostEqual(tallest(lit[:, w // 2 + 1:]) / tallest(lit[:, :w // 2]), 3, delta=0.5)

    def test_a_parcellation_gives_the_nodes(self):
        """A label volume (labels 3, 8, 20, 41; an oblique affine) as the
        nodes: one per label in increasing order at the centroid of its
        voxels (numpy and the affine here), the matrix's rows in that order:
        the same picture as a .node file of those centroids; a volume
        without labels is one line."""
        rng = np.random.default_rng(12)
        labels = np.zeros((20, 18, 16), np.int16)
        for value, (x, y, z), (a, b, c) in zip((41, 3, 20, 8), ((2, 3, 4), (12, 2, 1), (5, 11, 9), (13, 12, 10)),
                                               ((5, 4, 3), (2, 6, 2), (6, 2, 5), (3, 3, 4))):
            labels[x:x + a, y:y + b, z:z + c] = value  # (regions of different shapes: their centroids not one shift from their corners)
            labels[x, y, z + 5] = value  # (a stray voxel moves the centroid)
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        aff = np.eye(4)
        aff[:3, :3] = q * 3
        aff[:3, 3] = [-20, 10, 5]
        nib.save(nib.Nifti1Image(labels, aff), self.path("parc.nii.gz"))
        W = np.array([[0, 1, 0.2, 0], [1, 0, 0, 0.8], [0.2, 0, 0, 0.5], [0, 0.8, 0.5, 0]])
        np.savetxt(self.path("m.csv"), W, delimiter=",")
        with open(self.path("c.node"), "w") as f:
            for v in sorted(np.unique(labels[labels > 0])):
                ijk = np.argwhere(labels == v).mean(axis=0)
                x, y, z = aff[:3, :3] @ ijk + aff[:3, 3]
                f.write(f"{x:.6f} {y:.6f} {z:.6f} {v} 1 L{v}\n")
        a, sa = self.render(self.scene("p.json", {"type": "connectome", "nodes": "parc.nii.gz", "edges": "m.csv", "node_scale": 3}), "p.png")
        b, _ = self.render(self.scene("n.json", {"type": "connectome", "nodes": "c.node", "edges": "m.csv", "node_scale": 3}), "n.png")
        self.assertEqual(sa["streamlines_drawn"], 4)
        self.assertLess((np.abs(a - b).sum(axis=-1) > 30).mean(), 0.001)
        nib.save(nib.Nifti1Image(np.zeros((4, 4, 4), np.int16), np.eye(4)), self.path("empty.nii.gz"))
        scene_errors(self, {"empty.json": ({"type": "connectome", "nodes": "empty.nii.gz"}, "no label above 0")})

    def test_files_that_disagree(self):
        """Matrix rows or columns that are not the node count, a value that is
        not a number, a node of two values, a negative size, no nodes key:
        one line naming the scene and the file at fault, nothing written."""
        files = {"g.node": "0 0 0 1 1 a\n10 0 0 1 1 b\n0 10 0 1 1 c\n", "rows.edge": "0 1 1\n1 0 1\n", "cols.edge": "0 1 1\n1 0\n1 1 0\n",
                 "nan.edge": "0 1 1\n1 x 1\n1 1 0\n", "short.node": "0 0 0\n1 2\n", "neg.node": "0 0 0 1 -2 a\n"}
        for name, text in files.items():
            with open(self.path(name), "w") as f:
                f.write(text)
        scene_errors(self, {
            "rows.json": ({"type": "connectome", "nodes": "g.node", "edges": "rows.edge"}, "rows.edge: 2 rows, the node file g.node has 3 nodes"),
            "cols.json": ({"type": "connectome", "nodes": "g.node", "edges": "cols.edge"}, "cols.edge: line 2: 2 values"),
            "nan.json": ({"type": "connectome", "nodes": "g.node", "edges": "nan.edge"}, "nan.edge: line 2, column 2: 'x' is not a finite number"),
            "short.json": ({"type": "connectome", "nodes": "short.node"}, "short.node: line 2: 2 values"),
            "neg.json": ({"type": "connectome", "nodes": "neg.node"}, "negative"),
            "none.json": ({"type": "connectome", "edges": "rows.edge"}, "needs 'nodes'"),
            "missing.json": ({"type": "connectome", "nodes": "nowhere.node"}, "nowhere.node"),
        })


if __name__ == "__main__":
    unittest.main()
