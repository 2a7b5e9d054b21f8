"""Integrity of outputs: killed runs lose nothing, and the same seed gives the same bytes.

(a) ``are-stats fit``, ``generate`` and ``experiment`` run in a subprocess over the complete
outputs of an earlier run (``--force``) and are killed (SIGKILL, whole process group) after
a delay drawn from a seeded RNG. Afterwards every file under a final name is either the
earlier file, byte for byte, or a complete output that its reader accepts; a scenario
folder is replaced as a whole (never the old manifest beside new artefacts).

(b) Two runs with the same seed into two places write the same bytes.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

from are_stats.environment import shipped_path
from tests.helpers import PAPER_MODELS, TINY_SWEEP

LOG = shipped_path("courtyard_traffic", "log")
MAP = str(shipped_path("courtyard", "map"))
CAMERA = str(shipped_path("front_camera", "camera"))

# Kill moments per command (fractions of an uninterrupted run's time, seeded).
N_KILLS = 2
RNG_SEED = 20261123

# The runs in subprocesses are the slow tier (``make test-slow``, CI); ``make test`` keeps the
# kill harness's own test, and tests/scenarios/test_generate.py (same seed, same bytes; an
# interrupted folder write keeps the old folder) and tests/fitting/test_fit.py (the
# command writes fit_log's bytes) check the same properties in-process.

SWEEP = TINY_SWEEP


def _are_stats() -> list[str]:
    exe = Path(sys.executable).with_name("are-stats")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "are_stats.cli"]


def _env() -> dict[str, str]:
    return {**os.environ, "JAX_PLATFORMS": "cpu", "MPLBACKEND": "Agg", "COLUMNS": "200"}


def run(args: list[str], cwd: Path) -> float:
    """Run ``are-stats ARGS`` to completion; returns its wall time."""
    t = time.perf_counter()
    res = subprocess.run(
        [*_are_stats(), *args], cwd=cwd, env=_env(), capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, f"are-stats {' '.join(args)}\n{res.stdout[-2000:]}\n{res.stderr}"
    return time.perf_counter() - t


def run_killed(args: list[str], cwd: Path, delay: float) -> int | None:
    """Start ``are-stats ARGS`` in its own process group; SIGKILL the group after ``delay``.

    Returns the exit code when the run ended before the kill, else ``None``.
    """
    proc = subprocess.Popen(
        [*_are_stats(), *args],
        cwd=cwd,
        env=_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        return proc.wait(timeout=delay)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        return None


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every regular file under ``folder`` (relative path -> bytes)."""
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def delays(total: float, n: int = N_KILLS, salt: int = 0) -> list[float]:
    """Seeded kill moments between 30 % and 100 % of an uninterrupted run's time.

    The start (imports, JIT compilation) takes most of a small run; the outputs are written
    at the end, so the moments lean late. They reach down to 30 %: the run timed here may
    have shared the cores with another test worker, and a killed run that did not then ends
    before every kill, having checked nothing.
    """
    rng = np.random.default_rng([RNG_SEED, salt])
    return sorted(float(u) * total for u in rng.uniform(0.3, 1.0, n))


# Where every run ended before its kill, the kill moments are tried again at these
# fractions of themselves: the uninterrupted run was timed while the machine was busier
# (the other test worker compiling, other users), so the later runs were quicker. Down to
# 0.05: on 2026-11-28 the fit was timed at load ~20 and its killed runs came at load ~6, and
# every run of the three rounds down to 0.25 ended before its kill.
RETRY_SCALES = (0.5, 0.25, 0.1, 0.05)


def kill_rounds(total: float, salt: int, attempt: Callable[[int, float], bool]) -> None:
    """Call ``attempt(i, delay)`` at the seeded kill moments until a run was killed.

    ``attempt`` runs one killed run, checks its outputs and returns whether the kill
    came before the run's end. A round where no run was killed checked only finished
    runs; it is repeated at :data:`RETRY_SCALES` of the moments, and the test fails when
    no round killed a run.
    """
    i = 0
    for scale in (1.0, *RETRY_SCALES):
        killed = 0
        for delay in delays(total, salt=salt):
            killed += attempt(i, scale * delay)
            i += 1
        if killed:
            return
    raise AssertionError("every run ended before its kill: the test checked nothing")


