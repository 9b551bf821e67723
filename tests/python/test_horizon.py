"""The `horizon` Python package (issue 54) against independent references:
nibabel reads the same files; the command line draws the same scenes.

Run by ctest (python.pytest) with PYTHONPATH at the build tree's package and
HORIZON_BIN at the program."""
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

import horizon

HORIZON = os.environ.get("HORIZON_BIN", "horizon")


def _browser():
    """(chromium, node_modules with three and puppeteer-core) for the tests
    that open pages in a real browser; .ci/bootstrap installs them into
    BUILD/npm. A machine without them skips those tests; CI fails them."""
    # (the sanitized suite's build tree is another one: the sources' build/ too)
    build = os.environ.get("HORIZON_BUILD_DIR", "")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    candidates = [os.environ.get("HORIZON_NODE_MODULES"), os.path.join(build, "npm", "node_modules"),
                  os.path.join(root, "build", "npm", "node_modules")]
    modules = next((c for c in candidates if c and os.path.isdir(os.path.join(c, "puppeteer-core"))), candidates[1])
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    missing = [what for what, ok in (("chromium", chromium), ("node", shutil.which("node")),
                                     (os.path.join(modules, "three"), os.path.isdir(os.path.join(modules, "three"))),
                                     (os.path.join(modules, "puppeteer-core"), os.path.isdir(os.path.join(modules, "puppeteer-core"))))
               if not ok]
    if missing:
        if os.environ.get("CI"):
            pytest.fail(f"missing {', '.join(missing)} (.ci/bootstrap installs them)")
        pytest.skip(f"missing {', '.join(missing)}")
    return chromium, modules


def _open_views(chromium, modules, *pages):
    """The pages opened by Chromium (tests/browser/view3d.js): what it saw of
    each (without the sanitizer's preload: Chromium is not ours)."""
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "ASAN_OPTIONS", "LSAN_OPTIONS", "UBSAN_OPTIONS")}
    script = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "browser", "view3d.js")
    r = subprocess.run(["node", script, chromium, modules, *map(str, pages)], env=env, capture_output=True, text=True, timeout=300)
    seen = json.loads(r.stdout.strip().splitlines()[-1]) if r.stdout.strip() else {}
    assert r.returncode == 0, r.stdout + r.stderr
    return seen["pages"]


def _sphere_gifti(path, radius=60.0, centre=(0, 0, 0)):
    """A UV sphere (20 x 40 vertices, outward triangles) written by nibabel."""
    import nibabel as nib
    u, v = np.meshgrid(np.linspace(0, np.pi, 20), np.linspace(0, 2 * np.pi, 40, endpoint=False), indexing="ij")
    P = (np.stack([np.sin(u) * np.cos(v), np.sin(u) * np.sin(v), np.cos(u)], -1).reshape(-1, 3) * radius + centre).astype(np.float32)
    F = []
    for i in range(19):
        for j in range(40):
            a, b, c, d = i * 40 + j, i * 40 + (j + 1) % 40, (i + 1) * 40 + j, (i + 1) * 40 + (j + 1) % 40
            F += [[a, c, b], [b, c, d]]
    nib.save(nib.gifti.GiftiImage(darrays=[nib.gifti.GiftiDataArray(P, intent="NIFTI_INTENT_POINTSET"),
                                           nib.gifti.GiftiDataArray(np.array(F, np.int32), intent="NIFTI_INTENT_TRIANGLE")]), str(path))
    return path


@pytest.fixture
def tck(tmp_path):
    """Three streamlines of 5, 1 and 40 points written by nibabel (its TCK
    writer puts the data at an offset float32 cannot be read at in place)."""
    import nibabel as nib
    rng = np.random.default_rng(3)
    sl = [rng.normal(size=(n, 3)).astype(np.float32) * 20 for n in (5, 1, 40)]
    path = tmp_path / "t.tck"
    nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), str(path))
    return path, sl


def test_plugins_lists_the_loaders_and_their_extensions():
    found = {p["id"]: p for p in horizon.plugins()}
    tck = [p for p in found.values() if p["kind"] == "loader" and "tck" in p.get("extensions", [])]
    assert tck, found.keys()
    assert any(p["kind"] == "shader" for p in found.values())
    assert any(p["kind"] == "clustering" for p in found.values())


def test_streamlines_are_nibabels_without_a_copy(tck):
    import nibabel as nib
    path, sl = tck
    t = horizon.load(str(path))
    assert t.kind == "streamlines" and t.loader.endswith("tck")
    assert not t.positions.flags.writeable and not t.positions.flags.owndata
    assert len(t.offsets) == 4
    ours = horizon.streamlines(t)
    theirs = nib.streamlines.load(str(path)).streamlines
    assert len(ours) == len(theirs) == 3
    for a, b, c in zip(ours, theirs, sl):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)
    seq = horizon.to_nibabel(t)  # an ArraySequence over the same memory
    assert np.shares_memory(seq._data, t.positions)
    for a, b in zip(seq, theirs):
        np.testing.assert_array_equal(a, b)
    # The arrays keep the file's data alive after the object goes.
    p = t.positions
    del t, seq
    np.testing.assert_array_equal(p[:5], sl[0])


def test_volumes_are_nibabels(tmp_path):
    import nibabel as nib
    rng = np.random.default_rng(5)
    data = rng.integers(-300, 300, size=(7, 5, 3, 2)).astype(np.int16)
    affine = np.array([[-1.5, 0, 0, 10], [0, 2, 0, -20], [0, 0, 2.5, 5], [0, 0, 0, 1]])
    img = nib.Nifti1Image(data, affine)
    img.header.set_slope_inter(0.5, 3.0)
    path = tmp_path / "v.nii.gz"
    nib.save(img, str(path))
    v = horizon.load(str(path))
    assert v.kind == "volume"
    ref = nib.load(str(path))
    np.testing.assert_array_equal(v.voxels, np.asarray(ref.dataobj.get_unscaled()))
    assert v.voxels.shape == (7, 5, 3, 2) and v.voxels.dtype == np.int16
    np.testing.assert_allclose(v.affine, ref.affine)
    assert v.scale == (0.5, 3.0)
    back = horizon.to_nibabel(v)
    np.testing.assert_allclose(back.get_fdata(), ref.get_fdata())


