"""The README's ParaView recipe, run by ParaView itself:
`xvfb-run -a -s "-screen 0 1280x1024x24 -noreset" pvpython tests/system/paraview_readme.py XDMF TIME PNG`.

For each reader (Xdmf3ReaderT, Xdmf3ReaderS, XDMFReader): open solution.xdmf, Warp By Scalar with
Scalars = eta and Normal = (0, 1, 0), colour by contact, Line Width 3, go to time TIME. Prints one JSON line
per reader with what ParaView shows there (each point array's range at TIME among it); saves a screenshot of
the Xdmf3ReaderT view to PNG.
tests/system/test_paraview.py runs it and checks the numbers against the solver's own.
"""

import json
import sys

from paraview import servermanager
from paraview.simple import (
    ColorBy,
    CreateView,
    GetAnimationScene,
    SaveScreenshot,
    Show,
    WarpByScalar,
    Xdmf3ReaderS,
    Xdmf3ReaderT,
    XDMFReader,
)
from vtk.util.numpy_support import vtk_to_numpy


def readme_pipeline(reader, path, t, screenshot=None):
    # File -> Open solution.xdmf, pick the reader, Apply
    source = reader(FileNames=[path]) if reader is XDMFReader else reader(FileName=[path])
    GetAnimationScene().UpdateAnimationUsingDataTimeSteps()
    # Filters -> Warp By Scalar: Scalars = eta, Normal = (0, 1, 0), Apply
    warp = WarpByScalar(Input=source, Scalars=["POINTS", "eta"], Normal=[0.0, 1.0, 0.0])
    view = CreateView("RenderView")
    view.ViewSize = [900, 450]
    display = Show(warp, view)
    # Colour by contact; Styling -> Line Width 3
    ColorBy(display, ("POINTS", "contact"))
    display.RescaleTransferFunctionToDataRange(True, False)
    display.LineWidth = 3.0
    # the time controls: go to time t
    GetAnimationScene().AnimationTime = t
    view.ViewTime = t
    view.ResetCamera()
    warp.UpdatePipeline(t)
    data = servermanager.Fetch(warp)
    report = describe(data, source, warp, t)
    if screenshot:
        SaveScreenshot(screenshot, view, ImageResolution=[900, 450], TransparentBackground=0)
    report["reader"] = reader.__name__
    return report


def describe(data, source, warp, t):
    """What the warped string carries at time t."""
    point_data = data.GetPointData()
    arrays = [point_data.GetArrayName(i) for i in range(point_data.GetNumberOfArrays())]
    y = vtk_to_numpy(data.GetPoints().GetData())[:, 1]
    out = {"class": data.GetClassName(), "points": data.GetNumberOfPoints(), "arrays": arrays,
           "ranges": {name: list(point_data.GetArray(name).GetRange()) for name in arrays},
           "times": list(source.TimestepValues), "time": t}
    if "contact" in arrays and "eta" in arrays:
        contact, eta = vtk_to_numpy(point_data.GetArray("contact")), vtk_to_numpy(point_data.GetArray("eta"))
        out.update(contact_fraction=float(contact.mean()), max_y_in_contact=float(y[contact > 0.5].max(initial=-1.0)),
                   max_warp_error=float(abs(y - eta).max()), eta_type=point_data.GetArray("eta").GetDataTypeAsString(),
                   contact_range=list(warp.PointData["contact"].GetRange()))
    return out


def main(path, t, screenshot):
    for reader in (Xdmf3ReaderT, Xdmf3ReaderS, XDMFReader):
        print(json.dumps(readme_pipeline(reader, path, t, screenshot if reader is Xdmf3ReaderT else None)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), sys.argv[3])
