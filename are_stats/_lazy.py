"""A module imported on first use: heavy libraries stay out of a process that never needs
them, or come in after the work that does not (a fit starts compiling its programs before
ArviZ's two seconds of imports)."""

from __future__ import annotations

import importlib
import warnings
from types import ModuleType
from typing import Any

__all__ = ["LazyModule", "arviz", "import_xarray_dask", "scipy_signal", "scipy_stats"]


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

    def __getattr__(self, attr: str) -> Any:
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
