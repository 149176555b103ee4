"""The payload a run hands its picture process (`painter`): the Result in a private folder, each large array
as NumPy's .npy file that the painter and its helper map into memory, the rest pickled.

Files, not a pipe: writing to a pipe whose reader died raises SIGPIPE, which PETSc turns into an abort. A
module of its own so that `painter`, which the run imports first thing, does not import NumPy (`catalogue`).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import pickle
import time
from pathlib import Path

import numpy as np

#: arrays at least this large are handed over as .npy files mapped into memory (`np.load(mmap_mode="r")`):
#: pickling Example 1's 32 MB of rows and unpickling them in the painter took 0.06-0.12 s; mapping costs nothing
MAPPED_BYTES = 1 << 20


def write_payload(folder: Path, result, job: tuple) -> None:
    """`result` and `job` (output folder, window size, names) into `folder`: each large array of the Result
    as NumPy's .npy, the rest pickled; payload.pickle appears last and whole (os.replace), so a reader that
    sees it sees everything."""
    made = readings(result)
    result = dataclasses.replace(result, contact_force=np.empty((0, 0)))  # no picture shows it: less to write
    mapped = {f.name: getattr(result, f.name) for f in dataclasses.fields(result)
              if isinstance(getattr(result, f.name), np.ndarray) and getattr(result, f.name).nbytes >= MAPPED_BYTES}
    for name, values in mapped.items():
        np.save(folder / f"{name}.npy", values, allow_pickle=False)
    bare = dataclasses.replace(result, **dict.fromkeys(mapped))
    bare.__dict__.update(made)
    part = folder / "payload.part"
    with open(part, "wb") as f:
        pickle.dump((bare, tuple(mapped), job), f, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(part, folder / "payload.pickle")


def readings(result) -> dict:
    """The `cached_property` values `result` has computed already (contact_measure, contact_components: the run's
    diagnostics read them), so that the pictures do not compute them again (`dataclasses.replace` drops them):
    snapshots.png 0.25 against 0.26 s when its contact lengths come along (five runs each)."""
    cached = [name for name, attr in vars(type(result)).items() if isinstance(attr, functools.cached_property)]
    return {name: vars(result)[name] for name in cached if name in vars(result)}


def read_payload(folder: Path):
    """(result, job) of `write_payload`; the large arrays mapped read-only from their files."""
    with open(folder / "payload.pickle", "rb") as f:
        bare, mapped, job = pickle.load(f)
    arrays = {name: np.load(folder / f"{name}.npy", mmap_mode="r", allow_pickle=False) for name in mapped}
    result = dataclasses.replace(bare, **arrays)
    result.__dict__.update(readings(bare))
    return result, job


def await_payload(folder: Path, parent: int):
    """(result, job) once the payload is there; None if `parent` is gone or the folder removed first."""
    while not (folder / "payload.pickle").exists():
        if os.getppid() != parent or not folder.is_dir():
            return None
        time.sleep(0.005)
    return read_payload(folder)
