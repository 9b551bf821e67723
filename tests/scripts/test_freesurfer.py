"""FreeSurfer triangle surfaces through `horizon`, against nibabel's
read_geometry; conversions to and from GIFTI; malformed files."""
import struct
from collections import OrderedDict

import nibabel as nib
import nibabel.freesurfer as fs
import numpy as np

from hztest import TempDirTest, run, run_json


class FreeSurferTest(TempDirTest):
    def make(self, name, n=30, m=50, volume_info=True, seed=0):
        rng = np.random.default_rng(seed)
        v = (rng.normal(size=(n, 3)) * 40).astype(np.float32)
        f = rng.integers(0, n, size=(m, 3)).astype(np.int32)
        vi = None
        if volume_info:
            vi = OrderedDict(head=np.array([2, 0, 20], dtype=np.int32), valid="1  # volume info valid", filename="vol.nii",
                             volume=np.array([256, 256, 256]), voxelsize=np.array([1.0, 1.0, 1.0]), xras=np.array([-1.0, 0, 0]),
                             yras=np.array([0, 0, -1.0]), zras=np.array([0, 1.0, 0]), cras=np.array([1.5, -2.0, 3.25]))
        path = self.path(name)
        fs.write_geometry(path, v, f, volume_info=vi)
        return path

    def test_read_convert_and_back(self):
        for vi in (True, False):
            with self.subTest(volume_info=vi):
                src = self.make("lh.white", volume_info=vi, seed=int(vi))
                v, f = fs.read_geometry(src)
                info = run_json("info", src, "--json")
                self.assertEqual((info["nb_vertices"], info["nb_faces"]), (len(v), len(f)))
                out = self.path("rh.pial")
                self.assertEqual(run("convert", src, out, "--force").returncode, 0)
                v2, f2, meta = fs.read_geometry(out, read_metadata=True)
                np.testing.assert_array_equal(v2, v)
                np.testing.assert_array_equal(f2, f)
                if vi:
                    np.testing.assert_array_equal(meta["cras"], [1.5, -2.0, 3.25])
                # FreeSurfer -> GIFTI -> FreeSurfer keeps the geometry.
                gii, back = self.path("s.gii"), self.path("back.white")
                self.assertEqual(run("convert", src, gii, "--force").returncode, 0)
                self.assertEqual(run("convert", gii, back, "--force").returncode, 0)
                g = nib.load(gii)
                np.testing.assert_array_equal(g.agg_data("NIFTI_INTENT_POINTSET"), v)
                v3, f3 = fs.read_geometry(back)
                np.testing.assert_array_equal(v3, v)
                np.testing.assert_array_equal(f3, f)

    def test_malformed(self):
        src = self.make("good.white", n=10, m=8, volume_info=False)
        with open(src, "rb") as fh:
            good = fh.read()
        head = good.index(b"\n\n") + 2
        def counts(vn, fn):
            return good[:head] + struct.pack(">ii", vn, fn) + good[head + 8:]
        bad_face = bytearray(good)
        bad_face[head + 8 + 10 * 12: head + 8 + 10 * 12 + 4] = struct.pack(">i", 10)
        cases = {
            "bad_magic.white": b"\xff\xff\xfa" + good[3:],
            "quad.white": b"\xff\xff\xff" + good[3:],
            "truncated.white": good[:752 if len(good) > 752 else len(good) - 5],
            "absurd_vnum.white": counts(2 ** 30, 8),
            "negative_vnum.white": counts(-3, 8),
            "face_out_of_range.white": bytes(bad_face),
        }
        for name, data in cases.items():
            with self.subTest(case=name):
                f = self.path(name)
                with open(f, "wb") as fh:
                    fh.write(data)
                self.assert_clean_error(run("info", f, timeout=10), name)

    def test_curv_overlays(self):
        """curv files (lh.thickness, lh.curv) read as per-vertex values,
        as nibabel's read_morph_data reads them; written back, and to an
        overlay-only GIFTI and back."""
        rng = np.random.default_rng(5)
        vals = (rng.random(40) * 5 - 1).astype(np.float32)
        src = self.path("lh.thickness")
        fs.write_morph_data(src, vals)
        info = run_json("info", src, "--json")
        self.assertEqual(info["overlay_vertices"], 40)
        self.assertEqual([a["name"] for a in info["arrays"]], ["thickness"])
        for target in ("rh.curv", "v.shape.gii"):
            out = self.path(target)
            self.assertEqual(run("convert", src, out, "--force").returncode, 0)
            got = fs.read_morph_data(out) if target.endswith("curv") else nib.load(out).darrays[0].data
            np.testing.assert_array_equal(got, vals)
        back = self.path("back.sulc")
        self.assertEqual(run("convert", self.path("v.shape.gii"), back, "--force").returncode, 0)
        np.testing.assert_array_equal(fs.read_morph_data(back), vals)
        # A surface has no values to put in a curv file; a curv file has no geometry for a surface.
        self.assert_clean_error(run("convert", self.make("lh.white"), self.path("x.curv")), "x.curv")
        self.assert_clean_error(run("convert", src, self.path("x.white")), "x.white")
        # Truncated: fewer values than declared.
        with open(src, "rb") as fh:
            good = fh.read()
        for name, data in {"short.curv": good[:-9], "no_values.curv": good[:15]}.items():
            with self.subTest(case=name):
                with open(self.path(name), "wb") as fh:
                    fh.write(data)
                self.assert_clean_error(run("info", self.path(name), timeout=10), name)
