"""Plotting functions leave a running pyplot session's backend alone (a notebook's inline
backend stayed switched to Agg after ``plot_traffic_checks``, so every later figure of
``notebooks/02`` vanished from its outputs)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = """
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from are_stats.fitting import TRAFFIC_STATISTICS, plot_traffic_checks

table = pd.DataFrame({"observed": 1.0, "paper_flag": False, "chosen_flag": True},
                     index=list(TRAFFIC_STATISTICS))
rng = np.random.default_rng(0)
reps = {m: rng.normal(1.0, 0.2, (20, len(TRAFFIC_STATISTICS))) for m in ("paper", "chosen")}
fig = plot_traffic_checks(table, reps)
print(plt.get_backend(), sum(ax.get_visible() for ax in fig.axes), len(TRAFFIC_STATISTICS))
"""


def test_plot_traffic_checks_keeps_the_session_backend():
    env = {**os.environ, "MPLBACKEND": "svg", "PYTHONPATH": str(ROOT)}
    res = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env, cwd=ROOT
    )
    assert res.returncode == 0, res.stderr
    backend, n_axes, n_stats = res.stdout.split()
    assert backend == "svg"  # Agg before the fix
    assert int(n_axes) == int(n_stats) == 10  # one panel per statistic
