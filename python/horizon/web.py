"""3D views in a web browser: a scene's streamlines and surfaces exported to
glTF and drawn by three.js, turned with the mouse.

Two pages are made of the same viewer: the QC gallery's, one per subject,
with three.js's files beside the gallery (horizon.batch), and a notebook's,
self-contained (three.js and the data inside the page), shown inline by
Jupyter in an iframe (horizon.Scene.view3d). three.js is not part of
Horizon: it is npm's package three@0.147, the last release with the
classic-script loaders that a page opened from files (or from a notebook's
output) can use; find_three() says where it is.

What a view shows: streamlines as lines (every k-th streamline, so that at
most `points` points are drawn), coloured by direction unless a colour is
given; surfaces lit by a key light that follows the camera and a hemisphere
light, grey unless a colour is given; each with its opacity. Slices,
volumes and glyphs are not drawn (the page says which objects were left
out). Coordinates: glTF's, metres, +X left, +Y superior, +Z anterior (the
writer's: docs/formats.md).
"""
import base64
import html
import os
import tempfile

# What the views take of three.js (paths in its npm package).
THREE_FILES = {"three.min.js": "build/three.min.js", "GLTFLoader.js": "examples/js/loaders/GLTFLoader.js",
               "OrbitControls.js": "examples/js/controls/OrbitControls.js", "LICENSE": "LICENSE"}
SCRIPTS = ("three.min.js", "GLTFLoader.js", "OrbitControls.js")


def find_three(explicit=None, named="three"):
    """The folder of an npm package three with the classic-script files the
    views need, or None. Tried: `explicit`, $HORIZON_THREE_DIR, then
    node_modules/three under the working directory, ~/.local/lib,
    /usr/local/lib, /usr/lib and /usr/share/nodejs. An explicit folder (or
    $HORIZON_THREE_DIR) that lacks them raises ValueError saying what is
    missing; `named` names the explicit one in that message."""
    def ok(d):
        return d and all(os.path.isfile(os.path.join(d, f)) for f in THREE_FILES.values())
    for d, what in ((explicit, named), (os.environ.get("HORIZON_THREE_DIR"), "$HORIZON_THREE_DIR")):
        if d:
            d = os.fspath(d)
            if ok(d):
                return os.path.abspath(d)
            missing = [f for f in THREE_FILES.values() if not os.path.isfile(os.path.join(d, f))]
            raise ValueError(f"{what}: {d} is not an npm package three with {', '.join(missing)} "
                             f"(three.js 0.147 is the last release that has them: npm install three@0.147)")
    for prefix in (os.getcwd(), os.path.expanduser("~/.local/lib"), "/usr/local/lib", "/usr/lib", "/usr/share/nodejs"):
        d = os.path.join(prefix, "node_modules", "three") if not prefix.endswith("nodejs") else os.path.join(prefix, "three")
        if ok(d):
            return d
    return None


def _glb(data, selection=None):
    """`data` (a horizon.Data) as glTF binary bytes, through the glTF writer."""
    import horizon
    with tempfile.TemporaryDirectory(prefix="hz_web_") as d:
        path = os.path.join(d, "part.glb")
        if selection is None:
            horizon.save(data, path)
        else:
            horizon.save(data, path, selection=selection)
        with open(path, "rb") as f:
            return f.read()


def _colour(c, what):
    """A scene colour [r, g, b] (linear, 0-1) as the sRGB values the page
    shows; None for any other colour key (direction, cluster, data: the
    exported file's own colours)."""
    if isinstance(c, (list, tuple)) and len(c) == 3 and all(isinstance(x, (int, float)) for x in c):
        if not all(0 <= x <= 1 for x in c):
            raise ValueError(f"{what}: colour {list(c)} is not linear RGB in [0, 1]")
        return [round(float(x) ** (1 / 2.2), 4) for x in c]
    return None


