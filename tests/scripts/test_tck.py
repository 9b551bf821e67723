"""MRtrix TCK through `horizon info` / `horizon convert`, checked against
nibabel (the independent reference) and against the generating arrays."""
import glob
import json
import os
import re
import resource
import shutil
import subprocess
import time
import unittest

import nibabel as nib
import numpy as np

from hztest import FIXTURES, HORIZON, TempDirTest, environment, random_streamlines, run, run_json, tck_bytes

NIB_DATA = os.path.join(os.path.dirname(nib.__file__), "tests", "data")


def read_back(test, path):
    """Streamlines as horizon reads `path`: converted by horizon to a plain
    Float32LE TCK, then parsed here with numpy (keeps empty streamlines)."""
    out = test.path("readback_%d.tck" % time.monotonic_ns())
    p = run("convert", path, out)
    test.assertEqual(p.returncode, 0, p.stderr)
    with open(out, "rb") as f:
        raw = f.read()
    head_end = raw.index(b"\nEND\n")
    offset = [int(l.split()[-1]) for l in raw[:head_end].decode().splitlines() if l.startswith("file:")][0]
    data = np.frombuffer(raw[offset:], dtype="<f4").reshape(-1, 3)
    streamlines, cur = [], []
    for row in data:
        if np.isinf(row).all():
            break
        if np.isnan(row).all():
            streamlines.append(np.array(cur, dtype=np.float32).reshape(-1, 3))
            cur = []
        else:
            cur.append(row)
    return streamlines


