"""Fitting and choosing traffic models on logs simulated from stated truths.

Recovery tests: one seeded log per truth; the choice is right unless the log is an
unusually unlucky draw (with these sizes the LOO differences are tens of standard errors:
the false-failure rate is far below 1e-3). Parameter checks are 5-posterior-sd bounds.
"""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats.fitting import (
    FitSettings,
    choose_simplest,
    fit_log,
    fit_traffic,
    read_fit,
    traffic_checks,
    traffic_draws,
    write_fit,
)
from are_stats.inputs import InputError
from are_stats.scenarios import generate_scenarios, scenario_counts
from are_stats.traffic import (
    LifecyclePriors,
    TrafficLaws,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    fit_position_density,
    simulate_traffic_log,
    stationary_count_moments,
    uniform_position_density,
)

NUTS = {"num_warmup": 150, "num_samples": 200, "num_chains": 2}
FREE = np.ones((30, 40), bool)
FREE[:, 0] = False
RES, ORIGIN = 0.5, (0.0, 0.0)
AREA = float(FREE.sum()) * RES * RES


class _Grid:
    """The smallest map object fit_traffic needs (free cells, resolution, origin)."""

    free = FREE
    resolution = RES
    origin = (0.0, 0.0, 0.0)


def _paper(data, shape=(1, 400), seed=0):
    """Conjugate draws of the paper's rates, laid out as an EM fit's ``(1, S)`` posterior."""
    rng = np.random.default_rng(seed)
    a = conjugate_arrival_rate(data, LifecyclePriors())
    m = conjugate_leave_rate(data, LifecyclePriors())
    return {
        "arrival_rate": rng.gamma(a.shape, 1 / a.rate, shape),
        "leave_rate": rng.gamma(m.shape, 1 / m.rate, shape),
    }


def _doors() -> object:
    rng = np.random.default_rng(11)
    pts = np.vstack([rng.normal([1.0, 7.5], 0.4, (300, 2)), rng.normal([19.0, 1.0], 0.4, (300, 2))])
    return fit_position_density(np.clip(pts, 0.6, 19.9), FREE, RES, ORIGIN)


@pytest.fixture(scope="module")
def rich_log():
    """Truth: groups (sizes 1-3), gamma stays (mean 60 s, shape 6), door entries."""
    laws = TrafficLaws(arrivals="groups", lifetimes="gamma", positions="learned",
                       group_stay_sd=0.1, group_spread=0.3, entry=_doors())  # fmt: skip
    draw = {"event_rate": 1e-3, "stay_mean": 60.0, "stay_shape": 6.0,
            "group_size_probs": np.array([0.5, 0.3, 0.2])}  # fmt: skip
    uni = uniform_position_density(FREE, RES, ORIGIN)
    data = simulate_traffic_log(np.random.default_rng(1), draw, laws, (0.0, 1800.0), AREA,
                                free=uni, resolution=0.4)  # fmt: skip
    return data, draw


@pytest.fixture(scope="module")
def rich_fit(rich_log):
    """Every candidate sampled by NUTS (about 140 s of CPU cold): the slow tier's reference."""
    data, _ = rich_log
    return fit_traffic(jax.random.key(0), data, paper=_paper(data), grid=_Grid(), **NUTS)


@pytest.fixture(scope="module")
def nuts_fit(rich_log):
    """The true models named, each against the paper's, sampled by NUTS: the NUTS + PSIS-LOO
    path of ``rich_fit`` with two candidates a factor instead of all of them. The groups
    arrival model's NUTS program takes about 36 s of CPU to compile (2026-11-29, cold; its
    sampling 3 s): the slow tier's NUTS reference of the arrival factor."""
    data, _ = rich_log
    return fit_traffic(jax.random.key(0), data, paper=_paper(data), grid=_Grid(),
                       arrivals="groups", lifetimes="gamma", positions="learned",
                       **NUTS)  # fmt: skip


@pytest.fixture(scope="module")
def stays_nuts_fit(rich_log):
    """The true stay law and entries named, each against the paper's, the stays sampled by
    NUTS, the arrivals the paper's (its closed-form draws: no program): the NUTS + PSIS-LOO
    path of make test (``nuts_fit``'s stay factor, without its groups program)."""
    data, _ = rich_log
    return fit_traffic(jax.random.key(0), data, paper=_paper(data), grid=_Grid(),
                       arrivals="poisson", lifetimes="gamma", positions="learned",
                       **NUTS)  # fmt: skip


#: The stay law's parameters, which make test checks on ``stays_nuts_fit``
STAY_NAMES = ("stay_mean", "stay_shape")


