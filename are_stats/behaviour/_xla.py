"""``jax.jit`` with XLA compile options that a later jaxlib may not know.

The behaviour's programs (the social force's window, the MDP solver, the behaviour
likelihood's gradient) are compiled with XLA options (the CPU fusion emitters off, a vector
width) that exist today; a jaxlib that drops one refuses the compile with ``No such compile
option``. :func:`jit_with_options` compiles as ``jax.jit(fn, compiler_options=...)`` does
and, where XLA names an option it does not know, leaves that option out (from then on, for
every program made here) and compiles again: the same programs and bits where every option
is known, a program without the option (as the Laplace programs'
``_program_cache._compile_lowered`` does) where one is not.

:func:`padded_size` is the one sequence of sizes those programs pad a length to (the MDP's
epochs, the walls' grid sides), so that calls of nearby sizes share one program.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import jax

__all__ = ["jit_with_options", "padded_size"]

#: Options this jaxlib refused (``No such compile option``): left out from then on.
UNKNOWN_OPTIONS: set[str] = set()


def _unknown(err: Exception, options: Mapping[str, Any]) -> set[str]:
    """The options ``err`` (XLA's compile error) says this jaxlib does not know."""
    return {k for k in options if f"No such compile option: '{k}'" in str(err)}


class _OptionsJit:
    """``jax.jit(fn, compiler_options=options, **kwargs)``, remade without the options XLA
    refuses (:func:`jit_with_options`). Attributes (``lower``, ``_cache_size``...) are the
    jitted function's."""

    def __init__(self, fn: Callable, options: Mapping[str, Any], kwargs: dict[str, Any]) -> None:
        self._fn, self._options, self._kwargs = fn, dict(options), kwargs
        self._left_out: frozenset[str] = frozenset()
        self._jit = self._make()

    def _make(self) -> Any:
        self._left_out = frozenset(UNKNOWN_OPTIONS & self._options.keys())
        known = {k: v for k, v in self._options.items() if k not in UNKNOWN_OPTIONS}
        return jax.jit(self._fn, compiler_options=known, **self._kwargs)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        if UNKNOWN_OPTIONS & self._options.keys() != self._left_out:
            self._jit = self._make()  # another program found an option unknown
        try:
            return self._jit(*args, **kwargs)
        except Exception as err:  # noqa: BLE001 - XLA's own error type: one naming options
            unknown = _unknown(err, self._options) - UNKNOWN_OPTIONS
            if not unknown:
                raise
            UNKNOWN_OPTIONS.update(unknown)
            self._jit = self._make()
            return self._jit(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        if name == "_jit":  # not made yet
            raise AttributeError(name)
        return getattr(self._jit, name)


def jit_with_options(
    fn: Callable | None = None, /, *, compiler_options: Mapping[str, Any], **jit_kwargs: Any
) -> Any:
    """``jax.jit(fn, compiler_options=compiler_options, **jit_kwargs)`` that leaves out the
    options this jaxlib does not know (see the module docstring); as a decorator with
    ``fn`` omitted.

    Parameters
    ----------
    fn : callable, optional
        The function to compile.
    compiler_options : mapping of str to value
        XLA compile options (``xla_cpu_use_fusion_emitters``...).
    **jit_kwargs
        ``jax.jit``'s other arguments (``static_argnames``, ``donate_argnums``...).

    Returns
    -------
    callable
        Called as the jitted function; its attributes (``lower``...) are the jitted
        function's.
    """
    if fn is None:
        return lambda f: _OptionsJit(f, compiler_options, jit_kwargs)
    return _OptionsJit(fn, compiler_options, jit_kwargs)


def padded_size(n: int, least: int) -> int:
    """The padded length of ``n``: the next of ``least``, then powers of two and one and a half
    times them (``least`` 16: 16, 24, 32, 48, 64, 96, ...), so at most 1.5x ``n`` past
    ``least`` (a power of two)."""
    if n <= least:
        return least
    p = 1 << (n - 1).bit_length()  # the power of two >= n
    return 3 * p // 4 if 3 * p // 4 >= n else p
