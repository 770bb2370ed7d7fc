"""Simulated execution: PyBullet's position controller tracks a timed trajectory at its rate,
and the achieved joint states are logged and compared with the plan.

Before PyBullet runs, every sample of the trajectory is checked with the sphere collision
checker (the pre-check, when a checker is given): the same model the planner certified its
path with, so a trajectory a planner and timing made passes it; a file from elsewhere
may not, and the report says where.

The robot starts at rest at the trajectory's first sample. At each control step k (period
``1 / rate_hz``, PyBullet's time step) the controller receives the trajectory's sample k+1
(position target with velocity feed-forward, each joint's force limited to its URDF effort),
the simulator steps once, and the achieved state is logged at ``t[k+1]``: the tracking error
is ``achieved(t) - planned(t)`` at every sample. Gravity, the links' inertia and the effort
limits are what keep the achieved state off the plan. Contacts between the robot (except the links
bolted to the mount, ``world_ignored_links``) and the scene are collected at every step.
PyBullet collides the convex hulls of the link meshes, which bulge beyond the meshes
(millimetres in places): each contact with a scene of primitives is therefore re-checked
with the URDF's own concave meshes (:class:`planning.mesh_reference.MeshReference`) at the
planned configurations while it lasted, and a run whose contacts are all hull-only says so.
"""

from __future__ import annotations

import enum
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from execution.sim_cfg import SimCfg
from execution.sim_world import SimWorld
from execution.trajectory import TimedTrajectory
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.primitives import PrimitiveWorld
from planning.robot_model import RobotModel


class SimStatus(enum.Enum):
    CLEAR = "clear"  # no contact between the robot and the scene
    CONTACT = "contact"  # the robot touched the scene (see ``contacts``)
    # Only PyBullet's convex hulls of the link meshes touched the scene; the URDF's own
    # (concave) meshes at the planned configurations clear it.
    HULL_ONLY = "hull_only"


@dataclass(frozen=True)
class Contact:
    """Robot link ``link`` touching scene body ``obstacle`` from ``first_s`` to ``last_s``."""

    link: str
    obstacle: str
    first_s: float  # s, trajectory time
    last_s: float
    steps: int  # control steps with the contact
    deepest_m: float  # m, most negative contact distance (penetration)
    # True: the URDF's meshes at the planned configurations of those steps hit the scene too;
    # False: they clear it (PyBullet's convex hull of the link is what touched); None: not
    # checked (a cloud scene).
    mesh_confirmed: bool | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "link": self.link,
            "obstacle": self.obstacle,
            "first_s": self.first_s,
            "last_s": self.last_s,
            "steps": self.steps,
            "deepest_m": self.deepest_m,
            "mesh_confirmed": self.mesh_confirmed,
        }


@dataclass(frozen=True, kw_only=True)
class SimResult:
    status: SimStatus
    log: JointStates  # achieved states at every sample (t from the trajectory's start)
    error: Array  # (N, dof) rad, achieved - planned
    rms_rad: Array  # (dof,) RMS tracking error per joint
    max_rad: Array  # (dof,) largest absolute tracking error per joint
    contacts: tuple[Contact, ...]
    wall_s: float
    # the sphere pre-check: samples the checker finds invalid, and the first one's time (s)
    precheck_invalid: int | None = None  # None: no checker given
    precheck_first_s: float | None = None

    @property
    def rms_all_rad(self) -> float:
        """RMS tracking error over every joint and sample (rad)."""
        return float(np.sqrt(np.mean(self.error**2)))

    def summary(self) -> dict[str, Any]:
        names = self.log.names
        return {
            "status": self.status.value,
            "samples": len(self.log.t),
            "rms_rad": dict(zip(names, self.rms_rad.tolist(), strict=True)),
            "max_rad": dict(zip(names, self.max_rad.tolist(), strict=True)),
            "rms_all_rad": self.rms_all_rad,
            "max_all_rad": float(self.max_rad.max()),
            "contacts": [c.as_dict() for c in self.contacts],
            "wall_s": self.wall_s,
            "precheck_invalid_samples": self.precheck_invalid,
            "precheck_first_invalid_s": self.precheck_first_s,
        }


