"""VTK's module search with each folder listed once, and the font its text is drawn in (`_font_file`).

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
from pathlib import Path

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
