"""TRX through `horizon`: zip (stored, deflated) and directory forms, every
positions/offsets dtype, with and without the offsets sentinel, dpv/dps/
groups/dpg; the malformed cases of FORMATS.md fail cleanly; clustering
results stored as groups."""
import io
import json
import os
import zipfile

import nibabel as nib
import numpy as np

from hztest import TempDirTest, random_streamlines, run, run_json


def make_trx(path, streamlines, pos_dtype="float32", off_dtype="uint64", sentinel=True, compression=zipfile.ZIP_STORED,
             extra=None, header_patch=None, directory=False, dpv=True):
    pos = np.concatenate(streamlines).astype(pos_dtype) if streamlines else np.zeros((0, 3), pos_dtype)
    lengths = [len(s) for s in streamlines]
    off = np.concatenate([[0], np.cumsum(lengths)]).astype(off_dtype)
    if not sentinel:
        off = off[:-1]
    header = {"VOXEL_TO_RASMM": np.eye(4).tolist(), "DIMENSIONS": [10, 20, 30],
              "NB_STREAMLINES": len(streamlines), "NB_VERTICES": int(sum(lengths))}
    if header_patch:
        header.update(header_patch)
    entries = {"header.json": json.dumps(header).encode(), f"positions.3.{pos_dtype}": pos.tobytes(),
               f"offsets.{off_dtype}": off.tobytes()}
    n, v = len(streamlines), int(sum(lengths))
    if dpv and n:
        entries["dpv/fa.float32"] = np.arange(v, dtype=np.float32).tobytes()
        entries["dps/weight.2.float64"] = np.arange(2 * n, dtype=np.float64).tobytes()
        entries["groups/first.uint32"] = np.array([0, n - 1], np.uint32).tobytes()
        entries["dpg/first/mean.float32"] = np.array([1.5], np.float32).tobytes()
    if extra:
        entries.update(extra)
    entries = {k: v for k, v in entries.items() if v is not None}
    if directory:
        for k, data in entries.items():
            p = os.path.join(path, k)
            os.makedirs(os.path.dirname(p), exist_ok=True)
            with open(p, "wb") as f:
                f.write(data)
    else:
        with zipfile.ZipFile(path, "w", compression) as z:
            for k, data in entries.items():
                z.writestr(k, data)
    return pos, off


