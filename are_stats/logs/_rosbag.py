"""Tracks from ROS 1 bags, ROS 2 bags and MCAP files, read with ``rosbags`` (no ROS install).

Two kinds of topics become sightings (rows ``id, t, x, y, yaw, label``) that
:func:`tracks_to_lifecycle` turns into a life-cycle log:

* ``visualization_msgs/MarkerArray`` (and single ``visualization_msgs/Marker``): one sighting
  per ADD/MODIFY marker, track id ``"<ns>/<id>"``. DELETE ends the marker's track and
  DELETEALL ends every track of its namespace (every track of the topic when the namespace
  is empty); a marker id re-used after a deletion starts a new artefact ``"<ns>/<id>@2"``,
  ``@3``, ... The deletion itself is not a sighting.
* ``vision_msgs/Detection3DArray`` (vision_msgs 4, ROS 2; its definitions are registered
  from the ``.msg`` texts below, so no ROS install is needed): one sighting per detection,
  track id the detection's ``id`` field when not empty, else
  ``"<class_id of results[0]>/<index in the array>"``; position and yaw from
  ``bbox.center``; label ``results[0].hypothesis.class_id``.

Times are the message header stamps in seconds (the bag's receive time when the stamp is
zero); a stamp far from the rest of its topic's (:func:`check_stamps`) is refused, as are
non-finite positions and orientations that are not unit quaternions (an all-zero
orientation reads as the identity, as RViz reads it). Positions published in another
frame than the map frame are transformed into it through the bag's ``/tf`` and
``/tf_static`` (:class:`~are_stats.logs.TfBuffer`, at each sighting's stamp; the yaw turns
with the frame) and their ``frame_id`` becomes the map frame; in a bag without ``/tf`` they
are taken as published. The ``frame_id`` column says which frame the positions are in.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
import re
import sqlite3
import struct
from collections.abc import Callable, Iterator, Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, TypeVar  # Any: duck-typed ROS messages

import numpy as np
import numpy.typing as npt
import pandas as pd
import yaml

from are_stats.inputs import Described, InputError, Source, get_str
from are_stats.logs._bag_reader import bag_reader
from are_stats.logs._tf import TF_TYPES, TfBuffer, unit_quaternion

if TYPE_CHECKING:
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import Connection
    from rosbags.interfaces.typing import Typesdict
    from rosbags.typesys.store import Typestore

__all__ = [
    "BAG_SUFFIXES",
    "DETECTION3D_MSGS",
    "OUTLIER_SHARE",
    "STAMP_GAP",
    "SUPPORTED_TRACK_TYPES",
    "PassChannel",
    "PassThrough",
    "bag_messages",
    "bag_passthrough",
    "bag_read_errors",
    "check_bag_path",
    "check_stamps",
    "is_bag_path",
    "read_tracks_bag",
    "vision_msgs_typestore",
]

#: ``.msg`` definitions of vision_msgs 4 (ROS 2) used for ``Detection3DArray``.
DETECTION3D_MSGS: dict[str, str] = {
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/ObjectHypothesisWithPose": (
        "vision_msgs/ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n"
    ),
    "vision_msgs/msg/BoundingBox3D": "geometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
    "vision_msgs/msg/Detection3D": (
        "std_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\n"
        "vision_msgs/BoundingBox3D bbox\nstring id\n"
    ),
    "vision_msgs/msg/Detection3DArray": (
        "std_msgs/Header header\nvision_msgs/Detection3D[] detections\n"
    ),
}

_MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
_MARKER = "visualization_msgs/msg/Marker"
_DET3D_ARRAY = "vision_msgs/msg/Detection3DArray"
#: Message types :func:`read_tracks_bag` understands.
SUPPORTED_TRACK_TYPES = (_MARKER_ARRAY, _MARKER, _DET3D_ARRAY)


def vision_msgs_typestore(ros_version: int = 2) -> Typestore:
    """A rosbags typestore (ROS 2 Humble or ROS 1 Noetic) with vision_msgs registered.

    Parameters
    ----------
    ros_version : int
        1 for ROS 1 Noetic types, 2 for ROS 2 Humble types.

    Returns
    -------
    rosbags.typesys.store.Typestore
        Use it to serialise messages (``typestore.serialize_cdr`` / ``serialize_ros1``) and
        to create ``Detection3DArray`` objects (``typestore.types[...]``).
    """
    # lazy: rosbags' type store adds 0.07 s CPU to `import are_stats.logs`
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    if ros_version not in (1, 2):
        raise ValueError(f"ros_version: expected 1 or 2, got {ros_version!r}")
    store = get_typestore(Stores.ROS1_NOETIC if ros_version == 1 else Stores.ROS2_HUMBLE)
    types: Typesdict = {}
    for name, text in DETECTION3D_MSGS.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def _stamp(header: Any, fallback_ns: int) -> float:
    st = header.stamp
    sec, nsec = int(st.sec), int(st.nanosec)
    if sec == 0 and nsec == 0:
        return fallback_ns * 1e-9
    return sec + nsec * 1e-9


def _yaw(q: Any, source: Source, where: str) -> float:
    """Yaw of a marker's or detection's orientation: a unit quaternion, or all zeros (an
    orientation left unset, which RViz draws as the identity)."""
    if float(q.x) == float(q.y) == float(q.z) == float(q.w) == 0.0:
        return 0.0
    x, y, z, w = unit_quaternion(q, source, f"{where}, orientation")
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class _MarkerState:
    """Per-topic marker generations: ids re-used after a deletion are new artefacts."""

    def __init__(self) -> None:
        self.gen: dict[tuple[str, int], int] = {}
        self.alive: set[tuple[str, int]] = set()

    def add(self, key: tuple[str, int]) -> str:
        if key not in self.alive:
            self.gen[key] = self.gen.get(key, 0) + 1
            self.alive.add(key)
        g = self.gen[key]
        base = f"{key[0]}/{key[1]}"
        return base if g == 1 else f"{base}@{g}"

    def delete(self, key: tuple[str, int]) -> None:
        self.alive.discard(key)

    def delete_all(self, ns: str) -> None:
        self.alive = {k for k in self.alive if ns and k[0] != ns}


def _markers(
    markers: Sequence[Any],
    state: _MarkerState,
    topic: str,
    ts: int,
    rows: list[tuple],
    source: Source = "",
    where: str = "",
) -> None:
    for j, m in enumerate(markers):
        action = int(m.action)
        key = (str(m.ns), int(m.id))
        if action == 0:  # ADD / MODIFY
            tid = state.add(key)
            p = m.pose.position
            rows.append(
                (
                    tid,
                    _stamp(m.header, ts),
                    float(p.x),
                    float(p.y),
                    _yaw(m.pose.orientation, source, f"{where}, marker {j}"),
                    str(m.ns),
                    topic,
                    str(m.header.frame_id),
                )
            )
        elif action == 2:  # DELETE
            state.delete(key)
        elif action == 3:  # DELETEALL
            state.delete_all(str(m.ns))


def _class_id(result: object) -> str:
    hyp = getattr(result, "hypothesis", None)
    if hyp is not None:
        return str(hyp.class_id)
    return str(getattr(result, "id", ""))


def _detections(
    msg: Any, topic: str, ts: int, rows: list[tuple], source: Source = "", where: str = ""
) -> None:
    t_arr = _stamp(msg.header, ts)
    for j, det in enumerate(msg.detections):
        label = _class_id(det.results[0]) if len(det.results) else ""
        did = str(getattr(det, "id", "") or "")
        tid = did if did else f"{label}/{j}"
        hdr = det.header
        t = t_arr if (int(hdr.stamp.sec) == 0 and int(hdr.stamp.nanosec) == 0) else _stamp(hdr, ts)
        c = det.bbox.center
        frame = str(hdr.frame_id) or str(msg.header.frame_id)
        rows.append(
            (
                tid,
                t,
                float(c.position.x),
                float(c.position.y),
                _yaw(c.orientation, source, f"{where}, detection {j}"),
                label,
                topic,
                frame,
            )
        )


def _bag_errors() -> tuple[type[BaseException], ...]:
    """What rosbags raises on a corrupt or truncated bag (its own errors, and the plain
    ones its parsers let through on damaged bytes)."""
    # lazy: rosbags' readers add 0.40 s CPU to `import are_stats.logs` (the five imports)
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Ros1ReaderError
    from rosbags.rosbag2 import ReaderError as Ros2ReaderError
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    extra: tuple[type[BaseException], ...] = ()
    try:  # optional: rosbags reads ROS 2 sqlite3 bags with apsw when it is installed
        import apsw

        extra = (apsw.Error,)
    except ImportError:  # pragma: no cover - depends on the environment
        pass
    return (
        *extra,
        # a damaged size field makes the parser ask for a huge read
        MemoryError,
        AnyReaderError,
        Ros1ReaderError,
        Ros2ReaderError,
        SerdeError,
        TypesysError,
        sqlite3.DatabaseError,
        struct.error,
        KeyError,
        IndexError,
        AssertionError,
        UnicodeDecodeError,
        OverflowError,
        EOFError,
    )


_T = TypeVar("_T")


def _records(
    it: Iterator[_T], p: Path, errors: tuple[type[BaseException], ...], kind: str
) -> Iterator[_T]:
    """The items of a bag reader's iterator ``it``; a damaged record is a ``ValueError``
    naming the file ``p`` and the number of messages read before it."""
    n = 0
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except errors as err:
            raise ValueError(
                f"{p}: record after message {n}: expected a readable {kind} record, got a "
                f"damaged one ({type(err).__name__}: {err})"
            ) from None
        n += 1
        yield item


def _messages(
    reader: AnyReader, conns: list[Connection], p: Path, errors: tuple[type[BaseException], ...]
) -> Iterator[tuple[Connection, int, Any]]:
    """``(connection, receive time ns, message)``; a damaged record or message is a
    ``ValueError`` naming the bag (and the topic and time when known)."""
    records = _records(reader.messages(connections=conns), p, errors, "bag")
    for n, (conn, ts, raw) in enumerate(records, 1):
        try:
            msg = reader.deserialize(raw, conn.msgtype)
        except errors as err:
            raise ValueError(
                f"{p}: topic {conn.topic!r}, message {n} (received at {ts * 1e-9:.9f} s): "
                f"expected a valid {conn.msgtype}, got undecodable bytes "
                f"({type(err).__name__}: {err})"
            ) from None
        yield conn, ts, msg


def _to_map_frame(df: pd.DataFrame, tf: TfBuffer, map_frame: str, p: Path) -> pd.DataFrame:
    """Sightings in other frames moved into ``map_frame`` through the bag's tf tree."""
    frames = df["frame_id"].astype(str).str.lstrip("/")
    df = df.assign(frame_id=frames)
    for frame in sorted(set(frames) - {"", map_frame}):
        rows = np.flatnonzero((frames == frame).to_numpy())
        try:
            m = tf.lookup(map_frame, frame, df["t"].to_numpy(float)[rows])
        except KeyError:
            raise ValueError(
                f"{p}: topic {df['topic'].iloc[rows[0]]!r}, frame {frame!r}: expected a /tf "
                f"chain {map_frame} -> ... -> {frame}, got frames "
                f"{', '.join(tf.frames) or 'none'}"
            ) from None
        xy = df[["x", "y"]].to_numpy(float)[rows]
        pts = np.einsum("nij,nj->ni", m[:, :3, :3], np.c_[xy, np.zeros(len(rows))]) + m[:, :3, 3]
        turn = np.arctan2(m[:, 1, 0], m[:, 0, 0])
        yaw = np.angle(np.exp(1j * (df["yaw"].to_numpy(float)[rows] + turn)))
        df.iloc[rows, df.columns.get_loc("x")] = pts[:, 0]
        df.iloc[rows, df.columns.get_loc("y")] = pts[:, 1]
        df.iloc[rows, df.columns.get_loc("yaw")] = yaw
        df.iloc[rows, df.columns.get_loc("frame_id")] = map_frame
    return df


