"""Where and when each class of a labelled log comes (issue 31): per-class entry densities
and class shares by time of day, fitted and generated."""

from __future__ import annotations

import jax
import numpy as np
import pandas as pd
import pytest
from PIL import Image

from are_stats.environment import OccupancyGrid
from are_stats.fitting import (
    FitSettings,
    class_position_densities,
    fit_class_positions,
    fit_class_shares_by_time,
    fit_log,
    motion_attrs,
    motion_tables,
    plot_class_checks,
    read_fit,
    traffic_draws,
    write_fit,
)
from are_stats.inputs import InputError
from are_stats.scenarios import generate_scenarios, read_scenes
from are_stats.traffic import DAY, LifecycleData, PositionDensity, TrafficLaws, fit_position_density
from tests.helpers import chisquare_gof
from tests.test_cli_jobs import _invoke

RES = 0.5
FREE = np.ones((40, 60), bool)  # 30 x 20 m, all free
#: Where each class enters: bicycles by the west edge, people by the north edge.
REGIONS = {0: ((0.0, 1.5), (2.0, 18.0)), 1: ((5.0, 25.0), (18.5, 20.0))}
EM = {"method": "em", "num_chains": 1, "arrivals": "poisson", "lifetimes": "exponential"}


def _entries(rng, cls):
    (x0, x1), (y0, y1) = REGIONS[0]
    (u0, u1), (v0, v1) = REGIONS[1]
    x = np.where(cls == 0, rng.uniform(x0, x1, cls.size), rng.uniform(u0, u1, cls.size))
    y = np.where(cls == 0, rng.uniform(y0, y1, cls.size), rng.uniform(v0, v1, cls.size))
    return np.column_stack([x, y])


def _mass_in(prob, region):
    (x0, x1), (y0, y1) = region
    yy, xx = np.mgrid[0 : prob.shape[0], 0 : prob.shape[1]]
    cx, cy = (xx + 0.5) * RES, (yy + 0.5) * RES
    return float(prob[(cx >= x0) & (cx <= x1) & (cy >= y0) & (cy <= y1)].sum())


def _day_share(t):
    """Truth: bicycles are 80% of the arrivals from 07:00 to 19:00, 20% otherwise."""
    hour = np.mod(t, DAY) // 3600
    return np.where((hour >= 7) & (hour < 19), 0.8, 0.2)


def test_recovers_per_class_entry_densities(rng):
    cls = rng.choice(2, 400, p=[0.6, 0.4])
    f = fit_class_positions(_entries(rng, cls), cls, ["bicycle", "person"], FREE, RES, (0, 0))
    assert f.model == "per-class" and list(f.table.index) == ["pooled", "per-class"]
    assert f.entry.shape == (2, 40, 60) and np.allclose(f.entry.sum((1, 2)), 1.0)
    for c in (0, 1):  # each class's mass sits where it enters, not where the other does
        assert _mass_in(f.entry[c], REGIONS[c]) > 0.85
        assert _mass_in(f.entry[c], REGIONS[1 - c]) < 0.1
    # one law for both classes: the pooled density is kept
    same = rng.choice(2, 400)
    g = fit_class_positions(_entries(rng, np.zeros(400, int)), same, ["a", "b"], FREE, RES, (0, 0))
    assert g.model == "pooled" and np.array_equal(g.entry[0], g.entry[1])


def test_a_class_seen_once_takes_the_pool_and_a_large_prior_mass_is_the_base(rng):
    cls = np.r_[np.zeros(150, int), np.ones(150, int), [2]]
    xy = _entries(rng, np.minimum(cls, 1))
    f = fit_class_positions(xy, cls, ["bicycle", "person", "cart"], FREE, RES, (0, 0))
    pooled = fit_position_density(xy, FREE, RES, (0, 0))
    assert f.model == "per-class" and np.isnan(f.alpha[2]) and f.n_points[2] == 1
    np.testing.assert_allclose(f.entry[2], pooled.prob)
    # the partial pooling's limit: a prior mass far above the points returns the base
    base = f.entry[0]
    d = fit_position_density(xy[:3], FREE, RES, (0, 0), alphas=(1e9,), base=base)
    np.testing.assert_allclose(d.prob, base, atol=1e-8)
    # and without a base the density is the uniform-prior one as before
    u = fit_position_density(xy, FREE, RES, (0, 0), base=FREE / FREE.sum())
    np.testing.assert_allclose(u.prob, pooled.prob, rtol=1e-12)


