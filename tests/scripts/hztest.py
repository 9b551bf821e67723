"""Shared helpers for the scripted tests: they drive the real `horizon`
binary (paths come from CTest's environment) and write test files."""
import json
import os
import shutil
import struct
import subprocess
import tempfile
import unittest

import numpy as np

HORIZON = os.environ.get("HORIZON_BIN", "horizon")
BUILD = os.environ.get("HORIZON_BUILD_DIR", "")
SOURCE = os.environ.get("HORIZON_SOURCE_DIR", "")
FIXTURES = os.environ.get("HORIZON_FIXTURE_DIR", "")
TEMPLATES = os.environ.get("HORIZON_TEMPLATE_DIR", "")
BUNDLED = os.path.join(BUILD, "lib", "horizon", "plugins")


def environment(*args, env=None):
    """The environment run() gives horizon for `args` (for tests that start
    it themselves: pipes, ptys, limits, signals)."""
    e = dict(os.environ)
    e.pop("HORIZON_PLUGIN_PATH", None)
    # One trial list for the whole suite, in the build tree (not the user's).
    e["HORIZON_PLUGIN_CACHE"] = os.path.join(BUILD, "tests", "plugin-trials.json") if BUILD else "off"
    if env:
        e.update(env)
    e["XDG_DATA_HOME"] = e.get("HZ_TEST_XDG", "/nonexistent-xdg")
    if "ASAN_OPTIONS" in e and command_of(args) in GL_COMMANDS:
        e["ASAN_OPTIONS"] += ":detect_leaks=0"
    return e


def command_of(args):
    """The subcommand in a horizon command line (global options such as
    `--plugin-dir D` may come before it)."""
    args = [str(a) for a in args]
    i = 0
    while i < len(args) and args[i].startswith("-"):
        i += 2 if args[i] in ("--plugin-dir", "--plugin-timeout") else 1
    return args[i] if i < len(args) else None


def run(*args, timeout=60, env=None):
    """Runs horizon with `args`; returns the CompletedProcess (text mode)."""
    return subprocess.run([HORIZON, *map(str, args)], capture_output=True, text=True, timeout=timeout, env=environment(*args, env=env))


# Commands that load Mesa's OpenGL driver. Under the ASan suite their leak
# check is off: LeakSanitizer's stop-the-world tracer intermittently crashes
# on the driver's threads at exit ("Tracer caught signal 11"), and the
# driver's own process-lifetime allocations are not Horizon's. ASan and
# UBSan still check every memory access of these processes.
GL_COMMANDS = {"render", "view", "shader-check", "demo", "movie"}


def make_tractogram(path, n, seed, timeout=900):
    """A realistic whole-brain tractogram of n streamlines (bench's
    hz-make-tractogram: 100-400 points each, 0.5-0.8 mm steps) at `path`.

    Large ones (100k streamlines or more: 20 s at 1M) are made once per
    build tree and generator binary, kept read-only under
    BUILD/tests/tractograms, and linked at `path` (the mutation check runs
    the scale tests once a mutant)."""
    make = os.path.join(BUILD, "bin", "hz-make-tractogram")

    def generate(out):
        p = subprocess.run([make, str(out), "--streamlines", str(n), "--seed", str(seed)], capture_output=True, text=True,
                           timeout=timeout)
        if p.returncode != 0:
            raise AssertionError(f"hz-make-tractogram failed: {p.stderr}")

    if n < 100000 or not BUILD:
        generate(path)
        return
    st = os.stat(make)
    cache = os.path.join(BUILD, "tests", "tractograms")
    os.makedirs(cache, exist_ok=True)
    kept = os.path.join(cache, f"brain_{n}_{seed}_{st.st_size}_{st.st_mtime_ns}.tck")
    if not os.path.exists(kept):
        for old in os.listdir(cache):  # made by an older generator
            if old.startswith(f"brain_{n}_{seed}_"):
                os.unlink(os.path.join(cache, old))
        tmp = f"{kept}.{os.getpid()}.part"
        generate(tmp)
        os.chmod(tmp, 0o444)
        os.replace(tmp, kept)
    try:
        os.link(kept, path)
    except OSError:  # another file system
        os.symlink(kept, path)


def run_json(*args, **kw):
    p = run(*args, **kw)
    if p.returncode != 0:
        raise AssertionError(f"horizon {' '.join(map(str, args))} failed ({p.returncode}): {p.stderr}")
    return json.loads(p.stdout)


class TempDirTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="hz_test_")

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def path(self, name):
        return os.path.join(self.tmp, name)

    def assert_clean_error(self, proc, filename, elapsed_limit=None):
        """A failure: non-zero exit, exactly one stderr line naming the file."""
        self.assertNotEqual(proc.returncode, 0, proc.stdout)
        self.assertGreater(proc.returncode, 0, f"killed by a signal: {proc.returncode}")
        lines = [l for l in proc.stderr.splitlines() if l.strip()]
        self.assertEqual(len(lines), 1, f"expected one error line, got: {proc.stderr!r}")
        self.assertIn(os.path.basename(filename), lines[0])

    def assert_scene_errors(self, cases):
        """Each scene of `cases` (name: (scene, message)) written as NAME.json
        fails to render with one line naming that file and holding the
        message, nothing written."""
        for name, (scene, msg) in cases.items():
            with self.subTest(case=name):
                with open(self.path(name + ".json"), "w") as f:
                    json.dump(scene, f)
                p = run("render", self.path(name + ".json"), "-o", self.path("x.png"), env={"DISPLAY": ""}, timeout=60)
                self.assert_clean_error(p, name + ".json")
                self.assertIn(msg, p.stderr)
                self.assertFalse(os.path.exists(self.path("x.png")))


def tck_bytes(streamlines, datatype="Float32LE", header_extra=(), nan_bits=None, inf_sign=1.0,
              magic="mrtrix tracks", pad=0, terminator=True, count=None):
    """Builds a TCK file the way MRtrix/nibabel/MATLAB writers do."""
    fmt = {"Float32LE": "<f4", "Float32BE": ">f4", "Float64LE": "<f8", "Float64BE": ">f8"}[datatype]
    parts = []
    for s in streamlines:
        parts.append(np.asarray(s, dtype=np.float64).reshape(-1, 3))
        parts.append(np.full((1, 3), np.nan))
    if terminator:
        parts.append(np.full((1, 3), np.inf * inf_sign))
    data = np.concatenate(parts).astype(fmt) if parts else np.zeros((0, 3), fmt)
    raw = bytearray(data.tobytes())
    if nan_bits is not None:  # e.g. MATLAB's -NaN 0xffc00000
        size = np.dtype(fmt).itemsize
        rows = np.isnan(data).all(axis=1)
        bits = struct.pack("<I" if fmt[0] == "<" else ">I", nan_bits) if size == 4 else None
        for i in np.nonzero(rows)[0]:
            for k in range(3):
                off = (3 * i + k) * size
                raw[off:off + size] = bits
    lines = [magic]
    lines += [f"{k}: {v}" for k, v in header_extra]
    lines.append(f"count: {len(streamlines) if count is None else count}")
    lines.append(f"datatype: {datatype}")
    head = "\n".join(lines) + "\n"
    offset = len(head) + len("file: . \nEND\n") + pad
    offset += len(str(offset + 3))
    head += f"file: . {offset}\nEND\n"
    head = head.encode() + b"\0" * (offset - len(head))
    return head + bytes(raw)


def random_streamlines(n, rng, min_pts=1, max_pts=60, scale=80.0):
    out = []
    for _ in range(n):
        k = int(rng.integers(min_pts, max_pts + 1))
        steps = rng.normal(size=(k, 3))
        out.append((np.cumsum(steps, axis=0) + rng.uniform(-scale, scale, 3)).astype(np.float32))
    return out


def xvfb_run(args, env, timeout=300):
    """`args` under a fresh Xvfb (`xvfb-run -a`): the process. xvfb-run exits 5,
    hiding the command's own status, when it fails to remove its temporary
    directory (a race in its clean-up: about one run in twenty on this
    machine, more when it is loaded, and more often after a command that
    ends at once); a shell around the command writes its status to a file,
    which is then the process's status, and xvfb-run's line is dropped."""
    with tempfile.TemporaryDirectory() as d:
        status = os.path.join(d, "status")
        wrapped = ["sh", "-c", '"$@"; s=$?; echo $s > "$0"; exit $s', status, *args]
        p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", *wrapped], capture_output=True, text=True,
                           timeout=timeout, env=env)
        clean_up = "xvfb-run: error: problem while cleaning up temporary directory"
        if p.returncode == 5 and clean_up in p.stderr and os.path.exists(status):
            with open(status) as f:
                code = int(f.read())
            err = "".join(l for l in p.stderr.splitlines(keepends=True) if not l.startswith(clean_up))
            p = subprocess.CompletedProcess(args, code, p.stdout, err)
    return p
