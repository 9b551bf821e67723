#!/usr/bin/python3
"""Seed corpora for the loader fuzzers: small valid files of every variant
(written with nibabel, numpy and zipfile) plus nibabel's own test files."""
import json
import os
import sys
import zipfile

import nibabel as nib
import numpy as np

out = sys.argv[1]
rng = np.random.default_rng(0)
sl = [rng.normal(size=(int(rng.integers(1, 8)), 3)).astype(np.float32) * 10 for _ in range(6)]
nib_data = os.path.join(os.path.dirname(nib.__file__), "tests", "data")
for kind in ("tck", "trk", "trx", "nifti", "mgh", "gifti", "freesurfer", "gltf", "images", "plyobj"):
    os.makedirs(os.path.join(out, kind), exist_ok=True)
t = nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4))
nib.streamlines.save(t, os.path.join(out, "tck", "small.tck"))
nib.streamlines.save(t, os.path.join(out, "trk", "small.trk"))
for f in os.listdir(nib_data):
    for kind in ("tck", "trk"):
        if f.endswith("." + kind):
            with open(os.path.join(nib_data, f), "rb") as src, open(os.path.join(out, kind, f), "wb") as dst:
                dst.write(src.read())
pos = np.concatenate(sl)
off = np.concatenate([[0], np.cumsum([len(s) for s in sl])]).astype(np.uint64)
for comp, name in ((zipfile.ZIP_STORED, "stored"), (zipfile.ZIP_DEFLATED, "deflated")):
    with zipfile.ZipFile(os.path.join(out, "trx", name + ".trx"), "w", comp) as z:
        z.writestr("header.json", json.dumps({"NB_STREAMLINES": len(sl), "NB_VERTICES": len(pos),
                                              "VOXEL_TO_RASMM": np.eye(4).tolist(), "DIMENSIONS": [5, 5, 5]}))
        z.writestr("positions.3.float16", pos.astype(np.float16).tobytes())
        z.writestr("offsets.uint32", off[:-1].astype(np.uint32).tobytes())
        z.writestr("dpv/fa.float32", np.arange(len(pos), dtype=np.float32).tobytes())
        z.writestr("dps/w.2.float64", np.arange(2 * len(sl), dtype=np.float64).tobytes())
        z.writestr("groups/g.uint32", np.array([0, 2], np.uint32).tobytes())
        z.writestr("dpg/g/m.float32", np.array([1], np.float32).tobytes())

vol = (rng.random((4, 3, 2)) * 100).astype(np.int16)
nib.save(nib.Nifti1Image(vol, np.eye(4)), os.path.join(out, "nifti", "small.nii"))
nib.save(nib.Nifti1Image(vol.astype(np.float32), np.diag([2, 2, 2, 1])), os.path.join(out, "nifti", "small.nii.gz"))
nib.save(nib.Nifti2Image(vol, np.eye(4)), os.path.join(out, "nifti", "small2.nii"))
from nibabel.freesurfer.mghformat import MGHImage
nib.save(MGHImage(vol, np.eye(4)), os.path.join(out, "mgh", "small.mgh"))
nib.save(MGHImage(np.stack([vol, vol], 3).astype(np.float32), np.diag([2, 2, 2, 1])), os.path.join(out, "mgh", "small.mgz"))

from nibabel.gifti import GiftiDataArray, GiftiImage
verts = (rng.random((6, 3)) * 10).astype(np.float32)
tris = np.array([[0, 1, 2], [3, 4, 5]], np.int32)
for enc in ("GIFTI_ENCODING_ASCII", "GIFTI_ENCODING_B64BIN", "GIFTI_ENCODING_B64GZ"):
    img = GiftiImage(darrays=[GiftiDataArray(verts, intent="NIFTI_INTENT_POINTSET", datatype="NIFTI_TYPE_FLOAT32", encoding=enc),
                              GiftiDataArray(tris, intent="NIFTI_INTENT_TRIANGLE", datatype="NIFTI_TYPE_INT32", encoding=enc),
                              GiftiDataArray(verts[:, 0].copy(), intent="NIFTI_INTENT_SHAPE", datatype="NIFTI_TYPE_FLOAT32", encoding=enc)])
    nib.save(img, os.path.join(out, "gifti", enc.split("_")[-1].lower() + ".gii"))
