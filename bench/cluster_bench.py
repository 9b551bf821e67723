#!/usr/bin/python3
"""QuickBundles / QuickBundlesX benchmark: Horizon (exact and fast modes)
against DIPY (Debian's python3-dipy), on the same files, in one run.

    /usr/bin/python3 bench/cluster_bench.py [--build build] [--work /tmp/horizon-bench] [--quick]

Prints a Markdown table of times and ratios, checks that exact mode gives
DIPY's labels, and writes the speed-against-accuracy chart
(docs/cluster_chart.png) and the table (bench/results/cluster.md).
Times are wall-clock seconds of the clustering call only (file reading, which
for horizon includes making a mapped input resident,
excluded on both sides), the best of --repeat runs (3) for DIPY and Horizon
alike, run in turn (DIPY, exact, fast, then again), since this shared machine's speed drifts by 10-30 % between runs;
DIPY runs single-threaded, Horizon uses both cores. The machine load is printed with every run.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import zipfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def loadavg():
    with open("/proc/loadavg") as f:
        return float(f.read().split()[0])


def horizon(build, *args):
    p = subprocess.run([os.path.join(build, "bin", "horizon"), *map(str, args)], capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"horizon {' '.join(map(str, args))} failed: {p.stderr}")
    return p.stdout


def ours(build, tck, algo, mode, labels, thresholds=None, nb_points=None):
    """One `horizon cluster` process: (its clustering seconds, its labels)."""
    args = ["cluster", tck, "--algorithm", algo, "--mode", mode, "--labels", labels, "--force", "--json"]
    if thresholds:
        args += ["--thresholds", ",".join(map(str, thresholds))]
    if nb_points:
        args += ["--nb-points", nb_points]
    secs = json.loads(horizon(build, *args))["cluster_s"]
    lab = np.loadtxt(labels, delimiter=",", skiprows=1, dtype=np.int64, ndmin=2)
    return secs, lab


def interleaved(repeat, fns):
    """Each fn() once per round, `repeat` rounds, in turn: (the shortest time
    of each, the last result of each). A fn returns (seconds or None to time
    it here, result). Alternating keeps a slow spell of this shared VM from
    landing on one side only (running one side's repeats back to back let
    a spell decide a ratio)."""
    best, out = [float("inf")] * len(fns), [None] * len(fns)
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            s, out[i] = fn()
            best[i] = min(best[i], s if s is not None else time.perf_counter() - t0)
    return best, out


def dipy_labels(clusters, n):
    ref = np.full(n, -1, np.int64)
    for i, c in enumerate(clusters):
        ref[np.asarray(c.indices)] = i
    return ref


def ari(a, b):
    """Adjusted Rand index (Hubert & Arabie 1985) from the contingency table."""
    n = len(a)
    if n < 2:
        return 1.0
    _, ai = np.unique(a, return_inverse=True)
    _, bi = np.unique(b, return_inverse=True)
    pairs = ai.astype(np.int64) * (bi.max() + 1) + bi
    _, nij = np.unique(pairs, return_counts=True)
    comb = lambda x: (x * (x - 1) / 2.0).sum()
    sij, sa, sb = comb(nij), comb(np.bincount(ai)), comb(np.bincount(bi))
    expected = sa * sb / (n * (n - 1) / 2.0)
    denom = 0.5 * (sa + sb) - expected
    return 1.0 if denom == 0 else (sij - expected) / denom


def matched_fraction(a, b):
    """Fraction of streamlines whose cluster in `a` maps to their cluster in
    `b` under the majority mapping (each a-cluster -> the b-cluster holding
    most of its members)."""
    _, ai = np.unique(a, return_inverse=True)
    _, bi = np.unique(b, return_inverse=True)
    pairs = ai.astype(np.int64) * (bi.max() + 1) + bi
    u, cnt = np.unique(pairs, return_counts=True)
    best = np.zeros(ai.max() + 1, np.int64)
    np.maximum.at(best, u // (bi.max() + 1), cnt)
    return best.sum() / len(a)


def fast_agreement(le, lf, levels):
    """Fast mode against exact mode, worst level: the fraction of streamlines
    in the same cluster (fast clusters mapped to the exact cluster holding most
    of their members), and the fraction with the same cluster id. Ids are DFS
    positions, so one cluster created elsewhere late in the run renumbers every
    later one: the ids can differ for most streamlines while the clusters are
    the same for all but a few."""
    same = min(matched_fraction(lf[:, l], le[:, l]) for l in levels)
    ids = min((le[:, l] == lf[:, l]).mean() for l in levels)
    return f"fast in the same cluster: {100 * same:.3f}% (same id: {100 * ids:.3f}%)"


def make_real(work, n):
    """DIPY's minimal_bundles (3 bundles x 2 subjects) replicated with random
    rigid transforms (rotation up to 10 degrees, translation up to 10 mm)."""
    import nibabel as nib
    path = os.path.join(work, f"real_{n}.tck")
    if os.path.exists(path):
        return path
    import dipy
    z = os.path.join(os.path.dirname(dipy.__file__), "data", "files", "minimal_bundles.zip")
    base = []
    with tempfile.TemporaryDirectory() as d:
        zipfile.ZipFile(z).extractall(d)
        for root, _, files in os.walk(d):
            for f in sorted(files):
                if f.endswith(".trk"):
                    base += [s.astype(np.float64) for s in nib.streamlines.load(os.path.join(root, f)).streamlines]
    rng = np.random.default_rng(0)
    out = []
    while len(out) < n:
        ang = np.radians(rng.uniform(-10, 10, 3))
        cx, cy, cz = np.cos(ang)
        sx, sy, sz = np.sin(ang)
        R = (np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
             @ np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]))
        t = rng.uniform(-10, 10, 3)
        out += [(s @ R.T + t).astype(np.float32) for s in base]
    nib.streamlines.save(nib.streamlines.Tractogram(out[:n], affine_to_rasmm=np.eye(4)), path)
    return path


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--work", default="/tmp/horizon-bench")
    ap.add_argument("--quick", action="store_true", help="small sizes only (a smoke run)")
    ap.add_argument("--skip-5m", action="store_true")
    ap.add_argument("--dipy-qb-1m", action="store_true", help="also run DIPY's QB on 1M streamlines (about 15 min)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs per measurement in the ratio table, best taken, for DIPY and Horizon alike (default 3)")
    args = ap.parse_args()
    R = args.repeat
    os.makedirs(args.work, exist_ok=True)
    import nibabel as nib
    from dipy.segment.clustering import QuickBundles, QuickBundlesX

    sizes = [20_000, 50_000] if args.quick else [100_000, 1_000_000, 2_000_000]
    files = {}
    for n in sizes + ([] if args.quick or args.skip_5m else [5_000_000]):
        d = os.path.join(args.work, f"synth_{n}")
        if not os.path.exists(os.path.join(d, "phantom.tck")):
            horizon(args.build, "demo", "--out", d, "--streamlines", n, "--bundles", 120, "--seed", 7)
        files[f"synthetic {n // 1000}k"] = (os.path.join(d, "phantom.tck"), n)
    real_n = 50_000 if args.quick else 1_000_000
    files[f"DIPY bundles x{real_n // 1000}k"] = (make_real(args.work, real_n), real_n)
    lab = os.path.join(args.work, "labels.csv")
    T = [30, 25, 20, 15]
    rows = []

    def row(name, n, what, dipy_s, exact_s, fast_s, agree, note=""):
        rows.append((name, n, what, dipy_s, exact_s, fast_s, agree, note, loadavg()))
        d = f"{dipy_s:8.2f}" if dipy_s else "       -"
        print(f"{name:24s} {what:10s} dipy {d}  exact {exact_s:7.2f} ({(dipy_s or 0) / exact_s:5.1f}x)  "
              f"fast {fast_s:7.2f} ({(dipy_s or 0) / fast_s:5.1f}x)  {agree}  load {loadavg():.2f}", flush=True)

    # 1. QBX against DIPY on every file.
    for name, (tck, n) in files.items():
        if n > 2_000_000:
            continue
        sl = nib.streamlines.load(tck).streamlines
        (dipy_s, exact_s, fast_s), (ref, le, lf) = interleaved(R, [
            lambda: (None, QuickBundlesX(T).cluster(sl)),
            lambda: ours(args.build, tck, "qbx", "exact", lab),
            lambda: ours(args.build, tck, "qbx", "fast", lab)])
        same = all(np.array_equal(le[:, l], dipy_labels(ref.get_clusters(l), n)) for l in range(1, 5))
        row(name, n, "QBX", dipy_s, exact_s, fast_s, f"exact==DIPY at all levels: {same}; {fast_agreement(le, lf, range(1, 5))}")
        del sl, ref

    # 2. QB at 15 mm: DIPY on the smallest synthetic set only (it is O(N K)).
    name, (tck, n) = next(iter(files.items()))
    sl = nib.streamlines.load(tck).streamlines
    (dipy_s, exact_s, fast_s), (ref, le, lf) = interleaved(R, [
        lambda: (None, QuickBundles(15.0).cluster(sl)),
        lambda: ours(args.build, tck, "qb", "exact", lab, thresholds=[15]),
        lambda: ours(args.build, tck, "qb", "fast", lab, thresholds=[15])])
    row(name, n, "QB 15 mm", dipy_s, exact_s, fast_s,
        f"exact==DIPY: {np.array_equal(le[:, 1], dipy_labels(ref, n))}; {fast_agreement(le, lf, [1])}")
    del sl, ref

    if args.dipy_qb_1m and "synthetic 1000k" in files:
        tck, n = files["synthetic 1000k"]
        sl = nib.streamlines.load(tck).streamlines
        exact_s, le = ours(args.build, tck, "qb", "exact", lab, thresholds=[15])
        fast_s, lf = ours(args.build, tck, "qb", "fast", lab, thresholds=[15])
        t0 = time.perf_counter()
        ref = QuickBundles(15.0).cluster(sl)
        dipy_s = time.perf_counter() - t0
        row("synthetic 1000k", n, "QB 15 mm", dipy_s, exact_s, fast_s,
            f"exact==DIPY: {np.array_equal(le[:, 1], dipy_labels(ref, n))}; {fast_agreement(le, lf, [1])}")
        del sl, ref

    # 3. 5M streamlines, Horizon only.
    if "synthetic 5000k" in files:
        tck, n = files["synthetic 5000k"]
        (exact_s, fast_s), _ = interleaved(R, [lambda: ours(args.build, tck, "qbx", "exact", lab),
                                               lambda: ours(args.build, tck, "qbx", "fast", lab)])
        row("synthetic 5000k", n, "QBX", None, exact_s, fast_s, "Horizon only")

    # 4. The chart: time against agreement with a 64-point exact clustering.
    chart_name = next(iter(files))  # the smallest synthetic set: QB is O(N K)
    tck, n = files[chart_name]
    qb_name, qb_tck = chart_name, tck
    series = {}
    _, ref64 = ours(args.build, tck, "qbx", "exact", lab, nb_points=64)
    _, qb64 = ours(args.build, qb_tck, "qb", "exact", lab, thresholds=[15], nb_points=64)
    for algo, path, ref, pts_list in (("QBX", tck, ref64, [6, 8, 12, 16, 20, 32]), ("QB", qb_tck, qb64, [6, 8, 12, 16, 20, 32])):
        for mode in ("exact", "fast"):
            pts = []
            for p in pts_list:
                kw = {"thresholds": [15]} if algo == "QB" else {}
                t, l = ours(args.build, path, algo.lower(), mode, lab, nb_points=p, **kw)
                col = l[:, -1]
                pts.append((p, t, ari(col, ref[:, -1]), matched_fraction(col, ref[:, -1])))
                print(f"chart {algo} {mode:5s} {p:2d} points: {t:6.2f} s  ARI {pts[-1][2]:.4f}  matched {pts[-1][3]:.4f}", flush=True)
            series[(algo, mode)] = pts

    # QB against QBX: the same threshold (15 mm), 12 points, exact mode.
    _, qbx12 = ours(args.build, tck, "qbx", "exact", lab)
    _, qb12 = ours(args.build, tck, "qb", "exact", lab, thresholds=[15])
    cross = (ari(qbx12[:, -1], qb12[:, -1]), matched_fraction(qbx12[:, -1], qb12[:, -1]))
    print(f"QBX (finest level, 15 mm) against QB 15 mm: ARI {cross[0]:.4f}, matched {cross[1]:.4f}")

    # Outputs.
    os.makedirs(os.path.join(ROOT, "bench", "results"), exist_ok=True)
    with open(os.path.join(ROOT, "bench", "results", "cluster.md"), "w") as f:
        f.write(f"Best of {R} runs per time (DIPY and Horizon alike, run in turn: DIPY, exact, fast, then again).\n\n")
        f.write("| data | streamlines | algorithm | DIPY 1.6 (s) | Horizon exact (s) | ratio | Horizon fast (s) | ratio | check | load |\n")
        f.write("|---|---:|---|---:|---:|---:|---:|---:|---|---:|\n")
        for name, n, what, d, e, fa, agree, note, la in rows:
            ds = f"{d:.2f}" if d else "-"
            re_ = f"{d / e:.1f}x" if d else "-"
            rf = f"{d / fa:.1f}x" if d else "-"
            f.write(f"| {name} | {n:,} | {what} | {ds} | {e:.2f} | {re_} | {fa:.2f} | {rf} | {agree} | {la:.2f} |\n")
        f.write("\nChart data (finest level vs the 64-point exact clustering; "
                f"QBX on {chart_name}, QB 15 mm on {qb_name}):\n\n| algorithm | mode | points | time (s) | ARI | matched |\n|---|---|---:|---:|---:|---:|\n")
        for (algo, mode), pts in series.items():
            for p, t, a, m in pts:
                f.write(f"| {algo} | {mode} | {p} | {t:.2f} | {a:.4f} | {m:.4f} |\n")
        f.write(f"\nQBX (finest level, 15 mm) against QB 15 mm, 12 points, {chart_name}: "
                f"ARI {cross[0]:.4f}, matched fraction {cross[1]:.4f}.\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, metric, label in ((axes[0], 2, "adjusted Rand index"), (axes[1], 3, "matched fraction")):
        for (algo, mode), pts in series.items():
            xs = [p[1] for p in pts]
            ys = [p[metric] for p in pts]
            ax.plot(xs, ys, marker="o" if mode == "exact" else "s", linestyle="-" if algo == "QBX" else "--",
                    label=f"{algo} {mode}")
            for p in pts:
                ax.annotate(str(p[0]), (p[1], p[metric]), textcoords="offset points", xytext=(3, 3), fontsize=7)
        ax.set_xscale("log")
        ax.set_xlabel("clustering time (s, log scale)")
        ax.set_ylabel(f"{label} vs 64-point clustering")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"Speed against accuracy on {chart_name}: points per streamline (labels); QBX 30/25/20/15 mm "
                 f"(finest level), QB 15 mm; QBX vs QB: ARI {cross[0]:.3f}", fontsize=9)
    fig.tight_layout()
    os.makedirs(os.path.join(ROOT, "docs"), exist_ok=True)
    out = os.path.join(ROOT, "docs", "cluster_chart.png")
    fig.savefig(out, dpi=110)
    print(f"\nwrote {out} and bench/results/cluster.md")


if __name__ == "__main__":
    main()