def test_recovers_class_shares_by_time_of_day(rng):
    t = np.sort(rng.uniform(0.0, 3 * DAY, 3000))
    cls = (rng.random(t.size) >= _day_share(t)).astype(np.int64)
    overall = rng.dirichlet(1.0 + np.bincount(cls, minlength=2), 2000)
    f = fit_class_shares_by_time(jax.random.key(0), t, cls, overall, 0.0)
    assert f.model == "time-of-day" and f.weights.shape == (2000, 24, 2)
    truth = _day_share(np.arange(24) * 3600.0 + 1.0)
    m, sd = f.weights[:, :, 0].mean(0), f.weights[:, :, 0].std(0)
    assert np.all(np.abs(m - truth) < 4 * sd)  # k-sigma recovery, every hour
    assert f.counts.sum() == t.size
    # constant shares over the day: one set is kept
    flat = (rng.random(t.size) >= 0.5).astype(np.int64)
    g = fit_class_shares_by_time(jax.random.key(1), t, flat, rng.dirichlet([1500, 1500], 2000), 0.0)
    assert g.model == "constant"
    # a log inside one hour says nothing about the day: the counts are not used twice, so
    # the hour's shares are no sharper than the day's and the constant shares are kept
    one = np.sort(rng.uniform(0.0, 3000.0, 400))
    c1 = (rng.random(one.size) >= 0.3).astype(np.int64)
    day = rng.dirichlet(1.0 + np.bincount(c1, minlength=2), 2000)
    h = fit_class_shares_by_time(jax.random.key(2), one, c1, day, 8 * 3600.0)
    assert h.model == "constant" and h.ess > 500
    sd_day, sd_hour = day[:, 0].std(), h.weights[:, 8, 0].std()
    assert abs(sd_hour / sd_day - 1.0) < 0.15


def test_generated_shares_vary_over_the_day_as_fitted():
    tod = np.tile(np.array([0.2, 0.8]), (24, 1))
    tod[7:19] = [0.8, 0.2]
    params = {
        "arrival_rate": 0.001,
        "leave_rate": 1 / 30.0,
        "class_weights": [0.5, 0.5],
        "class_tod_weights": tod[None],
    }
    laws = TrafficLaws(clock_offset=6 * 3600.0)  # t = 0 at 06:00
    df = generate_scenarios(3, params, 5, DAY, area=100.0, start="empty", laws=laws)
    hour = np.mod(df["t_arrive"].to_numpy() + 6 * 3600.0, DAY) // 3600
    day = (hour >= 7) & (hour < 19)
    cls = df["class"].to_numpy()
    assert day.sum() > 1000 and (~day).sum() > 1000
    for sel, p0 in ((day, 0.8), (~day, 0.2)):  # seeded chi-square (ALPHA = 1e-3)
        chisquare_gof(cls[sel], lambda k, p0=p0: np.where(k == 0, p0, np.where(k == 1, 1 - p0, 0)))
    # without the clock the day's shares are the overall ones
    flat = generate_scenarios(3, params, 5, DAY, area=100.0, start="empty")
    chisquare_gof(flat["class"].to_numpy(), lambda k: np.where(k < 2, 0.5, 0.0))


