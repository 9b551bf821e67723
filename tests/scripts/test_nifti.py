"""NIfTI-1/2 through `horizon`, compared with nibabel: data exactly (after
scaling), affines from sform/qform as nibabel chooses them; every variant
of FORMATS.md; malformed headers fail cleanly without large allocations."""
import gzip
import os
import shutil
import struct

import nibabel as nib
import numpy as np

from hztest import BUILD, TempDirTest, run, run_json

DTYPES = [np.uint8, np.int8, np.int16, np.uint16, np.int32, np.uint32, np.int64, np.uint64, np.float32, np.float64]


def random_affine(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    a, b, c, d = q
    R = np.array([[a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
                  [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
                  [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d]])
    aff = np.eye(4)
    aff[:3, :3] = R @ np.diag(rng.uniform(0.5, 3, 3) * np.where(rng.random(3) < 0.5, -1, 1))
    aff[:3, 3] = rng.uniform(-100, 100, 3)
    return aff


class NiftiTest(TempDirTest):
    def roundtrip(self, src, name="out.nii"):
        out = self.path(name)
        p = run("convert", src, out, "--force")
        self.assertEqual(p.returncode, 0, p.stderr)
        return nib.load(out)

    def assert_same(self, src_img, ours, affine_tol=1e-5):
        np.testing.assert_array_equal(np.asanyarray(ours.dataobj, dtype=np.float64) if False else ours.get_fdata(), src_img.get_fdata())
        np.testing.assert_allclose(ours.affine, src_img.affine, atol=affine_tol)

    def test_dtypes_dims_affines_containers(self):
        rng = np.random.default_rng(3)
        for i, dt in enumerate(DTYPES):
            for ext in ("nii", "nii.gz", "img", "img.gz"):
                with self.subTest(dtype=np.dtype(dt).name, ext=ext):
                    shape = (3, 4, 5) if i % 2 else (3, 4, 5, 2)
                    data = (rng.random(shape) * 100).astype(dt)
                    aff = random_affine(rng)
                    f = self.path(f"v{i}.{ext}")
                    cls = nib.Nifti1Pair if ext.startswith("img") else nib.Nifti1Image
                    img = cls(data, aff, dtype=dt)
                    nib.save(img, f)
                    src = nib.load(f)
                    info = run_json("info", f, "--json")
                    self.assertEqual(info["dims"], list(shape))
                    np.testing.assert_allclose(np.array(info["affine"]), src.affine, atol=1e-6)
                    self.assert_same(src, self.roundtrip(f))

    def test_nifti2_big_endian_and_scaling(self):
        rng = np.random.default_rng(4)
        data = (rng.random((6, 5, 4)) * 1000).astype(np.int16)
        aff = random_affine(rng)
        cases = {}
        img = nib.Nifti2Image(data, aff)
        cases["n2.nii"] = img
        be = nib.Nifti1Image(data, aff, header=nib.Nifti1Header().as_byteswapped(">"))
        cases["be.nii"] = be
        be2 = nib.Nifti2Image(data.astype(">f4"), aff, header=nib.Nifti2Header().as_byteswapped(">"))
        cases["be2.nii.gz"] = be2
        scaled = nib.Nifti1Image(data, aff)
        scaled.header.set_slope_inter(0.5, -3)
        cases["scaled.nii"] = scaled
        for name, im in cases.items():
            with self.subTest(case=name):
                f = self.path(name)
                nib.save(im, f)
                self.assert_same(nib.load(f), self.roundtrip(f))

    def test_header_variants(self):
        rng = np.random.default_rng(5)
        data = (rng.random((4, 5, 6)) * 100).astype(np.float32)
        aff = random_affine(rng)
        def variant(name, edit):
            img = nib.Nifti1Image(data, aff)
            edit(img.header)
            f = self.path(name)
            nib.save(img, f)
            return f
        def qform_only(h):
            h.set_qform(aff, 1)
            h.set_sform(None, 0)
        def differ(h):
            h.set_qform(np.diag([1, 2, 3, 1]), 1)
            h.set_sform(aff, 2)
        def slope0(h):
            h["scl_slope"] = 0
            h["scl_inter"] = 5
        def slope_nan(h):
            h["scl_slope"] = np.nan
            h["scl_inter"] = np.nan
        for name, edit in [("qform_only.nii", qform_only), ("differ.nii", differ), ("slope0.nii", slope0), ("slope_nan.nii", slope_nan)]:
            with self.subTest(case=name):
                f = variant(name, edit)
                self.assert_same(nib.load(f), self.roundtrip(f))
        # qfac (pixdim[0]) = 0 is read as 1; nibabel refuses to write it, so
        # patch a file whose qfac was 1 (a right-handed affine).
        if np.linalg.det(aff[:3, :3]) < 0:
            aff[:3, 0] *= -1
        f = variant("qfac0.nii", qform_only)
        ref = nib.load(f)
        with open(f, "r+b") as fh:
            fh.seek(76)
            fh.write(struct.pack("<f", 0.0))
        self.assert_same(ref, self.roundtrip(f))
        # An extension pushes the data further (vox_offset > 352).
        img = nib.Nifti1Image(data, aff)
        img.header.extensions.append(nib.nifti1.Nifti1Extension(6, b"horizon test extension"))
        f = self.path("ext.nii")
        nib.save(img, f)
        with open(f, "rb") as fh:
            fh.seek(108)
            self.assertGreater(struct.unpack("<f", fh.read(4))[0], 352)
        self.assert_same(nib.load(f), self.roundtrip(f))
        # No orientation at all: the references disagree on the affine, so data only.
        img = nib.Nifti1Image(data, aff)
        img.header.set_qform(None, 0)
        img.header.set_sform(None, 0)
        f = self.path("noxform.nii")
        nib.save(img, f)
        np.testing.assert_array_equal(self.roundtrip(f).get_fdata(), nib.load(f).get_fdata())

    def test_nibabel_test_data(self):
        data_dir = os.path.join(os.path.dirname(nib.__file__), "tests", "data")
        tried = 0
        for name in sorted(os.listdir(data_dir)):
            if not (name.endswith(".nii") or name.endswith(".nii.gz")):
                continue
            path = os.path.join(data_dir, name)
            try:
                ref = nib.load(path)
                ref_data = ref.get_fdata()
            except Exception:
                continue  # nibabel cannot read it either
            if ref_data.dtype.kind == "c":
                continue
            with self.subTest(file=name):
                p = run("convert", path, self.path("t.nii"), "--force")
                if p.returncode != 0:
                    # Only unsupported datatypes may be refused, cleanly.
                    self.assert_clean_error(p, name)
                    self.assertRegex(p.stderr, "not supported|datatype")
                    continue
                tried += 1
                np.testing.assert_array_equal(np.squeeze(nib.load(self.path("t.nii")).get_fdata()), np.squeeze(ref_data))
        self.assertGreater(tried, 5)

    def test_malformed(self):
        rng = np.random.default_rng(6)
        data = (rng.random((10, 11, 12)) * 100).astype(np.int16)
        good_path = self.path("good.nii")
        nib.save(nib.Nifti1Image(data, np.eye(4)), good_path)
        with open(good_path, "rb") as fh:
            good = fh.read()
        def patched(off, fmt, value, base=good):
            b = bytearray(base)
            b[off:off + struct.calcsize(fmt)] = struct.pack(fmt, value)
            return bytes(b)
        n2_path = self.path("good2.nii")
        nib.save(nib.Nifti2Image(data, np.eye(4)), n2_path)
        with open(n2_path, "rb") as fh:
            good2 = fh.read()
        cases = {
            "truncated_data.nii": good[:-100],
            "truncated_header.nii": good[:69],
            "bad_sizeof_hdr.nii": patched(0, "<i", 349),
            "bad_magic.nii": good[:344] + b"n+3\0" + good[348:],
            "dim0_zero.nii": patched(40, "<h", 0),
            "dim0_nine.nii": patched(40, "<h", 9),
            "negative_dim.nii": patched(42, "<h", -20),
            "absurd_dims.nii": patched(42, "<h", 2048) and bytes(bytearray(patched(44, "<h", 1024, patched(46, "<h", 1024, patched(42, "<h", 2048))))),
            "voxoffset_beyond_eof.nii": patched(108, "<f", 1e7),
            "unknown_datatype.nii": patched(70, "<h", 9999),
            "nii2_absurd_dims.nii": patched(16 + 8, "<q", 2 ** 50, good2),
            "nii2_bad_magic.nii": good2[:4] + b"n+2\0\0\0\0\0" + good2[12:],
        }
        for name, blob in cases.items():
            with self.subTest(case=name):
                f = self.path(name)
                with open(f, "wb") as fh:
                    fh.write(blob)
                self.assert_clean_error(run("info", f, timeout=10), name)
        gz_cases = {
            "niigz_truncated.nii.gz": gzip.compress(good)[:-500],
            "niigz_absurd_dims.nii.gz": gzip.compress(bytes(bytearray(patched(44, "<h", 1024, patched(46, "<h", 1024, patched(42, "<h", 2048)))))),
        }
        corrupt = bytearray(gzip.compress(good))
        for i in range(60, 90):
            corrupt[i] ^= 0xA5
        gz_cases["niigz_corrupt_stream.nii.gz"] = bytes(corrupt)
        for name, blob in gz_cases.items():
            with self.subTest(case=name):
                f = self.path(name)
                with open(f, "wb") as fh:
                    fh.write(blob)
                self.assert_clean_error(run("info", f, timeout=10), name)
        # Pairs: a missing or short image file.
        pair = self.path("pair.hdr")
        nib.save(nib.Nifti1Pair(data, np.eye(4)), pair)
        os.remove(self.path("pair.img"))
        self.assert_clean_error(run("info", pair), "pair")
        nib.save(nib.Nifti1Pair(data, np.eye(4)), self.path("short.hdr"))
        with open(self.path("short.img"), "r+b") as fh:
            fh.truncate(os.path.getsize(self.path("short.img")) // 2)
        self.assert_clean_error(run("info", self.path("short.hdr")), "short")

    def test_a_pair_is_replaced_as_a_unit(self):
        """A .hdr/.img pair is one output: when the second file cannot be put
        in place (its rename fails, injected by an LD_PRELOAD shim), the first
        one is taken back, and with --force the pair it replaced is back as
        it was, byte for byte; nothing is left beside them. A half-new pair
        (a new .img beside the old .hdr) is a volume that was never written."""
        shim = os.path.join(BUILD, "tests", "fixtures", "hz_fail_rename.so")
        self.assertTrue(os.path.exists(shim), shim)
        rng = np.random.default_rng(12)
        old_path, new_path = self.path("old.nii"), self.path("new.nii")
        nib.save(nib.Nifti1Image(rng.random((4, 5, 6)).astype(np.float32), np.eye(4)), old_path)
        nib.save(nib.Nifti1Image(rng.random((3, 3, 3)).astype(np.int16), np.eye(4)), new_path)

        def failing(suffix):
            env = {"LD_PRELOAD": shim, "HZ_FAIL_RENAME_TO": suffix}
            if "ASAN_OPTIONS" in os.environ:
                env["ASAN_OPTIONS"] = os.environ["ASAN_OPTIONS"] + ":verify_asan_link_order=0"
            return env

        for target, other in (("hdr", "img"), ("img", "hdr")):
            with self.subTest(target=target):
                out, companion = self.path(f"pair.{target}"), self.path(f"pair.{other}")
                self.assertEqual(run("convert", old_path, out, "--force").returncode, 0)
                before = {f: open(f, "rb").read() for f in (out, companion)}
                # (the file named is put in place last: its rename fails)
                p = run("convert", new_path, out, "--force", env=failing("." + target))
                self.assertEqual(p.returncode, 1)
                self.assertEqual(len(p.stderr.strip().splitlines()), 1, p.stderr)
                self.assertIn(out, p.stderr)
                self.assertEqual({f: open(f, "rb").read() for f in (out, companion)}, before, "the old pair, whole")
                self.assertEqual(sorted(n for n in os.listdir(self.tmp) if n.startswith(".")), [])
                # A new pair: neither file appears.
                fresh = self.path(f"fresh.{target}")
                p = run("convert", new_path, fresh, env=failing("." + target))
                self.assertEqual(p.returncode, 1)
                self.assertFalse(os.path.exists(fresh) or os.path.exists(self.path(f"fresh.{other}")))
                # Without the fault, --force replaces both.
                self.assertEqual(run("convert", new_path, out, "--force").returncode, 0)
                self.assertEqual(nib.load(out).shape, (3, 3, 3))
                self.assertEqual(sorted(n for n in os.listdir(self.tmp) if n.startswith(".")), [])

    def test_writes_pairs(self):
        """convert writes .hdr/.img pairs (plain and gzipped) that nibabel reads
        as it reads the source; both files appear together or not at all."""
        rng = np.random.default_rng(11)
        for i, dt in enumerate((np.int16, np.float32, np.uint8)):
            data = (rng.random((5, 6, 7, 2)) * 90).astype(dt)
            src_path = self.path(f"src{i}.nii.gz")
            nib.save(nib.Nifti1Image(data, random_affine(rng)), src_path)
            src = nib.load(src_path)
            for target, other in (("hdr", "img"), ("img", "hdr"), ("hdr.gz", "img.gz"), ("img.gz", "hdr.gz")):
                with self.subTest(dtype=np.dtype(dt).name, target=target):
                    out = self.path(f"p{i}.{target}")
                    ours = self.roundtrip(src_path, os.path.basename(out))
                    self.assertIsInstance(ours, nib.Nifti1Pair)
                    self.assertNotIsInstance(ours, nib.Nifti1Image)
                    self.assertTrue(os.path.exists(self.path(f"p{i}.{other}")))
                    self.assertEqual(ours.header["magic"], b"ni1")
                    self.assert_same(src, ours)
                    # And back into a single file.
                    self.assert_same(src, self.roundtrip(out, f"back{i}.nii"))
        # An existing companion is not replaced without --force, and nothing is left behind.
        src_path = self.path("src0.nii.gz")
        with open(self.path("lonely.img"), "wb") as f:
            f.write(b"keep me")
        p = run("convert", src_path, self.path("lonely.hdr"))
        self.assert_clean_error(p, "lonely.img")
        self.assertIn("already exists", p.stderr)
        self.assertFalse(os.path.exists(self.path("lonely.hdr")))
        with open(self.path("lonely.img"), "rb") as f:
            self.assertEqual(f.read(), b"keep me")
        self.assertEqual([n for n in os.listdir(self.tmp) if ".tmp-" in n], [])
        self.assertEqual(run("convert", src_path, self.path("lonely.hdr"), "--force").returncode, 0)
        self.assert_same(nib.load(src_path), nib.load(self.path("lonely.hdr")))
