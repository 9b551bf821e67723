#!/usr/bin/python3
"""Anti-aliasing: image error against milliseconds (issue 52's chart).

    /usr/bin/python3 bench/aa_bench.py [--build build] [--size 640x400] [--tractogram FILE.tck]

The reference is the same scene drawn at 4x4 the size without
anti-aliasing and averaged over each 4x4 block (supersampling). Each
setting is drawn with `horizon render --json` at the size asked: no
anti-aliasing, 4x MSAA, the edge pass, and 2, 4, 8 and 16 jittered frames
(`--aa-frames`); its root-mean-square error against the reference (8-bit
levels) and its frame time (`first_frame_ms` of the JSON: the frames and the
passes, not the context or the upload). Two scenes: 300 phantom tubes
(0.4 mm; a width in millimetres, so that the larger picture shows the same
geometry) and, with --tractogram, a real file drawn as tubes too. Prints a
Markdown table, writes bench/results/antialiasing.md and
bench/results/antialiasing.png (error against milliseconds, log-log).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SETTINGS = [("none", ["--samples", "1", "--no-aa"]), ("4x MSAA", ["--samples", "4", "--no-aa"]), ("edge pass", ["--samples", "1"])] + [
    (f"{n} frames", ["--samples", "1", "--aa-frames", str(n)]) for n in (2, 4, 8, 16)]


def render(horizon, scene, out, size, args):
    p = subprocess.run([horizon, "render", scene, "-o", out, "--size", size, "--force", "--json", "--lod-pixels", "0", *args],
                       capture_output=True, text=True, env={**os.environ, "DISPLAY": ""})
    if p.returncode != 0:
        sys.exit(f"horizon render failed: {p.stderr.strip()}")
    return json.loads(p.stdout), np.asarray(Image.open(out).convert("RGB"), dtype=np.float64)


def measure(horizon, name, objects, size, tmp):
    w, h = map(int, size.split("x"))
    scene = os.path.join(tmp, "scene.json")
    with open(scene, "w") as f:
        json.dump({"objects": objects, "camera": {"view": "left"}}, f)
    _, ref = render(horizon, scene, os.path.join(tmp, "ref.png"), f"{4 * w}x{4 * h}", ["--samples", "1", "--no-aa"])
    ref = ref.reshape(h, 4, w, 4, 3).mean(axis=(1, 3))
    rows = []
    for label, args in SETTINGS:
        j, im = render(horizon, scene, os.path.join(tmp, "x.png"), size, args)
        rows.append((name, label, float(np.sqrt(((im - ref) ** 2).mean())), j["first_frame_ms"]))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--size", default="640x400")
    ap.add_argument("--tractogram")
    a = ap.parse_args()
    horizon = os.path.join(a.build, "bin", "horizon")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        rows += measure(horizon, "300 phantom tubes", [{"type": "streamlines", "builtin": "phantom", "render": "tubes", "radius": 0.4,
                                                        "phantom": {"streamlines": 300, "bundles": 6, "seed": 3}}], a.size, tmp)
        if a.tractogram:
            rows += measure(horizon, os.path.basename(a.tractogram),
                            [{"type": "streamlines", "file": os.path.abspath(a.tractogram), "render": "tubes", "radius": 0.2}], a.size, tmp)
    table = ["| scene | anti-aliasing | rms error (8-bit levels) | frame ms |", "|---|---|---:|---:|"]
    table += [f"| {s} | {l} | {e:.2f} | {ms:.0f} |" for s, l, e, ms in rows]
    print("\n".join(table))
    out = os.path.join(ROOT, "bench", "results")
    with open(os.path.join(out, "antialiasing.md"), "w") as f:
        f.write("# Anti-aliasing: error against milliseconds\n\n`bench/aa_bench.py` (llvmpipe, 2 cores, release build, "
                f"{a.size}; the reference: the scene at 4x4 the size, averaged per block).\n\n" + "\n".join(table) + "\n\n"
                "![chart](antialiasing.png)\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for scene in dict.fromkeys(r[0] for r in rows):
        pts = [r for r in rows if r[0] == scene]
        ax.plot([r[3] for r in pts], [r[2] for r in pts], "o-", label=scene)
        for r in pts:
            ax.annotate(r[1], (r[3], r[2]), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("frame time (ms)")
    ax.set_ylabel("rms error against 4x4 supersampling")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "antialiasing.png"), dpi=110)


if __name__ == "__main__":
    main()
