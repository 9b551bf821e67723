#!/usr/bin/env python3
"""ODF glyphs: resolution against error against milliseconds.

For each icosphere subdivision of a glyph (0: 12 vertices ... 4: 2562):
- error: the glyph's surface (flat triangles between the vertices, each at
  its min-max normalised radius) against the ODF itself along 20,000 random
  directions, for 200 realistic ODFs (order 8, DIPY's descoteaux07 basis,
  one to three sharp fibre lobes): the radius along each direction where the
  ray meets the glyph's triangle, against the true normalised radius there
  (horizon.sh_to_sf, which is DIPY's sh_to_sf: tests/python), in % of the
  glyph's size;
- time: `horizon render` of a whole-brain axial slice (96 x 96 voxels, order 8)
  at 1280 x 720 (llvmpipe here): the frame, the upload, the whole command and
  its peak memory.

    PYTHONPATH=build/python HORIZON_BIN=build/bin/horizon python3 bench/odf_bench.py [OUT_DIR]

Writes OUT_DIR/odfs.md (a table) and OUT_DIR/odfs.png (error against ms)."""
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

import horizon

HORIZON = os.environ.get("HORIZON_BIN", "horizon")


def icosphere(s):
    """The glyphs' sphere, built here again by the same rule (odfs.hpp):
    an icosahedron's faces split in four s times, midpoints normalised."""
    t = (1 + 5 ** 0.5) / 2
    v = [np.array(p, float) for p in [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
                                      (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]]
    v = [p / np.linalg.norm(p) for p in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4),
         (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(s):
        mid, g = {}, []

        def m(a, b):
            k = (min(a, b), max(a, b))
            if k not in mid:
                p = (v[a] + v[b]) / 2
                v.append(p / np.linalg.norm(p))
                mid[k] = len(v) - 1
            return mid[k]
        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            g += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = g
    return np.array(v), np.array(f)


def realistic_sh(rng, n):
    """n ODFs of order 8: one to three lobes exp(k ((u . d)^2 - 1)), k in
    [15, 40], weights in [0.3, 1], fitted by least squares on a dense sphere."""
    dense, _ = icosphere(5)
    B = horizon._core._sh_matrix(dense, 8, "descoteaux07", True)
    out = np.zeros((n, B.shape[1]))
    for i in range(n):
        sf = np.zeros(len(dense))
        for _ in range(rng.integers(1, 4)):
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            sf += rng.uniform(0.3, 1) * np.exp(rng.uniform(15, 40) * ((dense @ d) ** 2 - 1))
        out[i] = np.linalg.lstsq(B, sf, rcond=None)[0]
    return out


def glyph_errors(sh, s, dirs):
    """Per ODF: the largest and mean |glyph radius - ODF radius| along
    `dirs`, both min-max normalised (the glyph's size is 1)."""
    v, f = icosphere(s)
    dense, _ = icosphere(6)
    worst, mean = [], []
    # Each direction's face: the one whose three vertices' cone holds it
    # (barycentric coordinates of the ray through the face's plane all >= 0).
    A = v[f]  # (F, 3, 3)
    inv = np.linalg.inv(np.transpose(A, (0, 2, 1)))  # (F, 3, 3): u = A^T b
    face = np.concatenate([np.argmax(np.einsum("fij,nj->nfi", inv, dirs[k:k + 1000]).min(axis=2), axis=1)
                           for k in range(0, len(dirs), 1000)])
    # (each basis matrix once: horizon.sh_to_sf(sh, u) is sh @ B(u).T)
    Bd, Bv, Bx = (horizon._core._sh_matrix(np.ascontiguousarray(u), 8, "descoteaux07", True) for u in (dirs, v, dense))
    for c in sh:
        true, at_v, ref = Bd @ c, Bv @ c, Bx @ c
        lo, hi = min(ref.min(), at_v.min(), true.min()), max(ref.max(), at_v.max(), true.max())
        r_true = (true - lo) / (hi - lo)
        rv = (at_v - lo) / (hi - lo)
        # The glyph's surface along u: u t on the plane through the face's
        # three points r_i v_i.
        P = rv[f[face]][..., None] * v[f[face]]  # (N, 3, 3)
        nrm = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
        den = np.einsum("nk,nk->n", nrm, dirs)
        t = np.where(np.abs(den) > 1e-12, np.einsum("nk,nk->n", nrm, P[:, 0]) / np.where(den == 0, 1, den), 0)
        e = np.abs(np.abs(t) - r_true)
        worst.append(e.max())
        mean.append(e.mean())
    return float(np.median(worst)), float(np.mean(mean))


def render_slice(tmp, s):
    path = os.path.join(tmp, "slice.nii.gz")
    if not os.path.exists(path):
        import nibabel as nib
        rng = np.random.default_rng(3)
        sh = realistic_sh(rng, 256)
        idx = rng.integers(0, 256, size=(96, 96))
        data = sh[idx][:, :, None, :].astype(np.float32)
        aff = np.diag([2.0, 2.0, 2.0, 1.0])
        aff[:3, 3] = [-95, -95, 0]
        nib.save(nib.Nifti1Image(data, aff), path)
    scene = os.path.join(tmp, f"s{s}.json")
    with open(scene, "w") as fh:
        json.dump({"objects": [{"type": "odfs", "file": path, "z": 0, "sphere": s}], "camera": {"view": "superior"},
                   "environment": {"type": "none"}}, fh)
    t0 = time.perf_counter()
    p = subprocess.run(["/usr/bin/time", "-f", "%M", HORIZON, "render", scene, "-o", os.path.join(tmp, f"s{s}.png"), "--size", "1280x720",
                        "--force", "--json"], capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    stats = json.loads(p.stdout)
    peak_mb = int(p.stderr.strip().splitlines()[-1]) / 1024
    return stats, wall, peak_mb


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
    rng = np.random.default_rng(1)
    sh = realistic_sh(rng, 200)
    dirs = rng.normal(size=(20000, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for s in range(5):
            worst, mean = glyph_errors(sh, s, dirs)
            stats, wall, peak = render_slice(tmp, s)
            v, f = icosphere(s)
            rows.append(dict(s=s, vertices=len(v), triangles=len(f) * 96 * 96, worst=100 * worst, mean=100 * mean,
                             frame=stats["first_frame_ms"], upload=stats.get("upload_ms", 0.0), wall=wall, peak=peak))
            print(rows[-1], flush=True)
    lines = ["# ODF glyphs: resolution against error against time", "",
             "`bench/odf_bench.py`: glyphs of 200 realistic order-8 ODFs (one to three sharp lobes, descoteaux07) against the "
             "ODF along 20,000 random directions (error in % of the glyph's size, min-max normalised: the median over ODFs of "
             "the largest, and the mean); a whole-brain axial slice (96 x 96 voxels) rendered by `horizon render` at 1280 x 720 "
             "on llvmpipe (2 cores): the first frame, the upload, the whole command and its peak memory.", "",
             "| subdivisions | vertices a glyph | triangles (slice) | largest error % | mean error % | frame ms | upload ms | command s | peak MiB |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['s']} | {r['vertices']} | {r['triangles']:,} | {r['worst']:.1f} | {r['mean']:.2f} | {r['frame']:.0f} | "
                     f"{r['upload']:.0f} | {r['wall']:.2f} | {r['peak']:.0f} |")
    with open(os.path.join(out_dir, "odfs.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.plot([r["frame"] for r in rows], [r["worst"] for r in rows], "o-", label="largest")
        ax.plot([r["frame"] for r in rows], [r["mean"] for r in rows], "s-", label="mean")
        for r in rows:
            ax.annotate(f"{r['vertices']} vertices", (r["frame"], r["worst"]), textcoords="offset points", xytext=(5, 5), fontsize=8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("first frame of a 96 x 96 slice, ms (llvmpipe, 1280 x 720)")
        ax.set_ylabel("glyph error, % of its size")
        ax.legend()
        ax.grid(True, which="both", alpha=0.3)
        fig.tight_layout()
        fig.savefig(os.path.join(out_dir, "odfs.png"), dpi=100)
    except ImportError:
        pass


if __name__ == "__main__":
    main()
