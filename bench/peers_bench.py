#!/usr/bin/env python3
"""Horizon's window against its peers on the same realistic tractograms, in
one run, same window size (1280x800), all under Xvfb on this machine:

- mrview 3.0.3 (`mrtrix3`): launch to its first frame, taken as launch to the
  exit of `mrview REF -tractography.load FILE -capture.grab -exit` (it draws
  every streamline in its first frame; REF is an empty volume around the
  tractogram, which mrview needs to open a view);
- VTK 9.1 (`python3-vtk9`, the engine of DIPY's Horizon and FURY):
  bench/vtk_lines.py, launch (interpreter included) to the first frame of the
  streamlines as polylines, and the time of a second frame;
- Horizon: `horizon view FILE --stats` (launch to first frame, to the complete
  still image, moving frame median).

Peak RSS is the maximum resident set (/usr/bin/time %M: file pages included,
the same measure for all three).

    /usr/bin/python3 bench/peers_bench.py [--sizes 10000,100000] [--work DIR]

Writes bench/results/peers.md.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
XVFB = ["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24"]


def timed(cmd, timeout):
    """Wall seconds and peak RSS (MB) of cmd run under Xvfb via /usr/bin/time."""
    with tempfile.NamedTemporaryFile("r", suffix=".txt", delete=False) as tf:
        tpath = tf.name
    t0 = time.perf_counter()
    try:
        p = subprocess.run(XVFB + ["/usr/bin/time", "-o", tpath, "-f", "%M", *cmd], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, None, ""
    wall = time.perf_counter() - t0
    try:
        with open(tpath) as f:
            rss = int(f.read().strip().splitlines()[-1]) / 1024
    except (ValueError, IndexError, OSError):
        rss = None
    os.unlink(tpath)
    if p.returncode != 0:
        raise SystemExit(f"{cmd[0]} failed ({p.returncode}): {p.stderr[-2000:]}")
    return wall, rss, p.stdout


def reference_volume(path, work):
    import nibabel as nib
    import numpy as np
    info = json.loads(subprocess.run([os.path.join(ROOT, "build", "bin", "horizon"), "info", path, "--json"], capture_output=True,
                                     text=True, check=True).stdout)
    lo, hi = np.array(info["bbox_ras_mm"]["min"]), np.array(info["bbox_ras_mm"]["max"])
    aff = np.diag([2.0, 2.0, 2.0, 1.0])
    aff[:3, 3] = lo - 2
    dims = np.ceil((hi - lo + 4) / 2).astype(int)
    ref = os.path.join(work, "ref.nii.gz")
    nib.save(nib.Nifti1Image(np.zeros(dims, np.float32), aff), ref)
    return ref


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="10000,100000")
    ap.add_argument("--work", default=tempfile.gettempdir())
    ap.add_argument("--timeout", type=float, default=900)
    ap.add_argument("--vtk-max", type=int, default=200000,
                    help="larger files are not drawn with VTK (about 42 KB of memory per streamline: 1M would need ~40 GB)")
    args = ap.parse_args()
    horizon = os.path.join(ROOT, "build", "bin", "horizon")
    make = os.path.join(ROOT, "build", "bin", "hz-make-tractogram")
    work = tempfile.mkdtemp(prefix="hz_peers_")
    rows = []
    for n in map(int, args.sizes.split(",")):
        tck = os.path.join(args.work, f"brain_{n}.tck")
        if not os.path.exists(tck):
            subprocess.run([make, tck, "--streamlines", str(n), "--seed", "1"], check=True, capture_output=True)
        ref = reference_volume(tck, work)
        # Horizon: a rest, a drag, a rest, then quit once the still image is complete.
        script = os.path.join(work, "s.txt")
        with open(script, "w") as f:
            f.write(f"wait 3\ndrag 300 300 500 340\nwait 10\nscreenshot {os.path.join(work, 'h.png')}\nquit\n")
        stats = os.path.join(work, "stats.json")
        wall, h_rss, _ = timed([horizon, "view", tck, "--size", "1280x800", "--script", script, "--stats", stats], args.timeout)
        with open(stats) as f:
            st = json.load(f)
        moving = sorted(fr["ms"] for fr in st["frames"] if fr["kind"] == "moving")
        h = {"first": st["first_frame_s"], "complete": st["first_complete_s"], "moving": moving[len(moving) // 2] if moving else None,
             "rss": h_rss}
        # mrview
        cap = os.path.join(work, "cap")
        os.makedirs(cap, exist_ok=True)
        m_wall, m_rss, _ = timed(["mrview", ref, "-tractography.load", tck, "-mode", "3", "-size", "1280,800", "-capture.folder", cap,
                                  "-capture.prefix", f"m{n}", "-capture.grab", "-exit"], args.timeout)
        # VTK
        v_wall, v_rss, out, v = None, None, "", {}
        if n <= args.vtk_max:
            v_wall, v_rss, out = timed([sys.executable, os.path.join(ROOT, "bench", "vtk_lines.py"), tck, os.path.join(work, "v.png")],
                                       args.timeout)
            v = json.loads(out.strip().splitlines()[-1]) if out else {}
        rows.append((n, h, (m_wall, m_rss), (v.get("first_frame_s"), v.get("frame_s"), v_rss)))
        print(n, h, m_wall, m_rss, v, v_rss, flush=True)

    def f(x, fmt="{:.1f}"):
        return "—" if x is None else fmt.format(x)
    lines = ["# Horizon against mrview and VTK", "",
             "`/usr/bin/python3 bench/peers_bench.py` (release build; realistic tractograms from `hz-make-tractogram --seed 1`, "
             "about 164 points per streamline; 1280x800 under Xvfb; llvmpipe, 2 cores). Launch to first frame includes reading the file. "
             "mrview and VTK draw every streamline in their first frame; Horizon's first frame is its level-of-detail proxy, "
             "refined to every streamline by the complete still image. VTK is not run above --vtk-max streamlines (its memory, "
             "about 42 KB per streamline here, would exceed this 24 GB machine at 1M): shown as —.", "",
             "| streamlines | Horizon first frame (s) | Horizon complete (s) | Horizon moving frame (ms) | Horizon peak RSS (MB) | "
             "mrview first frame (s) | mrview peak RSS (MB) | VTK first frame (s) | VTK next frame (s) | VTK peak RSS (MB) | "
             "first frame: mrview / Horizon | VTK / Horizon |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for n, h, (mw, mr), (vf, vn, vr) in rows:
        lines.append(f"| {n:,} | {f(h['first'], '{:.2f}')} | {f(h['complete'])} | {f(h['moving'], '{:.0f}')} | {f(h['rss'], '{:.0f}')} | "
                     f"{f(mw)} | {f(mr, '{:.0f}')} | {f(vf)} | {f(vn, '{:.2f}')} | {f(vr, '{:.0f}')} | "
                     f"{f(mw / h['first'] if mw else None, '{:.0f}x')} | {f(vf / h['first'] if vf else None, '{:.0f}x')} |")
    text = "\n".join(lines) + "\n"
    print(text)
    with open(os.path.join(ROOT, "bench", "results", "peers.md"), "w") as fh:
        fh.write(text)


if __name__ == "__main__":
    main()