def streamlines_part(data, points, color=None, opacity=1.0):
    """A tractogram's part of a view: every k-th streamline, at most `points`
    points. Returns (part, streamlines shown, streamlines in all)."""
    import numpy as np
    offsets = np.asarray(data.offsets)
    n = len(offsets) - 1
    total = int(offsets[-1]) if n > 0 else 0
    k = max(1, -(-total // max(int(points), 1)))
    ids = list(range(0, n, k))
    part = {"kind": "streamlines", "glb": _glb(data, ids), "color": _colour(color, "streamlines"), "opacity": float(opacity)}
    return part, len(ids), n


def surface_part(data, color=None, opacity=1.0):
    """A surface's part of a view (its vertices and triangles)."""
    return {"kind": "surface", "glb": _glb(data), "color": _colour(color, "surface"), "opacity": float(opacity)}


def parts_js(parts):
    """The parts as the script that hands them to the viewer (window.HZ_PARTS)."""
    items = []
    for p in parts:
        colour = "null" if p["color"] is None else "[" + ",".join(repr(x) for x in p["color"]) + "]"
        items.append(f'{{kind:"{p["kind"]}",color:{colour},opacity:{p["opacity"]!r},'
                     f'glb:"{base64.b64encode(p["glb"]).decode()}"}}')
    return "window.HZ_PARTS = [\n" + ",\n".join(items) + "\n];\n"


# The viewer: one glTF per part, parsed in the page; the camera on the left
# side of them all, orbiting their centre. window.hzReady once all are drawn
# (hzError on failure), hzParts the parts read, hzFrames the frames drawn.
VIEWER = """
(function () {
  const renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(innerWidth, innerHeight);
  renderer.setClearColor(0x111111);
  document.body.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(30, innerWidth / innerHeight, 0.001, 100);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x333333, 0.55));
  const key = new THREE.DirectionalLight(0xffffff, 0.75);
  key.position.set(0.4, 0.8, 1);
  camera.add(key);
  scene.add(camera);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  const draw = () => { renderer.render(scene, camera); window.hzFrames = (window.hzFrames || 0) + 1; };
  controls.addEventListener('change', draw);
  addEventListener('resize', () => {
    camera.aspect = innerWidth / innerHeight; camera.updateProjectionMatrix();
    renderer.setSize(innerWidth, innerHeight); draw();
  });
  const fail = e => { document.getElementById('info').textContent = 'cannot read this scene: ' + e; window.hzError = String(e); };
  const parts = window.HZ_PARTS || [];
  if (!parts.length) return fail('nothing to show');
  const box = new THREE.Box3();
  let left = parts.length;
  window.hzParts = 0;
  for (const p of parts) {
    const bytes = Uint8Array.from(atob(p.glb), c => c.charCodeAt(0));
    new THREE.GLTFLoader().parse(bytes.buffer, '', gltf => {
      const see = p.opacity < 1;
      const colour = p.color ? new THREE.Color(p.color[0], p.color[1], p.color[2]) : null;
      gltf.scene.traverse(o => {
        const vc = !colour && !!(o.geometry && o.geometry.attributes.color);
        if (o.isMesh) {
          if (!o.geometry.attributes.normal) o.geometry.computeVertexNormals();
          o.material = new THREE.MeshStandardMaterial({color: colour || 0xd8d4cc, vertexColors: vc, metalness: 0, roughness: 0.65,
            side: THREE.DoubleSide, transparent: see, opacity: p.opacity, depthWrite: !see});
        } else if (o.isLine || o.isLineSegments) {
          o.material = new THREE.LineBasicMaterial({color: colour || 0xffffff, vertexColors: vc, transparent: see, opacity: p.opacity});
        }
      });
      scene.add(gltf.scene);
      box.union(new THREE.Box3().setFromObject(gltf.scene));
      window.hzParts += 1;
      if (--left) return;
      // The left side of them all, whole.
      const c = box.getCenter(new THREE.Vector3()), r = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 1e-3);
      controls.target.copy(c);
      camera.position.set(c.x + r / Math.sin(Math.PI / 12), c.y, c.z);
      camera.near = r / 100; camera.far = r * 20; camera.updateProjectionMatrix();
      controls.update();
      draw();
      window.hzReady = true;
    }, fail);
  }
})();
"""

PAGE = """<!doctype html>
<html><head><meta charset="utf-8"><title>{title}</title>
<style>html,body{{margin:0;height:100%;background:#111;color:#ddd;font-family:sans-serif;overflow:hidden}}
#info{{position:absolute;left:8px;top:6px;font-size:13px}} a{{color:#9cf}}</style></head><body>
<div id="info">{info}</div>
{scripts}
</body></html>
"""


def page(title, info_html, scripts):
    """The viewer's page. `scripts`: (src, None) for a script file, (None,
    text) for an inline one, in order; the viewer itself comes last."""
    out = []
    for src, text in list(scripts) + [(None, VIEWER)]:
        if src is not None:
            out.append(f'<script src="{html.escape(src)}"></script>')
        else:
            if "</script" in text.lower():
                raise ValueError("a script holding '</script' cannot be inlined")
            out.append("<script>" + text + "</script>")
    return PAGE.format(title=html.escape(title), info=info_html, scripts="\n".join(out))


def describe(shown, total, surfaces, left_out):
    """The view's line: what it shows of what."""
    bits = []
    if total is not None:
        bits.append(f"{shown} of {total} streamlines")
    if surfaces:
        bits.append(f"{surfaces} surface{'s' if surfaces > 1 else ''}")
    text = ", ".join(bits) or "nothing"
    if left_out:
        text += f" (not drawn here: {', '.join(left_out)})"
    return text


class View3D:
    """A scene's interactive 3D view, self-contained: `html` is the whole
    page (three.js and the data inside it), `save(path)` writes it (to a
    temporary name, then renamed), and Jupyter shows it inline (an iframe:
    no extension, no server, no network)."""

    def __init__(self, page_html, info, height=480):
        self.html = page_html
        self.info = info
        self.height = int(height)

    def save(self, path):
        path = os.fspath(path)
        folder = os.path.dirname(os.path.abspath(path))
        fd, tmp = tempfile.mkstemp(prefix=".hz_view_", dir=folder)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(self.html.encode())
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
        return path

    def _repr_html_(self):
        return (f'<iframe srcdoc="{html.escape(self.html, quote=True)}" style="width:100%;height:{self.height}px;border:0" '
                f'title="Horizon 3D view: {html.escape(self.info)}"></iframe>')

    def __repr__(self):
        return f"<horizon 3D view: {self.info}>"


def view_of_scene(scene, points=200000, three=None, height=480):
    """The View3D of a horizon.Scene (Scene.view3d)."""
    import horizon
    folder = find_three(three, "three=")
    if folder is None:
        raise ValueError("view3d: three.js was not found (npm install three@0.147, then three=DIR or $HORIZON_THREE_DIR)")
    if int(points) < 2:
        raise ValueError(f"view3d: points must be at least 2, not {points}")
    parts, left_out = [], []
    shown = total = None
    for i, obj in enumerate(scene.model.get("objects", [])):
        kind = obj.get("type")
        what = f"object {i} ({obj.get('file') or obj.get('data') or obj.get('builtin') or kind})"
        if obj.get("visible", True) is False:
            continue
        if kind not in ("streamlines", "surface") or ("file" not in obj and "data" not in obj):
            label = obj.get("builtin") or os.path.basename(str(obj.get("file", ""))) or obj.get("data") or f"object {i}"
            left_out.append(f"{label} ({kind})")
            continue
        data = scene.memory[obj["data"]] if "data" in obj else horizon.load(os.path.join(scene.base, obj["file"]))
        opacity = obj.get("opacity", 1.0)
        if kind == "streamlines":
            if data.kind != "streamlines":
                raise ValueError(f"view3d: {what} holds {data.kind}, not streamlines")
            part, s, n = streamlines_part(data, points, obj.get("color"), opacity)
            shown, total = (shown or 0) + s, (total or 0) + n
        else:
            if data.kind != "mesh":
                raise ValueError(f"view3d: {what} holds {data.kind}, not a surface")
            part = surface_part(data, obj.get("color"), opacity)
        parts.append(part)
    if not parts:
        raise ValueError("view3d: the scene has no streamlines or surface to show")
    surfaces = sum(p["kind"] == "surface" for p in parts)
    info = describe(shown, total, surfaces, left_out)
    scripts = []
    for name in SCRIPTS:
        with open(os.path.join(folder, THREE_FILES[name]), encoding="utf-8") as f:
            scripts.append((None, f.read()))
    scripts.append((None, parts_js(parts)))
    text = page("Horizon 3D view", html.escape(info) + " (drag: turn, wheel: zoom, right drag: pan)", scripts)
    return View3D(text, info, height)