def _tiny_log(d: Path) -> Path:
    d.mkdir(parents=True, exist_ok=True)
    lines = LOG.read_text().splitlines()[:61]
    (d / "log.csv").write_text("\n".join(lines) + "\n")
    (d / "log.yaml").write_text(yaml.safe_dump({"window": [0.0, 14400.0], "area": 900.0}))
    return d / "log.csv"


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """Two same-seed fits, generations and sweeps (shared by (a) and (b))."""
    d = tmp_path_factory.mktemp("integrity")
    log = _tiny_log(d)
    fit = ["fit", str(log), "--method", "em", "--no-figures", "--seed", "1", *PAPER_MODELS]
    # the kill moments scale with the quicker of the two runs: the first one compiles what
    # the second reads from the cache, and the killed runs read it too (on a busy machine a
    # delay from the first run alone let every killed run finish first)
    t_fit = min(run([*fit, "--out", str(d / "a.nc")], d), run([*fit, "--out", str(d / "b.nc")], d))
    gen = ["generate", str(d / "a.nc"), "--scenarios", "4", "--horizon", "600", "--seed", "7"]
    t_gen = min(
        run([*gen, "--out", str(d / "gen_a")], d), run([*gen, "--out", str(d / "gen_b")], d)
    )
    (d / "sweep.yaml").write_text(yaml.safe_dump(SWEEP))
    t_exp = min(
        run(["experiment", str(d / "sweep.yaml"), "--out", str(d / "exp_a")], d),
        run(["experiment", str(d / "sweep.yaml"), "--out", str(d / "exp_b")], d),
    )
    return {"dir": d, "log": log, "t_fit": t_fit, "t_gen": t_gen, "t_exp": t_exp}


# ----------------------------------------------------------------------------- (b) same bytes


def _diff(a: dict[str, bytes], b: dict[str, bytes]) -> list[str]:
    names = sorted(set(a) | set(b))
    return [n for n in names if a.get(n) != b.get(n)]


@pytest.mark.slow
def test_generate_same_seed_same_bytes(work) -> None:
    d = work["dir"]
    a, b = snapshot(d / "gen_a"), snapshot(d / "gen_b")
    assert set(a) >= {"artefacts.parquet", "manifest.yaml"}
    assert not _diff(a, b), f"generate, same seed: files differ: {_diff(a, b)}"


@pytest.mark.slow
def test_fit_same_seed_same_bytes(work) -> None:
    d = work["dir"]
    a, b = (d / "a.nc").read_bytes(), (d / "b.nc").read_bytes()
    if a != b:
        import arviz as az

        ia, ib = az.from_netcdf(str(d / "a.nc")), az.from_netcdf(str(d / "b.nc"))
        diffs = [
            f"{g}.attrs[{k!r}]"
            for g in ia.groups()
            for k in set(ia[g].attrs) | set(ib[g].attrs)
            if str(ia[g].attrs.get(k)) != str(ib[g].attrs.get(k))
        ]
        diffs += [
            f"{g}.{v}"
            for g in ia.groups()
            for v in ia[g].data_vars
            if not ia[g][v].equals(ib[g][v])
        ]
        raise AssertionError(f"fit --method em, same seed: the .nc bytes differ; fields: {diffs}")


# Sweep result columns measured on the wall clock (the replanning time and the paper's
# rho, its share of the mission time): they differ between runs by nature.
WALL_CLOCK = {"rho_t", "rho", "rho_mean", "rho_t_mean"}


def _sweep_diff(a: Path, b: Path) -> list[str]:
    """Files of two sweep folders that differ, beyond the :data:`WALL_CLOCK` columns."""
    import pandas as pd

    sa, sb = snapshot(a), snapshot(b)
    out = []
    for name in _diff(sa, sb):
        if name.endswith(".parquet") and name in sa and name in sb:
            fa, fb = pd.read_parquet(a / name), pd.read_parquet(b / name)
            keep = [c for c in fa.columns if c not in WALL_CLOCK]
            if list(fa.columns) == list(fb.columns) and fa[keep].equals(fb[keep]):
                continue
        out.append(name)
    return out


@pytest.mark.slow
def test_experiment_same_seed_same_results(work) -> None:
    """Same config, same results: bytes of every file, values beyond wall-clock columns."""
    d = work["dir"]
    assert snapshot(d / "exp_a"), "the sweep wrote nothing"
    diff = _sweep_diff(d / "exp_a", d / "exp_b")
    assert not diff, f"experiment, same config: files differ: {diff}"


