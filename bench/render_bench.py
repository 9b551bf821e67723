#!/usr/bin/env python3
"""Renderer benchmark (llvmpipe, 1280x720): cost per frame of the shading
models and of the principled BRDF's cheaper or costlier variants, their
error against the full model, and end-to-end headless PNGs of tractograms.

    /usr/bin/python3 bench/render_bench.py [--horizon build/bin/horizon] [--quick]

Writes bench/results/render.md and docs/shading_chart.png. Frame times are
the fastest of frames 2..16 of one `horizon render --frames 16` process (the
first frame includes the driver's shader compilation; on a shared machine
the fastest frame is the stable figure, the median drifts by up to 30%). Errors come from the
CPU references through `horizon brdf`: the mean over random shading points
(cosine-weighted light, uniform view, both in the upper hemisphere) of
|f_variant - f_full| n.l, relative to the mean of f_full n.l.
"""
import argparse
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

FULL = {"subsurface": 0.5, "metallic": 0.0, "specular": 0.5, "specular_tint": 0.0, "roughness": 0.4, "anisotropic": 0.5,
        "sheen": 0.5, "sheen_tint": 0.5, "clearcoat": 0.5, "clearcoat_gloss": 0.8, "base_color": [0.8, 0.45, 0.3]}


def variants():
    iso = dict(FULL, anisotropic=0.0)
    return [
        ("principled, default parameters", "principled", {}, None),
        ("flat (unlit)", "flat", {}, None),
        ("lambert", "lambert", {}, None),
        ("blinn-phong", "blinn_phong", {}, None),
        ("principled, full (reference)", "principled", FULL, FULL),
        ("principled, isotropic path", "principled", iso, iso),  # its own reference: exact
        ("principled, Lambert diffuse", "principled", dict(FULL, diffuse=1), FULL),
        ("principled, exact Fresnel", "principled", dict(FULL, fresnel=1), FULL),
        ("principled, height-correlated G", "principled", dict(FULL, visibility=1), FULL),
        ("principled, no clearcoat/sheen/subsurface", "principled",
         dict(FULL, clearcoat=0.0, sheen=0.0, subsurface=0.0), FULL),
    ]


def frame_ms(horizon, material, env, frames, tmp):
    scene = {"objects": [{"type": "surface", "builtin": "sphere", "color": FULL["base_color"],
                          "material": material}],
             "camera": {"position": [0, -58, 0], "target": [0, 0, 0], "fov": 90}, "environment": {"type": env}}
    path = os.path.join(tmp, "sphere.json")
    with open(path, "w") as f:
        json.dump(scene, f)
    out = subprocess.run([horizon, "render", path, "-o", os.path.join(tmp, "s.png"), "--force", "--frames", str(frames), "--samples", "1",
                          "--json"], capture_output=True, text=True, check=True, env={**os.environ, "DISPLAY": ""})
    return json.loads(out.stdout)["frame_ms_min"]


def unit(v):
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]


def brdf_error(horizon, params, ref, n=20000, seed=7):
    if ref is None:
        return None
    rng = random.Random(seed)
    cases = []
    for i in range(n):
        u1, u2 = rng.random(), rng.random()
        r, phi = math.sqrt(u1), 2 * math.pi * u2
        L = [r * math.cos(phi), r * math.sin(phi), math.sqrt(max(0.0, 1 - u1))]
        z = rng.random()
        s = math.sqrt(max(0.0, 1 - z * z))
        phi = 2 * math.pi * rng.random()
        V = [s * math.cos(phi), s * math.sin(phi), z]
        base = {"N": [0, 0, 1], "X": [1, 0, 0], "Y": [0, 1, 0], "L": L, "V": V}
        cases.append(dict(base, id=f"a{i}", model="principled", params=params))
        cases.append(dict(base, id=f"b{i}", model="principled", params=ref))
    text = "\n".join(json.dumps(c) for c in cases) + "\n"
    out = subprocess.run([horizon, "brdf"], input=text, capture_output=True, text=True, check=True).stdout.splitlines()
    vals = [json.loads(l)["value"] for l in out]
    num = den = 0.0
    for i in range(n):
        a, b = vals[2 * i], vals[2 * i + 1]
        cos = cases[2 * i]["L"][2]
        num += sum(abs(x - y) for x, y in zip(a, b)) * cos
        den += sum(b) * cos
    return num / den


