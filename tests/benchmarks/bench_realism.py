"""Benchmark: does the fitted motion beat the baselines on a crowd that is not constant
velocity (issue 26)?

The crowd is :mod:`tests.crowd` (an independent simulator: door to door round a pillar,
velocity-obstacle avoidance, groups abreast at about 0.7 m, 2.5 Hz, 5 cm noise), fitted
and scored by :func:`tests.crowd.crowd_realism` as ``are-stats fit`` does: the realism
table (fitted, constant velocity, catalogue behaviour) and the displacement errors (8
observed / 12 predicted, mean and best of 20) are printed, with the CPU time of each stage.

Run with ``python -m tests.benchmarks realism`` (300 s of crowd, 3 replicates of each
stochastic model; ``--quick``: one replicate, no displacement errors).
"""

from __future__ import annotations

import sys

import pandas as pd

from tests.crowd import crowd_realism


def main(quick: bool = False) -> None:
    """Fit the crowd, print the realism table and the displacement errors (``quick``: one
    replicate, no displacement errors)."""
    horizon = 300.0
    r = crowd_realism(0, horizon, 1 if quick else 3, errors=not quick)
    tr = r["tracks"]
    print(f"crowd: {tr['id'].nunique()} people, {len(tr)} rows over {horizon:g} s")
    print("fitted interaction:", r["interaction"], {k: round(v, 3) for k, v in r["info"].items()})
    with pd.option_context("display.width", 120, "display.float_format", "{:.3f}".format):
        print(r["table"])
        if r["errors"] is not None:
            print(r["errors"])
    print(
        f"observation noise the models are seen with: {r['table'].attrs['observation_noise']:.3f} m"
    )
    print("CPU s:", {k: round(v, 1) for k, v in r["cpu"].items()})


if __name__ == "__main__":
    main(quick="--quick" in sys.argv[1:])
