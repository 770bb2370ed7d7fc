"""Simulated execution: a controller tracks a timed trajectory in PyBullet, and the achieved
joint states are logged and compared with the plan.

Before PyBullet runs, every sample of the trajectory is checked with the sphere collision
checker (the pre-check, when a checker is given): the same model the planner certified its
path with, so a trajectory a planner and timing made passes it; a file from elsewhere
may not, and the report says where. On a cloud world the pre-check and the clearance take the
true distance to the cloud where the checker's look-up (a lower bound) refuses a sample
(:func:`report_validity`).

Two controllers (``SimCfg.controller``):

- ``servo`` (default): :mod:`execution.servo`'s model of a real arm controller. PyBullet steps
  at the servo's rate (500 Hz by default, whatever the trajectory's rate); each cycle the
  trajectory is sampled, the target goes through the delay FIFO and the velocity and
  acceleration limits, and a PD loop with inverse-dynamics feed-forward sets joint torques from
  noisy encoder positions. The log holds the measured states at every cycle, from t = 0 to the
  trajectory's end plus the delay (the arm finishes the motion) plus ``settle_s``.
- ``ideal``: PyBullet's position motor at the trajectory's rate. At each control step k the
  motor receives the trajectory's sample k+1 (position target with velocity feed-forward, each
  joint's force limited to its URDF effort), the simulator steps once, and the achieved state
  is logged at ``t[k+1]``; it tracks to ~1e-6 rad: a bound on what the physics allows, not a
  model of an arm.

The tracking error is ``logged(t) - planned(t)`` at every logged time (the plan held at its
goal after its end), the delay included; the figures ``*_after_delay_*`` take the configured
delay out: ``logged(t + delay) - planned(t)``. With a checker, the arm's achieved
configurations (PyBullet's exact state) are checked too: the smallest world clearance of the
spheres (m) against the checker's margin, and how many are invalid (limits, self-collision
or a sphere within the margin).

Contacts between the robot (except the links bolted to the mount, ``world_ignored_links``) and
the scene are collected at every step. PyBullet collides the convex hulls of the link meshes,
which bulge beyond the meshes (millimetres in places): each contact with a scene of
primitives is therefore re-checked with the URDF's own concave meshes
(:class:`planning.mesh_reference.MeshReference`) at the planned configurations while it
lasted, and a run whose contacts are all hull-only says so.
"""

from __future__ import annotations

import enum
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from execution.servo import ServoCommand, ServoLoop, hermite_resample, servo_command
from execution.sim_cfg import SimCfg
from execution.sim_world import SimWorld
from execution.trajectory import TimedTrajectory
from gaide_core.errors import ExecutionError
from gaide_core.joints import JointStates
from gaide_core.types import Array
from planning.checker import true_sphere_clearance
from planning.collision import CollisionChecker, Mask
from planning.primitives import PrimitiveWorld
from planning.robot_model import RobotModel

# Times a run is lengthened for a command the limits hold back (each covers what is left).
_MAX_EXTENSIONS = 8