def tractogram_png(horizon, n, lod, render, tmp):
    scene = {"objects": [{"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": n}, "render": render}]}
    path = os.path.join(tmp, "tracts.json")
    with open(path, "w") as f:
        json.dump(scene, f)
    t0 = time.perf_counter()
    out = subprocess.run([horizon, "render", path, "-o", os.path.join(tmp, "t.png"), "--force", "--lod-pixels", str(lod), "--json"],
                         capture_output=True, text=True, check=True, env={**os.environ, "DISPLAY": ""})
    wall = time.perf_counter() - t0
    return wall, json.loads(out.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--horizon", default=os.path.join(ROOT, "build", "bin", "horizon"))
    ap.add_argument("--quick", action="store_true", help="fewer frames and samples (smoke run)")
    args = ap.parse_args()
    frames = 3 if args.quick else 16
    nerr = 2000 if args.quick else 20000
    rows, tract_rows = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for name, shader, params, ref in variants():
            material = {"shader": shader, "params": {k: v for k, v in params.items() if k != "base_color"}}
            ms_none = frame_ms(args.horizon, material, "none", frames, tmp)
            ms_ibl = frame_ms(args.horizon, material, "studio", frames, tmp)
            err = brdf_error(args.horizon, params, ref, n=nerr)
            rows.append((name, ms_none, ms_ibl, err))
            print(f"{name:45s} {ms_none:7.1f} ms  {ms_ibl:7.1f} ms (IBL)  error {err if err is not None else '-'}", flush=True)
        for n in ([10000] if args.quick else [10000, 100000]):
            for render, lod in (("lines", 0.0), ("lines", 0.5), ("tubes", 0.5)):
                wall, st = tractogram_png(args.horizon, n, lod, render, tmp)
                tract_rows.append((n, render, lod, wall, st))
                print(f"{n:7d} {render:5s} lod {lod:.1f}: {wall:.2f} s end to end, frame {st['frame_ms']:.0f} ms, "
                      f"{st['points_kept']}/{st['points_total']} points", flush=True)

    host = subprocess.run([args.horizon, "render", "--help"], capture_output=True, text=True)
    md = ["# Renderer benchmark", "",
          f"llvmpipe (Mesa, 2 cores), 1280x720, one light rig of 3 lights, no MSAA; {time.strftime('%Y-%m-%d')}.", "",
          "## Shading: cost per frame and error against the full principled BRDF", "",
          "Full-screen sphere (every pixel shaded once). Error: mean |f - f_full| n.l / mean f_full n.l over 20 000 random",
          "shading points of the CPU references (`horizon brdf`); the isotropic path is compared with the full model at",
          "anisotropic = 0 (the specialised program must equal it).", "",
          "| variant | ms/frame, lights only | ms/frame, lights + studio IBL | relative error |", "|---|---|---|---|"]
    for name, a, b, e in rows:
        md.append(f"| {name} | {a:.1f} | {b:.1f} | {'-' if e is None else f'{e:.2e}'} |")
    md += ["", "## Tractograms: headless PNG, end to end", "",
           "Phantom tractogram (about 60 points per streamline), one `horizon render` process: EGL context, generation,",
           "upload, environment, first frame (with shader compilation), read-back and PNG.", "",
           "| streamlines | as | decimation (px) | points drawn | MSAA | first frame ms | end to end s |", "|---|---|---|---|---|---|---|"]
    for n, render, lod, wall, st in tract_rows:
        md.append(f"| {n} | {render} | {lod} | {st['points_kept']} / {st['points_total']} | {st['samples']}x | {st['first_frame_ms']:.0f} | {wall:.2f} |")
    os.makedirs(os.path.join(ROOT, "bench", "results"), exist_ok=True)
    with open(os.path.join(ROOT, "bench", "results", "render.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    print("\n".join(md))

    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no chart", file=sys.stderr)
        return
    fig, ax = plt.subplots(figsize=(8, 4.8))
    for name, a, b, e in rows:
        if e is None:
            continue
        y = max(e, 1e-7)
        ax.scatter([a], [y], s=40)
        ax.annotate(name.replace("principled, ", ""), (a, y), textcoords="offset points", xytext=(6, 4), fontsize=8)
    ax.set_yscale("log")
    ax.set_xlabel("ms per frame (1280x720, full-screen sphere, 3 lights, llvmpipe)")
    ax.set_ylabel("relative error vs the full principled BRDF\n(exact variants drawn at 1e-7)")
    ax.set_title("Principled BRDF variants: speed against accuracy")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(ROOT, "docs", "shading_chart.png"), dpi=110)
    print("wrote docs/shading_chart.png")


if __name__ == "__main__":
    main()
