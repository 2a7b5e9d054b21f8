"""Scenario generator against the laws it must reproduce (seeded; false-failure rate ALPHA=1e-3
per goodness-of-fit check), byte-identical output and argument errors."""

from __future__ import annotations

import hashlib

import jax
import numpy as np
import pandas as pd
import pytest
from scipy import stats

from are_stats._atomic import OutputExistsError
from are_stats.fitting import posterior_draws
from are_stats.inputs import InputError, LimitError, limits
from are_stats.scenarios import (
    SCENARIO_COLUMNS,
    ScenarioSize,
    atomic_folder,
    check_scenario_size,
    expected_artefacts,
    generate_scenarios,
    read_scenes,
    scenario_counts,
    write_scenes,
)
from tests.helpers import ALPHA, chisquare_gof

MU = 1 / 600.0  # mean lifetime 10 min
AREA = 400.0
LAM = 12 * MU / AREA  # 12 artefacts alive on average
W = np.array([0.2, 0.3, 0.5])
R = np.array([15.0, 3.0, 7.0])


def params(s=1, lam=LAM, mu=MU):
    return {
        "arrival_rate": np.full(s, lam),
        "leave_rate": np.full(s, mu),
        "mix_weights": np.tile(W, (s, 1)),
        "mix_rates": np.tile(R, (s, 1)),
    }


@pytest.fixture(scope="module")
def big():
    return generate_scenarios(11, params(), 4000, 3600.0, area=AREA)


def test_columns_and_order(big):
    assert list(big.columns) == list(SCENARIO_COLUMNS)
    sc = big["scenario"].to_numpy()
    assert np.all(np.diff(sc) >= 0)
    for _, g in big[big["scenario"] < 20].groupby("scenario"):
        assert g["artefact"].tolist() == list(range(len(g)))
        assert np.all(np.diff(g["t_arrive"].to_numpy()) >= 0)
    assert (big.loc[big["truncated"], "t_arrive"] == 0).all()
    assert ((big["t_arrive"] >= 0) & (big["t_arrive"] <= 3600)).all()
    assert (big["censored"] == (big["t_leave"] > 3600)).all()


@pytest.mark.parametrize("t", [0.0, 1800.0, 3599.0])
def test_stationary_count_law(big, t):
    n = scenario_counts(big, [t])[:, 0]
    assert n.shape == (4000,)
    chisquare_gof(n, lambda k: stats.poisson.pmf(k, LAM * AREA / MU))


def test_empty_start_transient_law():
    df = generate_scenarios(5, params(), 4000, 900.0, area=AREA, start="empty")
    t = 600.0
    n = scenario_counts(df, [t])[:, 0]
    mean = LAM * AREA / MU * (1 - np.exp(-MU * t))  # DECISIONS 2 with n0 = 0
    chisquare_gof(n, lambda k: stats.poisson.pmf(k, mean))
    assert not df["truncated"].any()


def test_marks_classes_lifetimes_and_arrival_times(big):
    marks = big["mark"].to_numpy()
    chisquare_gof(marks, lambda k: (W[:, None] * stats.poisson.pmf(k[None, :], R[:, None])).sum(0))
    chisquare_gof(big["class"].to_numpy(), lambda k: np.where(k < 3, W[np.minimum(k, 2)], 0.0))
    for c in range(3):  # each class draws from its own component
        mk = marks[big["class"].to_numpy() == c][:20000]
        chisquare_gof(mk, lambda k, c=c: stats.poisson.pmf(k, R[c]))
    life = (big["t_leave"] - big["t_arrive"]).to_numpy()
    assert stats.kstest(life, stats.expon(scale=1 / MU).cdf).pvalue > ALPHA
    arr = big.loc[~big["truncated"], "t_arrive"].to_numpy()
    assert stats.kstest(arr, stats.uniform(0, 3600).cdf).pvalue > ALPHA
    # arrivals per scenario ~ Poisson(lambda * area * horizon)
    n_arr = np.bincount(big.loc[~big["truncated"], "scenario"], minlength=4000)
    chisquare_gof(n_arr, lambda k: stats.poisson.pmf(k, LAM * AREA * 3600))


