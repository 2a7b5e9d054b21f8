"""End to end: are-stats fit -> report -> generate on small synthetic logs (issue 3).

Statistical checks state their false-failure rate: the conjugate comparison uses a
4-MCSE bound on the mean (about 6e-5 per parameter for a correct sampler) and a 10% bound
on the sd; the chi-square uses ALPHA from tests.helpers.
"""

from __future__ import annotations

import re
from pathlib import Path

import arviz as az
import jax
import numpy as np
import pandas as pd
import pytest
import yaml
from scipy import stats
from typer.testing import CliRunner

from are_stats import _cli_jobs as cli_jobs
from are_stats._stage_clock import StageClock
from are_stats.cli import app
from are_stats.traffic import (
    LifecyclePriors,
    conjugate_arrival_rate,
    conjugate_leave_rate,
    simulate_lifecycle,
)
from tests.helpers import PAPER_MODELS, chisquare_gof

runner = CliRunner()
AREA = 400.0


def _write_log(folder: Path, labels: bool = False, seed: int = 0) -> tuple[Path, object]:
    """A 2-hour log with censoring and truncation: lambda*A = 1/20 per s, mean stay 5 min."""
    data = simulate_lifecycle(
        jax.random.key(seed),
        1 / 20 / AREA,
        1 / 300,
        [0.6, 0.4],
        [3.0, 20.0],
        (0.0, 7200.0),
        area=AREA,
    )
    df = pd.DataFrame(
        {
            "id": [f"x{i}" for i in range(data.n)],
            "t_arrive": data.t_arrive,
            "t_leave": data.t_leave,
            "mark": data.marks,
        }
    )
    if labels:
        df["label"] = np.asarray(["small", "large"])[data.labels]
    path = folder / "log.csv"
    df.to_csv(path, index=False, na_rep="")
    (folder / "log.yaml").write_text(yaml.safe_dump({"window": [0.0, 7200.0], "area": AREA}))
    return path, data


def _invoke(args):
    res = runner.invoke(app, [str(a) for a in args])
    return res


def _quick_em_fit(log: Path, fit: Path, *extra, samples: int = 50):
    """A small conjugate + EM fit without figures (the setup of the downstream tests)."""
    res = _invoke(["fit", log, "--out", fit, "--method", "em", "--no-figures",
                   "--samples", str(samples), "--chains", "2", *PAPER_MODELS, *extra])  # fmt: skip
    assert res.exit_code == 0, res.output
    return res


@pytest.fixture(scope="module")
def em_fit_file(tmp_path_factory):
    """A small EM fit shared by the perceive, option and damaged-fit tests."""
    folder = tmp_path_factory.mktemp("emfit")
    log, _ = _write_log(folder)
    fit = folder / "small.nc"
    _quick_em_fit(log, fit, samples=20)
    return fit


@pytest.fixture(scope="module")
def em_labels_fit_file(tmp_path_factory):
    """A small EM fit of the labelled log (two classes), shared by the augment and the
    behaviours tests: one fit and one set of programs for its 20 draws instead of one each."""
    folder = tmp_path_factory.mktemp("emlabels")
    log, _ = _write_log(folder, labels=True)
    fit = folder / "small.nc"
    _quick_em_fit(log, fit, samples=20)
    return fit


