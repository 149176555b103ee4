"""VTK's start-up in this process: pyvista imported to draw off-screen (`_pyvista`: EGL where there is no
display), a plotter on a white background (`_plotter`), VTK's module search with each folder listed once
(`search_once`), and the font its text is drawn in (`_font_file`).

Every ``import vtkmodules.vtkX`` goes through VTK's own finder (``vtkmodules.VTKMetaHook``), which looks the
extension module up with ``vtkmodules.find_lib_path``: a ``Path.glob`` of the whole vtkmodules folder (543
files) per module and per extension (.pyd, then .so). pyvista's import and the first picture load 36 modules
that way. `search_once` swaps in the same search over a listing of each folder made once. The picture process
imports pyvista and draws its warm-up picture before it can draw anything, so this is on the way to the
first picture: CPU medians in fresh processes, VTK's search against this one (`benchmarks/bench_pictures.py
--vtk-search --repeats 12`), are in docs/explanation/performance.md.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

from .charts import without_axes3d_warning

#: VTK's own `find_lib_path`, kept by `search_once` (for the tests, which compare the two)
VTK_OWN = None


def search_once() -> bool:
    """Give VTK's finder `find_lib_path` (call before pyvista is imported; again costs nothing). Returns
    False, leaving VTK as it is, where VTK's finder is not the one `find_lib_path` mirrors (VTK 9.x's)."""
    global VTK_OWN
    try:
        import vtkmodules
    except ImportError:
        return False
    own = getattr(vtkmodules, "find_lib_path", None)
    if own is find_lib_path:
        return True
    if not callable(own) or getattr(vtkmodules, "LIB_EXTS", None) != [".pyd", ".so"]:
        return False
    VTK_OWN = own
    vtkmodules.find_lib_path = find_lib_path
    return True


@functools.cache
def _listing(folder: str) -> tuple[Path, ...]:
    try:
        return tuple(Path(folder).iterdir())  # the order Path.glob would see them in
    except OSError:  # as Path.glob: a missing folder holds nothing
        return ()


def find_lib_path(paths, vtk_module_name: str) -> str | None:
    """VTK's ``find_lib_path``: for each extension (.pyd, then .so) and each folder of `paths`, the first file
    named ``{vtk_module_name}.*`` or ``{vtk_module_name}-*`` (the glob ``{name}[.-]*``) whose resolved path
    is a file with that suffix, resolved; None if there is none."""
    for ext in (".pyd", ".so"):
        for base in paths:
            for f in _listing(str(base)):
                rest = f.name[len(vtk_module_name):]
                if f.name.startswith(vtk_module_name) and rest[:1] in (".", "-"):
                    resolved = f.resolve()
                    if resolved.is_file() and ext in resolved.suffixes:
                        return str(resolved)
    return None


def _font_file() -> str | None:
    """A TrueType font with Greek letters (VTK's built-in fonts have none): matplotlib's DejaVu Sans."""
    from matplotlib import font_manager

    try:
        return font_manager.findfont("DejaVu Sans", fallback_to_default=False)
    except ValueError:  # no such font: VTK's own, without Greek letters
        return None


#: VTK render windows that draw on an X server: without one, VTK 9 fails to make them and then crashes (SIGSEGV).
X_WINDOWS = ("vtkXOpenGLRenderWindow",)


def _pyvista():
    if "DISPLAY" not in os.environ:  # EGL needs no display; on a desktop VTK's default window works too
        window = os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        if window in X_WINDOWS:  # refused before VTK is asked: it would take the process down
            raise ValueError(f"VTK_DEFAULT_OPENGL_WINDOW={window} needs an X display and DISPLAY is not set; the "
                               "3-D pictures are left out (unset it, or set it to vtkEGLRenderWindow)")
    search_once()  # VTK's module search lists its folder once, not twice per module
    import pyvista as pv

    with without_axes3d_warning():  # pyvista's colour maps import matplotlib's projections
        import matplotlib.projections  # noqa: F401

    pv.OFF_SCREEN = True
    return pv


def _plotter(window_size, **layout):
    """An off-screen plotter; `layout`: pyvista's shape, groups, row_weights for several panels."""
    if layout:
        layout.setdefault("border", False)
    p = _pyvista().Plotter(window_size=list(window_size), off_screen=True, **layout)
    p.disable_anti_aliasing()  # pyvista's 8× MSAA: 0.71 s of llvmpipe's CPU for the surface instead of 0.39 s (bench_pictures.py)
    p.set_background("white")
    return p