def test_draws_cycle_per_scenario():
    p = params(2)
    p["arrival_rate"] = np.array([LAM, 3 * LAM])
    df = generate_scenarios(3, p, 3000, 600.0, area=AREA)
    n = scenario_counts(df, [300.0])[:, 0]
    assert df.attrs["draws"][:4] == [0, 1, 0, 1]
    chisquare_gof(n[0::2], lambda k: stats.poisson.pmf(k, LAM * AREA / MU))
    chisquare_gof(n[1::2], lambda k: stats.poisson.pmf(k, 3 * LAM * AREA / MU))
    rnd = generate_scenarios(3, p, 50, 600.0, area=AREA, draw="random")
    assert set(rnd.attrs["draws"]) <= {0, 1}


def test_positions_only_and_uniformly_in_free_cells():
    mask = np.zeros((6, 8), dtype=bool)
    mask[1:5, 2:7] = True
    mask[3, 4] = False
    res, ox, oy = 0.5, -1.0, 2.0
    df = generate_scenarios(
        9, params(), 400, 3600.0, free_mask=mask, resolution=res, origin=(ox, oy)
    )
    ix = np.floor((df["x"].to_numpy() - ox) / res).astype(int)
    iy = np.floor((df["y"].to_numpy() - oy) / res).astype(int)
    assert mask[iy, ix].all()
    # uniform over the free cells
    cells = np.ravel_multi_index((iy, ix), mask.shape)
    free_ids = np.flatnonzero(mask.ravel())
    code = np.searchsorted(free_ids, cells)
    chisquare_gof(code, lambda k: np.where(k < free_ids.size, 1 / free_ids.size, 0.0))
    # area from the map: free cells x resolution^2
    assert df.attrs["generation"]["area"] == pytest.approx(mask.sum() * res * res)
    # headings on the 4 grid directions (DECISIONS 6)
    assert np.isin(np.round(df["yaw"] / (np.pi / 2), 9), [0, 1, 2, 3]).all()


def test_occupancy_grid_with_rotated_origin():
    from are_stats.environment import OccupancyGrid

    data = np.full((5, 7), 100)
    data[1:4, 1:6] = 0
    grid = OccupancyGrid(data, 0.25, origin=(3.0, -2.0, 0.7))
    df = generate_scenarios(4, params(), 100, 3600.0, free_mask=grid)
    ij = grid.world_to_cell(df[["x", "y"]].to_numpy())
    assert grid.free[ij[:, 0], ij[:, 1]].all()


def test_same_seed_same_bytes(tmp_path):
    def digest(d):
        return {
            f: hashlib.sha256((d / f).read_bytes()).hexdigest()
            for f in ("artefacts.parquet", "manifest.yaml")
        }

    out = []
    for run in range(2):
        df = generate_scenarios(123, params(3), 50, 1800.0, area=AREA)
        write_scenes(df, tmp_path / f"r{run}", {"fit": "fits/demo.nc", "seed": 123})
        out.append(digest(tmp_path / f"r{run}"))
    assert out[0] == out[1]
    df = generate_scenarios(124, params(3), 50, 1800.0, area=AREA)
    write_scenes(df, tmp_path / "other", {"fit": "fits/demo.nc", "seed": 124})
    assert digest(tmp_path / "other")["artefacts.parquet"] != out[0]["artefacts.parquet"]
    back, meta, _ = read_scenes(tmp_path / "r0")
    pd.testing.assert_frame_equal(
        back, generate_scenarios(123, params(3), 50, 1800.0, area=AREA), check_like=False
    )
    assert meta["fit"] == "fits/demo.nc" and meta["n_scenarios"] == 50
    assert meta["generation"]["seed"] == 123 and "version" in meta


def test_refuses_overwrite_and_replaces_the_folder_as_a_whole(tmp_path):
    df = generate_scenarios(1, params(), 5, 100.0, area=AREA)
    out = tmp_path / "sc"
    write_scenes(df, out, {})
    (out / "perceived.parquet").write_text("from an earlier run")
    before = sorted(p.name for p in out.iterdir())
    with pytest.raises(OutputExistsError, match=r"sc: already exists; pass force=True"):
        write_scenes(df, out, {})
    assert sorted(p.name for p in out.iterdir()) == before  # nothing touched
    write_scenes(generate_scenarios(2, params(), 5, 100.0, area=AREA), out, {}, force=True)
    # replaced as a whole: no file of the earlier run stays, no temporary folder is left
    assert sorted(p.name for p in out.iterdir()) == ["artefacts.parquet", "manifest.yaml"]
    assert [p.name for p in tmp_path.iterdir()] == ["sc"]
    assert read_scenes(out).manifest["generation"]["seed"] == 2
    empty = tmp_path / "empty"
    empty.mkdir()
    write_scenes(df, empty, {})  # an empty folder is not an earlier output


