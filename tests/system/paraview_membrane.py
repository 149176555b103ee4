"""The README's membrane recipe, run by ParaView itself:
`xvfb-run -a -s "-screen 0 1280x1024x24 -noreset" pvpython tests/system/paraview_membrane.py XDMF TIME PNG`.

Open solution.xdmf with Xdmf3ReaderT, Warp By Scalar on eta (its default direction, z, for a mesh in the
x-y plane), colour by contact, go to time TIME. Prints one JSON line with what ParaView shows there and
saves a screenshot to PNG; tests/system/test_paraview.py checks the numbers against the solver's own.
"""

import json
import sys

from paraview import servermanager
from paraview.simple import ColorBy, CreateView, GetAnimationScene, SaveScreenshot, Show, WarpByScalar, Xdmf3ReaderT
from vtk.util.numpy_support import vtk_to_numpy


def main(path, t, screenshot):
    source = Xdmf3ReaderT(FileName=[path])
    GetAnimationScene().UpdateAnimationUsingDataTimeSteps()
    warp = WarpByScalar(Input=source, Scalars=["POINTS", "eta"])
    view = CreateView("RenderView")
    view.ViewSize = [800, 600]
    display = Show(warp, view)
    ColorBy(display, ("POINTS", "contact"))
    display.RescaleTransferFunctionToDataRange(True, False)
    GetAnimationScene().AnimationTime = t
    view.ViewTime = t
    view.CameraPosition = [0.0, -3.0, 3.0]
    view.CameraFocalPoint = [0.0, 0.0, 0.0]
    view.CameraViewUp = [0.0, 0.0, 1.0]
    view.ResetCamera()
    warp.UpdatePipeline(t)
    data = servermanager.Fetch(warp)
    points = vtk_to_numpy(data.GetPoints().GetData())
    point_data = data.GetPointData()
    eta, contact = vtk_to_numpy(point_data.GetArray("eta")), vtk_to_numpy(point_data.GetArray("contact"))
    cells = {data.GetCellType(i) for i in range(data.GetNumberOfCells())}
    print(json.dumps({"class": data.GetClassName(), "points": data.GetNumberOfPoints(), "cells": data.GetNumberOfCells(),
                      "cell_types": sorted(cells), "times": list(source.TimestepValues),
                      "max_warp_error": float(abs(points[:, 2] - eta).max()), "contact_nodes": int((contact > 0.5).sum()),
                      "max_z_in_contact": float(points[contact > 0.5, 2].max(initial=-1.0))}), flush=True)
    SaveScreenshot(screenshot, view, ImageResolution=[800, 600], TransparentBackground=0)


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), sys.argv[3])