def report_validity(checker: CollisionChecker, Q: Array) -> tuple[Mask, Array]:
    """Validity (B,) and smallest world clearance (B,) m of configurations Q (B, dof), as the
    reports give them: the clearance is the true one
    (:func:`planning.checker.true_sphere_clearance`), and a configuration the checker refuses
    is invalid only when that clearance is below the margin or it is invalid for another
    reason (limits, self-collision). On a cloud world the checker's look-up, a lower bound,
    can read a configuration on a certified edge as inside the margin (measured on ``gaide
    demo``'s path: 20 of 2,000 samples of a certified edge at 4.0 mm against a 5 mm margin,
    the true clearance there at least 14.7 mm); on primitives nothing changes."""
    ok = checker.config_valid(Q)
    clearance = true_sphere_clearance(checker, Q).min(axis=1)
    for i in np.flatnonzero(~ok & (clearance >= checker.margin)):  # refused by the bound alone?
        why = checker.diagnose(Q[i])
        ok[i] = not (why.outside_limits or why.self_contacts)
    return ok, clearance


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
    log: JointStates  # measured states at every control cycle (t from the trajectory's start)
    error: Array  # (N, dof) rad, logged - planned at the log's times
    rms_rad: Array  # (dof,) RMS tracking error per joint
    max_rad: Array  # (dof,) largest absolute tracking error per joint
    contacts: tuple[Contact, ...]
    wall_s: float
    # the sphere pre-check: samples the checker finds invalid, and the first one's time (s)
    precheck_invalid: int | None = None  # None: no checker given
    precheck_first_s: float | None = None
    controller: str = "servo"  # SimCfg.controller
    rate_hz: float = 500.0  # Hz, the control (and log) rate
    delay_s: float = 0.0  # s, the configured command-to-motion delay
    rms_after_delay_rad: Array | None = None  # (dof,) logged(t + delay) - planned(t), RMS
    max_after_delay_rad: Array | None = None  # (dof,) the same, largest absolute
    limited_cycles: int = 0  # servo: cycles where a velocity or acceleration limit acted
    saturated_cycles: int = 0  # servo: cycles with a joint torque at its effort limit
    # The achieved configurations against the checker (None: no checker given)
    executed_min_clearance_m: float | None = None  # m, smallest sphere-world clearance (inf:
    # an empty world)
    clearance_margin_m: float | None = None  # m, the checker's margin
    executed_invalid: int | None = None  # achieved configurations the checker refuses

    @property
    def rms_all_rad(self) -> float:
        """RMS tracking error over every joint and sample (rad)."""
        return float(np.sqrt(np.mean(self.error**2)))

    @property
    def max_all_rad(self) -> float:
        """Largest absolute tracking error over every joint and sample (rad)."""
        return float(self.max_rad.max())

    @property
    def rms_after_delay_all_rad(self) -> float | None:
        """RMS over every joint of ``logged(t + delay) - planned(t)`` (rad): the tracking
        error apart from the configured delay (None: not computed)."""
        rms = self.rms_after_delay_rad
        return None if rms is None else float(np.sqrt(np.mean(rms**2)))

    @property
    def max_after_delay_all_rad(self) -> float | None:
        """Largest absolute ``logged(t + delay) - planned(t)`` over every joint (rad)."""
        return None if self.max_after_delay_rad is None else float(self.max_after_delay_rad.max())

    @property
    def clearance_ok(self) -> bool | None:
        """The executed motion keeps the checker's margin (None: no checker given)."""
        if self.executed_min_clearance_m is None or self.clearance_margin_m is None:
            return None
        return self.executed_min_clearance_m >= self.clearance_margin_m

    def summary(self) -> dict[str, Any]:
        names = self.log.names
        clearance = self.executed_min_clearance_m
        return {
            "status": self.status.value,
            "controller": self.controller,
            "rate_hz": self.rate_hz,
            "samples": len(self.log.t),
            "rms_rad": dict(zip(names, self.rms_rad.tolist(), strict=True)),
            "max_rad": dict(zip(names, self.max_rad.tolist(), strict=True)),
            "rms_all_rad": self.rms_all_rad,
            "max_all_rad": self.max_all_rad,
            "delay_s": self.delay_s,
            "rms_after_delay_all_rad": self.rms_after_delay_all_rad,
            "max_after_delay_all_rad": self.max_after_delay_all_rad,
            "limited_cycles": self.limited_cycles,
            "saturated_cycles": self.saturated_cycles,
            "contacts": [c.as_dict() for c in self.contacts],
            "wall_s": self.wall_s,
            "precheck_invalid_samples": self.precheck_invalid,
            "precheck_first_invalid_s": self.precheck_first_s,
            # JSON has no infinity: an empty world's clearance is null, its verdict true.
            "executed_min_clearance_m": clearance
            if clearance is not None and np.isfinite(clearance)
            else None,
            "clearance_margin_m": self.clearance_margin_m,
            "executed_clearance_ok": self.clearance_ok,
            "executed_invalid_samples": self.executed_invalid,
        }


