"""pyvista in this process: off-screen (EGL where there is no display, `_pyvista`), a plotter on a white background
(`_plotter`), and the font its text is drawn in (`_font_file`)."""

from __future__ import annotations

import os


def _pyvista():
    if "DISPLAY" not in os.environ:  # VTK 9.7 would try X first and print "bad X server connection" before EGL
        window = os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        if window == "vtkXOpenGLRenderWindow":  # without a display VTK fails to make it, then crashes (SIGSEGV)
            raise ValueError(f"VTK_DEFAULT_OPENGL_WINDOW={window} needs an X display and DISPLAY is not set; the "
                             "3-D pictures are left out (unset it, or set it to vtkEGLRenderWindow)")
    from .charts import without_axes3d_warning

    with without_axes3d_warning():  # pyvista's colour maps import matplotlib's projections
        import matplotlib.projections  # noqa: F401
        import pyvista

    return pyvista


def _plotter(window_size):
    """An off-screen plotter `window_size` pixels large, on white, that takes empty meshes (an empty contact edge)."""
    p = _pyvista().Plotter(window_size=list(window_size), off_screen=True)
    p.theme.allow_empty_mesh = True
    p.disable_anti_aliasing()  # pyvista's 8× MSAA: the surface in 0.71, not 0.39 CPU-s of llvmpipe (bench_pictures.py)
    p.set_background("white")
    return p


def _font_file() -> str | None:
    """A TrueType font with Greek letters (VTK's built-in fonts have none): matplotlib's DejaVu Sans."""
    from matplotlib import font_manager

    try:
        return font_manager.findfont("DejaVu Sans", fallback_to_default=False)
    except ValueError:  # no such font: VTK's own, without Greek letters
        return None
