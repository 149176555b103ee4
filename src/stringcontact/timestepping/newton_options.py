"""The PETSc options a Newton step may be given: the tolerances that keep its stopping test meaningful and the line
searches it can run, checked before the mesh is built (one line naming the option and its allowed range)."""

from __future__ import annotations

from ..errors import SceneError

#: The largest tolerances Newton's stopping test may be given: above them it passes at once (snes_atol = 1e300
#: took the guess as the step's solution after 0 iterations: η = −2, the energy up 30 %, the run "complete").
SNES_TOLERANCE_MAX = {"snes_atol": 1e-6, "snes_rtol": 1e-2, "snes_stol": 1e-2}
#: The line searches a Newton step may take: "shell" needs a function of the caller's (PETSc stops with error 83),
#: and the error-oriented "nleqerr" does not take the bounds of a variational inequality (`VI_LINESEARCHES`).
LINESEARCHES = ("bt", "basic", "l2", "cp", "nleqerr")
VI_LINESEARCHES = ("bt", "basic", "l2", "cp")


def check_snes_options(options: dict, key: str = "petsc_options") -> None:
    """SceneError (one line naming the option and its allowed range, before the mesh) for a Newton tolerance that
    makes its stopping test vacuous (`SNES_TOLERANCE_MAX`), < 1 iteration, or a line search it cannot run."""
    for name, high in SNES_TOLERANCE_MAX.items():
        value = options.get(name)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and not 0 <= value <= high:
            raise SceneError(f"{key}: {name} = {value:g} is out of range; allowed: a number in [0, {high:g}] (a "
                             "larger one passes Newton's stopping test without solving the step)")
    iterations = options.get("snes_max_it")
    if isinstance(iterations, int) and not isinstance(iterations, bool) and iterations < 1:
        raise SceneError(f"{key}: snes_max_it = {iterations} is out of range; allowed: an integer in [1, 1000]")
    search = options.get("snes_linesearch_type")
    if search is not None and search not in LINESEARCHES:
        raise SceneError(f"{key}: snes_linesearch_type = {search!r} is not a line search a Newton step can take "
                         f"(it needs code or is unknown); allowed: {', '.join(LINESEARCHES)}")


def check_vi_linesearch(options: dict) -> None:
    """SceneError for a line search without bounds in a VI's step (a field bounded below, `Model.field_lower`)."""
    search = options.get("snes_linesearch_type")
    if search is not None and search not in VI_LINESEARCHES:
        raise SceneError(f"petsc_options: snes_linesearch_type = {search!r} does not take the bounds of this model's "
                         f"step (a variational inequality: a field bounded below); allowed: {', '.join(VI_LINESEARCHES)}")


__all__ = ["LINESEARCHES", "SNES_TOLERANCE_MAX", "VI_LINESEARCHES", "check_snes_options", "check_vi_linesearch"]