def test_generated_entries_follow_each_class_density(rng):
    cls = rng.choice(2, 400)
    f = fit_class_positions(_entries(rng, cls), cls, ["bicycle", "person"], FREE, RES, (0, 0))
    dens = tuple(PositionDensity(p, RES, (0.0, 0.0), 0.0, np.nan) for p in f.entry)
    params = {"arrival_rate": 0.002, "leave_rate": 0.1, "class_weights": [0.5, 0.5]}
    laws = TrafficLaws(class_entry=dens)
    grid = OccupancyGrid(np.zeros(FREE.shape, np.int8), RES, (0.0, 0.0, 0.0))
    df = generate_scenarios(5, params, 10, 600.0, free_mask=grid, laws=laws)
    arrived = df[~df["truncated"]]
    assert len(arrived) > 500
    for c in (0, 1):
        a = arrived[arrived["class"] == c]
        (x0, x1), (y0, y1) = REGIONS[c]
        inside = a["x"].between(x0 - 1, x1 + 1) & a["y"].between(y0 - 1, y1 + 1)
        assert inside.mean() > 0.85
    with pytest.raises(ValueError, match="an entry density per class"):
        generate_scenarios(
            5, {**params, "class_weights": [0.3, 0.3, 0.4]}, 3, 600.0, free_mask=grid, laws=laws
        )


def _mixed_log(rng, days=2.0, n=2400):
    t1 = days * DAY
    ta = np.sort(rng.uniform(0.0, t1, n))
    cls = (rng.random(n) >= _day_share(ta)).astype(np.int64)
    tl = ta + rng.exponential(20.0, n)
    xy = _entries(rng, cls)
    data = LifecycleData(
        t_arrive=ta,
        t_leave=np.where(tl > t1, np.nan, tl),
        window=(0.0, t1),
        area=600.0,
        x=xy[:, 0],
        y=xy[:, 1],
    )
    return data, cls


def _fit_mixed(data, cls, num_samples):
    """The fit of a mixed log on the open test map, clocked from midnight."""
    grid = OccupancyGrid(np.zeros(FREE.shape, np.int8), RES, (0.0, 0.0, 0.0))
    s = FitSettings(num_samples=num_samples, positions="auto", **EM)
    return fit_log(
        jax.random.key(0),
        data,
        s,
        class_labels=["bicycle", "person"],
        classes=cls,
        grid=grid,
        clock_start="2026-01-01T00:00:00",
    ).idata


def test_labelled_fit_with_map_and_clock_generates_per_class(tmp_path, rng):
    data, cls = _mixed_log(rng)
    grid = OccupancyGrid(np.zeros(FREE.shape, np.int8), RES, (0.0, 0.0, 0.0))
    idata = _fit_mixed(data, cls, 400)
    write_fit(idata, tmp_path / "fit.nc")
    back = read_fit(tmp_path / "fit.nc").idata
    a = back.posterior.attrs
    assert a["class_position_model"] == "per-class" and a["class_share_model"] == "time-of-day"
    assert back.constant_data["class_entry_density"].dims == ("class", "pos_y", "pos_x")
    assert len(class_position_densities(back)) == 2
    draws, laws = traffic_draws(back)
    assert draws["class_tod_weights"].shape == (400, 24, 2) and laws.class_entry is not None
    df = generate_scenarios(1, draws, 20, DAY, free_mask=grid, laws=laws)
    df = df[~df["truncated"]]
    hour = np.mod(df["t_arrive"].to_numpy(), DAY) // 3600
    day = (hour >= 7) & (hour < 19)
    bikes = df["class"].to_numpy() == 0
    assert abs(bikes[day].mean() - 0.8) < 0.03 and abs(bikes[~day].mean() - 0.2) < 0.03
    for c in (0, 1):
        a = df[df["class"] == c]
        (x0, x1), (y0, y1) = REGIONS[c]
        inside = a["x"].between(x0 - 1, x1 + 1) & a["y"].between(y0 - 1, y1 + 1)
        assert inside.mean() > 0.85


def test_a_log_without_labels_gets_no_class_traffic(rng):
    data, _ = _mixed_log(rng, days=1.0, n=600)
    grid = OccupancyGrid(np.zeros(FREE.shape, np.int8), RES, (0.0, 0.0, 0.0))
    s = FitSettings(num_samples=200, positions="auto", **EM)
    idata = fit_log(jax.random.key(0), data, s, grid=grid, clock_start="2026-01-01T00:00:00").idata
    names = [*idata.posterior.data_vars, *idata.constant_data.data_vars, *idata.posterior.attrs]
    assert not [n for n in names if "class_" in str(n)]
    draws, laws = traffic_draws(idata)
    assert laws.class_entry is None and not [n for n in draws if n.startswith("class_")]
    df = generate_scenarios(2, draws, 3, 600.0, free_mask=grid, laws=laws)
    assert (df["class"] == -1).all()


