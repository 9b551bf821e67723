"""Quality control over a cohort on Dask (issue 54): every tractogram a glob
matches under a folder tree is loaded, measured and drawn from fixed views,
headless, one subject per task on a Dask cluster (a local one by default),
and a gallery (a static HTML page: thumbnails, numbers, failures; sorting and
filtering in the page, no server) is written beside the results.

    python3 -m horizon.batch ROOT --glob 'sub-*/**/*.tck' --out qc [--anatomy 'sub-*/anat/*_T1w.nii.gz']
                             [--surface 'sub-*/surf/*.gii'] [--workers 2] [--scheduler tcp://HOST:8786]

Per subject, in OUT/subjects/ID/: qc.json (counts, lengths, bounding box, the
source's size and time) and one PNG per view. Every file is written to a
temporary name and renamed into place, qc.json last: a subject with a
qc.json whose source is unchanged is done and skipped by the next run, so a
run can be stopped and resumed, and a worker that dies loses only its
current subject (Dask runs the task again elsewhere). A subject that fails
(a missing, truncated or hostile file) is one failed row with its one-line
error and never stops the others; it is tried again by the next run. The
exit status is 0 unless --strict is given and a subject failed.

Each subject also gets an interactive 3D view in the browser, OUT/subjects/
ID/view.html: its streamlines exported to glTF (scene.glb, every k-th
streamline so that at most --web-points points are shown) and drawn by
three.js, which the gallery carries with it (OUT/three/) so that it opens
offline from the files themselves. three.js is not part of Horizon: it is
found with --three DIR, $HORIZON_THREE_DIR, or an npm install of three@0.147
(the last release with classic-script loaders, which a page opened from
files can use) in the usual places; without it the gallery has no 3D views
and says so.

With --anatomy, each subject's anatomy (the file the glob matches in the
same subject folder, ROOT's first level) is the affine's sanity check: a
tractogram reaching more than --tolerance mm outside the anatomy's grid,
in RAS+ mm, is flagged (the usual sign of a wrong affine or a voxel-space
file), and drawn over its anatomy's slices. With --surface, every file the
glob matches in the subject's folder (its pial or white surfaces: GIFTI,
FreeSurfer, PLY, OBJ, glTF) is drawn translucent around the streamlines, in
the pictures and in the 3D view; a subject without one is warned about.
"""
import argparse
import glob
import html
import json
import os
import sys
import time

VIEWS = ("superior", "left", "anterior")

from .web import THREE_FILES, find_three as _find_three


def find_three(explicit=None):
    """horizon.web.find_three, an explicit folder named --three."""
    return _find_three(explicit, "--three")


def copy_three(three, out):
    """three.js's files into OUT/three/ (each written atomically; the same
    bytes already there are left alone)."""
    os.makedirs(os.path.join(out, "three"), exist_ok=True)
    for name, rel in THREE_FILES.items():
        with open(os.path.join(three, rel), "rb") as f:
            data = f.read()
        dst = os.path.join(out, "three", name)
        if os.path.exists(dst):
            with open(dst, "rb") as f:
                if f.read() == data:
                    continue
        _write_atomic(dst, data)


def web_view(data, folder, sid, points, surfaces=()):
    """The subject's 3D view (horizon.web): scene.glb (every k-th
    streamline, at most `points` points), scene.js (the parts' bytes, for a
    page opened from files, which may not fetch them), view.html, which
    takes three.js from the gallery's three/. `surfaces`: (name, Data) drawn
    translucent around the streamlines. Returns view.html's path."""
    from . import web
    part, shown, total = web.streamlines_part(data, points)
    _write_atomic(os.path.join(folder, "scene.glb"), part["glb"])
    parts = [part] + [web.surface_part(s, opacity=0.35) for _, s in surfaces]
    _write_atomic(os.path.join(folder, "scene.js"), web.parts_js(parts).encode())
    info = (f"{html.escape(sid)}: {web.describe(shown, total, len(surfaces), [])} (drag: turn, wheel: zoom, right drag: pan) "
            f'&middot; <a href="../../index.html">gallery</a>')
    scripts = [(f"../../three/{name}", None) for name in web.SCRIPTS] + [("scene.js", None)]
    page = os.path.join(folder, "view.html")
    _write_atomic(page, web.page(f"Horizon 3D: {sid}", info, scripts).encode())
    return page