# A label GIFTI with a LabelTable.
lt = nib.gifti.GiftiLabelTable()
for k, name in ((0, "unknown"), (1, "cortex")):
    lab = nib.gifti.GiftiLabel(k, 0.5, 0.25 * k, 0.1, 1.0)
    lab.label = name
    lt.labels.append(lab)
img = GiftiImage(darrays=[GiftiDataArray(np.array([0, 1, 1, 0], np.int32), intent="NIFTI_INTENT_LABEL", datatype="NIFTI_TYPE_INT32",
                                         encoding="GIFTI_ENCODING_ASCII")])
img.labeltable = lt
nib.save(img, os.path.join(out, "gifti", "labels.gii"))
# FreeSurfer: a small surface with and without the volume-info footer, and a curv file.
from collections import OrderedDict
import nibabel.freesurfer as fsio
fv = (rng.normal(size=(6, 3)) * 20).astype(np.float32)
ff = np.array([[0, 1, 2], [2, 3, 4], [4, 5, 0]], np.int32)
fsio.write_geometry(os.path.join(out, "freesurfer", "lh.white"), fv, ff)
vi = OrderedDict(head=np.array([2, 0, 20], dtype=np.int32), valid="1  # volume info valid", filename="vol.nii",
                 volume=np.array([256, 256, 256]), voxelsize=np.array([1.0, 1.0, 1.0]), xras=np.array([-1.0, 0, 0]),
                 yras=np.array([0, 0, -1.0]), zras=np.array([0, 1.0, 0]), cras=np.array([1.5, -2.0, 3.25]))
fsio.write_geometry(os.path.join(out, "freesurfer", "rh.pial"), fv, ff, volume_info=vi)
fsio.write_morph_data(os.path.join(out, "freesurfer", "lh.thickness"), rng.random(6).astype(np.float32))
fsio.write_annot(os.path.join(out, "freesurfer", "lh.aparc.annot"), np.array([0, 1, -1, 2, 1, 0], np.int32),
                 np.array([[25, 5, 25, 0, 0], [220, 20, 10, 0, 0], [20, 220, 60, 0, 0]], np.int32), [b"unknown", b"a", b"b"])
# Quad surfaces (int16 and float32 coordinates), written by hand as nibabel reads them.
def b3(x):
    return int(x).to_bytes(3, "big")
quads = [[0, 1, 2, 3], [2, 3, 4, 5]]
for magic, coords in ((b"\xff\xff\xff", (fv * 100).astype(">i2")), (b"\xff\xff\xfd", fv.astype(">f4"))):
    with open(os.path.join(out, "freesurfer", "quad_" + magic.hex()), "wb") as f:
        f.write(magic + b3(6) + b3(2) + coords.tobytes() + b"".join(b3(q) for qd in quads for q in qd))
