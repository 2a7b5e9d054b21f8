"""group_spacing against a brute-force reference: every member's nearest co-member, frame by
frame (issue 29: the frames are now one k-d tree; the values must be the same bits)."""

import numpy as np
import pandas as pd

from are_stats.behaviour import formation, group_spacing


def _reference(tracks, groups, min_speed=0.2):
    """Per (scenario, group, time) of walking members, the nearest other member's
    distance, by all pairs (the plane's ``sqrt(dx^2 + dy^2)``, as a k-d tree computes it)."""
    keys = ["scenario", "id"] if "scenario" in tracks.columns else ["id"]
    tab = tracks.sort_values([*keys, "t"], kind="stable").reset_index(drop=True)
    vals = []
    frames: dict[tuple, list[int]] = {}
    # the columns as arrays, row r of each read as tab.loc[r, ...] read it (a .loc per
    # value was most of the test's 4 s)
    who = list(zip(*(tab[c].tolist() for c in keys), strict=True))
    t = tab["t"].to_numpy(float)
    xy = tab[["x", "y"]].to_numpy(float)
    for r in range(len(tab)):
        k = who[r]
        lab = groups.get(k if len(k) > 1 else k[0])
        if lab is None or str(lab) in ("", "nan", "None"):
            continue
        if r == 0 or who[r - 1] != k:
            continue  # no step into the first sample
        dt = t[r] - t[r - 1]
        dx, dy = xy[r] - xy[r - 1]
        step = np.hypot(dx, dy)
        if not (dt > 0 and step / dt >= min_speed):
            continue
        s = k[0] if "scenario" in tab.columns else 0
        frames.setdefault((s, str(lab), round(float(t[r]), 6)), []).append(r)
    for rows in frames.values():
        if len(rows) < 2:
            continue
        p = xy[rows]
        d = p[:, None, :] - p[None, :, :]
        dist = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1])
        np.fill_diagonal(dist, np.inf)
        vals.extend(dist.min(axis=1))
    return (float(np.median(vals)), len(vals)) if vals else (float("nan"), 0)


def _crowd(seed, scenarios):
    """Groups of 1-4 walking side by side (some standing, a few duplicated points), in
    ``scenarios`` scenes that reuse the same ids and labels."""
    rng = np.random.default_rng(seed)
    rows, groups = [], {}
    for s in range(scenarios):
        for g in range(12):
            size = int(rng.integers(1, 5))
            t0 = float(rng.integers(0, 5))
            speed = rng.uniform(0.0, 1.5)
            for m in range(size):
                i = f"p{g}_{m}"
                label = [f"g{g}", g, "", None][int(rng.integers(0, 4))] if m == 0 else f"g{g}"
                groups[(s, i) if scenarios > 1 else i] = label if size > 1 else None
                for k in range(int(rng.integers(3, 9))):
                    x = speed * k * 0.4 + rng.normal(0, 0.02)
                    y = 0.5 * m + (0.0 if m == 3 else rng.normal(0, 0.05))
                    rows.append((s, i, round(t0 + 0.4 * k, 1), x, y))
    tab = pd.DataFrame(rows, columns=["scenario", "id", "t", "x", "y"])
    return (tab if scenarios > 1 else tab.drop(columns="scenario")), groups


def test_group_spacing_is_the_brute_force_nearest_co_member_bit_for_bit():
    for seed, scenarios in ((0, 1), (1, 1), (2, 3), (3, 4)):
        tracks, groups = _crowd(seed, scenarios)
        got = group_spacing(tracks.sample(frac=1.0, random_state=seed), groups)
        want = _reference(tracks, groups)
        assert got[1] == want[1] > 10, (seed, got, want)
        assert got[0] == want[0], (seed, got, want)  # the same bits, not only close


def test_group_spacing_without_two_walking_members_at_a_time_is_nan():
    tracks = pd.DataFrame(
        {"id": ["a"] * 3 + ["b"] * 3, "t": [0, 1, 2, 5, 6, 7.0], "x": [0, 1, 2] * 2, "y": 0.0}
    )
    spacing, samples = group_spacing(tracks, {"a": "g", "b": "g"})
    assert np.isnan(spacing) and samples == 0
    assert np.isnan(group_spacing(tracks, {})[0])


def _formation_reference(scenario, group, t):
    """The leader and slot of each artefact by a loop over the groups (first to arrive
    leads, ties in order)."""
    n = len(t)
    leader, slot = np.arange(n), np.zeros(n, np.int64)
    members: dict[tuple, list[int]] = {}
    for i in sorted(range(n), key=lambda i: (t[i], i)):
        g = group[i]
        if g is None or (isinstance(g, float) and not g >= 0) or str(g) in ("", "nan", "None"):
            continue
        if isinstance(g, int | float) and g < 0:
            continue
        members.setdefault((scenario[i], str(g)), []).append(i)
    for idx in members.values():
        leader[idx] = idx[0]
        slot[idx] = np.arange(len(idx))
    return leader, slot


def test_formation_leaders_and_slots_are_those_of_a_loop_over_the_groups():
    rng = np.random.default_rng(5)
    n = 400
    scenario = rng.integers(0, 4, n)
    choices = ["a", "b", 3, 7, -1, "", None, float("nan"), "c"]
    group = [choices[k] for k in rng.integers(0, len(choices), n)]
    t = np.round(rng.uniform(0, 20, n), 0)  # ties in arrival
    leader, slot = formation(scenario, np.asarray(group, dtype=object), t)
    want_leader, want_slot = _formation_reference(scenario, group, t)
    assert np.array_equal(leader, want_leader) and np.array_equal(slot, want_slot)
    assert slot.max() >= 5 and (leader != np.arange(n)).sum() > 100