def test_save_writes_through_the_writer_and_keeps_the_input(tck, tmp_path):
    import nibabel as nib
    path, sl = tck
    t = horizon.load(str(path))
    out = tmp_path / "t.trk"
    dropped = horizon.save(t, str(out))
    assert isinstance(dropped, list)
    back = nib.streamlines.load(str(out)).streamlines
    for a, b in zip(back, sl):
        np.testing.assert_allclose(a, b, atol=1e-4)
    with pytest.raises(horizon.Error, match="force=True"):
        horizon.save(t, str(out))
    with pytest.raises(horizon.Error):
        horizon.save(t, str(path), force=True)  # never over what it was read from
    horizon.save(t, str(out), force=True)


def test_a_scene_renders_as_the_command_line_draws_it(tmp_path):
    from PIL import Image
    scene = {"camera": {"view": "superior"}, "environment": {"type": "none"},
             "objects": [{"type": "streamlines", "builtin": "phantom", "phantom": {"streamlines": 60}, "render": "tubes"}]}
    picture = horizon.render(scene, (160, 120))
    assert picture.shape == (120, 160, 4) and picture.dtype == np.uint8
    (tmp_path / "s.json").write_text(json.dumps(scene))
    out = tmp_path / "s.png"
    subprocess.run([HORIZON, "render", str(tmp_path / "s.json"), "-o", str(out), "--size", "160x120"], check=True,
                   capture_output=True)
    cli = np.asarray(Image.open(out).convert("RGBA"))
    np.testing.assert_array_equal(picture[..., :3], cli[..., :3])
    assert (picture[..., :3].max(axis=2) > 60).sum() > 200  # (not an empty picture)


def test_scene_builder_and_its_png(tck):
    path, _ = tck
    s = horizon.Scene(environment={"type": "none"}).add(path, render="tubes", radius=1.0)
    assert s.model["objects"][0]["type"] == "streamlines"
    png = s._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    from io import BytesIO
    from PIL import Image
    im = Image.open(BytesIO(png))
    assert im.size == (640, 480)
    np.testing.assert_array_equal(np.asarray(im), s.render())


def test_errors_are_exceptions_with_the_one_line_message(tmp_path):
    with pytest.raises(horizon.Error, match="missing.tck"):
        horizon.load(str(tmp_path / "missing.tck"))
    bad = tmp_path / "bad.tck"
    bad.write_bytes(b"mrtrix tracks\ncount: 5\ndatatype: Float32LE\nfile: . 999\nEND\n")
    with pytest.raises(horizon.Error, match="bad.tck"):
        horizon.load(str(bad))
    with pytest.raises(TypeError):
        horizon.load(3)
    with pytest.raises(TypeError, match="scene"):
        horizon.render(3)
    with pytest.raises(ValueError, match="size"):
        horizon.render({"objects": [{"type": "surface", "builtin": "sphere"}]}, (4, 4))
    with pytest.raises(horizon.Error, match="objects"):
        horizon.render({"objects": [{"type": "nothing"}]}, (64, 64))



def test_the_example_notebook_runs_and_shows_its_pictures(tmp_path, monkeypatch):
    """docs/examples/horizon.ipynb executed as a user would (nbclient, the
    python3 kernel), in a scratch folder: every cell runs, the scene shows
    inline as a PNG, the printed checks say what they should, and its 3D
    view (an iframe) draws in a real browser."""
    import base64
    import html as htmlmod
    import shutil

    import nbclient
    import nbformat
    from PIL import Image
    from io import BytesIO
    src = os.path.join(os.path.dirname(__file__), "..", "..", "docs", "examples", "horizon.ipynb")
    # (the kernel runs in the scratch folder: the package this test imports, by its absolute path)
    monkeypatch.setenv("PYTHONPATH", os.path.dirname(os.path.dirname(os.path.abspath(horizon.__file__))))
    chromium, modules = _browser()
    monkeypatch.setenv("HORIZON_THREE_DIR", os.path.join(modules, "three"))
    nb = nbformat.read(src, as_version=4)
    shutil.copy(src, tmp_path)
    nbclient.NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    text = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []))
    assert "loaders" in text
    assert "streamlines; same as nibabel: True" in text
    assert "(240, 320, 4) uint8" in text
    # The progress bar of horizon.load(..., progress=True): HTML, updated in place to 100 %.
    bars = [o["data"]["text/html"] for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
            if "data" in o and "text/html" in o["data"] and "horizon-progress" in o["data"]["text/html"]]
    assert len(bars) == 1, bars
    assert '<progress value="100" max="100"' in bars[0] and "reading bundle.tck: 100%" in bars[0]
    frames = [o["data"]["text/html"] for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if "data" in o and "text/html" in o["data"] and o["data"]["text/html"].startswith("<iframe srcdoc=")]
    assert len(frames) == 1 and "height:360px" in frames[0]
    page = tmp_path / "view3d.html"
    page.write_text(htmlmod.unescape(frames[0][len('<iframe srcdoc="'):frames[0].index('" style=')]))
    (seen,) = _open_views(chromium, modules, page)
    assert seen["error"] is None and seen["parts"] == 1 and seen["info"].startswith("5 of 5 streamlines")
    assert seen["before"]["coloured"] > 500 and seen["after"]["hash"] != seen["before"]["hash"], seen
    pngs = [o["data"]["image/png"] for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
            if "data" in o and "image/png" in o["data"]]
    assert len(pngs) == 1
    im = np.asarray(Image.open(BytesIO(base64.b64decode(pngs[0]))).convert("RGB"))
    assert im.shape == (360, 480, 3)
    assert (im.max(axis=2) > 80).sum() > 500  # (the tubes, not an empty picture)


def test_the_installed_package_finds_the_installed_plugins(tmp_path, tck):
    """`cmake --install` of the package and the plugins under any prefix: the
    package finds the plugins beside it, not the build tree's."""
    build = os.environ.get("HORIZON_BUILD_DIR")
    if not build:
        pytest.skip("HORIZON_BUILD_DIR is not set (ctest sets it)")
    prefix = tmp_path / "prefix"
    for component in ("python", "runtime"):
        subprocess.run(["cmake", "--install", build, "--prefix", str(prefix), "--component", component], check=True,
                       capture_output=True)
    site = next(prefix.glob("lib/python3*/dist-packages"))  # (python3.X under /usr/local-like prefixes)
    env = {**os.environ, "PYTHONPATH": str(site), "XDG_DATA_HOME": str(tmp_path / "none"), "HORIZON_PLUGIN_PATH": ""}
    code = ("import horizon, sys; ps = horizon.plugins(); "
            "print(horizon.__file__); print(sorted({p['file'].rsplit('/', 1)[0] for p in ps})); "
            f"print(horizon.load({str(tck[0])!r}).kind); print(horizon._paths.PROGRAM)")
    out = subprocess.run(["/usr/bin/python3", "-c", code], env=env, capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0].startswith(str(site))
    assert out[1] == repr([str(prefix / "lib" / "horizon" / "plugins")])
    assert out[2] == "streamlines"
    assert out[3] == str(prefix / "bin" / "horizon") and os.access(out[3], os.X_OK)  # (the window of Scene.show)


