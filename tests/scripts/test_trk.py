"""TrackVis TRK through `horizon`, compared with nibabel's reading (RAS+ mm,
1e-3 mm) on nibabel's own test files and on files nibabel writes with
random oblique and LPS affines; malformed files fail cleanly."""
import os
import struct

import nibabel as nib
import numpy as np
from nibabel.affines import from_matvec
from nibabel.streamlines import Field
from nibabel.streamlines.trk import TrkFile

from hztest import TempDirTest, random_streamlines, run, run_json

NIB_DATA = os.path.join(os.path.dirname(nib.__file__), "tests", "data")


def rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    a, b, c, d = q
    return np.array([[a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
                     [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
                     [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d]])


class TrkTest(TempDirTest):
    def horizon_streamlines(self, f):
        out = self.path("out_%d.tck" % len(os.listdir(self.tmp)))
        p = run("convert", f, out)
        self.assertEqual(p.returncode, 0, p.stderr)
        return list(nib.streamlines.load(out).streamlines)

    def assert_close(self, got, want, tol=1e-3):
        self.assertEqual(len(got), len(want))
        for a, b in zip(got, want):
            self.assertEqual(len(a), len(b))
            if len(a):
                self.assertLessEqual(np.abs(np.asarray(a, float) - np.asarray(b, float)).max(), tol)

    def test_nibabel_test_data(self):
        for name in ["empty.trk", "simple.trk", "complex.trk", "complex_big_endian.trk", "standard.trk", "standard.LPS.trk"]:
            with self.subTest(file=name):
                f = os.path.join(NIB_DATA, name)
                ref = nib.streamlines.load(f)
                self.assert_close(self.horizon_streamlines(f), list(ref.streamlines))
                info = run_json("info", f, "--json")
                self.assertEqual(info["nb_streamlines"], len(ref.streamlines))

    def test_scalars_and_properties_survive_trk_to_trk(self):
        for name in ["complex.trk", "complex_big_endian.trk"]:
            with self.subTest(file=name):
                f = os.path.join(NIB_DATA, name)
                ref = nib.streamlines.load(f)
                out = self.path("copy.trk")
                p = run("convert", f, out, "--force")
                self.assertEqual(p.returncode, 0, p.stderr)
                back = nib.streamlines.load(out)
                self.assert_close(list(back.streamlines), list(ref.streamlines))
                self.assertEqual(set(back.tractogram.data_per_point), set(ref.tractogram.data_per_point))
                for k in ref.tractogram.data_per_point:
                    np.testing.assert_allclose(back.tractogram.data_per_point[k]._data, ref.tractogram.data_per_point[k]._data)
                for k in ref.tractogram.data_per_streamline:
                    np.testing.assert_allclose(back.tractogram.data_per_streamline[k], ref.tractogram.data_per_streamline[k])
                # TCK cannot hold them: reported, not silently dropped.
                p = run("convert", f, self.path("x.tck"), "--force")
                self.assertIn("dropped", p.stderr)

    def test_random_affines(self):
        rng = np.random.default_rng(42)
        for trial in range(8):
            with self.subTest(trial=trial):
                vs = rng.uniform(0.5, 3.0, 3)
                flips = np.where(rng.random(3) < 0.5, -1.0, 1.0)
                R = rotation(rng) if trial % 2 else np.eye(3)
                aff = from_matvec(R @ np.diag(vs * flips), rng.uniform(-50, 50, 3))
                order = "".join(nib.aff2axcodes(aff))
                dims = rng.integers(20, 200, 3)
                sl = random_streamlines(40, rng, 1, 50)
                hdr = {Field.VOXEL_TO_RASMM: aff, Field.VOXEL_SIZES: vs, Field.DIMENSIONS: dims, Field.VOXEL_ORDER: order.encode()}
                f = self.path("r%d.trk" % trial)
                TrkFile(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), header=hdr).save(f)
                ref = list(nib.streamlines.load(f).streamlines)
                self.assert_close(self.horizon_streamlines(f), ref)
                # horizon's TRK writer, read back by nibabel.
                out = self.path("w%d.trk" % trial)
                self.assertEqual(run("convert", f, out).returncode, 0)
                back = nib.streamlines.load(out)
                self.assert_close(list(back.streamlines), ref)
                np.testing.assert_allclose(back.header[Field.VOXEL_TO_RASMM], aff, atol=1e-5)

    def test_voxel_orders_that_permute_the_axes(self):
        """Voxel orders that permute the axes, not only flip them (ASR, SAR,
        PIL, RSA, ILP, beside RAS and LPS), with a voxel-to-RAS affine that
        says the same, and as an old TrackVis file whose vox_to_ras is all
        zero (the voxel order and sizes alone): the streamlines nibabel
        reads, and a TRK that horizon writes back reads the same again."""
        from nibabel.orientations import axcodes2ornt
        rng = np.random.default_rng(17)
        sl = [(rng.normal(size=(int(n), 3)) * 12 + [5, -3, 8]).astype(np.float32) for n in rng.integers(2, 30, 12)]
        dims, sizes = np.array([60, 70, 50]), np.array([2.0, 1.5, 2.5])
        for order in ["RAS", "LPS", "ASR", "SAR", "PIL", "RSA", "ILP"]:
            aff = np.eye(4)
            aff[:3, :3] = 0
            for i, (axis, flip) in enumerate(axcodes2ornt(tuple(order))):
                aff[int(axis), i] = flip * sizes[i]
            aff[:3, 3] = -aff[:3, :3] @ (dims / 2)
            header = {"dimensions": dims.astype(np.int16), "voxel_sizes": sizes.astype(np.float32),
                      "voxel_to_rasmm": aff.astype(np.float32), "voxel_order": order}
            f = self.path(f"t_{order}.trk")
            TrkFile(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), header=header).save(f)
            old = self.path(f"old_{order}.trk")
            raw = bytearray(open(f, "rb").read())
            raw[440:504] = bytes(64)  # (vox_to_ras, 4x4 float32 at byte 440: unset)
            open(old, "wb").write(raw)
            for name in (f, old):
                with self.subTest(order=order, file=os.path.basename(name)):
                    import warnings
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        want = list(nib.streamlines.load(name).streamlines)
                    if name == f:
                        self.assert_close(want, sl)
                    self.assert_close(self.horizon_streamlines(name), want)
                    back = self.path(f"back_{order}_{len(os.listdir(self.tmp))}.trk")
                    self.assertEqual(run("convert", name, back).returncode, 0)
                    self.assert_close(list(nib.streamlines.load(back).streamlines), want)

    def test_decoded_positions_spilled_to_a_temporary_file(self):
        # Large decoded positions live in an unlinked file in the spill
        # folder (file-backed, reclaimable memory): the same streamlines as
        # in memory; an unusable folder falls back to memory; nothing is
        # left in the folder.
        rng = np.random.default_rng(8)
        sl = random_streamlines(300, rng, 2, 60)
        f = self.path("s.trk")
        nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), f)
        ref = list(nib.streamlines.load(f).streamlines)
        spill = self.path("spill")
        os.mkdir(spill)
        for where in (spill, self.path("absent"), "off"):
            out = self.path("s_%s.tck" % os.path.basename(where))
            p = run("convert", f, out, env={"HORIZON_SPILL_DIR": where, "HORIZON_SPILL_MIN_BYTES": "0", "HORIZON_TRACE": "1"})
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertEqual("decoded into a temporary file" in p.stderr, where == spill, p.stderr)
            self.assert_close(list(nib.streamlines.load(out).streamlines), ref)
        self.assertEqual(os.listdir(spill), [])
        # Without a temporary file, memory is used only where the kernel
        # reports that much available; otherwise one line says why, before
        # the decode, and nothing is written.
        out = self.path("s_nowhere.tck")
        for where in (self.path("absent"), "off"):
            env = {"HORIZON_SPILL_DIR": where, "HORIZON_SPILL_MIN_BYTES": "0", "HORIZON_MEMORY_AVAILABLE_MB": "0"}
            p = run("convert", f, out, env=env)
            self.assertEqual(p.returncode, 1, p.stderr)
            line = p.stderr.strip()
            self.assertNotIn("\n", line)
            self.assertIn(f"{f}: its decoded positions: ", line)
            self.assertIn("of memory are available (HORIZON_SPILL_DIR=DIR names a folder with room)", line)
            self.assertIn("no temporary file in " + where if where != "off" else "no temporary file (HORIZON_SPILL_DIR=off)", line)
            self.assertFalse(os.path.exists(out))
        p = run("convert", f, out, env={"HORIZON_SPILL_DIR": spill, "HORIZON_SPILL_MIN_BYTES": "0", "HORIZON_MEMORY_AVAILABLE_MB": "0"})
        self.assertEqual(p.returncode, 0, p.stderr)  # (a temporary file needs no memory)

    def test_tck_to_trk_to_tck(self):
        rng = np.random.default_rng(1)
        sl = random_streamlines(30, rng, 2, 40)
        f = self.path("a.tck")
        nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), f)
        self.assertEqual(run("convert", f, self.path("a.trk")).returncode, 0)
        self.assert_close(list(nib.streamlines.load(self.path("a.trk")).streamlines), sl)
        self.assert_close(self.horizon_streamlines(self.path("a.trk")), sl)

    def test_malformed(self):
        with open(os.path.join(NIB_DATA, "complex.trk"), "rb") as fh:
            good = fh.read()
        def patched(off, fmt, value):
            b = bytearray(good)
            b[off:off + struct.calcsize(fmt)] = struct.pack(fmt, value)
            return bytes(b)
        first_n = 1000  # the first record's point count
        cases = {
            "bad_magic.trk": b"TRICK" + good[5:],
            "bad_hdr_size.trk": patched(996, "<i", 999),
            "count_too_large.trk": patched(988, "<i", 1000),
            "negative_count.trk": patched(988, "<i", -4),
            "negative_points.trk": patched(first_n, "<i", -1),
            "absurd_points.trk": patched(first_n, "<i", 2 ** 30),
            "bad_version.trk": patched(992, "<i", 7),
            "zero_voxel.trk": patched(12, "<f", 0.0),
            "nan_point.trk": patched(first_n + 4, "<f", float("nan")),
            "bad_order.trk": good[:948] + b"XYZ\0" + good[952:],
            "short.trk": good[:500],
        }
        for name, data in cases.items():
            with self.subTest(case=name):
                f = self.path(name)
                with open(f, "wb") as fh:
                    fh.write(data)
                self.assert_clean_error(run("info", f, timeout=10), name)
        for cut in list(range(995, 1010)) + list(range(1010, len(good), 7)):
            with self.subTest(cut=cut):
                f = self.path("cut.trk")
                with open(f, "wb") as fh:
                    fh.write(good[:cut])
                self.assert_clean_error(run("info", f, timeout=10), "cut.trk")