def test_interrupted_folder_write_keeps_the_old_folder(tmp_path):
    out = tmp_path / "sc"
    write_scenes(generate_scenarios(7, params(), 5, 100.0, area=AREA), out, {})
    old = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(RuntimeError, match="killed"):
        with atomic_folder(out, force=True) as tmp:
            (tmp / "artefacts.parquet").write_text("half of seed 8")
            raise RuntimeError("killed between two files")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == old
    assert [p.name for p in tmp_path.iterdir()] == ["sc"]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_scenarios": 0}, r"n_scenarios: expected an integer >= 1, got 0"),
        ({"n_scenarios": True}, r"n_scenarios: expected an integer >= 1, got True \(a bool\)"),
        ({"n_scenarios": 2.5}, r"n_scenarios: expected an integer >= 1, got 2\.5"),
        ({"horizon": float("nan")}, r"horizon: expected a finite number > 0, got nan"),
        ({"horizon": float("inf")}, r"horizon: expected a finite number > 0"),
        ({"horizon": 0.0}, r"horizon: expected a finite number > 0, got 0\.0"),
    ],
)
def test_bad_sizes_are_named(kwargs, match):
    args = {"n_scenarios": 3, "horizon": 100.0} | kwargs
    with pytest.raises(ValueError, match=match):
        generate_scenarios(0, params(), area=AREA, **args)


def test_refuses_tables_past_the_limits_before_drawing():
    # 1e12 s at 12 artefacts per 10 min: about 2e10 artefacts, terabytes
    with pytest.raises(LimitError, match=r"n_scenarios, horizon: expected about 2e\+10 artefacts"):
        generate_scenarios(0, params(), 1, 1e12, area=AREA)
    with pytest.raises(LimitError, match=r"--n: expected about 2e\+10 artefacts \(1 scenarios of"):
        check_scenario_size(params(), ScenarioSize(1, 1e12, AREA), "--n")
    with pytest.raises(LimitError, match=r"expected 1000000000000 scenarios to fit in the memo"):
        generate_scenarios(0, params(), 10**12, 1.0, area=AREA)
    assert expected_artefacts(params(), ScenarioSize(10, 3600.0, AREA)) == pytest.approx(
        10 * (12 + 72)
    )
    with limits(memory="1M"):  # the limit can be lowered (and raised) by the user
        with pytest.raises(LimitError, match=r"memory limit of 1\.0 MiB .*--max-memory"):
            generate_scenarios(0, params(), 100, 3600.0, area=AREA)
    assert len(generate_scenarios(0, params(), 2, 60.0, area=AREA)) > 0


def test_jax_key_is_deterministic():
    k = jax.random.key(7)
    a = generate_scenarios(k, params(), 20, 600.0, area=AREA)
    b = generate_scenarios(jax.random.key(7), params(), 20, 600.0, area=AREA)
    c = generate_scenarios(jax.random.PRNGKey(8), params(), 20, 600.0, area=AREA)
    pd.testing.assert_frame_equal(a, b)
    assert not a.equals(c)


def test_scenario_counts_brute_force():
    df = generate_scenarios(2, params(), 30, 1200.0, area=AREA)
    times = np.array([0.0, 10.0, 700.0, 1199.0])
    got = scenario_counts(df, times)
    want = np.zeros((30, 4), dtype=int)
    for r in df.itertuples():
        for k, t in enumerate(times):
            want[r.scenario, k] += r.t_arrive <= t < r.t_leave
    np.testing.assert_array_equal(got, want)


def test_without_mixture_and_posterior_draws():
    import arviz as az

    idata = az.from_dict(
        posterior={"arrival_rate": np.full((2, 5), LAM), "leave_rate": np.full((2, 5), MU)}
    )
    p = posterior_draws(idata)
    assert p["arrival_rate"].shape == (10,)
    df = generate_scenarios(0, p, 10, 600.0, area=AREA)
    assert (df["mark"] == -1).all() and (df["class"] == -1).all()
    with pytest.raises(ValueError, match=r"posterior: expected a variable 'leave_rate'"):
        posterior_draws(az.from_dict(posterior={"arrival_rate": np.ones((1, 3))}))