@pytest.mark.slow  # every candidate by NUTS; make test: the true models against the paper's
def test_auto_picks_the_true_models(rich_fit):
    assert rich_fit.arrival_model == "groups"
    assert rich_fit.lifetime_model == "gamma"
    assert rich_fit.position_model == "learned"
    for table in rich_fit.tables.values():
        assert table["chosen"].sum() == 1
        assert "weight" not in table.columns  # no stacking weights posing as probabilities


def test_nuts_picks_the_true_stay_law_over_the_papers(stays_nuts_fit):
    """NUTS + PSIS-LOO between the true stay law and the paper's: the truth (the arrival
    factor: the slow test below; the auto choice among every candidate by NUTS: the slow
    test above; by Laplace, the tests below)."""
    fit = stays_nuts_fit
    assert (fit.arrival_model, fit.lifetime_model, fit.position_model) == (
        "poisson", "gamma", "learned",
    )  # fmt: skip
    assert list(fit.tables["lifetimes"].index) == ["exponential", "gamma"]
    assert "NUTS" in fit.attrs["model_choice"]
    assert np.isfinite(fit.tables["lifetimes"].loc["gamma", "r_hat"])  # sampled by NUTS
    for table in fit.tables.values():
        assert table["chosen"].sum() == 1
        assert "weight" not in table.columns  # no stacking weights posing as probabilities


@pytest.mark.slow  # the groups NUTS program; make test: test_nuts_picks_the_true_stay_law_...
def test_nuts_picks_the_true_models_over_the_papers(nuts_fit):
    """NUTS + PSIS-LOO between each true model and the paper's: the truth (the auto choice
    among every candidate by NUTS is the slow test above; by Laplace, the tests below)."""
    assert (nuts_fit.arrival_model, nuts_fit.lifetime_model, nuts_fit.position_model) == (
        "groups", "gamma", "learned",
    )  # fmt: skip
    assert list(nuts_fit.tables["arrivals"].index) == ["poisson", "groups"]
    assert "NUTS" in nuts_fit.attrs["model_choice"]
    for table in nuts_fit.tables.values():
        assert table["chosen"].sum() == 1
        assert "weight" not in table.columns  # no stacking weights posing as probabilities


def test_stay_parameters_are_recovered(stays_nuts_fit, rich_log):
    _, truth = rich_log
    for name in STAY_NAMES:
        v = stays_nuts_fit.posterior[name].ravel()
        assert abs(v.mean() - truth[name]) < 5 * v.std(), name


# make test: test_stay_parameters_are_recovered (NUTS), and the arrival parameters by the
# Laplace and ranked fits (test_laplace_picks_the_true_models, test_ranked_fit_agrees_...)
@pytest.mark.slow
def test_parameters_are_recovered(nuts_fit, rich_log):
    _, truth = rich_log
    post = nuts_fit.posterior
    for name in ("event_rate", "stay_mean", "stay_shape"):
        v = post[name].ravel()
        assert abs(v.mean() - truth[name]) < 5 * v.std(), name
    p = post["group_size_probs"].reshape(-1, post["group_size_probs"].shape[-1])
    k = truth["group_size_probs"].size
    assert np.all(np.abs(p[:, :k].mean(0) - truth["group_size_probs"]) < 5 * p[:, :k].std(0))
    assert nuts_fit.attrs["group_stay_sd"] == pytest.approx(0.1, abs=0.05)


def test_generated_scenarios_reproduce_the_crowding(rich_idata, rich_log):
    """N(t) variance/mean of the truth (closed form) inside the fit's predictive interval."""
    _, truth = rich_log
    idata = rich_idata
    draws, laws = traffic_draws(idata, "chosen")
    df = generate_scenarios(1, draws, 200, 1800.0, area=AREA, laws=laws, draw="random")
    n = scenario_counts(df, np.linspace(100.0, 1700.0, 30))
    ratio = n.var(axis=1, ddof=1) / np.maximum(n.mean(axis=1), 1e-9)
    mean, var = stationary_count_moments(truth["event_rate"], AREA, truth["stay_mean"],
                                         truth["group_size_probs"])  # fmt: skip
    lo, hi = np.quantile(ratio, [0.05, 0.95])
    assert lo < var / mean < hi
    # the paper's model cannot: its ratio is about 1
    p_draws, p_laws = traffic_draws(idata, "paper")
    df_p = generate_scenarios(1, p_draws, 200, 1800.0, area=AREA, laws=p_laws, draw="random")
    n_p = scenario_counts(df_p, np.linspace(100.0, 1700.0, 30))
    assert np.median(n_p.var(axis=1, ddof=1) / np.maximum(n_p.mean(axis=1), 1e-9)) < var / mean
    assert set(df["group"]) and df.groupby(["scenario", "group"]).size().max() > 1


