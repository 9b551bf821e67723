#!/usr/bin/env python3
"""Throughput of the cohort QC on Dask (issue 54): `python3 -m horizon.batch`
over a cohort of realistic tractograms (hz-make-tractogram: 100-400 points
per streamline), with a local cluster of 1 and then 2 workers, in one run;
subjects per minute and the speed-up of the second worker. Each run starts
from an empty results folder (no subject is taken from an earlier run).

Usage: bench/batch_bench.py BUILD_DIR [--subjects N] [--streamlines N]
       [--workers 1,2] [--out bench/results/batch.md]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("build")
    ap.add_argument("--subjects", type=int, default=8)
    ap.add_argument("--streamlines", type=int, default=20000)
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--views", default="superior,left")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results", "batch.md"))
    a = ap.parse_args()
    build = os.path.abspath(a.build)
    make = os.path.join(build, "bin", "hz-make-tractogram")
    env = {**os.environ, "PYTHONPATH": os.path.join(build, "python")}
    work = tempfile.mkdtemp(prefix="hz-batch-bench-")
    try:
        cohort = os.path.join(work, "cohort")
        t0 = time.monotonic()
        for i in range(a.subjects):
            d = os.path.join(cohort, f"sub-{i + 1:02d}", "dwi")
            os.makedirs(d)
            subprocess.run([make, os.path.join(d, "tracts.tck"), "--streamlines", str(a.streamlines), "--seed", str(i + 1)],
                           check=True, capture_output=True)
        size = sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(cohort) for f in fs)
        print(f"cohort: {a.subjects} subjects x {a.streamlines} streamlines, {size / 2**20:.0f} MiB "
              f"(made in {time.monotonic() - t0:.1f} s)", flush=True)
        rows = []
        for w in [int(x) for x in a.workers.split(",")]:
            out = os.path.join(work, f"qc{w}")
            cmd = ["/usr/bin/python3", "-m", "horizon.batch", cohort, "--glob", "sub-*/dwi/*.tck", "--out", out, "--workers", str(w),
                   "--views", a.views, "--strict"]
            t0 = time.monotonic()
            p = subprocess.run(cmd, env=env, capture_output=True, text=True)
            wall = time.monotonic() - t0
            if p.returncode != 0:
                sys.exit(f"batch with {w} workers failed:\n{p.stdout}\n{p.stderr}")
            records = json.load(open(os.path.join(out, "qc.json")))
            ok = sum(r["status"] == "ok" for r in records)
            rows.append((w, wall, ok))
            print(f"{w} worker(s): {wall:.1f} s, {ok} subjects ok, {60 * ok / wall:.1f} subjects/min", flush=True)
        base = rows[0][1]
        lines = ["# Cohort QC throughput (`python3 -m horizon.batch`, local Dask cluster)", "",
                 f"{a.subjects} subjects of {a.streamlines} realistic streamlines each ({size / 2**20:.0f} MiB of TCK), views "
                 f"{a.views}, 320x240; one run per worker count, each from an empty results folder, on this machine "
                 f"({os.cpu_count()} cores, llvmpipe). `bench/batch_bench.py`.", "",
                 "| workers | wall (s) | subjects/min | speed-up |", "|---:|---:|---:|---:|"]
        for w, wall, ok in rows:
            lines.append(f"| {w} | {wall:.1f} | {60 * ok / wall:.1f} | {base / wall:.2f}x |")
        with open(a.out, "w") as f:
            f.write("\n".join(lines) + "\n")
        print("\n".join(lines[4:]))
        print(f"-> {a.out}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
