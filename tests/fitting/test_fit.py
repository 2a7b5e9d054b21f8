"""The typed fit: fit_log takes one field log and returns the whole fit; read_fit gives the
same Fit back from the file; the CLI only writes it (issue 25)."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from are_stats import _cli_jobs as cli_jobs
from are_stats._stage_clock import StageClock
from are_stats.behaviour import SocialForce
from are_stats.cli import app
from are_stats.fitting import (
    Fit,
    FitSettings,
    as_fit,
    fit_log,
    interaction_attrs,
    read_fit,
    traffic_draws,
    write_fit,
)
from are_stats.inputs import InputError
from are_stats.logs import read_field_log, read_field_tracks
from tests.test_cli_tracks import _room, _tracks

EM = FitSettings(method="em", arrivals="poisson", lifetimes="exponential", positions="uniform")


@pytest.fixture(scope="module")
def tracks_log(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tracks")
    _room(folder)
    return _tracks(folder, horizon=120.0)  # 19 people: every stage runs, at half the cost


@pytest.fixture(scope="module")
def fitted(tracks_log):
    return fit_log(5, read_field_log(tracks_log), EM)


def test_field_log_keeps_its_tracks(tracks_log):
    """The tracks are read with the log: no second reading for the behaviour."""
    log = read_field_log(tracks_log)
    again = read_field_tracks(tracks_log)
    assert log.tracks is not None
    assert log.tracks.equals(again)


def test_fit_log_returns_the_whole_fit(fitted, tracks_log):
    fit = fitted
    assert isinstance(fit, Fit)
    assert fit.behaviour is not None  # a fit from tracks always carries a behaviour
    assert fit.grid is not None and fit.grid.free.shape == (100, 200)  # the manifest's map
    assert {"realism", "displacement"} <= set(fit.motion)
    assert fit.provenance["log"] == tracks_log.name
    assert fit.provenance["seed"] == "5"
    assert len(fit.provenance["log_sha256"]) == 64
    assert fit.log_report["rows_used"] > 0
    assert fit.laws.arrivals == "poisson" and fit.area == pytest.approx(
        fit.idata.posterior.attrs["area"]
    )
    assert fit.method == "em"


def test_read_fit_gives_the_same_fit_back(fitted, tmp_path):
    path = write_fit(fitted, tmp_path / "f.nc")
    back = read_fit(path)
    assert isinstance(back, Fit) and back.source == str(path)
    assert back.grid is None  # the map stays with the log
    for name in (
        "method",
        "area",
        "window",
        "n_components",
        "class_labels",
        "laws",
        "interaction",
        "notes",
        "class_stay_model",
        "time_resolution",
        "posterior_sources",
    ):
        assert getattr(back, name) == getattr(fitted, name), name
    assert back.format_version == 1
    assert dict(back.provenance) == dict(fitted.provenance)
    np.testing.assert_array_equal(back.behaviour.beta, fitted.behaviour.beta)
    np.testing.assert_array_equal(back.behaviour.free, fitted.behaviour.free)
    for name, table in fitted.motion.items():
        pd.testing.assert_frame_equal(back.motion[name], table)
    d0, laws0 = traffic_draws(fitted)
    d1, laws1 = back.traffic("chosen")
    assert laws0 == laws1 and d0.keys() == d1.keys()
    for k in d0:
        np.testing.assert_array_equal(d0[k], d1[k])
    assert as_fit(back) is back
    assert as_fit(path).provenance == back.provenance


@pytest.fixture(scope="module")
def command(tracks_log, tmp_path_factory):
    """``are-stats fit`` of the log with ``fitted``'s seed and settings: its output, the
    file it wrote and what its stage clock was told (a :class:`StageClock` that records
    the stages and steps and then does what it does). The second and last tracks fit of
    this file: it is the fit with a clock of the stage test too."""
    calls = []

    class Recording(StageClock):
        def __call__(self, stage):
            calls.append(stage)
            super().__call__(stage)

        def steps(self, done, total, what=""):
            calls.append((done, total, what))
            super().steps(done, total, what)

    out = tmp_path_factory.mktemp("cli") / "cli.nc"
    args = [
        "fit",
        str(tracks_log),
        "--out",
        str(out),
        "--method",
        "em",
        "--seed",
        "5",
        "--arrivals",
        "poisson",
        "--lifetimes",
        "exponential",
        "--positions",
        "uniform",
        "--no-figures",
    ]
    with pytest.MonkeyPatch.context() as m:
        m.setattr(cli_jobs, "StageClock", Recording)
        res = CliRunner().invoke(app, args)
    return res, out, calls


def test_the_command_only_writes_fit_log(fitted, command, tmp_path):
    """``are-stats fit`` writes what fit_log returns for the same seed: the same bytes."""
    res, out, _ = command
    assert res.exit_code == 0, res.output
    mine = write_fit(fitted, tmp_path / "api.nc")
    assert out.read_bytes() == mine.read_bytes()
    # how each posterior was drawn is read from the Fit, not from the file's attributes
    a = fitted.idata.posterior.attrs
    assert dict(fitted.posterior_sources) == {
        who: a[key]
        for who, key in (
            ("the paper's model", "paper_posterior"),
            ("arrivals", "traffic_arrival_posterior"),
            ("stays", "traffic_lifetime_posterior"),
        )
        if a.get(key)
    }
    assert fitted.posterior_sources, "an EM fit records how its posteriors were drawn"
    line = "; ".join(f"{k}: {v}" for k, v in fitted.posterior_sources.items())
    assert f"posteriors: {line}" in " ".join(res.output.split())


@pytest.mark.slow  # a second tracks fit on new grid shapes (68 s of CPU cold); make test:
# tests/behaviour/test_fit_without_map.py's open-area grid
def test_no_map_fits_the_open_area_with_a_note(tracks_log, tmp_path):
    log = tmp_path / "nomap.csv"
    shutil.copy(tracks_log, log)
    meta = yaml.safe_load(tracks_log.with_suffix(".yaml").read_text())
    del meta["map"]
    meta["area"] = 200.0
    log.with_suffix(".yaml").write_text(yaml.safe_dump(meta))
    fit = fit_log(5, read_field_log(log), EM)
    assert fit.behaviour is not None
    assert any("open area the tracks cover" in n for n in fit.notes)
    back = read_fit(write_fit(fit, tmp_path / "nomap.nc"))
    assert back.notes == fit.notes  # the note travels with the fit


def test_a_damaged_behaviour_group_is_named(fitted, tmp_path):
    idata = fitted.idata.copy()
    idata.behaviour = idata.behaviour.drop_vars("free")  # the MDP grid the behaviour needs
    path = write_fit(idata, tmp_path / "bad.nc")
    with pytest.raises(InputError, match=r"bad\.nc.*behaviour"):
        read_fit(path)


def test_a_fit_without_repulsion_reads_back_with_strength_0(fitted, tmp_path):
    """A log that shows no repulsion is stored with strength 0 (learn_interaction) and
    read back so, not refused as a non-positive parameter."""
    idata = fitted.idata.copy()
    idata.behaviour.attrs.update(
        interaction_attrs(SocialForce(strength=0.0, group_spacing=0.3), {"group_samples": 9.0})
    )
    back = read_fit(write_fit(idata, tmp_path / "none.nc"))
    assert back.interaction == SocialForce(strength=0.0, group_spacing=0.3)


def test_fit_is_frozen(fitted):
    with pytest.raises(dataclasses.FrozenInstanceError):
        fitted.area = 1.0  # type: ignore[misc]


def test_the_long_stages_tell_their_steps_to_the_clock(command, fitted):
    """A ``progress`` with a ``steps`` method (the CLI's stage clock) is told the steps of
    the behaviour (its classes) and of the motion criticism (the realism replicates, then
    the displacement errors, with their chunks of windows as a phase of their own, and the
    motion checks' routes and social force windows), each under its stage; the fit is the
    one without it (``fitted``: the command wrote its bytes, test above)."""
    res, out, calls = command
    assert res.exit_code == 0, res.output
    fit = read_fit(out)
    behaviour = calls.index("behaviour from the tracks (speeds, exits, rationality)")
    assert calls[behaviour + 1] == (1, 1, "classes")
    realism = calls.index("realism and displacement errors against the tracks")
    steps = calls[realism + 1 :]
    # the displacement errors' own phase: one step per chunk of windows predicted
    windows = [s for s in steps if s[2] == "displacement errors, windows"]
    chunks = len(windows)
    assert chunks >= 1 and [s[:2] for s in windows] == [(j, chunks) for j in range(1, chunks + 1)]
    steps = [s for s in steps if s not in windows]
    assert [s[:2] for s in steps[:3]] == [(1, 4), (2, 4), (3, 4)]
    assert steps[2][2] == "displacement errors"
    assert calls.index(windows[-1]) < calls.index(steps[2])
    # the motion checks' own steps (routes, social force windows) after the first three,
    # counted to the end
    checks = steps[3:]
    assert len(checks) > 2 and all(s[2].startswith("motion checks, ") for s in checks)
    assert [s[0] for s in checks] == sorted(s[0] for s in checks)
    assert checks[0][0] == 4 and checks[-1][0] == checks[-1][1], checks
    for name in ("realism", "displacement"):
        pd.testing.assert_frame_equal(fit.motion[name], fitted.motion[name])


def test_hand_set_draws_are_a_fit_that_gives_them_back():
    """Fit.from_draws holds hand-set rates as a posterior of one chain: traffic() returns
    them bit for bit (values, dtypes, shapes) with the laws given, else the paper's."""
    from are_stats.traffic import TrafficLaws

    draws = {
        "arrival_rate": np.array([3e-4, 1e-4]), "leave_rate": np.array([1 / 60, 0.1]),
        "mix_weights": np.array([[1.0, 0.0], [0.25, 0.75]]),
        "mix_rates": np.array([[15.0, 7.0], [3.0, 21.0]]),
        "group_size_probs": np.array([[0.0, 1.0], [0.5, 0.5]]),
    }  # fmt: skip
    laws = TrafficLaws(arrivals="groups")
    fit = Fit.from_draws(draws, laws=laws, class_labels=["person", "cart"], area=50.0)
    got, got_laws = fit.traffic()
    assert got_laws == laws and fit.area == 50.0 and fit.n_components == 2
    assert fit.class_labels == ("person", "cart") and fit.behaviour is None
    assert sorted(got) == sorted(draws)
    for name, want in draws.items():
        assert got[name].dtype == want.dtype and got[name].shape == want.shape
        np.testing.assert_array_equal(got[name], want)
    paper, paper_laws = fit.traffic("paper")
    assert paper_laws.is_paper and "group_size_probs" not in paper
    assert Fit.from_draws(draws).laws.is_paper
    one = Fit.from_draws({"arrival_rate": 2e-3, "leave_rate": 0.05, "class_stay_mean": [9.0]})
    got = one.traffic()[0]
    assert got["arrival_rate"].tolist() == [2e-3] and got["class_stay_mean"].tolist() == [[9.0]]
    assert one.class_stay_model == "per-class"  # the per-class stays are used, not dropped


@pytest.mark.parametrize(
    ("draws", "match"),
    [
        ({"leave_rate": [0.1]}, "rates: expected a variable 'arrival_rate'"),
        ({"arrival_rate": [1.0], "leave_rate": [0.1], "arival": [1.0]}, r"unknown \['arival'\]"),
    ],
)
def test_hand_set_draws_name_what_is_missing_or_unknown(draws, match):
    with pytest.raises(ValueError, match=match):
        Fit.from_draws(draws, source="rates")


def test_a_part_run_beside_another_tells_its_steps_in_order():
    """``_Relay`` (the criticism's threads): steps told before ``go_live`` are held and told
    then, in order; later ones pass straight on; a step told while the held ones are being
    told (here by the clock itself, as another thread could) comes after them, not between
    them."""
    from are_stats.fitting._field_fit import _Relay

    told = []

    def say(done, total, what):
        told.append((done, total, what))
        if what == "held" and done == 0:  # a step arrives while the held ones are told
            relay(9, 9, "meanwhile")

    relay = _Relay(say)
    for j in range(3):
        relay(j, 3, "held")
    assert told == []
    relay.go_live()
    relay(3, 3, "live")
    assert told == [(0, 3, "held"), (1, 3, "held"), (2, 3, "held"), (9, 9, "meanwhile"),
                    (3, 3, "live")]  # fmt: skip