def test_fit_report_generate_em(tmp_path):
    log, data = _write_log(tmp_path, labels=False)
    fit = tmp_path / "fits" / "small.nc"
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
            "--warmup",
            "200",
            "--chains",
            "2",
            "--seed",
            "3",
        ]
    )
    assert res.exit_code == 0, res.output
    assert "arrival_rate" in res.output and "mix_rates[1]" in res.output
    idata = az.from_netcdf(fit)
    for group in ("posterior", "log_likelihood", "observed_data", "prior"):
        assert group in idata.groups()
    post = idata.posterior
    assert set(post.data_vars) >= {"arrival_rate", "leave_rate", "mix_weights", "mix_rates"}
    assert post.attrs["method"] == "em" and post.attrs["seed"] == 3
    assert np.allclose(post.attrs["window"], [0.0, 7200.0]) and post.attrs["area"] == AREA
    # two well separated components, found by BIC, rates near the truth (3, 20)
    rates = post["mix_rates"].mean(("chain", "draw")).values
    assert rates.shape == (2,) and abs(rates[0] - 3) < 0.6 and abs(rates[1] - 20) < 2
    figures = fit.with_suffix("")
    for name in (
        "summary.csv",
        "criticism.png",
        "ppc_counts.png",
        "ppc_dwell.png",
        "ppc_marks.png",
        "ppc_interarrival.png",
        "ppc_dispersion.png",
        "traffic_checks.png",
        "traffic_checks.csv",
        "loo_arrivals.csv",
        "loo_lifetimes.csv",
    ):
        assert (figures / name).stat().st_size > 0, name
    # no clock_start in the manifest: no hour-of-day panel (t = 0 is not midnight)
    assert not (figures / "ppc_hour_of_day.png").exists()
    # the paper's model is the truth here: auto keeps it
    assert post.attrs["arrival_model"] == "poisson"
    assert post.attrs["lifetime_model"] == "exponential"
    checks = pd.read_csv(figures / "traffic_checks.csv", index_col=0)
    assert {"observed", "paper_5%", "paper_95%", "paper_flag"} <= set(checks.columns)
    # no overwrite without --force, then report and generate
    res = _invoke(["fit", log, "--out", fit, "--method", "em"])
    assert res.exit_code == 2 and "already exists" in res.output
    res = _invoke(["report", fit, "--out", tmp_path / "rep", "--replicates", "20"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "rep" / "ppc_counts.png").exists()
    out = tmp_path / "scen"
    res = _invoke(
        ["generate", fit, "--scenarios", "50", "--horizon", "600", "--seed", "7", "--out", out]
    )
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(out / "artefacts.parquet")
    assert df["scenario"].nunique() == 50 and set(df["class"]) <= {0, 1}
    manifest = yaml.safe_load((out / "manifest.yaml").read_text())
    assert manifest["seed"] == 7 and manifest["fit"] == str(fit)
    first = (out / "artefacts.parquet").read_bytes()
    res = _invoke(
        [
            "generate",
            fit,
            "--scenarios",
            "50",
            "--horizon",
            "600",
            "--seed",
            "7",
            "--out",
            out,
            "--force",
        ]
    )
    assert res.exit_code == 0 and (out / "artefacts.parquet").read_bytes() == first


def test_nuts_fit_matches_conjugate_posterior(tmp_path):
    log, data = _write_log(tmp_path, labels=True, seed=1)
    assert data.truncated.any() and data.censored.any()
    fit = tmp_path / "nuts.nc"
    res = _invoke(
        [
            "fit",
            log,
            "--out",
            fit,
            "--no-figures",
            "--no-stationary-start",
            *PAPER_MODELS,
            "--warmup",
            "400",
            "--samples",
            "600",
            "--chains",
            "2",
            "--seed",
            "1",
        ]
    )
    assert res.exit_code == 0, res.output
    idata = az.from_netcdf(fit)
    assert idata.posterior.attrs["class_labels"] == "large,small"
    summary = az.summary(idata, var_names=["arrival_rate", "leave_rate"], round_to="none")
    assert (summary["ess_bulk"] > 400).all(), summary
    priors = LifecyclePriors()
    for name, law in (
        ("arrival_rate", conjugate_arrival_rate(data, priors)),
        ("leave_rate", conjugate_leave_rate(data, priors)),
    ):
        row = summary.loc[name]
        assert abs(row["mean"] - law.mean) < 4 * row["mcse_mean"], (name, row, law)
        assert abs(row["sd"] / law.sd - 1) < 0.10, (name, row["sd"], law.sd)


@pytest.mark.slow  # 3,000 scenarios; make test: tests/scenarios/test_generate.py
def test_scenarios_reproduce_fitted_stationary_law(tmp_path):
    log, _ = _write_log(tmp_path)
    fit = tmp_path / "f.nc"
    _quick_em_fit(log, fit, samples=250)
    out = tmp_path / "s"
    assert (
        _invoke(
            [
                "generate",
                fit,
                "--scenarios",
                "3000",
                "--horizon",
                "900",
                "--seed",
                "2",
                "--out",
                out,
            ]
        ).exit_code
        == 0
    )
    df = pd.read_parquet(out / "artefacts.parquet")
    t = 450.0
    alive = df[(df.t_arrive <= t) & (df.t_leave > t)].groupby("scenario").size()
    n_t = alive.reindex(range(3000), fill_value=0).to_numpy()
    post = az.from_netcdf(fit).posterior
    lam = post["arrival_rate"].values.ravel()
    mu = post["leave_rate"].values.ravel()
    draws = np.arange(3000) % lam.size  # scenario i uses draw i mod S
    means = lam[draws] * AREA / mu[draws]

    def pmf(k):
        return stats.poisson.pmf(np.asarray(k)[:, None], means[None, :]).mean(axis=1)

    chisquare_gof(n_t, pmf)


@pytest.mark.parametrize(
    "content, match",
    [
        ("id,t_arrive,t_leave\na,1,x\n", r"row 1 \(line 2\), column 't_leave'"),
        ("id,t_arrive,t_leave\na,5,2\n", "t_leave"),
        ("id,t_arrive\na,1\n", "t_leave"),
        ("", "empty"),
    ],
)
def test_fit_bad_log_gives_clear_error(tmp_path, content, match):
    log = tmp_path / "bad.csv"
    log.write_text(content)
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump({"window": [0.0, 10.0], "area": 5.0}))
    res = _invoke(["fit", log, "--out", tmp_path / "x.nc", "--method", "em"])
    assert res.exit_code == 2
    assert "error:" in res.output and str(log) in res.output
    assert pytest.importorskip("re").search(match, res.output), res.output
    assert "Traceback" not in res.output


