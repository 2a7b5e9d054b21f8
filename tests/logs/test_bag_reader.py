"""``logs/_bag_reader.py``: the reader with shared type stores reads what rosbags'
``AnyReader`` reads (connections, types, messages, refusals), building a store once per
set of definitions."""

from __future__ import annotations

import sqlite3

import pytest

from are_stats.logs import bag_reader, vision_msgs_typestore
from tests.export.rosbag_fixtures import write_bag


def _read(reader) -> tuple[list, dict, list]:
    with reader as r:
        conns = [(c.topic, c.msgtype, c.msgcount) for c in r.connections]
        types = dict(r.typestore.fielddefs)
        msgs = [(c.topic, t, repr(r.deserialize(raw, c.msgtype))) for c, t, raw in r.messages()]
    return conns, types, msgs


@pytest.mark.parametrize("kind", ["ros1", "ros2", "mcap"])
def test_bag_reader_reads_what_anyreader_reads_with_one_store(tmp_path, kind):
    from rosbags.highlevel import AnyReader

    bag = write_bag(tmp_path / ("robot.bag" if kind == "ros1" else "robot"), kind)
    store = vision_msgs_typestore(1 if kind == "ros1" else 2)
    want = _read(AnyReader([bag], default_typestore=store))
    assert _read(bag_reader(bag, store)) == want
    with bag_reader(bag) as a, bag_reader([bag]) as b:  # one store for the same definitions
        first = a.typestore
        assert b.typestore is first
    other = write_bag(tmp_path / ("again.bag" if kind == "ros1" else "again"), kind)
    with bag_reader(other) as c:  # another bag recorded with the same definitions
        assert c.typestore is first
    assert _read(bag_reader(other)) == _read(AnyReader([other]))


def test_bag_reader_refuses_what_anyreader_refuses(tmp_path):
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag1 import Writer
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    bad = tmp_path / "bad.bag"  # a definition whose md5sum is not its hash
    with Writer(bad) as w:
        c = w.add_connection("/s", "std_msgs/msg/String", msgdef="string data\n", md5sum="0" * 32)
        w.write(c, 1, ts.serialize_ros1(ts.types["std_msgs/msg/String"](data="x"), c.msgtype))
    errors = []
    for reader in (AnyReader([bad]), bag_reader(bad)):
        with pytest.raises(AnyReaderError, match="hash mismatch") as err, reader:
            pass
        errors.append(str(err.value))
    assert errors[0] == errors[1]
    # a ROS 2 bag without definitions (as before rosbag2 stored them): the default store
    ts2 = get_typestore(Stores.ROS2_HUMBLE)
    old = tmp_path / "old"
    with Writer2(old, version=9) as w:
        c = w.add_connection("/s", "std_msgs/msg/String", typestore=ts2)
        w.write(c, 1, ts2.serialize_cdr(ts2.types["std_msgs/msg/String"](data="x"), c.msgtype))
    db = sqlite3.connect(next(old.glob("*.db3")))
    with db:
        db.execute("DELETE FROM message_definitions")
    db.close()
    assert _read(bag_reader(old, ts2)) == _read(AnyReader([old], default_typestore=ts2))
    made = []  # a function making the default store: called for such a bag only

    def default():
        made.append(1)
        return ts2

    assert _read(bag_reader(old, default)) == _read(AnyReader([old], default_typestore=ts2))
    assert made == [1]
    _read(bag_reader(write_bag(tmp_path / "d.bag", "ros1"), default))  # carries its own
    assert made == [1]
    for reader in (AnyReader([old]), bag_reader(old)):
        with pytest.raises(AnyReaderError, match="no type definitions"), reader:
            pass


def test_another_rosbags_release_gets_rosbags_own_reader(tmp_path, monkeypatch):
    """The shared-store reader rewrites ``AnyReader._open``, a private method of the tested
    releases (``TESTED_ROSBAGS``): with another release the reader is rosbags' own, with the
    default store's function called, and reads the same."""
    from rosbags.highlevel import AnyReader

    import are_stats.logs._bag_reader as module

    bag = write_bag(tmp_path / "robot", "ros2")
    store = vision_msgs_typestore(2)
    assert module._shared_stores_supported()  # the installed release is a tested one
    shared = bag_reader(bag, lambda: store)
    assert type(shared) is not AnyReader
    monkeypatch.setattr(module, "TESTED_ROSBAGS", ("0.0.",))
    plain = bag_reader(bag, lambda: store)
    assert type(plain) is AnyReader
    assert _read(plain) == _read(shared) == _read(AnyReader([bag], default_typestore=store))
