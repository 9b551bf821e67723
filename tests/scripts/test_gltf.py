"""glTF 2.0 meshes and streamlines (line primitives): independently written files (glTF JSON with an embedded
base64 buffer, binary GLB, node transforms) read as the glTF spec defines them
and mapped to RAS+ mm; GIFTI -> glTF -> GIFTI round trips against nibabel;
PBR factors reach the renderer; malformed files fail cleanly."""
import base64
import json
import os
import struct

import nibabel as nib
import numpy as np
from nibabel.gifti import GiftiDataArray, GiftiImage

from hztest import TempDirTest, run, run_json


def gltf_json(positions, indices, nodes=None, material=None, colors=None, index_type=5125):
    """A glTF 2.0 document written from the spec, not by Horizon."""
    pos = np.asarray(positions, np.float32)
    idx = np.asarray(indices, {5125: np.uint32, 5123: np.uint16, 5121: np.uint8}[index_type])
    blob = pos.tobytes()
    while len(blob) % 4:
        blob += b"\0"
    off_idx = len(blob)
    blob += idx.tobytes()
    while len(blob) % 4:
        blob += b"\0"
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes},
             {"buffer": 0, "byteOffset": off_idx, "byteLength": idx.nbytes}]
    accessors = [{"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3",
                  "min": pos.min(axis=0).tolist(), "max": pos.max(axis=0).tolist()},
                 {"bufferView": 1, "componentType": index_type, "count": idx.size, "type": "SCALAR"}]
    attributes = {"POSITION": 0}
    if colors is not None:
        col = np.asarray(colors, np.float32)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": col.nbytes})
        blob += col.tobytes()
        accessors.append({"bufferView": 2, "componentType": 5126, "count": len(col), "type": "VEC3"})
        attributes["COLOR_0"] = 2
    prim = {"attributes": attributes, "indices": 1, "mode": 4}
    doc = {"asset": {"version": "2.0", "generator": "hand-written test"},
           "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
           "bufferViews": views, "accessors": accessors, "meshes": [{"primitives": [prim]}],
           "nodes": nodes or [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0}
    if material is not None:
        doc["materials"] = [material]
        prim["material"] = 0
    return doc, blob


def to_glb(doc, blob):
    doc = json.loads(json.dumps(doc))
    doc["buffers"] = [{"byteLength": len(blob)}]
    j = json.dumps(doc).encode()
    while len(j) % 4:
        j += b" "
    chunks = struct.pack("<II", len(j), 0x4E4F534A) + j + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def ras_of_gltf(p):
    """RAS+ mm of glTF points (metres, +Y up, +Z front, +X left)."""
    p = np.asarray(p, np.float64)
    return np.stack([-1000 * p[:, 0], 1000 * p[:, 2], 1000 * p[:, 1]], axis=1)


class GltfTest(TempDirTest):
    def read_via_gifti(self, path):
        out = self.path("read.gii")
        p = run("convert", path, out, "--force")
        self.assertEqual(p.returncode, 0, p.stderr)
        g = nib.load(out)
        return g.agg_data("NIFTI_INTENT_POINTSET"), g.agg_data("NIFTI_INTENT_TRIANGLE")

    def test_independent_files_with_node_transforms(self):
        rng = np.random.default_rng(5)
        pos = rng.normal(size=(30, 3)) * 0.05
        idx = rng.integers(0, 30, size=(40, 3))
        # translation, rotation (90 degrees about +Y) and scale, child node under a parent.
        q = [0, np.sin(np.pi / 4), 0, np.cos(np.pi / 4)]
        nodes = [{"children": [1], "translation": [0.01, 0.02, -0.03]}, {"mesh": 0, "rotation": q, "scale": [2, 2, 2]}]
        doc, blob = gltf_json(pos, idx, nodes=nodes, index_type=5123)
        R = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)  # rotation of 90 degrees about +Y
        world = (pos * 2) @ R.T + [0.01, 0.02, -0.03]
        expect = ras_of_gltf(world)
        with open(self.path("a.gltf"), "w") as f:
            json.dump(doc, f)
        with open(self.path("a.glb"), "wb") as f:
            f.write(to_glb(doc, blob))
        for name in ("a.gltf", "a.glb"):
            v, fa = self.read_via_gifti(self.path(name))
            np.testing.assert_allclose(v, expect, atol=1e-3)
            np.testing.assert_array_equal(fa, idx)
        info = run_json("info", self.path("a.glb"), "--json")
        self.assertEqual(info["kind"], "mesh")

    def test_gifti_gltf_roundtrip_matches_nibabel(self):
        rng = np.random.default_rng(9)
        v = (rng.normal(size=(200, 3)) * 60).astype(np.float32)
        f = rng.integers(0, 200, size=(300, 3)).astype(np.int32)
        src = self.path("s.gii")
        nib.save(GiftiImage(darrays=[GiftiDataArray(v, intent="NIFTI_INTENT_POINTSET", datatype="NIFTI_TYPE_FLOAT32"),
                                     GiftiDataArray(f, intent="NIFTI_INTENT_TRIANGLE", datatype="NIFTI_TYPE_INT32")]), src)
        for ext in ("gltf", "glb"):
            out = self.path("s." + ext)
            p = run("convert", src, out)
            self.assertEqual(p.returncode, 0, p.stderr)
            v2, f2 = self.read_via_gifti(out)
            np.testing.assert_allclose(v2, v, atol=1e-3)
            np.testing.assert_array_equal(f2, f)
        # Horizon's glTF is standard: metres, Y up (read back here without Horizon).
        with open(self.path("s.gltf")) as fh:
            doc = json.load(fh)
        acc = doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
        np.testing.assert_allclose(acc["max"], [-v[:, 0].min() / 1000, v[:, 2].max() / 1000, v[:, 1].max() / 1000], rtol=1e-5)

    def test_colours_and_material_reach_the_renderer(self):
        rng = np.random.default_rng(1)
        pos = rng.normal(size=(60, 3)) * 0.04
        idx = rng.integers(0, 60, size=(80, 3))
        material = {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.1, 0.1, 1], "metallicFactor": 0.0, "roughnessFactor": 0.3}}
        doc, blob = gltf_json(pos, idx, material=material, colors=rng.random((60, 3)))
        with open(self.path("m.gltf"), "w") as f:
            json.dump(doc, f)
        info = run_json("info", self.path("m.gltf"), "--json")
        text = json.dumps(info)
        self.assertIn("material.baseColorFactor", text)
        self.assertIn("color", text)
        scene = {"objects": [{"type": "surface", "file": "m.gltf"}], "environment": {"type": "none"}}
        with open(self.path("m.json"), "w") as f:
            json.dump(scene, f)
        p = run("render", self.path("m.json"), "-o", self.path("m.png"), "--size", "160x120", env={"DISPLAY": ""})
        self.assertEqual(p.returncode, 0, p.stderr)
        from PIL import Image
        im = np.asarray(Image.open(self.path("m.png")).convert("RGB")).astype(float)
        obj = im[np.abs(im - im[0, 0]).sum(axis=2) > 30]
        self.assertGreater(len(obj), 50)
        self.assertGreater(obj[:, 0].mean(), 2 * obj[:, 2].mean(), "the red base colour factor is used")
        # COLOR_0 multiplies it (glTF): the same mesh without vertex colours renders differently.
        doc2, _ = gltf_json(pos, idx, material=material)
        with open(self.path("plain.gltf"), "w") as f:
            json.dump(doc2, f)
        with open(self.path("plain.json"), "w") as f:
            json.dump({"objects": [{"type": "surface", "file": "plain.gltf"}], "environment": {"type": "none"}}, f)
        p = run("render", self.path("plain.json"), "-o", self.path("plain.png"), "--size", "160x120", env={"DISPLAY": ""})
        self.assertEqual(p.returncode, 0, p.stderr)
        plain = np.asarray(Image.open(self.path("plain.png")).convert("RGB")).astype(float)
        self.assertGreater(np.abs(plain - im).mean(), 2.0, "the vertex colours are used")

    def test_streamlines_as_lines(self):
        """Streamlines written as one line primitive (mode 1), read back
        from the GLB as the spec lays it out (chunks, accessors, buffer
        views) and compared with nibabel's reading of the source: positions
        in glTF's metres, +Y up; one segment per pair of consecutive points;
        COLOR_0 the direction colour |tangent|. Back through Horizon: the
        same streamlines, empty and one-point ones included."""
        from hztest import tck_bytes
        rng = np.random.default_rng(5)
        sl = [np.cumsum(rng.normal(size=(n, 3)), axis=0).astype(np.float32) * 3 for n in (12, 40, 1, 0, 7, 2)]
        src = self.path("s.tck")
        with open(src, "wb") as f:
            f.write(tck_bytes(sl))
        glb = self.path("s.glb")
        p = run("convert", src, glb)
        self.assertEqual(p.returncode, 0, p.stderr)
        ref = list(nib.streamlines.load(src).streamlines)
        with open(glb, "rb") as f:
            data = f.read()
        magic, version, length = struct.unpack_from("<4sII", data)
        self.assertEqual((magic, version, length), (b"glTF", 2, len(data)))
        jlen, jtype = struct.unpack_from("<II", data, 12)
        doc = json.loads(data[20:20 + jlen])
        blen, btype = struct.unpack_from("<II", data, 20 + jlen)
        self.assertEqual((jtype, btype), (0x4E4F534A, 0x004E4942))
        blob = data[28 + jlen:28 + jlen + blen]

        def accessor(i):
            a = doc["accessors"][i]
            v = doc["bufferViews"][a["bufferView"]]
            dt = {5126: np.float32, 5125: np.uint32}[a["componentType"]]
            n = {"SCALAR": 1, "VEC3": 3}[a["type"]]
            off = v.get("byteOffset", 0) + a.get("byteOffset", 0)
            return np.frombuffer(blob, dt, a["count"] * n, off).reshape(a["count"], n)

        prim = doc["meshes"][0]["primitives"][0]
        self.assertEqual(prim["mode"], 1)
        pos = accessor(prim["attributes"]["POSITION"])
        pts = np.concatenate([s for s in ref if len(s)])
        np.testing.assert_allclose(ras_of_gltf(pos), pts, atol=1e-4)
        seg = accessor(prim["indices"]).reshape(-1, 2)
        starts = np.cumsum([0] + [len(s) for s in ref])
        want = [(starts[k] + i, starts[k] + i + 1) for k, s in enumerate(ref) for i in range(len(s) - 1)]
        np.testing.assert_array_equal(seg, want)
        col = accessor(prim["attributes"]["COLOR_0"])
        s1 = ref[1]
        t = s1[2] - s1[0]
        np.testing.assert_allclose(col[starts[1] + 1], np.abs(t) / np.linalg.norm(t), atol=1e-5)
        self.assertAlmostEqual(float(np.abs(doc["accessors"][prim["attributes"]["POSITION"]]["max"][1] - pos[:, 1].max())), 0, places=6)
        back = self.path("back.tck")
        p = run("convert", glb, back)
        self.assertEqual(p.returncode, 0, p.stderr)
        got = list(nib.streamlines.load(back).streamlines)
        self.assertEqual([len(x) for x in got], [len(x) for x in ref])
        for a, b in zip(got, ref):
            np.testing.assert_allclose(a, b, atol=1e-4)

    def test_independent_line_files_read_as_streamlines(self):
        """Lines (segments chained where one starts at the point the last
        ended) and a line strip, written from the spec, no triangles: read
        as streamlines in RAS+ mm."""
        pts = np.array([[0, 0, 0], [0.01, 0, 0], [0.02, 0.01, 0], [0, 0, 0.05], [0, 0.02, 0.05]], np.float32)
        # segments 0-1, 1-2 (one streamline of 3 points), then 3-4 (another)
        doc, blob = gltf_json(pts, [0, 1, 1, 2, 3, 4])
        doc["meshes"][0]["primitives"][0]["mode"] = 1
        with open(self.path("lines.glb"), "wb") as f:
            f.write(to_glb(doc, blob))
        info = run_json("info", self.path("lines.glb"), "--json")
        self.assertEqual((info["kind"], info["nb_streamlines"], info["nb_vertices"]), ("streamlines", 2, 5))
        p = run("convert", self.path("lines.glb"), self.path("lines.tck"))
        self.assertEqual(p.returncode, 0, p.stderr)
        got = list(nib.streamlines.load(self.path("lines.tck")).streamlines)
        np.testing.assert_allclose(got[0], ras_of_gltf(pts[:3]), atol=1e-4)
        np.testing.assert_allclose(got[1], ras_of_gltf(pts[3:]), atol=1e-4)
        doc, blob = gltf_json(pts, [4, 3, 0, 1])
        doc["meshes"][0]["primitives"][0]["mode"] = 3
        with open(self.path("strip.glb"), "wb") as f:
            f.write(to_glb(doc, blob))
        p = run("convert", self.path("strip.glb"), self.path("strip.tck"))
        self.assertEqual(p.returncode, 0, p.stderr)
        got = list(nib.streamlines.load(self.path("strip.tck")).streamlines)
        self.assertEqual(len(got), 1)
        np.testing.assert_allclose(got[0], ras_of_gltf(pts[[4, 3, 0, 1]]), atol=1e-4)

    def test_malformed(self):
        rng = np.random.default_rng(3)
        pos = rng.normal(size=(10, 3))
        doc, blob = gltf_json(pos, rng.integers(0, 10, size=(6, 3)))
        glb = to_glb(doc, blob)
        bad_index = json.loads(json.dumps(doc))
        doc2, blob2 = gltf_json(pos, np.full((2, 3), 50))  # face index out of range
        bad_view = json.loads(json.dumps(doc))
        bad_view["bufferViews"][0]["byteLength"] = 10_000
        bad_count = json.loads(json.dumps(doc))
        bad_count["accessors"][0]["count"] = 1_000_000
        cycle = json.loads(json.dumps(doc))
        cycle["nodes"] = [{"children": [1]}, {"children": [0], "mesh": 0}]
        # A chain of 60 nodes, each listing the next twice: 2^60 instances
        # of one mesh from a 5 kB file. Must fail fast, not hang or allocate.
        blowup = json.loads(json.dumps(doc))
        blowup["nodes"] = [{"children": [i + 1, i + 1]} for i in range(60)] + [{"mesh": 0}]
        cases = {
            "blowup.gltf": json.dumps(blowup).encode(),
            "trunc.glb": glb[: len(glb) // 2],
            "notjson.gltf": b"{ \"asset\": {\"version\": \"2.0\"}, oops",
            "index.gltf": json.dumps(doc2).encode(),
            "view.gltf": json.dumps(bad_view).encode(),
            "count.gltf": json.dumps(bad_count).encode(),
            "cycle.gltf": json.dumps(cycle).encode(),
            "empty.glb": b"",
        }
        for name, data in cases.items():
            with open(self.path(name), "wb") as f:
                f.write(data)
            p = run("info", self.path(name), timeout=10)
            self.assert_clean_error(p, name)
