"""Atomic, non-clobbering file output.

Everything the toolkit writes goes through :func:`atomic_path`: the content is written to
a temporary file in the destination folder and renamed over the target only when complete,
so an interrupted run never leaves a half-written file, and an existing file is kept
unless ``force=True``.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["OutputExistsError", "atomic_path", "check_writable"]


class OutputExistsError(FileExistsError):
    """Raised when an output exists and ``force`` was not given."""


def check_writable(path: str | os.PathLike, force: bool) -> Path:
    """Raise :class:`OutputExistsError` if ``path`` exists and ``force`` is false."""
    p = Path(path)
    if p.exists() and not force:
        raise OutputExistsError(f"{p}: already exists; pass --force (force=True) to overwrite it")
    return p


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, force: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    Examples
    --------
    >>> with atomic_path("fits/demo.nc", force=True) as tmp:  # doctest: +SKIP
    ...     idata.to_netcdf(tmp)
    """
    target = check_writable(path, force)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if tmp_path.exists():  # mkstemp creates 0600; give the file the usual permissions
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp_path, 0o666 & ~umask)
        os.replace(tmp_path, target)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()
