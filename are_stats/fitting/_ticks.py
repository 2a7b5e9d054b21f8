"""Tick marks made only for the ticks a criticism figure draws.

Matplotlib makes a tick (two marks, a grid line and two labels, copied property by
property from the axis' first) for every location its locator returns, and draws those
inside the axis' view: ``AutoLocator`` returns a step beyond each end, so a quarter of the
report's ticks (42 of 186 on the shipped log) were made and never drawn, at about 2 ms of
CPU each. :func:`ticks_in_view` wraps each axis' locator to return only the locations
inside its view; the labels are still those of all the locations (a
``ScalarFormatter`` chooses its decimals from them), so the figure's pixels stay the same.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.ticker import Formatter, Locator

__all__ = ["ticks_in_view"]

#: Relative slack kept around the view: matplotlib's own test (``_interval_contains_close``,
#: 1e-10) then decides which of the kept ticks it draws.
_SLACK = 1e-9


def _in_view(axis: Any, locs: np.ndarray) -> np.ndarray:
    lo, hi = sorted(axis.get_view_interval())
    slack = _SLACK * (hi - lo)
    return (locs >= lo - slack) & (locs <= hi + slack)


class _InView(Locator):
    """``locator``'s locations inside the axis' view."""

    def __init__(self, locator: Locator) -> None:
        self.locator = locator

    def set_axis(self, axis: Any) -> None:
        super().set_axis(axis)
        self.locator.set_axis(axis)

    def __call__(self) -> np.ndarray:
        locs = np.asarray(self.locator(), float)
        return locs[_in_view(self.axis, locs)]

    def tick_values(self, vmin: float, vmax: float) -> Any:
        return self.locator.tick_values(vmin, vmax)


class _LabelsOfAll(Formatter):
    """``formatter``'s labels of all of ``locator``'s locations, for those in view."""

    def __init__(self, formatter: Formatter, locator: Locator) -> None:
        self.formatter, self.locator = formatter, locator

    def set_axis(self, axis: Any) -> None:
        super().set_axis(axis)
        self.formatter.set_axis(axis)

    def format_ticks(self, values: Any) -> list[str]:
        locs = np.asarray(self.locator(), float)
        keep = _in_view(self.axis, locs)
        if int(keep.sum()) != len(values):  # not the locations of _InView: as they are
            return self.formatter.format_ticks(values)
        labels = self.formatter.format_ticks(locs)
        return [text for text, k in zip(labels, keep, strict=True) if k]

    def __call__(self, x: float, pos: int | None = None) -> str:
        return self.formatter(x, pos)

    def get_offset(self) -> str:
        return self.formatter.get_offset()

    def format_data_short(self, value: float) -> str:
        return self.formatter.format_data_short(value)


def ticks_in_view(axes: Any) -> None:
    """Make ``axes``' major ticks only where they are drawn (the module docstring).

    Call it once every axis' locator, formatter and limits are set: the wrappers read the
    view at every drawing, so later limits are followed, but a later ``set_xticks``
    replaces them.

    Parameters
    ----------
    axes : iterable of matplotlib.axes.Axes
    """
    for ax in axes:
        for axis in (ax.xaxis, ax.yaxis):
            locator = axis.get_major_locator()
            if isinstance(locator, _InView):
                continue
            formatter = axis.get_major_formatter()
            axis.set_major_locator(_InView(locator))
            axis.set_major_formatter(_LabelsOfAll(formatter, locator))