def _idata_with(traffic, data):
    """A small fit file holding the paper's conjugate draws and the traffic choice."""
    idata = fit_log(jax.random.key(3), data,
                    FitSettings(method="em", num_samples=200, num_chains=2, arrivals="poisson",
                                lifetimes="exponential", positions="uniform")).idata  # fmt: skip
    from are_stats.fitting import attach_traffic

    return attach_traffic(idata, traffic)


@pytest.fixture(scope="module")
def rich_idata(ranked_fit, rich_log):
    """The fit file of the rich log with the ranked fit of its true models (importance-
    resampled Laplace draws, the NUTS posterior within Monte Carlo error: test_ranked_fit_
    agrees_with_nuts; one per module: the tests that edit it edit a copy)."""
    return _idata_with(ranked_fit, rich_log[0])


def test_fit_file_round_trip_and_checks(rich_idata, tmp_path):
    idata = rich_idata
    write_fit(idata, tmp_path / "f.nc")
    back = read_fit(tmp_path / "f.nc").idata
    assert back.posterior.attrs["arrival_model"] == "groups"
    assert "entry_density" in back.constant_data
    table, reps = traffic_checks(0, back, 100)
    # each 90% band misses a correct model's statistic one time in ten: of the nine
    # statistics that can miss (the longest empty stretch is 0 in every window), three or
    # more miss in about 5% of seeds were they independent; the chosen model may miss two.
    # The paper's misses the groups, the stays and the doors
    assert table["chosen_flag"].sum() <= 2, table
    assert table.loc["zero gaps", "paper_flag"] and table.loc["stay cv", "paper_flag"]
    assert table.loc["entry to boundary (m)", "paper_flag"]
    # the statistics groups, stays and doors move (the burst statistics at 30-60 s and the
    # empty stretches are about the same under both models on this log)
    crowd = table.loc[["N(t) var/mean", "N(t) peak", "zero gaps", "stay cv",
                       "entry to boundary (m)", "arrivals var/mean (1 s)"]]  # fmt: skip
    closer = (crowd["chosen_50%"] - crowd["observed"]).abs() <= (
        crowd["paper_50%"] - crowd["observed"]
    ).abs()
    assert closer.all(), table
    assert reps["chosen"].shape == (100, len(table))


def test_checks_entry_distance_is_each_windows_own(rich_idata):
    """traffic_checks measures every replicate's entry distances in one call of
    boundary_distance; each window's values are window_statistics' on that window alone,
    bit for bit."""
    from are_stats.fitting import window_statistics
    from are_stats.fitting._traffic_checks import _free_of
    from are_stats.traffic import fold_in_key, key_from_seed

    idata = rich_idata
    n_rep = 12
    table, reps = traffic_checks(0, idata, n_rep)
    free = _free_of(idata)
    w = np.asarray(idata.posterior.attrs["window"], float)
    res = float(np.asarray(idata.posterior.attrs["traffic_time_resolution"]).ravel()[0])
    j = list(table.index).index("entry to boundary (m)")
    for i, model in enumerate(("paper", "chosen")):
        draws, laws = traffic_draws(idata, model)
        df = generate_scenarios(fold_in_key(key_from_seed(0), i), draws, n_rep, w[1] - w[0],
                                free_mask=free[0], area=float(idata.posterior.attrs["area"]),
                                draw="random", headings=0, laws=laws, resolution=free[1],
                                origin=free[2])  # fmt: skip
        want = []
        for r in range(n_rep):
            sc = df[df["scenario"] == r]
            ta = sc["t_arrive"].to_numpy() + w[0]
            ta = np.ceil((ta - w[0]) / res - 1e-9) * res + w[0]
            st = window_statistics(ta, sc["t_leave"].to_numpy() + w[0],
                                   sc["truncated"].to_numpy(), (w[0], w[1]), res,
                                   sc[["x", "y"]].to_numpy(), free)  # fmt: skip
            want.append([st[s] for s in table.index])
        want = np.asarray(want)
        assert np.isfinite(want[:, j]).all()
        np.testing.assert_array_equal(reps[model], want)


def test_read_fit_names_a_missing_variable(rich_idata, tmp_path):
    idata = rich_idata.copy()
    del idata.posterior["group_size_probs"]
    write_fit(idata, tmp_path / "bad.nc")
    with pytest.raises(InputError, match="group_size_probs"):
        read_fit(tmp_path / "bad.nc")


