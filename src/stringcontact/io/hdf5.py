"""`Hdf5File`: flat datasets written by ctypes through the libhdf5 dolfinx loaded. Hand-written
(docs/explanation/visualisation.md): h5py's wheel brings a second libhdf5 ("Not a datatype" after dolfinx), PETSc's
viewer fsyncs every dataset (412 fsyncs for ``run example1``, 9 with this: `bench_xdmf.py`), dolfinx's `XDMFFile`
writes a grid per function and its XML anew every frame."""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import errno
import functools
import os
import re
import sys
from pathlib import Path

import numpy as np

#: HDF5's constants, the same in 1.10 and 1.14 (H5Fpublic.h, H5Dpublic.h, H5Ppublic.h, H5Spublic.h).
H5F_ACC_TRUNC, H5P_DEFAULT, H5S_ALL, H5F_SCOPE_LOCAL, H5F_CLOSE_STRONG, H5D_ALLOC_TIME_EARLY = 2, 0, 0, 0, 3, 1
#: NumPy dtype -> the name of HDF5's native type (a global hid_t, set by H5open).
H5_NATIVE = {np.dtype(np.float64): "H5T_NATIVE_DOUBLE_g", np.dtype(np.int32): "H5T_NATIVE_INT32_g",
             np.dtype(np.int64): "H5T_NATIVE_INT64_g"}


@functools.cache
def hdf5_library():
    """The libhdf5 dolfinx and PETSc loaded (/proc/self/maps) through ctypes, errno kept per call; None if none."""
    try:
        with open("/proc/self/maps") as f:
            found = re.findall(r"(/\S*/libhdf5(?:_[a-z]+)?\.so[.\d]*)$", f.read(), re.MULTILINE)
        paths = sorted(p for p in set(found) if "_hl" not in os.path.basename(p) and ".libs/" not in p)
        if not paths:
            return None
        lib = ctypes.CDLL(paths[0], use_errno=True)
        hid, herr, sizes, ptr = ctypes.c_int64, ctypes.c_int, ctypes.POINTER(ctypes.c_uint64), ctypes.c_void_p
        signatures = {
            "H5Eget_auto2": (herr, [hid, ctypes.POINTER(ptr), ctypes.POINTER(ptr)]), "H5Eset_auto2": (herr, [hid, ptr, ptr]),
            "H5open": (herr, []), "H5Pcreate": (hid, [hid]), "H5Pset_fapl_sec2": (herr, [hid]),
            "H5Pset_fclose_degree": (herr, [hid, ctypes.c_int]),
            "H5Pset_file_locking": (herr, [hid, ctypes.c_bool, ctypes.c_bool]),
            "H5Pset_chunk": (herr, [hid, ctypes.c_int, sizes]), "H5Pset_alloc_time": (herr, [hid, ctypes.c_int]),
            "H5Pclose": (herr, [hid]), "H5Fcreate": (hid, [ctypes.c_char_p, ctypes.c_uint, hid, hid]),
            "H5Fflush": (herr, [hid, ctypes.c_int]), "H5Fget_eoa": (herr, [hid, sizes]),
            "H5Fget_vfd_handle": (herr, [hid, hid, ctypes.POINTER(ptr)]), "H5Fclose": (herr, [hid]),
            "H5Screate_simple": (hid, [ctypes.c_int, sizes, sizes]), "H5Sclose": (herr, [hid]),
            "H5Dcreate2": (hid, [hid, ctypes.c_char_p, hid, hid, hid, hid, hid]),
            "H5Dwrite": (herr, [hid, hid, hid, hid, hid, ptr]), "H5Dclose": (herr, [hid])}
        for name, (restype, argtypes) in signatures.items():
            getattr(lib, name).restype, getattr(lib, name).argtypes = restype, argtypes
        return lib
    except (OSError, AttributeError):
        return None


@functools.cache
def _silence_exit() -> None:
    """After a failed H5Fcreate, stderr to /dev/null at exit: libhdf5 1.10.8 then prints "HDF5: infinite loop closing
    library" after the command's one line (8-11 KiB free, test_reliability_output.py with the room check off)."""

    def silence():
        with contextlib.suppress(Exception):
            sys.stderr.flush()
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), 2)

    atexit.register(silence)


def _quiet(method):
    """HDF5's error printing off while `method` runs (once per method: per call cost 13 % of 400 datasets' writing)."""

    @functools.wraps(method)
    def quietly(self, *args):
        lib, printer, data = hdf5_library(), ctypes.c_void_p(), ctypes.c_void_p()
        saved = lib is not None and lib.H5Eget_auto2(0, ctypes.byref(printer), ctypes.byref(data)) >= 0  # H5E_DEFAULT
        if saved:
            lib.H5Eset_auto2(0, None, None)
        try:
            return method(self, *args)
        finally:
            if saved:
                lib.H5Eset_auto2(0, printer, data)

    return quietly


