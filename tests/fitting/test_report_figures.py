"""The report's figures tell their story (a new user's tour): every panel's axes say what
they count and in which unit, a panel that has nothing to compare for a log says so in
words (no lone bar, no empty axis), and legends list only what is drawn."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from are_stats.fitting import TRAFFIC_STATISTICS, plot_traffic_checks  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _texts(ax) -> str:
    return " ".join(t.get_text() for t in ax.texts)


def _traffic_inputs(seed: int = 0) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """The shipped log's case: nobody is ever absent (``longest N(t) = 0`` is 0 in the log
    and in every replicate); the last statistic is undefined everywhere."""
    n = len(TRAFFIC_STATISTICS)
    rng = np.random.default_rng(seed)
    reps = {m: rng.gamma(4.0, 0.25, (200, n)) for m in ("paper", "chosen")}
    table = pd.DataFrame(
        {"observed": rng.gamma(4.0, 0.25, n), "paper_flag": True, "chosen_flag": False},
        index=list(TRAFFIC_STATISTICS),
    )
    empty = TRAFFIC_STATISTICS.index("longest N(t) = 0 (s)")
    for r in reps.values():
        r[:, empty] = 0.0
        r[:, -1] = np.nan
    table.loc["longest N(t) = 0 (s)", "observed"] = 0.0
    table.loc[TRAFFIC_STATISTICS[-1], "observed"] = np.nan
    return table, reps


def test_traffic_checks_axes_are_labelled_and_an_all_equal_panel_says_so():
    fig = plot_traffic_checks(*_traffic_inputs())
    panels = dict(zip(TRAFFIC_STATISTICS, fig.axes, strict=False))
    for stat, ax in panels.items():
        assert ax.get_title() == stat
        assert ax.get_xlabel() and ax.get_xlabel() != stat, stat  # says what is counted
    # "zero gaps" is explained on its axis
    assert "same frame" in panels["zero gaps"].get_xlabel()
    assert "(s)" in panels["longest N(t) = 0 (s)"].get_xlabel()
    # the first panel of each row names what the bars count
    cols = (len(TRAFFIC_STATISTICS) + 1) // 2
    for row in range(2):
        assert fig.axes[row * cols].get_ylabel() == "replicated windows"
    # nobody ever absent: words, no bars and no observed line
    empty = panels["longest N(t) = 0 (s)"]
    assert "never empty" in _texts(empty)
    assert not empty.patches and not empty.lines and not list(empty.get_xticks())
    undefined = panels[TRAFFIC_STATISTICS[-1]]
    assert "not defined" in _texts(undefined) and not undefined.patches
    # a panel with data draws each model and the log, and says nothing in words
    full = panels["N(t) peak"]
    assert len(full.patches) == 2 and len(full.lines) == 1 and "never" not in _texts(full)


def test_traffic_checks_all_equal_panel_names_its_value():
    table, reps = _traffic_inputs(1)
    for r in reps.values():
        r[:, 1] = 7.0
    table.loc[TRAFFIC_STATISTICS[1], "observed"] = 7.0
    fig = plot_traffic_checks(table, reps)
    ax = fig.axes[1]
    assert "the log and every replicate:\n7" in _texts(ax) and not ax.patches