class TckVariantsTest(TempDirTest):
    def check_same(self, got, want, tol=1e-3):
        self.assertEqual(len(got), len(want))
        for a, b in zip(got, want):
            self.assertEqual(a.shape, np.asarray(b).reshape(-1, 3).shape)
            if len(a):
                self.assertLessEqual(np.abs(a - np.asarray(b, dtype=np.float64)).max(), tol)

    def test_datatypes_and_byte_orders(self):
        rng = np.random.default_rng(7)
        sl = random_streamlines(30, rng) + [np.zeros((0, 3), np.float32)] + random_streamlines(5, rng, 1, 1)
        for dt in ["Float32LE", "Float32BE", "Float64LE", "Float64BE"]:
            with self.subTest(datatype=dt):
                f = self.path(f"v_{dt}.tck")
                with open(f, "wb") as fh:
                    fh.write(tck_bytes(sl, dt))
                info = run_json("info", f, "--json")
                self.assertEqual(info["format"], "tck " + dt)
                self.assertEqual(info["nb_streamlines"], len(sl))
                self.assertEqual(info["nb_vertices"], sum(len(s) for s in sl))
                self.assertEqual(info["nb_empty_streamlines"], 1)
                self.check_same(read_back(self, f), sl, tol=0)  # float32 data survives bit for bit
                if dt.startswith("Float32"):  # nibabel 5.0 reads Float32 only; it drops empty streamlines
                    ref = nib.streamlines.load(f).streamlines
                    self.check_same([s for s in read_back(self, f) if len(s)], list(ref))

    def test_files_written_by_nibabel(self):
        rng = np.random.default_rng(11)
        sl = random_streamlines(200, rng, 2, 80)
        f = self.path("nib.tck")
        nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), f)
        info = run_json("info", f, "--json")
        self.assertEqual(info["nb_streamlines"], 200)
        # nibabel starts the data at byte 67: mapped (ABI 1.9 unaligned extent),
        # and `info` never copies the floats to aligned memory.
        with open(f, "rb") as fh:
            head = fh.read(4096)
        self.assertNotEqual(int(head[head.index(b"file: . ") + 8:].split(b"\n")[0]) % 4, 0)
        self.assertTrue(info["positions_mapped"])
        self.assertTrue(info["positions_copied_on_use"])
        # --verify: the host copies them and reads every coordinate itself.
        self.assertTrue(run_json("info", f, "--json", "--verify")["verified"])
        # ... and catches a loader that vouches for bounds 1 mm too wide.
        lying = self.path("lying")
        os.makedirs(lying)
        shutil.copy(os.path.join(FIXTURES, "fx_tck_lying_bounds.so"), lying)
        # (A plain `info` takes the loader's word, except in builds that verify every
        # claim as they load: Debug and the sanitizer build. --verify always checks.)
        self.assert_clean_error(run("--plugin-dir", lying, "info", "--verify", f), f)
        allp = np.concatenate(sl)
        np.testing.assert_allclose(info["bbox_ras_mm"]["min"], allp.min(0), atol=1e-4)
        np.testing.assert_allclose(info["bbox_ras_mm"]["max"], allp.max(0), atol=1e-4)
        self.check_same(read_back(self, f), sl, tol=0)
        # And nibabel reads what horizon writes.
        out = self.path("from_horizon.tck")
        self.assertEqual(run("convert", f, out).returncode, 0)
        self.check_same(list(nib.streamlines.load(out).streamlines), sl, tol=0)

    def test_aligned_data_are_mapped_with_their_delimiters(self):
        """MRtrix starts the data on a multiple of 4 bytes, and so does our writer: such a
        Float32LE file is mapped, not copied (ABI 1.5 delimited extent). An unaligned one
        (nibabel's) is mapped too (ABI 1.9), its floats copied to aligned memory when first
        used, which `info` never does. All read as nibabel reads them."""
        rng = np.random.default_rng(3)
        sl = random_streamlines(300, rng, 1, 60) + [np.zeros((0, 3), np.float32)] + random_streamlines(4, rng, 1, 1)
        mapped, copied = {}, {}
        for pad in range(4):
            f = self.path(f"pad{pad}.tck")
            with open(f, "wb") as fh:
                fh.write(tck_bytes(sl, pad=pad))
            with open(f, "rb") as fh:
                head = fh.read(4096)
            offset = int(head[head.index(b"file: . ") + 8:].split(b"\n")[0])
            info = run_json("info", f, "--json")
            self.assertTrue(info["positions_mapped"], (pad, offset))
            self.assertEqual(info["positions_copied_on_use"], offset % 4 != 0, (pad, offset))
            (mapped if offset % 4 == 0 else copied)[pad] = f
            self.assertEqual(info["nb_vertices"], sum(len(s) for s in sl))
            self.assertEqual(info["nb_empty_streamlines"], 1)
            allp = np.concatenate(sl)
            np.testing.assert_array_equal(info["bbox_ras_mm"]["min"], allp.min(0).astype(np.float64))
            np.testing.assert_array_equal(info["bbox_ras_mm"]["max"], allp.max(0).astype(np.float64))
            self.check_same(read_back(self, f), sl, tol=0)
        self.assertEqual((len(mapped), len(copied)), (1, 3))
        # Our writer aligns; what it writes is mapped again and nibabel reads it.
        out = self.path("ours.tck")
        self.assertEqual(run("convert", copied[min(copied)], out).returncode, 0)
        info = run_json("info", out, "--json")
        self.assertTrue(info["positions_mapped"])
        self.assertFalse(info["positions_copied_on_use"])
        self.check_same([s for s in nib.streamlines.load(out).streamlines], [s for s in sl if len(s)], tol=0)

    def test_nibabel_test_data(self):
        good = ["empty.tck", "simple.tck", "simple_big_endian.tck", "standard.tck", "matlab_nan.tck",
                "multiline_header_field.tck"]
        for name in good:
            with self.subTest(file=name):
                f = os.path.join(NIB_DATA, name)
                ref = list(nib.streamlines.load(f).streamlines)
                got = [s for s in read_back(self, f) if len(s)]
                self.check_same(got, ref, tol=0)
        for name in ["no_magic_number.tck", "no_header_end.tck", "no_header_end_eof.tck"]:
            with self.subTest(file=name):
                self.assert_clean_error(run("info", os.path.join(NIB_DATA, name)), name)

    def test_header_quirks(self):
        sl = [np.arange(9, dtype=np.float32).reshape(3, 3), np.ones((2, 3), np.float32)]
        cases = {
            "matlab_negnan": dict(nan_bits=0xFFC00000, inf_sign=-1.0, pad=7),
            "count_mismatch": dict(count=615000),
            "empty_value": dict(header_extra=[("roi", ""), ("command_history", "a: b:c")]),
            "magic_trailing_blanks": dict(magic="mrtrix tracks    "),
        }
        for name, kw in cases.items():
            with self.subTest(case=name):
                f = self.path(name + ".tck")
                with open(f, "wb") as fh:
                    fh.write(tck_bytes(sl, **kw))
                self.check_same(read_back(self, f), sl, tol=0)
        # Bytes after the Inf terminator are ignored, as mrtrix does.
        f = self.path("trailing.tck")
        with open(f, "wb") as fh:
            fh.write(tck_bytes(sl) + b"junk")
        self.check_same(read_back(self, f), sl, tol=0)
        # A missing count field is fine.
        f = self.path("nocount.tck")
        with open(f, "wb") as fh:
            fh.write(tck_bytes(sl).replace(b"count: 2\n", b"xount: 2\n"))
        self.check_same(read_back(self, f), sl, tol=0)

    def test_count_disagreeing_with_the_data_is_reported(self):
        # The data decide how many streamlines there are (an interrupted
        # mrtrix write leaves count 0); a disagreeing count is named once.
        sl = [np.arange(9, dtype=np.float32).reshape(3, 3), np.ones((2, 3), np.float32)]
        for name, count, warned in [("more", "615000", True), ("zero", "0000000000", True), ("same", "2", False),
                                    ("padded", "0000000002", False), ("not_a_number", "many", False)]:
            with self.subTest(case=name):
                f = self.path(name + ".tck")
                with open(f, "wb") as fh:
                    fh.write(tck_bytes(sl, count=count))
                p = run("info", f, "--json")
                self.assertEqual(p.returncode, 0, p.stderr)
                self.assertEqual(json.loads(p.stdout)["nb_streamlines"], 2)
                msg = f"{f}: the header says count {int(count) if warned else ''} but the data hold 2 streamlines"
                if warned:
                    self.assertIn(msg, p.stderr)
                    self.assertEqual(p.stderr.count("the header says count"), 1, p.stderr)
                else:
                    self.assertNotIn("the header says count", p.stderr)