def test_report_missing_fit(tmp_path):
    res = _invoke(["report", tmp_path / "nope.nc"])
    assert res.exit_code == 2 and "no such fit file" in res.output


def test_demo_quick(tmp_path):
    res = _invoke(["demo", "--out", tmp_path / "demo", "--quick"])
    assert res.exit_code == 0, res.output
    summary = yaml.safe_load((tmp_path / "demo" / "summary.yaml").read_text())
    # the fit goes under --out (never into the package); the log is the shipped one
    assert summary["fit"] == str(tmp_path / "demo" / "courtyard_traffic.nc")
    assert (tmp_path / "demo" / "courtyard_traffic.nc").is_file()
    # the example log's truth (models/make_example_log.py): groups, gamma stays of mean
    # 600 s, door entries; 1/30 artefacts per s
    assert summary["chosen_models"] == {
        "arrivals": "groups", "lifetimes": "gamma", "positions": "learned",
    }  # fmt: skip
    assert abs(summary["posterior_mean"]["leave_rate"] * 600 - 1) < 0.15
    scen = summary["scenarios (100 of 1 h; medians)"]
    # the chosen model's world is as crowded as the log's; the paper's is calmer
    assert scen["chosen"]["N(t) var/mean"] > 1.3 > scen["paper"]["N(t) var/mean"]
    assert scen["chosen"]["zero gaps"] > 0.2 > scen["paper"]["zero gaps"]
    assert scen["chosen"]["stay cv"] < 0.7 < scen["paper"]["stay cv"]
    checks = summary["checks (observed; outside the 90% band of)"]
    for stat in ("zero gaps", "stay cv", "entry to boundary (m)"):
        assert checks[stat]["paper misfit"], stat
    # a 90% band misses a correct model's statistic one time in ten: at most one of five
    assert sum(c["chosen misfit"] for c in checks.values()) <= 1
    for name in ("criticism.png", "traffic_checks.png", "loo_arrivals.csv"):
        assert (tmp_path / "demo" / "criticism" / name).exists()


def test_augment_camera_takes_a_shipped_name_as_perceive_does(tmp_path, em_labels_fit_file):
    from are_stats.environment import SHIPPED_DATA
    from tests.export.rosbag_fixtures import write_bag

    fit = em_labels_fit_file
    bag = write_bag(tmp_path / "robot.bag", "ros1")
    base = ["augment", bag, "--fit", fit, "--map", "courtyard", "--seed", "1",
            "--pose-topic", "/amcl_pose", "--period", "2.0"]  # fmt: skip
    by_path = tmp_path / "by_path.mcap"
    shipped = SHIPPED_DATA / "cameras" / "front_camera.yaml"
    res = _invoke([*base, "--out", by_path, "--camera", shipped])
    assert res.exit_code == 0, res.output
    by_name = tmp_path / "by_name.mcap"
    res = _invoke([*base, "--out", by_name, "--camera", "front_camera"])
    assert res.exit_code == 0, res.output
    assert by_name.read_bytes() == by_path.read_bytes()