class Hdf5File:
    """A new HDF5 file at `path` in PETSc's HDF5 viewer's layout. A failed call raises OSError with the system call's
    errno (ENOSPC on a full disk), else RuntimeError naming the HDF5 function."""

    @_quiet
    def __init__(self, path):
        self.path, self.lib, self.id, self.layouts, self.reserved = Path(path), hdf5_library(), None, {}, 0
        if self.lib is None:
            raise RuntimeError(f"{self.path.name}: the libhdf5 that dolfinx loaded was not found")
        self._call("H5open")  # sets the globals read below
        self.types = {dtype: self._global(name) for dtype, name in H5_NATIVE.items()}
        fapl = self._call("H5Pcreate", self._global("H5P_CLS_FILE_ACCESS_ID_g"))
        try:
            self._call("H5Pset_fapl_sec2", fapl)  # not MPI-IO, whatever HDF5_DRIVER says
            self._call("H5Pset_fclose_degree", fapl, H5F_CLOSE_STRONG)  # closing the file closes all in it
            self._call("H5Pset_file_locking", fapl, False, True)  # sec2 would lock out readers during the run
            self.id = self._call("H5Fcreate", os.fsencode(self.path), H5F_ACC_TRUNC, H5P_DEFAULT, fapl)
        except (OSError, RuntimeError):
            _silence_exit()
            raise
        finally:
            self.lib.H5Pclose(fapl)
        handle = ctypes.c_void_p()  # sec2's handle: a pointer to the file's descriptor
        try:
            self._call("H5Fget_vfd_handle", self.id, H5P_DEFAULT, ctypes.byref(handle))
        except (OSError, RuntimeError):
            self.lib.H5Fclose(self.id)
            raise
        self.fd = ctypes.cast(handle, ctypes.POINTER(ctypes.c_int)).contents.value

    def _global(self, name: str) -> int:
        return ctypes.c_int64.in_dll(self.lib, name).value

    def _call(self, name: str, *args) -> int:
        """HDF5's `name(*args)`, a negative value raised."""
        ctypes.set_errno(0)
        value = getattr(self.lib, name)(*args)
        if value < 0:
            err = ctypes.get_errno()
            if err:
                raise OSError(err, os.strerror(err), str(self.path))
            raise RuntimeError(f"HDF5's {name} failed on {self.path}")
        return value

    def _layout(self, shape: tuple) -> tuple[int, int]:
        """The dataspace and creation properties (one chunk, allocated at creation) of a shape, made once."""
        if shape not in self.layouts:
            dims = (ctypes.c_uint64 * len(shape))(*shape)
            self.layouts[shape] = (self._call("H5Screate_simple", len(shape), dims, None), H5P_DEFAULT)
            dcpl = self._call("H5Pcreate", self._global("H5P_CLS_DATASET_CREATE_ID_g"))
            self.layouts[shape] = (self.layouts[shape][0], dcpl)
            self._call("H5Pset_chunk", dcpl, len(shape), dims)
            self._call("H5Pset_alloc_time", dcpl, H5D_ALLOC_TIME_EARLY)
        return self.layouts[shape]

    @_quiet
    def write(self, name: str, array: np.ndarray) -> None:
        """The dataset `/name`: `array`'s shape and values."""
        array = np.ascontiguousarray(array)
        (space, dcpl), dtype = self._layout(array.shape), self.types[array.dtype]
        dataset = self._call("H5Dcreate2", self.id, name.encode(), dtype, space, H5P_DEFAULT, dcpl, H5P_DEFAULT)
        try:
            self._call("H5Dwrite", dataset, dtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, array.ctypes.data)
        finally:
            self._call("H5Dclose", dataset)

    def _reserve(self) -> None:
        """Allocate up to HDF5's end of allocation before a flush, so that a full disk fails here, the file still
        closable: after a failed flush libhdf5 1.10.8 crashed at exit for 148 of 249 disk sizes (test_xdmf.py)."""
        eoa = ctypes.c_uint64()
        self._call("H5Fget_eoa", self.id, ctypes.byref(eoa))
        if self.reserved is not None and eoa.value > self.reserved:
            try:
                os.posix_fallocate(self.fd, self.reserved, eoa.value - self.reserved)
            except OSError as exc:
                if exc.errno not in (errno.EOPNOTSUPP, errno.EINVAL, errno.ENOSYS):
                    raise OSError(exc.errno, exc.strerror, str(self.path)) from None
                self.reserved = None  # a file system that cannot: plain flushes
                return
            self.reserved = eoa.value

    @_quiet
    def flush(self) -> None:
        """Everything written so far to the OS (no fsync: the folder is fsynced when published)."""
        self._reserve()
        self._call("H5Fflush", self.id, H5F_SCOPE_LOCAL)

    @_quiet
    def close(self) -> None:
        """Close the file (its last flush); kept open if that fails, for `discard`."""
        if self.id is not None:
            self._reserve()
            self._call("H5Fclose", self.id)
            self.id = None
        self._release_layouts()

    @_quiet
    def discard(self) -> None:
        """Close a file about to be removed, whatever room is left (its descriptor pointed at a memory file first)."""
        if self.id is not None:
            with contextlib.suppress(OSError):
                scratch = os.memfd_create("discarded.h5")
                os.dup2(scratch, self.fd)
                os.close(scratch)
            with contextlib.suppress(OSError, RuntimeError):
                self._call("H5Fclose", self.id)
            self.id = None
        self._release_layouts()

    def _release_layouts(self) -> None:
        for space, dcpl in self.layouts.values():
            self.lib.H5Sclose(space)
            if dcpl != H5P_DEFAULT:
                self.lib.H5Pclose(dcpl)
        self.layouts = {}