class TckCountTest(TempDirTest):
    def test_the_header_count_matches_the_data_for_mrtrix(self):
        """The `count` of every TCK horizon writes (convert, filter, a
        selection written in place, the inverse selection) is the number of
        streamlines in the file, as MRtrix3's tckinfo reads it (nibabel
        ignores the field)."""
        tckinfo = shutil.which("tckinfo")
        if tckinfo is None:
            self.skipTest("tckinfo (package mrtrix3) is not installed")
        rng = np.random.default_rng(23)
        src = self.path("src.tck")
        nib.streamlines.save(nib.streamlines.Tractogram(random_streamlines(300, rng, min_pts=2, scale=30.0), affine_to_rasmm=np.eye(4)), src)
        outputs = {"convert": ("convert", src, self.path("c.tck")),
                   "filter": ("filter", src, "--include", "sphere:0,0,0,20", "-o", self.path("f.tck")),
                   "inverse": ("filter", src, "--include", "sphere:0,0,0,20", "--invert", "-o", self.path("i.tck")),
                   "lengths": ("filter", self.path("c.tck"), "--min-length", "30", "-o", self.path("l.tck"))}
        counts = {}
        for name, args in outputs.items():
            p = run(*args)
            self.assertEqual(p.returncode, 0, p.stderr)
            out = args[-1]
            q = subprocess.run([tckinfo, "-count", out], capture_output=True, text=True, timeout=60)
            self.assertEqual(q.returncode, 0, q.stderr)
            header = int(re.search(r"^\s*count:\s*(\d+)", q.stdout, re.M).group(1))
            actual = int(re.search(r"actual count in file:\s*(\d+)", q.stdout + q.stderr).group(1))
            counts[name] = actual
            with self.subTest(output=name):
                self.assertEqual(header, actual, q.stdout)
                self.assertEqual(actual, len(nib.streamlines.load(out).streamlines))
        self.assertEqual(counts["convert"], 300)
        self.assertEqual(counts["filter"] + counts["inverse"], 300)
        self.assertTrue(0 < counts["filter"] < 300 and 0 < counts["lengths"] < 300, counts)