class TrxTest(TempDirTest):
    def read_back(self, f):
        out = self.path("back_%d.tck" % len(os.listdir(self.tmp)))
        p = run("convert", f, out)
        self.assertEqual(p.returncode, 0, p.stderr)
        return list(nib.streamlines.load(out).streamlines)

    def test_variants(self):
        rng = np.random.default_rng(9)
        sl = random_streamlines(25, rng, 1, 30) + [np.zeros((0, 3), np.float32)] + random_streamlines(3, rng, 1, 4)
        for pos_dtype in ("float16", "float32", "float64"):
            for off_dtype in ("uint32", "uint64"):
                for sentinel in (True, False):
                    for form in ("stored", "deflated", "directory"):
                        with self.subTest(pos=pos_dtype, off=off_dtype, sentinel=sentinel, form=form):
                            f = self.path(f"v_{pos_dtype}_{off_dtype}_{sentinel}_{form}.trx")
                            pos, _ = make_trx(f, sl, pos_dtype, off_dtype, sentinel,
                                              zipfile.ZIP_DEFLATED if form == "deflated" else zipfile.ZIP_STORED,
                                              directory=form == "directory")
                            info = run_json("info", f, "--json")
                            self.assertEqual(info["nb_streamlines"], len(sl))
                            self.assertEqual(info["nb_empty_streamlines"], 1)
                            names = {a["name"]: a for a in info["arrays"]}
                            self.assertEqual(names["fa"]["attach"], "vertex")
                            self.assertEqual(names["weight"]["components"], 2)
                            self.assertEqual(names["first"]["attach"], "group")
                            self.assertEqual(names["first/mean"]["attach"], "group data")
                            got = [s for s in self.read_back(f)]
                            want = [np.asarray(s, np.float64) for s in sl if len(s)]
                            exp = np.split(pos.astype(np.float64), np.cumsum([len(s) for s in sl])[:-1])
                            exp = [e for e in exp if len(e)]
                            self.assertEqual(len(got), len(want))
                            for a, b in zip(got, exp):
                                np.testing.assert_allclose(a, b, atol=1e-3 if pos_dtype != "float16" else 0)

    def test_float16_positions_at_the_edges_of_the_range(self):
        """float16 positions (the TRX specification allows them) at the edges
        of the half-precision range: subnormals (2^-24, 6e-8), the smallest
        normal (2^-14), the largest finite value (65504), negative zero;
        read as numpy widens them to float32, bit for bit, written by zipfile
        and numpy from the specification, not by horizon."""
        pos = np.array([[0, 0, 0], [6e-8, 1e-5, -6e-8], [65504, -65504, 1.0], [2 ** -14, -(2 ** -14), 2 ** -24], [100.5, -0.0, 3.0],
                        [1, 2, 3]], dtype=np.float16)
        f = self.path("f16.trx")
        with zipfile.ZipFile(f, "w") as z:
            z.writestr("header.json", json.dumps({"DIMENSIONS": [1, 1, 1], "VOXEL_TO_RASMM": np.eye(4).tolist(), "NB_VERTICES": 6,
                                                  "NB_STREAMLINES": 2}))
            z.writestr("positions.3.float16", pos.tobytes())
            z.writestr("offsets.uint32", np.array([0, 3], np.uint32).tobytes())
        out = self.path("f16.tck")
        p = run("convert", f, out)
        self.assertEqual(p.returncode, 0, p.stderr)
        got = np.concatenate(list(nib.streamlines.load(out).streamlines))
        self.assertEqual(got.tobytes(), pos.astype(np.float32).tobytes(), "bit for bit, subnormals and -0 included")
        info = run_json("info", f, "--json")
        self.assertEqual((info["nb_streamlines"], info["nb_vertices"]), (2, 6))

    def test_arrays_survive_trx_to_trx(self):
        rng = np.random.default_rng(4)
        sl = random_streamlines(10, rng, 2, 20)
        f = self.path("a.trx")
        make_trx(f, sl, header_patch={"SOURCE": "unit test"})
        out = self.path("b.trx")
        p = run("convert", f, out)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(p.stderr, "")
        with zipfile.ZipFile(f) as za, zipfile.ZipFile(out) as zb:
            for name in ["dpv/fa.float32", "dps/weight.2.float64", "groups/first.uint32", "dpg/first/mean.float32"]:
                self.assertEqual(za.read(name), zb.read(name), name)
            self.assertTrue(all(i.compress_type == zipfile.ZIP_STORED for i in zb.infolist()))
            h = json.loads(zb.read("header.json"))
            self.assertEqual(h["SOURCE"], "unit test")
            off = np.frombuffer(zb.read("offsets.uint64"), np.uint64)
            self.assertEqual(len(off), len(sl) + 1)  # always written with the sentinel
        # TCK cannot hold the arrays: each is reported.
        p = run("convert", f, self.path("c.tck"))
        self.assertEqual(p.returncode, 0)
        self.assertEqual(p.stderr.count("dropped"), 4)

    def test_zero_copy(self):
        """Float32 positions stored as plain bytes at an aligned offset are mapped, not copied
        (hz.ext.mapped-positions/1): Horizon's own files, the directory form, and other writers' zips when aligned.
        Everything else is read as before, with the same answer."""
        rng = np.random.default_rng(12)
        sl = random_streamlines(40, rng, 2, 30)
        pos = np.concatenate(sl)

        def check(f, mapped):
            info = run_json("info", f, "--json")
            self.assertEqual(info["positions_mapped"], mapped, f)
            np.testing.assert_array_equal(info["bbox_ras_mm"]["min"], pos.min(axis=0).astype(np.float64))
            np.testing.assert_array_equal(info["bbox_ras_mm"]["max"], pos.max(axis=0).astype(np.float64))
            got = self.read_back(f)
            np.testing.assert_allclose(np.concatenate(got), pos, atol=1e-3)

        src = self.path("src.trx")
        make_trx(src, sl)
        own = self.path("own.trx")
        self.assertEqual(run("convert", src, own).returncode, 0)
        check(own, True)  # Horizon writes the positions first, at byte 64
        d = self.path("dir.trx")
        os.makedirs(d)
        make_trx(d, sl, directory=True)
        check(d, True)
        check(self.path_made(sl, compression=zipfile.ZIP_DEFLATED), False)  # deflated: decoded
        # Another writer's stored zip: mapped when the data happens to be 4-byte aligned, copied when not.
        for pad in range(4):
            f = self.path(f"pad{pad}.trx")
            make_trx(f, sl, header_patch={"PAD": "x" * pad})
            with zipfile.ZipFile(f) as z:
                i = z.getinfo("positions.3.float32")
            with open(f, "rb") as fh:
                fh.seek(i.header_offset + 26)
                nl, el = np.frombuffer(fh.read(4), np.uint16)
            check(f, (i.header_offset + 30 + int(nl) + int(el)) % 4 == 0)

        # Mapped positions are still checked: a NaN is named by its vertex, a flipped byte fails the CRC.
        bad = [s.copy() for s in sl]
        bad[3][1, 2] = np.nan
        f = self.path("nan.trx")
        os.makedirs(f)
        make_trx(f, bad, directory=True)
        p = run("info", f)
        self.assertNotEqual(p.returncode, 0)
        k = sum(len(s) for s in sl[:3]) + 1
        self.assertIn(f"non-finite coordinate at vertex {k}", p.stderr)
        raw = bytearray(open(own, "rb").read())
        raw[64 + 4 * 7] ^= 0x40
        f = self.path("flipped.trx")
        open(f, "wb").write(bytes(raw))
        p = run("info", f)
        self.assertNotEqual(p.returncode, 0)
        self.assertIn("flipped.trx", p.stderr)
        self.assertIn("CRC-32", p.stderr)
        self.assertEqual(len(p.stderr.strip().splitlines()), 1)

    def path_made(self, sl, **kw):
        f = self.path("made_%d.trx" % len(os.listdir(self.tmp)))
        make_trx(f, sl, **kw)
        return f

    def test_header_only_empty(self):
        f = self.path("empty.trx")
        with zipfile.ZipFile(f, "w") as z:
            z.writestr("header.json", json.dumps({"NB_STREAMLINES": 0, "NB_VERTICES": 0, "VOXEL_TO_RASMM": np.eye(4).tolist(),
                                                  "DIMENSIONS": [1, 1, 1]}))
        self.assertEqual(run_json("info", f, "--json")["nb_streamlines"], 0)

    def test_malformed(self):
        rng = np.random.default_rng(5)
        sl = random_streamlines(12, rng, 2, 10)
        v = sum(len(s) for s in sl)
        n = len(sl)
        pos = np.concatenate(sl).astype(np.float32)
        off = np.concatenate([[0], np.cumsum([len(s) for s in sl])]).astype(np.uint64)
        bad_off = off.copy(); bad_off[5] = bad_off[6] + 1
        far_off = off.copy(); far_off[5] = v + 10
        first_off = off.copy(); first_off[0] = 3
        nan_pos = pos.copy(); nan_pos[3, 1] = np.nan
        inf_pos = pos.copy(); inf_pos[4, 2] = -np.inf
        cases = {
            "path_traversal": dict(extra={"../evil.float32": b"1234"}),
            "absolute": dict(extra={"/abs/dpv/x.float32": b"1234"}),
            "nb_streamlines_too_large": dict(header_patch={"NB_STREAMLINES": 1050}),
            "nb_vertices_too_large": dict(header_patch={"NB_VERTICES": v + 5}),
            "nb_streamlines_negative": dict(header_patch={"NB_STREAMLINES": -1}),
            "nb_vertices_string": dict(header_patch={"NB_VERTICES": "many"}),
            "offsets_not_monotonic": dict(extra={"offsets.uint64": bad_off.tobytes()}),
            "offset_out_of_range": dict(extra={"offsets.uint64": far_off.tobytes()}),
            "offsets_first_nonzero": dict(extra={"offsets.uint64": first_off.tobytes()}),
            "positions_int32": dict(extra={"positions.3.float32": None, "positions.3.int32": pos.astype(np.int32).tobytes()}),
            "positions_dim4": dict(extra={"positions.3.float32": None, "positions.4.float32": pos.tobytes()}),
            "positions_no_dim": dict(extra={"positions.3.float32": None, "positions.float32": pos.tobytes()}),
            "offsets_int64": dict(extra={"offsets.uint64": None, "offsets.int64": off.astype(np.int64).tobytes()}),
            "offsets_float32": dict(extra={"offsets.uint64": None, "offsets.float32": off.astype(np.float32).tobytes()}),
            "too_many_dots": dict(extra={"dpv/fa.3.4.float32": b"x" * 4}),
            "bad_ext": dict(extra={"dpv/fa.txt": b"x"}),
            "missing_positions": dict(extra={"positions.3.float32": None}),
            "unknown_toplevel": dict(extra={"bogus.float32": np.zeros(3, np.float32).tobytes()}),
            "dpv_wrong_size": dict(extra={"dpv/fa.float32": np.zeros(v - 1, np.float32).tobytes()}),
            "dps_wrong_size": dict(extra={"dps/weight.2.float64": np.zeros(n, np.float64).tobytes()}),
            "group_out_of_range": dict(extra={"groups/first.uint32": np.array([0, n], np.uint32).tobytes()}),
            "group_int32": dict(extra={"groups/first.uint32": None, "groups/first.int32": np.array([0], np.int32).tobytes()}),
            "dpg_without_group": dict(extra={"dpg/ghost/mean.float32": np.array([1], np.float32).tobytes()}),
            "positions_odd_bytes": dict(extra={"positions.3.float32": pos.tobytes()[:-2]}),
            "nan_position": dict(extra={"positions.3.float32": nan_pos.tobytes()}),
            "inf_position": dict(extra={"positions.3.float32": inf_pos.tobytes()}),
            "missing_header": dict(extra={"header.json": None}),
            "bad_json": dict(extra={"header.json": b"{not json"}),
        }
        reasons = {"offsets_not_monotonic": "offsets decrease", "offsets_first_nonzero": "expected 0",
                   "path_traversal": "escapes the archive", "nb_vertices_too_large": "NB_VERTICES", "missing_header": "no header.json",
                   "dpv_wrong_size": "bytes, ", "dps_wrong_size": "bytes, "}
        for name, kw in cases.items():
            with self.subTest(case=name):
                f = self.path(name + ".trx")
                make_trx(f, sl, **kw)
                p = run("info", f, timeout=10)
                self.assert_clean_error(p, name + ".trx")
                if name in reasons:
                    self.assertIn(reasons[name], p.stderr)
        good = self.path("good.trx")
        make_trx(good, sl, compression=zipfile.ZIP_DEFLATED)
        with open(good, "rb") as fh:
            data = fh.read()
        broken = {"truncated_zip": data[: len(data) // 2], "not_a_zip": os.urandom(2000)}
        with zipfile.ZipFile(good) as z:
            info = z.getinfo("positions.3.float32")
        b = bytearray(data)
        start = info.header_offset + 30 + len(info.filename) + 10
        for i in range(start, start + 40):
            b[i] ^= 0x5A
        broken["corrupt_deflate"] = bytes(b)
        for name, blob in broken.items():
            with self.subTest(case=name):
                f = self.path(name + ".trx")
                with open(f, "wb") as fh:
                    fh.write(blob)
                self.assert_clean_error(run("info", f, timeout=10), name + ".trx")

    def test_clustering_stored_as_groups(self):
        d = self.path("demo")
        self.assertEqual(run("demo", "--out", d, "--streamlines", "800").returncode, 0)
        out, labels = self.path("clusters.trx"), self.path("labels.csv")
        p = run("cluster", os.path.join(d, "phantom.tck"), "--algorithm", "qbx", "--labels", labels, "--out", out)
        self.assertEqual(p.returncode, 0, p.stderr)
        lab = np.loadtxt(labels, delimiter=",", skiprows=1, dtype=np.int64)
        with zipfile.ZipFile(out) as z:
            names = z.namelist()
            for level, thr in enumerate(["30", "25", "20", "15"], start=1):
                dps = np.frombuffer(z.read(f"dps/cluster_level{level}_{thr}mm.int64"), np.int64)
                np.testing.assert_array_equal(dps, lab[:, level])
                groups = [n for n in names if n.startswith(f"groups/level{level}_{thr}mm_cluster")]
                self.assertEqual(len(groups), lab[:, level].max() + 1)
                for g in groups:
                    k = int(g.split("cluster")[1].split(".")[0])
                    members = np.frombuffer(z.read(g), np.uint32)
                    np.testing.assert_array_equal(np.sort(members), np.nonzero(lab[:, level] == k)[0])
        self.assertEqual(run_json("info", out, "--json")["nb_streamlines"], 800)