def subject_id(root, path):
    """The subject's name: its path below ROOT, without the extension, with
    / as __ (sub-01/dwi/tracts.tck -> sub-01__dwi__tracts)."""
    rel = os.path.relpath(path, root)
    for ext in (".nii.gz", ".tck", ".trk", ".trx"):
        if rel.endswith(ext):
            rel = rel[: -len(ext)]
            break
    return rel.replace(os.sep, "__")


def _write_atomic(path, data):
    tmp = f"{path}.tmp-{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def _stamp(path):
    st = os.stat(path)
    return {"size": st.st_size, "mtime_ns": st.st_mtime_ns}


def measure(data):
    """Counts and statistics of a horizon.Data of streamlines."""
    import numpy as np
    pos = data.positions  # (the file's points, not copied)
    offsets = np.asarray(data.offsets).astype(np.int64)
    gap = data.gap
    n = len(offsets) - 1
    counts = np.diff(offsets) - gap
    # Each streamline's length: the difference of the running sum of segment
    # lengths between its last and first points (a segment between two
    # streamlines lies outside both; one to or from a delimiter is NaN, taken
    # as 0 so that the sum goes on), the segments taken in pieces of a few
    # million points (memory stays bounded at any size).
    seg = np.zeros(max(len(pos) - 1, 0))
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    step = 1 << 22
    for a in range(0, len(pos), step):
        p = np.asarray(pos[a:min(a + step + 1, len(pos))], dtype=np.float64)
        if len(p) > 1:
            seg[a:a + len(p) - 1] = np.linalg.norm(np.diff(p, axis=0), axis=1)
        fin = p[np.isfinite(p).all(axis=1)]
        if len(fin):
            lo, hi = np.minimum(lo, fin.min(axis=0)), np.maximum(hi, fin.max(axis=0))
    seg = np.nan_to_num(seg)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    starts, ends = offsets[:-1], np.maximum(offsets[1:] - gap - 1, offsets[:-1])
    lengths = cum[ends] - cum[starts]
    return {"streamlines": int(n), "points": int(counts.sum()),
            "points_per_streamline": {"min": int(counts.min()) if n else 0, "max": int(counts.max()) if n else 0},
            "length_mm": {k: float(f(lengths)) if n else 0.0 for k, f in (("min", np.min), ("median", np.median), ("max", np.max))},
            "bounding_box_mm": [lo.tolist(), hi.tolist()] if np.isfinite(lo).all() else None}


def anatomy_box(data):
    """The RAS+ mm box of a volume's grid (its voxels' outer faces)."""
    import numpy as np
    dims = list(data.voxels.shape[:3])
    corners = np.array([[i, j, k, 1.0] for i in (-0.5, dims[0] - 0.5) for j in (-0.5, dims[1] - 0.5) for k in (-0.5, dims[2] - 0.5)])
    ras = corners @ np.asarray(data.affine).T
    return ras[:, :3].min(axis=0), ras[:, :3].max(axis=0)


def outside_mm(box, lo, hi):
    """How far (mm) the box [box[0], box[1]] reaches outside [lo, hi]."""
    import numpy as np
    return float(max(0.0, np.max(lo - np.asarray(box[0])), np.max(np.asarray(box[1]) - hi)))