def simulate(
    traj: TimedTrajectory,
    robot: RobotModel,
    *,
    primitives: PrimitiveWorld | None = None,
    cloud: Array | None = None,
    cfg: SimCfg | None = None,
    start_ns: int = 0,
    checker: CollisionChecker | None = None,
) -> SimResult:
    """Track ``traj`` with PyBullet's position control in a scene of primitives or a cloud
    (base frame, m; none: an empty world). ``start_ns`` is the log's absolute time of t = 0.
    With ``checker`` (of the same scene), every sample is pre-checked with the sphere
    model first (module docstring)."""
    cfg = cfg or SimCfg()
    if tuple(traj.joint_names) != tuple(robot.joint_names):
        raise ExecutionError(
            f"the trajectory's joints {list(traj.joint_names)} are not the robot's "
            f"{list(robot.joint_names)} (same names, same order)"
        )
    t0 = time.perf_counter()
    precheck_invalid, precheck_first = None, None
    if checker is not None:
        bad = np.flatnonzero(~checker.config_valid(traj.q))
        precheck_invalid = int(bad.size)
        precheck_first = float(traj.t[bad[0]]) if bad.size else None
    settle = round(cfg.settle_s * traj.rate_hz)
    times = np.concatenate([traj.t, traj.t[-1] + np.arange(1, settle + 1) / traj.rate_hz])
    targets = np.concatenate([traj.q, np.repeat(traj.q[-1:], settle, axis=0)])
    target_vel = np.concatenate([traj.qd, np.zeros((settle, robot.dof))])
    n = len(times)
    dt = 1.0 / traj.rate_hz
    q = np.empty((n, robot.dof))
    qd = np.empty((n, robot.dof))
    found: dict[
        tuple[str, str], list[float]
    ] = {}  # (link, obstacle) -> first, last, steps, deepest
    ignored = robot.config.world_ignored_links
    with SimWorld(
        robot,
        primitives=primitives,
        cloud=cloud,
        voxel=cfg.voxel_m,
        rate_hz=traj.rate_hz,
        gravity=cfg.gravity,
    ) as sim:
        sim.reset(targets[0])
        q[0], qd[0] = sim.state()
        for k in range(1, n):
            # PyBullet's motor sets the next velocity to velocity_gain * (qd* - qd) + qd +
            # position_gain * (q* - q) / dt: with unit gains a step ends at q* + qd* dt, so the
            # target is moved back by qd* dt for the step to end on the planned sample.
            sim.command(
                targets[k] - dt * target_vel[k],
                target_vel[k],
                cfg.position_gain,
                cfg.velocity_gain,
            )
            sim.step()
            q[k], qd[k] = sim.state()
            for link, obstacle, distance in sim.contacts(ignored):
                rec = found.setdefault((link, obstacle), [times[k], times[k], 0, 0.0])
                rec[1] = times[k]
                rec[2] += 1
                rec[3] = min(rec[3], distance)
    error = q - targets
    contacts = tuple(
        Contact(
            link=link,
            obstacle=obs,
            first_s=float(a),
            last_s=float(b),
            steps=int(n),
            deepest_m=float(d),
            mesh_confirmed=None
            if primitives is None
            else _mesh_hit(robot, primitives, times, targets, float(a), float(b)),
        )
        for (link, obs), (a, b, n, d) in sorted(found.items(), key=lambda kv: kv[1][0])
    )
    if not contacts:
        status = SimStatus.CLEAR
    elif all(c.mesh_confirmed is False for c in contacts):
        status = SimStatus.HULL_ONLY
    else:
        status = SimStatus.CONTACT
    return SimResult(
        status=status,
        log=JointStates(
            names=robot.joint_names, t=times, q=q, qd=qd, start_ns=start_ns, error=ExecutionError
        ),
        error=error,
        rms_rad=np.sqrt(np.mean(error**2, axis=0)),
        max_rad=np.abs(error).max(axis=0),
        contacts=contacts,
        wall_s=time.perf_counter() - t0,
        precheck_invalid=precheck_invalid,
        precheck_first_s=precheck_first,
    )


def _mesh_hit(
    robot: RobotModel, world: PrimitiveWorld, times: Array, targets: Array, t0: float, t1: float
) -> bool:
    """True if the URDF's concave collision meshes hit ``world`` at a planned configuration
    between t0 and t1 (s)."""
    from planning.mesh_reference import MeshReference

    inside = np.flatnonzero((times >= t0 - 1e-9) & (times <= t1 + 1e-9))
    with MeshReference(robot, world) as ref:
        return any(ref.collides(targets[k]) for k in inside)