def test_perceive_adds_flags(tmp_path, em_fit_file):
    fit = em_fit_file
    scen = tmp_path / "scen"
    res = _invoke(
        [
            "generate",
            fit,
            "--scenarios",
            "2",
            "--horizon",
            "300",
            "--seed",
            "0",
            "--out",
            scen,
            "--map",
            "courtyard",  # a shipped map, by name
        ]
    )
    assert res.exit_code == 0, res.output
    robot = tmp_path / "robot.csv"
    robot.write_text("t,x,y,yaw\n0,-15,-10,0.6\n100,-10,-5,0.6\n200,-5,0,0.6\n")
    res = _invoke(
        [
            "perceive",
            scen,
            "--camera",
            "front_camera",  # a shipped camera, by name
            "--robot-path",
            robot,
            "--tau",
            "20",
        ]
    )
    assert res.exit_code == 0, res.output
    df = pd.read_parquet(scen / "perceived.parquet")
    assert {"perceived", "n_frames_perceived", "max_count"} <= set(df.columns)
    # perceived exactly when the largest unoccluded pixel count exceeds tau
    assert (df["perceived"] == (df["max_count"] > 20)).all()
    res = _invoke(
        ["perceive", scen, "--camera", tmp_path / "none.yaml", "--robot-path", robot, "--force"]
    )
    assert res.exit_code == 2 and "none.yaml: no such file: expected a camera YAML" in res.output


class _SlowClock(StageClock):
    """The generate job's stage clock, its status lines recorded, on a forced slow timer
    (every reading 1.5 s after the one before: each step of the stage takes seconds),
    with no record of earlier runs (a machine's first run)."""

    lines: list[str] = []

    def __init__(self, status, *args, **kwargs):
        now = iter(np.arange(1, 10_000) * 1.5)
        kwargs.update(path=None, live=False, timer=lambda: float(next(now)))
        super().__init__(self, *args, **kwargs)

    def update(self, text):  # the rich status this clock writes to
        self.lines.append(text)


def test_generate_with_behaviours(tmp_path, monkeypatch, em_labels_fit_file):
    fit = em_labels_fit_file
    out = tmp_path / "s"
    monkeypatch.setattr(cli_jobs, "StageClock", _SlowClock)
    _SlowClock.lines = []
    res = _invoke(
        [
            "generate",
            fit,
            "--scenarios",
            "1",
            "--horizon",
            "120",
            "--seed",
            "0",
            "--out",
            out,
            "--map",
            "courtyard",  # a shipped map, by name
            "--behaviours",
        ]
    )
    assert res.exit_code == 0, res.output
    arte = pd.read_parquet(out / "artefacts.parquet")
    tracks = pd.read_parquet(out / "tracks.parquet")
    assert list(tracks.columns[:6]) == ["scenario", "id", "t", "x", "y", "yaw"]
    # every artefact has a track that starts at its arrival and stays inside the map
    assert set(tracks["id"]) == set(arte["artefact"])
    first = tracks.groupby("id")["t"].min()
    arrive = arte.set_index("artefact")["t_arrive"]
    assert (first.sort_index() - arrive.sort_index()).abs().max() <= 2.0
    assert tracks["x"].between(-20, 20).all() and tracks["y"].between(-15, 15).all()
    manifest = yaml.safe_load((out / "manifest.yaml").read_text())
    assert manifest["tracks"]["file"] == "tracks.parquet"
    # the summary names every file written, the tracks too
    said = " ".join(res.output.split())
    assert f"wrote {out / 'artefacts.parquet'}, {out / 'tracks.parquet'} and " in said, said
    # the stage's line says where the assembly stands and, once a long step is timed, the
    # time left (issue 27): on a first run too, with no record of the stage
    stage = "scenarios with their walks (rollouts) ... "
    lines = [w for w in _SlowClock.lines if w.startswith(stage)]
    assert any("scenarios drawn (1/3)" in w for w in lines), lines
    assert any(re.search(r"tracks planned \(2/3\), about \d+ s left", w) for w in lines), lines
    # then the social force, window by window (the steps' total grows when it starts)
    walked = [w for w in lines if "walked with the social force" in w]
    assert len(walked) >= 2 and re.search(r"\((\d+) of \1 windows\) \((\d+)/\2\)", lines[-1])
    assert all(re.search(r"about \d+ s left", w) for w in walked[1:]), walked


