"""`import are_stats` and `are-stats --help` stay light: heavy libraries load on first use."""

from __future__ import annotations

import functools
import os
import subprocess
import sys
from pathlib import Path

import are_stats

HEAVY = ["jax", "warp", "arviz", "numpyro", "pandas", "matplotlib", "scipy", "trimesh", "dask"]


def _loaded_at_each(*steps: str) -> list[set[str]]:
    """The modules loaded after each of ``steps``, run one after the other in one fresh
    process (each process costs seconds of CPU for its imports: one process answers for
    several steps)."""
    show = "print(' '.join(sorted(__import__('sys').modules)))"
    probe = "\n".join(f"{step}\n{show}" for step in steps)
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    lines = out.stdout.splitlines()[-len(steps) :]
    return [set(line.split()) for line in lines]


def _loaded_after(code: str) -> set[str]:
    return _loaded_at_each(code)[-1]


def test_import_loads_no_heavy_library():
    loaded = _loaded_after("import are_stats")
    assert not loaded & set(HEAVY)


@functools.cache
def _cli_help_then_dask() -> list[set[str]]:
    """The modules after ``are-stats --help`` (in process), then after ``import dask``: one
    process, read by two tests."""
    return _loaded_at_each(
        "from typer.testing import CliRunner\nfrom are_stats.cli import app\n"
        "assert CliRunner().invoke(app, ['--help']).exit_code == 0",
        "import dask",
    )


def test_cli_help_loads_no_heavy_library():
    assert not _cli_help_then_dask()[0] & set(HEAVY)


#: What the modules of ``are-stats fit`` (the CLI, its jobs, the fitting package) leave out
#: until they are used: ArviZ (it imports pyplot, scipy.stats and scipy.signal) and xarray
#: come with the fit's InferenceData, built in a thread beside the Laplace runs; h5netcdf with
#: the fit file; the rooms and libraries of other commands not at all. Together about 2.2 s
#: of CPU that a fit would otherwise pay on its main thread before it starts (measured
#: 2026-11-29, load 11: arviz with matplotlib and scipy.stats 2.0 s, xarray and h5netcdf
#: 0.2 s).
_NOT_BEFORE_THE_FIT = frozenset(
    {
        "arviz",
        "matplotlib",
        "scipy.stats",
        "scipy.signal",
        "xarray",
        "h5netcdf",
        "h5py",
        "trimesh",
        "warp",
        "dask",
        "numba",
        "are_stats.perception",
        "are_stats.experiments",
    }
)


@functools.cache
def _first_uses() -> list[set[str]]:
    """The modules after each step of one process, read by the three tests below: [0] the
    traffic and fitting packages imported; [1] the fit command's modules too; [2] a
    traffic function that needs scipy.stats ran; [3] ArviZ used for the first time by the
    fitting package (three processes before 2026-11-29, about 8 s of CPU more)."""
    return _loaded_at_each(
        "import are_stats.traffic, are_stats.fitting",
        "import are_stats.cli, are_stats._cli_jobs",
        "import are_stats.traffic as t\n"
        "assert abs(t.BirthDeath(2.0, 0.1).stationary_pmf(20) - 0.0888) < 1e-3",
        "from are_stats.fitting import _fit_log as f\nassert 'not imported' in repr(f.az)\n"
        "assert f.az.InferenceData.__name__ == 'InferenceData'\n"
        "assert 'not imported' not in repr(f.az)",
    )


def test_the_fit_commands_modules_leave_figures_and_other_rooms_out():
    loaded = _first_uses()[1]
    assert not loaded & _NOT_BEFORE_THE_FIT, sorted(loaded & _NOT_BEFORE_THE_FIT)


def test_the_fitting_package_imports_arviz_on_first_use():
    """ArviZ (2 s of imports) comes in when a fit is built or read, not with the package."""
    before, with_cli, _, used = _first_uses()
    assert "arviz" not in before and "arviz" not in with_cli
    assert "arviz" in used


def test_traffic_and_fitting_import_scipy_stats_on_first_use():
    """scipy.stats (0.3-0.4 s of imports, scipy.signal brings it too) comes in when a
    function that needs it runs, not with the traffic and fitting packages."""
    before, with_cli, used, _ = _first_uses()
    for loaded in (before, with_cli):
        assert "scipy.stats" not in loaded and "scipy.signal" not in loaded
    assert "scipy.stats" in used


