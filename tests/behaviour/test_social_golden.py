"""The social force's walks held to the bit (issues 26 and 29).

The digests were taken from :func:`social_force_tracks` before its routes were computed
in one pass and its windows laid out by one function (commit f59a774, same inputs):
every neighbour search (all pairs, blocks of small scenes, the grid of cells, none at
strength 0), with arrival groups, within-person speed variation, a kinematic artefact and
a map with walls. A change that is pure engineering leaves them as they are: so did the
padding of a walk's windows of blocks and without repulsion to the walk's largest (issue
29; a block's sums keep their width, a walk without repulsion has none). Retaken on
2026-11-28 (issue 26), a change of behaviour: every walk here has a pace (``VARIATION``),
which now keeps to its plan's schedule (``_on_schedule``); without a pace the walks are
as before, bit for bit. Retaken again on 2026-11-28 (issue 26 follow-up): the pace's
desired OU compensates the relaxation time's lag as the heading's does (``_pace``:
``T_d = T - tau``, ``sd_d = sd sqrt(1 + tau / (2 T_d))``), so that the fit reads it back
as its truth (``tests/fitting/test_speed_recovery.py``); nothing else changed.
Retaken on 2026-11-28: the digests had been taken on an AVX-512 host, whose NumPy
trigonometry and XLA kernels give other last bits than the AVX2 kernels the suite now pins
on every x86-64 host (``tests/conftest.py``: ``PINNED_ISA``; these walks differed on an
AVX2 AMD EPYC with the same code and packages); nothing else changed.
Retaken on 2026-11-28, a change of behaviour: a walker's first integration step covers
only the time since its arrival (``_window``'s ``h = clip(t - t_on, 0, dt)``), not a whole
``dt`` that put it up to ``v0 dt`` ahead of its plan; every walk here changes from each
walker's first step (all four digests); nothing else changed.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pandas as pd
import pytest

from are_stats.behaviour import SocialForce, _social, social_force_tracks
from are_stats.environment import OccupancyGrid

#: sha256 of the walked tracks (columns, dtypes, values), from the code before the change.
WANT = {
    "room": "cd1bf546c9044ba92f68814ffa27d7e36c1dff32deaeb722e39d98490a949d44",
    "scenes": "d8a20babdf102bc743e991e01b70b66113f619003fd21a722a1424271dbc5d2b",
    "scenes, strength 0": "edfff839907ee70d0cf1b35df787ab6143ac643a9dc30dd24d20a6406349d5a2",
    "crowd": "9f5f778726e513dc07fbcbf2806a030667ba6946889e7ff82a396bb7f4a2abe1",
}


def _digest(df: pd.DataFrame) -> str:
    h = hashlib.sha256()
    h.update(repr([(c, str(df[c].dtype)) for c in df.columns]).encode())
    h.update(pd.util.hash_pandas_object(df, index=False).to_numpy().tobytes())
    return h.hexdigest()


def _walkers(rng: np.random.Generator, n: int, size: float, t_max: float) -> pd.DataFrame:
    """``n`` planned crossings of a ``size`` m square, with a corner each, sampled at 0.5 s;
    arrivals uniform on [0, t_max]."""
    rows = []
    for i in range(n):
        t0 = np.round(rng.uniform(0.0, t_max), 1)
        a, c, b = (rng.uniform(1.0, size - 1.0, 2) for _ in range(3))
        v = rng.lognormal(np.log(1.3), 0.12)
        legs = np.hypot(*(c - a)), np.hypot(*(b - c))
        t = t0 + np.arange(0.0, np.ceil(sum(legs) / v / 0.5) + 1) * 0.5
        s = np.minimum((t - t0) * v, sum(legs))
        f1 = np.clip(s / max(legs[0], 1e-9), 0, 1)[:, None]
        f2 = np.clip((s - legs[0]) / max(legs[1], 1e-9), 0, 1)[:, None]
        xy = np.where(s[:, None] <= legs[0], a + (c - a) * f1, c + (b - c) * f2)
        rows.append(pd.DataFrame({"id": i, "t": t, "x": xy[:, 0], "y": xy[:, 1], "yaw": 0.0}))
    return pd.concat(rows, ignore_index=True)


def _pairs(plan: pd.DataFrame) -> np.ndarray:
    """Group labels per row: walkers 0-1, 4-5, 8-9, ... walk in pairs."""
    return np.where(plan["id"] % 4 < 2, plan["id"] // 4, -1)


#: Within-person speed variation: seed, log-sd 0.15, correlation time 4 s.
VARIATION = (7, 0.15, 4.0)


def _room() -> OccupancyGrid:
    """A 16 x 16 m room of 0.1 m cells with walls around and a pillar in the middle."""
    data = np.zeros((160, 160))
    data[:3, :] = data[-3:, :] = data[:, :3] = data[:, -3:] = 100
    data[70:90, 70:90] = 100
    return OccupancyGrid(data, 0.1)


def _walk(name: str) -> pd.DataFrame:
    rng = np.random.default_rng(sorted(WANT).index(name))
    if name == "room":  # all pairs: windows of 16 and 32 people
        plan = _walkers(rng, 40, 16.0, 60.0)
        plan = plan[~((plan["x"].between(6.6, 9.4)) & (plan["y"].between(6.6, 9.4)))]
        car = (plan["id"] == 3).to_numpy()
        return social_force_tracks(
            plan, grid=_room(), groups=_pairs(plan), kinematic=car,
            speed_variation=VARIATION,
        )  # fmt: skip
    if name.startswith("scenes"):  # blocks: 80 scenes of 2-5 people
        scenes = []
        for s in range(80):
            one = _walkers(rng, 2 + s % 4, 8.0, 20.0 + s)
            scenes.append(one.assign(scenario=s))
        plan = pd.concat(scenes, ignore_index=True)
        params = SocialForce(strength=0.0) if name.endswith("0") else None
        return social_force_tracks(plan, params, groups=_pairs(plan), speed_variation=VARIATION)
    plan = _walkers(rng, 450, 30.0, 50.0)  # the grid of cells: 256 and 512 slots
    return social_force_tracks(plan, groups=_pairs(plan), speed_variation=VARIATION)


@pytest.fixture(scope="module")
def walks() -> dict[str, tuple[pd.DataFrame, set]]:
    """Each configuration walked once for both tests below (the coverage test walked all
    four again: 7 s of CPU cold), with the programs its windows ran: ``(slots, all_pairs,
    block, repel)`` (the spy only records; the walk is the same call)."""
    out = {}
    window = _social._window
    for name in sorted(WANT):
        programs: set = set()

        def spy(*args, programs=programs, **kw):  # all_pairs, block, repel: the last three
            programs.add((args[0][0].shape[0], args[-3], args[-2], args[-1]))
            return window(*args, **kw)

        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(_social, "_window", spy)
            out[name] = (_walk(name), programs)
    return out


@pytest.mark.parametrize("name", sorted(WANT))
def test_the_walks_are_those_of_the_code_before_the_change(name, walks):
    assert _digest(walks[name][0]) == WANT[name]


def test_the_walks_cover_the_searches_and_share_programs_without_repulsion(walks):
    """The configurations above do run every neighbour search (else their digests would
    hold nothing about it), and without repulsion the windows of a size share one program
    whatever search they would have had (the small scenes at strength 0: three, four
    before)."""
    programs = {name: p for name, (_, p) in walks.items()}
    seen = {(pairs, block > 0, repel) for p in programs.values() for _, pairs, block, repel in p}
    assert {(True, False, True), (False, True, True), (False, False, True)} <= seen
    assert (False, False, False) in seen  # strength 0: no search
    kinds = {name: len(p) for name, p in programs.items()}
    # room: all pairs of 16 and 32; scenes: blocks, all pairs of 16, 64 and 128; crowd:
    # the grid of 256 and 512 (not padded: _layout), all pairs of 32; strength 0: every
    # window padded to the walk's largest, 512 (issue 29; three programs before: 16, 64
    # and 512)
    assert kinds == {"room": 2, "scenes": 4, "scenes, strength 0": 1, "crowd": 3}
