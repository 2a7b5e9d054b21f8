"""`import are_stats` and `are-stats --help` stay light: heavy libraries load on first use."""

from __future__ import annotations

import subprocess
import sys

HEAVY = ["jax", "warp", "arviz", "numpyro", "pandas", "matplotlib", "scipy", "trimesh", "dask"]


def _loaded_after(code: str) -> set[str]:
    probe = f"{code}\nimport sys\nprint(' '.join(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(out.stdout.split())


def test_import_loads_no_heavy_library():
    loaded = _loaded_after("import are_stats")
    assert not loaded & set(HEAVY)


def test_cli_help_loads_no_heavy_library():
    loaded = _loaded_after(
        "from typer.testing import CliRunner\nfrom are_stats.cli import app\n"
        "assert CliRunner().invoke(app, ['--help']).exit_code == 0"
    )
    assert not loaded & set(HEAVY)


def test_public_names_resolve_and_jax_runs_in_64_bits():
    code = (
        "import are_stats as ar\n"
        "missing = [n for n in ar.__all__ if not hasattr(ar, n)]\n"
        "assert not missing, missing\n"
        "import jax.numpy as jnp\n"
        "assert jnp.zeros(1).dtype == jnp.float64\n"
        "assert 'GridMDP' in dir(ar)\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_x64_is_switched_on_when_jax_came_first():
    code = (
        "import jax, jax.numpy as jnp\nimport are_stats\nassert jnp.zeros(1).dtype == jnp.float64\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
