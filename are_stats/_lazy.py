"""A module imported on first use: heavy libraries stay out of a process that never needs
them, or come in after the work that does not (a fit starts compiling its programs before
ArviZ's two seconds of imports)."""

from __future__ import annotations

import importlib
import sys
import warnings
from types import ModuleType
from typing import Any

__all__ = [
    "LazyModule",
    "arviz",
    "hide_dask",
    "hide_numba",
    "import_xarray_dask",
    "scipy_signal",
    "scipy_stats",
]


class LazyModule:
    """Stands for module ``name``, imported on the first attribute read.

    Parameters
    ----------
    name : str
        The module's import name.
    quiet : tuple of Warning types
        Warnings the import itself raises and nobody can act on (ArviZ 0.23 announces its
        1.0 refactor with a ``FutureWarning``).

    Examples
    --------
    >>> az = LazyModule("arviz", quiet=(FutureWarning,))
    >>> az.InferenceData.__name__  # arviz is imported here
    'InferenceData'
    """

    def __init__(self, name: str, quiet: tuple[type[Warning], ...] = ()) -> None:
        self._name = name
        self._quiet = quiet
        self._module: ModuleType | None = None

    def _load(self) -> ModuleType:
        if self._module is None:
            with warnings.catch_warnings():
                for kind in self._quiet:
                    warnings.simplefilter("ignore", kind)
                self._module = importlib.import_module(self._name)
        return self._module

    def __getattr__(self, attr: str) -> Any:  # whatever the module holds
        if attr.startswith("__") and attr.endswith("__"):  # copy, pickle, inspect probes
            raise AttributeError(attr)
        return getattr(self._load(), attr)

    def __repr__(self) -> str:
        state = "imported" if self._module is not None else "not imported yet"
        return f"<LazyModule {self._name!r} ({state})>"


#: ArviZ (2 s of imports), for the modules that build or read fits; its 0.23 release
#: announces the 1.0 refactor with a FutureWarning on import.
arviz = LazyModule("arviz", quiet=(FutureWarning,))

#: scipy.stats (0.3-0.4 s of imports), for the few traffic and fitting functions that use it.
scipy_stats = LazyModule("scipy.stats")

#: scipy.signal, which imports scipy.stats too (one convolution in the position densities).
scipy_signal = LazyModule("scipy.signal")


def import_xarray_dask() -> None:
    """Import ``dask.array`` (what xarray's first array of a process imports) here, before
    threads start that build xarray objects.

    xarray asks for ``dask.array`` when it makes its first variable; two threads doing that
    at once can meet ``dask.array`` half-initialised (a circular import inside dask:
    "partially initialized module 'dask.array' has no attribute 'Array'"), which an
    ``are-stats fit`` of a tracks table hit once in a full test run. About 1.4 s, once per
    process; nothing without dask.
    """
    try:
        importlib.import_module("dask.array")
    except ImportError:
        pass


#: The packages :func:`hide_dask` makes unimportable.
DASK_PACKAGES = ("dask", "distributed")


def hide_dask() -> bool:
    """Make ``dask`` and ``distributed`` unimportable in this process, so that xarray runs
    without them.

    xarray imports ``dask.array`` when it makes its first variable in a process where dask
    is installed, and ``dask.distributed`` when it writes a NetCDF file (to ask whether a
    distributed scheduler is running): about 0.6 s of imports in an ``are-stats fit``
    that uses neither. After this call ``import dask`` raises ``ImportError`` and
    ``importlib.util.find_spec("dask")`` returns None, which is how xarray (and
    :func:`import_xarray_dask`) learn that dask is not there.

    For a command's own process only (:func:`are_stats.cli.main` calls it for the commands
    that run no Dask sweep); a library user's process keeps dask.

    Returns
    -------
    bool
        True if dask is hidden now; False if it was imported already (then it stays).
    """
    return _hide(DASK_PACKAGES)


#: The packages :func:`hide_numba` makes unimportable.
NUMBA_PACKAGES = ("numba",)


def hide_numba() -> bool:
    """Make ``numba`` unimportable in this process, so that ArviZ runs without it.

    Where numba is installed (the ``bench`` extra's PyMC and PySocialForce bring it),
    ``import arviz`` imports it through ``arviz.plots`` (its ECDF bands) and compiles one
    ``@vectorize`` kernel with an eager signature at import: ``import arviz`` took
    5.7-5.9 s of user CPU with numba, 3.8-4.2 s without (measured 2026-11-28 at load 16),
    in an ``are-stats fit`` that calls no numba code (its ArviZ summary runs ArviZ's NumPy
    paths already, ``fitting._report._numpy_paths``). ArviZ asks
    ``importlib.util.find_spec("numba")``, which returns None after this call, and takes
    its NumPy paths.

    For a command's own process only (as :func:`hide_dask`); a library user's process keeps
    numba.

    Returns
    -------
    bool
        True if numba is hidden now; False if it was imported already (then it stays).
    """
    return _hide(NUMBA_PACKAGES)


def _hide(names: tuple[str, ...]) -> bool:
    """Make the top-level packages ``names`` unimportable, unless one is imported already."""
    if any(sys.modules.get(name) is not None for name in names):
        return False
    for name in names:
        sys.modules[name] = None  # type: ignore[assignment]  # the import system's "absent"
    return True
