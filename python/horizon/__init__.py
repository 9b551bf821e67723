"""Horizon from Python: the same loaders, writers and headless renderer as the
``horizon`` program, through the same plugins.

    import horizon
    t = horizon.load("bundle.tck")        # any format a loader plugin reads
    t.positions, t.offsets                # numpy views of the file's points, no copy
    seq = horizon.to_nibabel(t)           # nibabel's ArraySequence, still no copy
    picture = horizon.Scene().add("bundle.tck", render="tubes").render((640, 480))

Errors from files and plugins are ``horizon.Error`` with the one-line message
the command line prints.
"""
import json
import os
import shutil

from . import _paths
from ._core import Data, Error, _filter, plugins, save
from ._core import load as _load
from ._core import _buan_segments, _cluster, _from_mesh, _from_streamlines, _from_volume, _render, _set_plugin_dirs, _sh_matrix

__all__ = ["ClusterTree", "Data", "Error", "Scene", "buan_segments", "cluster", "filter", "from_mesh", "from_nibabel", "from_streamlines", "from_volume", "load", "plugins", "render", "save", "sh_to_sf",
           "streamlines", "to_nibabel"]
__version__ = _paths.VERSION

_set_plugin_dirs([d for d in _paths.PLUGIN_DIRS if os.path.isdir(d)])


def streamlines(data):
    """The streamlines of `data` (a horizon.Data of streamlines) as a list of
    (points, 3) float32 views, one per streamline, without copies."""
    import numpy as np
    _need(data, "streamlines", "streamlines")
    p, o, gap = data.positions, np.asarray(data.offsets).astype(np.int64), data.gap
    return [p[o[i]:o[i + 1] - gap] for i in range(len(o) - 1)]


def from_streamlines(streamlines):
    """A horizon.Data of streamlines from Python: a list of (points, 3)
    arrays, nibabel's ArraySequence or DIPY's Streamlines (RAS+ mm). The
    points are copied once, as float32; raises ValueError for a wrong shape
    or a point that is not finite."""
    import numpy as np
    parts = [np.asarray(s) for s in streamlines]  # (an ArraySequence: its streamlines in its order)
    for k, s in enumerate(parts):
        if s.ndim != 2 or s.shape[1] != 3:
            raise ValueError(f"from_streamlines: streamline {k} has shape {s.shape}, not (points, 3)")
    lengths = np.array([len(s) for s in parts], dtype=np.uint64)
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.uint64)
    points = np.concatenate(parts).astype(np.float32) if parts else np.zeros((0, 3), np.float32)
    try:
        return _from_streamlines(points, offsets)
    except Error as e:
        raise ValueError(f"from_streamlines: {e}") from None


def from_mesh(vertices, faces):
    """A horizon.Data surface from Python: vertices (n, 3) in RAS+ mm and
    triangles (m, 3) of 0-based vertex indices (nibabel's GIFTI arrays,
    FreeSurfer's read_geometry). Copied once (float32, uint32); raises
    ValueError for a wrong shape, an index out of range or a vertex that is
    not finite."""
    import numpy as np
    v, f = np.asarray(vertices), np.asarray(faces)
    if not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"from_mesh: faces must be integers, not {f.dtype}")
    return _from_mesh(v, f)


def from_volume(voxels, affine):
    """A horizon.Data volume from Python: voxels (x, y, z[, t...]) of any
    integer or float type (bool as uint8) and the voxel-to-RAS+ affine (4,
    4), as nibabel's image.get_fdata() or dataobj and image.affine. Copied
    once, in Fortran order (x fastest) as the volumes files give; raises
    ValueError for a wrong shape, type or affine."""
    import numpy as np
    v = np.asarray(voxels)
    if v.dtype == np.bool_:
        v = v.astype(np.uint8)
    if v.dtype.byteorder == ">" or (v.dtype.byteorder == "=" and np.dtype("=i4").byteorder == ">"):
        v = v.astype(v.dtype.newbyteorder("<"))
    return _from_volume(np.asfortranarray(v), np.asarray(affine, dtype=np.float64))


