"""FreeSurfer MGH/MGZ volumes through `horizon`, compared with nibabel:
dimensions, voxel types and values, the voxel-to-RAS affine (FreeSurfer's
direction cosines, voxel sizes and centre), the scan parameters; written
files read back by nibabel; nibabel's own test.mgz; malformed files fail
in one line, gzip bombs and absurd sizes without large allocations."""
import gzip
import os
import struct
import subprocess
import unittest
import zlib

import nibabel as nib
import numpy as np
from nibabel.freesurfer.mghformat import MGHImage

from hztest import HORIZON, TempDirTest, run, run_json
from test_nifti import random_affine

NIBABEL_TEST_MGZ = os.path.join(os.path.dirname(nib.__file__), "tests", "data", "test.mgz")


class MghTest(TempDirTest):
    def convert(self, src, name):
        out = self.path(name)
        p = run("convert", src, out, "--force")
        self.assertEqual(p.returncode, 0, p.stderr)
        return nib.load(out)

    def test_reads_as_nibabel_does(self):
        """Every MGH voxel type, 3D and 4D, .mgh and .mgz, oblique affines:
        `info` gives nibabel's dimensions and affine, and the voxels
        converted to NIfTI are nibabel's."""
        rng = np.random.default_rng(11)
        for i, dt in enumerate((np.uint8, np.int16, np.int32, np.float32)):
            for ext in ("mgh", "mgz"):
                with self.subTest(dtype=np.dtype(dt).name, ext=ext):
                    shape = (5, 6, 7) if i % 2 else (5, 6, 7, 3)
                    data = (rng.random(shape) * 200 - (0 if dt == np.uint8 else 100)).astype(dt)
                    f = self.path(f"v{i}.{ext}")
                    img = MGHImage(data, random_affine(rng))
                    img.header["tr"], img.header["te"], img.header["flip_angle"] = 2300.0, 2.98, 0.157
                    nib.save(img, f)
                    src = nib.load(f)
                    info = run_json("info", f, "--json")
                    self.assertEqual(info["dims"], list(shape))
                    np.testing.assert_allclose(np.array(info["affine"]), src.affine, atol=1e-4)
                    meta = dict(info["header"])
                    self.assertAlmostEqual(float(meta["tr"]), 2300.0, places=3)
                    self.assertAlmostEqual(float(meta["flip_angle"]), 0.157, places=5)
                    ours = self.convert(f, f"v{i}.nii.gz")
                    np.testing.assert_array_equal(ours.get_fdata(), src.get_fdata())
                    self.assertEqual(ours.get_data_dtype(), np.dtype(dt))
                    np.testing.assert_allclose(ours.affine, src.affine, atol=1e-4)

    def test_nibabel_test_mgz(self):
        src = nib.load(NIBABEL_TEST_MGZ)
        info = run_json("info", NIBABEL_TEST_MGZ, "--json")
        self.assertEqual(info["dims"], list(src.shape))
        np.testing.assert_allclose(np.array(info["affine"]), src.affine, atol=1e-5)
        ours = self.convert(NIBABEL_TEST_MGZ, "t.nii")
        np.testing.assert_array_equal(ours.get_fdata(), src.get_fdata())
        # Written back as MGZ: nibabel reads the same volume, affine and TR.
        back = self.convert(NIBABEL_TEST_MGZ, "t.mgz")
        np.testing.assert_array_equal(back.get_fdata(), src.get_fdata())
        np.testing.assert_allclose(back.affine, src.affine, atol=1e-5)
        self.assertAlmostEqual(float(back.header["tr"]), float(src.header["tr"]), places=5)

    def test_writes_what_nibabel_reads(self):
        """NIfTI volumes of any type written as MGZ/MGH: nibabel reads the
        values (scaled ones as float32), widened types where MGH lacks
        them, and the affine."""
        rng = np.random.default_rng(12)
        cases = [(np.uint8, np.uint8, 1, 0), (np.int16, np.int16, 1, 0), (np.int32, np.int32, 1, 0), (np.float32, np.float32, 1, 0),
                 (np.int8, np.int16, 1, 0), (np.uint16, np.int32, 1, 0), (np.float64, np.float32, 1, 0), (np.int16, np.float32, 0.5, 10)]
        for k, (dt, stored, slope, inter) in enumerate(cases):
            for ext in ("mgz", "mgh"):
                with self.subTest(dtype=np.dtype(dt).name, ext=ext, slope=slope):
                    shape = (4, 5, 6) if k % 2 else (4, 5, 6, 2)
                    data = (rng.random(shape) * 100).astype(dt)
                    img = nib.Nifti1Image(data, random_affine(rng), dtype=dt)
                    if slope != 1:
                        img.header.set_slope_inter(slope, inter)
                    src_path = self.path(f"s{k}.nii")
                    nib.save(img, src_path)
                    src = nib.load(src_path)
                    ours = self.convert(src_path, f"o{k}.{ext}")
                    self.assertEqual(ours.get_data_dtype(), np.dtype(stored).newbyteorder(">"))
                    np.testing.assert_allclose(ours.get_fdata(), src.get_fdata(), rtol=1e-6)
                    np.testing.assert_allclose(ours.affine, src.affine, atol=1e-4)
                    if ext == "mgz":
                        with open(self.path(f"o{k}.mgz"), "rb") as fh:
                            self.assertEqual(fh.read(2), b"\x1f\x8b")

    def test_slices_of_an_mgz_render(self):
        data = np.zeros((32, 32, 32), np.uint8)
        data[8:24, 8:24, 8:24] = 200
        nib.save(MGHImage(data, np.diag([2.0, 2.0, 2.0, 1.0])), self.path("T1.mgz"))
        out = self.path("s.png")
        p = run("render", self.path("T1.mgz"), "-o", out, "--size", "200x200", "--force")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertTrue(os.path.getsize(out) > 0)

    def test_malformed(self):
        data = (np.arange(6 * 7 * 8) % 251).astype(np.uint8).reshape(6, 7, 8)
        nib.save(MGHImage(data, np.eye(4)), self.path("good.mgh"))
        with open(self.path("good.mgh"), "rb") as fh:
            good = fh.read()

        def patched(off, fmt, value):
            b = bytearray(good)
            b[off:off + struct.calcsize(fmt)] = struct.pack(fmt, value)
            return bytes(b)
        cases = {
            "truncated_data.mgh": good[:284 + 100],
            "truncated_header.mgh": good[:60],
            "version_2.mgh": patched(0, ">i", 2),
            "type_7.mgh": patched(20, ">i", 7),
            "zero_dim.mgh": patched(8, ">i", 0),
            "negative_dim.mgh": patched(4, ">i", -6),
            "absurd_dims.mgh": patched(4, ">i", 2 ** 31 - 1)[:4 + 4] + struct.pack(">i", 2 ** 31 - 1) + patched(4, ">i", 2 ** 31 - 1)[12:],
            "zero_voxel_size.mgh": patched(30, ">f", 0.0),
            "nan_cosines.mgh": patched(42, ">f", float("nan")),
            "truncated.mgz": gzip.compress(good[:284 + 50]),
            "truncated_stream.mgz": gzip.compress(good)[:-40],
            "absurd_dims.mgz": gzip.compress(patched(4, ">i", 2 ** 20)[:300]),
        }
        corrupt = bytearray(gzip.compress(good))
        for i in range(40, 70):
            corrupt[i] ^= 0xA5
        cases["corrupt_stream.mgz"] = bytes(corrupt)
        for name, blob in cases.items():
            with self.subTest(case=name):
                f = self.path(name)
                with open(f, "wb") as fh:
                    fh.write(blob)
                self.assert_clean_error(run("info", f, timeout=10), name)
                self.assert_clean_error(run("convert", f, self.path("x.nii"), timeout=10), name)
                self.assertFalse(os.path.exists(self.path("x.nii")))

    def test_gzip_bomb_costs_what_it_declares(self):
        """An MGZ of 2x2x2 voxels followed by 1 GiB of zeros (1 MB
        compressed): read in well under a second, the zeros never inflated;
        one that declares 2^40 voxels but holds a few: an error, memory
        bounded by what the stream holds."""
        data = np.ones((2, 2, 2), np.uint8)
        nib.save(MGHImage(data, np.eye(4)), self.path("small.mgh"))
        with open(self.path("small.mgh"), "rb") as fh:
            small = fh.read()
        comp = zlib.compressobj(9, zlib.DEFLATED, 31)
        blob = [comp.compress(small)]
        zeros = bytes(1 << 24)
        for _ in range(64):
            blob.append(comp.compress(zeros))
        blob.append(comp.flush())
        with open(self.path("bomb.mgz"), "wb") as fh:
            fh.write(b"".join(blob))
        info = run_json("info", self.path("bomb.mgz"), "--json", timeout=10)
        self.assertEqual(info["dims"], [2, 2, 2])
        p = subprocess.run(["/usr/bin/time", "-f", "%M", HORIZON, "convert", self.path("bomb.mgz"), self.path("bomb.nii")],
                           capture_output=True, text=True, timeout=20)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertLess(int(p.stderr.strip().splitlines()[-1]), 400_000, "peak memory in KB: the zeros were inflated")
        big = bytearray(small)
        big[4:16] = struct.pack(">iii", 2 ** 14, 2 ** 13, 2 ** 13)  # 2^40 voxels
        with open(self.path("declares.mgz"), "wb") as fh:
            fh.write(gzip.compress(bytes(big)))
        p = subprocess.run(["/usr/bin/time", "-f", "%M", HORIZON, "info", self.path("declares.mgz")], capture_output=True, text=True,
                           timeout=20)
        self.assertNotEqual(p.returncode, 0)
        lines = p.stderr.strip().splitlines()
        self.assertIn("declares.mgz", lines[0])
        self.assertLess(int(lines[-1]), 400_000, "peak memory in KB")


if __name__ == "__main__":
    unittest.main()
