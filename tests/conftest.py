from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

from planning.robot_model import RobotModel, load_robot
from planning.sphere_model import SphereModel

# The property tests draw the same examples on every run (a CI run must not meet a case the
# last one did not): a case worth keeping becomes its own test.
settings.register_profile("gaide", derandomize=True, print_blob=True)
settings.load_profile("gaide")

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session", autouse=True)
def _one_torch_thread() -> None:
    """The tests' models are small, and the suite shares two cores with the subprocesses
    it starts: torch's spinning OpenMP threads then cost 10-60x more than they bring."""
    import torch

    torch.set_num_threads(1)


@pytest.fixture(scope="session")
def robot() -> RobotModel:
    return load_robot()


@pytest.fixture(scope="session")
def spheres(robot: RobotModel) -> SphereModel:
    assert robot.config.spheres is not None
    return SphereModel.load_for(robot.config.spheres, robot)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


def shared_data(rel: str) -> Path:
    """A file of ../shared/data, or a skip naming what is missing."""
    path = SHARED_DATA / rel
    if not path.exists():
        pytest.skip(f"real test data {path} is absent (../shared/data is not beside the repo)")
    return path


def run_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "gaide", *args],
        capture_output=True,
        text=True,
        cwd=cwd or ROOT,
        timeout=600,
    )
