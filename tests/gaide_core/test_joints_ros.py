"""gaide_core.joints and gaide_core.ros: one joint-state series, its messages and bags."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from gaide_core.errors import BagError, ExecutionError
from gaide_core.joints import JointStates
from gaide_core.ros import (
    JOINT_STATE,
    Messages,
    joint_state_messages,
    joint_states_from,
    message_stamp_ns,
    write_bag,
)

START_NS = 1_700_000_000_123_456_789


def _states(qd: bool = True) -> JointStates:
    q = np.arange(12.0).reshape(4, 3)
    return JointStates.from_stamps(
        ("a", "b", "c"),
        START_NS + 10_000_000 * np.arange(4, dtype=np.int64),
        q,
        -q if qd else None,
        error=BagError,
    )


def test_stamps_round_trip_exactly_and_select_reorders() -> None:
    js = _states()
    assert js.start_ns == START_NS and js.t[0] == 0.0
    np.testing.assert_array_equal(js.stamps_ns, START_NS + 10_000_000 * np.arange(4))
    np.testing.assert_array_equal(js.at(START_NS + 12_000_000), [3.0, 4.0, 5.0])
    picked = js.select(("c", "a"))
    np.testing.assert_array_equal(picked.q[0], [2.0, 0.0])
    assert picked.qd is not None and picked.error is BagError
    with pytest.raises(BagError, match=r"lack joints \['d'\].*\['b'\]"):
        js.select(("a", "c", "d"))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"names": ("a", "a"), "t": np.zeros(1), "q": np.zeros((1, 2))}, "repeat"),
        ({"names": ("a",), "t": np.zeros(0), "q": np.zeros((0, 1))}, "at least one sample"),
        ({"names": ("a",), "t": np.zeros(2), "q": np.zeros((2, 1))}, "increase strictly"),
        ({"names": ("a",), "t": np.arange(2.0), "q": np.zeros((2, 2))}, r"shape \(2, 2\)"),
    ],
)
def test_bad_series_raise_the_callers_error(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ExecutionError, match=match):
        JointStates(**kwargs, error=ExecutionError)


def test_messages_and_back_skip_partial_and_repeated_ones() -> None:
    js = _states()
    m = Messages(1)
    bag = joint_state_messages(js, m)
    assert [b.stamp_ns for b in bag] == js.stamps_ns.tolist()
    assert [b.msg.header.seq for b in bag] == [0, 1, 2, 3]  # ROS1: seq counts per topic
    gripper = m.joint_state("/joint_states", START_NS + 1, ["gripper"], np.zeros(1))
    stamped = [(b.stamp_ns, b.msg) for b in bag]
    stamped += [(START_NS + 1, gripper), (bag[2].stamp_ns, bag[3].msg)]
    back, skipped = joint_states_from(reversed(stamped), BagError)
    assert skipped == 1 and back is not None
    assert back.names == js.names and back.start_ns == js.start_ns
    np.testing.assert_array_equal(back.stamps_ns, js.stamps_ns)
    assert back.qd is not None
    np.testing.assert_array_equal(back.qd[:2], -js.q[:2])
    np.testing.assert_array_equal(back.q[2], js.q[3])  # of one stamp, the first message
    assert joint_states_from([]) == (None, 0)


@pytest.mark.parametrize(("name", "ros", "storage"), [("j.bag", 1, "sqlite3"), ("j", 2, "mcap")])
def test_write_bag_round_trips_and_stages(
    tmp_path: Path, name: str, ros: int, storage: str
) -> None:
    js = _states(qd=False)
    m = Messages(ros)
    path = write_bag(tmp_path / name, joint_state_messages(js, m), m, storage=storage)
    with AnyReader([path]) as reader:
        got = [
            (message_stamp_ns(msg, log), msg)
            for c, log, raw in reader.messages()
            for msg in [reader.deserialize(raw, c.msgtype)]
            if c.msgtype == JOINT_STATE
        ]
    back, skipped = joint_states_from(got)
    assert skipped == 0 and back is not None and back.qd is None
    np.testing.assert_array_equal(back.q, js.q)
    np.testing.assert_array_equal(back.stamps_ns, js.stamps_ns)
    with pytest.raises(BagError, match="storage must be one of"):
        write_bag(tmp_path / "x", [], m, storage="bogus", error=BagError)
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_a_failing_write_leaves_nothing(tmp_path: Path) -> None:
    m = Messages(2)
    bad = joint_state_messages(_states(), m)
    bad[2] = type(bad[2])("/joint_states", "no_such/msg/Type", bad[2].stamp_ns, bad[2].msg)
    with pytest.raises(ExecutionError, match="writing the bag failed"):
        write_bag(tmp_path / "out" / "j", bad, m, error=ExecutionError)
    assert list((tmp_path / "out").iterdir()) == []