ERROR_CASES = [
    (dict(params={"arrival_rate": [1.0]}), r"params: expected a key 'leave_rate'"),
    (
        dict(params={"arrival_rate": [-1.0], "leave_rate": [1.0]}),
        r"params\['arrival_rate'\]: expected finite numbers > 0, got .*-1\.0",
    ),
    (
        dict(params={"arrival_rate": [1.0, 2.0], "leave_rate": [1.0]}),
        r"params\['leave_rate'\]: expected 2 draws",
    ),
    (
        dict(params={**params(), "mix_weights": [[0.5, 0.6, 0.1]]}),
        r"params\['mix_weights'\]: expected rows summing to 1",
    ),
    (
        dict(params={**params(), "mix_rates": [[1.0, 2.0]]}),
        r"params\['mix_weights'\], params\['mix_rates'\]: expected shapes \(1, K\)",
    ),
    (dict(n_scenarios=0), r"n_scenarios: expected an integer >= 1"),
    (dict(horizon=0.0), r"horizon: expected a finite number > 0"),
    (dict(start="full"), r"start: expected one of 'stationary', 'empty'"),
    (dict(area=None), r"area: expected the free area"),
    (dict(free_mask=np.zeros((3, 3), bool), area=None), r"free_mask: expected at least one free"),
    (dict(free_mask=np.ones(3)), r"free_mask: expected a 2-d bool array"),
    (dict(key=-3), r"key: expected an int seed >= 0 or a JAX PRNG key"),
]


@pytest.mark.parametrize(("kw", "message"), ERROR_CASES)
def test_argument_errors(kw, message):
    args = dict(key=0, params=params(), n_scenarios=3, horizon=60.0, area=AREA)
    args.update(kw)
    with pytest.raises(ValueError, match=message):
        generate_scenarios(**args)


def test_read_scenes_names_the_bad_file(tmp_path):
    out = tmp_path / "sc"
    write_scenes(generate_scenarios(1, params(), 3, 100.0, area=AREA), out, {})
    (out / "manifest.yaml").write_text("- a list\n")
    with pytest.raises(InputError, match=r"manifest\.yaml: expected a mapping"):
        read_scenes(out)
    (out / "manifest.yaml").write_text("seed: 1\nseed: 2\n")
    with pytest.raises(InputError, match=r"manifest\.yaml: line 2: expected each key once"):
        read_scenes(out)
    (out / "manifest.yaml").write_text("seed: 1\n")
    (out / "artefacts.parquet").write_text("not parquet")
    with pytest.raises(InputError, match=r"artefacts\.parquet: expected a scenarios table in Par"):
        read_scenes(out)
    pd.DataFrame({"scenario": [0]}).to_parquet(out / "artefacts.parquet")
    with pytest.raises(ValueError, match=r"artefacts\.parquet: missing column\(s\) 'class'"):
        read_scenes(out)


@pytest.mark.parametrize(
    ("column", "value", "match"),
    [
        ("t_arrive", np.nan, r"row 1, column 't_arrive': expected a number, got an empty cell"),
        ("scenario", 2**62, r"row 1, column 'scenario': expected a non-negative integer <= 2"),
        ("mark", 1.5, r"row 1, column 'mark': expected an integer >= -1, got 1.5"),
        ("censored", 1, r"row 1, column 'censored': expected booleans"),
        ("t_leave", -1.0, r"row 1, column 't_leave': expected t_leave >= t_arrive"),
        ("x", 1e300, r"row 1, column 'x': expected a position within 1e\+07 m of the origin"),
    ],
)
def test_read_scenes_checks_every_column(tmp_path, column, value, match):
    out = tmp_path / "sc"
    write_scenes(generate_scenarios(1, params(), 3, 100.0, area=AREA), out, {})
    df = pd.read_parquet(out / "artefacts.parquet")
    df[column] = value
    df.to_parquet(out / "artefacts.parquet")
    with pytest.raises(InputError, match=r"artefacts\.parquet: " + match):
        read_scenes(out)
