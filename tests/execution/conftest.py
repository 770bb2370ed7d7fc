from __future__ import annotations

import numpy as np
import pytest

from execution.ruckig_timing import RuckigParameterizer
from execution.timing_cfg import TimingCfg, TimingMode
from execution.trajectory import TimedTrajectory
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


@pytest.fixture(scope="session")
def free_checker(robot: RobotModel, spheres: SphereModel) -> CollisionChecker:
    """The UR5 with no obstacles (joint limits and self-collision only)."""
    return make_checker(robot, spheres)


@pytest.fixture(scope="session")
def corner_path(robot: RobotModel) -> np.ndarray:
    """A collision-free path with two corners around the home configuration."""
    home = robot.named_configuration("home")
    return np.array(
        [
            home,
            home + np.array([0.9, 0.2, -0.3, 0.0, 0.4, 0.0]),
            home + np.array([1.2, 0.5, -0.6, 0.3, 0.2, 0.8]),
            home + np.array([0.4, 0.6, -0.2, 0.5, -0.3, 1.0]),
        ]
    )


@pytest.fixture(scope="session")
def small_traj(free_checker: CollisionChecker, corner_path: np.ndarray) -> TimedTrajectory:
    """A blended trajectory along ``corner_path`` at 100 Hz."""
    cfg = TimingCfg(rate_hz=100.0, mode=TimingMode.BLENDED, shortcut=False)
    return RuckigParameterizer(cfg).parameterize(corner_path, free_checker)