@functools.cache
def _public_names_then_warp() -> subprocess.CompletedProcess:
    """One process, read by two tests: every public name resolves (the perception package,
    and with it Warp, among them), then Warp lists its devices."""
    code = (
        "import are_stats as ar\n"
        "missing = [n for n in ar.__all__ if not hasattr(ar, n)]\n"
        "assert not missing, missing\n"
        "import jax.numpy as jnp\n"
        "assert jnp.zeros(1).dtype == jnp.float64\n"
        "assert 'GridMDP' in dir(ar)\n"
        "import are_stats.perception\nimport warp as wp\nprint(wp.get_devices())"
    )
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)


def test_public_names_resolve_and_jax_runs_in_64_bits():
    out = _public_names_then_warp()
    assert out.returncode == 0, out.stderr


def test_x64_is_switched_on_when_jax_came_first():
    code = (
        "import jax, jax.numpy as jnp\nimport are_stats\nassert jnp.zeros(1).dtype == jnp.float64\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_second_process_hits_the_compile_cache(tmp_path):
    """JAX's persistent cache is on by default (small programs too) and really hit."""

    code = (
        "import are_stats, jax, jax.numpy as jnp\n"
        "ev = []\n"
        "jax.monitoring.register_event_listener(lambda e, **k: ev.append(e))\n"
        "jax.jit(lambda x: jnp.sin(x) * 2 + 1)(jnp.arange(3.0)).block_until_ready()\n"
        "n = lambda tail: sum(e.endswith(tail) for e in ev)\n"
        "print(n('cache_hits'), n('cache_misses'))\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "ARE_STATS_"))}
    env["XDG_CACHE_HOME"] = str(tmp_path)

    def run(extra=()):
        out = subprocess.run(
            [sys.executable, "-c", code],
            env={**env, **dict(extra)},
            capture_output=True,
            text=True,
            check=True,
        )
        return [int(v) for v in out.stdout.split()]

    hits, misses = run()
    assert hits == 0 and misses > 0
    assert any((tmp_path / "are_stats" / "jax").iterdir())
    hits, misses = run()
    assert hits > 0 and misses == 0
    hits, misses = run({"ARE_STATS_NO_CACHE": "1"})
    assert hits == 0


def test_a_cli_run_keeps_the_cache_under_its_cap(tmp_path):
    """Every ``are-stats`` run prunes the cache folders it manages to their cap
    (``ARE_STATS_CACHE_MAX_MB``): the least recently used files go first."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("JAX_", "ARE_STATS_"))}
    env["XDG_CACHE_HOME"] = str(tmp_path)
    env["ARE_STATS_CACHE_MAX_MB"] = "0.001"  # 1048 bytes
    programs = tmp_path / "are_stats" / "programs"
    programs.mkdir(parents=True)
    old, new = programs / "old.jaxexport", programs / "new.jaxexport"
    old.write_bytes(b"o" * 800)
    new.write_bytes(b"n" * 800)
    os.utime(old, (1.0, 1.0))
    subprocess.run([sys.executable, "-m", "are_stats", "version"], env=env, check=True,
                   capture_output=True)  # fmt: skip
    assert not old.exists() and new.exists()


def test_warp_starts_without_the_cuda_probe_warning():
    """Warp's native start-up warns on stderr about a missing NVIDIA driver on every
    CPU-only machine; the perception package starts Warp with that line filtered out."""
    out = _public_names_then_warp()
    assert out.returncode == 0, out.stderr
    assert "cpu" in out.stdout
    assert "NVIDIA CUDA driver" not in out.stderr


def test_cli_keeps_xla_log_banners_from_the_user():
    """XLA's C++ log ('Very slow compile? If you want to file a bug...') is switched off in
    the command's process unless the user set its level."""
    code = "import os\nimport are_stats.cli\nprint(os.environ['TF_CPP_MIN_LOG_LEVEL'])"
    env = {k: v for k, v in os.environ.items() if k != "TF_CPP_MIN_LOG_LEVEL"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.strip() == "3", out.stderr
    env["TF_CPP_MIN_LOG_LEVEL"] = "1"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.strip() == "1", out.stderr


def test_type_checkers_see_every_lazy_name_and_the_table_matches_the_subpackages():
    """The TYPE_CHECKING block of are_stats/__init__.py imports exactly the names of the lazy
    table, each from the subpackage the table says, and every such name is in that
    subpackage's __all__ (so the table is tested against the subpackages)."""
    import ast
    import importlib
    from pathlib import Path

    import are_stats

    tree = ast.parse(Path(are_stats.__file__).read_text())
    seen: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom)
                seen.update({a.name: imp.module for a in imp.names})
    assert seen == are_stats._LAZY
    for name, module in are_stats._LAZY.items():
        assert name in importlib.import_module(module).__all__, (name, module)


#: The rooms in the order data flows through them (docs/src/index.md, the house), and the
#: rooms below the line that feed them: a room imports only from rooms to its left or below.
_LINE = ("logs", "fitting", "scenarios", "builder", "perception", "experiments", "export")
_BELOW = ("environment", "traffic", "behaviour")
#: Imports against the flow that stay, and why (each is a place to remove, not to copy).
_AGAINST_THE_FLOW = {
    # criticism simulates replicate logs from the posterior with the scenario generator
    ("fitting", "scenarios"),
    # a sweep task writes its mission's MCAP when asked (--mcap)
    ("experiments", "export"),
    # pose -> box is one function, in the builder's geometry (Scene.at uses it)
    ("scenarios", "builder"),
    # one collision story (DECISIONS 9): MDP rollouts resolve conflicts with the
    # AR-builder's own revert rule on the MDP's cells, not a copy of it
    ("behaviour", "builder"),
}


def test_rooms_import_one_way():
    """Every ``from are_stats.<room> import`` in a room's modules points left along the line
    (logs -> fitting -> scenarios -> builder -> perception -> experiments -> export) or down
    (environment, traffic, behaviour), apart from the listed exceptions."""
    import ast

    rooms = (*_LINE, *_BELOW)
    root = Path(are_stats.__file__).parent
    found = set()
    for f in root.rglob("*.py"):
        src = f.relative_to(root).parts[0]
        if src not in rooms:
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("are_stats."):
                dst = node.module.split(".")[1]
                if dst in rooms and dst != src:
                    found.add((src, dst, f"{f.relative_to(root)}:{node.lineno}"))

    def allowed(src: str, dst: str) -> bool:
        if dst in _BELOW and src not in _BELOW:
            return True
        if src in _LINE and dst in _LINE:
            return _LINE.index(dst) < _LINE.index(src)
        if src in _BELOW and dst in _BELOW:
            return _BELOW.index(dst) < _BELOW.index(src)
        return False

    bad = sorted(
        where
        for src, dst, where in found
        if not allowed(src, dst) and (src, dst) not in _AGAINST_THE_FLOW
    )
    assert not bad, f"imports against the flow: {bad}"
    used = {(s, d) for s, d, _ in found}
    assert _AGAINST_THE_FLOW <= used, f"exceptions no longer needed: {_AGAINST_THE_FLOW - used}"


def test_issue_25_recount_stays_at_one():
    """The recount of "Fit in, Scenes out": one call that builds Scenes from tables outside
    tests, one reader of a scenarios folder, one coarsener, one reader of the fit's class
    labels (the typed Fit)."""
    import re

    root = Path(are_stats.__file__).parent
    text = {
        str(f.relative_to(root)): f.read_text() for f in root.rglob("*.py")
    }  # fmt: skip

    def where(pattern: str) -> list[str]:
        return sorted(
            f"{name}:{i + 1}"
            for name, src in text.items()
            for i, line in enumerate(src.splitlines())
            if re.search(pattern, line) and ">>>" not in line
        )

    files = lambda pattern: [w.split(":")[0] for w in where(pattern)]  # noqa: E731
    assert files(r"Scene\.from_scenarios\(") == ["scenarios/_assembly.py"]
    assert where(r"def (read_scenarios|load_replay|read_scenario_folder)\b") == []
    # one writer of a scenarios folder too: write_scenes (write_scenarios was its wrapper)
    assert files(r"def write_scen") == ["scenarios/_folder.py"]
    assert where(r"def (coarse_free_mask|coarse_occupancy)\b") == []
    assert files(r'attrs\.get\("class_labels"\)') == ["fitting/_fit.py"]


def test_hide_dask_leaves_xarray_writing_and_reading_netcdf(tmp_path):
    """Without dask (are_stats._lazy.hide_dask) xarray still writes and reads a NetCDF
    file, and imports neither dask nor distributed on the way."""
    out = tmp_path / "x.nc"
    loaded = _loaded_after(
        "from are_stats._lazy import hide_dask, import_xarray_dask\n"
        "assert hide_dask()\n"
        "import_xarray_dask()\n"
        "import numpy as np, xarray as xr\n"
        "xr.Dataset({'a': ('x', np.arange(3.0))}).to_netcdf("
        f"{str(out)!r}, engine='h5netcdf')\n"
        f"with xr.open_dataset({str(out)!r}, engine='h5netcdf') as d:\n"
        "    assert d['a'].values.tolist() == [0.0, 1.0, 2.0]\n"
        "try:\n    import dask\nexcept ImportError:\n    pass\nelse:\n    raise AssertionError\n"
        "import sys\nassert all(sys.modules[n] is None for n in ('dask', 'distributed'))\n"
        "del sys.modules['dask'], sys.modules['distributed']"
    )
    assert not {m for m in loaded if m.split(".")[0] in ("dask", "distributed")}


@functools.cache
def _hidden_after_main(argv: tuple[str, ...]) -> dict[str, str]:
    """``repr(sys.modules.get(name))`` of dask and numba after are_stats.cli.main ran
    ``argv``: one process per command line, read by both tests below (each process costs
    seconds of CPU: the fit and report imports)."""
    code = (
        f"import sys\nsys.argv = ['are-stats', *{list(argv)!r}]\nfrom are_stats import cli\n"
        "try:\n    cli.main()\nexcept SystemExit:\n    pass\n"
        "print(repr(sys.modules.get('dask', 'absent')))\n"
        "print(repr(sys.modules.get('numba', 'absent')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    dask, numba = out.stdout.strip().splitlines()[-2:]
    return {"dask": dask, "numba": numba}


#: fit, report after a global option, experiment: the command lines both tests run.
_FIT = ("fit", "no_such_log.csv", "--out", "x.nc")
_REPORT = ("--max-memory", "4G", "report", "no_such_fit.nc")
_EXPERIMENT = ("experiment", "--help")


def test_cli_main_hides_dask_from_a_fit_only():
    """The console script hides dask for `fit` (also after global options), not for
    `experiment` (its sweeps run on Dask), and importing the CLI hides nothing."""
    assert _hidden_after_main(_FIT)["dask"] == "None"
    assert _hidden_after_main(_REPORT)["dask"] == "None"
    assert _hidden_after_main(_EXPERIMENT)["dask"] == "'absent'"


def test_cli_main_hides_numba_from_a_fit_only():
    """numba (imported and compiled by ``import arviz`` where installed) is hidden for
    `fit` and `report` (also after global options), as dask is, and not for `experiment`."""
    assert _hidden_after_main(_FIT)["numba"] == "None"
    assert _hidden_after_main(_REPORT)["numba"] == "None"
    assert _hidden_after_main(_EXPERIMENT)["numba"] == "'absent'"


def test_hide_numba_leaves_arviz_on_its_numpy_paths():
    """Without numba (are_stats._lazy.hide_numba) ArviZ imports, says it has no numba and
    summarises a posterior; nothing of numba or llvmlite is loaded on the way."""
    loaded = _loaded_after(
        "from are_stats._lazy import hide_numba\n"
        "assert hide_numba()\n"
        "import numpy as np, arviz as az\n"
        "assert not az.Numba.numba_flag\n"
        "draws = np.random.default_rng(0).normal(size=(2, 50))\n"
        "assert az.summary(az.from_dict(posterior={'a': draws})).shape[0] == 1\n"
        "import sys\nassert sys.modules['numba'] is None\ndel sys.modules['numba']"
    )
    assert not {m for m in loaded if m.split(".")[0] in ("numba", "llvmlite")}
    # importing the CLI hides nothing: dask still imports after it
    assert "dask" in _cli_help_then_dask()[1]


def test_command_of_skips_the_global_options():
    from are_stats.cli import _command_of

    assert _command_of(["fit", "log.csv"]) == "fit"
    assert _command_of(["--max-work", "1e9", "--no-cache", "report", "f.nc"]) == "report"
    assert _command_of(["--version"]) is None