def test_fit_with_count_panel_adds_birth_death_mle(tmp_path):
    log, _ = _write_log(tmp_path)
    import are_stats as ar

    times = np.arange(0.0, 7201.0, 60.0)
    counts = np.asarray(
        ar.BirthDeath(1 / 20, 1 / 300).simulate(jax.random.key(5), 15, 7200.0, 1, times)
    )[0]
    panel = tmp_path / "panel.csv"
    pd.DataFrame({"t": times, "count": counts}).to_csv(panel, index=False)
    fit = tmp_path / "f.nc"
    res = _quick_em_fit(log, fit, "--counts", panel)
    assert "birth-death MLE" in res.output
    attrs = az.from_netcdf(fit).posterior.attrs
    mle = ar.fit_birth_death(times, counts)
    assert attrs["birth_death_birth_rate"] == pytest.approx(mle.birth_rate, rel=1e-9)
    assert attrs["birth_death_death_rate"] == pytest.approx(mle.death_rate, rel=1e-9)
    assert np.allclose(attrs["birth_death_stderr"], mle.stderr)


def test_em_fit_without_marks_then_report_and_generate(tmp_path):
    """Issue 13: a log without a mark column fits by EM (no mixture) end to end."""
    log, _ = _write_log(tmp_path)
    df = pd.read_csv(log).drop(columns="mark")
    df.to_csv(log, index=False, na_rep="")
    fit = tmp_path / "nomarks.nc"
    res = _quick_em_fit(log, fit, samples=20)
    assert "mix_weights" not in res.output
    res = _invoke(["report", fit, "--out", tmp_path / "rep", "--replicates", "5"])
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "rep" / "ppc_marks.png").exists()
    digests = []
    for _ in range(2):  # same seed, same bytes: every file of the folder
        out = tmp_path / "scen"
        args = ["generate", fit, "--scenarios", "4", "--horizon", "300", "--seed", "5"]
        res = _invoke([*args, "--out", out, "--force"])
        assert res.exit_code == 0, res.output
        digests.append({p.name: p.read_bytes() for p in out.iterdir()})
    assert digests[0] == digests[1] and set(digests[0]) == {"artefacts.parquet", "manifest.yaml"}
    assert (pd.read_parquet(out / "artefacts.parquet")["mark"] == -1).all()


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (
            ["--horizon", "1e12"],
            r"small\.nc, --scenarios, --horizon: expected about .* artefacts .* memory",
        ),
        (["--horizon", "nan"], r"--horizon: expected a finite number > 0, got nan"),
        (["--scenarios", "0"], r"--scenarios: expected an integer >= 1, got 0"),
        (["--scenarios", "100000000000"], r"expected 100000000000 scenarios to fit in the memory"),
        (["--area", "-1"], r"--area: expected a finite number > 0, got -1\.0"),
        (["--seed", "-3"], r"--seed: expected an integer >= 0"),
        (["--behaviours", "--behaviour-cell", "0"], r"--behaviour-cell: expected a finite number"),
        (["--behaviours", "--behaviour-dt", "inf"], r"--behaviour-dt: expected a finite number"),
        # the assembly's behaviour rule, in the command's words: a fit without a behaviour
        # walks the catalogue's MDP, which needs the map
        (["--behaviours"], r"^error: --behaviours: expected --map \(trajectories need the grid\)$"),
    ],
)
def test_generate_options_are_checked_before_any_work(tmp_path, em_fit_file, extra, match):
    args = {"--scenarios": "3", "--horizon": "60", "--seed": "1"}
    for flag, value in zip(extra[::2], extra[1::2], strict=False):
        if flag in args:
            args[flag] = value
    rest = [a for a in extra if a not in args and a not in args.values()]
    flat = [x for kv in args.items() for x in kv]
    res = _invoke(["generate", em_fit_file, *flat, *rest, "--out", tmp_path / "o"])
    assert res.exit_code == 2, res.output
    assert re.search(match, " ".join(res.output.split())), res.output
    assert not (tmp_path / "o").exists()


def test_generate_needs_force_for_an_existing_folder(tmp_path, em_fit_file):
    out = tmp_path / "scen"
    args = ["generate", em_fit_file, "--scenarios", "2", "--horizon", "60", "--out", out]
    assert _invoke([*args, "--seed", "7"]).exit_code == 0
    (out / "stale.txt").write_text("from another run")
    res = _invoke([*args, "--seed", "8"])
    assert res.exit_code == 2 and "already exists" in res.output
    assert yaml.safe_load((out / "manifest.yaml").read_text())["seed"] == 7
    assert _invoke([*args, "--seed", "8", "--force"]).exit_code == 0
    assert sorted(p.name for p in out.iterdir()) == ["artefacts.parquet", "manifest.yaml"]
    assert yaml.safe_load((out / "manifest.yaml").read_text())["seed"] == 8


