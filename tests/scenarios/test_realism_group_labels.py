"""The realism's group spacing reads each kind of label as before (issue 29: a label's text
is now read once per distinct text or integer label): pairs walking abreast at known
spacings, labelled in every way a log or a scene labels them."""

import numpy as np
import pandas as pd

from are_stats.scenarios import realism_features

#: (label of both members, their spacing in m or None: they walk alone)
PAIRS = [
    ("g1", 0.30),
    (7, 0.40),
    (np.int64(8), 0.50),
    (True, 0.60),
    (0.0, 0.70),
    (-0.0, 0.80),  # -0.0 == 0.0, but its text is "-0.0": a group of its own
    (-1, None),
    ("", None),
    ("nan", None),
    (None, None),
    (float("-inf"), None),
]


def test_group_spacing_reads_every_kind_of_label():
    rows, groups = [], {}
    t = np.round(np.arange(0.0, 4.0, 0.4), 6)
    for k, (label, gap) in enumerate(PAIRS):
        for m in range(2):
            ident = f"p{k}_{m}"
            groups[ident] = label
            y = 3.0 * k + (gap or 2.0) * m
            rows += [(ident, tt, 1.0 * tt, y) for tt in t]
    tracks = pd.DataFrame(rows, columns=["id", "t", "x", "y"])
    spacing = realism_features(tracks, 0.4, None, groups=groups)["group spacing (m)"]
    walking = len(t) - 1  # the first sample has no velocity's step before it
    want = np.repeat([g for _, g in PAIRS if g is not None], 2 * walking)
    assert spacing.size == want.size
    np.testing.assert_allclose(np.sort(spacing), np.sort(want), rtol=0, atol=1e-9)
