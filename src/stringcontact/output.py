"""Results on disk: `solution.xdmf`/`.h5`, `diagnostics.csv` and `summary.json`.

Everything is written into a hidden folder beside the target and renamed into place at the end,
so a target folder is either absent, complete, or explicitly marked `interrupted`/`unstable`.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import time
from pathlib import Path

import dolfinx
import numpy as np
from dolfinx import fem
from dolfinx.io import XDMFFile

FIELDS = ("eta", "velocity", "contact", "contact_force")


class OutputError(RuntimeError):
    """The output folder cannot be used (not empty, not writable, disk full)."""


def check_target(path, force: bool) -> Path:
    """Refuse a non-empty folder unless `force`; refuse a path that is a file."""
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise OutputError(f"--out {target}: exists and is not a folder")
    if target.is_dir() and any(target.iterdir()) and not force:
        raise OutputError(f"--out {target}: folder is not empty; choose another or pass --force to replace it")
    return target


class OutputWriter:
    """Streams the stored rows to XDMF during the run and writes the tables at the end."""

    def __init__(self, path, scene, V, comm, force: bool = False, pictures: bool = True):
        self.comm = comm
        self.pictures = pictures
        self.scene = scene
        self.target = check_target(path, force).resolve()
        self.partial = self.target.parent / f".{self.target.name}.partial"
        self.write_time = 0.0
        if comm.rank == 0:
            try:
                self.target.parent.mkdir(parents=True, exist_ok=True)
                shutil.rmtree(self.partial, ignore_errors=True)
                self.partial.mkdir()
            except OSError as exc:
                raise OutputError(f"--out {self.target}: cannot create the output folder ({exc.strerror})") from None
        comm.barrier()
        self.functions = {}
        for name in FIELDS:
            u = fem.Function(V)
            u.name = name
            self.functions[name] = u
        self.n_owned = V.dofmap.index_map.size_local
        self.xdmf = XDMFFile(comm, str(self.partial / "solution.xdmf"), "w")
        self.xdmf.write_mesh(V.mesh)

    def write(self, t: float, fields: dict) -> None:
        t0 = time.perf_counter()
        for name, values in fields.items():
            u = self.functions[name]
            u.x.array[: self.n_owned] = values
            u.x.scatter_forward()
            self.xdmf.write_function(u, t)
        self.write_time += time.perf_counter() - t0

    def _close(self, summary: dict, result=None) -> None:
        self.xdmf.close()
        if self.comm.rank == 0:
            if result is not None:
                write_diagnostics(self.partial / "diagnostics.csv", result)
                if self.pictures:
                    from .viz import write_pictures  # pictures on rank 0 only

                    t0 = time.perf_counter()
                    write_pictures(result, self.partial)
                    summary.setdefault("timings", {})["pictures"] = time.perf_counter() - t0
            with open(self.partial / "summary.json", "w") as f:
                json.dump(summary, f, indent=2, default=_jsonable)
            if self.target.exists():
                shutil.rmtree(self.target)
            os.replace(self.partial, self.target)
        self.comm.barrier()

    def finish(self, result) -> None:
        self._close(summary_dict(result), result)

    def abort(self, status: str, message: str) -> None:
        self._close({"status": status, "message": message, "scene": self.scene.as_dict()})


def _jsonable(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


DIAGNOSTIC_COLUMNS = (
    "step",
    "t",
    "kinetic",
    "elastic",
    "viscous_dissipation",
    "contact_dissipation",
    "numerical_dissipation",
    "external_work",
    "balance_residual",
    "min_eta",
    "contact_length",
    "max_contact_force",
)


def write_diagnostics(path: Path, result) -> None:
    cols = {
        "step": result.steps,
        "t": result.t,
        **result.energy,
        "balance_residual": result.balance_residual,
        "min_eta": result.eta.min(axis=1),
        "contact_length": result.contact_length,
        "max_contact_force": result.contact_force.max(axis=1),
    }
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(DIAGNOSTIC_COLUMNS)
        for i in range(len(result.t)):
            w.writerow([int(cols[c][i]) if c == "step" else repr(float(cols[c][i])) for c in DIAGNOSTIC_COLUMNS])


def summary_dict(result) -> dict:
    scene = result.scene
    return {
        "status": result.status,
        "message": result.message,
        "scene": scene.as_dict(),
        "penalty": result.penalty,
        "mass": result.mass,
        "model": result.model,
        "r": scene.dt / scene.eps,
        "dolfinx": dolfinx.__version__,
        "timings": result.timings,
        "min_eta": result.min_eta,
        "stored_rows": len(result.t),
        "final_energy": {k: float(v[-1]) for k, v in result.energy.items()},
        "initial_energy": float(result.total_energy[0]),
        "max_abs_balance_residual": float(np.max(np.abs(result.balance_residual))),
    }
