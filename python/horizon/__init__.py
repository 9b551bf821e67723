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

from . import _paths
from ._core import Data, Error, load, plugins, save
from ._core import _render, _set_plugin_dirs

__all__ = ["Data", "Error", "Scene", "load", "plugins", "render", "save", "streamlines", "to_nibabel"]
__version__ = _paths.VERSION

_set_plugin_dirs([d for d in _paths.PLUGIN_DIRS if os.path.isdir(d)])


def streamlines(data):
    """The streamlines of `data` (a horizon.Data of streamlines) as a list of
    (points, 3) float32 views, one per streamline, without copies."""
    import numpy as np
    _need(data, "streamlines", "streamlines")
    p, o, gap = data.positions, np.asarray(data.offsets).astype(np.int64), data.gap
    return [p[o[i]:o[i + 1] - gap] for i in range(len(o) - 1)]


def to_nibabel(data):
    """nibabel's object for `data`: an ``ArraySequence`` of the streamlines
    (its points the file's, not a copy; DIPY's ``Streamlines`` is the same
    class) or a ``Nifti1Image`` of a volume (its voxels as stored, without a
    copy, or scaled by the file's slope and intercept where it has them)."""
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
    raise TypeError(f"to_nibabel: {data.path} holds {data.kind}; streamlines and volumes convert")


def _need(data, kind, what):
    if not isinstance(data, Data):
        raise TypeError(f"{what}: expected a horizon.Data (horizon.load), not {type(data).__name__}")
    if data.kind != kind:
        raise TypeError(f"{what}: {data.path} holds {data.kind}, not {kind}")


def render(scene, size=(1280, 720), base="."):
    """Draws `scene` (a horizon.Scene, a dict of the scene-file model, or the
    path of a scene file) headless (EGL) and returns the picture as a
    (height, width, 4) uint8 array, rows top to bottom."""
    if isinstance(scene, Scene):
        text, base = json.dumps(scene.model), scene.base
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
    return _render(text, os.fspath(base), width, height)


class Scene:
    """A scene built in Python with the model of scene files
    (docs/scene-format.md): objects, camera, lights, environment and the
    passes (ambient occlusion, shadows, ...). Shown inline in Jupyter."""

    def __init__(self, base=".", **settings):
        self.base = os.fspath(base)
        self.model = {"objects": []}
        self.model.update(settings)
        self.size = (640, 480)

    def add(self, file=None, type=None, **keys):
        """Adds an object: a file (its type guessed from what it holds unless
        given: streamlines, surface, slices or volume) or a builtin
        (builtin="phantom", "cortex", "head", "sphere") with the scene
        file's keys (render, radius, color, material, transfer, ...)."""
        obj = dict(keys)
        if file is not None:
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
