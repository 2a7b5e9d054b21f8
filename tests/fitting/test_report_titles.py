"""The report's overview gives each panel's title its place (y = 1) instead of letting
matplotlib look for it at every drawing; the picture must be matplotlib's own, pixel for
pixel, with and without a y offset text ("1e7") under a title (where matplotlib would
lift the title)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from are_stats.fitting._criticism import kaplan_meier  # noqa: E402
from are_stats.fitting._report import (  # noqa: E402
    REPORT_DPI,
    PredictiveChecks,
    _overview,
    _overview_images,
)


def _checks(hour_scale: float) -> PredictiveChecks:
    rng = np.random.default_rng(3)
    t0, t1 = 0.0, 7200.0
    times = np.linspace(t0, t1, 201)
    stays = rng.exponential(300.0, 80)
    censored = rng.random(80) < 0.2
    rep = rng.poisson(5.0, (50, 24)) * hour_scale
    return PredictiveChecks(
        times=times,
        counts_obs=rng.poisson(4, times.size),
        counts_rep=rng.poisson(4, (50, times.size)),
        gaps_obs=rng.exponential(60.0, 100),
        gaps_rep=[rng.exponential(60.0, 100) for _ in range(50)],
        km=kaplan_meier(stays, censored),
        leave_rate=rng.gamma(50.0, 1 / 15000.0, 100),
        hours_obs=rng.poisson(5.0, 24) * hour_scale,
        clock_offset=0.0,
        hours_rep=rep,
        dispersion_obs=1.3,
        dispersion_rep=rng.gamma(10.0, 0.1, 50),
        dispersion_pvalue=0.4,
        bin_width=120.0,
        marks_obs=rng.poisson(2.0, 80),
        mix_weights=np.full((100, 2), 0.5),
        mix_rates=np.tile([1.0, 4.0], (100, 1)),
        window=(t0, t1),
    )


@pytest.mark.parametrize("hour_scale", [1, 10**7])
def test_overview_is_matplotlibs_own_picture(hour_scale):
    checks = _checks(hour_scale)
    fig, panels = _overview(checks)  # matplotlib places the titles
    fig.set_dpi(REPORT_DPI)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    offset = any(ax.yaxis.offsetText.get_text() for ax in panels.values())
    want = np.asarray(canvas.buffer_rgba()).copy()
    plt.close(fig)
    assert offset == (hour_scale > 1)  # the second case has an offset text
    got = _overview_images(checks)["criticism"]
    np.testing.assert_array_equal(got, want)
