"""The collision re-check of blended segments, which leave the checked path.

Each blend is sampled every ``dt`` (the controller rate), and more densely wherever the
checker's displacement bound says a sphere may move more than the checker's resolution
between two samples: there the interval is split into as many equal steps as the checker
would use for an edge between the two samples, evaluated on the Ruckig trajectory itself.
All samples are checked in one batch. Between two consecutive samples the trajectory is
their chord to within ``a dt^2 / 8`` rad (4e-6 rad at 8 rad/s^2 and 2 ms), so the swept volume
is covered as the checker covers an edge (resolution <= 2 x margin).
"""

from __future__ import annotations

import numpy as np
import ruckig

from execution.limits import JointLimits
from execution.ruckig_segments import MoveTable, profile_extrema
from gaide_core.types import Array
from planning.collision import CollisionChecker


def _extrema(traj: ruckig.Trajectory, dof: int) -> tuple[Array, Array]:
    bounds = [profile_extrema(prof) for prof in traj.profiles[0][:dof]]
    return np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])


def _blend_samples(traj: ruckig.Trajectory, checker: CollisionChecker, dt: float) -> Array:
    """(M, dof) configurations of ``traj`` every ``dt`` s (end included), refined where a
    sphere may move more than the checker's resolution between two of them."""
    table = MoveTable(traj, checker.robot.dof)
    times = np.append(np.arange(0.0, traj.duration, dt), traj.duration)
    Q = table.states(times)[0]
    steps = checker.edge_steps(Q[:-1], Q[1:])
    wide = np.flatnonzero(steps > 1)
    if wide.size == 0:
        return Q
    extra = np.concatenate(
        [times[i] + (times[i + 1] - times[i]) * np.arange(1, steps[i]) / steps[i] for i in wide]
    )
    return np.concatenate([Q, table.states(extra)[0]])


def recheck(
    todo: dict[int, ruckig.Trajectory],
    checker: CollisionChecker,
    limits: JointLimits,
    dt: float,
) -> tuple[dict[int, str], int]:
    """Re-check blends (segment index -> Ruckig trajectory): the samples above with the
    checker and the exact position extrema against the joint limits. Returns a verdict per
    blend ("" clear, else why not) and the number of configurations checked."""
    verdicts: dict[int, str] = {}
    blocks: list[Array] = []
    keys: list[int] = []
    for k, traj in todo.items():
        lo, hi = _extrema(traj, limits.dof)
        if np.any(lo < limits.lower) or np.any(hi > limits.upper):
            verdicts[k] = "leaves the joint limits"
            continue
        blocks.append(_blend_samples(traj, checker, dt))
        keys.append(k)
    if not blocks:
        return verdicts, 0
    ok = checker.config_valid(np.concatenate(blocks))
    start = 0
    for k, block in zip(keys, blocks, strict=True):
        verdicts[k] = "" if ok[start : start + len(block)].all() else "collides"
        start += len(block)
    return verdicts, start
