"""Logs that name their classes (labels, no marks; issue 31): shares and stays per class."""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest

from are_stats.environment import load_catalogue
from are_stats.fitting import (
    CLASS_STATISTICS,
    FitSettings,
    NoWalkersError,
    class_checks,
    class_motion_checks,
    fit_behaviour,
    fit_class_labels,
    fit_classes,
    fit_log,
    read_fit,
    traffic_draws,
    write_fit,
)
from are_stats.fitting._classes import _loglik
from are_stats.inputs import InputError
from are_stats.logs import read_lifecycle_log
from are_stats.scenarios import generate_scenarios, scenes_from_fit
from are_stats.traffic import LifecycleData, TrafficLaws, stay_loglik
from tests.fitting.test_behaviour_fit import _model_tracks
from tests.helpers import chisquare_gof
from tests.test_cli_jobs import _invoke

LABELS = ["bicycle", "cart", "person"]
PAPER = {"arrivals": "poisson", "lifetimes": "exponential", "positions": "uniform"}


def _mixed_log(rng, n, shares, means, window=20000.0):
    """Arrivals uniform on the window, exponential stays of each class's mean; censored at t1."""
    cls = rng.choice(len(shares), n, p=shares)
    ta = np.sort(rng.uniform(0.0, window, n))
    tl = ta + rng.exponential(np.asarray(means)[cls])
    tl = np.where(tl > window, np.nan, tl)
    return LifecycleData(t_arrive=ta, t_leave=tl, window=(0.0, window), area=100.0), cls


def test_recovers_class_shares_and_stay_means(rng):
    shares, means = np.array([0.34, 0.11, 0.55]), np.array([6.8, 30.0, 18.0])
    data, cls = _mixed_log(rng, 4000, shares, means)
    f = fit_classes(jax.random.key(0), data, cls, LABELS, n_draws=2000)
    assert f.weights.shape == (2000, 3) and np.allclose(f.weights.sum(1), 1.0)
    # 4 posterior sd (k-sigma recovery against the truth)
    assert np.all(np.abs(f.weights.mean(0) - shares) < 4 * f.weights.std(0))
    log_m = np.log(f.stay_mean)
    assert np.all(np.abs(log_m.mean(0) - np.log(means)) < 4 * log_m.std(0) + 0.02)
    assert f.stay_model == "per-class"  # the classes differ: LOO prefers them
    assert list(f.table.index) == ["pooled", "per-class"]


def test_one_law_for_all_classes_is_kept_pooled(rng):
    data, cls = _mixed_log(rng, 1500, [0.5, 0.2, 0.3], [12.0, 12.0, 12.0])
    f = fit_classes(jax.random.key(1), data, cls, LABELS, n_draws=1000)
    assert f.stay_model == "pooled"


def test_a_class_seen_twice_shrinks_toward_the_pool(rng):
    # two large classes around 10-12 s and one seen twice, staying 200 s both times: on its
    # own (flat prior on the log mean) its rate's posterior is Gamma(2, 400), the median
    # mean stay 400 / 1.678 = 238 s
    data, cls = _mixed_log(rng, 2000, [0.5, 0.0, 0.5], [10.0, 1.0, 12.0])
    ta = np.concatenate([data.t_arrive, [100.0, 5000.0]])
    tl = np.concatenate([data.t_leave, [300.0, 5200.0]])
    data2 = LifecycleData(t_arrive=ta, t_leave=tl, window=data.window, area=100.0)
    cls2 = np.concatenate([cls, [1, 1]])
    f = fit_classes(jax.random.key(2), data2, cls2, LABELS, n_draws=4000)
    rare = np.median(f.stay_mean[:, 1])
    pool = np.median(f.pool_mean)
    assert 8.0 < pool < 60.0
    assert pool < rare < 0.7 * 238.0  # pulled well below 238 s, toward the pool
    # the well-observed classes barely move
    assert abs(np.median(f.stay_mean[:, 0]) - 10.0) < 1.5
    assert abs(np.median(f.stay_mean[:, 2]) - 12.0) < 1.5