@dataclass
class _Run:
    """What one controller's run leaves: the log's times, the plan at them, the command the
    joints followed (the plan delayed and limited), the logged (measured) and the true
    states, and the contacts found per step."""

    times: Array  # (n,) s
    planned: Array  # (n, dof) rad
    commanded: Array  # (n, dof) rad
    q_log: Array  # (n, dof) rad
    qd_log: Array  # (n, dof) rad/s
    q_true: Array  # (n, dof) rad
    found: dict[tuple[str, str], list[float]]  # (link, obstacle) -> first, last, steps, deepest
    delay_cycles: int = 0
    limited_cycles: int = 0
    saturated_cycles: int = 0


def _record(
    found: dict[tuple[str, str], list[float]], sim: SimWorld, ignored: tuple[str, ...], t: float
) -> None:
    """Add the robot-scene contacts of the last step (at time t, s) to ``found``."""
    for link, obstacle, distance in sim.contacts(ignored):
        rec = found.setdefault((link, obstacle), [t, t, 0, 0.0])
        rec[1] = t
        rec[2] += 1
        rec[3] = min(rec[3], distance)


def _world(robot: RobotModel, scene: dict[str, Any], cfg: SimCfg, rate_hz: float) -> SimWorld:
    return SimWorld(robot, **scene, voxel=cfg.voxel_m, rate_hz=rate_hz, gravity=cfg.gravity)


def _run_ideal(
    traj: TimedTrajectory, robot: RobotModel, scene: dict[str, Any], cfg: SimCfg
) -> _Run:
    """PyBullet's position motor at the trajectory's rate (module docstring)."""
    settle = round(cfg.settle_s * traj.rate_hz)
    times = np.concatenate([traj.t, traj.t[-1] + np.arange(1, settle + 1) / traj.rate_hz])
    targets = np.concatenate([traj.q, np.repeat(traj.q[-1:], settle, axis=0)])
    target_vel = np.concatenate([traj.qd, np.zeros((settle, robot.dof))])
    n = len(times)
    dt = 1.0 / traj.rate_hz
    q = np.empty((n, robot.dof))
    qd = np.empty((n, robot.dof))
    found: dict[tuple[str, str], list[float]] = {}
    ignored = robot.config.world_ignored_links
    with _world(robot, scene, cfg, traj.rate_hz) as sim:
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
            _record(found, sim, ignored, float(times[k]))
    return _Run(
        times=times,
        planned=targets,
        commanded=targets,
        q_log=q,
        qd_log=qd,
        q_true=q,
        found=found,
    )


def _planned_at(traj: TimedTrajectory, times: Array) -> Array:
    """The plan's positions (M, dof) at ``times`` (s), held at the goal after its end."""
    if traj.chain is not None:  # Ruckig's segments: the exact states
        return traj.chain.evaluate(np.minimum(times, traj.duration))[0]
    return hermite_resample(traj.t, traj.q, traj.qd, traj.qdd, times)  # a file's samples


def _servo_plan(
    traj: TimedTrajectory, robot: RobotModel, cfg: SimCfg
) -> tuple[Array, Array, ServoCommand]:
    """The servo's cycle times (n,) s, the plan at them and the command the joints follow.
    The run lasts until the command has reached the goal (the trajectory's end plus the
    delay, or later where a limit held the command back), then ``settle_s`` more."""
    servo = cfg.servo
    rate = servo.rate_hz
    v_max, a_max = servo.joint_limits(robot.velocity_limits, robot.acceleration_limits)
    goal = traj.q[-1]
    n_min = int(np.floor(traj.duration * rate + 1e-9)) + 1 + servo.delay_cycles
    n = n_min
    for _ in range(_MAX_EXTENSIONS):
        planned = _planned_at(traj, np.arange(n) / rate)
        command = servo_command(planned, 1.0 / rate, servo.delay_cycles, v_max, a_max)
        off = np.abs(command.q[-1] - goal)
        if np.all(off <= 1e-9) and np.all(np.abs(command.qd[-1]) <= 1e-6):
            break
        # A limited command still on its way: room to cover what is left at the limits.
        left = np.max(off / v_max + np.abs(command.qd[-1]) / a_max + v_max / a_max)
        n += int(np.ceil(left * rate)) + 1
    moving = np.flatnonzero(
        np.any(np.abs(command.q - goal) > 1e-9, axis=1) | np.any(np.abs(command.qd) > 1e-6, axis=1)
    )
    n = max(n_min, int(moving[-1]) + 2 if moving.size else 1) + round(cfg.settle_s * rate)
    times = np.arange(n) / rate
    planned = _planned_at(traj, times)
    command = servo_command(planned, 1.0 / rate, servo.delay_cycles, v_max, a_max)
    return times, planned, command


