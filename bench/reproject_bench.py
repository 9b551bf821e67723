#!/usr/bin/env python3
"""The moving picture with and without the reprojected still (--lod-reproject),
in the window, as a user turns the camera.

    /usr/bin/python3 bench/reproject_bench.py [--tck FILE] [--drags 0,6,12,30] [--out bench/results/reproject.md]

For each drag (window pixels; the orbit turns 0.008 rad per pixel; a drag of
at most 3 pixels is a click and turns nothing) and each
mode, `horizon view --script` under Xvfb at 1280x800: the still image at the
first camera completes, the camera turns by the drag while held moving
(`moving on`), a screenshot of the moving frame is taken, then the camera
rests and the complete still image at the new camera is taken. The error of
the moving frame against that still (same camera): SSIM and MAE of the
4x-downsampled pictures (bench/imgmetrics.py, as bench/scale_bench.py
measures the proxy), and the moving frames' median time from --stats.
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import imgmetrics  # noqa: E402

HORIZON = os.path.join(ROOT, "build", "bin", "horizon")


def load(p):
    return np.asarray(Image.open(p).convert("RGB"))


def one(tck, drag, mode, work):
    moving, still = os.path.join(work, f"m_{mode}_{drag}.png"), os.path.join(work, f"s_{mode}_{drag}.png")
    script, stats = os.path.join(work, "script.txt"), os.path.join(work, "stats.json")
    with open(script, "w") as f:
        f.write("\n".join(["wait 3", f"screenshot {os.path.join(work, 'first.png')}", "moving on",
                           f"drag 640 400 {640 + drag} 400", "wait 3", f"screenshot {moving}", "moving off",
                           f"screenshot {still}", "quit"]) + "\n")
    p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", HORIZON, "view", tck, "--size", "1280x800", "--script", script,
                        "--stats", stats, "--lod-reproject", mode], capture_output=True, text=True, timeout=1800)
    if p.returncode != 0:
        raise SystemExit(f"view failed: {p.stderr[-2000:]}")
    frames = [f for f in json.load(open(stats))["frames"] if f["kind"] == "moving"]
    a, b = imgmetrics.downsample(load(moving), 4), imgmetrics.downsample(load(still), 4)
    return {"ssim": imgmetrics.ssim(a, b), "mae": imgmetrics.mae(a, b), "ms": statistics.median(f["ms"] for f in frames),
            "reprojected": max(f.get("reprojected", 0) for f in frames)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tck", default="/var/tmp/hz_scale_bench/brain_1000000.tck")
    ap.add_argument("--drags", default="0,6,12,30")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "reproject.md"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for drag in [int(x) for x in args.drags.split(",")]:
            r = {mode: one(args.tck, drag, mode, work) for mode in ("on", "off")}
            deg = math.degrees(drag * 0.008)
            rows.append((drag, deg, r))
            print(f"drag {drag:3d} px ({deg:4.1f} deg): reproject SSIM {r['on']['ssim']:.3f} ({r['on']['ms']:.0f} ms), "
                  f"proxy only {r['off']['ssim']:.3f} ({r['off']['ms']:.0f} ms)", flush=True)
    lines = ["# The moving picture: the reprojected still under the proxy", "",
             f"{time.strftime('%Y-%m-%d')}, `bench/reproject_bench.py --tck {os.path.basename(args.tck)}`, this machine (2 cores, llvmpipe), "
             "the window at 1280x800 under Xvfb.",
             "The camera turns from a complete still by the drag (0.008 rad per pixel) while held moving; the moving frame is",
             "compared with the complete still image at the same camera: SSIM and MAE of the 4x-downsampled pictures.", "",
             "| turn | --lod-reproject on: SSIM / MAE / frame ms (points) | off (the proxy alone): SSIM / MAE / frame ms |",
             "|---|---|---|"]
    for drag, deg, r in rows:
        on, off = r["on"], r["off"]
        lines.append(f"| {drag} px ({deg:.1f}°) | {on['ssim']:.3f} / {on['mae']:.1f} / {on['ms']:.0f} ({on['reprojected']:,}) | "
                     f"{off['ssim']:.3f} / {off['mae']:.1f} / {off['ms']:.0f} |")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 3.5))
        degs = [deg for _, deg, _ in rows]
        ax.plot(degs, [r["on"]["ssim"] for *_, r in rows], "o-", label="the still reprojected, under the proxy")
        ax.plot(degs, [r["off"]["ssim"] for *_, r in rows], "s--", label="the proxy alone")
        ax.axhline(0.9, color="grey", lw=0.8, ls=":")
        ax.set_xlabel("camera turn from the last complete still (degrees)")
        ax.set_ylabel("SSIM against the full frame (4x down)")
        ax.set_title("moving frames, 1280x800, all within 33 ms", fontsize=9)
        ax.legend(fontsize=8)
        fig.tight_layout()
        chart = os.path.splitext(args.out)[0] + ".png"
        fig.savefig(chart, dpi=110)
        lines += ["", f"![SSIM against the turn]({os.path.basename(chart)})"]
    except ImportError:
        pass
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("wrote", args.out)


if __name__ == "__main__":
    sys.exit(main())
