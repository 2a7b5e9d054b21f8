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

from are_stats.fitting import (  # noqa: E402
    MOTION_STATISTICS,
    TRAFFIC_STATISTICS,
    plot_class_checks,
    plot_class_entries,
    plot_class_shares_by_hour,
    plot_motion_checks,
    plot_traffic_checks,
)


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


def _class_rows(stat: str, values: dict[str, tuple[float, float, float, float, bool]]):
    idx = pd.MultiIndex.from_product([list(values), [stat]], names=["class", "statistic"])
    cols = ["observed", "model_5%", "model_50%", "model_95%", "model_flag"]
    return pd.DataFrame(list(values.values()), index=idx, columns=cols)


def test_class_checks_label_units_and_say_when_nobody_stands_still():
    traffic = pd.concat(
        [
            _class_rows(
                "share",
                {"child": (0.1, 0.05, 0.12, 0.2, False), "person": (0.9, 0.8, 0.88, 0.95, False)},
            ),  # fmt: skip
            _class_rows(
                "stay median",
                {
                    "child": (40.0, 20.0, 25.0, 30.0, True),
                    "person": (27.0, 25.0, 27.0, 29.0, False),
                },
            ),  # fmt: skip
        ]
    )
    motion = _class_rows(
        "fraction still",
        {"child": (0.0, 0.0, 0.0, 0.0, False), "person": (0.0, 0.0, 0.0, 0.0, False)},  # fmt: skip
    )
    fig = plot_class_checks(traffic, motion)
    share, stay, still = fig.axes
    assert stay.get_xlabel() == "median stay (s)" and share.get_xlabel()
    assert share.get_ylabel() == "class"
    assert "no track stands still" in _texts(still) and not still.lines
    # the legend lists what is drawn: the flagged stay is an entry of its own
    (legend,) = fig.legends
    names = [t.get_text() for t in legend.get_texts()]
    assert names == ["model 90%", "model median", "log", "log, outside the 90% band"]


def _by_hour(hours: range, classes=("child", "person")) -> pd.DataFrame:
    rows = []
    for c, name in enumerate(classes):
        for h in range(24):
            n = 40 if h in hours else 0
            w = (0.2, 0.8)[c]
            band = (w - 0.1, w, w + 0.1) if n else (np.nan,) * 3
            rows.append((name, h, n, w if n else np.nan, *band, False))
    cols = ["class", "hour", "arrivals", "observed", "model_5%", "model_50%", "model_95%"]
    return pd.DataFrame(rows, columns=[*cols, "model_flag"]).set_index(["class", "hour"])


def test_class_shares_of_a_short_log_show_its_hour_and_its_bands():
    fig = plot_class_shares_by_hour(_by_hour(range(8, 9)), "constant")
    (ax,) = fig.axes
    assert ax.get_xlim() == (8.0, 9.0)  # the log's hour, not the day
    assert ax.get_xlabel() == "hour of the day (h)" and ax.get_ylabel()
    bands = [p for p in ax.patches if p.get_height() > 0]
    assert len(bands) == 2  # one band per class in the log's one hour
    for p, w in zip(bands, (0.2, 0.8), strict=True):
        assert p.get_y() == pytest.approx(w - 0.1) and p.get_height() == pytest.approx(0.2)
        assert 8.0 <= p.get_x() and p.get_x() + p.get_width() <= 9.0
    names = [t.get_text() for t in ax.get_legend().get_texts()]
    assert sorted(names) == sorted(
        ["child: model 90%", "person: model 90%", "child: log", "person: log"]
    )


def test_class_shares_of_a_day_span_the_day():
    fig = plot_class_shares_by_hour(_by_hour(range(0, 24)))
    (ax,) = fig.axes
    assert ax.get_xlim() == (0.0, 24.0)
    assert len(ax.patches) == 48


