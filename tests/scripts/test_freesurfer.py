"""FreeSurfer triangle surfaces through `horizon`, against nibabel's
read_geometry; conversions to and from GIFTI; malformed files."""
import os
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
            "quad.white": b"\xff\xff\xff" + good[3:],  # a triangle file's bytes under the quad magic
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

    def test_quad_surfaces(self):
        """Quad surfaces (FF FF FF with int16 coordinates in 1/100 mm, FF FF FD with float32) read as nibabel's
        read_geometry reads them, each quad split into two triangles by its rule; a quad file is told from a
        curv file (same magic) by its layout; malformed ones fail cleanly."""
        rng = np.random.default_rng(3)
        nv, nq = 40, 30
        quads = rng.integers(0, nv, size=(nq, 4))
        def b3(x):
            return int(x).to_bytes(3, "big")
        for magic, coords in ((b"\xff\xff\xff", rng.integers(-20000, 20000, size=(nv, 3)).astype(">i2")),
                              (b"\xff\xff\xfd", (rng.normal(size=(nv, 3)) * 50).astype(">f4"))):
            with self.subTest(magic=magic.hex()):
                data = magic + b3(nv) + b3(nq) + coords.tobytes() + b"".join(b3(q) for q in quads.ravel())
                src = self.path("lh.orig" if magic == b"\xff\xff\xff" else "lh.new.orig")
                with open(src, "wb") as fh:
                    fh.write(data)
                want_v, want_f = fs.read_geometry(src)
                info = run_json("info", src, "--json")
                self.assertEqual((info["format"], info["nb_vertices"], info["nb_faces"]), ("freesurfer quads", nv, 2 * nq))
                for target in ("q.gii", "q.white"):
                    out = self.path(target)
                    p = run("convert", src, out, "--force")
                    self.assertEqual(p.returncode, 0, p.stderr)
                    v, f = (fs.read_geometry(out) if target.endswith("white") else
                            (nib.load(out).agg_data("NIFTI_INTENT_POINTSET"), nib.load(out).agg_data("NIFTI_INTENT_TRIANGLE")))
                    np.testing.assert_allclose(v, want_v, rtol=1e-6, atol=1e-6)  # float32 of nibabel's float64
                    np.testing.assert_array_equal(f, want_f)
                bad_index = bytearray(data)
                bad_index[-3:] = b3(nv)
                for name, bad in {"cut.orig": data[:-2], "head.orig": data[:7], "index.orig": bytes(bad_index),
                                  "counts.orig": magic + b3(0xFFFFFF) + b3(0xFFFFFF) + data[9:]}.items():
                    with self.subTest(case=name):
                        with open(self.path(name), "wb") as fh:
                            fh.write(bad)
                        self.assert_clean_error(run("info", self.path(name), timeout=10), name)

    def test_annotations(self):
        """Annotations (lh.aparc.annot) read as nibabel's read_annot reads them: a label index per vertex
        (-1 unlabeled) and the label colours, both colour-table formats; malformed ones fail cleanly."""
        rng = np.random.default_rng(8)
        n = 300
        names = [b"unknown", b"bankssts", b"caudalanteriorcingulate", b"cuneus", b"frontalpole"]
        ctab = np.array([[25, 5, 25, 0, 0], [25, 100, 40, 0, 0], [125, 100, 160, 0, 0], [220, 180, 140, 0, 0],
                         [100, 0, 100, 30, 0]], np.int32)
        labels = rng.integers(-1, len(names), n).astype(np.int32)
        src = self.path("lh.aparc.annot")
        fs.write_annot(src, labels, ctab, names)
        want_labels, want_ctab, want_names = fs.read_annot(src)
        info = run_json("info", src, "--json")
        self.assertEqual(info["format"], "freesurfer annot")
        self.assertEqual(info["overlay_vertices"], n)
        self.assertEqual([(a["name"], a["dtype"], a["components"]) for a in info["arrays"]],
                         [("aparc", "int32", 1), ("aparc rgba", "uint8", 4)])
        header = dict(info["header"])
        for i, nm in enumerate(want_names):
            r, g, b, t = want_ctab[i, :4]
            self.assertEqual(header[f"label {i}"], f"{nm.decode()} {r} {g} {b} {t}")
        # The label indices, through an overlay-only label GIFTI: the colour table becomes its LabelTable (so
        # the colour array is not dropped), as nibabel reads it.
        gii = self.path("aparc.label.gii")
        p = run("convert", src, gii)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertNotIn("dropped", p.stderr)
        g = nib.load(gii)
        self.assertEqual(g.darrays[0].intent, nib.nifti1.intent_codes["NIFTI_INTENT_LABEL"])
        np.testing.assert_array_equal(g.darrays[0].data, want_labels)
        table = {l.key: l for l in g.labeltable.labels}
        self.assertEqual(sorted(table), list(range(len(want_names))))
        for i, nm in enumerate(want_names):
            r, gg, b, t = want_ctab[i, :4]
            self.assertEqual(table[i].label, nm.decode())
            np.testing.assert_allclose(table[i].rgba, [r / 255, gg / 255, b / 255, (255 - t) / 255], atol=1e-7)
        # ... and the GIFTI reads back with the same table and colours, and writes an annotation nibabel reads
        # as the original (labels, colour table, names).
        ginfo = run_json("info", gii, "--json")
        self.assertEqual([(a["name"], a["dtype"]) for a in ginfo["arrays"]], [("aparc", "int32"), ("aparc rgba", "uint8")])
        self.assertEqual(dict(ginfo["header"])["label 4"], "frontalpole 100 0 100 30")
        for via, name in ((src, "rh.copy.annot"), (gii, "rh.fromgii.annot")):
            with self.subTest(via=via):
                out = self.path(name)
                p = run("convert", via, out)
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertNotIn("dropped", p.stderr)
                l2, c2, n2 = fs.read_annot(out)
                np.testing.assert_array_equal(l2, want_labels)
                np.testing.assert_array_equal(c2, want_ctab)
                self.assertEqual(n2, want_names)
        # The old colour-table format (n > 0 entries, no indices), written by hand.
        def be(*v):
            return struct.pack(">%di" % len(v), *v)
        packed = lambda c: int(c[0]) + int(c[1]) * 256 + int(c[2]) * 65536
        old = be(4) + b"".join(be(i, packed(ctab[k]) if k >= 0 else 0) for i, k in enumerate([1, 2, -1, 1])) + be(1, 3)
        old += be(7) + b"NOFILE\0" + b"".join(be(len(nm) + 1) + nm + b"\0" + be(*ctab[i, :4]) for i, nm in enumerate(names[:3]))
        with open(self.path("lh.old.annot"), "wb") as fh:
            fh.write(old)
        info = run_json("info", self.path("lh.old.annot"), "--json")
        self.assertEqual(info["overlay_vertices"], 4)
        self.assertEqual(dict(info["header"])["label 2"], "caudalanteriorcingulate 125 100 160 0")
        # Writing an annotation needs labels the table defines, and a table: said so, nothing written.
        lt = nib.gifti.GiftiLabelTable()
        for k, nm in ((0, "unknown"), (1, "a b c")):  # names may contain spaces
            lab = nib.gifti.GiftiLabel(k, 0.1 * k, 0.2, 0.3, 1.0)
            lab.label = nm
            lt.labels.append(lab)
        for case, vals, table in (("undefined", [0, 1, 2], lt), ("no_table", [0, 1, 1], None), ("good", [0, 1, -1], lt)):
            with self.subTest(case=case):
                img = nib.gifti.GiftiImage(darrays=[nib.gifti.GiftiDataArray(np.array(vals, np.int32), intent="NIFTI_INTENT_LABEL",
                                                                             datatype="NIFTI_TYPE_INT32")])
                if table is not None:
                    img.labeltable = table
                g2 = self.path(case + ".label.gii")
                nib.save(img, g2)
                out = self.path(case + ".annot")
                p = run("convert", g2, out)
                if case == "good":
                    self.assertEqual(p.returncode, 0, p.stderr)
                    l3, c3, n3 = fs.read_annot(out)
                    np.testing.assert_array_equal(l3, [0, 1, -1])
                    self.assertEqual(n3, [b"unknown", b"a b c"])
                    np.testing.assert_array_equal(c3[:, :4], [[0, 51, 77, 0], [26, 51, 77, 0]])
                else:
                    self.assert_clean_error(p, out)
                    self.assertFalse(os.path.exists(out))
        # Malformed: truncated anywhere, a vertex out of range, a negative or absurd table.
        with open(src, "rb") as fh:
            good = fh.read()
        bad = {"cut_pairs.annot": good[:4 + 8 * 100], "cut_table.annot": good[:-7], "no_table.annot": good[:4 + 8 * n],
               "vertex.annot": good[:4] + be(n + 5) + good[8:], "version.annot": good[:4 + 8 * n] + be(1, -3) + good[4 + 8 * n + 8:],
               "int_min.annot": good[:4 + 8 * n] + be(1, -2**31) + good[4 + 8 * n + 8:],  # fuzz_freesurfer: UB negating it
               "huge.annot": good[:4 + 8 * n] + be(1, -2, 5, 7) + b"NOFILE\0" + be(0x7FFFFFFF), "empty.annot": b""}
        for name, data in bad.items():
            with self.subTest(case=name):
                with open(self.path(name), "wb") as fh:
                    fh.write(data)
                self.assert_clean_error(run("info", self.path(name), timeout=10), name)

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
        # float64 values (a GIFTI FLOAT64 array) go into a curv file rounded to float32, and the
        # conversion says so.
        v64 = vals.astype(np.float64) + 1e-9
        g64 = self.path("v64.shape.gii")
        nib.save(nib.gifti.GiftiImage(darrays=[nib.gifti.GiftiDataArray(v64, intent="NIFTI_INTENT_SHAPE",
                                                                        datatype="NIFTI_TYPE_FLOAT64")]), g64)
        p = run("convert", g64, self.path("r64.curv"), "--force")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("float64 precision", p.stderr)
        np.testing.assert_array_equal(fs.read_morph_data(self.path("r64.curv")), v64.astype(np.float32))
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
