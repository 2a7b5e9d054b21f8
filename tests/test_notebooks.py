"""Every notebook in notebooks/ executes top to bottom (with its own small arguments)."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


def test_there_are_notebooks():
    assert NOTEBOOKS, "notebooks/ has no notebook"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebooks_are_committed_with_their_outputs(path):
    """Readers where the code is hosted see the figures: every code cell ran (in order,
    without an error) and the notebook holds its pictures."""
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code" and c.source.strip()]
    counts = [c.get("execution_count") for c in code]
    assert all(isinstance(n, int) for n in counts), f"{path.name}: cells not executed"
    assert counts == sorted(counts), f"{path.name}: cells executed out of order"
    outputs = [o for c in code for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    assert any("image/png" in o.get("data", {}) for o in outputs), f"{path.name}: no figure"


@pytest.fixture(scope="module")
def kernel(tmp_path_factory):
    """One kernel runs the notebooks one after the other (started once: each kernel's start
    and imports of the package, JAX and Matplotlib cost some 4 s of CPU); before each, its
    namespace is emptied (``%reset -f``), so a notebook that uses a name it does not define
    or import still fails, and the working directory is the notebook's own folder."""
    from jupyter_client.manager import AsyncKernelManager
    from jupyter_core.utils import run_sync

    with pytest.MonkeyPatch.context() as env:
        env.setenv("ARE_STATS_NOTEBOOK_QUICK", "1")
        env.setenv("MPLBACKEND", "Agg")
        km = AsyncKernelManager(kernel_name="python3")
        run_sync(km.start_kernel)(cwd=str(tmp_path_factory.mktemp("kernel")))
    yield km
    run_sync(km.shutdown_kernel)(now=True)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, kernel):
    nb = nbformat.read(path, as_version=4)
    fresh = f"%reset -f\nimport os\nos.chdir({str(tmp_path)!r})\ndel os"
    nb.cells.insert(0, nbformat.v4.new_code_cell(fresh))
    client = NotebookClient(nb, km=kernel, timeout=600)
    client.execute()
    errors = [
        o
        for c in nb.cells
        if c.cell_type == "code"
        for o in c.get("outputs", [])
        if o.get("output_type") == "error"
    ]
    assert not errors
