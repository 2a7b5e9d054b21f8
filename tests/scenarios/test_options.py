"""The assembly's one options record (AssemblyOptions): its keywords, its command-line
checks, and that the record and the keywords draw the same scenes and manifest."""

from __future__ import annotations

import dataclasses
import typing

import numpy as np
import pandas as pd
import pytest

from are_stats.environment import OccupancyGrid, load_catalogue
from are_stats.fitting import Fit
from are_stats.inputs import InputError
from are_stats.scenarios import (
    AssemblyOptions,
    AssemblySettings,
    generate_manifest,
    scenes_from_fit,
    scenes_tables,
)

RATES = Fit.from_draws(
    {
        "arrival_rate": np.array([0.002]),
        "leave_rate": np.array([1 / 30]),
        "mix_weights": np.array([[0.5, 0.5]]),
        "mix_rates": np.array([[1.0, 3.0]]),
    }
)


def test_the_keywords_are_the_records_fields():
    """AssemblySettings (the keywords' types) names every field of the record, typed alike."""
    names = {"SocialForce": object}  # imported for type checkers only
    want = typing.get_type_hints(AssemblyOptions, localns=names)
    assert typing.get_type_hints(AssemblySettings, localns=names) == want
    assert list(want) == [f.name for f in dataclasses.fields(AssemblyOptions)]


def test_settings_replace_fields_and_unknown_ones_are_refused():
    base = AssemblyOptions(behaviours=True, behaviour_cell=0.5)
    assert base.with_settings({}) is base
    got = base.with_settings({"behaviour_dt": 1.0, "start": "empty"})
    assert got == AssemblyOptions(behaviours=True, behaviour_cell=0.5, behaviour_dt=1.0,
                                  start="empty")  # fmt: skip
    with pytest.raises(dataclasses.FrozenInstanceError):
        got.behaviours = False  # type: ignore[misc]
    with pytest.raises(TypeError, match="'behaviour_cel'"):
        base.with_settings({"behaviour_cel": 1.0})


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((False, "papers", "chosen", 1.0, 2.0), r"^--model: expected one of"),
        ((False, "chosen", "learned", 1.0, 2.0), r"^--positions: expected one of"),
        ((True, "chosen", "chosen", 0.0, 2.0), r"^--behaviour-cell: expected a finite number"),
        ((True, "chosen", "chosen", 1.0, float("inf")), r"^--behaviour-dt: expected a finite"),
    ],
)
def test_the_command_options_are_checked_by_their_names(args, match):
    with pytest.raises(InputError, match=match):
        AssemblyOptions.from_command(*args)


def test_the_command_options_without_behaviours_leave_the_cells_unchecked():
    got = AssemblyOptions.from_command(False, "paper", "uniform", -1.0, 0)
    assert got == AssemblyOptions(model="paper", positions="uniform", behaviour_cell=-1.0,
                                  behaviour_dt=0, cell_source="--behaviour-cell")  # fmt: skip
    moved = AssemblyOptions.from_command(True, "chosen", "chosen", 1, 3)
    assert (moved.behaviour_cell, moved.behaviour_dt) == (1.0, 3.0)
    assert type(moved.behaviour_cell) is float and type(moved.behaviour_dt) is float


def test_the_record_and_the_keywords_draw_the_same_moving_scenes():
    """One record, or its fields as keywords, or a record with a keyword over it: the same
    scenes and tracks (catalogue behaviours on a small open room)."""
    grid = OccupancyGrid(np.zeros((24, 24)), 0.5)
    catalogue = load_catalogue()
    kw = {"behaviours": "catalogue", "behaviour_cell": 1.0, "behaviour_dt": 2.0,
          "interaction": False, "start": "empty"}  # fmt: skip
    by_words = scenes_from_fit(5, RATES, grid, catalogue, 2, 40.0, **kw)
    by_record = scenes_from_fit(5, RATES, grid, catalogue, 2, 40.0, AssemblyOptions(**kw))
    over = AssemblyOptions(**{**kw, "behaviours": False})
    overridden = scenes_from_fit(5, RATES, grid, catalogue, 2, 40.0, over, behaviours="catalogue")
    art, tracks = scenes_tables(by_words)
    assert len(art) and len(tracks)  # something moved
    for other in (by_record, overridden):
        got_art, got_tracks = scenes_tables(other)
        pd.testing.assert_frame_equal(got_art, art)
        pd.testing.assert_frame_equal(got_tracks, tracks)
    standing = scenes_from_fit(5, RATES, grid, catalogue, 2, 40.0, over)
    assert not any(s.has_tracks.any() for s in standing)


def test_the_manifest_records_the_record():
    from types import SimpleNamespace

    df = pd.DataFrame({"scenario": [0], "artefact": [0]})
    tracks = pd.DataFrame({"scenario": [0, 0], "id": [0, 0], "t": [0.0, 2.0]})
    grid = OccupancyGrid(np.zeros((40, 40)), 0.1)
    fit = SimpleNamespace(class_labels=None, behaviour=None)
    where = {"fit_file": "f.nc", "map_file": "m.yaml", "seed": 3}
    options = AssemblyOptions.from_command(True, "paper", "uniform", 0.5, 1.5)
    manifest, kept = generate_manifest(df, tracks, fit, grid, options, **where)
    by_words, _ = generate_manifest(
        df, tracks, fit, grid, **where, behaviours=True, model="paper", positions="uniform",
        behaviour_cell=0.5, behaviour_dt=1.5, cell_source="--behaviour-cell",
    )  # fmt: skip
    assert manifest == by_words and kept is tracks
    assert manifest["model"] == "paper" and manifest["generation"]["positions"] == "uniform"
    assert manifest["tracks"] == {"source": "catalogue behaviour", "cell_m": 0.5, "dt_s": 1.5,
                                  "rows": 2}  # fmt: skip
