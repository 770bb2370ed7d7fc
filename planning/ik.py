"""Inverse kinematics to an end-effector pose: damped least squares on Pinocchio's frame
Jacobian, from random restarts, keeping only within-limit (and, given a checker,
collision-free) solutions."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.robot_model import RobotModel


@dataclass(frozen=True, kw_only=True)
class IKCfg:
    restarts: int = 24  # random initial configurations (after the seed, if given)
    max_iters: int = 150
    tol_pos: float = 1e-4  # m
    tol_rot: float = 1e-3  # rad
    damping: float = 1e-6
    step: float = 1.0  # fraction of the Gauss-Newton step taken per iteration
    max_solutions: int = 8  # stop once this many distinct solutions are found

    def __post_init__(self) -> None:
        if self.restarts < 1 or self.max_iters < 1 or self.max_solutions < 1:
            raise PlanningError("IK restarts, max_iters and max_solutions must be >= 1")
        if min(self.tol_pos, self.tol_rot, self.damping, self.step) <= 0:
            raise PlanningError("IK tolerances, damping and step must be > 0")


def _wrap_into_limits(robot: RobotModel, q: Array) -> Array:
    """Shift revolute angles by multiples of 2 pi towards the middle of their limits."""
    mid = (robot.lower + robot.upper) / 2
    wrapped = q - 2 * np.pi * np.round((q - mid) / (2 * np.pi))
    return np.where((wrapped >= robot.lower) & (wrapped <= robot.upper), wrapped, q)


def _converge(robot: RobotModel, target: pin.SE3, fid: int, q: Array, cfg: IKCfg) -> Array | None:
    model, data = robot.model, robot.data
    for _ in range(cfg.max_iters):
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacement(model, data, fid)
        current_to_target = data.oMf[fid].actInv(target)
        err = pin.log6(current_to_target).vector
        if np.linalg.norm(err[:3]) < cfg.tol_pos and np.linalg.norm(err[3:]) < cfg.tol_rot:
            return q
        J = pin.computeFrameJacobian(model, data, q, fid, pin.ReferenceFrame.LOCAL)
        J = pin.Jlog6(current_to_target) @ J
        dq = J.T @ np.linalg.solve(J @ J.T + cfg.damping * np.eye(6), err)
        q = pin.integrate(model, q, cfg.step * dq)
    return None


def solve_ik(
    robot: RobotModel,
    T_world_target: Array,
    rng: np.random.Generator,
    *,
    cfg: IKCfg | None = None,
    checker: CollisionChecker | None = None,
    seed: Array | None = None,
    frame: str | None = None,
) -> list[Array]:
    """Solutions (dof,) reaching ``T_world_target`` (4, 4) with ``frame`` (default: the end
    effector), within limits and valid for ``checker`` when given; closest to ``seed`` first.
    An empty list means none was found from the restarts."""
    cfg = cfg or IKCfg()
    fid = robot.ee_frame if frame is None else robot.frame_id(frame)
    T_base_target = np.linalg.inv(robot.T_world_base) @ np.asarray(T_world_target, float)
    target = pin.SE3(T_base_target[:3, :3], T_base_target[:3, 3])
    starts = [] if seed is None else [robot.as_configuration(seed, "IK seed")]
    starts += list(robot.sample_uniform(rng, cfg.restarts))
    found: list[Array] = []
    for q0 in starts:
        q = _converge(robot, target, fid, q0.copy(), cfg)
        if q is None:
            continue
        q = _wrap_into_limits(robot, q)
        if not robot.within_limits(q[None])[0]:
            continue
        if checker is not None and not checker.config_valid(q[None])[0]:
            continue
        if any(np.linalg.norm(q - other) < 1e-3 for other in found):
            continue
        found.append(q)
        if len(found) >= cfg.max_solutions:
            break
    reference = starts[0] if seed is not None else None
    if reference is not None:
        found.sort(key=lambda s: float(np.linalg.norm(s - reference)))
    return found
