#!/usr/bin/env python3
"""VTK 9 (the engine under DIPY's Horizon and FURY) drawing a TCK's streamlines
as lines, for bench/peers_bench.py: reads the file (numpy, mapped), builds one
vtkPolyData of polylines coloured by direction, renders one 1280x800 frame in
an on-screen window (Xvfb), writes it and prints the seconds from start to the
first frame as JSON.

    /usr/bin/python3 bench/vtk_lines.py FILE.tck OUT.png
"""
import json
import os
import sys
import time

T0 = time.perf_counter()

import numpy as np  # noqa: E402
import vtk  # noqa: E402
from vtk.util import numpy_support  # noqa: E402


def read_tck(path):
    with open(path, "rb") as f:
        head = f.read(4096).decode("latin1")
    offset = int([l for l in head.split("\n") if l.startswith("file:")][0].split()[-1])
    n = (os.path.getsize(path) - offset) // 12
    pts = np.memmap(path, dtype="<f4", mode="r", offset=offset, shape=(n, 3))
    sep = np.flatnonzero(~np.isfinite(pts[:, 0]))
    starts = np.concatenate([[0], sep[:-1] + 1])
    lengths = sep - starts
    keep = lengths > 0
    return pts, starts[keep], lengths[keep]


def main():
    path, out = sys.argv[1], sys.argv[2]
    pts, starts, lengths = read_tck(path)
    # Points without the delimiters, one polyline cell per streamline.
    finite = np.isfinite(pts[:, 0])
    xyz = np.ascontiguousarray(pts[finite], dtype=np.float32)
    new_starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    # Direction colours (|tangent| as RGB), as Horizon's default.
    tangent = np.gradient(xyz, axis=0)
    norm = np.linalg.norm(tangent, axis=1, keepdims=True)
    colors = (np.abs(tangent / np.maximum(norm, 1e-12)) * 255).astype(np.uint8)
    points = vtk.vtkPoints()
    points.SetData(numpy_support.numpy_to_vtk(xyz, deep=False))
    conn = np.empty(len(lengths) + len(xyz), dtype=np.int64)
    pos = new_starts + np.arange(len(lengths))
    conn[pos] = lengths
    mask = np.ones(len(conn), bool)
    mask[pos] = False
    conn[mask] = np.arange(len(xyz))
    cells = vtk.vtkCellArray()
    cells.SetCells(len(lengths), numpy_support.numpy_to_vtkIdTypeArray(conn, deep=True))
    poly = vtk.vtkPolyData()
    poly.SetPoints(points)
    poly.SetLines(cells)
    vc = numpy_support.numpy_to_vtk(colors, deep=True)
    vc.SetName("colors")
    poly.GetPointData().SetScalars(vc)
    mapper = vtk.vtkPolyDataMapper()
    mapper.SetInputData(poly)
    actor = vtk.vtkActor()
    actor.SetMapper(mapper)
    ren = vtk.vtkRenderer()
    ren.AddActor(actor)
    ren.SetBackground(0.02, 0.02, 0.025)
    cam = ren.GetActiveCamera()
    cam.SetPosition(-1, 0, 0)
    cam.SetViewUp(0, 0, 1)
    ren.ResetCamera()
    win = vtk.vtkRenderWindow()
    win.SetSize(1280, 800)
    win.AddRenderer(ren)
    win.Render()
    first = time.perf_counter() - T0
    grab = vtk.vtkWindowToImageFilter()
    grab.SetInput(win)
    grab.Update()
    w = vtk.vtkPNGWriter()
    w.SetFileName(out)
    w.SetInputConnection(grab.GetOutputPort())
    w.Write()
    # A second frame of the same view (what orbiting costs per frame).
    t1 = time.perf_counter()
    cam.Azimuth(5)
    win.Render()
    print(json.dumps({"first_frame_s": first, "frame_s": time.perf_counter() - t1, "streamlines": int(len(lengths)),
                      "points": int(len(xyz))}))


if __name__ == "__main__":
    main()