def test_streamlines_in_memory_draw_as_their_file_does(tmp_path):
    """A scene of streamlines held in Python (a list of arrays, nibabel's
    ArraySequence) draws what the same streamlines read from a file draw."""
    import nibabel as nib
    rng = np.random.default_rng(11)
    sl = [(np.cumsum(rng.normal(size=(80, 3)), axis=0) + [0, 8 * k, 0]).astype(np.float32) for k in range(6)]
    path = tmp_path / "m.tck"
    nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), str(path))
    looks = {"render": "tubes", "radius": 0.6}
    settings = {"environment": {"type": "none"}, "camera": {"view": "superior"}}
    from_file = horizon.Scene(**settings).add(path, **looks).render((160, 120))
    assert (from_file[..., :3].max(axis=2) > 60).sum() > 300
    for given in (sl, nib.streamlines.ArraySequence(sl), horizon.from_streamlines(sl)):
        np.testing.assert_array_equal(horizon.Scene(**settings).add(given, **looks).render((160, 120)), from_file)
    d = horizon.from_streamlines(sl)
    assert len(d.offsets) == 7 and d.gap == 0
    np.testing.assert_array_equal(d.positions[80:160], sl[1])
    with pytest.raises(ValueError, match="streamline 1"):
        horizon.from_streamlines([sl[0], np.zeros((4, 2))])
    with pytest.raises(ValueError, match="finite"):
        horizon.from_streamlines([np.full((3, 3), np.inf)])
    with pytest.raises(horizon.Error, match="no dataset in memory"):
        horizon.render({"objects": [{"type": "streamlines", "data": "nope"}]}, (64, 64))


def test_surfaces_and_volumes_in_memory_draw_as_their_files_do(tmp_path):
    """Surfaces and volumes held in Python (from_mesh, from_volume, and
    nibabel's images through from_nibabel or Scene.add) draw, pixel for
    pixel, what the same data read from GIFTI and NIfTI files draw: a
    scaled int16 volume (slope and intercept) and a float one, a 4D volume's
    first volume, a surface. Wrong shapes, indices, types and affines are
    ValueErrors naming what is wrong."""
    import nibabel as nib
    gii = _sphere_gifti(tmp_path / "s.gii", 40.0)
    surf = nib.load(str(gii))
    v, f = surf.darrays[0].data, surf.darrays[1].data
    settings = {"environment": {"type": "none"}, "camera": {"view": "left"}}
    looks = {"type": "surface", "color": [0.7, 0.4, 0.2]}
    from_file = horizon.Scene(**settings).add(str(gii), **looks).render((160, 120))
    assert (from_file[..., :3].max(axis=2) > 40).sum() > 3000
    for given in (horizon.from_mesh(v, f.astype(np.int64)), horizon.from_nibabel(surf), surf):
        np.testing.assert_array_equal(horizon.Scene(**settings).add(given, **looks).render((160, 120)), from_file)
    m = horizon.from_mesh(v, f)
    assert m.kind == "mesh" and m.faces.dtype == np.uint32
    np.testing.assert_array_equal(m.vertices, v)
    rng = np.random.default_rng(2)
    aff = np.array([[-2.0, 0, 0, 20], [0, 2, 0, -24], [0, 0, 2, -16], [0, 0, 0, 1]])
    raw = (rng.random((20, 24, 16)) * 1000).astype(np.int16)
    scaled = nib.Nifti1Image(raw, aff)
    scaled.header.set_slope_inter(0.5, 10)
    plain = nib.Nifti1Image(rng.random((20, 24, 16, 2)).astype(np.float32), aff)
    for k, img in enumerate((scaled, plain)):
        path = tmp_path / f"v{k}.nii.gz"
        nib.save(img, str(path))
        img = nib.load(str(path))
        from_file = horizon.Scene().add(str(path), type="slices").render((160, 120))
        assert (from_file[..., :3].max(axis=2) > 40).sum() > 3000
        for given in (img, horizon.from_nibabel(img), horizon.from_volume(img.get_fdata(dtype=np.float32), img.affine)):
            np.testing.assert_array_equal(horizon.Scene().add(given, type="slices").render((160, 120)), from_file)
        np.testing.assert_allclose(horizon.from_nibabel(img).voxels, img.get_fdata())  # (the values: raw * 0.5 + 10 for the first)
    vol = horizon.from_volume(raw, aff)
    assert vol.kind == "volume" and vol.voxels.dtype == np.int16
    np.testing.assert_array_equal(vol.voxels, raw)
    np.testing.assert_array_equal(vol.affine, aff)
    for call, message in ((lambda: horizon.from_mesh(v, f + len(v)), "uses vertex"), (lambda: horizon.from_mesh(v[:, :2], f), r"\(n, 3\)"),
                          (lambda: horizon.from_mesh(v, f.astype(float)), "integers"),
                          (lambda: horizon.from_mesh(np.full((3, 3), np.nan), [[0, 1, 2]]), "non-finite"),
                          (lambda: horizon.from_volume(raw[0], aff), "3 to 5 dimensions"),
                          (lambda: horizon.from_volume(raw.astype(complex), aff), "complex128"),
                          (lambda: horizon.from_volume(raw, np.zeros((4, 4))), "last row"),
                          (lambda: horizon.from_volume(raw, np.diag([1.0, 0, 1, 1])), "singular"),
                          (lambda: horizon.from_volume(raw, aff[:3]), "4 x 4")):
        with pytest.raises(ValueError, match=message):
            call()