@pytest.fixture(scope="module")
def paper_log():
    """Truth: the paper's model (Poisson arrivals, exponential stays, uniform entries).

    Stays of 90 s on average: the arrivals' units are then in bins of a median stay
    (about 60 s, 30 bins) as on the rich log, so that its Laplace programs of the
    arrival candidates are the rich log's (the same padded shapes: compiled once).
    """
    draw = {"event_rate": 1e-3, "stay_mean": 90.0}
    return simulate_traffic_log(np.random.default_rng(2), draw, TrafficLaws(), (0.0, 1800.0),
                                AREA, free=uniform_position_density(FREE, RES, ORIGIN),
                                resolution=0.4)  # fmt: skip


@pytest.mark.slow  # all-NUTS; make test keeps the Laplace twin below
def test_paper_truth_keeps_the_paper_model(paper_log):
    data = paper_log
    fit = fit_traffic(jax.random.key(1), data, paper=_paper(data), grid=_Grid(), **NUTS)
    assert (fit.arrival_model, fit.lifetime_model, fit.position_model) == (
        "poisson", "exponential", "uniform",
    )  # fmt: skip
    assert (
        "groups not offered" in fit.attrs["arrival_notes"]
        or "groups" in fit.tables["arrivals"].index
    )


@pytest.mark.slow  # two NUTS fits; make test fits gamma stays by NUTS (stays_nuts_fit)
def test_stays_in_days_fit_like_stays_in_seconds():
    """Gamma stays of about 8 h: the same log in seconds and in days gives the same shape."""
    laws = TrafficLaws(lifetimes="gamma")
    draw = {"event_rate": 2e-6, "stay_mean": 8 * 3600.0, "stay_shape": 3.0}
    data = simulate_traffic_log(np.random.default_rng(3), draw, laws, (0.0, 30 * 86400.0),
                                AREA, resolution=60.0)  # fmt: skip
    day = 86400.0
    from are_stats.traffic import LifecycleData

    in_days = LifecycleData(t_arrive=data.t_arrive / day, t_leave=data.t_leave / day,
                            window=(0.0, 30.0), area=AREA)  # fmt: skip
    fits = []
    for d in (data, in_days):
        f = fit_traffic(jax.random.key(2), d, paper=_paper(d), lifetimes="gamma",
                        arrivals="poisson", positions="uniform", **NUTS)  # fmt: skip
        fits.append(f)
        assert f.tables["lifetimes"].loc["gamma", "divergent"] == 0
        assert f.tables["lifetimes"].loc["gamma", "r_hat"] < 1.05
    shape_s = fits[0].posterior["stay_shape"].mean()
    shape_d = fits[1].posterior["stay_shape"].mean()
    assert shape_s == pytest.approx(shape_d, rel=0.05)
    assert fits[0].posterior["stay_mean"].mean() / day == pytest.approx(
        fits[1].posterior["stay_mean"].mean(), rel=0.05
    )
    assert abs(shape_s - 3.0) < 5 * fits[0].posterior["stay_shape"].std()


def test_choose_simplest_prefers_simple_within_two_se():
    rng = np.random.default_rng(0)
    base = rng.normal(-1.0, 0.3, 400)
    close = base + rng.normal(0.001, 0.02, 400)  # a hair better, well within 2 SE
    far = base + 0.2  # much better everywhere
    chosen, table = choose_simplest({"a": base, "b": close}, ["a", "b"])
    assert chosen == "a" and isinstance(table, pd.DataFrame)
    chosen, _ = choose_simplest({"a": base, "b": far}, ["a", "b"])
    assert chosen == "b"


def test_time_of_day_needs_a_clock_and_two_days():
    from are_stats.fitting._traffic import _arrival_candidates

    cands, notes = _arrival_candidates("auto", 1, None, 3 * 86400.0)
    assert "time-of-day" not in cands and "clock_start" in notes[-1]
    cands, notes = _arrival_candidates("auto", 1, 0.0, 13 * 60.0)
    assert "time-of-day" not in cands and "two days" in notes[-1]
    cands, notes = _arrival_candidates("auto", 2, 0.0, 3 * 86400.0)
    assert {"time-of-day", "groups+time-of-day"} <= set(cands)
    # the bursts with a time of day: only where the time of day itself is offered
    assert {"mmpp+time-of-day", "hawkes+time-of-day"} <= set(cands)
    # the groups+ variants with a time of day only when named (costly), and the notes say so
    assert not {"groups+mmpp+time-of-day", "groups+hawkes+time-of-day"} & set(cands)
    assert "groups+hawkes+time-of-day" in notes[-1]
    assert "groups+hawkes" in cands
    for clock, dur in ((None, 3 * 86400.0), (0.0, 13 * 60.0)):
        cands, _ = _arrival_candidates("auto", 2, clock, dur)
        assert not any("time-of-day" in c for c in cands) and "groups+hawkes" in cands
    with pytest.raises(ValueError, match="clock_start"):
        _arrival_candidates("hawkes+time-of-day", 1, None, 3 * 86400.0)
    with pytest.raises(ValueError, match="clock_start"):
        _arrival_candidates("time-of-day", 1, None, 3 * 86400.0)


