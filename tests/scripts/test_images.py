"""The images loader (OpenImageIO behind a thin plugin): PNG/TIFF round
trips against Pillow's reading, and malformed images fail with one line."""
import os
import resource
import struct
import subprocess
import zlib

import numpy as np
from PIL import Image

from hztest import HORIZON, TempDirTest, run, run_json


class ImagesTest(TempDirTest):
    def test_roundtrip_png_tiff(self):
        # Values as stored: RGBA is not premultiplied on the way through.
        rng = np.random.default_rng(3)
        for mode, shape in (("RGB", (37, 53, 3)), ("RGBA", (20, 31, 4)), ("L", (16, 9))):
            px = rng.integers(0, 256, size=shape, dtype=np.uint8)
            src = self.path(f"a_{mode}.png")
            Image.fromarray(px, mode).save(src)
            info = run_json("info", src, "--json")
            self.assertEqual(info["kind"], "image")
            self.assertEqual((info["width"], info["height"], info["channels"], info["dtype"]),
                             (shape[1], shape[0], shape[2] if len(shape) == 3 else 1, "uint8"))
            text = run("info", src).stdout
            self.assertIn(f"image:         {shape[1]} x {shape[0]} pixels", text)
            for ext in ("tif", "png"):
                out = self.path(f"b_{mode}.{ext}")
                p = run("convert", src, out, "--force")
                self.assertEqual(p.returncode, 0, p.stderr)
                np.testing.assert_array_equal(np.asarray(Image.open(out)), px)

    def test_tiff_rows_per_strip_beyond_the_height(self):
        # A valid TIFF may declare more rows per strip than it has (one strip); OpenImageIO 2.4 would size
        # its conversion buffer by that count. Such files are read row by row: right pixels, small memory.
        h, w = 5, 7
        px = (np.arange(h * w * 3, dtype=np.uint8) * 7).reshape(h, w, 3)
        data = px.tobytes()
        entries = [(256, 4, 1, w), (257, 4, 1, h), (258, 3, 1, 8), (259, 3, 1, 1), (262, 3, 1, 2),
                   (273, 4, 1, 8 + 2 + 12 * 11 + 4), (277, 3, 1, 3), (278, 4, 1, 0x0A000006), (279, 4, 1, len(data)),
                   (284, 3, 1, 1), (339, 3, 1, 1)]
        ifd = struct.pack("<H", len(entries)) + b"".join(struct.pack("<HHII", *e) for e in entries) + struct.pack("<I", 0)
        f = self.path("rps.tif")
        with open(f, "wb") as fh:
            fh.write(b"II*\0" + struct.pack("<I", 8) + ifd + data)
        def capped(*args):  # address space capped at 1.5 GB (not under ASan, whose shadow memory needs it)
            def cap():
                if "ASAN_OPTIONS" not in os.environ:
                    resource.setrlimit(resource.RLIMIT_AS, (1536 << 20, 1536 << 20))
            return subprocess.run([HORIZON, *args], capture_output=True, text=True, timeout=30, preexec_fn=cap,
                                  env={**os.environ, "XDG_DATA_HOME": "/nonexistent-xdg"})
        out = self.path("rps.png")
        p = capped("convert", f, out)
        self.assertEqual(p.returncode, 0, p.stderr)
        np.testing.assert_array_equal(np.asarray(Image.open(out)), px)
        # The forged file fuzz_images found (RowsPerStrip 167772166 for an 8 x 38 image of an unknown
        # compression): no 4 GB allocation; a one-line error naming the file.
        forged = bytes.fromhex(
            "49492a00080000000a0000010400010000000800000001010400010000000603000000020301000000008600000003"
            "010300010000004100000006010300010000000200000011010400010000008c000000150103000100000003000000"
            "16010400010000000600000a170104000100000090f8000001010400010000002600000000cb")
        g = self.path("forged.tif")
        with open(g, "wb") as fh:
            fh.write(forged)
        p = capped("convert", g, self.path("forged.png"))
        self.assertNotIn(p.returncode, (-6, -11), p.stderr)
        self.assertNotEqual(p.returncode, 0)  # its strip cannot be decoded
        self.assertIn("forged.tif", p.stderr)
        self.assertNotIn("bad_alloc", p.stderr)  # what the 4 GB request gave under the cap
        self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)

    def test_malformed_images_fail_cleanly(self):
        Image.fromarray(np.zeros((40, 40, 3), np.uint8)).save(self.path("good.png"))
        with open(self.path("good.png"), "rb") as f:
            good = f.read()

        def chunk(t, d):
            return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

        huge = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 1000000, 1000000, 8, 2, 0, 0, 0)) + \
            chunk(b"IDAT", zlib.compress(b"\0" * 10)) + chunk(b"IEND", b"")
        cases = {"truncated.png": good[: len(good) // 2], "empty.png": b"", "magic.png": b"NOT A PNG AT ALL" * 4,
                 "huge.png": huge, "garbage.exr": b"\x76\x2f\x31\x01" + os.urandom(200)}
        for name, data in cases.items():
            with self.subTest(case=name):
                with open(self.path(name), "wb") as f:
                    f.write(data)
                self.assert_clean_error(run("info", self.path(name), timeout=10), name)