def test_a_surface_converts_to_gifti_and_back(tmp_path):
    """to_nibabel of a surface read by Horizon: a GiftiImage that nibabel
    writes and reads back with the same vertices, triangles and per-vertex
    array (by its name); from_nibabel of it is the same surface again."""
    import nibabel as nib
    g = nib.load(str(_sphere_gifti(tmp_path / "s.gii")))
    thickness = np.linspace(1, 4, len(g.darrays[0].data)).astype(np.float32)
    g.add_gifti_data_array(nib.gifti.GiftiDataArray(thickness, intent="NIFTI_INTENT_SHAPE",
                                                    meta=nib.gifti.GiftiMetaData({"Name": "thickness"})))
    nib.save(g, str(tmp_path / "t.gii"))
    m = horizon.load(str(tmp_path / "t.gii"))
    nib.save(horizon.to_nibabel(m), str(tmp_path / "back.gii"))
    back = nib.load(str(tmp_path / "back.gii"))
    np.testing.assert_array_equal(back.get_arrays_from_intent("NIFTI_INTENT_POINTSET")[0].data, g.darrays[0].data)
    np.testing.assert_array_equal(back.get_arrays_from_intent("NIFTI_INTENT_TRIANGLE")[0].data, g.darrays[1].data)
    (named,) = [d for d in back.darrays if d.meta.get("Name") == "thickness"]
    np.testing.assert_array_equal(named.data, thickness)
    again = horizon.from_nibabel(back)
    np.testing.assert_array_equal(again.vertices, m.vertices)
    np.testing.assert_array_equal(again.faces, m.faces)


def test_clustering_is_dipys_quickbundlesx_bit_for_bit(tmp_path):
    """horizon.cluster in exact mode against DIPY's QuickBundlesX on the
    same streamlines: the same clusters at every level, in the same order,
    with the same float32 centroids, in file order and in a given order;
    DIPY's ClusterMapCentroid out."""
    from dipy.segment.clustering import QuickBundlesX
    p = subprocess.run([HORIZON, "demo", "--out", str(tmp_path), "--streamlines", "1500", "--no-window"], capture_output=True,
                       env={**os.environ, "DISPLAY": ""})
    assert p.returncode == 0, p.stderr
    data = horizon.load(str(tmp_path / "phantom.tck"))
    sl = [s.astype(np.float32) for s in horizon.streamlines(data)]
    thresholds = [30, 25, 20, 15]
    order = np.random.default_rng(5).permutation(len(sl))
    for ordering in (None, order):
        tree = horizon.cluster(data, "qbx", thresholds, ordering=ordering, mode="exact")
        ref = QuickBundlesX(thresholds).cluster(sl, ordering=ordering)
        assert tree.nb_levels == 4 and tree.thresholds == thresholds
        for level in (1, 2, 3, 4):
            clusters = ref.get_clusters(level)
            want = np.full(len(sl), -1)
            for i, c in enumerate(clusters):
                want[np.asarray(c.indices)] = i
            np.testing.assert_array_equal(tree.labels(level), want)
            for c, node in zip(clusters, tree.nodes(level)):
                assert np.array_equal(c.centroid, tree.centroids[node])
    cmap = tree.to_dipy(2, sl)
    assert len(cmap) == len(tree.nodes(2)) and sum(len(c) for c in cmap) == len(sl)
    # Streamlines from Python cluster alike.
    np.testing.assert_array_equal(horizon.cluster(sl, "qbx", thresholds, mode="exact").labels(4),
                                  horizon.cluster(data, "qbx", thresholds, mode="exact").labels(4))
    with pytest.raises(ValueError, match="ordering"):
        horizon.cluster(data, "qbx", ordering=[0, 0, 1])
    with pytest.raises(ValueError, match="permutation"):
        horizon.cluster(data, "qbx", ordering=np.zeros(len(sl), np.int64))
    with pytest.raises(horizon.Error, match="no parameter 'nonsense'"):
        horizon.cluster(data, "qbx", nonsense=3)
    with pytest.raises(ValueError, match="level 5"):
        tree.labels(5)


