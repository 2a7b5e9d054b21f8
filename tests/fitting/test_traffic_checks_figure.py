"""The traffic checks' figure is laid out on a fixed grid (no layout solver), and its
panels' titles, tick labels and the legend (one row in the title band) still stay inside
the page and clear of each other. Its histograms are outlines with hist's patches and limits."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from are_stats.fitting import TRAFFIC_STATISTICS, _traffic_checks, plot_traffic_checks  # noqa: E402


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
        (legend,) = fig.legends  # one row in the title band, left of the title
        key = legend.get_window_extent(renderer)
        assert [t.get_text() for t in legend.get_texts()] == ["paper", "chosen", "observed"]
        assert key.x0 >= page.x0 and key.y1 <= page.y1 and key.x1 < top.x0
        assert all(key.y0 >= b.y1 for b in boxes), "the legend covers a panel or its title"
    finally:
        plt.close(fig)


def test_an_outline_is_the_patch_and_limits_of_hist_stepfilled():
    rng = np.random.default_rng(4)
    v = rng.gamma(2.0, 1.0, 300)
    bins = np.linspace(v.min() - 0.1, v.max() + 0.1, 30)
    fig, (a, b) = plt.subplots(1, 2)
    try:
        a.hist(v, bins=bins, color="tab:blue", alpha=0.55, label="chosen", histtype="stepfilled")
        _traffic_checks._add_outline(b, v, bins, "tab:blue", "chosen")
        (want,), (got,) = a.patches, b.patches
        np.testing.assert_array_equal(got.get_xy(), want.get_xy())
        for prop in ("facecolor", "edgecolor", "linewidth", "alpha", "label", "zorder", "fill"):
            assert got.properties()[prop] == want.properties()[prop], prop
        assert got.sticky_edges.y == want.sticky_edges.y == [0]
        assert got.get_clip_on() and want.get_clip_on()  # clipped to the panel, as hist's
        assert (
            got.get_clip_box().bounds == b.bbox.bounds
            and want.get_clip_box().bounds == a.bbox.bounds
        )
        assert got.get_data_transform() is b.transData and want.get_data_transform() is a.transData
        b.autoscale_view()
        assert a.get_xlim() == b.get_xlim() and a.get_ylim() == b.get_ylim()
        assert a.get_legend_handles_labels()[1] == b.get_legend_handles_labels()[1] == ["chosen"]
    finally:
        plt.close(fig)
