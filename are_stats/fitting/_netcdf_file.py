"""A fit's NetCDF file, opened with its HDF5 objects looked up once.

h5netcdf (the NetCDF layer under xarray) keeps no HDF5 object: every property of a variable
or a dimension (dtype, shape, chunks, filters, whether a dimension is unlimited) looks its
dataset up again by path in the root file (``File[path]``: an HDF5 path walk and two new
h5py objects, about 0.2 ms each). Reading the shipped log's fit (8 groups, 60 variables)
did 2,700 such look-ups, more than half of :func:`~are_stats.fitting.read_fit`'s time, and
writing it as many. :func:`open_netcdf` hands h5netcdf an h5py file whose look-ups by path
are memoised, so that the values read, and the bytes written, are the same:

- Reading, the file does not change: a path names the same object all along.
- Writing, h5netcdf adds objects (a path not there yet is not memoised: its look-up failed)
  and deletes one only where a coordinate variable takes the place of its dimension's scale
  dataset (``del group[name]``, then a new dataset under that name): every group handed out
  clears the memo when something is deleted from it.
- Writing, a dataset held open would keep its written chunks in HDF5's chunk cache until
  the file closes, and space for them would be allocated then, in another order: other
  bytes (the same contents). The file is opened without a chunk cache (``rdcc_nbytes=0``),
  so every chunk goes to the file when it is written, where closing the dataset after each
  write (h5netcdf's way) put it.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

import h5netcdf
import h5py

__all__ = ["open_netcdf"]

#: h5netcdf's (private, 1.8) choice of the order tracking it gives h5py; without it (another
#: release) :func:`open_netcdf` writes with h5netcdf's own file, without the memo.
_TRACK_ORDER = getattr(h5netcdf.core, "_get_track_order", None)


class _Group(h5py.Group):
    """An h5py group whose deletions clear its file's memo of look-ups."""

    def __init__(self, bind: h5py.h5g.GroupID, memo: dict[str, object]) -> None:
        super().__init__(bind)
        self._memo = memo

    def __delitem__(self, name: str) -> None:
        self._memo.clear()
        super().__delitem__(name)


class _MemoFile(h5py.File):
    """An h5py file whose look-ups by path (``f["/group/var"]``) are memoised; anything
    else (an HDF5 object reference) is looked up as h5py does. Groups come back as
    :class:`_Group`: deleting through them clears the memo."""

    def __init__(self, name: str, mode: str, **kwargs: object) -> None:
        super().__init__(name, mode, **kwargs)
        self._memo: dict[str, object] = {}

    def __getitem__(self, name: object) -> object:
        if not isinstance(name, str):
            return super().__getitem__(name)
        try:
            return self._memo[name]
        except KeyError:
            pass
        obj = super().__getitem__(name)
        if type(obj) is h5py.Group:
            obj = _Group(obj.id, self._memo)
        self._memo[name] = obj
        return obj

    def __delitem__(self, name: str) -> None:
        self._memo.clear()
        super().__delitem__(name)


@contextmanager
def open_netcdf(path: str | os.PathLike[str], mode: str = "r") -> Iterator[h5netcdf.File]:
    """The NetCDF file ``path`` open as ``h5netcdf.File(path, mode, decode_vlen_strings=True)``
    opens it, its HDF5 look-ups memoised; closed on exit.

    Parameters
    ----------
    path : str or PathLike
        The ``.nc`` file.
    mode : {"r", "w"}
        Read it, or write it (created, or truncated, with h5netcdf's order tracking).

    Yields
    ------
    h5netcdf.File
        The open file.

    Raises
    ------
    OSError
        If HDF5 cannot open it (as ``h5netcdf.File``).
    ValueError
        If ``mode`` is neither.
    """
    if mode == "r":
        h5 = _MemoFile(str(path), "r")
    elif mode == "w":  # the track_order h5netcdf gives h5py; no chunk cache (see above)
        if _TRACK_ORDER is None:  # another h5netcdf release: its own file, memo-less
            with h5netcdf.File(str(path), "w", decode_vlen_strings=True) as f:
                yield f
            return
        h5 = _MemoFile(str(path), "w", track_order=_TRACK_ORDER("h5py"), rdcc_nbytes=0)
    else:
        raise ValueError(f"mode: expected 'r' or 'w', got {mode!r}")
    try:
        # given an open h5py file, h5netcdf leaves it open: the finally closes it
        with h5netcdf.File(h5, mode, decode_vlen_strings=True) as f:
            yield f
    finally:
        h5._memo.clear()
        h5.close()
