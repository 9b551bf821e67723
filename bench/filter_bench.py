#!/usr/bin/env python3
"""`horizon filter` against MRtrix3 tckedit 3.0.3 (`mrtrix3`) on the same
realistic tractograms (hz-make-tractogram) and the same regions, in one run.

For each case, both tools read the TCK, select, and write a TCK; the two
outputs must hold the same bytes after their headers (same streamlines, same
order, same coordinates), or the benchmark stops. Times are wall seconds,
launch to exit, the median of --repeat runs, with the previous run's output
deleted and `sync` before each run (so that neither tool is charged for
freeing the last run's output, and one run's write-back does not land in the
next); the input is in the page cache (one untimed read first). tckedit runs on every core (its
default), as Horizon does.

    /usr/bin/python3 bench/filter_bench.py [--sizes 100000,1000000] [--work DIR] [--repeat 3]

Writes bench/results/filter.md (a table and a chart).
"""
import argparse
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HORIZON = os.path.join(ROOT, "build", "bin", "horizon")
MAKE = os.path.join(ROOT, "build", "bin", "hz-make-tractogram")


def data_bytes(path):
    """The bytes of a TCK after its header ("file: . OFFSET")."""
    with open(path, "rb") as f:
        head = f.read(65536)
        for line in head.split(b"\n"):
            if line.startswith(b"file:"):
                off = int(line.split()[2])
                f.seek(off)
                return f.read()
    raise SystemExit(f"{path}: no 'file:' line")


def timed(cmd, repeat, out):
    times = []
    for _ in range(repeat):
        if os.path.exists(out):
            os.unlink(out)
        subprocess.run(["sync"], check=True)
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True)
        times.append(time.perf_counter() - t0)
        if p.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed: {p.stderr[-2000:]}")
    return statistics.median(times), p


def make_mask(path):
    """A mask on its own grid (2 mm, rotated 20 degrees about z): an
    ellipsoid in the right hemisphere."""
    import nibabel as nib
    import numpy as np
    a = np.deg2rad(20)
    aff = np.eye(4)
    aff[:3, :3] = 2.0 * np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    aff[:3, 3] = [-70, -90, -60]
    ijk = np.stack(np.meshgrid(np.arange(80), np.arange(100), np.arange(70), indexing="ij"), -1).reshape(-1, 3)
    xyz = ijk @ aff[:3, :3].T + aff[:3, 3]
    blob = (((xyz - [30, -10, 10]) / [18, 30, 20]) ** 2).sum(1) <= 1
    nib.save(nib.Nifti1Image(blob.reshape(80, 100, 70).astype(np.uint8), aff), path)


def first_streamline_ends(path):
    import nibabel as nib
    t = nib.streamlines.load(path, lazy_load=True)
    s = next(iter(t.streamlines))
    return s[0], s[-1]


def sphere(c, r):
    return ",".join(f"{x:.3f}" for x in c) + f",{r}"