def _csv_mixed_log(folder, rng, n=1500):
    """A labelled log of two days with entry points, a map and a clock (CSV + manifest)."""
    data, cls = _mixed_log(rng, days=2.0, n=n)
    t1 = data.window[1]
    tl = np.asarray(data.t_leave)
    df = pd.DataFrame(
        {
            "id": [f"a{i}" for i in range(data.n)],
            "t_arrive": np.round(data.t_arrive, 3),
            "t_leave": np.where(np.isfinite(tl), np.round(tl, 3).astype(str), ""),
            "x": np.round(data.x, 3),
            "y": np.round(data.y, 3),
            "label": np.array(["bicycle", "person"])[cls],
        }
    )
    df.to_csv(folder / "mixed.csv", index=False)
    Image.fromarray(np.full(FREE.shape, 254, np.uint8)).save(folder / "m.pgm")
    (folder / "m.yaml").write_text(
        "image: m.pgm\nresolution: 0.5\norigin: [0, 0, 0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    (folder / "mixed.yaml").write_text(
        f"window: [0, {t1}]\nmap: m.yaml\nclock_start: '2026-01-01T00:00:00'\n"
    )
    return folder / "mixed.csv"


@pytest.mark.slow
def test_cli_log_fit_generate_report_per_class(tmp_path, rng):
    log = _csv_mixed_log(tmp_path, rng)
    fit = tmp_path / "fit.nc"
    res = _invoke(
        [
            "fit",
            log,
            "--out",
            fit,
            "--method",
            "em",
            "--samples",
            "200",
            "--chains",
            "1",
            "--arrivals",
            "poisson",
            "--lifetimes",
            "exponential",
            "--no-figures",
        ]
    )
    assert res.exit_code == 0, res.output
    text = " ".join(res.output.split())
    assert "entry/exit densities per-class, shares time-of-day" in text
    assert "bicycle" in text and "/h, mean stay" in text
    res = _invoke(
        [
            "generate",
            fit,
            "--scenarios",
            "10",
            "--horizon",
            str(DAY),
            "--seed",
            "1",
            "--out",
            tmp_path / "scen",
            "--map",
            tmp_path / "m.yaml",
        ]
    )
    assert res.exit_code == 0, res.output
    df, manifest, _ = read_scenes(tmp_path / "scen")
    assert manifest["class_labels"] == ["bicycle", "person"]
    df = df[~df["truncated"]]
    hour = np.mod(df["t_arrive"].to_numpy(), DAY) // 3600
    day = (hour >= 7) & (hour < 19)
    bikes = df["class"].to_numpy() == 0
    assert abs(bikes[day].mean() - 0.8) < 0.04 and abs(bikes[~day].mean() - 0.2) < 0.04
    west = df["x"].to_numpy() < 2.5
    assert west[bikes].mean() > 0.85 and west[~bikes].mean() < 0.1
    res = _invoke(["report", fit, "--out", tmp_path / "rep", "--replicates", "50"])
    assert res.exit_code == 0, res.output
    rep = tmp_path / "rep"
    for name in ("ppc_classes.png", "ppc_class_shares_by_hour.png", "class_entries.png"):
        assert (rep / name).stat().st_size > 10_000, name
    by_hour = pd.read_csv(rep / "class_shares_by_hour.csv", index_col=[0, 1])
    assert by_hour.loc[("bicycle", 10), "observed"] > 0.6
    assert by_hour.loc[("bicycle", 22), "observed"] < 0.4
    assert by_hour["model_flag"].mean() < 0.25  # 48 rows, 90% bands
    loo = pd.read_csv(rep / "loo_class_shares.csv", index_col=0)
    assert bool(loo.loc["time-of-day", "chosen"])


