"""The installed package stands alone (issue 17): build the wheel, install it outside the
repository and run the shipped defaults from an empty folder.

No network: the wheel is built with ``pip wheel --no-build-isolation --no-index`` (the build
backend, hatchling, is in the dev extra) and installed with ``pip install --target``. The
commands run with the dev environment's Python and ``PYTHONPATH`` set to the install only,
from an empty working directory, so the repository's copy cannot be imported and the
shipped files can only come from the wheel. The install is snapshotted before and after:
nothing may be written into it.

``ARE_STATS_FRESH_VENV=1`` (set by ``.ci/run``) also installs the wheel *with its
dependencies* into a fresh virtual environment, as a user's ``pip install`` does (from the
package registry the machine's pip is configured with: it needs that network), and runs the
console script there: a package the code imports but ``pyproject.toml`` does not declare
fails it.
"""

from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

import pytest
import yaml

from tests.helpers import TINY_SWEEP

ROOT = Path(__file__).resolve().parents[1]

#: What the defaults need from the wheel (paths inside the package).
SHIPPED_FILES = [
    "data/courtyard.yaml",
    "data/courtyard.pgm",
    "data/courtyard.ply",
    "data/artefacts/catalogue.yaml",
    "data/artefacts/person.obj",
    "data/cameras/front_camera.yaml",
    "data/logs/courtyard_traffic.csv",
    "data/logs/courtyard_traffic.yaml",
    "data/experiments/fig7.yaml",
    "data/experiments/fig7_fit.yaml",
]


def _snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``folder``: relative path -> (size, mtime in ns)."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _run(args: list[str], cwd: Path, env: dict[str, str], timeout: float = 300) -> str:
    res = subprocess.run(
        args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout, check=False
    )
    assert res.returncode == 0, f"{' '.join(map(str, args))} failed:\n{res.stdout}\n{res.stderr}"
    return res.stdout


PIP = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--no-input"]


def _build_wheel(tmp_path: Path) -> Path:
    """The package's wheel, built offline from the repository into ``tmp_path/dist``."""
    try:
        import hatchling  # noqa: F401
    except ImportError:  # pragma: no cover - an environment without the dev extra
        pytest.fail("the wheel is built offline with hatchling: pip install -e '.[dev]'")
    dist = tmp_path / "dist"
    _run(
        [*PIP, "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q",
         "-w", str(dist), str(ROOT)],
        tmp_path, dict(os.environ),
    )  # fmt: skip
    (wheel,) = dist.glob("are_stats-*.whl")
    return wheel


def _run_shipped_defaults(python: str, script: Path, pkg: Path, work: Path,
                          env: dict[str, str]) -> None:  # fmt: skip
    """Run the shipped defaults from the empty folder ``work`` with an installed package.

    ``python`` imports the package from ``pkg`` (checked); ``script`` is its installed
    ``are-stats`` console script.
    """
    where = _run([python, "-c", "import are_stats; print(are_stats.__file__)"], work, env)
    assert Path(where.strip()).resolve().is_relative_to(pkg.resolve()), where
    assert "demo" in _run([str(script), "--help"], work, env)

    # show: a shipped map by name, through the installed console script
    _run([str(script), "show", "courtyard", "--out", "x.png"], work, env)
    assert (work / "x.png").stat().st_size > 0

    # demo: the shipped log and map; the fit goes under --out (here where fig7_fit wants it)
    _run([python, "-m", "are_stats", "demo", "--quick", "--out", "fits"], work, env, timeout=900)
    for name in ("courtyard_traffic.nc", "summary.yaml", "scenarios/artefacts.parquet"):
        assert (work / "fits" / name).is_file(), name
    summary = yaml.safe_load((work / "fits" / "summary.yaml").read_text())
    assert summary["log"].startswith("courtyard_traffic")

    # experiment: a tiny sweep on the shipped map; the shipped configs resolve by name
    (work / "tiny.yaml").write_text(yaml.safe_dump(TINY_SWEEP))
    _run([python, "-m", "are_stats", "experiment", "tiny.yaml", "--out", "r"], work, env)
    assert len(list((work / "r" / "runs").glob("*.parquet"))) == 2
    check = (
        "from are_stats.experiments import load_sweep_config\n"
        "assert load_sweep_config('fig7')['map'] == 'courtyard'\n"
        "print(load_sweep_config('fig7_fit')['scenario']['fit'])\n"
    )
    fit = _run([python, "-c", check], work, env).strip()
    assert Path(fit) == (work / "fits" / "courtyard_traffic.nc").resolve()


@pytest.mark.slow
def test_wheel_runs_the_defaults_from_an_empty_folder(tmp_path):
    # 1. build the wheel from the repository, offline
    wheel = _build_wheel(tmp_path)
    # 2. install it outside the repository
    site = tmp_path / "site"
    _run(
        [*PIP, "install", "--no-deps", "--no-index", "-q", "--target", str(site), str(wheel)],
        tmp_path, dict(os.environ),
    )  # fmt: skip
    pkg = site / "are_stats"
    for name in SHIPPED_FILES:
        assert (pkg / name).is_file(), f"{name} is not in the wheel"
    before = _snapshot(site)
    # 3. run from an empty folder, importing only the install
    work = tmp_path / "work"
    work.mkdir()
    env = {
        **os.environ,
        "PYTHONPATH": str(site),
        "PYTHONDONTWRITEBYTECODE": "1",  # Python's own caches aside, the install stays as is
        "MPLBACKEND": "Agg",
    }
    env.pop("PYTHONSTARTUP", None)
    _run_shipped_defaults(sys.executable, site / "bin" / "are-stats", pkg, work, env)

    # nothing was written into the install
    after = _snapshot(site)
    assert after == before, sorted(set(after.items()) ^ set(before.items()))[:10]


@pytest.mark.slow
@pytest.mark.skipif(
    os.environ.get("ARE_STATS_FRESH_VENV", "") in ("", "0"),
    reason="the fresh virtual environment installs from the registry: ARE_STATS_FRESH_VENV=1",
)
def test_wheel_installs_into_a_fresh_venv_with_its_declared_dependencies(tmp_path):
    wheel = _build_wheel(tmp_path)
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True, clear=True).create(env_dir)
    bin_dir = env_dir / "bin"
    env = {
        k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")
    }
    env.update(
        PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '')}",
        MPLBACKEND="Agg",
        XDG_CACHE_HOME=str(tmp_path / "cache"),  # a user's first run: nothing compiled yet
    )
    py = str(bin_dir / "python")
    _run([py, "-m", "pip", "install", "--disable-pip-version-check", "--no-input", "-q",
          str(wheel)], tmp_path, env, timeout=900)  # fmt: skip
    work = tmp_path / "work"
    work.mkdir()
    _run_shipped_defaults(py, bin_dir / "are-stats", env_dir, work, env)