def test_cohort_qc_on_dask_writes_a_gallery_and_resumes(tmp_path):
    """python3 -m horizon.batch over a cohort of four subjects (one file
    truncated) on a local Dask cluster of two workers: the three good ones
    measured as nibabel measures them and drawn, the bad one a failed row
    naming its file; a second run skips what is done and unchanged, redoes
    a changed subject, retries the failed one; --strict makes the failure
    the exit status."""
    import nibabel as nib
    from PIL import Image
    rng = np.random.default_rng(2)
    cohort, out = tmp_path / "cohort", tmp_path / "qc"
    truth = {}
    for i in range(1, 5):
        d = cohort / f"sub-{i:02d}" / "dwi"
        d.mkdir(parents=True)
        sl = [(np.cumsum(rng.normal(size=(int(rng.integers(20, 60)), 3)), axis=0) * 2 + [0, 10 * k, 0]).astype(np.float32)
              for k in range(25 + i)]
        f = d / f"sub-{i:02d}_tractography.{'trk' if i == 3 else 'tck'}"  # (a TRK: no delimiters between streamlines)
        nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), str(f))
        lengths = [float(np.linalg.norm(np.diff(s.astype(np.float64), axis=0), axis=1).sum()) for s in sl]
        truth[f"sub-{i:02d}__dwi__sub-{i:02d}_tractography"] = (len(sl), float(np.median(lengths)))
    bad = cohort / "sub-04" / "dwi" / "sub-04_tractography.tck"
    bad.write_bytes(bad.read_bytes()[:300])  # truncated
    env = {**os.environ, "PYTHONPATH": os.path.dirname(os.path.dirname(os.path.abspath(horizon.__file__)))}
    cmd = ["/usr/bin/python3", "-m", "horizon.batch", str(cohort), "--glob", "sub-*/dwi/*_tractography.*", "--out", str(out),
           "--workers", "2"]

    p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    assert "4 subjects: 3 ok (0 done before), 1 failed" in p.stdout
    records = {r["id"]: r for r in json.loads((out / "qc.json").read_text())}
    assert len(records) == 4
    for sid, (n, median) in truth.items():
        r = records[sid]
        if sid.startswith("sub-04"):
            assert r["status"] == "failed" and "sub-04_tractography.tck" in r["error"]
            continue
        assert r["status"] == "ok" and r["streamlines"] == n
        assert r["length_mm"]["median"] == pytest.approx(median, rel=1e-5)
        for view in ("superior", "left"):
            im = Image.open(out / r["views"][view])
            assert im.size == (320, 240)
            assert (np.asarray(im.convert("RGB")).max(axis=2) > 80).sum() > 50
    page = (out / "index.html").read_text()
    assert page.count("<tr class=\"ok\">") == 3 and page.count("<tr class=\"failed\">") == 1
    assert "sub-04_tractography.tck" in page and "superior.png" in page

    # Again: the done ones skipped (their records untouched), a changed one redone.
    done = out / "subjects" / "sub-01__dwi__sub-01_tractography" / "qc.json"
    before = done.stat().st_mtime_ns
    changed = cohort / "sub-02" / "dwi" / "sub-02_tractography.tck"
    nib.streamlines.save(nib.streamlines.Tractogram([np.zeros((3, 3), np.float32) + [0, 0, k] for k in range(3)],
                                                    affine_to_rasmm=np.eye(4)), str(changed))
    p = subprocess.run(cmd + ["--strict"], env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 1, p.stdout + p.stderr
    assert "4 subjects: 3 ok (2 done before), 1 failed" in p.stdout
    assert done.stat().st_mtime_ns == before
    records = {r["id"]: r for r in json.loads((out / "qc.json").read_text())}
    assert records["sub-02__dwi__sub-02_tractography"]["streamlines"] == 3

    # What is wrong with the command itself: one line, before any work.
    p = subprocess.run(cmd[:-2] + ["--views", "top"], env=env, capture_output=True, text=True)
    assert p.returncode == 2 and "--views" in p.stderr
    p = subprocess.run(cmd[:3] + [str(cohort), "--glob", "*.trx", "--out", str(tmp_path / "none")], env=env, capture_output=True,
                       text=True)
    assert p.returncode == 1 and "no file under" in p.stderr


def test_the_gallery_and_its_3d_views_in_a_real_browser(tmp_path):
    """The cohort's gallery opened from its files by Chromium (headless,
    driven by puppeteer-core from npm: tests/browser/gallery.js): its rows,
    sorting by a click on a header, filtering by typing; a subject's 3D view
    (its streamlines as glTF, drawn by three.js from npm, carried in the
    gallery) drawn in colour, not the background, and turned by a drag. The
    exported streamlines are every k-th of the subject's, as nibabel reads
    them. (Needs chromium, node and BUILD/npm/node_modules with three@0.147
    and puppeteer-core, which .ci/bootstrap installs; a machine without them
    skips it, CI fails.)"""
    import nibabel as nib
    chromium, modules = _browser()
    rng = np.random.default_rng(6)
    cohort, out = tmp_path / "cohort", tmp_path / "qc"
    for i in (1, 2, 3):
        d = cohort / f"sub-{i:02d}"
        d.mkdir(parents=True)
        sl = [(np.cumsum(rng.normal(size=(40, 3)), axis=0) * 2 + [0, 3 * k - 40, 0]).astype(np.float32) for k in range(30 * i)]
        nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), str(d / "t.tck"))
        if i == 1:  # (a surface around sub-01's streamlines; sub-02 has none: a warning)
            _sphere_gifti(d / "lh.pial.gii", 70.0)
    (cohort / "sub-03" / "t.tck").write_bytes(b"mrtrix tracks\ncount: 3\n")  # (broken: a failed row, no 3D view)
    env = {**os.environ, "PYTHONPATH": os.path.dirname(os.path.dirname(os.path.abspath(horizon.__file__)))}
    p = subprocess.run(["/usr/bin/python3", "-m", "horizon.batch", str(cohort), "--glob", "sub-*/t.tck", "--out", str(out), "--workers",
                        "1", "--three", os.path.join(modules, "three"), "--web-points", "1000", "--surface", "sub-*/*.gii"], env=env, capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr
    records = {r["id"]: r for r in json.loads((out / "qc.json").read_text())}
    assert records["sub-01__t"]["surfaces"] == [str(cohort / "sub-01" / "lh.pial.gii")]
    assert records["sub-02__t"]["warnings"] == ["no surface found for this subject"]
    # The exported proxy: every k-th streamline, at most 1000 points (40 each: every 3rd of sub-02's 60).
    glb = out / "subjects" / "sub-02__t" / "scene.glb"
    src = list(nib.streamlines.load(str(cohort / "sub-02" / "t.tck")).streamlines)
    back = tmp_path / "back.tck"
    assert subprocess.run([os.environ.get("HORIZON_BIN", "horizon"), "convert", str(glb), str(back)], capture_output=True).returncode == 0
    got = list(nib.streamlines.load(str(back)).streamlines)
    assert len(got) == 20
    for a, b in zip(got, src[::3]):
        np.testing.assert_allclose(a, b, atol=1e-4)
    # In the browser (without the sanitizer's preload: Chromium is not ours).
    benv = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "ASAN_OPTIONS", "LSAN_OPTIONS", "UBSAN_OPTIONS")}
    script = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "browser", "gallery.js")
    r = subprocess.run(["node", script, str(out / "index.html"), chromium, modules], env=benv, capture_output=True, text=True,
                       timeout=300)
    seen = json.loads(r.stdout.strip().splitlines()[-1]) if r.stdout.strip() else {}
    assert r.returncode == 0, r.stdout + r.stderr
    assert seen["rows"] == ["sub-01__t", "sub-02__t", "sub-03__t"] and seen["failed"] == 1
    assert [x for x in seen["sorted_up"] if x] == ["30", "60"] and [x for x in seen["sorted_down"] if x] == ["60", "30"]
    assert seen["filtered"] == ["sub-01__t"]
    assert seen["links_3d"] == 2 and seen["view_url"].endswith("sub-01__t/view.html")
    assert seen["view_error"] is None and "15 of 30 streamlines, 1 surface" in seen["info"] and seen["parts"] == 2
    before, after = seen["before"], seen["after"]
    assert before["drawn"] > 2000 and before["coloured"] > 1000, before  # (direction colours, not the background)
    assert before["drawn"] > 20000, before  # (sub-01's surface around them: a disc)
    assert after["drawn"] > 2000 and after["hash"] != before["hash"] and seen["frames"] >= 2, seen