def test_class_figures_draw_the_stored_motion_rows():
    idx = pd.MultiIndex.from_product(
        [["bicycle", "person"], ["share"]], names=["class", "statistic"]
    )
    cols = {
        "observed": [0.4, 0.6],
        "model_5%": [0.3, 0.5],
        "model_50%": [0.4, 0.6],
        "model_95%": [0.5, 0.7],
        "model_flag": [False, False],
    }
    traffic = pd.DataFrame(cols, index=idx)
    motion = traffic.rename(index={"share": "median speed (m/s)"}) * 1.0
    motion["model_flag"] = [True, False]
    back = motion_tables(motion_attrs(class_motion=motion.reset_index()))["class_motion"]
    back = back.set_index(["class", "statistic"])
    pd.testing.assert_frame_equal(back, motion, check_dtype=False)
    fig = plot_class_checks(traffic, back)
    assert [ax.get_title() for ax in fig.axes] == ["share", "median speed (m/s)"]


def test_per_class_entries_on_another_map_are_refused(rng):
    cls = rng.choice(2, 200)
    f = fit_class_positions(_entries(rng, cls), cls, ["bicycle", "person"], FREE, RES, (0, 0))
    dens = tuple(PositionDensity(p, RES, (0.0, 0.0), 0.0, np.nan) for p in f.entry)
    far = OccupancyGrid(np.zeros(FREE.shape, np.int8), RES, (100.0, 100.0, 0.0))
    params = {"arrival_rate": 0.002, "leave_rate": 0.1, "class_weights": [0.5, 0.5]}
    with pytest.raises(ValueError, match="^map: expected the map the fit learned its entry"):
        generate_scenarios(1, params, 2, 600.0, free_mask=far, laws=TrafficLaws(class_entry=dens))
    # a map read from a file is named by it (the check only had the grid: "map:")
    far = OccupancyGrid(far.data, RES, (100.0, 100.0, 0.0), source="far.yaml")
    with pytest.raises(ValueError, match="^far.yaml: expected the map the fit learned its entry"):
        generate_scenarios(1, params, 2, 600.0, free_mask=far, laws=TrafficLaws(class_entry=dens))


def test_read_fit_names_damaged_class_traffic(tmp_path, rng):
    data, cls = _mixed_log(rng, days=1.0, n=600)
    idata = _fit_mixed(data, cls, 100)
    write_fit(idata, tmp_path / "ok.nc")
    read_fit(tmp_path / "ok.nc")
    bad = idata.copy()
    bad.posterior["class_tod_weights"] = bad.posterior["class_tod_weights"] * 2.0
    write_fit(bad, tmp_path / "tod.nc")
    with pytest.raises(InputError, match="class_tod_weights.*summing to 1"):
        read_fit(tmp_path / "tod.nc")
    bad = idata.copy()
    one = bad.constant_data["class_entry_density"].isel({"class": [0]})  # one class of two
    bad.constant_data = bad.constant_data.drop_vars("class_entry_density").assign(
        class_entry_density=one
    )
    write_fit(bad, tmp_path / "dens.nc")
    with pytest.raises(InputError, match="class_entry_density.*one per class"):
        read_fit(tmp_path / "dens.nc")


def test_a_class_seen_thrice_borrows_the_other_classes_entries(rng):
    # carts enter three times, by the bicycles' west edge: alone they would say "only there";
    # pooled toward the others they keep mass where the others enter
    cls = np.r_[np.zeros(200, int), np.ones(200, int), [2, 2, 2]]
    xy = _entries(rng, np.minimum(cls, 1))
    xy[-3:] = _entries(rng, np.zeros(3, int))
    f = fit_class_positions(xy, cls, ["bicycle", "person", "cart"], FREE, RES, (0, 0))
    assert f.alpha[2] >= 10.0  # the prior mass outweighs its three points
    alone = fit_position_density(xy[-3:], FREE, RES, (0, 0))
    assert _mass_in(alone.prob, REGIONS[1]) < 0.05
    assert _mass_in(f.entry[2], REGIONS[1]) > 0.2
    assert _mass_in(f.entry[2], REGIONS[0]) > _mass_in(f.entry[1], REGIONS[0]) + 0.2