@pytest.mark.parametrize("law", ["exponential", "gamma", "weibull", "lognormal"])
def test_numpy_stay_likelihood_equals_the_stay_law(rng, law):
    d = rng.exponential(5.0, 300)
    d[:20] = 0.05  # shorter than the resolution
    cen, tru = rng.random(300) < 0.3, rng.random(300) < 0.3
    m = np.array([[0.5], [3.0], [40.0]])
    k = np.array([[0.4], [2.0], [30.0]]) / (20.0 if law == "lognormal" else 1.0)
    # the law in one compiled program (eager, each of its few hundred operations compiled
    # on its own: 7 s of CPU cold for the gamma law's incomplete gamma, 4 s jitted)
    ref = jax.jit(stay_loglik, static_argnums=(0, 6))(law, d[None], cen[None], tru[None], m, k, 0.1)
    assert np.allclose(_loglik(law, d[None], cen[None], tru[None], m, k, 0.1), ref, atol=1e-8)


def test_unknown_label_is_a_clear_error():
    q = load_catalogue()
    assert {"bicycle", "skater", "cart"} <= set(q.labels)
    assert q.rows_of_labels(["person", "bicycle"]).tolist() == [
        q.labels.index("person"),
        q.labels.index("bicycle"),
    ]
    with pytest.raises(
        InputError,
        match=r"log.csv: column 'label': expected class labels of "
        r"the artefact catalogue \(person, .*bicycle.*\); to add one.*append a "
        r"row.*hoverboard.*got the unknown label\(s\) 'hoverboard'",
    ):
        q.rows_of_labels(["person", "hoverboard"], "log.csv", "column 'label'")


def test_new_rows_have_boxes_of_real_size():
    q = load_catalogue()
    bike, skater = q["bicycle"], q["skater"]
    assert 1.6 < 2 * bike.half_extents[0] < 1.9 and 1.5 < 2 * bike.half_extents[2] < 1.9
    assert 0.7 < 2 * skater.half_extents[0] < 0.9 and 2 * skater.half_extents[2] > 1.6
    assert q.run_thresholds()["bicycle"] > 5.0 and q.run_thresholds()["person"] == 2.5


def _csv_log(tmp_path, rng, labels=True, n=300):
    shares, means = [0.34, 0.11, 0.55], [6.8, 30.0, 18.0]
    cls = rng.choice(3, n, p=shares)
    ta = np.sort(rng.uniform(0, 3600.0, n)).round(3)
    tl = (ta + rng.exponential(np.asarray(means)[cls])).round(3)
    df = pd.DataFrame(
        {
            "id": [f"a{i}" for i in range(n)],
            "t_arrive": ta,
            "t_leave": np.where(tl > 3600, "", tl.astype(str)),
        }
    )
    if labels:
        df["label"] = np.asarray(LABELS)[cls]
    p = tmp_path / ("mixed.csv" if labels else "plain.csv")
    df.to_csv(p, index=False)
    p.with_suffix(".yaml").write_text("window: [0, 3600]\narea: 200\n")
    return p


def test_labelled_log_fit_generate_end_to_end(tmp_path, rng):
    log = read_lifecycle_log(_csv_log(tmp_path, rng))
    codes, names = log.label_classes()
    assert names == sorted(LABELS)
    data = log.to_lifecycle_data()
    assert data.marks is None and data.labels is None
    s = FitSettings(method="em", num_samples=500, num_chains=1, **PAPER)
    idata = fit_log(jax.random.key(0), data, s, class_labels=names, classes=codes).idata
    write_fit(idata, tmp_path / "fit.nc")
    back = read_fit(tmp_path / "fit.nc").idata
    post = back.posterior
    assert fit_class_labels(back) == names
    assert post["class_weights"].dims == ("chain", "draw", "class")
    assert post["class_weights"].shape == (1, 500, 3)
    assert post.attrs["class_stay_model"] in ("pooled", "per-class")
    draws, _ = traffic_draws(back)
    assert "class_weights" in draws
    scenes = scenes_from_fit(1, back, None, load_catalogue(), 5, 3600.0)
    labels = {str(v) for sc in scenes for v in sc.labels}
    assert labels <= set(LABELS) and "person" in labels and "bicycle" in labels
    cls = np.concatenate([sc.artefacts["class"].to_numpy() for sc in scenes])
    assert cls.min() >= 0 and cls.max() <= 2
    # the report's per-class rows: the log's shares beside the model's bands
    table = class_checks(0, back, 100)
    assert list(table.index.levels[0]) == names and set(CLASS_STATISTICS) == set(
        table.index.levels[1]
    )
    arrived = ~log.to_arrays()["truncated"]
    for c, name in enumerate(names):
        share = np.mean(codes[arrived] == c)
        assert table.loc[(name, "share"), "observed"] == pytest.approx(share)
    assert table["model_flag"].sum() <= 2  # 9 rows, 90% bands


