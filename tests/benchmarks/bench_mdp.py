"""Benchmark: finite-horizon MDP backward induction, ours vs pymdptoolbox FiniteHorizon.

Problem (MEASUREMENTS.md): a 100 x 100 grid with 10 % random obstacles, 4 headings
(40,000 states), 5 actions (behaviour ``run``: every action allowed), slip 0.1, horizon
d = 100. pymdptoolbox solves the very same ``(P, R)`` exported by ``GridMDP.to_dense(...,
sparse=True)``; its values must agree with ours (float32) to 1e-4.

pymdptoolbox 4.0b3 on current scipy: its non-negativity check evaluates ``matrix >= 0`` on a
sparse matrix, which scipy answers with a dense boolean matrix of S x S entries (1.6e9 for
40,000 states: memory exhausted). We patch ``mdptoolbox.util.isNonNegative`` with a check of
the stored entries only (``matrix.data >= 0``) and hand it ``csr_array`` matrices.

Also timed: a batch of 64 goals in one ``solve`` (split across the XLA host devices, one
item at a time on each), against 64 pymdptoolbox solves (extrapolated from the single-goal
time). Like the CLI, the benchmark asks for two XLA host devices (one per core of the 2-core
reference machine) unless ``XLA_FLAGS`` is set.

Targets (issue 16, "Performance"): at most 3 ms per solve with the policy, and at most
0.2 s for the batch of 64 (full size only); the benchmark prints each time against its target.

Run ``python -m tests.benchmarks.bench_mdp`` (``--quick``: 50 x 50 grid, 3 repeats).
"""

from __future__ import annotations

import os
import sys
import time

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=2")

import numpy as np
import scipy.sparse as sp

import are_stats  # noqa: F401  (x64 on; we ask for float32 explicitly)
from are_stats.behaviour import GridMDP

#: Issue 16 targets (full size): seconds per solve with the policy, per batch of 64 goals.
_TARGET_SOLVE = 3e-3
_TARGET_BATCH = 0.2


def _median_time(fn, repeats: int) -> float:
    fn()  # warm-up (compilation)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def _patch_mdptoolbox():
    import mdptoolbox.util as util

    def is_non_negative(matrix) -> bool:
        if sp.issparse(matrix):
            return bool((matrix.data >= 0).all())
        return bool((np.asarray(matrix) >= 0).all())

    util.isNonNegative = is_non_negative
    import mdptoolbox.mdp as mdp_mod

    return mdp_mod


def main(quick: bool = False) -> None:
    size = 50 if quick else 100
    d = 50 if quick else 100
    repeats = 3 if quick else 7
    batch = 16 if quick else 64
    rng = np.random.default_rng(0)
    occ = rng.random((size, size)) < 0.1
    free = np.argwhere(~occ)
    goal = free[len(free) // 2]
    mdp = GridMDP(occ, slip=0.1)
    import jax

    print(
        f"grid {size} x {size} x 4 = {mdp.n_states} states, 5 actions, slip 0.1, d = {d}; "
        f"{jax.local_device_count()} XLA device(s)"
    )

    sol = mdp.solve(goal, "run", d, store_values=False)
    t_ours = _median_time(lambda: mdp.solve(goal, "run", d, store_values=False), repeats)
    t_vals = _median_time(
        lambda: mdp.solve(goal, "run", d, store_values=False, with_policy=False), repeats
    )

    try:
        mdp_mod = _patch_mdptoolbox()
    except ImportError:
        print("pymdptoolbox not installed (pip install '.[bench]'): peer skipped")
        mdp_mod = None
    if mdp_mod is not None:
        p, r, _ = mdp.to_dense(goal, "run", sparse=True)
        fh = mdp_mod.FiniteHorizon(tuple(p), r, 1.0, d)

        def peer():
            fh.V[:, :d] = 0.0
            fh.run()

        t_peer = _median_time(peer, repeats)
        err = np.abs(fh.V[:, 0] - sol.v0[0].reshape(-1)).max()
        q = r + np.stack([m @ fh.V[:, 1] for m in p], axis=1)
        top2 = np.sort(q, axis=1)[:, -2:]
        decisive = top2[:, 1] - top2[:, 0] > 1e-5  # near-ties break differently in float32
        agree = np.mean((fh.policy[:, 0] == sol.policy[0, 0].reshape(-1))[decisive])
        print(f"pymdptoolbox FiniteHorizon   {t_peer * 1e3:9.2f} ms per solve")
        print(f"ours (JAX stencil, float32)  {t_ours * 1e3:9.2f} ms per solve (V_t and pi_t)")
        print(f"speed-up                     {t_peer / t_ours:9.1f} x")
        print(f"ours, values only            {t_vals * 1e3:9.2f} ms per solve (pi_t on demand)")
        print(f"speed-up                     {t_peer / t_vals:9.1f} x")
        print(
            f"max |V0 ours - V0 peer| = {err:.2e}; policy pi_0 agreement {agree:.4f} "
            f"on the {decisive.mean():.0%} of states without near-ties"
        )
    else:
        print(f"ours (JAX stencil, float32)  {t_ours * 1e3:9.2f} ms per solve (V_t and pi_t)")
        print(f"ours, values only            {t_vals * 1e3:9.2f} ms per solve")

    goals = free[rng.choice(len(free), batch, replace=False)]
    t_batch = _median_time(
        lambda: mdp.solve(goals, "run", d, store_values=False), max(3, repeats // 2)
    )
    print(
        f"batch of {batch} goals (policy)   {t_batch:9.3f} s ({t_batch / batch * 1e3:.1f} ms/goal)"
    )
    t_bvals = _median_time(
        lambda: mdp.solve(goals, "run", d, store_values=False, with_policy=False),
        max(3, repeats // 2),
    )
    print(f"batch of {batch}, values only     {t_bvals:9.3f} s")
    if mdp_mod is not None:
        print(f"pymdptoolbox x {batch} (extrapolated) {t_peer * batch:9.3f} s")
        print(f"batch speed-up vs pymdptoolbox {t_peer * batch / t_batch:9.1f} x")
    if not quick:
        for name, t, target in (
            ("solve with the policy", t_ours, _TARGET_SOLVE),
            (f"batch of {batch} with the policy", t_batch, _TARGET_BATCH),
        ):
            verdict = "met" if t <= target else "MISSED"
            print(
                f"target {name}: <= {target * 1e3:.0f} ms, measured {t * 1e3:.1f} ms "
                f"({t / target:.2f} of the target): {verdict}"
            )
    sys.stdout.flush()


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
