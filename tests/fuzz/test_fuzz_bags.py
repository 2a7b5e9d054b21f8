"""Fuzz the bag door of ``are-stats augment`` (issue 30) with robot bags built by rosbags.

Each case starts from the valid test bag of :mod:`tests.export.rosbag_fixtures` (ROS 1,
ROS 2 sqlite3 or MCAP; poses from ``/tf`` or ``/amcl_pose``) and applies one edit: a
quaternion scaled or made NaN, a position made NaN or infinite, one stamp in 1970 (on the
header clock, or on both clocks), header stamps on a simulation clock, a special file where
the bag belongs, or an extreme ``--period``. Every case ends in one of four outcomes, and
the test fails on the last two and on any hang or memory error (:func:`bounded`):

* clean error: exit 2, the bag or the option named on stderr;
* accepted valid: exit 0, an MCAP whose camera frames hold live artefacts;
* traceback (an uncaught exception, exit 1);
* silent: garbage accepted (exit 0 on a case that is not a valid bag), or a valid bag
  refused.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest
from hypothesis import strategies as st

from tests.export.rosbag_fixtures import (
    ODD_K,
    SIM_START,
    START,
    robot_pose,
    write_bag,
)
from tests.fuzz.strategies import fuzz_tiers
from tests.fuzz.test_fuzz_cli import invoke

pytestmark = pytest.mark.fuzz

#: tf2's tolerance on ``| |q|^2 - 1 |`` (:data:`are_stats.logs.QUATERNION_TOLERANCE`).
TOL = 1e-2


@pytest.fixture(scope="session")
def busy_fit(fuzz_root: Path) -> Path:
    """An EM fit of busy traffic (about 15 artefacts alive at once): a 12 s bag meets some."""
    from are_stats._cli_jobs import run_fit
    from tests.test_cli_jobs import _write_log

    d = fuzz_root / "busy"
    d.mkdir()
    log, _ = _write_log(d, labels=True)
    out = d / "busy.nc"
    run_fit(log, out, method="em", seed=3, figures=None, arrivals="poisson",
            lifetimes="exponential", positions="uniform", samples=20)  # fmt: skip
    return out


def _mutation():
    scale = st.one_of(
        st.floats(0.0, 3.0),
        st.floats(1.0 - 0.004, 1.0 + 0.004),  # inside tf2's tolerance: valid
    )
    return st.one_of(
        st.tuples(st.just("none"), st.none()),
        st.tuples(st.just("scale_quat"), scale),
        st.tuples(st.just("nan_quat"), st.sampled_from([0, 1, 2, 3])),
        st.tuples(st.just("bad_pos"), st.sampled_from([math.nan, math.inf, -math.inf])),
        st.tuples(st.just("outlier"), st.booleans()),  # True: recorded in 1970 too
        st.tuples(st.just("sim_clock"), st.sampled_from([SIM_START, START + 86400.0, 3.0])),
        st.tuples(st.just("special"), st.sampled_from(["fifo", "dev_zero", "folder"])),
        st.tuples(st.just("period"), st.sampled_from([1e-9, 1e-4, 2.0])),
    )


def _bag(d: Path, kind: str, source: str, mutation: tuple) -> tuple[Path, bool]:
    """The case's bag and whether it is a valid one."""
    what, arg = mutation
    which: dict = {"poses": False} if source == "tf" else {"tf": False}
    x, y, yaw = robot_pose(ODD_K / 10)
    q = [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]
    valid = True
    if what == "special":
        p = d / ("b.bag" if arg != "folder" else "f.mcap")
        if arg == "fifo":
            os.mkfifo(p)
        elif arg == "dev_zero":
            p.symlink_to("/dev/zero")
        else:
            p.mkdir()
        return p, False
    if what == "scale_quat":
        which["bad"] = (x, y, tuple(arg * v for v in q))
        valid = abs(arg * arg - 1.0) < TOL * 0.99
    elif what == "nan_quat":
        q[arg] = math.nan
        which["bad"] = (x, y, tuple(q))
        valid = False
    elif what == "bad_pos":
        which["bad"] = (arg, y, tuple(q))
        valid = False
    elif what == "outlier":
        which["outlier"] = True
        which["outlier_log"] = arg
        valid = False
    elif what == "sim_clock":
        which["header_start"] = arg
    path = d / ("bag.bag" if kind == "ros1" else "bag")
    return write_bag(path, kind, **which), valid


@fuzz_tiers(
    16,
    kind=st.sampled_from(["ros1", "ros2", "mcap"]),
    source=st.sampled_from(["tf", "pose"]),
    mutation=_mutation(),
)
def test_augment_bag_door(kind, source, mutation, busy_fit, case_dir) -> None:
    """Clean error or live artefacts; garbage never accepted, valid bags never refused."""
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    d = case_dir()
    bag, valid = _bag(d, kind, source, mutation)
    out = d / "out.mcap"
    args = ["augment", str(bag), "--fit", str(busy_fit), "--map", "courtyard", "--out",
            str(out), "--seed", "5"]  # fmt: skip
    args += ["--pose-topic", "/amcl_pose"] if source == "pose" else []
    names = [str(bag)]
    if mutation[0] == "period":
        args += ["--period", str(mutation[1])]
        names.append("--period")
        valid = mutation[1] >= 1.0  # a frame every 1e-4 s is past the fuzz limits
    else:
        args += ["--camera-info-topic", "/camera/camera_info"]
    code = invoke(args, names, seconds=60.0)
    assert code == (0 if valid else 2), f"{mutation}: exit {code} (valid: {valid})"
    if code == 0:  # accepted: every camera frame holds live artefacts
        ts = get_typestore(Stores.ROS2_HUMBLE)
        with open(out, "rb") as fh:
            docs = [
                json.loads(ts.deserialize_cdr(m.data, s.name).data)
                for s, _, m in make_reader(fh).iter_messages(topics=["/perceived"])
            ]
        assert docs and any(doc["live"] for doc in docs), f"{mutation}: no live artefact"
    else:
        assert not out.exists()