def test_class_motion_rows_against_hand_counts():
    tracks = pd.DataFrame(
        {
            "id": ["a", "a", "b", "b", "c", "c"],
            "t": [0, 1, 0, 1, 0, 1],
            "x": 0.0,
            "y": 0.0,
            "label": ["bicycle"] * 2 + ["person"] * 4,
        }
    )
    obs = pd.DataFrame(
        {"speed": [4.0, 1.2, 1.4], "still": [False, False, True]},
        index=pd.Index(["a", "b", "c"], name="id"),
    )
    rep_index = pd.MultiIndex.from_tuples(
        [(r, i) for r in range(3) for i in "abc"], names=["scenario", "id"]
    )
    rep = pd.DataFrame(
        {"speed": [3.0, 1.0, 1.0, 4.0, 1.5, 1.1, 5.0, 1.2, 1.3], "still": [False, True, True] * 3},
        index=rep_index,
    )
    table = class_motion_checks(tracks, {"observed": obs, "tracks": rep})
    assert table.loc[("bicycle", "median speed (m/s)"), "observed"] == 4.0
    assert table.loc[("person", "median speed (m/s)"), "observed"] == pytest.approx(1.3)
    assert table.loc[("person", "fraction still"), "observed"] == 0.5
    assert table.loc[("bicycle", "median speed (m/s)"), "model_50%"] == 4.0
    assert table.loc[("person", "fraction still"), "model_50%"] == 1.0
    assert class_motion_checks(tracks.drop(columns="label"), {}) is None


def test_a_log_without_labels_is_fitted_as_before(tmp_path, rng):
    p = _csv_log(tmp_path, rng, labels=False)
    log = read_lifecycle_log(p)
    assert log.label_classes() is None
    data = log.to_lifecycle_data()
    s = FitSettings(method="em", num_samples=200, num_chains=1, **PAPER)
    plain = fit_log(jax.random.key(0), data, s).idata
    assert not [v for v in plain.posterior.data_vars if str(v).startswith("class_")]
    assert "class_labels" not in plain.posterior.attrs
    # the class fit comes after the pooled one and leaves its draws as they were
    codes = rng.integers(0, 3, data.n)
    labelled = fit_log(jax.random.key(0), data, s, class_labels=LABELS, classes=codes).idata
    for name in ("arrival_rate", "leave_rate"):
        assert np.array_equal(plain.posterior[name].values, labelled.posterior[name].values)
    # and so are the scenarios of a fit without classes
    a = generate_scenarios(3, traffic_draws(plain)[0], 20, 600.0, area=200.0)
    assert (a["class"] == -1).all() and (a["mark"] == -1).all()


def test_generated_class_shares_and_stays_follow_the_fit():
    w = np.array([0.34, 0.11, 0.55])
    m = np.array([6.8, 30.0, 18.0])
    params = {
        "arrival_rate": 0.002,
        "leave_rate": 1 / 15.0,
        "class_weights": w,
        "class_stay_mean": m,
    }
    df = generate_scenarios(7, params, 50, 3600.0, area=100.0, start="empty")
    cls = df["class"].to_numpy()
    assert df["mark"].eq(-1).all() and len(df) > 10000
    # seeded chi-square test of the generated classes against the shares (ALPHA = 1e-3)
    chisquare_gof(cls, lambda k: np.where(k < 3, w[np.minimum(k, 2)], 0.0))
    stay = (df["t_leave"] - df["t_arrive"]).to_numpy()
    for c in range(3):
        s = stay[cls == c]  # exponential: sd of the mean is m / sqrt(n)
        assert abs(s.mean() - m[c]) < 4 * m[c] / np.sqrt(s.size)
    # the initial population's classes follow shares x mean stays (stationary composition)
    df0 = generate_scenarios(8, params, 400, 10.0, area=100.0)
    c0 = df0.loc[df0["truncated"], "class"].to_numpy()
    comp = w * m / np.sum(w * m)
    chisquare_gof(c0, lambda k: np.where(k < 3, comp[np.minimum(k, 2)], 0.0))


