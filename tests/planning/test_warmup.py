"""``python -m planning.compiled.warmup`` (part of ``make setup``) calls every kernel that
planning uses, for every world kind, so that a process's first plan loads machine code from
numba's cache instead of compiling it (seconds per kernel)."""

from __future__ import annotations

import json
import subprocess
import sys

from tests.conftest import ROOT

# Run in a fresh process: kernels the other tests already called would hide a gap here.
_SCRIPT = """
import json
import numpy as np
from numba.core.registry import CPUDispatcher
from planning.compiled import geometry, lanes, rrtc_kernel, shortcut_kernel, validity
from planning.compiled.warmup import warm_up
from planning.checker import make_checker
from planning.distance_field import CloudWorld
from planning.robot_model import load_robot
from planning.rrtc import CompiledRRTConnect, RRTCCfg
from planning.sphere_model import SphereModel
from tests.planning.ompl_problems import wall_problem


def signatures():
    mods = (geometry, lanes, rrtc_kernel, shortcut_kernel, validity)
    return {
        f"{m.__name__}.{name}": [str(s) for s in obj.signatures]
        for m in mods
        for name, obj in vars(m).items()
        if isinstance(obj, CPUDispatcher)
    }


warm_up()
before = signatures()
robot = load_robot()
spheres = SphereModel.load_for(robot.config.spheres, robot)
# the wall of ompl_problems.wall_checker as a perceived cloud: float32 points, 1 cm apart
y, z = np.meshgrid(np.arange(-0.6, 0.6, 0.01), np.arange(0.0, 0.6, 0.01))
points = np.stack([np.full(y.size, 0.45), y.ravel(), z.ravel()], axis=1).astype(np.float32)
checker = make_checker(robot, spheres, CloudWorld(points, voxel=0.01))
start, goal = wall_problem()
res = CompiledRRTConnect(RRTCCfg(max_iterations=100_000)).plan(
    checker, start, goal, budget_s=60.0, rng=np.random.default_rng(0)
)
assert res.path is not None and len(res.path) >= 3, res.detail
assert checker.first_invalid_edge(res.path) is None
after = signatures()
print(json.dumps({k: v for k, v in after.items() if v != before.get(k)}))
"""


def test_after_warm_up_planning_in_a_cloud_compiles_nothing() -> None:
    run = subprocess.run(
        [sys.executable, "-c", _SCRIPT], capture_output=True, text=True, check=False, cwd=ROOT
    )
    assert run.returncode == 0, run.stderr[-3000:]
    new = json.loads(run.stdout.strip().splitlines()[-1])
    assert new == {}, f"kernels the warm-up left out: {new}"
