"""PLY and OBJ meshes through `horizon`, against meshio (python3-meshio, an
independent reader and writer): files meshio writes read as meshio reads them,
files horizon writes read in meshio as the source surface; vertex order is the
file's (overlays stay aligned); vertex colours survive; malformed files fail
cleanly."""
import os
import struct
import unittest

import meshio
import nibabel as nib
import nibabel.freesurfer as fs
import numpy as np

from hztest import TempDirTest, run, run_json


def surface(rng, n=60, m=80):
    v = (rng.normal(size=(n, 3)) * 40).astype(np.float32)
    f = rng.integers(0, n, size=(m, 3)).astype(np.int32)
    return v, f


def ply_colours(m, names):
    # meshio 7.0's binary PLY reader maps 'uchar' to int8; the bytes are right, so reinterpret them.
    return np.stack([np.asarray(m.point_data[c]).astype(np.int16).astype(np.uint8) for c in names], 1)


def gii_surface(path):
    g = nib.load(path)
    return g.agg_data("NIFTI_INTENT_POINTSET"), g.agg_data("NIFTI_INTENT_TRIANGLE")


class PlyObjTest(TempDirTest):
    def test_meshio_files_read_as_meshio_reads_them(self):
        rng = np.random.default_rng(1)
        v, f = surface(rng)
        colours = rng.integers(0, 256, size=(len(v), 3)).astype(np.uint8)
        for name, kw, data in (("a.ply", dict(binary=True), {}), ("b.ply", dict(binary=False), {}),
                               ("c.ply", dict(binary=True), {"red": colours[:, 0], "green": colours[:, 1], "blue": colours[:, 2]}),
                               ("d.obj", {}, {})):
            with self.subTest(file=name):
                src = self.path(name)
                meshio.write(src, meshio.Mesh(v, [("triangle", f)], point_data=data), **kw)
                ref = meshio.read(src)
                info = run_json("info", src, "--json")
                self.assertEqual((info["format"], info["nb_vertices"], info["nb_faces"]), (name[-3:], len(v), len(f)))
                gii = self.path(name + ".gii")
                p = run("convert", src, gii)
                self.assertEqual(p.returncode, 0, p.stderr)
                gv, gf = gii_surface(gii)
                np.testing.assert_array_equal(gv, ref.points.astype(np.float32))
                np.testing.assert_array_equal(gf, ref.cells_dict["triangle"])
                if data:
                    self.assertEqual([(a["name"], a["components"]) for a in info["arrays"]], [("color", 3)])
                    # colours through glTF's COLOR_0 and back to PLY, exact in 8 bits
                    glb, back = self.path("c.glb"), self.path("back.ply")
                    self.assertEqual(run("convert", src, glb).returncode, 0)
                    p = run("convert", glb, back)
                    self.assertEqual(p.returncode, 0, p.stderr)
                    b = meshio.read(back)
                    np.testing.assert_array_equal(ply_colours(b, ("red", "green", "blue")), colours)
                    np.testing.assert_array_equal(ply_colours(b, ("alpha",))[:, 0], 255)

    def test_written_files_read_in_meshio(self):
        """A FreeSurfer surface and its annotation's colours to PLY and OBJ: meshio reads the same vertices (in the
        same order, exactly), faces and colours."""
        rng = np.random.default_rng(2)
        v, f = surface(rng, 50, 70)
        src = self.path("lh.white")
        fs.write_geometry(src, v, f)
        for target in ("s.ply", "s.obj"):
            with self.subTest(target=target):
                out = self.path(target)
                p = run("convert", src, out)
                self.assertEqual(p.returncode, 0, p.stderr)
                m = meshio.read(out)
                np.testing.assert_array_equal(m.points.astype(np.float32), v)
                np.testing.assert_array_equal(m.cells_dict["triangle"], f)
                # and back through horizon, bit for bit
                back = self.path("back_" + target + ".white")
                self.assertEqual(run("convert", out, back).returncode, 0)
                v2, f2 = fs.read_geometry(back)
                np.testing.assert_array_equal(v2, v)
                np.testing.assert_array_equal(f2, f)
        # Label colours of an annotation, attached to the surface in a GIFTI, then to PLY as RGBA.
        ctab = np.array([[25, 5, 25, 0], [220, 20, 10, 0], [20, 220, 60, 55]], np.int32)
        labels = rng.integers(0, 3, len(v)).astype(np.int32)
        annot = self.path("lh.aparc.annot")
        fs.write_annot(annot, labels, ctab, [b"unknown", b"a", b"b"])
        gii = nib.gifti.GiftiImage(darrays=[
            nib.gifti.GiftiDataArray(v, intent="NIFTI_INTENT_POINTSET", datatype="NIFTI_TYPE_FLOAT32"),
            nib.gifti.GiftiDataArray(f, intent="NIFTI_INTENT_TRIANGLE", datatype="NIFTI_TYPE_INT32"),
            nib.gifti.GiftiDataArray(labels, intent="NIFTI_INTENT_LABEL", datatype="NIFTI_TYPE_INT32")])
        gii.labeltable = nib.gifti.GiftiLabelTable()
        for k, c in enumerate(ctab):
            lab = nib.gifti.GiftiLabel(k, *(c[:3] / 255.0), (255 - c[3]) / 255.0)
            lab.label = "abc"[k]
            gii.labeltable.labels.append(lab)
        nib.save(gii, self.path("lab.gii"))
        out = self.path("lab.ply")
        p = run("convert", self.path("lab.gii"), out)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertNotIn("dropped array", p.stderr)
        m = meshio.read(out)
        rgba = ply_colours(m, ("red", "green", "blue", "alpha"))
        want = np.concatenate([ctab[:, :3], 255 - ctab[:, 3:]], 1)[labels]
        np.testing.assert_array_equal(rgba, want)
        # the label indices themselves: an int vertex property named after the array
        info = run_json("info", self.path("lab.gii"), "--json")
        name = [a["name"] for a in info["arrays"] if a["dtype"] == "int32"][0]
        np.testing.assert_array_equal(m.point_data[name], labels)
        # OBJ cannot hold them, and says so
        p = run("convert", self.path("lab.gii"), self.path("lab.obj"))
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("dropped array '%s'" % name, p.stderr)

    def test_vertex_properties(self):
        """Scalar vertex properties other than position, normal and colour (MeshLab's quality, a thickness, a
        label) read as per-vertex arrays of their own type, as meshio reads them, in ASCII, little- and
        big-endian files; PLY writes them back bit for bit; other formats that hold per-vertex data keep them."""
        rng = np.random.default_rng(5)
        v, f = surface(rng, 40, 50)
        pd = {"quality": rng.normal(size=len(v)).astype(np.float32),
              "label": rng.integers(-5, 100000, len(v)).astype(np.int32),
              "thickness": rng.normal(size=len(v)),  # float64
              "nx": np.zeros(len(v), np.float32)}  # a normal: not an array
        for binary in (True, False):
            with self.subTest(binary=binary):
                src = self.path("p%d.ply" % binary)
                meshio.write(src, meshio.Mesh(v, [("triangle", f)], point_data=pd), binary=binary)
                ref = meshio.read(src)
                info = run_json("info", src, "--json")
                self.assertEqual([(a["name"], a["dtype"], a["components"]) for a in info["arrays"]],
                                 [("quality", "float32", 1), ("label", "int32", 1), ("thickness", "float64", 1)])
                out = self.path("out%d.ply" % binary)
                p = run("convert", src, out)
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertNotIn("dropped", p.stderr)
                m = meshio.read(out)
                for k in ("quality", "label", "thickness"):
                    self.assertEqual(m.point_data[k].dtype, ref.point_data[k].dtype)
                    np.testing.assert_array_equal(m.point_data[k], ref.point_data[k])
                # through GIFTI (float32 and int32 arrays) and back
                gii, back = self.path("p%d.gii" % binary), self.path("back%d.ply" % binary)
                self.assertEqual(run("convert", src, gii).returncode, 0)
                self.assertEqual(run("convert", gii, back).returncode, 0)
                b = meshio.read(back)
                np.testing.assert_array_equal(b.point_data["quality"], pd["quality"])
                np.testing.assert_array_equal(b.point_data["label"], pd["label"])
        # Big-endian, with short and uchar properties between the coordinates.
        be = self.path("be_props.ply")
        hdr = ("ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty short s\nproperty float y\n"
               "property float z\nproperty uchar u\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n").encode()
        rows = [(1.5, -300, 2.5, 3.5, 200), (0, 7, 1, 0, 0), (4, 32767, 5, 6, 255)]
        with open(be, "wb") as fh:
            fh.write(hdr + b"".join(struct.pack(">fhffB", *r) for r in rows) + struct.pack(">B3i", 3, 0, 1, 2))
        out = self.path("be_props_out.ply")
        self.assertEqual(run("convert", be, out).returncode, 0)
        # (meshio 7.0's binary reader has no 'short'; the vertex records are read here with numpy)
        with open(out, "rb") as fh:
            data = fh.read()
        end = data.index(b"end_header\n") + len(b"end_header\n")
        props = [l.split()[1:] for l in data[:end].decode().splitlines() if l.startswith("property ") and "list" not in l]
        np_type = {"float": "<f4", "short": "<i2", "uchar": "u1"}
        self.assertEqual(props, [["float", "x"], ["float", "y"], ["float", "z"], ["short", "s"], ["uchar", "u"]])
        recs = np.frombuffer(data, dtype=[(n, np_type[t]) for t, n in props], count=3, offset=end)
        np.testing.assert_array_equal(np.stack([recs["x"], recs["y"], recs["z"]], 1), [[r[0], r[2], r[3]] for r in rows])
        np.testing.assert_array_equal(recs["s"], [r[1] for r in rows])
        np.testing.assert_array_equal(recs["u"], [r[4] for r in rows])
        # An ASCII integer outside its type is an error naming the record.
        bad = self.path("bad_uchar.ply")
        with open(bad, "w") as fh:
            fh.write("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                     "property uchar u\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                     "0 0 0 1\n1 0 0 300\n0 1 0 2\n3 0 1 2\n")
        p = run("info", bad)
        self.assert_clean_error(p, "bad_uchar.ply")
        self.assertIn("record 1", p.stderr)

    def test_vertex_order_polygons_and_unused_vertices(self):
        """Vertices stay one per record in file order, unused ones included; polygons become triangles over the
        same vertices; negative (relative) OBJ indices resolve; OBJ materials are not read."""
        pts = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [9, 9, 9], [0, 0, 1]]
        ply = ("ply\nformat ascii 1.0\ncomment from a test\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
               "element face 2\nproperty list uchar int vertex_indices\nend_header\n" +
               "".join("%g %g %g\n" % tuple(p) for p in pts) + "4 0 1 2 3\n3 0 3 5\n")
        obj = ("mtllib /nonexistent/materials.mtl\n" + "".join("v %g %g %g\n" % tuple(p) for p in pts) +
               "usemtl x\nf 1 2 3 4\nf -6 -3 -1\nl 1 2\n")
        for name, text in (("q.ply", ply), ("q.obj", obj)):
            with self.subTest(file=name):
                src = self.path(name)
                with open(src, "w") as fh:
                    fh.write(text)
                info = run_json("info", src, "--json")
                self.assertEqual((info["nb_vertices"], info["nb_faces"]), (6, 3))
                gii = self.path(name + ".gii")
                self.assertEqual(run("convert", src, gii).returncode, 0)
                gv, gf = gii_surface(gii)
                np.testing.assert_array_equal(gv, np.array(pts, np.float32))
                # the quad 0 1 2 3 split along either diagonal, and the triangle 0 3 5
                tris = sorted(map(tuple, np.sort(gf, 1)))
                self.assertIn(tris, ([(0, 1, 2), (0, 2, 3), (0, 3, 5)], [(0, 1, 3), (0, 3, 5), (1, 2, 3)]))
                if name.endswith("ply"):
                    self.assertIn(["comment", "from a test"], info["header"])
                else:
                    self.assertIn(["ignored lines", "1"], info["header"])

    def test_big_endian_ply(self):
        v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [3, 4, 5]], np.float32)
        f = [[0, 1, 2], [1, 3, 2]]
        hdr = ("ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
               "element face 2\nproperty list uchar int vertex_indices\nend_header\n").encode()
        with open(self.path("be.ply"), "wb") as fh:
            fh.write(hdr + v.astype(">f4").tobytes() + b"".join(struct.pack(">B3i", 3, *t) for t in f))
        self.assertEqual(run("convert", self.path("be.ply"), self.path("be.gii")).returncode, 0)
        gv, gf = gii_surface(self.path("be.gii"))
        np.testing.assert_array_equal(gv, v)
        np.testing.assert_array_equal(gf, f)

    def test_malformed(self):
        rng = np.random.default_rng(3)
        v, f = surface(rng, 10, 8)
        meshio.write(self.path("good.ply"), meshio.Mesh(v, [("triangle", f)]), binary=True)
        with open(self.path("good.ply"), "rb") as fh:
            good = fh.read()
        body = good.index(b"end_header\n") + len(b"end_header\n")
        bad_index = bytearray(good)
        bad_index[-4:] = struct.pack("<i", 10)
        nan_vertex = bytearray(good)
        nan_vertex[body:body + 4] = struct.pack("<f", float("nan"))
        cases = {
            "truncated.ply": good[:-7],
            "header_only.ply": good[:body],
            "absurd.ply": good.replace(b"element vertex 10", b"element vertex 2000000000"),
            "huge.ply": good.replace(b"element vertex 10", b"element vertex 99999999999"),
            "no_end.ply": good[:body - 11],
            # found by fuzz_plyobj: Assimp 5.2 crashed on an end_header that is not on its own line
            "inline_end.ply": good.replace(b"vertex_indices\nend_header", b"vertex_indices*end_header"),
            "lone_cr.ply": good.replace(b"property float z", b"property float\r\r\r z"),  # found by fuzz_plyobj too
            # found by fuzz_plyobj: a hundred property-less elements made Assimp 5.2 allocate 2.3 GB
            "bare_elements.ply": good.replace(b"end_header\n", b"element pad 6\n" * 100 + b"end_header\n", 1),
            # found by fuzz_plyobj: a 29-digit colour value passed the checks (std::from_chars reports it out of
            # range, not unparsed) and Assimp 5.2 then allocated 7.6 GB
            "long_int.ply": b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                            b"property uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                            b"0 0 0 1\n1 0 0 88888888888888888888888888888\n0 1 0 2\n3 0 1 2\n",
            "long_list.ply": good[:-13] + b"\xff" + good[-12:],  # the last face claims 255 indices
            "two_vertex_face.ply": good[:-13] + b"\x02" + good[-12:],
            "index.ply": bytes(bad_index),
            "nan.ply": bytes(nan_vertex),
            "bad_format.ply": good.replace(b"binary_little_endian", b"binary_middle_endian"),
            "wrong_magic.ply": b"plx" + good[3:],
            "empty.ply": b"",
            "points.ply": b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n",
            "index.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
            "negative.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n",
            "no_faces.obj": b"v 0 0 0\nv 1 0 0\n",
            "nan.obj": b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            "empty.obj": b"",
            "binary.obj": bytes(range(256)) * 4,
        }
        for name, data in cases.items():
            with self.subTest(case=name):
                with open(self.path(name), "wb") as fh:
                    fh.write(data)
                p = run("info", self.path(name), timeout=10)
                self.assert_clean_error(p, name)
                if name in ("wrong_magic.ply", "empty.ply"):
                    self.assertIn("not a PLY file", p.stderr)
        # A surface without faces cannot be written; nothing is left behind.
        fs.write_morph_data(self.path("lh.thickness"), np.ones(5, np.float32))
        out = self.path("x.ply")
        self.assert_clean_error(run("convert", self.path("lh.thickness"), out), "x.ply")
        self.assertFalse(os.path.exists(out))


if __name__ == "__main__":
    unittest.main()

    def test_float64_vertex_data_written_to_gifti_as_float64(self):
        """A double per-vertex property is written to GIFTI as NIFTI_TYPE_FLOAT64,
        not narrowed to float32 (values float32 cannot hold survive exactly)."""
        vals = np.array([0.1 + 1e-12, 1.0 / 3.0, 2.0 ** 40 + 0.5])
        src, gii = self.path("d.ply"), self.path("d.gii")
        with open(src, "w") as fh:
            fh.write("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                     "property double thickness\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n")
            for i, v in enumerate(vals):
                fh.write(f"{i} {i * 2} 0 {v!r}\n")
            fh.write("3 0 1 2\n")
        p = run("convert", src, gii)
        self.assertEqual(p.returncode, 0, p.stderr)
        arrays = [d for d in nib.load(gii).darrays if d.intent not in (1008, 1009)]  # not POINTSET / TRIANGLE
        self.assertEqual(len(arrays), 1)
        self.assertEqual(arrays[0].data.dtype, np.float64)
        np.testing.assert_array_equal(arrays[0].data, vals)