def test_report_of_a_damaged_fit_names_the_file_and_field(tmp_path, em_fit_file):
    idata = az.from_netcdf(em_fit_file)
    idata.load()
    del idata.posterior.attrs["area"]
    bad = tmp_path / "bad.nc"
    idata.to_netcdf(str(bad))
    for cmd in (["report", bad, "--out", tmp_path / "r"], ["generate", bad, "--scenarios", "2",
                "--horizon", "60", "--seed", "0", "--out", tmp_path / "g"]):  # fmt: skip
        res = _invoke(cmd)
        assert res.exit_code == 2, res.output
        assert "posterior.attrs.area: expected this attribute" in " ".join(res.output.split())
    res = _invoke(["report", em_fit_file, "--out", tmp_path / "r", "--replicates", "0"])
    assert res.exit_code == 2 and "--replicates: expected an integer >= 1" in res.output


def test_steps_left_from_the_steps_timed_or_the_record(tmp_path):
    """The generate stage's time left: on a first run from the mean of the steps timed
    after the quick first one, on a later run from the stage's recorded duration."""
    now = [0.0]
    timer = lambda: now[0]  # noqa: E731
    said = []

    class Clock(StageClock):
        def left(self, seconds, words=""):
            said.append((seconds, words))

    first = Clock(None, path=tmp_path / "times.json", timer=timer)
    first("rollouts")
    steps = cli_jobs.StepsLeft(first, "rollouts", timer=timer)
    for at, done in ((0.5, 1), (20.5, 2), (30.5, 3), (40.5, 4)):
        now[0] = at
        steps(done, 4, f"step {done}")
    first.close()  # records 40.5 s
    assert said == [(None, "step 1 (1/4)"), (40.0, "step 2 (2/4)"), (15.0, "step 3 (3/4)"),
                    (0.0, "step 4 (4/4)")]  # fmt: skip
    said.clear()
    second = Clock(None, path=tmp_path / "times.json", timer=timer)
    second("rollouts")
    steps = cli_jobs.StepsLeft(second, "rollouts", timer=timer)
    now[0] += 10.0
    steps(1, 4, "step 1")
    assert said == [(30.5, "step 1 (1/4)")]


def test_steps_left_times_each_phase_by_its_own_steps(tmp_path):
    """The planning's steps and the social force's windows take different times: a first
    run's time left comes from the steps of the phase running (a phase announces its own
    total), after its first step (which compiles); a later run's from the record, less the
    compiling this run had to do."""
    now = [0.0]
    said = []

    class Clock(StageClock):
        def left(self, seconds, words=""):
            said.append((seconds, words.split(" (")[-1]))

    first = Clock(None, path=tmp_path / "t.json", timer=lambda: now[0], compiled=None)
    first("rollouts")
    steps = cli_jobs.StepsLeft(first, "rollouts", timer=lambda: now[0])
    # the draw (1 of 3), 4 planning steps of 5 s after a first of 9 s, 20 windows of 0.5 s
    for at, done, total in ((1.0, 1, 3), (10.0, 2, 7), (15.0, 3, 7), (20.0, 4, 7),
                            (30.0, 7, 26), (30.5, 8, 26), (31.0, 9, 26)):  # fmt: skip
        now[0] = at
        steps(done, total, "step")
    assert said == [(None, "1/3)"), (None, "2/7)"), (20.0, "3/7)"), (15.0, "4/7)"),
                    (None, "7/26)"), (9.0, "8/26)"), (8.5, "9/26)")]  # fmt: skip
    first.close()
    said.clear()
    # 11 s in, 5 of them compiling (from 103 s to 108 s): 6 of the 31 s done
    compiled = lambda t0, t1: max(0.0, min(t1, 108.0) - max(t0, 103.0))  # noqa: E731
    second = Clock(None, path=tmp_path / "t.json", timer=lambda: now[0], compiled=compiled)
    now[0] = 100.0
    second("rollouts")
    steps = cli_jobs.StepsLeft(second, "rollouts", timer=lambda: now[0])
    now[0] = 111.0
    steps(2, 7, "step")
    assert said == [(25.0, "2/7)")]
