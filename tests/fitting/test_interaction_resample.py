"""The interaction learner's tracks on one step (issue 29: one table built from arrays, not
one per track) against a table per track made with np.interp, as it was made before."""

import numpy as np
import pandas as pd
import pytest

from are_stats.fitting._interaction import _on_one_step


def _reference(tracks, labels):
    tab = tracks.sort_values(["id", "t"], kind="stable")
    ids, t = tab["id"].to_numpy(), tab["t"].to_numpy(float)
    dt = float(np.median(np.diff(t)[ids[1:] == ids[:-1]]))
    parts = []
    for i, g in tab.groupby("id", sort=False, observed=True):
        tt = g["t"].to_numpy(float)
        grid_t = np.arange(np.ceil(tt[0] / dt - 1e-9), np.floor(tt[-1] / dt + 1e-9) + 1) * dt
        if grid_t.size >= 3:
            x = np.interp(grid_t, tt, g["x"].to_numpy(float))
            y = np.interp(grid_t, tt, g["y"].to_numpy(float))
            parts.append(pd.DataFrame({"id": i, "t": grid_t, "x": x, "y": y}))
    groups = {i: labels[str(i)] for i in pd.unique(ids) if str(i) in labels}
    return pd.concat(parts, ignore_index=True), groups


def _tracks(seed):
    """Tracks of irregular periods (jittered 0.4 s), some too short for three steps."""
    rng = np.random.default_rng(seed)
    rows = []
    for k in range(40):
        n = int(rng.integers(1, 30))
        t = np.round(rng.uniform(0, 100) + np.cumsum(rng.uniform(0.3, 0.5, n)), 2)
        rows += [(f"p{k}", a, rng.normal(), rng.normal()) for a in t]
    return pd.DataFrame(rows, columns=["id", "t", "x", "y"]).sample(frac=1.0, random_state=seed)


@pytest.mark.parametrize("ids", ["str", "int", "category"])
def test_tracks_on_one_step_are_the_per_track_interpolation(ids):
    tracks = _tracks(3)
    if ids == "int":
        tracks = tracks.assign(id=tracks["id"].str[1:].astype(int))
    elif ids == "category":
        tracks = tracks.assign(id=tracks["id"].astype("category"))
    labels = {str(i): f"g{k % 5}" for k, i in enumerate(pd.unique(tracks["id"])) if k % 3}
    got, groups = _on_one_step(tracks, labels)
    want, want_groups = _reference(tracks, labels)
    assert len(got) > 100
    pd.testing.assert_frame_equal(got, want, check_exact=True)  # values and dtypes
    assert groups == want_groups


def test_tracks_too_short_for_three_steps_are_refused():
    tracks = pd.DataFrame(
        {"id": ["a", "a", "b", "b"], "t": [0.0, 0.4, 0.0, 0.4], "x": 0.0, "y": 0.0}
    )
    with pytest.raises(ValueError, match="at least three samples"):
        _on_one_step(tracks, {})
