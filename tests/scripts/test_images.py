"""The images loader (OpenImageIO behind a thin plugin): PNG/TIFF round
trips against Pillow's reading, and malformed images fail with one line."""
import os
import struct
import zlib

import numpy as np
from PIL import Image

from hztest import TempDirTest, run, run_json


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
            for ext in ("tif", "png"):
                out = self.path(f"b_{mode}.{ext}")
                p = run("convert", src, out, "--force")
                self.assertEqual(p.returncode, 0, p.stderr)
                np.testing.assert_array_equal(np.asarray(Image.open(out)), px)

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