def qc_subject(root, path, out, views, size, anatomy=None, tolerance=10.0, web_points=None, surfaces=None):
    """One subject's QC (run on a worker): its record, written to
    OUT/subjects/ID/qc.json; done before and unchanged: read back. With
    `web_points`, its 3D view too (web_view). `surfaces`: the subject's
    surface files (None: none asked for), drawn translucent in its views."""
    import horizon
    sid = subject_id(root, path)
    folder = os.path.join(out, "subjects", sid)
    record_path = os.path.join(folder, "qc.json")
    try:
        stamp = _stamp(path)
    except OSError as e:
        stamp = None
        error = f"{path}: {e.strerror}"
    if stamp and os.path.exists(record_path):
        with open(record_path) as f:
            old = json.load(f)
        if old.get("status") == "ok" and old.get("source") == stamp and old.get("anatomy", {}).get("file") == (anatomy or None) and \
                (web_points is None or "view_3d" in old) and old.get("surfaces", []) == (surfaces or []):
            old["skipped"] = True
            return old
    os.makedirs(folder, exist_ok=True)
    record = {"id": sid, "file": path, "source": stamp, "views": {}, "warnings": []}
    t0 = time.perf_counter()
    try:
        if stamp is None:
            raise horizon.Error(error)
        data = horizon.load(path)
        if data.kind != "streamlines":
            raise horizon.Error(f"{path}: holds {data.kind}, not streamlines")
        record.update(measure(data))
        anat = None
        if anatomy:
            anat = horizon.load(anatomy)
            if anat.kind != "volume":
                raise horizon.Error(f"{anatomy}: holds {anat.kind}, not a volume")
            lo, hi = anatomy_box(anat)
            far = outside_mm(record["bounding_box_mm"], lo, hi) if record["bounding_box_mm"] else 0.0
            record["anatomy"] = {"file": anatomy, "box_mm": [lo.tolist(), hi.tolist()], "outside_mm": round(far, 2)}
            if far > tolerance:
                record["warnings"].append(f"the streamlines reach {far:.1f} mm outside {os.path.basename(anatomy)}'s grid "
                                          f"(a wrong affine, or streamlines in voxel space?)")
        elif anatomy is not None:
            record["warnings"].append("no anatomy found for this subject")
        surfs = []
        for f in surfaces or []:
            m = horizon.load(f)
            if m.kind != "mesh":
                raise horizon.Error(f"{f}: holds {m.kind}, not a surface")
            surfs.append((f, m))
        if surfaces:
            record["surfaces"] = list(surfaces)
        elif surfaces is not None:
            record["warnings"].append("no surface found for this subject")
        for view in views:
            scene = horizon.Scene(environment={"type": "studio"}, camera={"view": view})
            scene.add(data, render="lines")
            if anat is not None:
                scene.add(anat, type="slices")
            for _, m in surfs:
                scene.add(m, type="surface", opacity=0.35)
            png = os.path.join(folder, f"{view}.png")
            _write_atomic(png, horizon._png(scene.render(size)))
            record["views"][view] = os.path.relpath(png, out)
        if web_points is not None:
            record["view_3d"] = os.path.relpath(web_view(data, folder, sid, web_points, surfs), out)
        record["status"] = "ok"
    except Exception as e:  # (a subject's failure is its row, never the batch's)
        record["status"] = "failed"
        record["error"] = str(e).splitlines()[0] if str(e) else type(e).__name__
    record["seconds"] = round(time.perf_counter() - t0, 3)
    _write_atomic(record_path, json.dumps(record, indent=1).encode())
    record["skipped"] = False
    return record


GALLERY = """<!doctype html>
<html><head><meta charset="utf-8"><title>Horizon QC: {title}</title>
<style>
body{{font-family:sans-serif;margin:1em;background:#111;color:#ddd}} table{{border-collapse:collapse}}
td,th{{padding:4px 8px;border-bottom:1px solid #333;text-align:right}} th{{cursor:pointer;background:#222}}
td.id,td.error{{text-align:left}} tr.failed td{{color:#f88}} tr.warned td.error{{color:#fc6}} img{{height:96px}} input{{margin:0 0 1em 0;width:30em}}
</style></head><body>
<h1>Horizon QC: {title}</h1>
<p>{summary}</p>
<input id="filter" placeholder="filter (subject, status, error)">
<table id="t"><thead><tr>{head}</tr></thead><tbody>
{rows}
</tbody></table>
<script>
const t = document.getElementById('t');
document.getElementById('filter').addEventListener('input', e => {{
  const q = e.target.value.toLowerCase();
  for (const r of t.tBodies[0].rows) r.style.display = r.textContent.toLowerCase().includes(q) ? '' : 'none';
}});
t.tHead.addEventListener('click', e => {{
  const th = e.target.closest('th'); if (!th) return;
  const k = th.cellIndex, up = th.dataset.up !== '1'; th.dataset.up = up ? '1' : '0';
  const rows = [...t.tBodies[0].rows];
  const v = r => {{ const s = r.cells[k].dataset.v ?? r.cells[k].textContent; const x = parseFloat(s); return isNaN(x) ? s : x; }};
  rows.sort((a, b) => (v(a) > v(b) ? 1 : v(a) < v(b) ? -1 : 0) * (up ? 1 : -1));
  for (const r of rows) t.tBodies[0].appendChild(r);
}});
</script></body></html>
"""


