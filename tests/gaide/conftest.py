"""One successful `gaide run` on a small synthetic bag, shared by every module that checks
its outputs (the pipeline's files, the report in a browser, run.mcap)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaide.synthetic.record import record_scene
from gaide.synthetic.scene import fixed_scene
from planning.robot_model import RobotModel
from tests.conftest import run_cli

# Above the table in front of the robot, hand down as at the start: valid in every seed's
# scene (the boxes stand at the sides, the board further out).
GOAL = "xyz:0.45,-0.1,0.25"
# The run on the synthetic bag plans with RRT-Connect: GAIDE's weights are exercised by the
# demo; this run checks the wiring and must not depend on them.
RUN_FLAGS = ("--planner", "rrtconnect", "--rate", "100", "--set", "simulate.settle_s=0")


@pytest.fixture(scope="session")
def bag(tmp_path_factory: pytest.TempPathFactory, robot: RobotModel) -> Path:
    rng = np.random.default_rng(5)
    scene = fixed_scene(robot, rng, frames=2)
    path, _ = record_scene(scene, robot, tmp_path_factory.mktemp("bag") / "cell.bag", rng)
    return path


@pytest.fixture(scope="session")
def run_out(bag: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The run's folder and what it printed."""
    out = tmp_path_factory.mktemp("run") / "out"
    proc = run_cli("run", str(bag), "--goal", GOAL, "-o", str(out), *RUN_FLAGS)
    assert proc.returncode == 0, proc.stderr
    return out, proc.stdout
