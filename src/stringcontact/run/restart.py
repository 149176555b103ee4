"""A run continued from a state: the whole state (η, v and every further unknown of the model) of a `Stepper`, of a
`Result`, or of a finished run's output folder (its ``rows.npz``), put back into the scene as ``eta0``, ``v0`` and
``fields0``, with the time left."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..scene import SceneWarning

__all__ = ["continued"]


def continued(scene, source, t: float | None = None):
    """`scene` from the state of `source` at the time `t` (default: its last): a `Stepper` (its state now), a `Result`
    or the path of an output folder (or of its ``rows.npz``) holding a stored row at `t`. The scene's T, nt and
    output times become the ones left; a 1D scene (its nodal values in the order of x). ValueError, naming the stored
    times, if `source` holds no row at `t`."""
    if hasattr(source, "core"):  # a Stepper: its state now, gathered in the order of `Result.x` (collective)
        fields = {name: source.gather(np.asarray(f)[source._order]) for name, f in source.scheme.fields.items()}
        eta, v, at, step = source.gather(source.eta), source.gather(source.velocity), source.t, source.step
    else:
        if isinstance(source, (str, Path)):
            from ..io.readback import read_output

            path = Path(source)
            source = read_output(path.parent if path.name.endswith(".npz") else path)
        times = np.asarray(source.t, dtype=float)
        k = len(times) - 1 if t is None else int(np.argmin(np.abs(times - t)))
        if t is not None and abs(times[k] - t) > 1e-9 * max(scene.T, 1.0):
            raise ValueError(f"t: {t:g} is not a stored time of the run; allowed: one of its {len(times)} stored times "
                             f"in [{times[0]:g}, {times[-1]:g}] (Result.t)")
        info = getattr(source, "field_info", {}) or {}
        fields = {name: rows[k] for name, rows in source.fields.items() if not info.get(name, {}).get("derived")}
        eta, v, at, step = source.eta[k], source.velocity[k], float(times[k]), int(source.steps[k])
    left = [s - at for s in scene.output_times if s > at + 1e-12 * scene.T]
    with warnings.catch_warnings():  # a state in contact is below the obstacle by the law's depth, as it ran
        warnings.simplefilter("ignore", SceneWarning)
        return scene.replace(eta0=np.asarray(eta), v0=np.asarray(v), T=scene.T - at, nt=scene.nt - step,
                             fields0={name: np.asarray(f) for name, f in fields.items()}, output_times=left)