def test_a_scenes_3d_view_inline_in_a_notebook_and_in_a_browser(tmp_path):
    """Scene.view3d(): the scene's streamlines (every k-th, at most `points`
    points) and surfaces with their colours and opacities, one
    self-contained page that Jupyter shows inline as an iframe (its srcdoc
    is the page). Opened in Chromium from that srcdoc: both parts drawn, the
    red translucent surface as a large warm disc that the streamlines alone
    do not make, turned by a drag. Slices are named as left out; bad
    arguments are one-line ValueErrors."""
    import html as htmlmod
    chromium, modules = _browser()
    three = os.path.join(modules, "three")
    rng = np.random.default_rng(6)
    sl = [(np.cumsum(rng.normal(size=(40, 3)), axis=0) * 2 + [0, 3 * k - 40, 0]).astype(np.float32) for k in range(30)]
    sphere = _sphere_gifti(tmp_path / "sphere.gii")
    scene = horizon.Scene(base=str(tmp_path)).add(sl).add("sphere.gii", type="surface", color=[0.8, 0.1, 0.05], opacity=0.5)
    scene.add("sphere.gii", type="slices")
    view = scene.view3d(points=600, three=three)
    assert view.info == "15 of 30 streamlines, 1 surface (not drawn here: sphere.gii (slices))"  # (every 2nd: 40 points each)
    shown = view._repr_html_()
    assert shown.startswith('<iframe srcdoc="')
    page = tmp_path / "from_the_notebook.html"
    page.write_text(htmlmod.unescape(shown[len('<iframe srcdoc="'):shown.index('" style=')]))
    assert page.read_text() == view.html
    lines = scene.__class__().add(sl).view3d(three=three).save(tmp_path / "lines.html")
    both, alone = _open_views(chromium, modules, page, lines)
    assert both["error"] is None and both["parts"] == 2 and both["info"].startswith(view.info)
    assert alone["error"] is None and alone["parts"] == 1 and alone["info"].startswith("30 of 30 streamlines")
    assert both["before"]["warm"] > 30000 and alone["before"]["warm"] < 10000, (both["before"], alone["before"])
    assert alone["before"]["coloured"] > 1000  # (direction colours)
    for seen in (both, alone):
        assert seen["after"]["hash"] != seen["before"]["hash"] and seen["frames"] >= 2
    with pytest.raises(ValueError, match="points must be at least 2"):
        scene.view3d(points=1, three=three)
    with pytest.raises(ValueError, match="/nonexistent"):
        scene.view3d(three="/nonexistent")
    with pytest.raises(ValueError, match="no streamlines or surface"):
        horizon.Scene(base=str(tmp_path)).add(str(sphere), type="slices").view3d(three=three)
    with pytest.raises(ValueError, match="not linear RGB"):
        horizon.Scene().add(sl, color=[2, 0, 0]).view3d(three=three)


def test_show_opens_the_window_on_the_scene(tmp_path, monkeypatch):
    """Scene.show() under Xvfb: the window (`horizon view`, scripted) shows
    the scene, streamlines and a surface held in Python and a volume's file,
    as render() draws it; no hidden scene file or temporary data is left; a
    script the window refuses is a horizon.Error with the window's own
    message; without a display, an Error at once."""
    import nibabel as nib
    from PIL import Image
    if not shutil.which("xvfb-run"):
        if os.environ.get("CI"):
            pytest.fail("missing xvfb-run (.ci/bootstrap installs it)")
        pytest.skip("missing xvfb-run")
    _sphere_gifti(tmp_path / "s.gii", 50.0)
    rng = np.random.default_rng(4)
    nib.save(nib.Nifti1Image((rng.random((20, 24, 16)) * 100).astype(np.int16), np.diag([4.0, 4, 4, 1])), str(tmp_path / "v.nii.gz"))
    (tmp_path / "good.txt").write_text(f"wait 2\nscreenshot {tmp_path / 'shown.png'}\nquit\n")
    (tmp_path / "bad.txt").write_text("frobnicate 3\n")
    child = tmp_path / "child.py"
    child.write_text(f"""
import numpy as np, nibabel as nib, horizon
rng = np.random.default_rng(1)
sl = [(np.cumsum(rng.normal(size=(40, 3)), axis=0) * 2 + [0, 3 * k - 40, 0]).astype(np.float32) for k in range(30)]
s = horizon.Scene(base={str(tmp_path)!r}).add(sl, render="tubes").add(nib.load({str(tmp_path / 's.gii')!r}), type="surface", opacity=0.4)
s.add("v.nii.gz", type="slices")
try:
    s.show((320, 240), script={str(tmp_path / 'bad.txt')!r})
except horizon.Error as e:
    print("ERROR", e)
s.show((320, 240), script={str(tmp_path / 'good.txt')!r})
np.save({str(tmp_path / 'rendered.npy')!r}, s.render((320, 240)))
""")
    # (the sanitizer's preload for the child alone, not for Xvfb and the shells)
    env = {**os.environ, "PYTHONPATH": os.path.dirname(os.path.dirname(os.path.abspath(horizon.__file__))),
           "XDG_DATA_HOME": str(tmp_path / "xdg"), "TMPDIR": str(tmp_path)}
    preload = env.pop("LD_PRELOAD", None)
    python = ["env", f"LD_PRELOAD={preload}", "/usr/bin/python3"] if preload else ["/usr/bin/python3"]
    # (the child's status through a file: xvfb-run sometimes exits 5 on a
    # race in its own clean-up, hiding it; tests/scripts/hztest.xvfb_run)
    status = tmp_path / "status"
    p = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", "sh", "-c", '"$@"; echo $? > "$0"', str(status), *python, str(child)],
                       env=env, capture_output=True, text=True, timeout=300)
    assert status.read_text().strip() == "0", p.stdout + p.stderr
    errors = [line for line in p.stdout.splitlines() if line.startswith("ERROR")]
    assert len(errors) == 1 and "bad.txt" in errors[0] and "frobnicate" in errors[0], p.stdout
    shown = np.asarray(Image.open(tmp_path / "shown.png").convert("RGB")).astype(float)
    rendered = np.load(tmp_path / "rendered.npy")[..., :3].astype(float)
    assert shown.shape == rendered.shape == (240, 320, 3)
    assert np.abs(shown - shown.mean()).mean() > 20  # (a picture, not a flat colour)
    assert np.abs(shown - rendered).mean() < 3, np.abs(shown - rendered).mean()
    assert not [f for f in os.listdir(tmp_path) if f.startswith((".hz_show_", "hz_show_"))]
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(horizon.Error, match="no display"):
        horizon.Scene().add(str(tmp_path / "s.gii")).show()


def test_progress_is_reported_and_an_exception_in_it_stops_the_work(tmp_path, capsys):
    """load(progress=...) and cluster(progress=...): fractions in [0, 1],
    never decreasing, ending at 1, with what is being done; an exception the
    callback raises (KeyboardInterrupt, as Ctrl-C in a notebook) stops the
    work and is raised by the call; True draws a text bar; anything else is
    a TypeError."""
    import nibabel as nib
    rng = np.random.default_rng(8)
    sl = [np.cumsum(rng.normal(size=(60, 3)), axis=0).astype(np.float32) for _ in range(20000)]
    path = tmp_path / "p.tck"
    nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), str(path))
    seen = []
    data = horizon.load(path, progress=lambda f, what: seen.append((f, what)))
    assert len(data.offsets) == 20001
    fractions = [f for f, _ in seen]
    assert fractions and fractions[-1] == 1.0 and all(0 <= f <= 1 for f in fractions)
    assert fractions == sorted(fractions)
    assert any("TCK" in w for _, w in seen)

    def interrupt(f, what):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        horizon.load(path, progress=interrupt)
    seen.clear()
    tree = horizon.cluster(data, "qbx", [30, 20], progress=lambda f, what: seen.append(f))
    assert len(tree.labels(2)) == 20000
    assert seen and seen[-1] == 1.0 and seen == sorted(seen)
    with pytest.raises(KeyboardInterrupt):
        horizon.cluster(data, "qbx", [30, 20], progress=interrupt)
    horizon.load(path, progress=True)
    assert "100%" in capsys.readouterr().err
    with pytest.raises(TypeError, match="progress"):
        horizon.load(path, progress=3)


