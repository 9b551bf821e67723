"""GIFTI surfaces through `horizon`, compared with nibabel: every encoding,
both index orders, overlays; malformed files fail cleanly."""
import base64
import gzip
import os
import subprocess
import zlib

import nibabel as nib
import numpy as np
from nibabel.gifti import GiftiDataArray, GiftiImage

from hztest import HORIZON, TempDirTest, run, run_json

NIB_DATA = os.path.join(os.path.dirname(nib.__file__), "gifti", "tests", "data")


def surface(rng, n=40, m=60):
    v = rng.normal(size=(n, 3)).astype(np.float32) * 50
    f = rng.integers(0, n, size=(m, 3)).astype(np.int32)
    return v, f


class GiftiTest(TempDirTest):
    def write(self, name, v, f, encoding, ordering="C", overlay=None, endian="little"):
        arrays = [GiftiDataArray(v, intent="NIFTI_INTENT_POINTSET", datatype="NIFTI_TYPE_FLOAT32", encoding=encoding,
                                 ordering=ordering, endian=endian),
                  GiftiDataArray(f, intent="NIFTI_INTENT_TRIANGLE", datatype="NIFTI_TYPE_INT32", encoding=encoding,
                                 ordering=ordering, endian=endian)]
        if overlay is not None:
            arrays.append(GiftiDataArray(overlay, intent="NIFTI_INTENT_SHAPE", datatype="NIFTI_TYPE_FLOAT32", encoding=encoding))
        path = self.path(name)
        nib.save(GiftiImage(darrays=arrays), path)
        return path

    def check_roundtrip(self, path, v=None, f=None, overlay=None):
        """horizon's reading (converted to GIFTI by horizon) equals nibabel's reading of the source."""
        out = self.path("out.gii")
        p = run("convert", path, out, "--force")
        self.assertEqual(p.returncode, 0, p.stderr)
        ref, g = nib.load(path), nib.load(out)
        for intent in ("NIFTI_INTENT_POINTSET", "NIFTI_INTENT_TRIANGLE"):
            np.testing.assert_array_equal(np.asarray(g.agg_data(intent)).reshape(-1, 3), np.asarray(ref.agg_data(intent)).reshape(-1, 3))
        if v is not None:
            np.testing.assert_allclose(g.agg_data("NIFTI_INTENT_POINTSET"), v, rtol=1e-6, atol=1e-4)  # ASCII keeps ~6 decimals
            np.testing.assert_array_equal(g.agg_data("NIFTI_INTENT_TRIANGLE"), f)
        if overlay is not None:
            np.testing.assert_array_equal(g.agg_data("NIFTI_INTENT_SHAPE"), ref.agg_data("NIFTI_INTENT_SHAPE"))

    def test_encodings_orders_overlays(self):
        rng = np.random.default_rng(2)
        for enc in ("GIFTI_ENCODING_ASCII", "GIFTI_ENCODING_B64BIN", "GIFTI_ENCODING_B64GZ"):
            for ordering in ("C", "F"):
                with self.subTest(encoding=enc, ordering=ordering):
                    v, f = surface(rng)
                    ov = rng.random(len(v)).astype(np.float32)
                    path = self.write(f"s_{enc}_{ordering}.gii", v, f, enc, ordering, ov)
                    info = run_json("info", path, "--json")
                    self.assertEqual((info["nb_vertices"], info["nb_faces"]), (len(v), len(f)))
                    self.assertEqual(len(info["arrays"]), 1)
                    self.check_roundtrip(path, v, f, ov)

    def test_base64_with_line_breaks(self):
        """Base64 wrapped at 76 characters with CRLF and indentation, as
        MIME encoders and several GIFTI writers lay it out (nibabel writes
        one line): the same arrays as nibabel reads from the same file."""
        import re
        rng = np.random.default_rng(3)
        v, f = surface(rng, 300, 500)
        for enc in ("GIFTI_ENCODING_B64BIN", "GIFTI_ENCODING_B64GZ"):
            with self.subTest(encoding=enc):
                path = self.write("one_line.gii", v, f, enc)
                with open(path) as fh:
                    text = fh.read()

                def wrap(m):
                    lines = base64.encodebytes(base64.b64decode(m.group(2))).decode()
                    return m.group(1) + "\n  " + lines.replace("\n", "\r\n  ") + m.group(3)

                wrapped, count = re.subn(r"(<Data>)([^<]*)(</Data>)", wrap, text)
                self.assertEqual(count, 2)
                self.assertGreater(wrapped.count("\r\n"), 20)
                path = self.path("wrapped.gii")
                with open(path, "w", newline="") as fh:
                    fh.write(wrapped)
                np.testing.assert_array_equal(nib.load(path).agg_data("NIFTI_INTENT_POINTSET"), v)
                self.check_roundtrip(path, v, f)

    def test_float64_overlay_kept(self):
        """A NIFTI_TYPE_FLOAT64 array reads as float64 (not narrowed) and converts to GIFTI exactly."""
        rng = np.random.default_rng(5)
        v, f = surface(rng)
        ov = rng.random(len(v)) * 1e3 + 1e-9  # values float32 cannot hold
        for enc in ("GIFTI_ENCODING_ASCII", "GIFTI_ENCODING_B64BIN", "GIFTI_ENCODING_B64GZ"):
            with self.subTest(encoding=enc):
                arrays = [GiftiDataArray(v, intent="NIFTI_INTENT_POINTSET", datatype="NIFTI_TYPE_FLOAT32", encoding=enc),
                          GiftiDataArray(f, intent="NIFTI_INTENT_TRIANGLE", datatype="NIFTI_TYPE_INT32", encoding=enc),
                          GiftiDataArray(ov, intent="NIFTI_INTENT_SHAPE", datatype="NIFTI_TYPE_FLOAT64", encoding=enc)]
                path = self.path(f"f64_{enc}.gii")
                nib.save(GiftiImage(darrays=arrays), path)
                ref = nib.load(path).agg_data("NIFTI_INTENT_SHAPE")
                self.assertEqual(ref.dtype, np.float64)
                info = run_json("info", path, "--json")
                self.assertEqual([a["dtype"] for a in info["arrays"]], ["float64"])
                out = self.path("f64_out.gii")
                p = run("convert", path, out, "--force")
                self.assertEqual(p.returncode, 0, p.stderr)
                g = nib.load(out).agg_data("NIFTI_INTENT_SHAPE")
                self.assertEqual(g.dtype, np.float64)
                if enc == "GIFTI_ENCODING_ASCII":  # (nibabel writes ASCII with %.6g-like precision)
                    np.testing.assert_array_equal(g, ref)
                else:
                    np.testing.assert_array_equal(g, ov)

    def test_big_endian_and_external(self):
        rng = np.random.default_rng(3)
        v, f = surface(rng)
        path = self.write("le.gii", v, f, "GIFTI_ENCODING_B64BIN")
        with open(path) as fh:
            text = fh.read()
        b64_v = base64.b64encode(v.tobytes()).decode()
        # nibabel writes little-endian only: swap the POINTSET by hand.
        be = text.replace('Endian="LittleEndian"', 'Endian="BigEndian"', 1).replace(b64_v, base64.b64encode(v.astype(">f4").tobytes()).decode(), 1)
        with open(self.path("be.gii"), "w") as fh:
            fh.write(be)
        self.check_roundtrip(self.path("be.gii"), v, f)
        # ExternalFileBinary with an offset (nibabel reads it, cannot write it).
        with open(self.path("side.dat"), "wb") as fh:
            fh.write(b"\0" * 16 + v.tobytes())
        ext = text.replace('Encoding="Base64Binary"', 'Encoding="ExternalFileBinary"', 1).replace(
            'ExternalFileName=""', 'ExternalFileName="side.dat"', 1).replace('ExternalFileOffset="0"', 'ExternalFileOffset="16"', 1).replace(b64_v, "", 1)
        with open(self.path("ext.gii"), "w") as fh:
            fh.write(ext)
        self.check_roundtrip(self.path("ext.gii"), v, f)

    def test_label_without_colour(self):
        # nibabel writes a label it has no colour for without Red/Green/Blue/
        # Alpha: it reads as a label without a colour (header "- - - -"), is
        # written back without them, and gets a generated opaque colour where
        # one is needed (an annotation), not black.
        lt = nib.gifti.GiftiLabelTable()
        red = nib.gifti.GiftiLabel(key=0, red=1, green=0, blue=0, alpha=1)
        red.label = "red"
        plain = nib.gifti.GiftiLabel(key=1)
        plain.label = "plain"
        lt.labels = [red, plain]
        img = nib.gifti.GiftiImage(labeltable=lt, darrays=[nib.gifti.GiftiDataArray(np.array([0, 1, 1, 0], np.int32),
                                                                                    intent="NIFTI_INTENT_LABEL")])
        nib.save(img, self.path("lab.gii"))
        header = dict(run_json("info", self.path("lab.gii"), "--json")["header"])
        self.assertEqual(header["label 0"], "red 255 0 0 0")
        self.assertEqual(header["label 1"], "plain - - - -")
        self.assertEqual(run("convert", self.path("lab.gii"), self.path("back.gii")).returncode, 0)
        back = {l.key: l for l in nib.load(self.path("back.gii")).labeltable.labels}
        self.assertEqual((back[1].label, back[1].red, back[1].alpha), ("plain", None, None))
        self.assertEqual((back[0].red, back[0].green, back[0].blue, back[0].alpha), (1, 0, 0, 1))
        self.assertEqual(run("convert", self.path("lab.gii"), self.path("lab.annot")).returncode, 0)
        labels, ctab, names = nib.freesurfer.read_annot(self.path("lab.annot"))
        self.assertEqual(names, [b"red", b"plain"])
        np.testing.assert_array_equal(labels, [0, 1, 1, 0])
        self.assertEqual(list(ctab[0, :4]), [255, 0, 0, 0])
        self.assertGreater(ctab[1, :3].sum(), 200, "a generated colour, not black")
        self.assertEqual(ctab[1, 3], 0, "opaque")

    def test_generated_label_colour_never_merges_labels(self):
        # An annotation identifies a vertex's label by its colour: the colour
        # generated for a label without one must not be another label's.
        def gifti(name, labels):
            lt = nib.gifti.GiftiLabelTable()
            lt.labels = labels
            img = nib.gifti.GiftiImage(labeltable=lt, darrays=[nib.gifti.GiftiDataArray(np.array([0, 1, 1, 0], np.int32),
                                                                                        intent="NIFTI_INTENT_LABEL")])
            nib.save(img, self.path(name + ".gii"))
            return self.path(name + ".gii")

        def label(key, name, rgb=None):
            if rgb is None:
                lab = nib.gifti.GiftiLabel(key=key)
            else:
                lab = nib.gifti.GiftiLabel(key=key, red=rgb[0] / 255, green=rgb[1] / 255, blue=rgb[2] / 255, alpha=1)
            lab.label = name
            return lab

        # The colour label 1 is generated when it is alone without one ...
        src = gifti("alone", [label(0, "grey", (10, 10, 10)), label(1, "plain")])
        self.assertEqual(run("convert", src, self.path("alone.annot")).returncode, 0)
        generated = [int(v) for v in nib.freesurfer.read_annot(self.path("alone.annot"))[1][1, :3]]
        # ... is taken by label 0: label 1 gets another, and both survive.
        src = gifti("clash", [label(0, "taken", generated), label(1, "plain")])
        self.assertEqual(run("convert", src, self.path("clash.annot")).returncode, 0)
        labels, ctab, names = nib.freesurfer.read_annot(self.path("clash.annot"))
        self.assertEqual(names, [b"taken", b"plain"])
        self.assertEqual([int(v) for v in ctab[0, :3]], generated)
        self.assertNotEqual([int(v) for v in ctab[1, :3]], generated)
        np.testing.assert_array_equal(labels, [0, 1, 1, 0])
        # Two labels the data gives one colour cannot be told apart in an annotation.
        src = gifti("same", [label(0, "a", (200, 10, 10)), label(1, "b", (200, 10, 10))])
        self.assert_clean_error(run("convert", src, self.path("same.annot")), "same.annot")
        self.assertFalse(os.path.exists(self.path("same.annot")))

    def test_nibabel_test_data(self):
        for name in ("ascii.gii", "external.gii"):
            with self.subTest(file=name):
                path = os.path.join(NIB_DATA, name)
                self.check_roundtrip(path)
        # Face indices past the vertex count (nibabel reads them unchecked).
        for name in ("base64bin.gii",):
            with self.subTest(file=name):
                self.assert_clean_error(run("info", os.path.join(NIB_DATA, name)), name)
        # Overlay-only files: per-vertex values for a surface kept elsewhere,
        # read as nibabel reads them and written back overlay-only.
        for name in ("label.gii", "rh.shape.curv.gii", "task.func.gii", "gzipbase64.gii"):
            with self.subTest(file=name):
                path = os.path.join(NIB_DATA, name)
                ref = nib.load(path)
                info = run_json("info", path, "--json")
                self.assertEqual(info["nb_vertices"], 0)
                self.assertEqual(info["overlay_vertices"], ref.darrays[0].data.shape[0])
                # A label array of a file with a LabelTable also reads as its colours ("<name> rgba").
                table = {l.key: l.label for l in ref.labeltable.labels}
                derived = [a for a in ref.darrays if a.intent == nib.nifti1.intent_codes["NIFTI_INTENT_LABEL"] and table]
                self.assertEqual(len(info["arrays"]), len(ref.darrays) + len(derived))
                self.assertEqual({k: v.split(" ")[0] for k, v in info["header"] if k.startswith("label ")},
                                 {f"label {k}": v for k, v in table.items()})
                out = self.path("ov_" + name)
                p = run("convert", path, out, "--force")
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertNotIn("dropped", p.stderr)
                back = nib.load(out)
                self.assertEqual(len(back.darrays), len(ref.darrays))
                self.assertEqual({l.key: l.label for l in back.labeltable.labels}, table)
                for a, b in zip(ref.darrays, back.darrays):
                    np.testing.assert_array_equal(np.asarray(b.data).reshape(a.data.shape), a.data)
        # Arrays of different lengths cannot describe one surface.
        mixed = nib.gifti.GiftiImage(darrays=[nib.gifti.GiftiDataArray(np.zeros(5, np.float32), intent="NIFTI_INTENT_SHAPE"),
                                               nib.gifti.GiftiDataArray(np.zeros(6, np.float32), intent="NIFTI_INTENT_SHAPE")])
        nib.save(mixed, self.path("mixed.gii"))
        self.assert_clean_error(run("info", self.path("mixed.gii")), "mixed.gii")
        # An integer overlay whose ASCII text holds a number far outside int32
        # (found by fuzzing: an undefined conversion).
        labels = nib.gifti.GiftiImage(darrays=[nib.gifti.GiftiDataArray(np.arange(3, dtype=np.int32), intent="NIFTI_INTENT_LABEL",
                                                                         encoding="GIFTI_ENCODING_ASCII")])
        nib.save(labels, self.path("labels.gii"))
        self.assertEqual(run("info", self.path("labels.gii")).returncode, 0)
        with open(self.path("labels.gii")) as fh:
            text = fh.read()
        body = text[text.index("<Data>") + 6:text.index("</Data>")]
        with open(self.path("huge_label.gii"), "w") as fh:
            fh.write(text.replace("<Data>" + body, "<Data>" + body.replace("2", "2.22222e+43", 1), 1))
        p = run("info", self.path("huge_label.gii"))
        self.assert_clean_error(p, "huge_label.gii")
        self.assertIn("not an int32 value", p.stderr)

    def test_malformed(self):
        rng = np.random.default_rng(4)
        v, f = surface(rng, 10, 8)
        good = self.write("good.gii", v, f, "GIFTI_ENCODING_B64BIN")
        with open(good) as fh:
            text = fh.read()
        b64_v = base64.b64encode(v.tobytes()).decode()
        bad_f = f.copy()
        bad_f[0, 0] = len(v)
        cases = {
            "bad_base64.gii": text.replace(b64_v[:20], "!!not*base64!!" + b64_v[14:20], 1),
            "short_data.gii": text.replace(b64_v, base64.b64encode(v[:-2].tobytes()).decode(), 1),
            "face_out_of_range.gii": text.replace(base64.b64encode(f.tobytes()).decode(), base64.b64encode(bad_f.tobytes()).decode(), 1),
            "truncated.gii": text[: len(text) // 2],
            "bad_datatype.gii": text.replace("NIFTI_TYPE_FLOAT32", "NIFTI_TYPE_FLOAT99", 1),
            "dim_mismatch.gii": text.replace('Dim1="3"', 'Dim1="4"', 1),
            "gzip_container.gii": text.replace('Encoding="Base64Binary"', 'Encoding="GZipBase64Binary"', 1).replace(
                b64_v, base64.b64encode(gzip.compress(v.tobytes())).decode(), 1),
            "corrupt_zlib.gii": text.replace('Encoding="Base64Binary"', 'Encoding="GZipBase64Binary"', 1).replace(
                b64_v, base64.b64encode(b"\x78\x9c" + os.urandom(40)).decode(), 1),
            "missing_external.gii": text.replace('Encoding="Base64Binary"', 'Encoding="ExternalFileBinary"', 1).replace(
                'ExternalFileName=""', 'ExternalFileName="nowhere.dat"', 1),
            "no_triangles.gii": self.write_only_points(v),
            # Declared sizes far beyond what the file holds: rejected before
            # any allocation of that size (found by fuzzing: a 600-byte file
            # asked for 2.4 GB).
            "huge_dims_ascii.gii": self.write_ascii_points(v).replace('Dim0="10"', 'Dim0="299999999"', 1),
            "huge_dims_gzip.gii": text.replace('Encoding="Base64Binary"', 'Encoding="GZipBase64Binary"', 1).replace(
                'Dim0="10"', 'Dim0="2000000000"', 1),
            "huge_dims_external.gii": text.replace('Encoding="Base64Binary"', 'Encoding="ExternalFileBinary"', 1).replace(
                'ExternalFileName=""', 'ExternalFileName="small.dat"', 1).replace('Dim0="10"', 'Dim0="2000000000"', 1),
            # A face index far outside any integer type (found by fuzzing: UB in the message).
            "huge_face_index.gii": text.replace('Encoding="Base64Binary"', 'Encoding="ASCII"').replace(
                b64_v, " ".join(map(str, v.ravel())), 1).replace(base64.b64encode(f.tobytes()).decode(),
                                                                  "4.4e109 " + " ".join(map(str, f.ravel()[1:])), 1).replace(
                'DataType="NIFTI_TYPE_INT32"', 'DataType="NIFTI_TYPE_FLOAT64"', 1),
        }
        with open(self.path("small.dat"), "wb") as fh:
            fh.write(v.tobytes())
        for name, content in cases.items():
            with self.subTest(case=name):
                path = self.path(name)
                with open(path, "w") as fh:
                    fh.write(content)
                p = subprocess.run(["/usr/bin/time", "-f", "%M", HORIZON, "info", path], capture_output=True, text=True, timeout=10,
                                   env={**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"})
                lines = p.stderr.strip().splitlines()
                self.assertLess(int(lines[-1]), 300_000, f"{name}: peak RSS {lines[-1]} KB")
                p.stderr = "\n".join(l for l in lines[:-1] if not l.startswith("Command exited")) + "\n"
                self.assert_clean_error(p, name)

    def write_ascii_points(self, v):
        p = self.path("ascii_src.gii")
        nib.save(GiftiImage(darrays=[GiftiDataArray(v, intent="NIFTI_INTENT_POINTSET", datatype="NIFTI_TYPE_FLOAT32",
                                                    encoding="ASCII")]), p)
        with open(p) as fh:
            return fh.read()

    def write_only_points(self, v):
        p = self.path("points_only_src.gii")
        nib.save(GiftiImage(darrays=[GiftiDataArray(v, intent="NIFTI_INTENT_POINTSET", datatype="NIFTI_TYPE_FLOAT32",
                                                    encoding="GIFTI_ENCODING_B64BIN")]), p)
        with open(p) as fh:
            return fh.read()