@pytest.mark.slow
def test_report_show_perceive_plot_same_bytes(work) -> None:
    """The other commands' outputs (figures, tables) are the same bytes for the same inputs."""
    import pandas as pd
    from typer.testing import CliRunner

    from are_stats.cli import app

    d = work["dir"]
    runner = CliRunner()
    gen = ["generate", str(d / "a.nc"), "--scenarios", "2", "--horizon", "600", "--seed", "3"]
    assert runner.invoke(app, [*gen, "--out", str(d / "gm"), "--map", MAP]).exit_code == 0
    path = d / "path.csv"
    pd.DataFrame(
        {"t": np.linspace(0, 600, 7), "x": np.linspace(-5, 5, 7), "y": 0.0, "yaw": 0.0}
    ).to_csv(path, index=False)
    runs = {
        "report": lambda k: ["report", str(d / "a.nc"), "--out", str(d / f"rep{k}"),
                             "--seed", "3", "--replicates", "20"],
        "show": lambda k: ["show", "courtyard", "--artefacts", "5", "--seed", "2",
                           "--out", str(d / f"show{k}.png")],
        "perceive": lambda k: ["perceive", str(d / "gm"), "--camera", CAMERA, "--robot-path",
                               str(path), "--out", str(d / f"perc{k}.parquet")],
        "plot": lambda k: ["plot", str(d / "exp_a"), "--out", str(d / f"plot{k}")],
    }  # fmt: skip
    for name, args in runs.items():
        for k in (1, 2):
            res = runner.invoke(app, args(k))
            assert res.exit_code == 0, (name, res.output)
    for a, b in [("rep1", "rep2"), ("plot1", "plot2")]:
        sa, sb = snapshot(d / a), snapshot(d / b)
        assert sa and not _diff(sa, sb), f"{a}: files differ: {_diff(sa, sb)}"
    for a, b in [("show1.png", "show2.png"), ("perc1.parquet", "perc2.parquet")]:
        assert (d / a).read_bytes() == (d / b).read_bytes(), a


# ----------------------------------------------------------------------------- (a) kills


def _complete_fit(path: Path) -> bool:
    from are_stats import read_fit

    try:
        read_fit(path)
    except ValueError:
        return False
    return True


@pytest.mark.slow
def test_fit_killed(work, tmp_path: Path) -> None:
    """``fit --force`` killed over an existing fit: the old fit, or a complete new one."""
    d = work["dir"]
    old = (d / "a.nc").read_bytes()

    def attempt(i: int, delay: float) -> bool:
        w = tmp_path / f"k{i}"
        w.mkdir()
        (w / "keep.txt").write_text("an unrelated earlier output")
        (w / "fit.nc").write_bytes(old)
        args = [
            "fit",
            str(work["log"]),
            "--method",
            "em",
            "--no-figures",
            "--seed",
            "2",
            "--force",
            "--out",
            str(w / "fit.nc"),
            *PAPER_MODELS,
        ]
        killed = run_killed(args, w, delay) is None
        now = (w / "fit.nc").read_bytes()
        assert now == old or _complete_fit(w / "fit.nc"), f"killed after {delay:.2f} s: fit.nc"
        assert (w / "keep.txt").read_text() == "an unrelated earlier output"
        if i == 0:  # a fresh run killed: nothing, or a complete fit, under the final name
            fresh = w / "fresh.nc"
            run_killed([*args[:-1], str(fresh)], w, delay)
            assert not fresh.exists() or _complete_fit(fresh), f"killed at {delay:.2f} s: fresh"
        return killed

    kill_rounds(work["t_fit"], 1, attempt)


def _scenarios_whole(folder: Path, old: dict[str, bytes], seed: int) -> str | None:
    """None when ``folder`` is the old folder byte for byte or a complete new one."""
    from are_stats import read_scenes

    now = snapshot(folder)
    if now == old:
        return None
    try:
        df, manifest, _ = read_scenes(folder)
    except (ValueError, FileNotFoundError) as err:
        return f"neither the old folder nor a readable new one: {err}"
    if int(manifest.get("seed", -1)) != seed:
        return f"a mix of the old and the new run: manifest seed {manifest.get('seed')}"
    if int(manifest.get("n_artefacts", len(df))) != len(df):
        return "manifest and artefacts disagree"
    return None


@pytest.mark.slow
def test_generate_killed(work, tmp_path: Path) -> None:
    """``generate --force`` killed over an existing scenario folder: replaced as a whole."""
    d = work["dir"]
    old = snapshot(d / "gen_a")

    def attempt(i: int, delay: float) -> bool:
        w = tmp_path / f"k{i}"
        shutil.copytree(d / "gen_a", w / "scen")
        args = [
            "generate",
            str(d / "a.nc"),
            "--scenarios",
            "6",
            "--horizon",
            "600",
            "--seed",
            "8",
            "--force",
            "--out",
            str(w / "scen"),
        ]
        killed = run_killed(args, w, delay) is None
        problem = _scenarios_whole(w / "scen", old, 8)
        assert problem is None, f"killed after {delay:.2f} s: {problem}"
        return killed

    kill_rounds(work["t_gen"], 2, attempt)


def _readable(path: Path) -> bool:
    if path.stat().st_size == 0:
        return False
    if path.suffix == ".parquet":
        import pyarrow.parquet as pq

        try:
            pq.read_table(path)
        except Exception:  # noqa: BLE001 (pyarrow raises several types for a damaged file)
            return False
    elif path.suffix in (".yaml", ".yml"):
        try:
            yaml.safe_load(path.read_text())
        except (yaml.YAMLError, UnicodeDecodeError):
            return False
    return True


