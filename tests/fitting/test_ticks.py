"""ticks_in_view: fewer ticks made, the same figure drawn (labels, offset texts and all)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from are_stats.fitting._ticks import ticks_in_view  # noqa: E402


def _figure(limits: list[tuple[float, float]]) -> Figure:
    fig = Figure(figsize=(8, 3), dpi=80)
    for i, (lo, hi) in enumerate(limits):
        ax = fig.add_subplot(1, len(limits), i + 1)
        x = np.linspace(lo, hi, 50)
        ax.plot(x, np.sin(x - lo))
        ax.set_xlim(lo, hi)
    return fig


def _draw(fig: Figure) -> tuple[np.ndarray, int]:
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    made = sum(len(a.xaxis.majorTicks) + len(a.yaxis.majorTicks) for a in fig.axes)
    return np.asarray(canvas.buffer_rgba()).copy(), made


# limits inside a tick step (a step beyond each end), an offset text (1e6 + small range),
# tiny and negative ranges, one tick in view
LIMITS = [(0.05, 0.95), (1e6 + 0.013, 1e6 + 0.087), (-3.3e-4, 7.1e-4), (-17.0, 4.0), (0.9, 1.6)]


@pytest.mark.parametrize("limits", [LIMITS[:3], LIMITS[3:]])
def test_same_pixels_fewer_ticks(limits):
    plain, made_plain = _draw(_figure(limits))
    fig = _figure(limits)
    ticks_in_view(fig.axes)
    ticks_in_view(fig.axes)  # twice: wrapped once
    wrapped, made = _draw(fig)
    assert np.array_equal(plain, wrapped)
    assert made < made_plain
    fig.axes[0].set_xlim(*limits[-1])  # later limits are followed
    again = _figure(limits)
    again.axes[0].set_xlim(*limits[-1])
    assert np.array_equal(_draw(again)[0], _draw(fig)[0])