@pytest.mark.slow  # a 3-day NUTS fit; make test checks the candidates above
def test_diurnal_truth_picks_time_of_day():
    """Three days with a strong daily profile and a clock: auto picks the time of day."""
    hours = np.arange(24)
    tod = 1.0 + 0.9 * np.sin(2 * np.pi * (hours - 6) / 24)  # peak at noon, trough at midnight
    tod = tod / tod.mean()
    laws = TrafficLaws(arrivals="time-of-day", clock_offset=0.0)
    draw = {"event_rate": 6e-6, "stay_mean": 60.0, "arrival_tod": tod}
    data = simulate_traffic_log(np.random.default_rng(7), draw, laws, (0.0, 3 * 86400.0),
                                AREA, resolution=1.0)  # fmt: skip
    fit = fit_traffic(jax.random.key(4), data, paper=_paper(data), lifetimes="exponential",
                      positions="uniform", clock_start="2026-01-05T00:00:00", **NUTS)  # fmt: skip
    assert fit.arrival_model == "time-of-day", fit.tables["arrivals"]
    got = fit.posterior["arrival_tod"].reshape(-1, 24)
    assert np.all(np.abs(got.mean(0) - tod) < 5 * got.std(0) + 0.05)


# ---- the Laplace approximation (method em: no NUTS program) ----------------------------


@pytest.fixture(scope="module")
def laplace_fit(rich_log):
    data, _ = rich_log
    return fit_traffic(jax.random.key(0), data, paper=_paper(data), grid=_Grid(),
                       approximation="laplace")  # fmt: skip


def test_laplace_picks_the_true_models(laplace_fit, stays_nuts_fit, rich_log):
    """On the rich log (groups, gamma stays, door entries: none the paper's) the Laplace +
    importance-sampled PSIS-LOO comparison of every candidate picks the truth; the chosen
    models' Gaussians recover the truth, the stay law's with the spread of its NUTS
    posterior (the arrival model's: the slow test below)."""
    _, truth = rich_log
    got = (laplace_fit.arrival_model, laplace_fit.lifetime_model, laplace_fit.position_model)
    assert got == ("groups", "gamma", "learned")
    assert "Laplace" in laplace_fit.attrs["model_choice"]
    post = laplace_fit.posterior
    for name in ("event_rate", "stay_mean", "stay_shape"):
        v = post[name].ravel()
        assert v.shape == stays_nuts_fit.posterior["stay_mean"].ravel().shape  # draws alike
        assert abs(v.mean() - truth[name]) < 5 * v.std(), name
    _assert_laplace_spread_is_nuts(laplace_fit, stays_nuts_fit, STAY_NAMES)


def _assert_laplace_spread_is_nuts(laplace_fit, nuts, names) -> None:
    """The Gaussian's spread is the posterior's (NUTS) within 20%."""
    for name in names:
        v = laplace_fit.posterior[name].ravel()
        assert v.std() == pytest.approx(nuts.posterior[name].std(), rel=0.2), name


@pytest.mark.slow  # the groups NUTS program; make test: test_laplace_picks_the_true_models
def test_laplace_arrival_spread_is_the_nuts_posteriors(laplace_fit, nuts_fit):
    _assert_laplace_spread_is_nuts(laplace_fit, nuts_fit, ("event_rate", *STAY_NAMES))


@pytest.mark.slow  # every candidate by NUTS; make test: test_laplace_picks_the_true_models
def test_laplace_choice_agrees_with_nuts_loo(laplace_fit, rich_fit):
    """The Laplace comparison picks what NUTS + PSIS-LOO of every candidate picks, with
    elpd within a few nats of NUTS's for every candidate."""
    got = (laplace_fit.arrival_model, laplace_fit.lifetime_model, laplace_fit.position_model)
    assert got == (rich_fit.arrival_model, rich_fit.lifetime_model, rich_fit.position_model)
    assert "NUTS" in rich_fit.attrs["model_choice"]
    for factor in ("arrivals", "lifetimes"):
        a, b = laplace_fit.tables[factor], rich_fit.tables[factor]
        assert list(a.index) == list(b.index)
        # MC error of PSIS-LOO and the Gaussian's fit: a few nats, against differences of
        # hundreds between the candidates
        assert np.all(np.abs(a["elpd"] - b["elpd"]) < 5.0 + 0.02 * b["se"]), (a, b)


