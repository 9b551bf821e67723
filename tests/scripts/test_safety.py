"""Nothing a user feeds horizon harms their data or their machine (issue 28).

Each case is one class of the probe: outputs that are devices or inputs,
full disks, file size limits, signals, races, companion files that point
elsewhere, FIFOs that would block, data shown through the tone curve. Cases
that need root (mknod, a tmpfs for a full disk) fail in CI when not root
(CI runs as root) and are skipped elsewhere.
"""
import json
import os
import resource
import signal
import struct
import subprocess
import time
import unittest

import numpy as np
from PIL import Image

from hztest import HORIZON, TempDirTest, environment, run, tck_bytes

ROOT = os.geteuid() == 0
IN_CI = bool(os.environ.get("CI"))


def needs_root(test):
    if ROOT or IN_CI:
        return test
    return unittest.skip("needs root (mknod, mount)")(test)


def temporaries(folder):
    return [n for n in os.listdir(folder) if ".tmp-" in n]


class SafetyTest(TempDirTest):
    def setUp(self):
        super().setUp()
        self.tck = self.path("in.tck")
        rng = np.random.default_rng(1)
        lines = [np.cumsum(rng.normal(size=(40, 3)), axis=0) for _ in range(300)]
        with open(self.tck, "wb") as f:
            f.write(tck_bytes(lines))

    # -- outputs -----------------------------------------------------------
    @needs_root
    def test_a_device_is_never_replaced(self):
        self.assertTrue(ROOT, "CI runs as root")
        dev = self.path("null")
        os.mknod(dev, 0o666 | 0o020000, os.makedev(1, 3))
        p = run("cluster", self.tck, "--labels", dev, "--force")
        self.assert_clean_error(p, dev)
        self.assertIn("not a regular file", p.stderr)
        self.assertTrue(os.path.exists(dev) and not os.path.isfile(dev), "still a device")
        fifo = self.path("pipe.png")
        os.mkfifo(fifo)
        p = run("render", self.tck, "-o", fifo, "--force", timeout=120)
        self.assert_clean_error(p, fifo)
        self.assertFalse(os.path.isfile(fifo))
        self.assertEqual(temporaries(self.tmp), [])

    def test_dash_is_standard_output(self):
        p = subprocess.run([HORIZON, "cluster", self.tck, "--labels", "-"], capture_output=True, timeout=120, env=environment("cluster"))
        self.assertEqual(p.returncode, 0, p.stderr)
        rows = p.stdout.decode().splitlines()
        self.assertTrue(rows[0].startswith("streamline,"), rows[:2])
        self.assertEqual(len(rows), 301)
        p = subprocess.run([HORIZON, "render", self.tck, "-o", "-", "--size", "64x48"], capture_output=True, timeout=120,
                           env=environment("render"))
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(p.stdout[:8], b"\x89PNG\r\n\x1a\n")
        self.assertEqual(temporaries(self.tmp), [])

    def test_no_output_replaces_an_input(self):
        before = open(self.tck, "rb").read()
        for args in (("cluster", self.tck, "--labels", self.tck, "--force"), ("cluster", self.tck, "--out", self.tck, "--force"),
                     ("convert", self.tck, self.tck, "--force"), ("render", self.tck, "-o", self.tck, "--force")):
            p = run(*args, timeout=120)
            self.assert_clean_error(p, self.tck)
            self.assertIn("refusing to overwrite the input", p.stderr)
        self.assertEqual(open(self.tck, "rb").read(), before)
        # A NIfTI pair's other half, and two outputs naming one file.
        import nibabel as nib
        nib.save(nib.Nifti1Pair(np.zeros((4, 4, 4), np.float32), np.eye(4)), self.path("v.hdr"))
        img = open(self.path("v.img"), "rb").read()
        p = run("render", self.path("v.hdr"), "-o", self.path("v.img"), "--force", timeout=120)
        self.assert_clean_error(p, "v.img")
        self.assertEqual(open(self.path("v.img"), "rb").read(), img)
        p = run("cluster", self.tck, "--labels", self.path("x.csv"), "--out", self.path("x.csv"))
        self.assert_clean_error(p, "x.csv")
        # Inputs named indirectly (issue 53): an ordering file, and every
        # file a scene file names (here its environment map and a mesh).
        order = self.path("order.txt")
        with open(order, "w") as f:
            f.write("\n".join(str(i) for i in range(300)) + "\n")
        before = open(order, "rb").read()
        p = run("cluster", self.tck, "--order", order, "--labels", order, "--force")
        self.assert_clean_error(p, "order.txt")
        self.assertIn("refusing to overwrite the input", p.stderr)
        self.assertEqual(open(order, "rb").read(), before)
        Image.fromarray(np.full((8, 16, 3), 200, np.uint8)).save(self.path("env.png"))
        env = open(self.path("env.png"), "rb").read()
        p = run("convert", self.tck, self.path("copy.trk"))
        self.assertEqual(p.returncode, 0, p.stderr)
        with open(self.path("scene.json"), "w") as f:
            json.dump({"environment": {"path": "env.png"}, "objects": [{"type": "streamlines", "file": "copy.trk"}]}, f)
        for out in ("env.png", "copy.trk"):
            p = run("render", self.path("scene.json"), "-o", self.path(out), "--force", "--size", "32x24", timeout=120)
            self.assert_clean_error(p, out)
            self.assertIn("refusing to overwrite the input file " + self.path(out), p.stderr)
        self.assertEqual(open(self.path("env.png"), "rb").read(), env)

    def test_existing_outputs_need_force(self):
        for args, out in ((("convert", self.tck, self.path("o.trk")), "o.trk"), (("cluster", self.tck, "--labels", self.path("l.csv")), "l.csv"),
                          (("render", self.tck, "-o", self.path("o.png"), "--size", "64x48"), "o.png")):
            with open(self.path(out), "w") as f:
                f.write("keep me")
            p = run(*args, timeout=120)
            self.assert_clean_error(p, out)
            self.assertIn("--force", p.stderr)
            self.assertEqual(open(self.path(out)).read(), "keep me")
            self.assertEqual(run(*args, "--force", timeout=120).returncode, 0)
            self.assertNotEqual(open(self.path(out), "rb").read(), b"keep me")

    def test_two_writers_of_one_new_output(self):
        # Without --force, exactly one of two simultaneous writers succeeds
        # (the check and the rename are one atomic step).
        big = self.path("big.tck")
        rng = np.random.default_rng(2)
        with open(big, "wb") as f:
            f.write(tck_bytes([np.cumsum(rng.normal(size=(100, 3)), axis=0) for _ in range(20000)]))
        out = self.path("race.trk")
        for _ in range(3):
            if os.path.exists(out):
                os.remove(out)
            procs = [subprocess.Popen([HORIZON, "convert", big, out], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                      env=environment("convert"))
                     for _ in range(2)]
            errs = [p.communicate(timeout=120)[1] for p in procs]
            codes = sorted(p.returncode for p in procs)
            self.assertEqual(codes, [0, 1], errs)
            self.assertIn("already exists", "".join(errs))
        self.assertEqual(temporaries(self.tmp), [])

    @needs_root
    def test_full_disk_is_an_error_not_a_truncated_file(self):
        self.assertTrue(ROOT, "CI runs as root")
        disk = self.path("disk")
        os.mkdir(disk)
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", disk], check=True)
        try:
            import nibabel as nib  # noqa: F401
            surf = self.path("s.gii")
            self.make_gifti(surf, n=4000)
            cases = [("render", self.tck, "-o", os.path.join(disk, "x.png"), "--size", "640x480"),
                     ("render", self.tck, "-o", os.path.join(disk, "x.jpg"), "--size", "640x480"),
                     ("convert", surf, os.path.join(disk, "x.gltf")), ("convert", surf, os.path.join(disk, "x.glb")),
                     ("convert", self.tck, os.path.join(disk, "x.trk")), ("cluster", self.tck, "--labels", os.path.join(disk, "l.csv"))]
            with open(os.path.join(disk, "fill"), "wb", buffering=0) as f:  # to the last byte
                try:
                    while True:
                        f.write(b"\0" * 512)
                except OSError:
                    pass
            for args in cases:
                p = run(*args, timeout=120)
                self.assertNotEqual(p.returncode, 0, f"{args}: {p.stdout}")
                self.assertIn("horizon: error:", p.stderr)
                self.assertIn("No space left", p.stderr)
                self.assertEqual(sorted(os.listdir(disk)), ["fill"], f"{args}: nothing left at the final name or as a temporary")
        finally:
            subprocess.run(["umount", disk])

    def test_file_size_limit_is_an_error(self):
        def limit():
            resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))
        out = self.path("big.trk")
        p = subprocess.run([HORIZON, "convert", self.tck, out], capture_output=True, text=True, timeout=120, preexec_fn=limit,
                           env=environment("convert"))
        self.assertEqual(p.returncode, 1, p.stderr)
        self.assertIn("File too large", p.stderr)
        self.assertFalse(os.path.exists(out))
        self.assertEqual(temporaries(self.tmp), [])

    def test_a_failed_forced_write_keeps_the_old_output(self):
        # --force replaces an output only once the new one is complete.
        def limit():
            resource.setrlimit(resource.RLIMIT_FSIZE, (1500, 1500))
        for args, out in ((("cluster", self.tck, "--labels"), "l.csv"), (("convert", self.tck), "o.trk"),
                          (("render", self.tck, "--size", "320x200", "-o"), "o.png")):
            with open(self.path(out), "w") as f:
                f.write("keep me")
            p = subprocess.run([HORIZON, *args, self.path(out), "--force"], capture_output=True, text=True, timeout=120, preexec_fn=limit,
                               env=environment(*args))
            self.assertNotEqual(p.returncode, 0, out)
            self.assertIn("File too large", p.stderr)
            with open(self.path(out)) as f:
                self.assertEqual(f.read(), "keep me", out)
        self.assertEqual(temporaries(self.tmp), [])

    def test_signals_leave_no_temporary(self):
        big = self.path("big.tck")
        rng = np.random.default_rng(3)
        with open(big, "wb") as f:
            f.write(tck_bytes([np.cumsum(rng.normal(size=(200, 3)), axis=0) for _ in range(60000)]))
        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            out = self.path("sig.trk")
            p = subprocess.Popen([HORIZON, "convert", big, out, "--force"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 env=environment("convert"))
            deadline = time.time() + 60
            while not temporaries(self.tmp) and p.poll() is None and time.time() < deadline:
                time.sleep(0.005)
            p.send_signal(sig)
            p.wait(timeout=60)
            if p.returncode == 0:
                continue  # (it finished first: nothing to clean)
            self.assertEqual(p.returncode, -sig)
            self.assertEqual(temporaries(self.tmp), [], sig)

    def test_a_signal_while_libzip_writes_leaves_nothing(self):
        """libzip writes a TRX to a file of its own beside the temporary it
        was given (TEMP.XXXXXX), then renames it: a signal then left that
        file (issue 53). Interrupted once it is there: nothing is left."""
        import re
        big = self.path("big.tck")
        rng = np.random.default_rng(4)
        with open(big, "wb") as f:
            f.write(tck_bytes([np.cumsum(rng.normal(size=(200, 3)), axis=0) for _ in range(60000)]))
        libzips = lambda: [n for n in temporaries(self.tmp) if re.search(r"\.tmp-\d+-\d+\.", n)]
        caught = 0
        for _ in range(3):
            p = subprocess.Popen([HORIZON, "convert", big, self.path("sig.trx"), "--force"], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL, env=environment("convert"))
            deadline = time.time() + 60
            while not libzips() and p.poll() is None and time.time() < deadline:
                time.sleep(0.002)
            p.send_signal(signal.SIGINT)
            p.wait(timeout=60)
            if p.returncode == 0:
                continue  # (it finished first)
            caught += 1
            self.assertEqual(p.returncode, -signal.SIGINT)
            self.assertEqual(temporaries(self.tmp), [])
        self.assertGreater(caught, 0, "never interrupted while libzip wrote")

    def test_stale_temporaries_are_removed(self):
        # Left by a process that is gone (a power cut, SIGKILL).
        stale = self.path(".out.trk.tmp-999999999-12")
        with open(stale, "w") as f:
            f.write("x")
        # Beside it, the temporary of a writer still running (another
        # process's, for the same output): left alone.
        writer = subprocess.Popen(["sleep", "60"])
        try:
            live = self.path(f".out.trk.tmp-{writer.pid}-34")
            with open(live, "w") as f:
                f.write("y")
            self.assertEqual(run("convert", self.tck, self.path("out.trk")).returncode, 0)
            self.assertFalse(os.path.exists(stale))
            self.assertTrue(os.path.exists(live), "a live writer's temporary was removed")
        finally:
            writer.kill()
            writer.wait()

    def test_sizes_are_bounded_before_allocating(self):
        """Counts and sizes are bounded before memory is taken, in one line
        that says the limit (issue 53: a scene's phantom of 2^32 streamlines
        grew past 10 GB; a 0.8 MB PNG of 16384 x 16384 as an environment map
        took 11 GB). Run under a 3 GB address-space limit: an attempt to
        take the memory would end as an out-of-memory error instead. (Not
        under AddressSanitizer, whose shadow memory needs far more address
        space: the same errors must come, without the limit.)"""
        def limited():
            if "ASAN_OPTIONS" not in os.environ:
                resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

        def run_limited(*args):
            return subprocess.run([HORIZON, *args], capture_output=True, text=True, timeout=120, env=environment(*args), preexec_fn=limited)

        with open(self.path("phantom.json"), "w") as f:
            json.dump({"objects": [{"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 2 ** 32}}]}, f)
        p = run_limited("render", self.path("phantom.json"), "-o", self.path("x.png"))
        self.assert_clean_error(p, "phantom.json")
        self.assertIn("objects[0].phantom.streamlines", p.stderr)
        Image.new("L", (16384, 16384)).save(self.path("huge.png"))
        self.assertLess(os.path.getsize(self.path("huge.png")), 2 << 20)
        with open(self.path("env.json"), "w") as f:
            json.dump({"environment": {"path": "huge.png"}, "objects": [{"type": "streamlines", "file": self.tck}]}, f)
        p = run_limited("render", self.path("env.json"), "-o", self.path("x.png"), "--size", "64x48")
        self.assert_clean_error(p, "huge.png")
        self.assertIn("environment map of 16384x16384 pixels, more than the 134217728 it may have: downsample it", p.stderr)
        self.assertFalse(os.path.exists(self.path("x.png")))
        # Any volume or image: no more than the memory available.
        import nibabel as nib
        nib.save(nib.Nifti1Image(np.zeros((64, 64, 64), np.float32), np.eye(4)), self.path("v.nii"))
        p = run("info", self.path("v.nii"), env={"HORIZON_MEMORY_AVAILABLE_MB": "0"})
        self.assert_clean_error(p, "v.nii")
        self.assertIn("its 64x64x64 values need 1 MB of memory, and 0 MB are available", p.stderr)
        self.assertEqual(run("info", self.path("v.nii")).returncode, 0)

    def test_long_output_names(self):
        """An output name of 250 bytes is valid (NAME_MAX is 255): its hidden
        temporary's name is cut to fit, at a character boundary (issue 53:
        it failed), and a stale temporary of such a name is still found."""
        name = "é" * 3 + "a" * 240  # 246 bytes, the cut falling inside the é's when shifted below
        for out, args in ((name + ".trk", ("convert", self.tck)), (name + ".csv", ("cluster", self.tck, "--labels")),
                          (name + ".png", ("render", self.tck, "--size", "64x48", "-o"))):
            self.assertEqual(len(out.encode()), 250)
            p = run(*args, self.path(out), timeout=120)
            self.assertEqual(p.returncode, 0, p.stderr)
            self.assertTrue(os.path.exists(self.path(out)))
        self.assertEqual(temporaries(self.tmp), [])
        # The temporaries' prefix: "." + the name cut to 232 bytes + ".tmp-"
        # (232 = 255 - 1 - len(".tmp-") - len("PID-RANDOM") at most 17).
        long_name = "b" + "é" * 120 + ".trk"  # 245 bytes; byte 232 is inside an é
        cut = long_name.encode()[:231].decode()  # (the character boundary below 232)
        stale = self.path("." + cut + ".tmp-999999999-12")
        with open(stale, "w") as f:
            f.write("x")
        p = run("convert", self.tck, self.path(long_name))
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertFalse(os.path.exists(stale))

    def test_a_full_standard_output_is_an_error(self):
        """What a command writes to standard output must arrive: `info` and
        `plugins` into /dev/full exit 1 with one line (issue 53: exit 0)."""
        for args in (("info", self.tck), ("info", self.tck, "--json"), ("plugins",), ("plugins", "--json")):
            with open("/dev/full", "w") as full:
                p = subprocess.run([HORIZON, *args], stdout=full, stderr=subprocess.PIPE, text=True, timeout=60, env=environment(*args))
            self.assertEqual(p.returncode, 1, args)
            self.assertEqual(p.stderr.strip().splitlines(), ["horizon: error: standard output: a write failed"], args)

    # -- inputs ------------------------------------------------------------
    def make_gifti(self, path, n=3, external=None):
        data = "<Data>" + " ".join("0" for _ in range(n * 3)) + "</Data>"
        enc = "ASCII"
        if external is not None:
            enc, data = f'ExternalFileBinary" ExternalFileName="{external}" ExternalFileOffset="0', "<Data></Data>"
        tris = " ".join(f"0 {i} {i + 1}" for i in range(1, n - 1))
        with open(path, "w") as f:
            f.write(f'''<?xml version="1.0" encoding="UTF-8"?>
<GIFTI Version="1.0" NumberOfDataArrays="2">
<DataArray Intent="NIFTI_INTENT_POINTSET" DataType="NIFTI_TYPE_FLOAT32" ArrayIndexingOrder="RowMajorOrder" Dimensionality="2" Dim0="{n}" Dim1="3" Encoding="{enc}" Endian="LittleEndian">{data}</DataArray>
<DataArray Intent="NIFTI_INTENT_TRIANGLE" DataType="NIFTI_TYPE_INT32" ArrayIndexingOrder="RowMajorOrder" Dimensionality="2" Dim0="{n - 2}" Dim1="3" Encoding="ASCII" Endian="LittleEndian"><Data>{tris}</Data></DataArray>
</GIFTI>
''')

    def test_an_input_truncated_while_mapped(self):
        # The pages past the new end raise SIGBUS: one line naming the file
        # and exit status 1, never a death by signal (whichever moment the
        # truncation hits: before the open, during the read, or after).
        big = self.path("big.tck")
        rng = np.random.default_rng(6)
        with open(big, "wb") as f:
            f.write(tck_bytes([np.cumsum(rng.normal(size=(150, 3)), axis=0) for _ in range(40000)]))
        data = open(big, "rb").read()
        seen_error = False
        for delay in (0.0, 0.02, 0.05, 0.1, 0.2, 0.4):
            with open(big, "wb") as f:
                f.write(data)
            p = subprocess.Popen([HORIZON, "cluster", big, "--labels", self.path("l.csv"), "--force"], stdout=subprocess.DEVNULL, env=environment("cluster"),
                                 stderr=subprocess.PIPE, text=True)
            time.sleep(delay)
            os.truncate(big, 4096)
            err = p.communicate(timeout=120)[1]
            self.assertIn(p.returncode, (0, 1), err)
            if p.returncode == 1:
                seen_error = True
                self.assertEqual(len(err.strip().splitlines()), 1, err)
                self.assertIn("big.tck", err)
        self.assertTrue(seen_error)

    def test_companion_files_stay_in_the_folder(self):
        secret = self.path("secret.bin")
        with open(secret, "wb") as f:
            f.write(np.arange(9, dtype="<f4").tobytes())
        sub = self.path("sub")
        os.mkdir(sub)
        os.symlink(secret, os.path.join(sub, "link.bin"))
        os.mkfifo(os.path.join(sub, "fifo.bin"))
        with open(os.path.join(sub, "ok.bin"), "wb") as f:
            f.write(np.arange(9, dtype="<f4").tobytes())
        gltf = {"asset": {"version": "2.0"}, "buffers": [{"uri": None, "byteLength": 36}],
                "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
                "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 1, 2], "max": [6, 7, 8]}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0}
        for name, ok in (("ok.bin", True), ("../secret.bin", False), (secret, False), ("link.bin", False), ("fifo.bin", False)):
            for kind in ("gltf", "gifti"):
                path = os.path.join(sub, f"m.{'gltf' if kind == 'gltf' else 'surf.gii'}")
                if kind == "gltf":
                    gltf["buffers"][0]["uri"] = name
                    with open(path, "w") as f:
                        json.dump(gltf, f)
                else:
                    self.make_gifti(path, external=name)
                out = self.path(f"copy.{kind}.glb")
                if os.path.exists(out):
                    os.remove(out)
                p = run("convert", path, out, timeout=20)
                if ok:
                    self.assertEqual(p.returncode, 0, p.stderr)
                else:
                    self.assert_clean_error(p, path)
                    self.assertRegex(p.stderr, "outside the file's folder|absolute path|not a regular file|File not found")
                    self.assertFalse(os.path.exists(out))

    def test_fifo_inputs_do_not_block(self):
        import nibabel as nib
        nib.save(nib.Nifti1Pair(np.zeros((4, 4, 4), np.float32), np.eye(4)), self.path("v.hdr"))
        os.remove(self.path("v.img"))
        os.mkfifo(self.path("v.img"))
        p = run("info", self.path("v.hdr"), timeout=20)
        self.assert_clean_error(p, "v.img")
        os.mkfifo(self.path("f.tck"))
        p = run("info", self.path("f.tck"), timeout=20)
        self.assert_clean_error(p, "f.tck")

    def test_small_text_inputs_are_bounded(self):
        """A scene or ordering file that is /dev/zero (or a link to it) or a
        FIFO is refused at once, one line naming it (issue 53: /dev/zero was
        read to 2 GB before the size check, a FIFO blocked for ever)."""
        os.symlink("/dev/zero", self.path("zero.json"))
        os.mkfifo(self.path("fifo.json"))
        for scene in (self.path("zero.json"), self.path("fifo.json")):
            t0 = time.monotonic()
            p = run("render", scene, "-o", self.path("x.png"), "--size", "32x24", timeout=30)
            self.assert_clean_error(p, scene)
            self.assertIn(scene + ": the scene file is not a regular file", p.stderr)
            self.assertLess(time.monotonic() - t0, 20)
        p = run("cluster", self.tck, "--order", self.path("fifo.json"), "--labels", self.path("l.csv"), timeout=30)
        self.assert_clean_error(p, "fifo.json")
        self.assertIn("the ordering file is not a regular file", p.stderr)
        # A scene larger than its bound is refused by its size, before it is read.
        with open(self.path("big.json"), "wb") as f:
            f.truncate((64 << 20) + 1)
        p = run("render", self.path("big.json"), "-o", self.path("x.png"), "--size", "32x24", timeout=30)
        self.assert_clean_error(p, "big.json")
        self.assertIn("scene file larger than 64 MiB", p.stderr)
        self.assertFalse(os.path.exists(self.path("x.png")))

    def test_trk_with_a_singular_affine_is_refused(self):
        # nibabel refuses it as well; accepted, every point would collapse.
        import nibabel as nib
        path = self.path("singular.trk")
        nib.streamlines.save(nib.streamlines.Tractogram([np.array([[1.0, 2, 3], [4, 5, 6]], np.float32)], affine_to_rasmm=np.eye(4)), path)
        with open(path, "rb") as f:
            data = bytearray(f.read())
        data[440:504] = np.diag([0.0, 0.0, 0.0, 1.0]).astype("<f4").tobytes()
        with open(path, "wb") as f:
            f.write(bytes(data))
        p = run("info", path)
        self.assert_clean_error(p, path)
        self.assertIn("singular", p.stderr)

    def test_streamlines_without_points_are_left_out_of_a_trk(self):
        # A TRX (here a TCK) with an empty streamline and per-streamline data,
        # converted to TRK: nibabel must read it (it could not).
        import nibabel as nib
        src = self.path("e.trx")
        lines = [np.zeros((0, 3), np.float32), np.array([[0, 0, 0], [1, 1, 1]], np.float32), np.array([[2, 2, 2], [3, 3, 3]], np.float32)]
        from test_trx import make_trx
        make_trx(src, lines, dpv=False, extra={"dps/weight.float32": np.array([1.0, 2.0, 3.0], np.float32).tobytes()})
        out = self.path("e.trk")
        p = run("convert", src, out)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("without points", p.stderr)
        t = nib.streamlines.load(out)
        self.assertEqual(len(t.streamlines), 2)
        np.testing.assert_allclose(t.tractogram.data_per_streamline["weight"].ravel(), [2.0, 3.0])

    # -- messages ----------------------------------------------------------
    def on_terminal(self, *args):
        # Runs horizon with stderr on a pseudo-terminal; returns what it showed there.
        import pty
        master, slave = pty.openpty()
        env = environment(*args, env={"HORIZON_PROGRESS_DELAY": "0"})
        p = subprocess.Popen([HORIZON, *args], stdout=subprocess.PIPE, stderr=slave, env=env)
        os.close(slave)
        shown = b""
        while True:
            try:
                chunk = os.read(master, 4096)
            except OSError:
                break
            if not chunk:
                break
            shown += chunk
        out = p.communicate(timeout=120)[0]
        os.close(master)
        self.assertEqual(p.returncode, 0, shown)
        return shown.decode(errors="replace"), out.decode()

    def test_odd_file_names_keep_errors_on_one_line(self):
        # A newline in a name does not split the error; a name that is not
        # UTF-8 does not break --json.
        odd = self.path("two\nlines.tck")
        with open(odd, "wb") as f:
            f.write(b"not a tractogram")
        p = run("info", odd)
        self.assertEqual(p.returncode, 1)
        self.assertEqual(len(p.stderr.splitlines()), 1, p.stderr)
        self.assertIn("two\\nlines.tck", p.stderr)
        raw = os.path.join(os.fsencode(self.tmp), b"caf\xe9.tck")
        with open(raw, "wb") as f:
            f.write(tck_bytes([np.zeros((3, 3))]))
        p = subprocess.run([os.fsencode(HORIZON), b"info", raw, b"--json"], capture_output=True, timeout=60, env=environment("info"))
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(json.loads(p.stdout.decode("utf-8"))["nb_streamlines"], 1)

    def test_progress_lines_on_a_terminal_only(self):
        big = self.path("big.tck")
        rng = np.random.default_rng(4)
        with open(big, "wb") as f:
            f.write(tck_bytes([np.cumsum(rng.normal(size=(100, 3)), axis=0) for _ in range(30000)]))
        shown, _ = self.on_terminal("cluster", big, "--labels", self.path("l.csv"))
        self.assertRegex(shown, r"horizon: clustering 30000 streamlines \(qbx\) \.\.\. ")
        self.assertIn("\r\x1b[K", shown, "the line is cleared when the work ends")
        # Not on a terminal, or with --json: no progress line.
        p = run("cluster", big, "--labels", self.path("l.csv"), "--force", env={"HORIZON_PROGRESS_DELAY": "0"})
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertNotIn("clustering", p.stderr)
        shown, out = self.on_terminal("cluster", big, "--labels", self.path("l.csv"), "--force", "--json")
        self.assertNotIn("horizon: clustering", shown)
        json.loads(out)

    # -- pictures ----------------------------------------------------------
    def test_meaningless_render_parameters_are_refused(self):
        import nibabel as nib
        nib.save(nib.Nifti1Image(np.zeros((8, 8, 8), np.float32), np.eye(4)), self.path("v.nii.gz"))
        tracts = {"type": "streamlines", "file": self.tck}
        slices = {"type": "slices", "file": self.path("v.nii.gz")}
        cases = {"exposure": ({"objects": [tracts], "exposure": -1}, "exposure"),
                 "zoom": ({"objects": [tracts], "camera": {"zoom": 0}}, "camera.zoom"),
                 "opacity": ({"objects": [{**tracts, "opacity": 2}]}, "objects[0].opacity"),
                 "radius": ({"objects": [{**tracts, "radius": -1}]}, "objects[0].radius"),
                 "window": ({"objects": [{**slices, "window": [3, 3]}]}, "objects[0].window"),
                 "slice": ({"objects": [{**slices, "z": 100}]}, "outside the volume"),
                 "hidden": ({"objects": [{**tracts, "visible": False}]}, "nothing to draw")}
        for name, (scene, where) in cases.items():
            with self.subTest(case=name):
                f = self.path(name + ".json")
                with open(f, "w") as fh:
                    json.dump(scene, fh)
                out = self.path(name + ".png")
                p = run("render", f, "-o", out, "--size", "64x48", timeout=120)
                self.assert_clean_error(p, name + ".json")
                self.assertIn(where, p.stderr)
                self.assertFalse(os.path.exists(out))
        empty = self.path("empty.tck")
        with open(empty, "wb") as fh:
            fh.write(tck_bytes([]))
        p = run("render", empty, "-o", self.path("e.png"), timeout=120)
        self.assert_clean_error(p, "empty.tck")
        self.assertIn("nothing to draw", p.stderr)


    def test_data_is_shown_as_it_is(self):
        # A 0-1 ramp through window [0, 1] and the gray colormap: pixel values
        # follow the colormap (linear for gray), whatever the exposure: only
        # lit geometry goes through exposure and the tone curve.
        import nibabel as nib
        x = np.linspace(0, 1, 64, dtype=np.float32)
        nib.save(nib.Nifti1Image(np.broadcast_to(x[:, None, None], (64, 64, 64)).copy(), np.eye(4)), self.path("ramp.nii.gz"))
        for exposure in (1.0, 2.5):
            for tonemap in ("aces", "reinhard"):
                scene = {"objects": [{"type": "slices", "file": self.path("ramp.nii.gz"), "x": None, "y": None, "z": 32, "window": [0, 1],
                                      "colormap": "gray"}],
                         "camera": {"view": "superior"}, "background": [0, 0, 0], "exposure": exposure, "tonemap": tonemap}
                with open(self.path("s.json"), "w") as f:
                    json.dump(scene, f)
                out = self.path("ramp.png")
                p = run("render", self.path("s.json"), "-o", out, "--size", "256x256", "--force", timeout=120)
                self.assertEqual(p.returncode, 0, p.stderr)
                row = np.asarray(Image.open(out).convert("L"), dtype=float)[128]
                lit = np.flatnonzero(row > 0)
                xs = np.linspace(0, 1, lit[-1] - lit[0] + 1)
                err = np.abs(row[lit[0]:lit[-1] + 1] - 255 * xs)
                self.assertLess(np.median(err), 3.0, (exposure, tonemap))
                mid = row[(lit[0] + lit[-1]) // 2]
                self.assertAlmostEqual(mid, 128, delta=4, msg=(exposure, tonemap))


if __name__ == "__main__":
    unittest.main()
