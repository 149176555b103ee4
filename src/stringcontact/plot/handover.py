"""The payload a run hands its picture process (`picture_process`): the Result in a private folder, each large array
(an output field's of `Result.fields` too) as NumPy's .npy file that the painter and its helper map into memory,
the rest pickled.

Files, not a pipe: writing to a pipe whose reader died raises SIGPIPE, which PETSc turns into an abort. A
module of its own so that `picture_process`, which the run imports first thing, does not import NumPy (`picture_names`).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import pickle
import struct
import time
import zipfile
from pathlib import Path

import numpy as np
from numpy.lib import format as npy

from ..io.tables import ROWS_FILE, member_offset

#: arrays at least this large are handed over as .npy files mapped into memory (`np.load(mmap_mode="r")`):
#: pickling Example 1's 32 MB of rows and unpickling them in the painter took 0.06-0.12 s; mapping costs nothing
MAPPED_BYTES = 1 << 20


def write_payload(folder: Path, result, job: tuple) -> None:
    """`result` and `job` (output folder, window size, names) into `folder`: each large array of the Result
    mapped from the output folder's rows.npz where that holds it uncompressed (`stored_in`), else written as
    NumPy's .npy; the rest pickled. payload.pickle appears last and whole (os.replace), so a reader that sees
    it sees everything."""
    made = readings(result)
    result = dataclasses.replace(result, contact_force=np.empty((0, 0)))  # no picture shows it: less to write
    large = {f.name: getattr(result, f.name) for f in dataclasses.fields(result)
             if isinstance(getattr(result, f.name), np.ndarray) and getattr(result, f.name).nbytes >= MAPPED_BYTES}
    where = stored_in(Path(job[0]) / ROWS_FILE, large)
    for name, values in large.items():
        if name not in where:
            np.save(folder / f"{name}.npy", values, allow_pickle=False)
            where[name] = None
    bare = dataclasses.replace(result, **dict.fromkeys(large), fields=_fields_apart(folder, result.fields))
    bare.__dict__.update(made)
    part = folder / "payload.part"
    with open(part, "wb") as f:
        pickle.dump((bare, where, job), f, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(part, folder / "payload.pickle")


def _fields_apart(folder: Path, fields: dict) -> dict:
    """The output fields with each large array written to ``fields.NAME.npy`` in `folder` and left as None
    (`read_payload` maps it back)."""
    kept = {}
    for name, values in fields.items():
        large = isinstance(values, np.ndarray) and values.nbytes >= MAPPED_BYTES
        if large:
            np.save(folder / f"fields.{name}.npy", values, allow_pickle=False)
        kept[name] = None if large else values
    return kept


def stored_in(npz: Path, arrays: dict) -> dict:
    """Where the .npz file `npz` (the run's rows.npz, written just before) holds each of `arrays` as it is:
    name -> (path, offset, dtype, shape, order) of its uncompressed member of the same dtype and shape.

    Mapping eta and velocity from there spares writing Example 1's 30 MB a second time: the run's hand-over to
    its pictures took 0.05-0.07 s of its critical path (docs/explanation/performance.md). The offset is the member's data
    in the zip (`tables.member_offset`) past the .npy header (`numpy.lib.format`). Members that are
    compressed, absent, or differ are left out: they are written."""
    found = {}
    try:
        with zipfile.ZipFile(npz) as archive, open(npz, "rb") as raw:
            for name, values in arrays.items():
                info = archive.NameToInfo.get(f"{name}.npy")
                if info is None or info.compress_type != zipfile.ZIP_STORED:
                    continue
                offset = member_offset(raw, info)
                if offset is None:
                    continue
                raw.seek(offset)
                version = npy.read_magic(raw)
                read_header = npy.read_array_header_1_0 if version == (1, 0) else npy.read_array_header_2_0
                shape, fortran, dtype = read_header(raw)
                if shape == values.shape and dtype == values.dtype and not dtype.hasobject:
                    found[name] = (str(npz), raw.tell(), dtype.str, shape, "F" if fortran else "C")
    except (OSError, ValueError, zipfile.BadZipFile, struct.error):
        return {}
    return found


def readings(result) -> dict:
    """The `cached_property` values `result` has computed already (contact_measure, contact_components: the run's
    diagnostics read them), so that the pictures do not compute them again (`dataclasses.replace` drops them):
    snapshots.png 0.25 against 0.26 s when its contact lengths come along (five runs each)."""
    cached = [name for name, attr in vars(type(result)).items() if isinstance(attr, functools.cached_property)]
    return {name: vars(result)[name] for name in cached if name in vars(result)}


def read_payload(folder: Path):
    """(result, job) of `write_payload`; the large arrays mapped read-only from their files."""
    with open(folder / "payload.pickle", "rb") as f:
        bare, where, job = pickle.load(f)
    arrays = {name: np.load(folder / f"{name}.npy", mmap_mode="r", allow_pickle=False) if at is None
              else np.memmap(at[0], dtype=np.dtype(at[2]), mode="r", offset=at[1], shape=at[3], order=at[4])
              for name, at in where.items()}
    fields = {name: np.load(folder / f"fields.{name}.npy", mmap_mode="r", allow_pickle=False) if values is None else values
              for name, values in bare.fields.items()}
    result = dataclasses.replace(bare, **arrays, fields=fields)
    result.__dict__.update(readings(bare))
    return result, job


def await_payload(folder: Path, parent: int):
    """(result, job) once the payload is there; None if `parent` is gone or the folder removed first."""
    while not (folder / "payload.pickle").exists():
        if os.getppid() != parent or not folder.is_dir():
            return None
        time.sleep(0.005)
    return read_payload(folder)