def from_nibabel(obj):
    """A horizon.Data of a nibabel object: an image (Nifti1Image, Nifti2Image,
    MGHImage, ...: its values as nibabel's dataobj gives them, the stored
    type, or float32 where the file scales them), a GiftiImage
    surface (its NIFTI_INTENT_POINTSET and NIFTI_INTENT_TRIANGLE arrays), or
    streamlines (an ArraySequence, a Tractogram, a StatefulTractogram: moved
    to RAS+ mm in place first, as DIPY's save_tractogram does)."""
    import numpy as np
    import nibabel as nib
    if isinstance(obj, nib.gifti.GiftiImage):
        pts = obj.get_arrays_from_intent("NIFTI_INTENT_POINTSET")
        tri = obj.get_arrays_from_intent("NIFTI_INTENT_TRIANGLE")
        if not pts or not tri:
            raise ValueError("from_nibabel: the GIFTI image has no NIFTI_INTENT_POINTSET and NIFTI_INTENT_TRIANGLE arrays")
        return from_mesh(pts[0].data, tri[0].data)
    if isinstance(obj, nib.spatialimages.SpatialImage):
        values = np.asanyarray(obj.dataobj)  # (the stored type, or floats where the file scales its values)
        if values.dtype == np.float64 and obj.get_data_dtype() != np.float64:
            values = values.astype(np.float32)
        return from_volume(values, obj.affine)
    if hasattr(obj, "to_rasmm") or hasattr(obj, "to_space"):  # (a StatefulTractogram: in RAS+ mm first)
        obj.to_rasmm()
    return from_streamlines(getattr(obj, "streamlines", obj))


def to_nibabel(data):
    """nibabel's object for `data`: an ``ArraySequence`` of the streamlines
    (its points the file's, not a copy; DIPY's ``Streamlines`` is the same
    class), a ``Nifti1Image`` of a volume (its voxels as stored, without a
    copy, or scaled by the file's slope and intercept where it has them), or
    a ``GiftiImage`` of a surface (its vertices and triangles, and each
    per-vertex array as a data array named by its name)."""
    import numpy as np
    if data.kind == "streamlines":
        from nibabel.streamlines import ArraySequence
        seq = ArraySequence()
        offsets = np.asarray(data.offsets)
        seq._data = data.positions
        seq._offsets = offsets[:-1].astype(np.intp)
        seq._lengths = (np.diff(offsets) - data.gap).astype(np.intp)
        return seq
    if data.kind == "volume":
        import nibabel as nib
        slope, inter = data.scale
        voxels = np.asarray(data.voxels)
        if (slope, inter) != (1.0, 0.0):  # (the values, scaled: a copy)
            voxels = voxels * np.float32(slope) + np.float32(inter)
        return nib.Nifti1Image(voxels, data.affine)
    if data.kind == "mesh":
        import nibabel as nib
        arrays = [nib.gifti.GiftiDataArray(np.asarray(data.vertices), intent="NIFTI_INTENT_POINTSET", datatype="NIFTI_TYPE_FLOAT32"),
                  nib.gifti.GiftiDataArray(np.asarray(data.faces).astype(np.int32), intent="NIFTI_INTENT_TRIANGLE",
                                           datatype="NIFTI_TYPE_INT32")]
        for name, (attach, values) in data.arrays.items():
            if attach == "vertex":
                meta = nib.gifti.GiftiMetaData({"Name": name})
                arrays.append(nib.gifti.GiftiDataArray(np.asarray(values), intent="NIFTI_INTENT_NONE", meta=meta))
        return nib.gifti.GiftiImage(darrays=arrays)
    raise TypeError(f"to_nibabel: {data.path} holds {data.kind}; streamlines, volumes and surfaces convert")