class TckMalformedTest(TempDirTest):
    def write(self, name, data):
        f = self.path(name)
        with open(f, "wb") as fh:
            fh.write(data)
        return f

    def test_every_truncation_fails_cleanly(self):
        good = tck_bytes([np.arange(12, dtype=np.float32).reshape(4, 3), np.ones((2, 3), np.float32)])
        # Under the sanitizers (a process start is ~0.3 s there) every third
        # cut: 3 is prime to the 4-byte values and 12-byte points, so every
        # kind of cut still comes; the Release suite tries each one, and the
        # TCK fuzzer truncates under the sanitizers too.
        for cut in range(0, len(good), 3 if "ASAN_OPTIONS" in os.environ else 1):
            f = self.write("cut.tck", good[:cut])
            t0 = time.monotonic()
            p = run("info", f, timeout=10)
            with self.subTest(cut=cut):
                self.assert_clean_error(p, "cut.tck")
                self.assertLess(time.monotonic() - t0, 10)

    def test_malformed_cases(self):
        sl = [np.arange(9, dtype=np.float32).reshape(3, 3)]
        good = tck_bytes(sl)
        off = good.index(b"END\n") + 4
        data_at = int(good.split(b"file: . ")[1].split(b"\n")[0])
        cases = {
            "bad_magic.tck": good.replace(b"mrtrix tracks", b"mrtrix trucks"),
            "int32.tck": good.replace(b"Float32LE", b"Int32LE  "),
            "external.tck": good.replace(b"file: . ", b"file: x "),
            "offset_beyond_eof.tck": good.replace(b"file: . %d" % data_at, b"file: . 99999999999"),
            "offset_in_header.tck": good.replace(b"file: . %d" % data_at, b"file: . 1" + b" " * (len(str(data_at)) - 1)),
            "offset_negative.tck": good.replace(b"file: . %d" % data_at, b"file: . -5"),
            "no_terminator.tck": good[:-12],
            "no_last_delimiter.tck": good[:-24] + good[-12:],
            "partial_nan.tck": good[:data_at] + np.array([[np.nan, 1, 2]], "<f4").tobytes() + good[data_at + 12:],
            "partial_inf.tck": good[:data_at] + np.array([[0, 1, np.inf]], "<f4").tobytes() + good[data_at + 12:],
            "no_end.tck": good[:off - 4],
            "binary_junk.tck": b"mrtrix tracks\n" + os.urandom(3000).replace(b"END", b"xxx"),
        }
        # The reason, where one check owns the case (another failing later
        # with a vaguer message would hide a broken check).
        reasons = {"offset_beyond_eof.tck": "past the end of the file", "offset_in_header.tck": "inside the header",
                   "no_terminator.tck": "terminator", "no_end.tck": "no END line", "int32.tck": "unsupported"}
        for name, data in cases.items():
            with self.subTest(case=name):
                f = self.write(name, data)
                p = run("info", f, timeout=10)
                self.assert_clean_error(p, name)
                if name in reasons:
                    self.assertIn(reasons[name], p.stderr)

    def test_absurd_sizes_do_not_allocate(self):
        # A header claiming an enormous count with almost no data, read with
        # the address space capped at 1.5 GB: believing 2e8 streamlines would
        # take 1.6 GB of offsets alone, and fail (not under ASan, whose
        # shadow memory needs the address space; the cap is what measures).
        def cap():
            if "ASAN_OPTIONS" not in os.environ:
                resource.setrlimit(resource.RLIMIT_AS, (1536 << 20, 1536 << 20))
        for count in (2 * 10**8, 10**15):
            f = self.write(f"huge_count_{count}.tck", tck_bytes([np.zeros((1, 3))], count=count))
            p = subprocess.run([HORIZON, "info", f, "--json"], capture_output=True, text=True, timeout=60, preexec_fn=cap,
                               env=environment("info"))
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertEqual(json.loads(p.stdout)["nb_streamlines"], 1)


if __name__ == "__main__":
    unittest.main()
