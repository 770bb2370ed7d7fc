from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gaide_core.errors import TimingError
from gaide_core.plan_file import PlanFile, read_plan, write_plan


def test_a_plan_round_trips_with_every_key(tmp_path: Path) -> None:
    plan = PlanFile(
        planner="rrtc",
        status="success",
        scene="shelf_1 seed 3",
        joint_names=("a", "b"),
        time_s=0.25,
        cost_rad=1.5,
        start=np.array([0.0, 1.0]),
        goal=np.array([1.0, 0.0]),
        path=np.array([[0.0, 1.0], [0.5, 0.5], [1.0, 0.0]]),
        stats={"iterations": np.int64(7), "kind": Path("x")},
    )
    out = tmp_path / "plan.json"
    write_plan(out, plan)
    raw = json.loads(out.read_text())
    assert list(raw) == [
        "planner", "status", "scene", "joint_names", "time_s", "cost_rad",
        "start", "goal", "path", "stats",
    ]  # fmt: skip
    assert raw["stats"] == {"iterations": "7", "kind": "x"}
    back = read_plan(out)
    np.testing.assert_array_equal(back.path, plan.path)
    assert back.joint_names == ("a", "b") and back.scene == "shelf_1 seed 3"
    assert back.cost_rad == 1.5 and back.start is not None and back.start.tolist() == [0, 1]


def test_a_hand_written_file_needs_only_the_path(tmp_path: Path) -> None:
    out = tmp_path / "p.json"
    out.write_text('{"path": [[0, 0], [1, 1]]}')
    plan = read_plan(out)
    assert plan.path.shape == (2, 2) and plan.joint_names is None and plan.scene is None


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ('{"waypoints": []}', "needs a 'path' list of waypoints"),
        ("[1, 2]", "needs a 'path' list of waypoints"),
        ('{"path": [[0, 0], [1]]}', "differ in length"),
        ('{"path": [[0, "a"]]}', "each a list of numbers"),
        ('{"path": 3}', "each a list of numbers"),
        ('{"path": [[0]], "joint_names": "a"}', "'joint_names' must be a list"),
        ('{"path": [[0]], "scene": 4}', "'scene' must be"),
        ('{"path": [[0]], "cost_rad": "long"}', "'cost_rad' must be a finite number"),
        ('{"path": [[0]], "start": [true]}', "'start' must be a list of numbers"),
    ],
)
def test_a_wrong_file_names_its_key(tmp_path: Path, content: str, message: str) -> None:
    out = tmp_path / "p.json"
    out.write_text(content)
    with pytest.raises(TimingError, match=message) as err:
        read_plan(out)
    assert str(out) in str(err.value)
