"""Count panel against the life-cycle fit of the same scene (issue 14, count panels).

False-failure rate: on the paper's own data each of the three z-scores is at most standard
normal (a panel counted from the same log makes them smaller: measured |z| < 0.05), and the
test asserts ``|z| < 3.29`` (probability below 1e-3 each, 3e-3 together); on group data the
rates' z-scores are measured at 11.0 and 9.8 against a bound of 3. Seeds are fixed, so the
outcome is deterministic."""

from __future__ import annotations

import warnings

import jax
import numpy as np
import pytest

from are_stats.fitting import (
    FitSettings,
    compare_panel,
    count_path,
    fit_log,
    read_fit,
    write_fit,
)
from are_stats.traffic import LifecycleData, TrafficLaws, sample_population, simulate_lifecycle
from tests.helpers import assert_allclose

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    import arviz as az

AREA = 200.0
BIRTH, DEATH = 0.2, 0.01  # per second: mean count 20, mean stay 100 s
WINDOW = (0.0, 10_000.0)
GRID = np.arange(0.0, 10_000.0 + 1e-9, 10.0)  # a count every tenth of a mean stay
PAPER = FitSettings(
    method="em",
    num_samples=500,
    num_chains=2,
    n_bootstrap=2,
    arrivals="poisson",
    lifetimes="exponential",
    positions="uniform",
)


def _panel(data: LifecycleData) -> tuple[np.ndarray, np.ndarray]:
    return GRID, count_path(data.t_arrive, data.t_leave, GRID)


def test_paper_data_agree_and_attrs_round_trip(tmp_path):
    d = simulate_lifecycle(jax.random.key(4), BIRTH / AREA, DEATH, [1.0], [1.0], WINDOW, area=AREA)
    data = LifecycleData(d.t_arrive, d.t_leave, d.window, d.area)
    idata = fit_log(jax.random.key(5), data, PAPER, counts_panel=_panel(data)).idata
    back = read_fit(write_fit(idata, tmp_path / "fit.nc")).idata
    a = back.posterior.attrs
    se_r = np.asarray(a["birth_death_stderr_robust"])
    assert se_r.shape == (2,) and np.all(se_r > 0)
    assert str(a["birth_death_stderr_method"]).startswith("hac, ")
    cmp = compare_panel(back)
    assert cmp.stderr_kind == "robust" and cmp.names == ("birth_rate", "death_rate", "mean_count")
    assert np.all(np.abs(cmp.z) < 3.29), cmp.z
    assert cmp.warning is None and not cmp.disagree


def test_group_data_disagree_with_a_warning():
    # groups of 1-4 (equally likely) arriving and leaving together: the life-cycle fit of the
    # paper's model still estimates the member arrival rate and the stay, the panel's
    # rates are both about 2.5x too large while its mean count agrees
    rng = np.random.default_rng(41)
    probs = np.full(4, 0.25)
    draw = {"event_rate": BIRTH / AREA / 2.5, "stay_mean": 1 / DEATH, "group_size_probs": probs}
    pop = sample_population(rng, draw, TrafficLaws(arrivals="groups"), WINDOW[1], AREA)
    t_arrive = np.where(pop["truncated"], np.nan, pop["t_arrive"])
    t_leave = np.where(pop["t_leave"] >= WINDOW[1], np.nan, pop["t_leave"])
    data = LifecycleData(t_arrive, t_leave, WINDOW, AREA)
    idata = fit_log(jax.random.key(6), data, PAPER, counts_panel=_panel(data)).idata
    cmp = compare_panel(idata)
    assert cmp.z[0] > 3 and cmp.z[1] > 3 and abs(cmp.z[2]) < 3.29, cmp.z
    assert cmp.disagree and "group arrivals" in cmp.warning
    assert "birth rate" in cmp.warning and "panel errors robust" in cmp.warning
    # the life-cycle side is right about the truth, the panel is not
    assert abs(cmp.lifecycle_mean[0] / BIRTH - 1) < 0.2
    assert cmp.panel_estimate[0] / BIRTH > 1.8


def _idata(est=(2.0, 0.1), robust=True, draws=None):
    rng = np.random.default_rng(0)
    if draws is None:
        draws = (rng.normal(0.01, 0.001, (2, 400)), rng.normal(0.1, 0.01, (2, 400)))
    idata = az.from_dict(posterior={"arrival_rate": draws[0], "leave_rate": draws[1]})
    attrs = {
        "area": 200.0,
        "birth_death_birth_rate": est[0],
        "birth_death_death_rate": est[1],
        "birth_death_stderr": np.array([0.1, 0.005]),
    }
    if robust:
        attrs["birth_death_stderr_robust"] = np.array([0.2, 0.01])
        attrs["birth_death_log_cov_robust"] = np.array([0.01, 0.008, 0.008, 0.01])
    idata.posterior.attrs.update(attrs)
    return idata, draws


def test_z_scores_by_hand():
    idata, (lam, mu) = _idata(est=(3.2, 0.1))
    cmp = compare_panel(idata)
    b, m = lam.ravel() * 200.0, mu.ravel()
    ratio_se = 32.0 * np.sqrt(0.01 + 0.01 - 2 * 0.008)
    expected = [
        (3.2 - b.mean()) / np.hypot(0.2, b.std(ddof=1)),
        (0.1 - m.mean()) / np.hypot(0.01, m.std(ddof=1)),
        (32.0 - (b / m).mean()) / np.hypot(ratio_se, (b / m).std(ddof=1)),
    ]
    assert_allclose(cmp.z, expected, rtol=1e-12)
    assert cmp.disagree and cmp.z[0] > 3 and "different times, areas" in cmp.warning
    # an older fit without robust errors falls back to the model-based ones, and says so
    old, _ = _idata(robust=False)
    cmp = compare_panel(old)
    assert cmp.stderr_kind == "model"
    assert_allclose(cmp.panel_stderr[:2], [0.1, 0.005], rtol=1e-12)
    assert compare_panel(old, threshold=100.0).warning is None


@pytest.mark.parametrize(
    "make, name",
    [
        (lambda: compare_panel(object()), "idata"),
        (lambda: compare_panel(az.from_dict(posterior={"leave_rate": np.ones((1, 5))})), "idata"),
        (lambda: compare_panel(_idata()[0], threshold=-1.0), "threshold"),
        (lambda: compare_panel(_idata()[0], threshold=[1.0, 2.0]), "threshold"),
    ],
)
def test_bad_input_names_argument(make, name):
    with pytest.raises(ValueError, match=name) as info:
        make()
    assert "expected" in str(info.value)


def test_fit_without_panel_is_refused():
    idata, _ = _idata()
    del idata.posterior.attrs["birth_death_birth_rate"]
    with pytest.raises(ValueError, match="--counts"):
        compare_panel(idata)