class _Bar:
    """progress=True: a text bar on standard error, one line redrawn."""

    def __init__(self, title):
        import sys
        self.title, self.err, self.shown = title, sys.stderr, -1

    def __call__(self, fraction, what):
        pct = int(fraction * 100)
        if pct == self.shown:
            return
        self.shown = pct
        bar = "#" * (pct // 4) + "." * (25 - pct // 4)
        self.err.write(f"\r{self.title}: [{bar}] {pct:3d}% {what[:40]:40s}" + ("\n" if pct >= 100 else ""))
        self.err.flush()


    def finish(self):
        if self.shown < 100:
            self(1.0, "")


class _NotebookBar:
    """progress=True in a Jupyter kernel: an HTML progress bar in the cell's
    output, updated in place through IPython's display handles (no widget
    extension needed); the callback may come from any thread."""

    def __init__(self, title):
        from IPython.display import HTML, display
        self.title, self.shown, self.HTML = title, -1, HTML
        self.handle = display(HTML(self._html(0, "")), display_id=True)

    def _html(self, pct, what):
        import html
        return (f'<div class="horizon-progress"><progress value="{pct}" max="100" style="width: 40ex"></progress> '
                f"{html.escape(self.title)}: {pct}% {html.escape(what[:60])}</div>")

    def __call__(self, fraction, what):
        pct = int(fraction * 100)
        if pct == self.shown:
            return
        self.shown = pct
        self.handle.update(self.HTML(self._html(pct, what)))

    def finish(self):
        if self.shown < 100:
            self(1.0, "")


def _in_notebook():
    """Whether this runs in a Jupyter kernel (IPython's ZMQ shell)."""
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and type(shell).__name__ == "ZMQInteractiveShell"


def _progress(progress, title="horizon"):
    if progress is None or progress is False:
        return None
    if progress is True:
        return _NotebookBar(title) if _in_notebook() else _Bar(title)
    if not callable(progress):
        raise TypeError("progress must be a callable progress(fraction, what), True (a text bar) or None")
    return progress


def load(path, progress=None):
    """Reads `path` through the loader plugin that claims it (a
    horizon.Data); raises horizon.Error naming the file. `progress`: a
    callable progress(fraction, what) called as the file is read (from the
    reading thread, at most ten times a second; an exception it raises, such
    as KeyboardInterrupt, stops the reading and is raised here), or True for
    a bar (in a notebook, an HTML bar in the cell's output; else a text bar
    on standard error)."""
    bar = _progress(progress, f"reading {os.path.basename(os.fspath(path))}")
    data = _load(os.fspath(path), bar)
    if hasattr(bar, "finish"):
        bar.finish()
    return data


def cluster(data, algorithm="qbx", thresholds=None, ordering=None, progress=None, **params):
    """Clusters the streamlines of `data` (a horizon.Data, or streamlines as
    from_streamlines takes them) with clustering plugin `algorithm` (its id
    or the last part of it: qb, qbx, qbx_merge, ...), `thresholds` in mm
    (the plugin's defaults if None), the processing `ordering` (a
    permutation of the streamlines; None: their order) and the plugin's own
    parameters by name (`horizon plugins ID` lists them), e.g. mode="exact"
    (DIPY's results, bit for bit) or mode="fast". `progress`: as load()'s.
    Returns a ClusterTree."""
    import numpy as np
    if not isinstance(data, Data):
        data = from_streamlines(data)
    _need(data, "streamlines", "cluster")
    order = None
    if ordering is not None:
        order = np.asarray(ordering)
        if order.ndim != 1 or order.dtype.kind not in "iu":
            raise TypeError("cluster: ordering must be a 1-D array of streamline indices")
        order = [int(i) for i in order]
    try:
        bar = _progress(progress, f"clustering ({algorithm})")
        result = _cluster(data, algorithm, [float(t) for t in (thresholds or [])], json.dumps(params), order, bar)
        if hasattr(bar, "finish"):
            bar.finish()
    except Error as e:
        if str(e).startswith("ordering:"):
            raise ValueError(f"cluster: {e}") from None
        raise
    return ClusterTree(result)


def filter(data, include=(), exclude=(), min_length=0.0, max_length=None, ends_only=False, invert=False):
    """The streamlines of `data` (a horizon.Data, or streamlines as
    from_streamlines takes them) that `horizon filter` selects with the same
    regions: `include` and `exclude` are lists of "sphere:X,Y,Z,R",
    "box:X0,Y0,Z0,X1,Y1,Z1" (RAS+ mm) or mask files (any volume, voxels > 0);
    a streamline passes when it meets every include region and no exclude
    region (with `ends_only`, through its end points only), and its length
    in mm is within [min_length, max_length]; `invert` keeps the others.
    Returns their indices, increasing (numpy uint64): save(data, path,
    selection=ids) writes them."""
    import math
    if not isinstance(data, Data):
        data = from_streamlines(data)
    _need(data, "streamlines", "filter")
    for name, regions in (("include", include), ("exclude", exclude)):
        if isinstance(regions, str) or not all(isinstance(r, str) for r in regions):
            raise TypeError(f"filter: {name} must be a list of region specs (strings), e.g. ['sphere:0,0,0,10']")
    if min_length < 0 or (max_length is not None and (max_length < 0 or max_length < min_length)):
        raise ValueError(f"filter: lengths must satisfy 0 <= min_length <= max_length (got {min_length}, {max_length})")
    return _filter(data, list(include), list(exclude), float(min_length), math.inf if max_length is None else float(max_length),
                   bool(ends_only), bool(invert))


class ClusterTree:
    """A clustering's tree (paper Fig. 4): one level per threshold, each
    level's clusters partitioning the streamlines, each a child of one
    cluster of the level above. Node arrays: `parent`, `level`,
    `centroids` (nodes, points, 3); `member_offsets`, `members`."""

    def __init__(self, r):
        self.algorithm = r["algorithm"]
        self.nb_levels = r["nb_levels"]
        self.thresholds = list(r["thresholds"])
        self.parent, self.level, self.centroids = r["parent"], r["level"], r["centroids"]
        self.member_offsets, self.members = r["member_offsets"], r["members"]
        self.nb_streamlines = int(self.member_offsets[1]) if len(self.member_offsets) > 1 else 0

    def nodes(self, level):
        """The nodes of `level` (1: the coarsest; -1: the finest), in order."""
        import numpy as np
        level = self.nb_levels if level == -1 else level
        if not 1 <= level <= self.nb_levels:
            raise ValueError(f"level {level}: the tree has levels 1..{self.nb_levels}")
        return np.nonzero(self.level == level)[0]

    def clusters(self, level=-1):
        """The streamline indices of each cluster of `level`."""
        return [self.members[self.member_offsets[k]:self.member_offsets[k + 1]] for k in self.nodes(level)]

    def labels(self, level=-1):
        """Each streamline's cluster at `level` (the clusters numbered in order)."""
        import numpy as np
        out = np.empty(self.nb_streamlines, np.int64)
        for i, m in enumerate(self.clusters(level)):
            out[m] = i
        return out

    def to_dipy(self, level=-1, streamlines=None):
        """DIPY's ClusterMapCentroid of `level` (its clusters' centroids and
        indices; `streamlines`, if given, as their reference data)."""
        from dipy.segment.clustering import ClusterCentroid, ClusterMapCentroid
        cmap = ClusterMapCentroid(refdata=streamlines) if streamlines is not None else ClusterMapCentroid()
        for k, m in zip(self.nodes(level), self.clusters(level)):
            cmap.add_cluster(ClusterCentroid(self.centroids[k], indices=[int(i) for i in m]))
        return cmap

    def __repr__(self):
        sizes = [len(self.nodes(l)) for l in range(1, self.nb_levels + 1)]
        return f"<horizon.ClusterTree {self.algorithm}: {self.nb_streamlines} streamlines, clusters per level {sizes}>"


def _need(data, kind, what):
    if not isinstance(data, Data):
        raise TypeError(f"{what}: expected a horizon.Data (horizon.load), not {type(data).__name__}")
    if data.kind != kind:
        raise TypeError(f"{what}: {data.path} holds {data.kind}, not {kind}")


def buan_segments(bundle, n=100):
    """The segment ("disk") of each point of a bundle along its model
    centroid, as BUAN numbers them: dipy.stats.analysis.assignment_map(bundle,
    bundle, n) (the streamlines resampled to n points, QuickBundles at 85 mm,
    each point the nearest centroid point). `bundle`: a
    horizon.Data of streamlines or what from_streamlines takes; returns one
    index a point (numpy uint32, in the points' order)."""
    data = bundle if isinstance(bundle, Data) else from_streamlines(bundle)
    return _buan_segments(data, int(n))


def sh_to_sf(sh, vertices, basis="descoteaux07", legacy=True):
    """The values on the sphere of ODFs given by their real spherical-harmonic
    coefficients, as the ODF glyphs evaluate them: `sh` (..., C) with C =
    (L + 1)(L + 2) / 2 for an even order L (DIPY's order of coefficients),
    `vertices` (N, 3) unit vectors; returns (..., N). `basis`: "descoteaux07"
    or "tournier07" (DIPY's names; MRtrix3's is tournier07 with legacy
    False), `legacy` as DIPY's (dipy.reconst.shm.sh_to_sf's equal)."""
    import numpy as np
    sh = np.asarray(sh, dtype=np.float64)
    C = sh.shape[-1]
    orders = [L for L in range(0, 17, 2) if (L + 1) * (L + 2) // 2 == C]
    if not orders:
        raise Error(f"sh_to_sf: {C} coefficients are not an even-order SH series (1, 6, 15, 28, 45, ...)")
    return sh @ _sh_matrix(np.asarray(vertices, dtype=np.float64), orders[0], basis, bool(legacy)).T


def render(scene, size=(1280, 720), base="."):
    """Draws `scene` (a horizon.Scene, a dict of the scene-file model, or the
    path of a scene file) headless (EGL) and returns the picture as a
    (height, width, 4) uint8 array, rows top to bottom."""
    memory = {}
    if isinstance(scene, Scene):
        text, base, memory = json.dumps(scene.model), scene.base, scene.memory
    elif isinstance(scene, dict):
        text = json.dumps(scene)
    elif isinstance(scene, (str, os.PathLike)):
        with open(scene) as f:
            text = f.read()
        base = os.path.dirname(os.path.abspath(scene))
    else:
        raise TypeError(f"render: expected a horizon.Scene, a dict or a scene file, not {type(scene).__name__}")
    try:
        width, height = (int(v) for v in size)
    except (TypeError, ValueError):
        raise TypeError(f"render: size must be (width, height), not {size!r}") from None
    return _render(text, os.fspath(base), width, height, memory)


def _is_nibabel(obj):
    """Whether `obj` is one of nibabel's images or tractograms, or DIPY's
    StatefulTractogram (from_nibabel; nibabel imported only for those)."""
    if type(obj).__module__.split(".")[0] not in ("nibabel", "dipy"):
        return False
    import nibabel as nib
    return isinstance(obj, (nib.spatialimages.SpatialImage, nib.gifti.GiftiImage, nib.streamlines.Tractogram)) or \
        hasattr(obj, "to_rasmm")


class Scene:
    """A scene built in Python with the model of scene files
    (docs/scene-format.md): objects, camera, lights, environment and the
    passes (ambient occlusion, shadows, ...). Shown inline in Jupyter."""

    def __init__(self, base=".", **settings):
        self.base = os.fspath(base)
        self.model = {"objects": []}
        self.model.update(settings)
        self.memory = {}  # the objects' data held in Python, by name
        self.size = (640, 480)

    def add(self, file=None, type=None, **keys):
        """Adds an object: a file (its type guessed from what it holds unless
        given: streamlines, surface, slices or volume), data in memory (a
        horizon.Data, as from_mesh and from_volume make; a nibabel image,
        GIFTI surface or tractogram; or streamlines: a list of arrays, an
        ArraySequence, DIPY's Streamlines) or a builtin (builtin="phantom", "cortex", "head",
        "sphere"), with the scene file's keys (render, radius, color,
        material, transfer, ...)."""
        obj = dict(keys)
        if file is not None and not isinstance(file, (str, os.PathLike)):
            data = file if isinstance(file, Data) else from_nibabel(file) if _is_nibabel(file) else from_streamlines(file)
            name = f"data{len(self.memory)}"
            self.memory[name] = data
            obj["data"] = name
            if type is None:
                type = {"streamlines": "streamlines", "mesh": "surface", "volume": "slices"}.get(data.kind)
        elif file is not None:
            obj["file"] = os.fspath(file)
            if type is None:
                type = {"streamlines": "streamlines", "mesh": "surface", "volume": "slices"}.get(load(obj["file"]).kind)
        if type is None:
            raise ValueError("add: give type= (streamlines, surface, slices or volume)")
        obj["type"] = type
        self.model["objects"].append(obj)
        return self

    def render(self, size=None):
        """The picture, (height, width, 4) uint8."""
        return render(self, size or self.size)

    def _repr_png_(self):
        return _png(self.render())

    def show(self, size=(1280, 720), script=None):
        """Opens the scene in Horizon's window (the `horizon view` program of
        this build: its panel, keys, slicer, selections) and returns when the
        window is closed. Data held in Python is written to a temporary
        folder first (TCK, GIFTI, NIfTI); the scene itself is written beside
        its files (`base`, as a hidden file removed afterwards) so that its
        relative names mean what they mean in a scene file. Needs a display
        ($DISPLAY or $WAYLAND_DISPLAY; render() and view3d() need none):
        horizon.Error otherwise, and with the window's own one-line error
        if it fails. `script`: a file of scripted input for the window
        (`horizon view --script`, docs/rendering.md), for demos and tests."""
        import subprocess
        import tempfile
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise Error("show: no display ($DISPLAY is not set); render() and view3d() draw without one")
        try:
            width, height = (int(v) for v in size)
        except (TypeError, ValueError):
            raise TypeError(f"show: size must be (width, height), not {size!r}") from None
        program = _paths.PROGRAM if os.path.exists(_paths.PROGRAM) else shutil.which("horizon")
        if not program:
            raise Error(f"show: the horizon program is not at {_paths.PROGRAM} nor on PATH")
        with tempfile.TemporaryDirectory(prefix="hz_show_") as held:
            model = json.loads(json.dumps(self.model))
            suffix = {"streamlines": ".tck", "mesh": ".gii", "volume": ".nii.gz"}
            for obj in model.get("objects", []):
                if "data" in obj:
                    data = self.memory[obj["data"]]
                    if data.kind not in suffix:
                        raise Error(f"show: {data.kind} data held in Python cannot be shown in the window")
                    path = os.path.join(held, obj.pop("data") + suffix[data.kind])
                    save(data, path)
                    obj["file"] = path
            fd, scene = tempfile.mkstemp(prefix=".hz_show_", suffix=".json", dir=self.base)
            try:
                with os.fdopen(fd, "w") as f:
                    json.dump(model, f)
                command = [program, "view", scene, "--size", f"{width}x{height}"]
                if script is not None:
                    command += ["--script", os.fspath(script)]
                p = subprocess.run(command, stderr=subprocess.PIPE, text=True)
            finally:
                os.unlink(scene)
        if p.returncode != 0:
            lines = [line for line in p.stderr.splitlines() if line.strip()]
            raise Error(lines[-1] if lines else f"show: the window ended with status {p.returncode}")

    def view3d(self, points=200000, three=None, height=480):
        """The scene's interactive 3D view (horizon.web.View3D): its
        streamlines (every k-th, at most `points` points) and surfaces, with
        their colours ([r, g, b]; else direction, grey) and opacities, drawn
        by three.js and turned with the mouse. Self-contained: shown inline
        in Jupyter (an iframe), or written with .save(path). Needs npm's
        three@0.147: `three` (its folder), $HORIZON_THREE_DIR, or
        node_modules/three in the usual places; ValueError without it."""
        from .web import view_of_scene
        return view_of_scene(self, points, three, height)


def _png(rgba):
    """`rgba` (height, width, 4 uint8) as PNG bytes (zlib, no other library)."""
    import struct
    import zlib
    h, w = rgba.shape[:2]
    raw = b"".join(b"\x00" + rgba[y].tobytes() for y in range(h))

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))
