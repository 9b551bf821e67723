#!/usr/bin/env python3
"""Scale benchmark: a realistic whole-brain tractogram in the window and headless.

    /usr/bin/python3 bench/scale_bench.py [--build build] [--streamlines 1000000] [--work DIR]
                                          [--no-window] [--chart PNG]

Writes (or reuses) DIR/brain_N.tck with hz-make-tractogram, then measures, on
this machine (llvmpipe), at 1280x800:
- the window (`horizon view --stats` under Xvfb, a scripted drag then rest):
  launch to first frame, moving frame times, refinement steps, launch to the
  complete still image, peak anonymous memory (RssAnon: mapped file pages are
  not counted); with --explore, launch to the clusters shown;
- `horizon render` at full detail, end to end, and `render --preview`;
- the level-of-detail chart: the proxy's error against the full-detail frame
  from the same camera (SSIM of the 4x-downsampled luminance, bench/imgmetrics.py)
  against its frame time, for the three proxies (--lod-proxy volume, shell, uniform) and
  several --lod-points and --lod-scale, and from other cameras.
Prints a Markdown table (kept in bench/results/scale.md) and writes docs/lod_chart.png
(or --chart). --no-window measures `render` alone, for a machine without Xvfb
(a GPU server: the headless renderer takes the first EGL device that is not
a software renderer).
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from PIL import Image

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import imgmetrics  # noqa: E402

SIZE = "1280x800"


def load(p):
    return np.asarray(Image.open(p).convert("RGB"))


def render(horizon, tck, out, *extra):
    t0 = time.perf_counter()
    p = subprocess.run([horizon, "render", tck, "-o", out, "--force", "--size", SIZE, "--json", *extra], capture_output=True,
                       text=True, env={**os.environ, "DISPLAY": ""})
    if p.returncode != 0:
        raise SystemExit(p.stderr)
    j = json.loads(p.stdout)
    j["wall_s"] = time.perf_counter() - t0
    return j


# Moves from the third frame on, while the background work (the shell, the
# fibre volume, the bricks) is still being computed.
EARLY = "wait 3\ndrag 300 300 500 340\nwait 10\ndrag 500 340 300 300\nwait 10\n"
# Moves once the still is complete and the fibre volume adopted: the proxy
# the window draws from then on.
SETTLED = "sleep 22\nmoving on\ndrag 640 400 700 400\nwait 20\ndrag 700 400 760 420\nwait 20\nmoving off\n"


def window(horizon, tck, work, *extra, moves=EARLY):
    script = os.path.join(work, "s.txt")
    with open(script, "w") as f:
        f.write(moves + f"screenshot {os.path.join(work, 'still.png')}\nquit\n")
    stats = os.path.join(work, "stats.json")
    p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", horizon, "view", tck, "--size", SIZE, "--script", script,
                        "--stats", stats, *extra], capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(p.stderr)
    with open(stats) as f:
        return json.load(f)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--streamlines", type=int, default=1000000)
    ap.add_argument("--work", default=tempfile.gettempdir())
    ap.add_argument("--no-window", action="store_true", help="skip the window's measures (no Xvfb here)")
    ap.add_argument("--chart", default=os.path.join(ROOT, "docs", "lod_chart.png"))
    args = ap.parse_args()
    horizon = os.path.join(args.build, "bin", "horizon")
    make = os.path.join(args.build, "bin", "hz-make-tractogram")
    tck = os.path.join(args.work, f"brain_{args.streamlines}.tck")
    if not os.path.exists(tck):
        subprocess.run([make, tck, "--streamlines", str(args.streamlines), "--seed", "1"], check=True)
    work = tempfile.mkdtemp(prefix="hz_scale_bench_")
    rows = []

    if not args.no_window:
        w = window(horizon, tck, work)
        fr = w["frames"]
        moving = [f["ms"] for f in fr if f["kind"] == "moving"]
        steps = [f["ms"] for f in fr if f["kind"] in ("refine", "complete") and f["step"] > 0]
        rows.append(("window: launch to first frame (s)", f"{w['first_frame_s']:.2f}"))
        rows.append(("window: launch to complete still image (s)", f"{w['first_complete_s']:.1f}"))
        rows.append(("window: moving frame, median / max (ms)", f"{np.median(moving):.0f} / {max(moving):.0f}"))
        rows.append(("window: refinement step, median / max (ms)", f"{np.median(steps):.0f} / {max(steps):.0f}"))
        rows.append(("window: peak anonymous memory (MB)", f"{w['peak_rss_anon_mb']:.0f}"))
        ws = window(horizon, tck, work, moves=SETTLED)
        settled = [f["ms"] for f in ws["frames"] if f["kind"] == "moving" and f["fibre_volumes"] > 0]
        rows.append(("window: moving frame over the fibre volume, once the still is complete, median / max (ms)",
                     f"{np.median(settled):.0f} / {max(settled):.0f} ({len(settled)} frames)"))
        # The proxy's level the window chose for them (--lod-frame-ms 33), in order.
        by_level = {}
        for f in ws["frames"]:
            if f["kind"] == "moving" and f["fibre_volumes"] > 0:
                by_level.setdefault(f["proxy_level"], []).append(f["ms"])
        rows.append(("window: those frames by proxy level (1/scale, points): frames, median ms",
                     "; ".join(f"1/{ws['proxy_levels'][k][0]}, {ws['proxy_levels'][k][1]:g}: {len(v)}, {np.median(v):.0f}"
                               for k, v in sorted(by_level.items()))))
        # Occlusion culling (--lod-occlusion): the same, drawn in file order.
        # --explore: QuickBundlesX in the background, the tractogram shown meanwhile
        # (`sleep`: frames, which sample the memory, go on while it clusters).
        we = window(horizon, tck, work, "--explore", moves=f"wait 2\nnowait key e\nsleep {max(6, 4 * args.streamlines // 1000000)}\n")
        during = [f for f in we["frames"] if f.get("clustering")]
        gap = max((b["t"] - a["t"] for a, b in zip(during, during[1:])), default=0)
        rows.append(("window --explore: launch to first frame / to clusters shown (s)",
                     f"{we['first_frame_s']:.2f} / {we['clusters_shown_s']:.1f}"))
        rows.append(("window --explore: longest time between frames while clustering (ms); peak anonymous memory (MB)",
                     f"{1000 * gap:.0f}; {we['peak_rss_anon_mb']:.0f}"))
        w_off = window(horizon, tck, work, "--lod-occlusion", "off")
        rows.append(("window, --lod-occlusion off: launch to complete still image (s)",
                     f"{w_off['first_complete_s']:.1f} ({w_off['first_complete_s'] / w['first_complete_s']:.1f}x on's)"))

    full = render(horizon, tck, os.path.join(work, "full.png"))
    off = render(horizon, tck, os.path.join(work, "full_off.png"), "--lod-occlusion", "off")
    prev = render(horizon, tck, os.path.join(work, "preview.png"), "--preview")
    rows.append(("render, full detail, end to end (s)",
                 f"{full['wall_s']:.1f} ({full['points_drawn'] / 1e6:.0f}M points drawn, {full['culled_points'] / 1e6:.0f}M of "
                 f"{full['points_total'] / 1e6:.0f}M hidden and skipped)"))
    rows.append(("render, full detail, --lod-occlusion off (s)",
                 f"{off['wall_s']:.1f} ({off['points_drawn'] / 1e6:.0f}M points drawn; {off['wall_s'] / full['wall_s']:.1f}x on's)"))
    rows.append(("render --preview, end to end (s)", f"{prev['wall_s']:.2f}"))

    ref = imgmetrics.downsample(load(os.path.join(work, "full.png")), 4)
    chart = []
    # "volume, direct": the fibre volume ray-marched at the proxy's own size.
    for proxy in ("volume", "volume, direct", "shell", "uniform"):
        for scale in (2, 4):
            for pts in (2e5, 5e5, 1e6):
                out = os.path.join(work, f"p_{proxy[:6]}{len(proxy)}_{scale}_{pts:g}.png")
                extra = ("--lod-volume-scale", str(scale)) if proxy == "volume, direct" else ()
                j = render(horizon, tck, out, "--preview", "--lod-proxy", proxy.split(",")[0], "--lod-points", f"{pts:g}", "--lod-scale",
                           str(scale), "--frames", "5", *extra)
                im = imgmetrics.downsample(load(out), 4)
                chart.append((proxy, scale, pts, j["frame_ms_min"], imgmetrics.ssim(ref, im), imgmetrics.mae(ref, im)))
    # The window's proxy levels (--lod-frame-ms picks one): each is the base
    # level of these --lod-scale and --lod-points (proxy_levels in renderer.hpp).
    for scale, pts in ((8, 1e5), (8, 2e5), (4, 2e5), (2, 2e5), (2, 4e5), (1, 4e5), (1, 8e5)):
        out = os.path.join(work, f"p_level_{scale}_{pts:g}.png")
        j = render(horizon, tck, out, "--preview", "--lod-points", f"{pts:g}", "--lod-scale", str(scale), "--frames", "5")
        im = imgmetrics.downsample(load(out), 4)
        chart.append(("volume, the window's levels", scale, pts, j["frame_ms_min"], imgmetrics.ssim(ref, im), imgmetrics.mae(ref, im)))
    # The shell is the same for every camera: the default proxy from other sides.
    views = []
    for view in ("superior", "anterior"):
        f = render(horizon, tck, os.path.join(work, f"full_{view}.png"), "--view", view)
        for proxy in ("volume", "shell", "uniform"):
            render(horizon, tck, os.path.join(work, f"p_{view}_{proxy}.png"), "--view", view, "--preview", "--lod-proxy", proxy)
        r = imgmetrics.downsample(load(os.path.join(work, f"full_{view}.png")), 4)
        views.append((view, *(imgmetrics.ssim(r, imgmetrics.downsample(load(os.path.join(work, f"p_{view}_{p}.png")), 4))
                              for p in ("volume", "shell", "uniform"))))
    head = f"{args.streamlines} streamlines ({full['points_total'] / 1e6:.0f}M points), {SIZE}, {full['gl']}"
    lines = ["# Scale benchmark", "", head, "", "| measure | value |", "|---|---|"] + [f"| {a} | {b} |" for a, b in rows]
    lines += ["", "Level of detail: the proxy (`render --preview`) against the full-detail frame, same camera (left).", "",
              "| --lod-proxy | --lod-scale | --lod-points | frame ms (fastest of 4) | SSIM, 4x downsampled | MAE, 4x downsampled |",
              "|---|---|---|---|---|---|"]
    lines += [f"| {x} | {s} | {p:g} | {ms:.1f} | {ss:.3f} | {ma:.1f} |" for x, s, p, ms, ss, ma in chart]
    lines += ["", "Other cameras, default proxy settings: SSIM, 4x downsampled.", "", "| view | volume | shell | uniform |", "|---|---|---|---|"]
    lines += [f"| {v} | {a:.3f} | {b:.3f} | {c:.3f} |" for v, a, b, c in views]
    text = "\n".join(lines) + "\n"
    print(text)
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 4))
        for proxy, mark in (("volume", "^-"), ("volume, direct", "v:"), ("shell", "o-"), ("uniform", "s--")):
            for scale in (2, 4):
                pts = [c for c in chart if c[0] == proxy and c[1] == scale]
                ax.plot([c[3] for c in pts], [c[4] for c in pts], mark, label=f"{proxy} proxy at 1/{scale} size")
        levels = [c for c in chart if c[0] == "volume, the window's levels"]
        ax.plot([c[3] for c in levels], [c[4] for c in levels], "D-", color="black", label="the window's proxy levels (volume)")
        ax.axvline(33, color="gray", ls="--", lw=0.8)
        gl = full["gl"].split(", ", 1)[-1]
        ax.set_xlabel(f"frame time, ms ({gl.split(' (')[0]}, {os.cpu_count()} cores)")
        ax.set_ylabel("SSIM against full detail (4x downsampled)")
        ax.set_title(f"Level of detail, {args.streamlines // 1000}k streamlines")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.chart, dpi=100)
    except ImportError:
        pass
    return text


if __name__ == "__main__":
    main()