def window_selection_times(tck):
    """Selection times the window prints while a region is dragged (None without xvfb-run)."""
    import re
    import shutil
    import tempfile
    if not shutil.which("xvfb-run"):
        return None
    steps = ["wait 2", "sleep 5", "roi sphere 10 -20 15 12"] + [f"roi move 0 {10 + 2 * k} -20 15" for k in range(1, 9)] + \
            ["roi sphere -30 0 0 10 exclude"] + [f"roi move 1 {-30 + 2 * k} 0 0" for k in range(1, 5)] + ["quit"]
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
        f.write("\n".join(steps) + "\n")
    p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", HORIZON, "view", tck, "--size", "640x400", "--script", f.name],
                       capture_output=True, text=True, timeout=600)
    os.unlink(f.name)
    if p.returncode != 0:
        raise SystemExit(f"view failed: {p.stderr[-2000:]}")
    ms = [float(m.group(2)) for m in (re.match(r"roi: (\d+) regions, .*\(([\d.]+) ms\)$", l) for l in p.stdout.splitlines()) if m]
    n = int(re.search(r"of (\d+) streamlines selected", p.stdout).group(1))
    print("window selection times (ms):", ms, flush=True)
    return n, ms[0], ms[1:]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="100000,1000000")
    ap.add_argument("--work", default="/var/tmp/hz_filter_bench")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "filter.md"))
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    mask = os.path.join(args.work, "mask.nii.gz")
    make_mask(mask)
    version = subprocess.run(["tckedit", "-version"], capture_output=True, text=True).stdout.splitlines()[0]
    rows = []
    for n in [int(x) for x in args.sizes.split(",")]:
        tck = os.path.join(args.work, f"brain_{n}.tck")
        if not os.path.exists(tck):
            subprocess.run([MAKE, tck, "--streamlines", str(n), "--seed", "1"], check=True)
        subprocess.run(["cat", tck], stdout=subprocess.DEVNULL, check=True)  # (into the page cache)
        a, b = first_streamline_ends(tck)
        cases = [
            ("bundle: 2 spheres", [("include", sphere(a, 8)), ("include", sphere(b, 8))], []),
            ("sphere + exclude + min length", [("include", "10,-20,15,12"), ("exclude", "-30,0,0,10")], [("min", 80)]),
            ("mask (rotated grid) + exclude", [("include", mask), ("exclude", "-20,0,-10,12")], []),
            ("length 40-250 mm only", [], [("min", 40), ("max", 250)]),
        ]
        for name, rois, lengths in cases:
            ours, theirs = os.path.join(args.work, "h.tck"), os.path.join(args.work, "m.tck")
            h = [HORIZON, "filter", tck, "-o", ours, "--force", "--json"]
            m = ["tckedit", tck, theirs, "-quiet", "-force"]
            for kind, spec in rois:
                h += [f"--{kind}", spec if spec == mask else "sphere:" + spec]
                m += [f"-{kind}", spec]
            for kind, v in lengths:
                h += [f"--{kind}-length", str(v)]
                m += [f"-{kind}length", str(v)]
            th, p = timed(h, args.repeat, ours)
            import json
            summary = json.loads(p.stdout)
            tm, _ = timed(m, args.repeat, theirs)
            same = data_bytes(ours) == data_bytes(theirs)
            if not same:
                raise SystemExit(f"{name} at {n}: the outputs differ")
            rows.append((n, name, summary["selected"], th, tm, tm / th, summary["read_s"], summary["filter_s"], summary["write_s"]))
            print(f"{n:>9} {name:32s} {summary['selected']:>8} horizon {th:6.2f} s  tckedit {tm:6.2f} s  x{tm / th:5.1f}", flush=True)
    for f in (ours, theirs):
        os.unlink(f)
    window = window_selection_times(os.path.join(args.work, f"brain_{max(int(x) for x in args.sizes.split(','))}.tck"))

    lines = ["# `horizon filter` against tckedit", "",
             f"{time.strftime('%Y-%m-%d')}, `bench/filter_bench.py`, this machine (2 cores, Debian 12), {version}.",
             "Realistic generated tractograms (hz-make-tractogram, seed 1: 100-400 points per streamline), TCK in, TCK out,",
             "input in the page cache, the previous output deleted and `sync` before each run, median of " + str(args.repeat) +
             " runs, wall time launch to exit.",
             "Both outputs hold the same bytes after their headers in every case (checked each run).", "",
             "| streamlines | case | selected | horizon s | tckedit s | ratio | horizon read / filter / write s |",
             "|---:|---|---:|---:|---:|---:|---|"]
    for n, name, sel, th, tm, r, rs, fs, ws in rows:
        lines.append(f"| {n:,} | {name} | {sel:,} | {th:.2f} | {tm:.2f} | {r:.1f}x | {rs:.2f} / {fs:.2f} / {ws:.2f} |")
    if window:
        n, first, times = window
        lines += ["", f"## The window: a region dragged over {n:,} streamlines", "",
                  "`horizon view FILE --script` under Xvfb (640x400): a 12 mm include sphere placed 5 s after launch, then moved",
                  "in 2 mm steps, then an exclude sphere added and moved; each step selects again (the spatial grid) and prints",
                  "its time. The first step waits for what remains of the grid's background build.", "",
                  "| step | ms |", "|---|---:|", f"| first region | {first:.0f} |"]
        lines += [f"| move {i + 1} | {t:.0f} |" for i, t in enumerate(times)]
        lines.append(f"| median of the moves | {statistics.median(times):.0f} |")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(8, 3.5))
        labels = [f"{name}\n{n // 1000}k" for n, name, *_ in rows]
        x = range(len(rows))
        ax.barh([i + 0.2 for i in x], [r[4] for r in rows], 0.4, label="tckedit")
        ax.barh([i - 0.2 for i in x], [r[3] for r in rows], 0.4, label="horizon filter")
        ax.set_yticks(list(x), labels, fontsize=7)
        ax.set_xlabel("seconds, launch to exit (lower is better)")
        ax.legend()
        fig.tight_layout()
        chart = os.path.splitext(args.out)[0] + ".png"
        fig.savefig(chart, dpi=110)
        lines += ["", f"![horizon filter and tckedit]({os.path.basename(chart)})"]
    except ImportError:
        pass
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("wrote", args.out)


if __name__ == "__main__":
    sys.exit(main())
