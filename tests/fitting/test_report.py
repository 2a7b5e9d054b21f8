"""fit_summary: ArviZ's summary of a fit, quiet for single-chain (em) fits."""

from __future__ import annotations

import logging

import arviz as az
import jax
import numpy as np
import pandas as pd
import pytest
from PIL import Image

from are_stats.fitting import FitSettings, fit_log, fit_summary, write_report
from are_stats.traffic import simulate_lifecycle


class _Records(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def test_single_chain_summary_is_quiet_and_has_no_r_hat():
    rng = np.random.default_rng(0)
    lam = rng.gamma(50.0, 1e-6, size=(1, 400))
    mu = rng.gamma(80.0, 2e-5, size=(1, 400))
    idata = az.from_dict(posterior={"arrival_rate": lam, "leave_rate": mu})
    log = getattr(az, "_log", logging.getLogger("arviz"))
    seen = _Records()
    log.addHandler(seen)
    try:
        table = fit_summary(idata)
    finally:
        log.removeHandler(seen)
    assert [r.getMessage() for r in seen.records if r.levelno >= logging.WARNING] == []
    assert list(table.index) == ["arrival_rate", "leave_rate"]
    assert np.isnan(table["r_hat"]).all()
    np.testing.assert_allclose(table.loc["leave_rate", "mean"], mu.mean(), rtol=1e-12)
    # the level ArviZ's logger had is restored
    assert log.level == logging.NOTSET or log.level < logging.ERROR


def test_summary_matches_arviz_and_leaves_its_numba_flag_alone():
    # fit_summary takes ArviZ's NumPy paths (no numba compile per process); the numbers
    # are ArviZ's own, and ArviZ's flag is what it was afterwards
    rng = np.random.default_rng(1)
    post = {
        "arrival_rate": rng.gamma(50.0, 1e-6, size=(4, 300)),
        "mix_rates": rng.gamma(9.0, 1.0, size=(4, 300, 2)).cumsum(axis=-1),
    }
    idata = az.from_dict(posterior=post)
    flag = az.Numba.numba_flag
    table = fit_summary(idata)
    assert az.Numba.numba_flag == flag
    ref = az.summary(idata, round_to="none")
    assert list(table.index) == list(ref.index)
    np.testing.assert_allclose(table.to_numpy(float), ref.to_numpy(float), rtol=1e-8)


def _where(full: np.ndarray, img: np.ndarray) -> list[tuple[int, int]]:
    """Every offset at which ``img`` is exactly a region of ``full`` (RGB arrays)."""
    h, w = img.shape[:2]
    big_h, big_w = full.shape[0] - h + 1, full.shape[1] - w + 1
    rng = np.random.default_rng(0)
    drawn = np.argwhere(np.any(img < 255, axis=-1))
    probes = drawn[rng.choice(len(drawn), min(40, len(drawn)), replace=False)]
    ok = np.ones((big_h, big_w), bool)
    for r, c in probes:
        ok &= np.all(full[r : r + big_h, c : c + big_w] == img[r, c], axis=-1)
    return [
        (int(r), int(c)) for r, c in np.argwhere(ok)
        if np.array_equal(full[r : r + h, c : c + w], img)
    ]  # fmt: skip


def _small_em_fit(horizon: float):
    """The paper's model fitted by EM to a small seeded log of ``horizon`` seconds."""
    data = simulate_lifecycle(
        jax.random.key(0), 1 / 30 / 200.0, 1 / 200, [0.5, 0.5], [2.0, 12.0], (0.0, horizon),
        area=200.0,
    )  # fmt: skip
    paper = {"arrivals": "poisson", "lifetimes": "exponential", "positions": "uniform"}
    settings = FitSettings(method="em", num_samples=40, num_chains=2, n_bootstrap=8, k_max=2,
                           **paper)  # fmt: skip
    return fit_log(jax.random.key(1), data, settings).idata


@pytest.fixture(scope="module")
def em_fit():
    """``_small_em_fit(3600.0)``, fitted once for the module (each of four tests fitted it,
    one at 1800 s, which compiled the EM's programs for a second data size)."""
    return _small_em_fit(3600.0)


@pytest.fixture(scope="module")
def report(em_fit, tmp_path_factory):
    """``write_report`` of ``em_fit`` as a caller without a summary calls it: read by the
    two tests below (each rendered the report of its own)."""
    return write_report(em_fit, tmp_path_factory.mktemp("report") / "report", n_replicates=3)


def test_report_panels_are_whole_cut_outs_of_the_overview(report):
    """write_report renders the checks once: each ``ppc_<check>.png`` is the region of
    ``criticism.png`` around that check's panel, cut where the overview is blank (the
    panel's title, labels and legend whole), and the panels are different regions."""
    written = report
    full = np.asarray(Image.open(written["criticism"]).convert("RGB"))
    panels = sorted(n for n in written if n.startswith("ppc_"))
    assert len(panels) >= 5
    corners = set()
    for name in panels:
        img = np.asarray(Image.open(written[name]).convert("RGB"))
        h, w = img.shape[:2]
        assert full.shape[0] / 4 < h < full.shape[0] and full.shape[1] / 5 < w < full.shape[1] / 2
        edges = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
        assert np.all(edges == 255), name  # nothing of the drawing cut at the border
        assert np.mean(np.any(img < 255, axis=-1)) > 0.05, name  # a drawing, not blank
        found = _where(full, img)
        assert len(found) == 1, (name, found)
        corners.add(found[0])
    assert len(corners) == len(panels)


def test_write_report_writes_the_summary_its_caller_passes(tmp_path, em_fit, report):
    """``summary=`` (are-stats fit has printed it already) is written as summary.csv
    instead of being computed again; without it the report computes the same table."""
    idata = em_fit
    own = report["summary"]  # written without summary=
    summary = fit_summary(idata)
    pd.testing.assert_frame_equal(pd.read_csv(own, index_col=0), summary, check_dtype=False)
    given = write_report(idata, tmp_path / "given", n_replicates=3, summary=summary.iloc[:1])
    assert list(pd.read_csv(given["summary"], index_col=0).index) == list(summary.index[:1])


def test_panel_extents_from_the_drawing_contain_matplotlibs_tight_boxes(em_fit):
    """The overview's panel extents, read off the drawn texts without laying the ticks out
    again, hold each panel's ``Axes.get_tightbbox`` (matplotlib's own extent: its axes,
    title, labels and tick labels) with at most the margin around it, and do not meet."""
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from are_stats.fitting import predictive_checks
    from are_stats.fitting._report import _PANEL_MARGIN, _overview, _panel_boxes

    overview, panels = _overview(predictive_checks(0, em_fit, 3))
    try:
        canvas = FigureCanvasAgg(overview)
        canvas.draw()
        renderer = canvas.get_renderer()
        boxes = _panel_boxes(overview, panels, renderer)
        assert boxes is not None and set(boxes) == set(panels)
        for name, ax in panels.items():
            tight = ax.get_tightbbox(renderer).extents
            box = np.asarray(boxes[name])
            inner = box + np.array([1, 1, -1, -1]) * _PANEL_MARGIN
            assert np.all(inner[:2] <= tight[:2] + 1e-6) and np.all(inner[2:] >= tight[2:] - 1e-6)
            np.testing.assert_allclose(inner, tight, atol=1.0, err_msg=name)
    finally:
        plt.close(overview)


def test_report_panels_stay_whole_where_the_fixed_grid_is_too_small(tmp_path, monkeypatch, em_fit):
    """A grid with no room for the labels (no left margin, panels abutting) is found out
    from the drawing and laid out by ``tight_layout``: the panels are whole cut-outs still."""
    from are_stats.fitting import _report

    tiny = {"left": 0.0, "right": 1.0, "bottom": 0.0, "top": 0.95, "wspace": 0.0, "hspace": 0.0}
    monkeypatch.setattr(_report, "_OVERVIEW_GRID", tiny)
    written = write_report(em_fit, tmp_path / "report", n_replicates=3)
    full = np.asarray(Image.open(written["criticism"]).convert("RGB"))
    for name in (n for n in written if n.startswith("ppc_")):
        img = np.asarray(Image.open(written[name]).convert("RGB"))
        edges = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
        assert np.all(edges == 255), name
        assert len(_where(full, img)) == 1, name