def test_regular_stays_per_class_get_their_own_shape(rng):
    # crossing times: cv 0.1 within each class, means 7 and 22 s (pooled cv about 0.5)
    n, window = 1500, 20000.0
    cls = rng.choice(2, n, p=[0.5, 0.5])
    means = np.array([7.0, 22.0])
    ta = np.sort(rng.uniform(0.0, window - 100.0, n))
    tl = ta + rng.gamma(100.0, means[cls] / 100.0)
    data = LifecycleData(t_arrive=ta, t_leave=tl, window=(0.0, window), area=100.0)
    f = fit_classes(jax.random.key(3), data, cls, ["bicycle", "person"], law="gamma", n_draws=1000)
    assert f.stay_model == "per-class"
    cv = 1.0 / np.sqrt(np.median(f.stay_shape))
    assert 0.07 < cv < 0.14  # the grid's shapes are 30% apart
    assert 1.0 / np.sqrt(np.median(f.pooled_shape)) > 0.4
    # generation draws each class's stays from its mean and the shared shape

    params = {
        "arrival_rate": 0.002,
        "leave_rate": 1 / 15.0,
        "stay_mean": 15.0,
        "stay_shape": 4.0,
        "class_weights": [0.5, 0.5],
        "class_stay_mean": means,
        "class_stay_shape": np.median(f.stay_shape),
    }
    df = generate_scenarios(5, params, 20, 3600.0, area=100.0, laws=TrafficLaws(lifetimes="gamma"))
    arrived = ~df["truncated"].to_numpy()
    stay = (df["t_leave"] - df["t_arrive"]).to_numpy()
    for c in range(2):
        s = stay[arrived & (df["class"].to_numpy() == c)]
        assert abs(s.mean() / means[c] - 1.0) < 0.03 and 0.07 < s.std() / s.mean() < 0.14


def test_cli_fit_refuses_a_label_the_catalogue_lacks(tmp_path, rng):
    p = _csv_log(tmp_path, rng, n=30)
    df = pd.read_csv(p, keep_default_na=False)
    df.loc[3, "label"] = "hoverboard"
    df.to_csv(p, index=False)
    res = _invoke(["fit", p, "--out", tmp_path / "f.nc", "--method", "em", "--no-figures"])
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert "column 'label': expected class labels of the artefact catalogue" in text
    assert "hoverboard" in text and "Traceback" not in res.output
    assert not (tmp_path / "f.nc").exists()


def test_marks_and_labels_keep_the_mixture(tmp_path, rng):
    p = _csv_log(tmp_path, rng, n=40)
    df = pd.read_csv(p, keep_default_na=False)
    df["mark"] = rng.poisson(3.0, len(df))
    df.to_csv(p, index=False)
    log = read_lifecycle_log(p)
    assert log.label_classes() is None  # the labels are the mixture's components
    data = log.to_lifecycle_data()
    assert data.labels is not None and data.marks is not None
    # a label on some rows only is refused, naming the artefact
    df = df.drop(columns="mark")
    df.loc[5, "label"] = ""
    df.to_csv(p, index=False)
    with pytest.raises(ValueError, match=r"artefact 'a5', column 'label': expected a label on"):
        read_lifecycle_log(p).label_classes()


@pytest.mark.slow  # a soft-policy fit (about 50 s on a busy 2-core machine)
def test_cyclists_ride_at_their_speed_rather_than_all_run():
    # one cell (1 m) per 0.25 s: every cyclist moves at 4 m/s, above the people's 2.5 m/s
    tracks, free = _model_tracks(0, 2.0, 0.1, dt=0.25, n=30)
    tracks["label"] = "bicycle"
    with pytest.raises(NoWalkersError, match="bicycle"):
        fit_behaviour(tracks, free, 1.0, (0.0, 0.0), cell=1.0, max_fit_tracks=3)
    thresholds = load_catalogue().run_thresholds()
    fit = fit_behaviour(
        tracks, free, 1.0, (0.0, 0.0), cell=1.0, max_fit_tracks=3, run_speed=thresholds
    )
    assert fit.classes == ("bicycle",) and fit.run_fraction[0] == 0.0
    assert abs(np.exp(fit.speed_mu[0]) - 4.0) < 0.5