def test_class_entries_show_the_logs_entries_over_the_density():
    import arviz as az
    import xarray as xr

    dens = np.zeros((2, 10, 20))
    dens[:, 5, 0] = 1.0  # everyone enters by one door cell
    x = np.array([0.25, 0.25, 0.25, 5.0])
    y = np.array([2.75, 2.75, 2.75, 1.0])
    idata = az.from_dict(
        posterior={"arrival_rate": np.ones((1, 2))},
        observed_data={
            "x": x,
            "y": y,
            "classes": np.array([0, 0, 1, 1]),
            "t_arrive": np.array([1.0, 2.0, 3.0, np.nan]),  # the last was there at the start
        },
    )
    idata.posterior.attrs["class_labels"] = "child,person"
    idata.add_groups(
        constant_data=xr.Dataset(
            {"class_entry_density": (("class", "row", "col"), dens)},
            attrs={"class_position_resolution": 0.5, "class_position_origin": [0.0, 0.0, 0.0]},
        )
    )
    fig = plot_class_entries(idata)
    child, person = (ax for ax in fig.axes if ax.get_title())
    assert child.get_title() == "child (2 entries in the log)"
    assert person.get_title() == "person (1 entry in the log)"
    for ax in (child, person):
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "y (m)")
        (rings,) = ax.collections
        assert rings.get_zorder() > ax.images[0].get_zorder()
        assert rings.get_sizes()[0] >= 20 and rings.get_alpha() >= 0.8  # seen, not a speck
    assert len(child.collections[0].get_offsets()) == 2
    assert (child.get_xlim(), child.get_ylim()) == ((0.0, 10.0), (0.0, 5.0))
    bars = [ax for ax in fig.axes if ax.get_ylabel() == "entry density (1/m^2)"]
    assert len(bars) == 2


def _motion_inputs(still: float) -> tuple[pd.DataFrame, dict]:
    """Walking tracks (none still when ``still`` is 0) and 30 replicates of them."""
    rng = np.random.default_rng(2)

    def tracks(n: int) -> pd.DataFrame:
        return pd.DataFrame(
            {
                "speed": rng.normal(1.2, 0.1, n),
                "straightness": rng.uniform(0.9, 1.0, n),
                "exit_fraction": rng.uniform(0.9, 1.0, n),
                "still": rng.random(n) < still,
            }
        )

    summary = rng.normal(1.0, 0.1, (30, len(MOTION_STATISTICS)))
    summary[:, 3] = rng.binomial(40, still, 30) / 40
    table = pd.DataFrame(
        {
            "observed": summary.mean(0),
            "model_5%": summary.min(0),
            "model_50%": summary.mean(0),
            "model_95%": summary.max(0),
            "model_flag": False,
        },  # fmt: skip
        index=list(MOTION_STATISTICS),
    )
    table.loc["fraction still", "observed"] = 0.0 if still == 0 else 0.5
    return table, {"observed": tracks(40), "tracks": tracks(1200), "summary": summary}


def test_motion_checks_label_their_axes_and_say_when_nobody_stands_still():
    fig = plot_motion_checks(*_motion_inputs(0.0))
    panels = [ax for ax in fig.axes if ax.axison]
    assert len(panels) == 5
    for ax in panels:
        assert ax.get_xlabel(), ax.get_title()
    speed, _, _, still, spread = panels
    assert speed.get_xlabel() == "walking speed (m/s)" and speed.get_ylabel()
    assert "(m/s)" in spread.get_xlabel() and spread.get_ylabel() == "replicates"
    assert "no track still" in _texts(still) and "30 replicates" in _texts(still)
    assert not still.patches and not still.lines
    # one legend, outside the panels, with what is drawn (no "still" histogram)
    (legend,) = fig.legends
    names = [t.get_text() for t in legend.get_texts()]
    assert "observed tracks" in names and "model: one value per replicate" in names
    assert not any(ax.get_legend() for ax in fig.axes)


def test_motion_checks_draw_the_still_fraction_when_someone_stands():
    fig = plot_motion_checks(*_motion_inputs(0.3))
    still = [ax for ax in fig.axes if ax.axison][3]
    assert still.patches and still.lines and not still.texts
