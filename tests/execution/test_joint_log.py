from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from execution.joint_log import check_log, read_log_csv
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates

ROSTOPIC = """%time,field.header.seq,field.header.stamp,field.header.frame_id,field.name0,field.name1,field.position0,field.position1,field.velocity0,field.velocity1,field.effort0,field.effort1
1700000000100000000,1,1700000000100000000,,a,b,0.2,1.0,0.0,0.0,0,0
1700000000000000000,0,1700000000000000000,,a,b,0.1,1.5,0.5,0.0,0,0
1700000000200000000,2,1700000000200000000,,a,b,0.3,0.5,1.0,0.0,0,0
"""


def test_rostopic_echo_csv_is_read_in_time_order(tmp_path: Path) -> None:
    src = tmp_path / "log.csv"
    src.write_text(ROSTOPIC)
    log = read_log_csv(src)
    assert log.names == ("a", "b")
    assert log.start_ns == 1_700_000_000_000_000_000
    np.testing.assert_allclose(log.t, [0.0, 0.1, 0.2])
    np.testing.assert_allclose(log.q[:, 0], [0.1, 0.2, 0.3])
    assert log.qd is not None
    np.testing.assert_allclose(log.qd[:, 0], [0.5, 0.0, 1.0])


def test_select_reorders_and_names_missing_joints() -> None:
    log = JointStates(
        names=("a", "b", "c"),
        t=np.arange(3.0),
        q=np.arange(9.0).reshape(3, 3),
        error=ExecutionError,
    )
    np.testing.assert_array_equal(log.select(("c", "a")).q, [[2, 0], [5, 3], [8, 6]])
    with pytest.raises(ExecutionError, match=r"lack joints \['d'\].*\['b', 'c'\]"):
        log.select(("a", "d"))


def test_a_bad_log_is_refused(tmp_path: Path) -> None:
    src = tmp_path / "log.csv"
    src.write_text("time,a\n0,1\n")
    with pytest.raises(ExecutionError, match="first column must be 't'"):
        read_log_csv(src)
    with pytest.raises(ExecutionError, match="repeat"):
        JointStates(names=("a", "a"), t=np.arange(2.0), q=np.zeros((2, 2)), error=ExecutionError)
    src.write_text("t,a_pos\n0,1\n")
    with pytest.raises(ExecutionError, match=r"log.csv: a joint log needs >= 2 samples"):
        read_log_csv(src)
    one = JointStates(names=("a",), t=np.zeros(1), q=np.zeros((1, 1)), error=ExecutionError)
    with pytest.raises(ExecutionError, match=">= 2 samples to compare, got 1"):
        check_log(one)
