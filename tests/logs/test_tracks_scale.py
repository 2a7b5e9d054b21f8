"""Tracks tables at scale: group inference with bounded work, duplicate sightings, far cells.

Group inference is checked against a plain all-pairs reference (the algorithm it replaced,
kept here): on random tracks, crowds and moving groups the groups must be the same; on
thousands of tracks that start together at one spot its work must stay far below the
number of pairs (a ``check_work`` bound the all-pairs algorithm cannot meet).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import are_stats.logs._tracks as tracks_module
from are_stats.inputs import LimitError, limits
from are_stats.logs import read_tracks, tracks_to_lifecycle
from are_stats.logs._tracks import GROUP_HORIZON_STEPS

# ---- the all-pairs reference (the algorithm before the sweep and grid) -------------------


def _reference_move_together(a, b, first, last, t, x, y, horizon, step, max_dist):
    start = max(t[first[a]], t[first[b]])
    ta, tb = t[first[a] : last[a] + 1], t[first[b] : last[b] + 1]
    ka = np.flatnonzero((ta >= start - 0.5 * step) & (ta <= start + horizon))
    if ka.size == 0 or tb.size == 0:
        return True
    pos = np.clip(np.searchsorted(tb, ta[ka]), 1, max(tb.size - 1, 1))
    lo = np.clip(pos - 1, 0, tb.size - 1)
    hi = np.clip(pos, 0, tb.size - 1)
    near = np.where(np.abs(tb[lo] - ta[ka]) <= np.abs(tb[hi] - ta[ka]), lo, hi)
    match = np.abs(tb[near] - ta[ka]) < 0.5 * step
    if match.sum() < 2:
        return True
    ia, ib = ka[match] + first[a], near[match] + first[b]
    return bool((np.hypot(x[ia] - x[ib], y[ia] - y[ib]) <= max_dist).all())


def _reference_groups(segs, first, last, t, x, y, seg_ids, g_time, g_dist, step):
    out = np.full(len(first), "", dtype=object)
    if len(segs) < 2 or g_dist <= 0:
        return out
    tf = t[first[segs]]
    order = np.argsort(tf, kind="stable")
    segs, tf = segs[order], tf[order]
    fx, fy = x[first[segs]], y[first[segs]]
    parent = list(range(len(segs)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    horizon = GROUP_HORIZON_STEPS * step
    for i in range(len(segs)):
        for j in range(i + 1, len(segs)):
            if not tf[j] <= tf[i] + g_time:
                break
            if np.hypot(fx[j] - fx[i], fy[j] - fy[i]) > g_dist:
                continue
            if _reference_move_together(
                segs[i], segs[j], first, last, t, x, y, horizon, step, 2 * g_dist
            ):
                parent[find(i)] = find(j)
    comp = np.array([find(i) for i in range(len(segs))])
    for c in np.unique(comp):
        members = np.flatnonzero(comp == c)
        if members.size > 1:
            out[segs[members]] = seg_ids[segs[members.min()]]
    return out


def _groups(frame, monkeypatch=None, reference=False, **kwargs):
    if reference:
        monkeypatch.setattr(tracks_module, "_infer_groups", _reference_groups)
    out = tracks_to_lifecycle(frame, **kwargs)
    if reference:
        monkeypatch.undo()
    return dict(zip(out["id"], out["group"], strict=True))


def _random_tracks(rng, n, box, step=0.4):
    """People arriving on a frame clock (some off it), alone or walking in loose groups,
    some standing, in a ``box`` m square: dense enough for many candidate pairs."""
    rows = []
    for k in range(n):
        t0 = rng.integers(0, 40) * step + (rng.random() < 0.2) * rng.normal(0, 0.05)
        length = int(rng.integers(1, 30))
        x0, y0 = rng.uniform(0, box, 2)
        v = rng.normal(0, 1, 2) * rng.choice([0.0, 1.0])
        tt = np.sort(t0 + np.arange(length) * step + rng.normal(0, 0.03, length) * (k % 3 == 0))
        for i, ti in enumerate(tt):
            rows.append(
                (f"p{k}", ti, x0 + v[0] * step * i + rng.normal(0, 0.3),
                 y0 + v[1] * step * i + rng.normal(0, 0.3))
            )  # fmt: skip
    frame = pd.DataFrame(rows, columns=["id", "t", "x", "y"])
    return frame.drop_duplicates(["id", "t"]).reset_index(drop=True)


@pytest.mark.parametrize("seed", range(6))
def test_groups_match_the_all_pairs_reference(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    frame = _random_tracks(rng, int(rng.integers(40, 160)), box=[1.0, 3.0, 10.0][seed % 3])
    new = _groups(frame, window=(-1.0, 40.0))
    old = _groups(frame, monkeypatch, reference=True, window=(-1.0, 40.0))
    assert new == old
    assert sum(g != "" for g in new.values()) > 5  # groups were found at all


def test_groups_of_a_parting_crowd_match_the_reference(monkeypatch):
    """80 people leave one spot together at 6 m/s in random directions: neighbours in
    direction stay within 2 x group_distance and link, the others part (many pairs)."""
    rng = np.random.default_rng(7)
    n, length = 80, 12
    ang = np.repeat(rng.uniform(0, 2 * np.pi, n), length)
    tt = np.tile(np.arange(length) * 0.4, n) + np.repeat(rng.integers(0, 2, n) * 0.4, length)
    r = np.tile(np.arange(length) * 0.4, n) * 6.0
    frame = pd.DataFrame(
        {"id": np.repeat([f"q{k}" for k in range(n)], length), "t": tt,
         "x": r * np.cos(ang), "y": r * np.sin(ang)}
    )  # fmt: skip
    new = _groups(frame)
    old = _groups(frame, monkeypatch, reference=True)
    assert new == old
    assert 1 < len(set(new.values()) - {""}) < n


@pytest.mark.parametrize(
    ("n", "length", "limit"),
    [
        (5000, 10, 2e6),  # thousands standing together at one spot
        (5000, 1, 2e6),  # thousands seen once, at one spot, in one frame
        (1000, 1000, 2e5),  # a million sightings at one spot
    ],
)
def test_colocated_tracks_are_grouped_with_bounded_work(n, length, limit):
    """All pairs (n^2 / 2 = 12.5 million, or 500,000 checks of 1000 sightings) would
    break the work limit; the sweep checks each new track against a few members of the one
    group nearby."""
    frame = pd.DataFrame(
        {
            "id": np.repeat([f"p{k}" for k in range(n)], length),
            "t": np.tile(np.arange(length) * 0.4, n),
            "x": 3.0,
            "y": -2.0,
        }
    )
    with limits(work=limit):
        out = tracks_to_lifecycle(frame, window=(-10.0, 1000.0), time_step=0.4)
    assert len(out) == n
    assert set(out["group"]) == {"p0"}
    assert out.attrs["tracks"]["groups"] == 1


def test_group_work_is_counted_and_bounded():
    """The work counter: linear in the crowd for tracks that move together, and a parting
    crowd whose pairs must all be looked at is refused by the work limit, cleanly."""
    first = np.arange(0, 2000 * 5, 5)
    last = first + 4
    t = np.tile(np.arange(5) * 0.4, 2000)
    x = np.zeros(t.size)
    y = np.zeros(t.size)
    ids = np.array([f"p{k}" for k in range(2000)], dtype=object)
    segs = np.arange(2000)
    stats: dict = {}
    out = tracks_module._infer_groups(segs, first, last, t, x, y, ids, 0.6, 1.5, 0.4, stats)
    assert set(out) == {"p0"}
    assert stats["pair_checks"] <= 4 * 2000  # a few checks per track, not 2 million
    # parting in 2000 directions: about 2 million pairs to look at, past a small limit
    ang = np.repeat(np.linspace(0, 2 * np.pi, 2000, endpoint=False), 5)
    x, y = np.cos(ang) * t * 5.0, np.sin(ang) * t * 5.0
    with limits(work=1e5), pytest.raises(LimitError, match="group inference"):
        tracks_module._infer_groups(segs, first, last, t, x, y, ids, 0.6, 1.5, 0.4)


# ---- duplicate sightings and far coordinates ------------------------------------------


@pytest.mark.parametrize(
    ("text", "message"),
    [
        # a one-point track seen twice at one time, at the same spot
        ("id,t,x,y\na,0,1,1\nb,0,2,2\nb,1,2,3\na,0,1,1\n",
         r"row 4 \(line 5\), column 't': expected one sighting per \(id, t\), got id 'a' seen "
         r"twice at t=0\.0: row 1 \(line 2\) has the same position"),
        # conflicting positions
        ("id,t,x,y\na,0,1,1\na,0.4,1,2\na,0.4,5,5\n",
         r"row 3 \(line 4\), column 't': .* id 'a' seen twice at t=0\.4: row 2 \(line 3\) has "
         r"another position \(1\.0, 2\.0\)"),
        # one time written two ways
        ("id,t,x,y\n7,1,0,0\n7,1.0e0,0,0\n", r"row 2 \(line 3\), column 't': .* id '7'"),
        ("id,t,x,y\na,0,1e300,0\n", r"row 1 \(line 2\), column 'x': expected a map coordinate "
         r"within \+-1e\+09 m, got 1e\+300"),
        ("id,t,x,y\na,0,0,0\na,1,0,-2e9\n", r"row 2 \(line 3\), column 'y'"),
    ],
)  # fmt: skip
def test_duplicate_sightings_and_far_coordinates_are_errors(tmp_path, text, message):
    path = tmp_path / "tr.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as err:
        read_tracks(path)
    assert str(err.value).startswith(str(path))


def test_duplicate_sightings_in_a_frame_are_errors():
    frame = pd.DataFrame({"id": ["a", "b", "a"], "t": [1.0, 1.0, 1.0], "x": 0.0, "y": 0.0})
    with pytest.raises(ValueError, match=r"tracks: row 3, column 't': .* id 'a' seen twice"):
        tracks_to_lifecycle(frame)
    # the same time for different ids, and different times for one id, are fine
    ok = pd.DataFrame({"id": ["a", "b", "a"], "t": [1.0, 1.0, 2.0], "x": 0.0, "y": 0.0})
    assert len(tracks_to_lifecycle(ok, window=(0.0, 5.0))) == 2


def test_a_time_past_the_limit_is_refused_naming_the_row(tmp_path):
    """t = 1e308 (a finite number) made a step sum overflow inside the conversion."""
    from are_stats.logs import read_tracks

    p = tmp_path / "tr.csv"
    p.write_text("id,t,x,y\na,1e308,1,2\na,0.5,1,2\nb,1,0,0\n")
    with pytest.raises(ValueError, match=r"tr\.csv.*row.*t.*within \+-1e\+12 s"):
        read_tracks(p)