def bag_read_errors() -> tuple[type[BaseException], ...]:
    """The exceptions rosbags raises on a corrupt or truncated bag (to catch around a
    reader and report as a ``ValueError`` naming the bag)."""
    return _bag_errors()


def bag_messages(
    reader: AnyReader, connections: list[Connection], path: str | os.PathLike
) -> Iterator[tuple[Connection, int, Any]]:
    """``(connection, receive time ns, message)`` of an open rosbags ``AnyReader``; a damaged
    record or message is a ``ValueError`` naming the bag (and the topic and time when
    known)."""
    return _messages(reader, connections, Path(path), _bag_errors())


#: Stamps of one topic further apart than this (s) are separate stretches of the recording.
STAMP_GAP = 3600.0
#: A stretch holding at most this share of a topic's stamps (and at least one), further
#: than :data:`STAMP_GAP` and than ten times the main stretch's length from it, is an
#: outlier (a stamp of another clock or a damaged one), not a part of the recording.
OUTLIER_SHARE = 0.01


def _iso(t: float) -> str:
    try:
        return _dt.datetime.fromtimestamp(float(t), _dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    except (OverflowError, OSError, ValueError):
        return "out of the calendar"


#: Suffixes of the bag files :func:`check_bag_path` takes.
BAG_SUFFIXES = (".bag", ".mcap", ".db3")


def is_bag_path(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a bag: a ``.bag``/``.mcap``/``.db3`` file name (existing or
    not) or a folder holding ``metadata.yaml`` (a ROS 2 bag)."""
    p = Path(path)
    return p.suffix.lower() in BAG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").exists())


def check_bag_path(path: str | os.PathLike) -> Path:
    """The bag's path, checked before a reader opens it: a regular file (ROS 1 ``.bag``,
    ``.mcap``, ``.db3``) or a ROS 2 bag folder (``metadata.yaml`` beside its storage files).

    A FIFO, a device or a socket would block a reader or never end; a folder without
    ``metadata.yaml`` is not a bag.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    are_stats.inputs.InputError
        If it is neither a regular file nor a ROS 2 bag folder of regular files.
    """
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such bag file or directory")
    expected = "a ROS 1 .bag, an .mcap / .db3 file or a ROS 2 bag folder (with metadata.yaml)"
    if p.is_dir():
        if not (p / "metadata.yaml").exists():
            raise InputError(p, "", expected, Described("a folder without metadata.yaml"))
        for f in sorted(p.iterdir()):
            if not f.is_dir() and not f.is_file():
                raise InputError(
                    p, f.name, "a regular file in the bag folder", Described("a special file")
                )
        return p
    if not p.is_file():
        raise InputError(
            p, "", f"{expected} in a regular file", Described("a FIFO, a device or a socket")
        )
    return p


def check_stamps(
    t: npt.ArrayLike,
    source: Source,
    what: str,
    index: npt.ArrayLike | None = None,
    *,
    gap: float = STAMP_GAP,
    item: str = "message",
    recorded: npt.ArrayLike | None = None,
) -> None:
    """Refuse a topic's stamps when a few lie far from the rest (a clear outlier).

    The sorted stamps split at gaps longer than ``gap``; the stretch with the most stamps is
    the recording. Another stretch of at most :data:`OUTLIER_SHARE` of the stamps (and at
    least one) further than ``max(gap, 10 x the recording's length)`` from it is refused,
    naming the message and its stamp: one pose stamped 1970 among 2026 ones would otherwise
    stretch the bag's span over 55 years. Larger stretches (a recording paused for hours)
    are kept.

    Parameters
    ----------
    t : (m,) float
        Stamps, s since the epoch, in message order.
    source : str or PathLike
        The bag, named in errors.
    what : str
        The topic (or tf link), named in errors.
    index : (m,) int, optional
        Message numbers (1-based) of the stamps within ``what``; default ``1 .. m``.
    gap : float
        Stamps further apart than this (s) are separate stretches.
    item : str
        What ``index`` counts, for messages (``"message"``, ``"sighting"``).
    recorded : (m,) float, optional
        Each message's recording time as seconds into the bag (after its first recording
        time): the error then places the message and the recording's stretch in the bag,
        as ``augment``'s errors give times, with the stamps' dates in brackets.

    Raises
    ------
    are_stats.inputs.InputError
        Naming the topic, the message, its stamp (and date) and the recording's stretch
        (and where they were recorded in the bag, with ``recorded``).

    Examples
    --------
    >>> t = [1782000000.0 + k for k in range(200)] + [5.25]
    >>> check_stamps(t, "b.bag", "topic /odom", recorded=[*range(200), 3.5])
    Traceback (most recent call last):
    are_stats.inputs.InputError: b.bag: topic /odom, message 201 (recorded 3.500 s into the
    bag), stamp 5.250000000 s (1970-01-01T00:00:05Z): expected stamps on the clock of the
    other 200 messages (recorded 0.000 to 199.000 s into the bag, stamped ...), got ...
    """
    t = np.asarray(t, float)
    if t.size < 2:
        return
    idx = np.arange(1, t.size + 1) if index is None else np.asarray(index)
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(source, f"{what}, {item} {int(idx[i])}", "a finite stamp", float(t[i]))
    order = np.argsort(t, kind="stable")
    ts = t[order]
    cuts = np.flatnonzero(np.diff(ts) > gap) + 1
    if cuts.size == 0:
        return
    bounds = np.r_[0, cuts, ts.size]
    sizes = np.diff(bounds)
    main = int(np.argmax(sizes))
    lo, hi = ts[bounds[main]], ts[bounds[main + 1] - 1]
    far = max(gap, 10.0 * (hi - lo))
    small = max(1, int(OUTLIER_SHARE * ts.size))
    for k in range(sizes.size):
        if k == main or sizes[k] > small:
            continue
        a, b = ts[bounds[k]], ts[bounds[k + 1] - 1]
        if min(abs(a - hi), abs(lo - b)) <= far:
            continue
        j = int(order[bounds[k]])
        at = stretch = ""
        if recorded is not None:
            rec = np.asarray(recorded, float)
            main_rec = rec[order[bounds[main] : bounds[main + 1]]]
            at = f" (recorded {rec[j]:.3f} s into the bag)"
            stretch = (
                f"recorded {main_rec.min():.3f} to {main_rec.max():.3f} s into the bag, stamped "
            )
        raise InputError(
            source,
            f"{what}, {item} {int(idx[j])}{at}, stamp {t[j]:.9f} s ({_iso(t[j])})",
            f"stamps on the clock of the other {int(sizes[main])} {item}s "
            f"({stretch}{_iso(lo)} to {_iso(hi)})",
            Described(
                f"{int(sizes[k])} {item}(s) {abs(t[j] - (lo if t[j] < lo else hi)):.6g} s away "
                "from them (a stamp of another clock or a damaged one)"
            ),
        )


def read_tracks_bag(
    path: str | os.PathLike, topics: Sequence[str] | None = None, map_frame: str = "map"
) -> pd.DataFrame:
    """Read tracked objects from a ROS 1 ``.bag``, a ROS 2 bag directory or an ``.mcap`` file.

    Parameters
    ----------
    path : str or PathLike
        ``*.bag`` (ROS 1), a ROS 2 bag directory (``metadata.yaml`` + sqlite3/mcap storage) or
        a single ``*.mcap`` / ``*.db3`` storage file.
    topics : sequence of str, optional
        Topics to read; default: every topic of a supported type
        (:data:`SUPPORTED_TRACK_TYPES`).
    map_frame : str
        The frame positions are returned in when the bag has ``/tf`` (sightings in other
        frames are transformed).

    Returns
    -------
    pandas.DataFrame
        One row per sighting: ``id`` (str), ``t`` (s), ``x``, ``y`` (m), ``yaw`` (rad),
        ``label`` (str: the marker namespace, or the detection's class id), ``topic``,
        ``frame_id`` (the map frame once transformed); sorted by ``t`` (stable).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the bag cannot be read, a requested topic is missing or of an unsupported type,
        no supported topic exists, the topics hold no sightings, or a sighting's frame has
        no ``/tf`` chain to ``map_frame`` in a bag with ``/tf``.

    Examples
    --------
    >>> tracks = read_tracks_bag("field/courtyard.mcap", topics=["/people"])  # doctest: +SKIP
    >>> log = tracks_to_lifecycle(tracks, gap_tolerance=1.0)  # doctest: +SKIP
    """

    p = check_bag_path(path)
    if topics is not None:
        if isinstance(topics, str) or not isinstance(topics, Sequence):
            raise InputError("topics", "", "a list of topic names", topics)
        for k, t in enumerate(topics):
            get_str(t, "topics", f"[{k}]")
    ros1 = p.suffix == ".bag"
    rows: list[tuple] = []
    bag_errors = _bag_errors()
    try:
        default = partial(vision_msgs_typestore, 1 if ros1 else 2)  # built if the bag needs it
        with bag_reader([p], default_typestore=default) as reader:
            by_topic: dict[str, str] = {}
            for c in reader.connections:
                by_topic.setdefault(c.topic, c.msgtype)
            if topics is None:
                chosen = [t for t, ty in by_topic.items() if ty in SUPPORTED_TRACK_TYPES]
                if not chosen:
                    found = ", ".join(f"{t} ({ty})" for t, ty in by_topic.items()) or "none"
                    raise ValueError(
                        f"{p}: expected a topic of type {', '.join(SUPPORTED_TRACK_TYPES)}, "
                        f"got topics: {found}"
                    )
            else:
                chosen = list(topics)
                for t in chosen:
                    if t not in by_topic:
                        raise ValueError(
                            f"{p}: topic {t!r}: expected a topic of the bag "
                            f"({', '.join(sorted(by_topic)) or 'none'}), got "
                            "a missing topic"
                        )
                    if by_topic[t] not in SUPPORTED_TRACK_TYPES:
                        raise ValueError(
                            f"{p}: topic {t!r}: expected a message type in "
                            f"{', '.join(SUPPORTED_TRACK_TYPES)}, got "
                            f"{by_topic[t]}"
                        )
            tf_topics = [t for t in ("/tf", "/tf_static") if by_topic.get(t) in TF_TYPES]
            tf = TfBuffer()
            conns = [c for c in reader.connections if c.topic in (*chosen, *tf_topics)]
            states = {t: _MarkerState() for t in chosen}
            counts: dict[str, int] = {}
            for conn, ts, msg in _messages(reader, conns, p, bag_errors):
                n = counts[conn.topic] = counts.get(conn.topic, 0) + 1
                where = f"topic {conn.topic!r}, message {n}"
                if conn.topic in tf_topics and conn.topic not in chosen:
                    tf.add_message(
                        msg, ts * 1e-9, conn.topic == "/tf_static", p, where.replace("'", "")
                    )
                    continue
                try:
                    if conn.msgtype == _MARKER_ARRAY:
                        _markers(msg.markers, states[conn.topic], conn.topic, ts, rows, p, where)
                    elif conn.msgtype == _MARKER:
                        _markers([msg], states[conn.topic], conn.topic, ts, rows, p, where)
                    else:
                        _detections(msg, conn.topic, ts, rows, p, where)
                except (AttributeError, TypeError) as err:
                    # the bag's own definition of the type lacks a standard field
                    raise ValueError(
                        f"{p}: topic {conn.topic!r} (received at {ts * 1e-9:.9f} s): expected "
                        f"a {conn.msgtype} with its standard fields, got a message whose "
                        f"definition differs ({err})"
                    ) from None
    except bag_errors as err:
        # opening the bag (its index, connections and schemas) failed
        raise ValueError(
            f"{p}: expected a readable ROS 1 / ROS 2 bag or MCAP file, got: "
            f"{type(err).__name__}: {err}"
        ) from None
    if not rows:
        raise ValueError(
            f"{p}: topics {', '.join(chosen)}: expected at least one sighting "
            "(ADD marker or detection), got none"
        )
    df = pd.DataFrame(rows, columns=["id", "t", "x", "y", "yaw", "label", "topic", "frame_id"])
    for topic, part in df.groupby("topic", sort=True):
        check_stamps(
            part["t"].to_numpy(float), p, f"topic {topic!r}", part.index + 1, item="sighting"
        )
    if tf_topics:
        df = _to_map_frame(df, tf, map_frame.lstrip("/"), p)
    for c in ("t", "x", "y"):
        v = df[c].to_numpy(dtype=np.float64)
        bad = ~np.isfinite(v)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(
                p,
                f"topic {df['topic'].iloc[i]!r}, track {df['id'].iloc[i]!r}, message "
                f"{i + 1} of the topics read, {c}",
                "a finite number",
                float(v[i]),
            )
    for c in ("id", "label", "topic", "frame_id"):
        df[c] = df[c].astype("str")
    order = np.argsort(df["t"].to_numpy(), kind="stable")
    return df.iloc[order].reset_index(drop=True)


# ---- pass-through: an input bag's channels copied raw -------------------------------------


class PassChannel(NamedTuple):
    """One channel of an input bag, as it is copied into an MCAP.

    Attributes
    ----------
    topic, msgtype : str
        Topic and schema name (a ROS 1 type renamed as ``rosbags.convert`` renames it).
    schema_encoding : str
        ``ros2msg`` or ``ros2idl`` (``""``: no schema).
    schema : bytes
        The schema's definition text, as the input holds it (generated for a bag without
        one).
    message_encoding : str
        ``cdr`` (a ROS 1 bag's messages are converted to it).
    metadata : dict of str to str
        The input's channel metadata (``offered_qos_profiles``, ``topic_type_hash``);
        empty for a ROS 1 bag (the writer adds QoS from :attr:`latched`).
    latched : bool
        A ROS 1 latched topic or a transient-local one.
    count : int
        Messages of the channel in the input (its index).
    """

    topic: str
    msgtype: str
    schema_encoding: str
    schema: bytes
    message_encoding: str
    metadata: dict
    latched: bool
    count: int


class PassThrough(NamedTuple):
    """The channels of an input bag selected for pass-through and how to stream them.

    Attributes
    ----------
    path : Path
        The bag.
    channels : list of PassChannel
        The selected channels (index ``k`` in :attr:`messages`' records).
    topics : dict of str to str
        Every topic of the bag and its type (selected or not).
    qos_form : {"int", "string"}
        How the bag spells QoS: Humble's integers or Jazzy's names (``int`` when it says
        nothing).
    type_hash : bool
        Whether the bag's channels carry a ``topic_type_hash`` (Jazzy).
    messages : callable
        ``messages()`` yields ``(log_time ns, publish_time ns, sequence, k, data)`` in the
        input's log-time order, streamed (one record at a time), the bytes unchanged
        (CDR converted from ROS 1 for a ``.bag``).
    """

    path: Path
    channels: list[PassChannel]
    topics: dict[str, str]
    qos_form: str
    type_hash: bool
    messages: Callable[[], Iterator[tuple[int, int, int, int, bytes]]]


def _qos_form(texts: Sequence[str]) -> str:
    for text in texts:
        m = re.search(r"reliability'?:\s*'?([A-Za-z_]+|\d+)", str(text))
        if m:
            return "int" if m.group(1).isdigit() else "string"
    return "int"


def _select(p: Path, by_topic: dict[str, str], topics: Sequence[str] | None) -> set[str]:
    if topics is None:
        return set(by_topic)
    listed = ", ".join(f"{t} ({ty})" for t, ty in sorted(by_topic.items())) or "none"
    for t in topics:
        if t not in by_topic:
            raise InputError(
                p,
                f"--topics {t}",
                "a topic of the bag",
                Described(f"no such topic; topics: {listed}"),
            )
    return set(topics)


def _mcap_passthrough(p: Path, topics: Sequence[str] | None) -> PassThrough:
    # lazy: mcap's reader adds 0.07 s CPU to `import are_stats.logs`
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    errors = (*_bag_errors(), McapError, ValueError)
    try:
        with open(p, "rb") as fh:
            summary = make_reader(fh).get_summary()
    except errors as err:
        raise ValueError(
            f"{p}: expected a readable MCAP file, got: {type(err).__name__}: {err}"
        ) from None
    if summary is None:
        raise InputError(p, "", "an MCAP file with a summary (index)", Described("none"))
    by_topic: dict[str, str] = {}
    for ch in summary.channels.values():
        sc = summary.schemas.get(ch.schema_id)
        by_topic.setdefault(ch.topic, sc.name if sc is not None else "")
    sel = _select(p, by_topic, topics)
    counts = summary.statistics.channel_message_counts if summary.statistics else {}
    index: dict[int, int] = {}
    channels: list[PassChannel] = []
    for cid, ch in sorted(summary.channels.items()):
        if ch.topic not in sel:
            continue
        sc = summary.schemas.get(ch.schema_id)
        meta = dict(ch.metadata)
        index[cid] = len(channels)
        channels.append(
            PassChannel(
                ch.topic,
                sc.name if sc is not None else "",
                sc.encoding if sc is not None else "",
                bytes(sc.data) if sc is not None else b"",
                ch.message_encoding,
                meta,
                "transient_local" in meta.get("offered_qos_profiles", "")
                or "durability: 1" in meta.get("offered_qos_profiles", ""),
                int(counts.get(cid, 0)),
            )
        )
    texts = [c.metadata.get("offered_qos_profiles", "") for c in summary.channels.values()]
    hashed = any(c.metadata.get("topic_type_hash") for c in summary.channels.values())

    def messages() -> Iterator[tuple[int, int, int, int, bytes]]:
        with open(p, "rb") as fh:
            it = make_reader(fh).iter_messages(topics=sorted(sel), log_time_order=True)
            for _, ch, m in _records(it, p, errors, "MCAP"):
                yield m.log_time, m.publish_time, m.sequence, index[ch.id], m.data

    return PassThrough(p, channels, by_topic, _qos_form(texts), hashed, messages)


def _folder_metadata(p: Path) -> dict[str, dict]:
    """``{topic: topic_metadata}`` of a ROS 2 bag folder's ``metadata.yaml``."""
    try:
        info = yaml.safe_load((p / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        rows = info.get("topics_with_message_count") or []
        return {str(r["topic_metadata"]["name"]): dict(r["topic_metadata"]) for r in rows}
    except (yaml.YAMLError, KeyError, TypeError, AttributeError, UnicodeDecodeError) as err:
        raise InputError(
            p / "metadata.yaml",
            "rosbag2_bagfile_information.topics_with_message_count",
            "rosbag2 metadata",
            Described(f"{type(err).__name__}: {err}"),
        ) from None


def _rosbags_passthrough(p: Path, topics: Sequence[str] | None) -> PassThrough:
    # lazy: rosbags' converter adds 0.48 s CPU to `import are_stats.logs` (the four imports)
    from rosbags.convert.converter import STATIC_MSGTYPE_RENAMES, generate_message_converter
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    errors = _bag_errors()
    ros1 = p.suffix == ".bag"
    store = partial(vision_msgs_typestore, 1 if ros1 else 2)  # built if a bag needs it
    meta = {} if ros1 or not p.is_dir() else _folder_metadata(p)
    keys: dict[tuple[str, str], int] = {}
    channels: list[PassChannel] = []
    convert: dict[str, Callable[[bytes | memoryview], memoryview]] = {}
    try:
        with bag_reader([p], default_typestore=store) as reader:
            by_topic: dict[str, str] = {}
            for c in reader.connections:
                by_topic.setdefault(c.topic, c.msgtype)
            sel = _select(p, by_topic, topics)
            dst = None
            if ros1:  # ROS 2 Header (no seq) over the bag's own definitions, as rosbags.convert
                header = get_typestore(Stores.ROS2_FOXY).fielddefs["std_msgs/msg/Header"]
                dst = get_typestore(Stores.EMPTY)
                dst.register({**reader.typestore.fielddefs, "std_msgs/msg/Header": header})
            for c in reader.connections:
                if c.topic not in sel:
                    continue
                typ = STATIC_MSGTYPE_RENAMES.get(c.msgtype, c.msgtype) if ros1 else c.msgtype
                key = (c.topic, typ)
                if key in keys:
                    k = keys[key]
                    channels[k] = channels[k]._replace(count=channels[k].count + int(c.msgcount))
                    continue
                if ros1:
                    try:
                        if typ not in dst.fielddefs:
                            msgdef = reader.typestore.generate_msgdef(c.msgtype, ros_version=2)[0]
                            typs = get_types_from_msg(msgdef, typ)
                            typs.pop("std_msgs/msg/Header", None)
                            dst.register(typs)
                        convert[c.msgtype] = generate_message_converter(
                            reader.typestore, dst, c.msgtype, typ, {}, src_is2=False, dst_is2=True
                        )
                        text, enc = dst.generate_msgdef(typ, ros_version=2)[0], "ros2msg"
                    except errors as err:
                        raise InputError(
                            p,
                            f"topic {c.topic}",
                            "a ROS 1 type convertible to ROS 2 CDR for the MCAP (or leave the "
                            "topic out with --topics)",
                            Described(f"{c.msgtype}: {type(err).__name__}: {err}"),
                        ) from None
                    md: dict[str, str] = {}
                    latched = bool(getattr(c.ext, "latching", 0))
                else:
                    if c.msgdef.format == MessageDefinitionFormat.IDL:
                        text, enc = c.msgdef.data, "ros2idl"
                    elif c.msgdef.format == MessageDefinitionFormat.MSG and c.msgdef.data:
                        text, enc = c.msgdef.data, "ros2msg"
                    else:
                        text, enc = (
                            reader.typestore.generate_msgdef(typ, ros_version=2)[0],
                            "ros2msg",
                        )
                    tm = meta.get(c.topic, {})
                    qos = tm.get("offered_qos_profiles", "")
                    md = {
                        "offered_qos_profiles": qos if isinstance(qos, str) else yaml.safe_dump(qos)
                    }
                    if tm.get("type_description_hash"):
                        md["topic_type_hash"] = str(tm["type_description_hash"])
                    latched = any(
                        getattr(getattr(q, "durability", None), "value", None) == 1
                        for q in (getattr(c.ext, "offered_qos_profiles", None) or [])
                    )
                keys[key] = len(channels)
                channels.append(
                    PassChannel(
                        c.topic, typ, enc, text.encode(), "cdr", md, latched, int(c.msgcount)
                    )
                )
    except errors as err:
        raise ValueError(
            f"{p}: expected a readable ROS 1 / ROS 2 bag or MCAP file, got: "
            f"{type(err).__name__}: {err}"
        ) from None
    texts = [str(tm.get("offered_qos_profiles", "")) for tm in meta.values()]
    hashed = any(tm.get("type_description_hash") for tm in meta.values())

    def messages() -> Iterator[tuple[int, int, int, int, bytes]]:
        with bag_reader([p], default_typestore=store) as reader:
            conns = [c for c in reader.connections if c.topic in sel]
            it = reader.messages(connections=conns)
            n = 0
            while True:
                try:
                    conn, ts, raw = next(it)
                except StopIteration:
                    return
                except errors as err:
                    raise ValueError(
                        f"{p}: record after message {n}: expected a readable bag record, got "
                        f"a damaged one ({type(err).__name__}: {err})"
                    ) from None
                n += 1
                typ = (
                    STATIC_MSGTYPE_RENAMES.get(conn.msgtype, conn.msgtype) if ros1 else conn.msgtype
                )
                if ros1:
                    try:
                        raw = bytes(convert[conn.msgtype](raw))
                    except errors as err:
                        raise ValueError(
                            f"{p}: topic {conn.topic!r}, message {n}: expected a ROS 1 "
                            f"{conn.msgtype} convertible to ROS 2 CDR (or leave the topic out "
                            f"with --topics), got {type(err).__name__}: {err}"
                        ) from None
                yield int(ts), int(ts), n - 1, keys[(conn.topic, typ)], bytes(raw)

    return PassThrough(p, channels, by_topic, _qos_form(texts), hashed, messages)


def bag_passthrough(path: str | os.PathLike, topics: Sequence[str] | None = None) -> PassThrough:
    """The channels of a bag to copy into an MCAP unchanged, streamed.

    An ``.mcap`` file is copied raw (schemas, channel metadata, message bytes, log and
    publish times, sequences); a ROS 2 bag folder (sqlite3 or MCAP storage) with its
    schemas and the QoS / type hash of its ``metadata.yaml``; a ROS 1 ``.bag`` has its
    messages converted to ROS 2 CDR with the bag's own definitions (the ROS 2 ``Header``
    without ``seq``, ``tf/tfMessage`` as ``tf2_msgs/msg/TFMessage``, as
    ``rosbags.convert`` converts), or is refused when a type cannot be converted.

    Parameters
    ----------
    path : path
        The bag (checked with :func:`check_bag_path`).
    topics : sequence of str, optional
        The topics to pass through (default all).

    Returns
    -------
    PassThrough

    Raises
    ------
    are_stats.inputs.InputError
        A topic not in the bag (the bag's topics listed), a ROS 1 type that cannot be
        converted, unreadable metadata.
    ValueError
        A damaged bag (naming it).
    """
    p = check_bag_path(path)
    if topics is not None:
        topics = [get_str(t, "--topics", "") for t in topics]
    if p.is_file() and p.suffix == ".mcap":
        return _mcap_passthrough(p, topics)
    return _rosbags_passthrough(p, topics)