# glTF: the hand-written documents of tests/scripts/test_gltf.py, as .gltf and .glb.
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scripts"))
from test_gltf import gltf_json, to_glb  # noqa: E402
gpos = [[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0], [0, 0, 0.01]]
gidx = [0, 1, 2, 0, 2, 3]
doc, blob = gltf_json(gpos, gidx, colors=[[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]],
                      material={"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.2, 1], "metallicFactor": 0.1}})
with open(os.path.join(out, "gltf", "a.gltf"), "w") as f:
    json.dump(doc, f)
with open(os.path.join(out, "gltf", "a.glb"), "wb") as f:
    f.write(to_glb(doc, blob))
doc, blob = gltf_json(gpos, gidx, nodes=[{"children": [1], "translation": [0.01, 0, 0]},
                                         {"mesh": 0, "rotation": [0, 0.7071, 0, 0.7071], "scale": [2, 2, 2]}], index_type=5123)
with open(os.path.join(out, "gltf", "nodes.glb"), "wb") as f:
    f.write(to_glb(doc, blob))
# Images: the first byte picks the extension the fuzz target gives the file
# (0 png, 1 jpg, 2 exr, 3 hdr, 4 tif); small pictures written by Pillow and a
# hand-written Radiance file.
import io
from PIL import Image
grad = (np.arange(8 * 6 * 3).reshape(6, 8, 3) * 5 % 256).astype(np.uint8)
for code, fmt, mode in ((0, "PNG", "RGB"), (0, "PNG", "RGBA"), (1, "JPEG", "RGB"), (4, "TIFF", "RGB")):
    b = io.BytesIO()
    Image.fromarray(grad if mode == "RGB" else np.dstack([grad, grad[..., :1]])).save(b, fmt)
    with open(os.path.join(out, "images", f"{fmt.lower()}_{mode}.bin"), "wb") as f:
        f.write(bytes([code]) + b.getvalue())
rgbe = bytes([128, 64, 32, 129]) * (4 * 3)
with open(os.path.join(out, "images", "radiance.bin"), "wb") as f:
    f.write(bytes([3]) + b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 3 +X 4\n" + rgbe)

# PLY (ASCII, binary both byte orders, with colours) and OBJ (with colours, a quad, relative indices).
import struct
pv = (rng.normal(size=(6, 3)) * 10).astype(np.float32)
pf = [[0, 1, 2], [2, 3, 4], [4, 5, 0]]
head = "ply\nformat {}\ncomment seed\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n" \
       "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n"
cols = rng.integers(0, 256, size=(6, 3))
with open(os.path.join(out, "plyobj", "ascii.ply"), "w") as f:
    f.write(head.format("ascii 1.0") + "".join("%g %g %g %d %d %d\n" % (*p, *c) for p, c in zip(pv, cols)) +
            "".join("3 %d %d %d\n" % tuple(t) for t in pf))
for fmt, e in (("binary_little_endian 1.0", "<"), ("binary_big_endian 1.0", ">")):
    body = b"".join(struct.pack(e + "3f3B", *p, *c) for p, c in zip(pv, cols)) + b"".join(struct.pack(e + "B3i", 3, *t) for t in pf)
    with open(os.path.join(out, "plyobj", fmt.split()[0] + ".ply"), "wb") as f:
        f.write(head.format(fmt).encode() + body)
# extra vertex properties of several types (read into per-vertex arrays)
head_p = "ply\nformat {}\nelement vertex 6\nproperty float x\nproperty short s\nproperty float y\nproperty float z\n" \
         "property double quality\nproperty uchar u\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n"
with open(os.path.join(out, "plyobj", "props_ascii.ply"), "w") as f:
    f.write(head_p.format("ascii 1.0") + "".join("%g %d %g %g %g %d\n" % (p[0], i - 3, p[1], p[2], p[0] * 0.5, i) for i, p in enumerate(pv)) +
            "".join("3 %d %d %d\n" % tuple(t) for t in pf))
with open(os.path.join(out, "plyobj", "props_be.ply"), "wb") as f:
    f.write(head_p.format("binary_big_endian 1.0").encode() +
            b"".join(struct.pack(">fhffdB", p[0], i - 3, p[1], p[2], p[0] * 0.5, i) for i, p in enumerate(pv)) +
            b"".join(struct.pack(">B3i", 3, *t) for t in pf))
with open(os.path.join(out, "plyobj", "a.obj"), "w") as f:
    f.write("# seed\no part\n" + "".join("v %g %g %g %g %g %g\n" % (*p, *(c / 255)) for p, c in zip(pv, cols)) +
            "vn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1\nf 3 4 5 6\nf -1 -2 -3\nl 1 2\n")