def test_threads_loading_at_once_do_not_deadlock(tck):
    """Four threads of a fresh interpreter load files at once, the first
    call finding the plugins (done with the GIL released, under a lock):
    all finish."""
    path, _ = tck
    code = ("import threading, horizon\n"
            f"ts = [threading.Thread(target=lambda: [horizon.load({str(path)!r}) for _ in range(20)]) for _ in range(4)]\n"
            "[t.start() for t in ts]\n[t.join(20) for t in ts]\n"
            "print('alive' if any(t.is_alive() for t in ts) else 'done')\n"
            "import os\nos._exit(0)\n")
    env = {**os.environ, "PYTHONPATH": os.path.dirname(os.path.dirname(os.path.abspath(horizon.__file__)))}
    p = subprocess.run(["/usr/bin/python3", "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert p.stdout.strip() == "done", p.stdout + p.stderr


def test_cohort_qc_checks_the_affine_against_the_anatomy(tmp_path):
    """--anatomy: a tractogram inside its subject's T1 grid passes; one moved
    200 mm away (a wrong affine) is flagged with how far it reaches outside;
    a subject without an anatomy says so; the views draw the T1's slices."""
    import nibabel as nib
    rng = np.random.default_rng(4)
    cohort, out = tmp_path / "cohort", tmp_path / "qc"
    affine = np.diag([2.0, 2.0, 2.0, 1.0])
    affine[:3, 3] = -40
    for i, shift in ((1, 0.0), (2, 200.0), (3, 0.0)):
        (cohort / f"sub-{i:02d}" / "dwi").mkdir(parents=True)
        if i != 3:
            (cohort / f"sub-{i:02d}" / "anat").mkdir()
            nib.save(nib.Nifti1Image(rng.random((40, 40, 40)).astype(np.float32) * 100, affine),
                     str(cohort / f"sub-{i:02d}" / "anat" / f"sub-{i:02d}_T1w.nii.gz"))
        sl = [(np.cumsum(rng.normal(size=(30, 3)), axis=0) + [shift, 2 * k - 20, 0]).astype(np.float32) for k in range(20)]
        nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)),
                             str(cohort / f"sub-{i:02d}" / "dwi" / f"sub-{i:02d}_tractography.tck"))
    env = {**os.environ, "PYTHONPATH": os.path.dirname(os.path.dirname(os.path.abspath(horizon.__file__)))}
    p = subprocess.run(["/usr/bin/python3", "-m", "horizon.batch", str(cohort), "--glob", "sub-*/dwi/*.tck", "--out", str(out),
                        "--anatomy", "sub-*/anat/*_T1w.nii.gz", "--workers", "1", "--views", "superior"],
                       env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    records = {r["id"].split("__")[0]: r for r in json.loads((out / "qc.json").read_text())}
    assert all(r["status"] == "ok" for r in records.values())
    assert records["sub-01"]["warnings"] == [] and records["sub-01"]["anatomy"]["outside_mm"] <= 10
    np.testing.assert_allclose(records["sub-01"]["anatomy"]["box_mm"], [[-41, -41, -41], [39, 39, 39]])
    far = records["sub-02"]["anatomy"]["outside_mm"]
    assert 150 < far < 250 and "outside sub-02_T1w.nii.gz's grid" in records["sub-02"]["warnings"][0]
    assert records["sub-03"]["warnings"] == ["no anatomy found for this subject"]
    assert "(2 with warnings)" in (out / "index.html").read_text()
    assert "warning sub-02" in p.stdout


def test_cohort_qc_survives_a_subject_that_kills_its_worker(tmp_path):
    """A loader that dies on the files it opens (a test fixture replacing the
    TCK loader through HORIZON_PLUGIN_PATH): the subject's task kills its
    worker each time Dask gives it one; it is one failed row, the others
    are done."""
    import nibabel as nib
    build = os.environ.get("HORIZON_BUILD_DIR")
    if not build:
        pytest.skip("HORIZON_BUILD_DIR is not set (ctest sets it)")
    crash = os.path.join(build, "tests", "fixtures", "crash_on_open")
    assert os.path.exists(os.path.join(crash, "fx_tck_crash_on_open.so"))
    rng = np.random.default_rng(6)
    cohort, out = tmp_path / "cohort", tmp_path / "qc"
    for i, ext in ((1, "trk"), (2, "tck"), (3, "trk")):
        (cohort / f"sub-{i:02d}").mkdir(parents=True)
        sl = [np.cumsum(rng.normal(size=(30, 3)), axis=0).astype(np.float32) for _ in range(10)]
        nib.streamlines.save(nib.streamlines.Tractogram(sl, affine_to_rasmm=np.eye(4)), str(cohort / f"sub-{i:02d}" / f"t.{ext}"))
    env = {**os.environ, "PYTHONPATH": os.path.dirname(os.path.dirname(os.path.abspath(horizon.__file__))),
           "HORIZON_PLUGIN_PATH": crash, "HORIZON_PLUGIN_CACHE": "off"}
    p = subprocess.run(["/usr/bin/python3", "-m", "horizon.batch", str(cohort), "--glob", "sub-*/t.*", "--out", str(out),
                        "--workers", "2", "--views", "superior"], env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    # (a subject finished on a worker that the bad one then killed may be
    # given again to another, which finds it done: "done before")
    assert "3 subjects: 2 ok (" in p.stdout and "), 1 failed" in p.stdout, p.stdout
    records = {r["id"]: r for r in json.loads((out / "qc.json").read_text())}
    assert records["sub-02__t"]["status"] == "failed"
    assert "failed on every worker" in records["sub-02__t"]["error"] and "t.tck" in records["sub-02__t"]["error"]
    assert records["sub-01__t"]["status"] == records["sub-03__t"]["status"] == "ok"


def test_filter_selects_what_the_command_line_selects(tmp_path):
    """horizon.filter with the regions `horizon filter` takes (spheres,
    boxes, a mask file; include, exclude, ends only, lengths, invert) keeps
    the same streamlines as the command line, and a sphere's against numpy;
    save(selection=...) writes those, read back by nibabel."""
    import nibabel as nib
    p = subprocess.run([HORIZON, "demo", "--out", str(tmp_path), "--streamlines", "1500", "--no-window"], capture_output=True,
                       env={**os.environ, "DISPLAY": ""})
    assert p.returncode == 0, p.stderr
    src = str(tmp_path / "phantom.tck")
    data = horizon.load(src)
    sl = horizon.streamlines(data)
    mask = np.zeros((40, 40, 40), np.uint8)
    mask[10:25, 15:30, 12:28] = 1
    affine = np.diag([3.0, 3.0, 3.0, 1.0])
    affine[:3, 3] = -60
    nib.save(nib.Nifti1Image(mask, affine), str(tmp_path / "mask.nii.gz"))
    cases = [dict(include=["sphere:-29,27,-30,12"]),
             dict(include=["box:-20,-40,-10,20,10,30"], exclude=["sphere:0,-20,10,8"]),
             dict(include=[str(tmp_path / "mask.nii.gz")], min_length=40, max_length=160),
             dict(include=["sphere:-29,27,-30,12"], ends_only=True),
             dict(include=["sphere:-29,27,-30,12"], invert=True)]
    for c in cases:
        ids = horizon.filter(data, **c)
        args = [a for r in c.get("include", []) for a in ("--include", r)] + [a for r in c.get("exclude", []) for a in ("--exclude", r)]
        args += ["--min-length", str(c["min_length"])] if "min_length" in c else []
        args += ["--max-length", str(c["max_length"])] if "max_length" in c else []
        args += ["--ends-only"] if c.get("ends_only") else []
        args += ["--invert"] if c.get("invert") else []
        cli = subprocess.run([HORIZON, "filter", src, *args, "--ids", "-"], capture_output=True, text=True)
        assert cli.returncode == 0, cli.stderr
        assert ids.dtype == np.uint64
        np.testing.assert_array_equal(ids, [int(x) for x in cli.stdout.split()], err_msg=str(c))
        assert 0 < len(ids) < len(sl), c
    within = [i for i, s in enumerate(sl) if (np.linalg.norm(s - [-29, 27, -30], axis=1) <= 12).any()]
    np.testing.assert_array_equal(horizon.filter(data, include=["sphere:-29,27,-30,12"]), within)
    ids = horizon.filter(data, include=["sphere:-29,27,-30,12"])
    horizon.save(data, str(tmp_path / "kept.trk"), selection=ids)
    kept = nib.streamlines.load(str(tmp_path / "kept.trk")).streamlines
    assert len(kept) == len(ids)
    for k, i in zip(kept, ids):
        np.testing.assert_allclose(k, sl[i], atol=1e-4)
    with pytest.raises(ValueError, match="increasing"):
        horizon.save(data, str(tmp_path / "bad.trk"), selection=[3, 1])
    with pytest.raises(TypeError, match="list of region specs"):
        horizon.filter(data, include="sphere:0,0,0,1")
    with pytest.raises(horizon.Error, match="nowhere.nii"):
        horizon.filter(data, include=[str(tmp_path / "nowhere.nii")])
    assert not (tmp_path / "bad.trk").exists()


def test_sh_to_sf_is_dipys_in_every_basis():
    """The ODF glyphs' SH basis (horizon.sh_to_sf, core's sh_matrix) against
    dipy.reconst.shm.sh_to_sf on DIPY's own sphere: descoteaux07 and
    tournier07, legacy and not, orders 0 to 12, random coefficients."""
    import warnings
    from dipy.core.sphere import Sphere
    from dipy.data import get_sphere
    from dipy.reconst.shm import sh_to_sf
    sphere = get_sphere("repulsion724")
    rng = np.random.default_rng(4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for order in (0, 2, 4, 8, 12):
            sh = rng.normal(size=(5, (order + 1) * (order + 2) // 2))
            for basis in ("descoteaux07", "tournier07"):
                for legacy in (True, False):
                    want = sh_to_sf(sh, sphere, sh_order=order, basis_type=basis, legacy=legacy)
                    got = horizon.sh_to_sf(sh, sphere.vertices, basis=basis, legacy=legacy)
                    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-10, err_msg=f"{basis} legacy={legacy} order {order}")
    # (the poles and the x axis, where the angles are degenerate)
    poles = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [-1.0, 0, 0]])
    sh = rng.normal(size=45)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = sh_to_sf(sh, Sphere(xyz=poles), sh_order=8)
    np.testing.assert_allclose(horizon.sh_to_sf(sh, poles), want, rtol=1e-9, atol=1e-10)
    with pytest.raises(horizon.Error, match="7 coefficients are not an even-order SH series"):
        horizon.sh_to_sf(np.zeros(7), poles)


def test_buan_segments_are_dipys_assignment_map(tmp_path):
    """BUAN's segment of every point (horizon.buan_segments, which `--buan`
    draws by) against dipy.stats.analysis.assignment_map on DIPY's own
    bundles (minimal_bundles.zip: 5 subjects x 3 bundles), for 100 and 37
    segments, and on two bundles taken as one (two clusters: indices from n
    on); from a file and from Python's streamlines alike."""
    import os
    import zipfile
    import dipy
    import nibabel as nib
    from dipy.stats.analysis import assignment_map
    with zipfile.ZipFile(os.path.join(os.path.dirname(dipy.__file__), "data", "files", "minimal_bundles.zip")) as z:
        z.extractall(tmp_path)
    for path in sorted(tmp_path.glob("sub_*/*.trk")):
        sl = nib.streamlines.load(str(path)).streamlines
        for n in (100, 37):
            ref = np.asarray(assignment_map(sl, sl, n))
            got = horizon.buan_segments(horizon.load(str(path)), n)
            assert got.shape == ref.shape
            assert (got == ref).mean() >= 0.998, (path, n)  # (float32 ties: one point in 1000 at most)
    a = nib.streamlines.load(str(tmp_path / "sub_1" / "AF_L.trk")).streamlines
    b = nib.streamlines.load(str(tmp_path / "sub_1" / "CST_R.trk")).streamlines
    both = list(a) + [s + np.float32([150, 0, 0]) for s in b]  # (the second 150 mm away: a cluster of its own)
    ref = np.asarray(assignment_map(nib.streamlines.ArraySequence(both), nib.streamlines.ArraySequence(both), 50))
    assert ref.max() >= 50  # (two clusters)
    got = horizon.buan_segments(both, 50)
    assert (got == ref).mean() >= 0.998