def gallery(out, records, views, title, note_3d=""):
    cols = ["subject", "status", "streamlines", "points", "median length (mm)", "min length", "max length"] + list(views) + \
        ["3D", "error or warning"]
    head = "".join(f"<th>{html.escape(c)}</th>" for c in cols)
    rows = []
    for r in sorted(records, key=lambda r: r["id"]):
        ok = r.get("status") == "ok"
        lengths = r.get("length_mm", {})
        cells = [f'<td class="id">{html.escape(r["id"])}</td>', f"<td>{r.get('status')}</td>",
                 f"<td>{r.get('streamlines', '')}</td>", f"<td>{r.get('points', '')}</td>"]
        cells += [f"<td>{lengths[k]:.1f}</td>" if k in lengths else "<td></td>" for k in ("median", "min", "max")]
        for v in views:
            src = r.get("views", {}).get(v)
            cells.append(f'<td><a href="{html.escape(src)}"><img src="{html.escape(src)}" alt="{v}"></a></td>' if src else "<td></td>")
        v3 = r.get("view_3d") if ok else None
        cells.append(f'<td><a class="view3d" href="{html.escape(v3)}">3D</a></td>' if v3 else "<td></td>")
        note = r.get("error") or "; ".join(r.get("warnings", []))
        cells.append(f'<td class="error">{html.escape(note)}</td>')
        kind = "failed" if not ok else "warned" if r.get("warnings") else "ok"
        rows.append(f'<tr class="{kind}">' + "".join(cells) + "</tr>")
    failed = sum(r.get("status") != "ok" for r in records)
    warned = sum(r.get("status") == "ok" and bool(r.get("warnings")) for r in records)
    summary = f"{len(records)} subjects: {len(records) - failed} ok ({warned} with warnings), {failed} failed." + \
        (f" {html.escape(note_3d)}" if note_3d else "")
    page = GALLERY.format(title=html.escape(title), summary=summary, head=head, rows="\n".join(rows))
    _write_atomic(os.path.join(out, "index.html"), page.encode())
    _write_atomic(os.path.join(out, "qc.json"), json.dumps(sorted(records, key=lambda r: r["id"]), indent=1).encode())


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python3 -m horizon.batch", description=__doc__.split("\n\n")[0])
    ap.add_argument("root", help="the cohort's folder")
    ap.add_argument("--glob", default="**/*.tck", help="the tractograms, relative to ROOT (default **/*.tck; ** spans folders)")
    ap.add_argument("--out", required=True, help="the results folder (the gallery: OUT/index.html)")
    ap.add_argument("--views", default="superior,left", help=f"views drawn per subject, among {', '.join(VIEWS)} (default superior,left)")
    ap.add_argument("--size", default="320x240", help="each view's size, WIDTHxHEIGHT (default 320x240)")
    ap.add_argument("--workers", type=int, default=2, help="a local Dask cluster of this many worker processes, one thread each")
    ap.add_argument("--scheduler", help="the address of a Dask scheduler started elsewhere (then --workers is ignored)")
    ap.add_argument("--anatomy", help="each subject's anatomy, relative to ROOT (e.g. 'sub-*/anat/*_T1w.nii.gz'): the affine's "
                    "sanity check, and slices under the views")
    ap.add_argument("--surface", help="each subject's surfaces, relative to ROOT (e.g. 'sub-*/surf/*.pial.gii'): every file the glob "
                    "matches in the subject's folder, drawn translucent in its views and 3D view")
    ap.add_argument("--tolerance", type=float, default=10.0, help="--anatomy: mm the streamlines may reach outside its grid (10)")
    ap.add_argument("--strict", action="store_true", help="exit with status 1 if a subject failed")
    ap.add_argument("--three", help="an npm package three (0.147: npm install three@0.147) for the 3D views "
                    "(default: $HORIZON_THREE_DIR, else node_modules/three in the usual places)")
    ap.add_argument("--web-points", type=int, default=100000, help="the most points a 3D view shows (every k-th streamline; 100000)")
    ap.add_argument("--no-3d", action="store_true", help="no 3D views")
    a = ap.parse_args(argv)
    if a.web_points < 2:
        ap.error("--web-points: at least 2")
    three = None
    if not a.no_3d:
        try:
            three = find_three(a.three)
        except ValueError as e:
            ap.error(str(e))
    note_3d = "" if three or a.no_3d else "No 3D views: three.js was not found (npm install three@0.147, then --three DIR)."
    views = [v for v in a.views.split(",") if v]
    for v in views:
        if v not in VIEWS:
            ap.error(f"--views: '{v}' is not one of {', '.join(VIEWS)}")
    try:
        w, h = (int(x) for x in a.size.lower().split("x"))
        if not (16 <= w <= 4096 and 16 <= h <= 4096):
            raise ValueError
    except ValueError:
        ap.error(f"--size: expected WIDTHxHEIGHT between 16 and 4096, not '{a.size}'")
    if not os.path.isdir(a.root):
        ap.error(f"{a.root}: not a folder")
    root, out = os.path.abspath(a.root), os.path.abspath(a.out)
    files = sorted(glob.glob(os.path.join(root, a.glob), recursive=True))
    if not files:
        print(f"horizon.batch: error: no file under {a.root} matches '{a.glob}'", file=sys.stderr)
        return 1
    anatomy = [None] * len(files)
    if a.anatomy:
        by_subject = {}
        for f in sorted(glob.glob(os.path.join(root, a.anatomy), recursive=True)):
            by_subject.setdefault(os.path.relpath(f, root).split(os.sep)[0], f)
        anatomy = [by_subject.get(os.path.relpath(f, root).split(os.sep)[0], "") for f in files]
    surfaces = [None] * len(files)
    if a.surface:
        by_subject = {}
        for f in sorted(glob.glob(os.path.join(root, a.surface), recursive=True)):
            by_subject.setdefault(os.path.relpath(f, root).split(os.sep)[0], []).append(f)
        surfaces = [by_subject.get(os.path.relpath(f, root).split(os.sep)[0], []) for f in files]
    os.makedirs(os.path.join(out, "subjects"), exist_ok=True)
    from dask.distributed import Client, LocalCluster
    cluster = None
    if a.scheduler:
        client = Client(a.scheduler)
    else:
        cluster = LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    t0 = time.perf_counter()
    try:
        if three:
            copy_three(three, out)
        futures = client.map(qc_subject, [root] * len(files), files, [out] * len(files), [views] * len(files), [(w, h)] * len(files),
                             anatomy, [a.tolerance] * len(files), [a.web_points if three else None] * len(files), surfaces, pure=False,
                             retries=2)
        records = []
        for f, fut in zip(files, futures):
            try:
                records.append(fut.result())
            except Exception as e:  # (its workers died every time: a crash in a plugin, memory; the others go on)
                records.append({"id": subject_id(root, f), "file": f, "status": "failed", "views": {}, "warnings": [],
                                "error": f"{f}: its task failed on every worker it was given ({type(e).__name__})"})
    finally:
        client.close()
        if cluster:
            cluster.close()
    gallery(out, records, views, os.path.basename(root.rstrip(os.sep)) or root, note_3d)
    failed = [r for r in records if r.get("status") != "ok"]
    skipped = sum(1 for r in records if r.get("skipped"))
    print(f"{len(records)} subjects: {len(records) - len(failed)} ok ({skipped} done before), {len(failed)} failed, "
          f"in {time.perf_counter() - t0:.1f} s; gallery: {os.path.join(out, 'index.html')}")
    for r in failed:
        print(f"  failed {r['id']}: {r.get('error')}")
    for r in records:
        for w_ in r.get("warnings", []) if r.get("status") == "ok" else []:
            print(f"  warning {r['id']}: {w_}")
    return 1 if failed and a.strict else 0


if __name__ == "__main__":
    sys.exit(main())
