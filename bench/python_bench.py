#!/usr/bin/python3
"""`horizon.load` from Python against nibabel's `load`, on the same file, in
one run (issue 54: a 1M-streamline TRK into numpy at least 10x nibabel).

    /usr/bin/python3 bench/python_bench.py FILE.trk [--build build] [--repeat 3]

Each tool runs in its own process, in turn (horizon, nibabel, then again),
the best of --repeat kept; the time is the call's inside the process
(imports and the interpreter's start excluded): horizon.load plus
horizon.to_nibabel (an ArraySequence of the streamlines, as nibabel's load
returns), and the same followed by one read of every coordinate (np.max),
which nibabel's arrays have had to decode already and a reader that defers
its work would still owe (horizon decodes a TRK when it loads it). The two
ArraySequences are compared, every 50th streamline's coordinates. Prints a Markdown table and
writes bench/results/python.md.
"""
import argparse
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

HORIZON = """
import sys, time, numpy as np
sys.path.insert(0, sys.argv[2])
import horizon
t0 = time.perf_counter()
seq = horizon.to_nibabel(horizon.load(sys.argv[1]))
t1 = time.perf_counter()
m = float(np.max(seq._data))
print(t1 - t0, len(seq), time.perf_counter() - t0)
"""

NIBABEL = """
import sys, time, numpy as np
import nibabel as nib
t0 = time.perf_counter()
seq = nib.streamlines.load(sys.argv[1]).streamlines
t1 = time.perf_counter()
m = float(np.max(seq._data))
print(t1 - t0, len(seq), time.perf_counter() - t0)
"""

SAME = """
import sys, numpy as np
sys.path.insert(0, sys.argv[2])
import horizon, nibabel as nib
ours = horizon.to_nibabel(horizon.load(sys.argv[1]))
theirs = nib.streamlines.load(sys.argv[1]).streamlines
assert len(ours) == len(theirs)
np.testing.assert_array_equal(ours._lengths, theirs._lengths)
worst = 0.0
for k in range(0, len(ours), 50):
    worst = max(worst, float(np.abs(ours[k] - theirs[k]).max()))
print(worst)
"""


def run(script, *args):
    out = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, check=True).stdout.split()
    return float(out[0]), int(out[1]) if len(out) > 1 else 0, float(out[2]) if len(out) > 2 else 0.0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    pkg = os.path.join(os.path.abspath(a.build), "python")
    best = {"horizon": 1e30, "nibabel": 1e30, "horizon+read": 1e30, "nibabel+read": 1e30}
    n = 0
    for _ in range(a.repeat):
        t, n, tr = run(HORIZON, a.file, pkg)
        best["horizon"], best["horizon+read"] = min(best["horizon"], t), min(best["horizon+read"], tr)
        t, _, tr = run(NIBABEL, a.file)
        best["nibabel"], best["nibabel+read"] = min(best["nibabel"], t), min(best["nibabel+read"], tr)
    worst = run(SAME, a.file, pkg)[0]
    size = os.path.getsize(a.file) / 2**20
    lines = ["| file | MiB | streamlines | horizon.load + to_nibabel (s) | nibabel load (s) | ratio | "
             "both + a read of every coordinate (s) | ratio | largest difference (mm) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
             f"| {os.path.basename(a.file)} | {size:.0f} | {n} | {best['horizon']:.2f} | {best['nibabel']:.2f} | "
             f"{best['nibabel'] / best['horizon']:.1f}x faster | {best['horizon+read']:.2f} against {best['nibabel+read']:.2f} | "
             f"{best['nibabel+read'] / best['horizon+read']:.1f}x faster | {worst:.2g} |"]
    text = "\n".join(lines)
    print(text)
    with open(os.path.join(ROOT, "bench", "results", "python.md"), "w") as f:
        f.write("# horizon.load against nibabel (bench/python_bench.py)\n\nBest of %d, each in its own process, in turn.\n\n%s\n"
                % (a.repeat, text))


if __name__ == "__main__":
    main()
