"""The traffic checks' figure is laid out on a fixed grid (no layout solver), and its
panels' titles and tick labels still stay inside the page and clear of each other."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from are_stats.fitting import TRAFFIC_STATISTICS, plot_traffic_checks  # noqa: E402


def _inputs(scale: float, seed: int) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """A table and replicates whose statistics span ``scale`` (wide tick labels when
    large), one of them undefined everywhere."""
    n = len(TRAFFIC_STATISTICS)
    rng = np.random.default_rng(seed)
    reps = {m: rng.gamma(4.0, scale / 4.0, (200, n)) for m in ("paper", "chosen")}
    reps["paper"][:, -1] = np.nan
    reps["chosen"][:, -1] = np.nan
    table = pd.DataFrame(
        {"observed": rng.gamma(4.0, scale / 4.0, n), "paper_flag": True, "chosen_flag": False},
        index=list(TRAFFIC_STATISTICS),
    )
    table.loc[TRAFFIC_STATISTICS[-1], "observed"] = np.nan
    return table, reps


@pytest.mark.parametrize(("scale", "seed"), [(1.0, 0), (0.03, 1), (2500.0, 2), (1.7e5, 3)])
def test_panels_fit_the_page_without_a_layout_engine(scale, seed):
    fig = plot_traffic_checks(*_inputs(scale, seed))
    try:
        assert fig.get_layout_engine() is None  # constrained layout before
        canvas = FigureCanvasAgg(fig)
        fig.set_dpi(110)
        canvas.draw()
        renderer = canvas.get_renderer()
        page = fig.bbox
        boxes = [ax.get_tightbbox(renderer) for ax in fig.axes if ax.get_visible()]
        assert len(boxes) == len(TRAFFIC_STATISTICS)
        for b in boxes:  # titles and tick labels on the page (a pixel of rounding)
            assert b.x0 >= page.x0 - 1 and b.x1 <= page.x1 + 1
            assert b.y0 >= page.y0 - 1 and b.y1 <= page.y1 + 1
        for i, a in enumerate(boxes):  # no two panels' labels overlap
            for b in boxes[i + 1 :]:
                overlap_x = min(a.x1, b.x1) - max(a.x0, b.x0)
                overlap_y = min(a.y1, b.y1) - max(a.y0, b.y0)
                assert overlap_x <= 0 or overlap_y <= 0, (a, b)
        title = fig.get_suptitle()
        top = fig._suptitle.get_window_extent(renderer)
        assert title and top.y1 <= page.y1 and all(top.y0 >= b.y1 for b in boxes)
    finally:
        plt.close(fig)