def _run_servo(
    traj: TimedTrajectory,
    robot: RobotModel,
    scene: dict[str, Any],
    cfg: SimCfg,
    rng: np.random.Generator,
) -> _Run:
    """:mod:`execution.servo`'s controller at its own rate (module docstring)."""
    servo = cfg.servo
    rate = servo.rate_hz
    times, planned, command = _servo_plan(traj, robot, cfg)
    n = len(times)
    q_log = np.empty((n, robot.dof))
    qd_log = np.empty((n, robot.dof))
    q_true = np.empty((n, robot.dof))
    found: dict[tuple[str, str], list[float]] = {}
    ignored = robot.config.world_ignored_links
    with _world(robot, scene, cfg, rate) as sim:
        sim.reset(planned[0])
        loop = ServoLoop(sim, servo, command, rng)
        q_true[0], q_log[0], qd_log[0] = loop.measure(0)
        for k in range(1, n):
            loop.drive(k - 1)
            sim.step()
            q_true[k], q_log[k], qd_log[k] = loop.measure(k)
            _record(found, sim, ignored, float(times[k]))
    return _Run(
        times=times,
        planned=planned,
        commanded=command.q,
        q_log=q_log,
        qd_log=qd_log,
        q_true=q_true,
        found=found,
        delay_cycles=servo.delay_cycles,
        limited_cycles=command.limited_cycles,
        saturated_cycles=loop.saturated_cycles,
    )


def cloud_near_motion(
    points: Array, traj: TimedTrajectory, checker: CollisionChecker, crop_m: float
) -> Array:
    """The cloud points (M, 3) within ``crop_m`` of a collision sphere of the robot anywhere
    along ``traj`` (sampled every 20 ms, where a sphere moves a few cm at most): the only ones
    the moving robot can touch, and all the simulator needs as boxes (fewer bodies, faster
    steps, so the boxes can be as fine as the run's)."""
    from scipy.spatial import cKDTree

    stride = max(1, round(0.02 * traj.rate_hz))
    Q = traj.q[::stride]
    centres = checker.sphere_centers(Q).reshape(-1, 3)
    reach = np.round(np.tile(checker.radii, len(Q)) + crop_m, 4)
    tree = cKDTree(points)
    keep = np.zeros(len(points), bool)
    for r in np.unique(reach):
        for idx in tree.query_ball_point(centres[reach == r], r):
            keep[idx] = True
    return points[keep]