@pytest.fixture(scope="module")
def paper_laplace_fit(paper_log):
    """The Laplace comparison of the paper-truth log's candidates, run LAPLACE_THREADS (two)
    at a time: the fit of the two tests below."""
    import are_stats.fitting._traffic as traffic

    assert traffic.LAPLACE_THREADS == 2
    data = paper_log
    return fit_traffic(jax.random.key(3), data, paper=_paper(data), grid=_Grid(),
                       approximation="laplace")  # fmt: skip


def test_laplace_keeps_the_paper_model_on_paper_truth(paper_laplace_fit):
    fit = paper_laplace_fit
    assert (fit.arrival_model, fit.lifetime_model, fit.position_model) == (
        "poisson", "exponential", "uniform",
    )  # fmt: skip


def _group_stats_loop(data):
    """The per-group loop ``_group_stats`` replaced (a scan of all artefacts per group)."""
    g = np.asarray(data.group)
    seen = ~data.truncated & ~data.censored
    stay = np.where(seen, data.t_leave - data.t_arrive, np.nan)
    ss_stay = df_stay = ss_xy = df_xy = 0.0
    for gid in np.unique(g):
        idx = np.flatnonzero(g == gid)
        if idx.size < 2:
            continue
        s = stay[idx]
        s = s[np.isfinite(s) & (s > 0)]
        if s.size >= 2:
            ls = np.log(s)
            ss_stay += float(np.sum((ls - ls.mean()) ** 2))
            df_stay += s.size - 1
        xy = np.column_stack([data.x[idx], data.y[idx]])
        ss_xy += float(np.sum((xy - xy.mean(axis=0)) ** 2))
        df_xy += 2 * (idx.size - 1)
    return {
        "group_stay_sd": float(np.sqrt(ss_stay / df_stay)) if df_stay else 0.0,
        "group_spread": float(np.sqrt(ss_xy / df_xy)) if df_xy else 0.0,
    }


