#!/usr/bin/python3
"""Tractogram loading benchmark: Horizon against nibabel (Debian's
python3-nibabel) and `cat`, on the same files, in one run.

    /usr/bin/python3 bench/io_bench.py [--build build] [--work /tmp/horizon-io] [--streamlines 1000000] [--points 100]

Writes one TCK of N random-walk streamlines of P points (float32), converts
it with horizon to TRK and TRX (stored zip), then times, per file, with a
warm page cache (each file's pages dropped, then read back once by `cat`, so
every file is cached as a cold read leaves it) and Horizon's plugin trial list
warm: `cat FILE > /dev/null`, nibabel's `nib.streamlines.load`
(CPU seconds of the whole process minus the interpreter's start-up, as
measured on an empty script), `horizon info FILE` (a full load into the
data model plus its statistics) and `horizon info --verify FILE` (the same,
then the host reads every coordinate again: for a file whose floats are
mapped at an unaligned offset, that includes copying them to aligned
memory, which a plain load defers to the first use). Peak memory is the
process's maximum RSS against the decoded data (positions + offsets).
The unaligned TCK is the aligned one as nibabel saves it (data at byte 67).
Each time is the best of --repeat runs, the tools run in turn (cat, horizon,
horizon --verify, nibabel, then again), so that a slow spell of the machine
does not fall on one side only.
Prints a Markdown table and writes bench/results/io.md.
"""
import argparse
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def timed(cmd, env=None):
    """(wall s, cpu s, max rss MiB) of one child process, via GNU time."""
    t0 = time.perf_counter()
    p = subprocess.run(["/usr/bin/time", "-f", "TIME %U %S %M", *cmd], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       env=env, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        sys.exit(f"{cmd} failed: {p.stderr}")
    line = [l for l in p.stderr.splitlines() if l.startswith("TIME ")][-1].split()
    return wall, float(line[1]) + float(line[2]), float(line[3]) / 1024.0


def best_of(n, cmd):
    return best_in_turn(n, [cmd])[0]


def best_in_turn(n, cmds):
    """Each command once per round, n rounds, in turn: per command (the
    shortest wall s, the smallest cpu s, the largest max rss). Alternating
    keeps a slow spell of this shared VM from landing on one side only."""
    runs = [[] for _ in cmds]
    for _ in range(n):
        for i, cmd in enumerate(cmds):
            runs[i].append(timed(cmd))
    return [(min(r[0] for r in rs), min(r[1] for r in rs), max(r[2] for r in rs)) for rs in runs]


def write_tck(path, n, p, seed=0):
    """Random walks as a Float32LE TCK, the data starting on a multiple of 4
    bytes, as MRtrix writes them (Horizon maps them in place)."""
    rng = np.random.default_rng(seed)
    head = "mrtrix tracks\ncount: %d\ndatatype: Float32LE\nfile: . %%d\nEND\n" % n
    offset = (len(head) + 10 + 3) // 4 * 4
    head = (head % offset).encode()
    head += b"\0" * (offset - len(head))
    with open(path, "wb") as f:
        f.write(head)
        chunk = 50_000
        for start in range(0, n, chunk):
            k = min(chunk, n - start)
            steps = rng.normal(scale=0.6, size=(k, p, 3)).astype(np.float32)
            pts = np.cumsum(steps, axis=1) + rng.uniform(-60, 60, (k, 1, 3)).astype(np.float32)
            block = np.concatenate([pts, np.full((k, 1, 3), np.nan, np.float32)], axis=1)
            f.write(block.astype("<f4").tobytes())
        f.write(np.full(3, np.inf, "<f4").tobytes())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--work", default="/tmp/horizon-io")
    ap.add_argument("--streamlines", type=int, default=1_000_000)
    ap.add_argument("--points", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    horizon = os.path.join(args.build, "bin", "horizon")
    n, p = args.streamlines, args.points
    tck = os.path.join(args.work, f"walks_{n}x{p}_aligned.tck")
    if not os.path.exists(tck):
        write_tck(tck, n, p)
    unaligned = os.path.join(args.work, f"walks_{n}x{p}_nibabel.tck")
    if not os.path.exists(unaligned):  # (about 25 s)
        subprocess.run(["/usr/bin/python3", "-c", "import sys, nibabel as nib; "
                        "nib.streamlines.save(nib.streamlines.load(sys.argv[1]).tractogram, sys.argv[2])", tck, unaligned],
                       check=True)
    files = {"tck": tck, "tck (nibabel-written)": unaligned}
    for ext in ("trk", "trx"):
        out = os.path.join(args.work, f"walks_{n}x{p}.{ext}")
        if not os.path.exists(out):
            subprocess.run([horizon, "convert", tck, out], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        files[ext] = out
    decoded_mib = (n * p * 12 + (n + 1) * 8) / 2**20
    nib_script = "import sys, nibabel as nib; s = nib.streamlines.load(sys.argv[1]).streamlines; len(s._data)"
    _, py_start, _ = best_of(args.repeat, ["/usr/bin/python3", "-c", "import sys, nibabel"])
    # Horizon's plugin trial list as after any earlier command (README: the trial list).
    subprocess.run([horizon, "plugins"], check=True, stdout=subprocess.DEVNULL)
    rows = []
    for ext, path in files.items():
        size_mib = os.path.getsize(path) / 2**20
        # The page cache as a cold read leaves it: the file's pages dropped, then
        # read back once. How a file was written changes how the kernel caches
        # it (in how large pieces), and with it the cost of reading it again.
        fd = os.open(path, os.O_RDONLY)
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
        os.close(fd)
        subprocess.run(["cat", path], stdout=subprocess.DEVNULL)
        cmds = [["cat", path], [horizon, "info", path], [horizon, "info", "--verify", path]]
        if ext != "trx":  # (nibabel 5.0 has no TRX reader)
            cmds.append(["/usr/bin/python3", "-c", nib_script, path])
        res = best_in_turn(args.repeat, cmds)
        (cat_s, _, _), (hz_s, hz_cpu, hz_rss), (ver_s, _, ver_rss) = res[:3]
        nib_cpu = res[3][1] - py_start if ext != "trx" else None
        rows.append((ext, size_mib, cat_s, nib_cpu, hz_s, hz_cpu, hz_rss, ver_s, ver_rss, os.getloadavg()[0]))
        nib_txt = f"{nib_cpu:7.2f}" if nib_cpu else "      -"
        print(f"{ext}: {size_mib:7.0f} MiB  cat {cat_s:5.2f} s  nibabel {nib_txt} s  horizon {hz_s:5.2f} s "
              f"(cpu {hz_cpu:5.2f})  rss {hz_rss:6.0f} MiB ({hz_rss / decoded_mib:.2f}x decoded)  --verify {ver_s:5.2f} s "
              f"rss {ver_rss:6.0f} MiB", flush=True)
    os.makedirs(os.path.join(ROOT, "bench", "results"), exist_ok=True)
    with open(os.path.join(ROOT, "bench", "results", "io.md"), "w") as f:
        f.write(f"{n:,} streamlines x {p} points, decoded {decoded_mib:.0f} MiB; page cache warm from a cold read (each file dropped from it, then read once); plugin trial list warm; best of {args.repeat}, the tools run in turn.\n"
                "tck: data at a multiple of 4 bytes, as MRtrix writes them (mapped in place); tck (nibabel-written): the "
                "same streamlines saved by nibabel, data at byte 67 (mapped; the floats are copied to aligned memory on "
                "first use). `--verify`: the load, then the host reads every coordinate again (for the nibabel-written "
                "TCK, after that copy). load: the 1-minute load average.\n\n")
        f.write("| format | file (MiB) | cat (s) | nibabel load, CPU (s) | horizon info (s) | vs nibabel | vs cat "
                "| info --verify (s) | vs nibabel | peak RSS / decoded (info, --verify) | load |\n")
        f.write("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
        for ext, size, cat_s, nib_cpu, hz_s, hz_cpu, rss, ver_s, ver_rss, la in rows:
            vs_nib = f"{nib_cpu / hz_s:.1f}x faster" if nib_cpu else "-"
            ver_nib = f"{nib_cpu / ver_s:.1f}x faster" if nib_cpu else "-"
            nib_txt = f"{nib_cpu:.2f}" if nib_cpu else "- (no TRX reader)"
            f.write(f"| {ext} | {size:.0f} | {cat_s:.2f} | {nib_txt} | {hz_s:.2f} | {vs_nib} | {hz_s / cat_s:.1f}x cat | "
                    f"{ver_s:.2f} | {ver_nib} | {rss / decoded_mib:.2f}, {ver_rss / decoded_mib:.2f} | {la:.2f} |\n")
    print("wrote bench/results/io.md")


if __name__ == "__main__":
    main()