def simulate(
    traj: TimedTrajectory,
    robot: RobotModel,
    *,
    primitives: PrimitiveWorld | None = None,
    cloud: Array | None = None,
    cfg: SimCfg | None = None,
    start_ns: int = 0,
    checker: CollisionChecker | None = None,
    rng: np.random.Generator | None = None,
) -> SimResult:
    """Track ``traj`` with the configured controller in a scene of primitives or a cloud
    (base frame, m; none: an empty world). ``start_ns`` is the log's absolute time of t = 0.
    With ``checker`` (of the same scene), every sample is pre-checked with the sphere
    model first and the achieved configurations are checked after (module docstring).
    ``rng`` draws the servo's encoder noise (default: seeded with ``cfg.servo.seed``)."""
    cfg = cfg or SimCfg()
    if tuple(traj.joint_names) != tuple(robot.joint_names):
        raise ExecutionError(
            f"the trajectory's joints {list(traj.joint_names)} are not the robot's "
            f"{list(robot.joint_names)} (same names, same order)"
        )
    t0 = time.perf_counter()
    precheck_invalid, precheck_first = None, None
    if checker is not None:
        bad = np.flatnonzero(~report_validity(checker, traj.q)[0])
        precheck_invalid = int(bad.size)
        precheck_first = float(traj.t[bad[0]]) if bad.size else None
    scene: dict[str, Any] = {"primitives": primitives, "cloud": cloud}
    if cfg.controller == "ideal":
        run = _run_ideal(traj, robot, scene, cfg)
        rate = traj.rate_hz
    else:
        rng = rng if rng is not None else np.random.default_rng(cfg.servo.seed)
        run = _run_servo(traj, robot, scene, cfg, rng)
        rate = cfg.servo.rate_hz
    error = run.q_log - run.planned
    d = run.delay_cycles
    after = run.q_log[d:] - run.planned[: len(run.planned) - d]
    contacts, status = _contacts(run, robot, primitives)
    clearance, margin, invalid = None, None, None
    if checker is not None:
        valid, clearances = report_validity(checker, run.q_true)
        clearance = float(clearances.min())
        margin = float(checker.margin)
        invalid = int(np.count_nonzero(~valid))
    return SimResult(
        status=status,
        log=JointStates(
            names=robot.joint_names,
            t=run.times,
            q=run.q_log,
            qd=run.qd_log,
            start_ns=start_ns,
            error=ExecutionError,
        ),
        error=error,
        rms_rad=np.sqrt(np.mean(error**2, axis=0)),
        max_rad=np.abs(error).max(axis=0),
        contacts=contacts,
        wall_s=time.perf_counter() - t0,
        precheck_invalid=precheck_invalid,
        precheck_first_s=precheck_first,
        controller=cfg.controller,
        rate_hz=rate,
        delay_s=d / rate,
        rms_after_delay_rad=np.sqrt(np.mean(after**2, axis=0)),
        max_after_delay_rad=np.abs(after).max(axis=0),
        limited_cycles=run.limited_cycles,
        saturated_cycles=run.saturated_cycles,
        executed_min_clearance_m=clearance,
        clearance_margin_m=margin,
        executed_invalid=invalid,
    )


def _contacts(
    run: _Run, robot: RobotModel, primitives: PrimitiveWorld | None
) -> tuple[tuple[Contact, ...], SimStatus]:
    """The run's contacts in the order they began, each re-checked against the URDF's meshes
    where the scene is primitives, and the run's status: clear, hull-only (every contact
    cleared by the meshes) or contact."""
    contacts = tuple(
        Contact(
            link=link,
            obstacle=obs,
            first_s=float(a),
            last_s=float(b),
            steps=int(steps),
            deepest_m=float(depth),
            mesh_confirmed=None
            if primitives is None
            else _mesh_hit(robot, primitives, run.times, run.commanded, float(a), float(b)),
        )
        for (link, obs), (a, b, steps, depth) in sorted(run.found.items(), key=lambda kv: kv[1][0])
    )
    if not contacts:
        return contacts, SimStatus.CLEAR
    if all(c.mesh_confirmed is False for c in contacts):
        return contacts, SimStatus.HULL_ONLY
    return contacts, SimStatus.CONTACT


def _mesh_hit(
    robot: RobotModel, world: PrimitiveWorld, times: Array, targets: Array, t0: float, t1: float
) -> bool:
    """True if the URDF's concave collision meshes hit ``world`` at a commanded configuration
    (the plan, delayed and limited by the servo) between t0 and t1 (s)."""
    from planning.mesh_reference import MeshReference

    inside = np.flatnonzero((times >= t0 - 1e-9) & (times <= t1 + 1e-9))
    with MeshReference(robot, world) as ref:
        return any(ref.collides(targets[k]) for k in inside)