@pytest.mark.parametrize("seed", range(4))
def test_group_stats_match_the_per_group_loop(seed):
    """Group spreads by sums per group equal the per-group loop (censored, truncated and
    lone artefacts, groups with one whole stay); 100,000 groups take no quadratic time."""
    from are_stats.fitting._traffic import _group_stats
    from are_stats.traffic import LifecycleData

    rng = np.random.default_rng(seed)
    n = 3000
    group = rng.integers(0, 900, n)
    ta = np.sort(rng.uniform(0, 1000, n))
    tl = ta + rng.exponential(30, n)
    trunc, cens = rng.random(n) < 0.1, tl > 990
    data = LifecycleData(
        t_arrive=np.where(trunc, np.nan, ta), t_leave=np.where(cens, np.nan, np.minimum(tl, 1000)),
        window=(0.0, 1000.0), area=100.0, x=rng.normal(0, 3, n), y=rng.normal(0, 3, n),
        group=group,
    )  # fmt: skip
    got, want = _group_stats(data), _group_stats_loop(data)
    assert got["group_stay_sd"] == pytest.approx(want["group_stay_sd"], rel=1e-9)
    assert got["group_spread"] == pytest.approx(want["group_spread"], rel=1e-9)
    assert got["group_stay_sd"] > 0 and got["group_spread"] > 0
    # many groups: linear work (the loop would scan 200,000 artefacts 100,000 times)
    big = LifecycleData(t_arrive=np.arange(200000.0), t_leave=np.arange(200000.0) + 5.0,
                        window=(-1.0, 300000.0), area=100.0, x=np.zeros(200000),
                        y=np.zeros(200000), group=np.arange(200000) // 2)  # fmt: skip
    assert _group_stats(big)["group_spread"] == 0.0


# ---- ranked by the Laplace approximation, the chosen model's Laplace draws importance-
# ---- resampled (NUTS where their weights are unreliable): the default --


@pytest.fixture(scope="module")
def ranked_fit(rich_log):
    data, _ = rich_log
    return fit_traffic(jax.random.key(0), data, paper=_paper(data), grid=_Grid(),
                       approximation="ranked", **NUTS)  # fmt: skip


def _assert_ranked_is_nuts(ranked_fit, nuts, names) -> None:
    """The chosen posterior is the NUTS posterior within Monte Carlo error."""
    for name in names:
        a, b = ranked_fit.posterior[name], nuts.posterior[name]
        assert a.shape == b.shape
        mc = 4.0 * b.std(axis=(0, 1)) / np.sqrt(b.shape[0] * b.shape[1] / 10.0)
        assert np.all(np.abs(a.mean(axis=(0, 1)) - b.mean(axis=(0, 1))) <= mc + 1e-12), name
        assert np.all(np.abs(a.std(axis=(0, 1)) / b.std(axis=(0, 1)) - 1.0) < 0.3), name


def test_ranked_fit_agrees_with_nuts(ranked_fit, stays_nuts_fit, rich_log):
    """Ranked by Laplace + importance-sampled PSIS-LOO, then the chosen model's Laplace
    draws importance-resampled (Pareto k below 0.7 here): the true models, the stay law as
    NUTS chooses it, and the chosen stay posterior is the NUTS posterior within Monte Carlo
    error (the arrival model's: the slow test below); the arrival parameters recover the
    truth within 5 posterior sd."""
    got = (ranked_fit.arrival_model, ranked_fit.lifetime_model, ranked_fit.position_model)
    assert got == ("groups", stays_nuts_fit.lifetime_model, stays_nuts_fit.position_model)
    assert "importance resampling" in ranked_fit.attrs["model_choice"]
    for attr in ("arrival_posterior", "lifetime_posterior"):
        assert ranked_fit.attrs[attr].startswith("importance-resampled Laplace"), attr
    _assert_ranked_is_nuts(ranked_fit, stays_nuts_fit, STAY_NAMES)
    _, truth = rich_log
    v = ranked_fit.posterior["event_rate"].ravel()
    assert abs(v.mean() - truth["event_rate"]) < 5 * v.std()
    p = ranked_fit.posterior["group_size_probs"]
    p = p.reshape(-1, p.shape[-1])[:, : truth["group_size_probs"].size]
    assert np.all(np.abs(p.mean(0) - truth["group_size_probs"]) < 5 * p.std(0))
    # no NUTS ran: no row carries NUTS diagnostics
    for factor in ("arrivals", "lifetimes"):
        assert not np.isfinite(ranked_fit.tables[factor]["r_hat"]).any()


@pytest.mark.slow  # the groups NUTS program; make test: test_ranked_fit_agrees_with_nuts
def test_ranked_arrival_posterior_is_the_nuts_posterior(ranked_fit, nuts_fit):
    """The ranked fit's choices are NUTS's, and its importance-resampled arrival (and stay)
    posterior is the NUTS posterior within Monte Carlo error."""
    got = (ranked_fit.arrival_model, ranked_fit.lifetime_model, ranked_fit.position_model)
    assert got == (nuts_fit.arrival_model, nuts_fit.lifetime_model, nuts_fit.position_model)
    names = ("event_rate", "stay_mean", "stay_shape", "group_size_probs")
    _assert_ranked_is_nuts(ranked_fit, nuts_fit, names)


@pytest.mark.slow  # every candidate by NUTS; make test: test_ranked_fit_agrees_with_nuts
def test_ranked_choice_is_the_all_nuts_choice_on_the_rich_log(ranked_fit, rich_fit):
    """The ranked fit's choices are those of sampling every candidate by NUTS."""
    got = (ranked_fit.arrival_model, ranked_fit.lifetime_model, ranked_fit.position_model)
    assert got == (rich_fit.arrival_model, rich_fit.lifetime_model, rich_fit.position_model)


@pytest.mark.parametrize(
    "arrivals, lifetimes, draw",
    [
        ("poisson", "exponential", {"event_rate": 1e-3, "stay_mean": 60.0}),
        ("negbin", "exponential", {"event_rate": 1e-3, "stay_mean": 60.0, "arrival_phi": 0.5}),
        ("poisson", "weibull", {"event_rate": 1e-3, "stay_mean": 60.0, "stay_shape": 0.6}),
        ("poisson", "lognormal", {"event_rate": 1e-3, "stay_mean": 60.0, "stay_shape": 1.2}),
    ],
)
@pytest.mark.slow  # 8 fits; make test: test_ranked_fit_agrees_with_nuts
def test_ranked_choice_is_the_all_nuts_choice_on_each_candidates_logs(arrivals, lifetimes, draw):
    """Logs drawn from each candidate (the rich log covers groups and gamma): ranking by
    the Laplace approximation chooses what sampling every candidate by NUTS chooses, with
    every candidate's elpd within a few nats of its NUTS value."""
    laws = TrafficLaws(arrivals=arrivals, lifetimes=lifetimes,
                       bin_width=60.0 if arrivals == "negbin" else None)  # fmt: skip
    data = simulate_traffic_log(np.random.default_rng(5), draw, laws, (0.0, 3600.0), AREA,
                                free=uniform_position_density(FREE, RES, ORIGIN),
                                resolution=0.4)  # fmt: skip
    fits = {
        how: fit_traffic(
            jax.random.key(3),
            data,
            paper=_paper(data),
            positions="uniform",
            approximation=how,
            **NUTS,
        )  # fmt: skip
        for how in ("nuts", "ranked")
    }
    nuts, ranked = fits["nuts"], fits["ranked"]
    assert (ranked.arrival_model, ranked.lifetime_model) == (arrivals, lifetimes)
    for factor, got, want in (
        ("arrivals", ranked.arrival_model, nuts.arrival_model),
        ("lifetimes", ranked.lifetime_model, nuts.lifetime_model),
    ):
        t = nuts.tables[factor]
        if got != want and t.loc[got, "r_hat"] > 1.05:
            # NUTS is no reference where its chains did not mix: on this Weibull log (shape
            # 0.6) its Weibull run sticks (r_hat ~4), so sampling every candidate chose gamma;
            # the ranked fit chose the true law and kept its (resampled) Laplace draws
            resampled = ranked.attrs[f"{factor[:-1]}_posterior"].startswith("importance-")
            assert resampled or any("did not mix" in w for w in ranked.warnings), ranked.attrs
            shape = float(ranked.posterior["stay_shape"].mean())
            assert abs(shape - draw["stay_shape"]) < 0.1, shape
            return
        assert got == want, (factor, got, want, t)
    for factor in ("arrivals", "lifetimes"):
        a, b = ranked.tables[factor], nuts.tables[factor]
        assert list(a.index) == list(b.index)
        assert np.all(np.abs(a["elpd"] - b["elpd"]) < 5.0 + 0.02 * b["se"]), (a, b)
    for name, v in nuts.posterior.items():
        w = ranked.posterior[name]
        mc = 4.0 * v.std(axis=(0, 1)) / np.sqrt(v.shape[0] * v.shape[1] / 10.0)
        assert np.all(np.abs(w.mean(axis=(0, 1)) - v.mean(axis=(0, 1))) <= mc + 1e-12), name


def test_an_unreliable_loo_does_not_set_the_bar():
    """A candidate whose PSIS-LOO has k > 0.7 on many units (its elpd too optimistic) is not
    the best the others are measured against; it may still be chosen where simplest."""
    from are_stats.fitting._traffic import choose_simplest, unreliable_loo

    rng = np.random.default_rng(0)
    base = rng.normal(-1.0, 0.3, 400)
    elpd = {"simple": base, "rich": base + 0.01, "shaky": base + 0.05}  # shaky: +20 nat
    ks = {
        "simple": np.zeros(400),
        "rich": np.zeros(400),
        "shaky": np.r_[np.ones(40), np.zeros(360)],
    }
    assert unreliable_loo(ks) == ["shaky"]
    chosen, table = choose_simplest(elpd, ["simple", "rich", "shaky"])
    assert chosen == "shaky"  # 20 nat over the others with a tiny standard error
    chosen, table = choose_simplest(elpd, ["simple", "rich", "shaky"], unreliable_loo(ks))
    assert chosen == "rich" and table.loc["rich", "elpd_diff"] == 0.0
    # an unreliable candidate simpler than the bar may still be chosen
    chosen, _ = choose_simplest(elpd, ["shaky", "simple", "rich"], ["shaky"])
    assert chosen == "shaky"


def test_laplace_candidates_in_threads_fit_as_one_at_a_time(
    monkeypatch, paper_log, paper_laplace_fit
):
    """The candidates' Laplace approximations run LAPLACE_THREADS at a time and are taken
    in order: the fit (draws, tables, notes, warnings) is the one a single thread gives.
    On the paper-truth log: two threads are the fixture's fit, whose candidates' programs
    this one-thread fit reuses."""
    import are_stats.fitting._traffic as traffic

    data = paper_log
    monkeypatch.setattr(traffic, "LAPLACE_THREADS", 1)
    one = fit_traffic(jax.random.key(3), data, paper=_paper(data), grid=_Grid(),
                      approximation="laplace")  # fmt: skip
    two = paper_laplace_fit
    assert sorted(one.posterior) == sorted(two.posterior)
    for name in one.posterior:
        np.testing.assert_array_equal(np.asarray(one.posterior[name]),
                                      np.asarray(two.posterior[name]))  # fmt: skip
    assert sorted(one.tables) == sorted(two.tables)
    for name in one.tables:
        pd.testing.assert_frame_equal(one.tables[name], two.tables[name])
    assert one.attrs == two.attrs and one.warnings == two.warnings
    assert (one.arrival_model, one.lifetime_model) == (two.arrival_model, two.lifetime_model)
