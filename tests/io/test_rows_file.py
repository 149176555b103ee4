"""rows.npz as `tables.write_rows` writes it: NumPy's bytes in every member, the compressed ones at zlib level 1."""

from __future__ import annotations

import io
import struct
import zipfile
import zlib
from types import SimpleNamespace

import numpy as np
import pytest
from numpy.lib import format as npy

from stringcontact.io import tables

RNG = np.random.default_rng(7)

ARRAYS = {
    "rows of floats": RNG.standard_normal((37, 53)),
    "a bool mask": RNG.random((37, 53)) < 0.3,
    "steps": np.arange(0, 1500, 4, dtype=np.int64),
    "no rows": np.zeros((0, 5)),
    "one value": np.array([2.5]),
    "a column (not contiguous)": RNG.standard_normal((9, 4))[:, 1],
}


@pytest.mark.parametrize("name", ARRAYS)
def test_write_npy_writes_numpys_bytes(name):
    a = ARRAYS[name]
    ours, numpys = io.BytesIO(), io.BytesIO()
    tables.write_npy(ours, a)
    npy.write_array(numpys, a, allow_pickle=False)
    assert ours.getvalue() == numpys.getvalue()


def _rows(nodes=400, rows=60):
    force = np.where(RNG.random((rows, nodes)) < 0.2, RNG.standard_normal((rows, nodes)), 0.0)
    return SimpleNamespace(t=np.linspace(0, 1, rows), steps=np.arange(rows) * 4, x=np.linspace(0, 1, nodes), dim=1,
                           eta=RNG.standard_normal((rows, nodes)), velocity=RNG.standard_normal((rows, nodes)),
                           contact=force != 0, contact_force=force)


def _raw(path, info: zipfile.ZipInfo) -> bytes:
    """A member's bytes as stored in the file (compressed): past its local header (APPNOTE 4.3.7: 30 bytes, then the
    name and extra fields)."""
    with open(path, "rb") as f:
        f.seek(info.header_offset)
        local = f.read(30)
        assert local[:4] == b"PK\x03\x04"
        f.seek(info.header_offset + 30 + sum(struct.unpack("<HH", local[26:30])))
        return f.read(info.compress_size)


def _deflated(data: bytes, level: int) -> bytes:
    c = zlib.compressobj(level, zlib.DEFLATED, -15)  # zipfile's raw deflate
    return c.compress(data) + c.flush()


def test_rows_npz_holds_the_arrays_with_contact_and_force_deflated_at_level_1(tmp_path):
    res = _rows()
    path = tmp_path / tables.ROWS_FILE
    tables.write_rows(path, res)
    with np.load(path) as npz:
        for name in ("t", "steps", "x", *tables.FIELDS):
            assert np.array_equal(npz[name], getattr(res, name)), name
    with zipfile.ZipFile(path) as archive:
        kinds = {info.filename: info.compress_type for info in archive.infolist()}
        assert kinds["eta.npy"] == kinds["velocity.npy"] == zipfile.ZIP_STORED
        for name in ("contact.npy", "contact_force.npy"):
            info = archive.getinfo(name)
            assert info.compress_type == zipfile.ZIP_DEFLATED
            data, raw = archive.read(name), _raw(path, info)
            assert _deflated(data, 6) != _deflated(data, 1)  # the levels tell apart on these rows
            assert raw == _deflated(data, tables.ZLIB_LEVEL) and tables.ZLIB_LEVEL == 1, name
