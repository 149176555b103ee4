"""libhdf5 through ctypes: the library dolfinx and PETSc loaded (`hdf5_library`), a file of flat datasets written
with its sec2 driver (`Hdf5File`), its error printing switched off (`Hdf5Quiet`) and what C libraries print to
stderr held back (`stderr_held`). `io.xdmf` writes `solution.h5` with it.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import os
import re
import sys
import tempfile
from pathlib import Path

import numpy as np


@functools.cache
def _silence_exit_later() -> None:
    """Point stderr at /dev/null when the process ends (once registered, after a failed H5Fcreate).

    libhdf5 1.10.8 leaks what a failed H5Fcreate opened (a full disk: measured with 8 and 10 KiB free on
    a 2 MiB tmpfs and the room check off), and prints ``HDF5: infinite loop closing library`` and a line
    of its interfaces when the process ends (H5close, from MPI_Finalize or C's atexit). The command has
    reported its one-line error by then. Registered after petsc4py's own atexit handler, so it runs first.
    """
    import atexit

    atexit.register(_silence_exit)


def _silence_exit() -> None:
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    with contextlib.suppress(OSError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 2)
        os.close(devnull)


@functools.cache
def hdf5_library():
    """The libhdf5 that dolfinx and PETSc loaded (not h5py's bundled copy), through ctypes; None if not found.

    Kept hand-written rather than h5py, measured on bookworm (dolfinx 0.5, libhdf5_openmpi 1.10.8):

    * in the .venv, ``import h5py`` after dolfinx gets the h5py wheel (the tests' meshio needs it; built
      against HDF5 2.0.0) and fails at import: "ValueError: Not a datatype" in h5t, with a warning that it
      runs against HDF5 1.10.8: two libhdf5 versions do not share one process;
    * Debian's h5py (python3-h5py-mpi 3.7.0) picks its serial build unless OMPI_COMM_WORLD_SIZE or
      H5PY_ALWAYS_USE_MPI is set, and the serial build loads libhdf5_serial beside PETSc's libhdf5_openmpi:
      its error switch and object lists would act on the other library. Even the MPI build silences HDF5's
      error printing for the whole process at import (no saved handler to put back, as `Hdf5Quiet` does),
      and its object ids close what they wrap when collected, which PETSc's viewer still owns.

    The signatures are those of HDF5 1.10 and 1.14 alike (hid_t is int64_t, hsize_t unsigned long long,
    herr_t int); errno is kept per call (``use_errno``) so that a failed write can say why (`Hdf5File`).
    """
    try:
        with open("/proc/self/maps") as f:
            paths = set(re.findall(r"(/\S*/libhdf5(?:_[a-z]+)?\.so[.\d]*)$", f.read(), re.MULTILINE))
        paths = sorted(p for p in paths if "_hl" not in os.path.basename(p) and ".libs/" not in p)
        if not paths:
            return None
        lib = ctypes.CDLL(paths[0], use_errno=True)
        hid, herr, hsizes = ctypes.c_int64, ctypes.c_int, ctypes.POINTER(ctypes.c_uint64)
        signatures = {
            "H5Eget_auto2": (herr, [hid, ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_void_p)]),
            "H5Eset_auto2": (herr, [hid, ctypes.c_void_p, ctypes.c_void_p]),
            "H5open": (herr, []),
            "H5Pcreate": (hid, [hid]),
            "H5Pset_fapl_sec2": (herr, [hid]),
            "H5Pset_fclose_degree": (herr, [hid, ctypes.c_int]),
            "H5Pset_file_locking": (herr, [hid, ctypes.c_bool, ctypes.c_bool]),
            "H5Pset_evict_on_close": (herr, [hid, ctypes.c_uint]),
            "H5Pset_chunk": (herr, [hid, ctypes.c_int, hsizes]),
            "H5Pset_alloc_time": (herr, [hid, ctypes.c_int]),
            "H5Pclose": (herr, [hid]),
            "H5Fcreate": (hid, [ctypes.c_char_p, ctypes.c_uint, hid, hid]),
            "H5Fflush": (herr, [hid, ctypes.c_int]),
            "H5Fget_eoa": (herr, [hid, ctypes.POINTER(ctypes.c_uint64)]),
            "H5Fget_vfd_handle": (herr, [hid, hid, ctypes.POINTER(ctypes.c_void_p)]),
            "H5Fclose": (herr, [hid]),
            "H5Screate_simple": (hid, [ctypes.c_int, hsizes, hsizes]),
            "H5Sclose": (herr, [hid]),
            "H5Dcreate2": (hid, [hid, ctypes.c_char_p, hid, hid, hid, hid, hid]),
            "H5Dwrite": (herr, [hid, hid, hid, hid, hid, ctypes.c_void_p]),
            "H5Dclose": (herr, [hid]),
        }
        for name, (restype, argtypes) in signatures.items():
            func = getattr(lib, name)
            func.restype, func.argtypes = restype, argtypes
        return lib
    except (OSError, AttributeError):
        return None


class Hdf5Quiet:
    """Turns HDF5's automatic error printing off while the writer runs.

    On a full disk, HDF5 prints a 60-line error stack to stderr before the failed call returns (an OSError);
    we report one line instead (`describe_os_error`). The switch is HDF5's own H5Eset_auto2 on the libhdf5
    that dolfinx and PETSc loaded (not h5py's bundled copy); where it cannot be found nothing changes.
    """

    @classmethod
    def _library(cls):
        return hdf5_library()

    def __init__(self):
        self.saved = None

    def __enter__(self):
        lib = self._library()
        if lib is not None:
            func, data = ctypes.c_void_p(), ctypes.c_void_p()
            if lib.H5Eget_auto2(0, ctypes.byref(func), ctypes.byref(data)) >= 0:  # 0 is H5E_DEFAULT
                self.saved = (func, data)
                lib.H5Eset_auto2(0, None, None)
        return self

    def __exit__(self, *exc):
        if self.saved is not None:
            self._library().H5Eset_auto2(0, self.saved[0], self.saved[1])
            self.saved = None
        return False


#: HDF5's constants, the same in 1.10 and 1.14 (H5Fpublic.h, H5Dpublic.h, H5Ppublic.h, H5Spublic.h).
H5F_ACC_TRUNC, H5P_DEFAULT, H5S_ALL, H5F_SCOPE_LOCAL, H5F_CLOSE_STRONG, H5D_ALLOC_TIME_EARLY = 2, 0, 0, 0, 3, 1
#: NumPy dtype -> the name of HDF5's native type (a global hid_t, set by H5open).
H5_NATIVE = {np.dtype(np.float64): "H5T_NATIVE_DOUBLE_g", np.dtype(np.int32): "H5T_NATIVE_INT32_g",
             np.dtype(np.int64): "H5T_NATIVE_INT64_g"}


class Hdf5File:
    """An HDF5 file of flat datasets, written through the libhdf5 dolfinx loaded (`hdf5_library`), sec2 driver.

    Hand-written instead of PETSc's HDF5 viewer, which could write this file too: the viewer flushes
    the file with H5Fflush(H5F_SCOPE_GLOBAL) after every VecView, and Debian's libhdf5 is the Open MPI
    build, whose viewer always opens the file with the MPI-IO driver, where a flush is MPI_File_sync, an
    fsync: `stringcontact run example1` would make 412 fsyncs with it, 9 with this (strace). Measured with
    benchmarks/bench_xdmf.py (docs/explanation/visualisation.md; load 0.4), 100 frames of 4 x 5001 doubles (16 MB):
    the viewer 0.27 s on ext4 and 0.078 s on tmpfs; this class (load 2-3) 0.063-0.105 s and 0.045-0.056 s,
    about 60 us of HDF5's CPU per dataset; the bytes alone 0.01 s. h5py is no alternative (see
    `hdf5_library`).

    The layout is the viewer's, dataset for dataset (tests/io/test_xdmf.py compares them): one chunk the
    size of the dataset, space allocated when it is created, no attributes. `flush` hands the data and
    HDF5's metadata to the OS without an fsync (sec2 has none), so a reader sees a well-formed file after
    every flush; the run's folder is fsynced once, when it is published (io/publish.py). Every call is
    checked: a failure raises OSError with the errno of the failed system call (ENOSPC on a full disk), or
    RuntimeError naming the HDF5 function.
    """

    def __init__(self, path: Path):
        self.path, self.lib = Path(path), hdf5_library()
        if self.lib is None:
            raise RuntimeError(f"{self.path.name}: the libhdf5 that dolfinx loaded was not found")
        self._call("H5open")  # sets the globals read below
        self.types = {dtype: self._global(name) for dtype, name in H5_NATIVE.items()}
        self.id, self.layouts = None, {}
        fapl = self._call("H5Pcreate", self._global("H5P_CLS_FILE_ACCESS_ID_g"))
        try:
            self._call("H5Pset_fapl_sec2", fapl)  # not MPI-IO, whatever HDF5_DRIVER says
            self._call("H5Pset_fclose_degree", fapl, H5F_CLOSE_STRONG)  # closing the file closes all in it
            # sec2 would lock the file while it is open (MPI-IO does not): no reader during the run
            self._call("H5Pset_file_locking", fapl, False, True)
            # bytes: a Linux file name need not be UTF-8
            self.id = self._call("H5Fcreate", os.fsencode(self.path), H5F_ACC_TRUNC, H5P_DEFAULT, fapl)
        except (OSError, RuntimeError):
            _silence_exit_later()
            raise
        finally:
            self.lib.H5Pclose(fapl)
        handle = ctypes.c_void_p()  # sec2's handle: a pointer to the file's descriptor
        try:
            self._call("H5Fget_vfd_handle", self.id, H5P_DEFAULT, ctypes.byref(handle))
        except (OSError, RuntimeError):
            self.lib.H5Fclose(self.id)
            raise
        self.fd, self.reserved = ctypes.cast(handle, ctypes.POINTER(ctypes.c_int)).contents.value, 0

    def _global(self, name: str) -> int:
        return ctypes.c_int64.in_dll(self.lib, name).value

    def _call(self, name: str, *args) -> int:
        """HDF5's `name(*args)`, its failure (a negative value) raised."""
        ctypes.set_errno(0)
        value = getattr(self.lib, name)(*args)
        if value < 0:
            err = ctypes.get_errno()
            if err:
                raise OSError(err, os.strerror(err), str(self.path))
            raise RuntimeError(f"HDF5's {name} failed on {self.path}")
        return value

    def _layout(self, shape: tuple) -> tuple[int, int]:
        """The dataspace and creation properties of a dataset of `shape` (made once): PETSc's viewer's
        choices, one chunk of the whole dataset, its space allocated when it is created."""
        if shape not in self.layouts:
            dims = (ctypes.c_uint64 * len(shape))(*shape)
            space = self._call("H5Screate_simple", len(shape), dims, None)
            self.layouts[shape] = (space, H5P_DEFAULT)  # so that `close` releases it if what follows fails
            dcpl = self._call("H5Pcreate", self._global("H5P_CLS_DATASET_CREATE_ID_g"))
            self.layouts[shape] = (space, dcpl)
            self._call("H5Pset_chunk", dcpl, len(shape), dims)
            self._call("H5Pset_alloc_time", dcpl, H5D_ALLOC_TIME_EARLY)
        return self.layouts[shape]

    def write(self, name: str, array: np.ndarray) -> None:
        """The dataset `/name`: `array`'s shape and values."""
        array = np.ascontiguousarray(array)
        space, dcpl = self._layout(array.shape)
        dtype = self.types[array.dtype]
        dataset = self._call("H5Dcreate2", self.id, name.encode(), dtype, space, H5P_DEFAULT, dcpl, H5P_DEFAULT)
        try:
            self._call("H5Dwrite", dataset, dtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, array.ctypes.data)
        finally:
            self._call("H5Dclose", dataset)  # the chunk reaches the file here

    def _reserve(self) -> None:
        """Allocate the file's blocks up to HDF5's end of allocated space, so that the flush that follows
        only writes where the disk has room: a full disk fails here, with the file still closable.

        libhdf5 1.10.8 cannot flush a file again after one of its flushes failed (the failed flush leaves
        its cache's list of dirty entries switched on: "slist already enabled?"), and crashes when the
        process ends (SIGSEGV in H5F__close_cb, from MPI_Finalize), with H5Fclose called or not: measured
        for 3 of 128 disk sizes of `run example1 --nx 200` on a 2 MiB tmpfs with the room check off, and
        148 of 249 in tests/io/test_xdmf.py. Blocks below `reserved` stay
        allocated: HDF5 cuts the file only to its end of allocation, at a flush, which is `reserved` then.
        """
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

    def flush(self) -> None:
        """Everything written so far to the OS (no fsync): a reader now sees a well-formed file."""
        self._reserve()
        self._call("H5Fflush", self.id, H5F_SCOPE_LOCAL)

    def close(self) -> None:
        """Close the file (its last flush); kept open if that fails, so that `discard` can close it."""
        if self.id is not None:
            self._reserve()
            self._call("H5Fclose", self.id)
            self.id = None
        self._release_layouts()

    def discard(self) -> None:
        """Close the file, which the caller is about to remove, whatever room its disk has left: HDF5's
        descriptor is pointed at a file in memory first, which takes the closing flush. Never raises."""
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



@contextlib.contextmanager
def stderr_held(replay: bool = True):
    """Hold back what C libraries print to stderr; print it after the block (if `replay`), or drop it if the
    block fails.

    HDF5 prints its error stack for a failed call unless `Hdf5Quiet` is on (and dolfinx's or PETSc's
    MPI-IO writes print Open MPI's own line, "mca_fbtl_posix_pwritev: ... No space left on device"); the
    caller reports one line instead.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with tempfile.TemporaryFile() as held:
            os.dup2(held.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
            held.seek(0)
            text = held.read()
            if text and replay:
                os.write(2, text)
    finally:
        os.close(saved)
