"""Atomic, non-clobbering file and folder output.

Every file the toolkit writes goes through :func:`atomic_path`: the content is written to
a temporary file in the destination folder and renamed over the target only when complete,
so an interrupted run never leaves a half-written file, and an existing file is kept
unless ``force=True``. Output *folders* (scenario sets, sweep results) go through
:func:`atomic_folder` / :func:`replace_folder`: they are written beside the target and
put in its place as a whole, so files of two runs never stand side by side.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import errno
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import matplotlib.figure

__all__ = [
    "OutputExistsError",
    "atomic_folder",
    "atomic_path",
    "check_folder",
    "check_writable",
    "replace_folder",
]


class OutputExistsError(FileExistsError):
    """Raised when an output exists and ``force`` was not given.

    ``str(err)`` says how to overwrite from Python (``force=True``); :attr:`cli_message`
    says it as the command line does (``--force``), and the CLI prints that one: neither
    mixes the two.

    Parameters
    ----------
    where : str
        The output and what is in the way (``"fits/f.nc: already exists"``).
    remedy : str
        What forcing does (``"to overwrite it"``); empty where forcing does not help.

    Examples
    --------
    >>> err = OutputExistsError("f.nc: already exists", "to overwrite it")
    >>> str(err)
    'f.nc: already exists; pass force=True to overwrite it'
    >>> err.cli_message
    'f.nc: already exists; pass --force to overwrite it'
    """

    def __init__(self, where: str, remedy: str = "") -> None:
        self.where, self.remedy = where, remedy
        super().__init__(self._say("force=True"))

    def _say(self, flag: str) -> str:
        return f"{self.where}; pass {flag} {self.remedy}" if self.remedy else self.where

    @property
    def cli_message(self) -> str:
        """The message in the command line's words (``--force``)."""
        return self._say("--force")


def check_writable(path: str | os.PathLike, force: bool) -> Path:
    """Raise :class:`OutputExistsError` if ``path`` exists and ``force`` is false."""
    p = Path(path)
    if p.exists() and not force:
        raise OutputExistsError(f"{p}: already exists", "to overwrite it")
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


def save_figure(
    fig: matplotlib.figure.Figure,
    path: str | os.PathLike,
    force: bool = False,
    dpi: int = 120,
    *,
    tight: bool = True,
    close: bool = False,
) -> Path:
    """Write a matplotlib figure atomically (PNG/PDF/SVG by suffix), refusing to overwrite
    unless ``force``; ``tight`` trims the margins, ``close`` closes the figure after."""
    with atomic_path(path, force=force) as tmp:
        fig.savefig(
            tmp,
            dpi=dpi,
            bbox_inches="tight" if tight else None,
            format=str(path).rsplit(".", 1)[-1],
        )
    if close:
        # lazy: pyplot adds 0.74 s CPU to `import are_stats.environment` (its maps use this module)
        import matplotlib.pyplot as plt

        plt.close(fig)
    return Path(path)


_RENAME_EXCHANGE = 2  # renameat2 flag (Linux >= 3.15)
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2(RENAME_EXCHANGE)``); False where unsupported."""
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    libc = ctypes.CDLL(name, use_errno=True)
    fn = getattr(libc, "renameat2", None)
    if fn is None:
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    rc = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.EPERM, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def replace_folder(new: str | os.PathLike, out: str | os.PathLike) -> None:
    """Put the finished folder ``new`` in place of the existing folder ``out`` as a whole.

    An atomic exchange where the OS has one (Linux), else two renames; the old content is
    removed only after ``new`` is in place.
    """
    new, out = Path(new), Path(out)
    if _exchange(new, out):
        shutil.rmtree(new)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".old", dir=out.parent))
    os.replace(out, old / out.name)
    os.replace(new, out)
    shutil.rmtree(old)


def check_folder(path: str | os.PathLike, force: bool) -> Path:
    """Raise :class:`OutputExistsError` unless ``path`` may become a new output folder.

    It may when it does not exist, is an empty folder, or is a folder and ``force`` is true.
    """
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise OutputExistsError(f"{target}: exists and is not a folder")
    if target.exists() and not force and any(target.iterdir()):
        raise OutputExistsError(f"{target}: already exists", "to replace the folder")
    return target


@contextlib.contextmanager
def atomic_folder(path: str | os.PathLike, force: bool = False) -> Iterator[Path]:
    """Yield a temporary sibling folder; put it in place of ``path`` as a whole on success.

    Everything of an output folder is written into the temporary folder, which then
    replaces ``path`` in one step (:func:`replace_folder`), so a reader never sees files of
    two runs side by side and an interrupted run leaves the old folder intact (and at most
    a hidden ``.<name>.*.tmp`` sibling). An existing folder is replaced only with
    ``force``; an existing empty folder is replaced without it.

    Parameters
    ----------
    path : str or PathLike
        The output folder.
    force : bool
        Replace an existing non-empty folder (all its files: nothing of the old run stays).

    Raises
    ------
    OutputExistsError
        If ``path`` exists, is not an empty folder, and ``force`` is false (nothing is
        written then).
    """
    target = check_folder(path, force)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes 0700: the usual folder permissions
        if target.exists():
            replace_folder(tmp, target)
        else:
            os.replace(tmp, target)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