@pytest.mark.slow
def test_experiment_killed(work, tmp_path: Path) -> None:
    """``experiment --force`` killed over existing results: each file old or complete."""
    d = work["dir"]
    old = snapshot(d / "exp_a")

    def attempt(i: int, delay: float) -> bool:
        w = tmp_path / f"k{i}"
        shutil.copytree(d / "exp_a", w / "exp")
        args = ["experiment", str(d / "sweep.yaml"), "--force", "--out", str(w / "exp")]
        killed = run_killed(args, w, delay) is None
        bad = [
            name
            for name, data in snapshot(w / "exp").items()
            if old.get(name) != data and not _readable(w / "exp" / name)
        ]
        assert not bad, f"killed after {delay:.2f} s: damaged files {bad}"
        lost = [n for n in old if not (w / "exp" / n).exists()]
        assert not lost, f"killed after {delay:.2f} s: earlier results lost: {lost}"
        # the killed sweep resumes to the same results as an uninterrupted one
        run(["experiment", str(d / "sweep.yaml"), "--out", str(w / "exp")], w)
        diff = _sweep_diff(w / "exp", d / "exp_a")
        assert not diff, f"resumed after a kill at {delay:.2f} s: {diff} differ"
        return killed

    kill_rounds(work["t_exp"], 3, attempt)


def _complete_mcap(path: Path) -> bool:
    """The MCAP reads to its end: summary, every message's bytes."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as fh:
            reader = make_reader(fh)
            reader.get_summary()
            n = sum(1 for _ in reader.iter_messages())
    except Exception:  # noqa: BLE001 (the mcap reader raises several types on a torn file)
        return False
    return n > 0


@pytest.mark.slow
def test_augment_killed(tmp_path: Path) -> None:
    """``augment --force`` killed over an existing MCAP: the old file or a complete new one,
    never a partial file under the output's name; a fresh run killed leaves nothing or a
    complete file."""
    from tests.export.rosbag_fixtures import write_bag
    from tests.test_cli_jobs import _write_log

    d = tmp_path / "setup"
    d.mkdir()
    log, _ = _write_log(d, labels=True)  # busy traffic: artefacts alive in a 12 s bag
    fit = ["fit", str(log), "--method", "em", "--no-figures", "--seed", "1"]
    run([*fit, *PAPER_MODELS, "--samples", "20", "--out", str(d / "a.nc")], d)
    bag = write_bag(d / "robot_bag", "mcap")
    base = ["augment", str(bag), "--fit", str(d / "a.nc"), "--map", MAP,
            "--camera-info-topic", "/camera/camera_info"]  # fmt: skip
    t_aug = run([*base, "--seed", "3", "--out", str(d / "aug_a.mcap")], d)
    old = (d / "aug_a.mcap").read_bytes()
    assert _complete_mcap(d / "aug_a.mcap")

    def attempt(i: int, delay: float) -> bool:
        w = tmp_path / f"k{i}"
        w.mkdir()
        (w / "aug.mcap").write_bytes(old)
        args = [*base, "--seed", "4", "--force", "--out", str(w / "aug.mcap")]
        killed = run_killed(args, w, delay) is None
        now = (w / "aug.mcap").read_bytes()
        assert now == old or _complete_mcap(w / "aug.mcap"), f"killed after {delay:.2f} s"
        fresh = w / "fresh.mcap"
        run_killed([*args[:-1], str(fresh)], w, delay)
        assert not fresh.exists() or _complete_mcap(fresh), f"killed at {delay:.2f} s: fresh"
        # anything else left is the writer's hidden temporary, never a file under a final name
        left = {p.name for p in w.iterdir()} - {"aug.mcap", "fresh.mcap"}
        assert all(n.startswith(".") and n.endswith(".tmp") for n in left), left
        return killed

    kill_rounds(t_aug, 4, attempt)


def test_kill_rounds_retries_at_shorter_moments_and_fails_when_none_killed() -> None:
    """A round where every run ended first is repeated at shorter moments; no kill at all
    fails the test (the kill tests above never pass without killing a run)."""
    total = 10.0
    seen: list[tuple[int, float]] = []

    def quick(i: int, delay: float) -> bool:  # a run that ends 2 s in
        seen.append((i, delay))
        return delay < 2.0

    kill_rounds(total, 1, quick)
    first = delays(total, salt=1)
    assert [d for _, d in seen[: len(first)]] == first and min(first) >= 3.0
    assert [i for i, _ in seen] == list(range(len(seen))) and len(seen) > len(first)
    assert any(d < 2.0 for _, d in seen)
    with pytest.raises(AssertionError, match="checked nothing"):
        kill_rounds(total, 1, lambda i, delay: False)
