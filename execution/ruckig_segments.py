"""Ruckig state-to-state segments and their exact evaluation at any time.

Ruckig's open-source version plans one state-to-state move at a time (no intermediate
waypoints offline), so a path is timed as a chain of segments, waypoint to waypoint.
:class:`SegmentPlanner` plans one segment: a straight line in joint space from rest to rest
(phase-synchronized), or a time-synchronized move between arbitrary velocities (a blend).
:class:`SegmentChain` puts segments one after another and evaluates position, velocity,
acceleration and jerk at any time from Ruckig's own profiles (no interpolation of samples).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import ruckig

from execution.limits import JointLimits
from gaide_core.types import Array

log = logging.getLogger(__name__)

_OK = (ruckig.Result.Working, ruckig.Result.Finished)


class SegmentPlanner:
    """Plans single Ruckig segments under fixed limits (one reusable Ruckig instance)."""

    def __init__(self, limits: JointLimits) -> None:
        self.limits = limits
        self.dof = limits.dof
        self._otg = ruckig.Ruckig(self.dof)
        inp = ruckig.InputParameter(self.dof)
        inp.max_velocity = limits.velocity.tolist()
        inp.max_acceleration = limits.acceleration.tolist()
        inp.max_jerk = limits.jerk.tolist()
        zeros = [0.0] * self.dof
        inp.current_acceleration = zeros
        inp.target_acceleration = zeros
        self._inp = inp
        self.calls = 0  # Ruckig calculations made (a cost figure)

    def plan(self, p0: Array, p1: Array, v0: Array, v1: Array) -> ruckig.Trajectory | None:
        """The time-optimal, time-synchronized move (all joints finish together) from
        (p0, v0) to (p1, v1), both at zero acceleration; (dof,) rad and rad/s. None when
        Ruckig finds no trajectory."""
        inp = self._inp
        inp.current_position = p0.tolist()
        inp.target_position = p1.tolist()
        inp.current_velocity = v0.tolist()
        inp.target_velocity = v1.tolist()
        inp.synchronization = ruckig.Synchronization.Time
        return self._calculate()

    def plan_line(self, p0: Array, p1: Array) -> ruckig.Trajectory | None:
        """The fastest rest-to-rest move along the straight line p0 -> p1 (rad).

        Ruckig's phase synchronization scales the slowest joint's profile onto the others,
        and falls back to time synchronization (a curve) when a scaled copy would break
        another joint's own limits (as with unequal limit ratios per joint). So each moving
        joint j gets the limits ``|d_j| * L`` with ``L`` the path-parameter limits every
        joint allows (``min_j limit_j / |d_j|``, d = p1 - p0): the joints' profiles are then
        scaled copies of one another, phase synchronization always holds, and the move is
        the straight line, within every joint's limits."""
        lim = self.limits
        d = np.abs(p1 - p0)
        moving = d > 1e-12  # rad; a smaller step is rounding noise
        if not moving.any():
            return None
        scale = {
            name: np.where(moving, d * np.min(getattr(lim, name)[moving] / d[moving]), 1.0)
            for name in ("velocity", "acceleration", "jerk")
        }
        inp = self._inp
        inp.current_position = p0.tolist()
        inp.target_position = p1.tolist()
        zeros = [0.0] * self.dof
        inp.current_velocity = zeros
        inp.target_velocity = zeros
        inp.synchronization = ruckig.Synchronization.Phase
        # Never above the joint's own limit, whatever the rounding.
        inp.max_velocity = np.minimum(scale["velocity"], lim.velocity).tolist()
        inp.max_acceleration = np.minimum(scale["acceleration"], lim.acceleration).tolist()
        inp.max_jerk = np.minimum(scale["jerk"], lim.jerk).tolist()
        try:
            return self._calculate()
        finally:
            inp.max_velocity = lim.velocity.tolist()
            inp.max_acceleration = lim.acceleration.tolist()
            inp.max_jerk = lim.jerk.tolist()

    def _calculate(self) -> ruckig.Trajectory | None:
        traj = ruckig.Trajectory(self.dof)
        self.calls += 1
        try:
            result = self._otg.calculate(self._inp, traj)
        except RuntimeError as err:  # ruckig.RuckigError: invalid input (e.g. a limit)
            log.debug("ruckig refused a segment: %s", err)
            return None
        return traj if result in _OK else None

    def duration(self, p0: Array, p1: Array, v0: Array, v1: Array) -> float:
        """Duration (s) of the time-synchronized segment; inf when there is none."""
        traj = self.plan(p0, p1, v0, v1)
        return float("inf") if traj is None else float(traj.duration)


class MoveTable:
    """One Ruckig move as arrays: per joint, the phase start times (s) and the position,
    velocity, acceleration (rad, rad/s, rad/s^2) and constant jerk (rad/s^3) each phase starts
    with, so that states at many times are a vectorized cubic instead of one
    ``Trajectory.at_time`` call each. Moves with a brake or accel pre/post phase (start or
    target states beyond the limits, which this package never plans) fall back to at_time."""

    def __init__(self, traj: ruckig.Trajectory, dof: int) -> None:
        self.traj = traj
        self.dof = dof
        profs = traj.profiles[0][:dof]
        self.exact = all(p.brake.duration == 0.0 and p.accel.duration == 0.0 for p in profs)
        self.t0 = np.array([np.concatenate([[0.0], np.cumsum(p.t)[:-1]]) for p in profs])
        self.p = np.array([p.p[:-1] for p in profs], float)  # (dof, 7)
        self.v = np.array([p.v[:-1] for p in profs], float)
        self.a = np.array([p.a[:-1] for p in profs], float)
        self.j = np.array([p.j for p in profs], float)

    def target(self) -> tuple[Array, Array, Array]:
        """The move's target position, velocity and acceleration (dof,), exactly as asked
        (``Trajectory.at_time(duration)`` integrates the phases and lands ~1e-8 rad off)."""
        profs = self.traj.profiles[0][: self.dof]
        return (
            np.array([p.pf for p in profs], float),
            np.array([p.vf for p in profs], float),
            np.array([p.af for p in profs], float),
        )

    def states(self, local: Array) -> tuple[Array, Array, Array, Array]:
        """Position, velocity, acceleration, jerk (N, dof) at local times (N,) s within the
        move."""
        n = local.size
        if not self.exact:
            rows = [self.traj.at_time(t) for t in local.tolist()]
            q, qd, qdd = (
                np.array([r[i] for r in rows], float).reshape(n, self.dof) for i in range(3)
            )
            return q, qd, qdd, np.zeros((n, self.dof))
        idx = np.stack(
            [np.searchsorted(self.t0[d], local, side="right") - 1 for d in range(self.dof)], axis=1
        )
        idx = np.clip(idx, 0, self.t0.shape[1] - 1)
        cols = np.arange(self.dof)[None, :]
        dt = local[:, None] - self.t0[cols, idx]
        p, v, a, j = self.p[cols, idx], self.v[cols, idx], self.a[cols, idx], self.j[cols, idx]
        q = p + dt * (v + dt * (a / 2.0 + dt * j / 6.0))
        qd = v + dt * (a + dt * j / 2.0)
        qdd = a + dt * j
        return q, qd, qdd, j


class SegmentChain:
    """Ruckig segments back to back: segment k runs from ``starts[k]`` for
    ``durations[k]`` seconds."""

    def __init__(self, segments: Sequence[ruckig.Trajectory], dof: int) -> None:
        if not segments:
            raise ValueError("a segment chain needs at least one segment")
        self.segments = tuple(segments)
        self.dof = dof
        self.durations = np.array([s.duration for s in self.segments], float)
        self.starts = np.concatenate([[0.0], np.cumsum(self.durations)[:-1]])
        self.duration = float(self.durations.sum())
        self._tables = [MoveTable(s, dof) for s in self.segments]

    def segment_of(self, times: Array) -> npt.NDArray[np.int64]:
        """(N,) index of the segment each time (s) falls in (the last one at the end)."""
        idx = np.searchsorted(self.starts, times, side="right") - 1
        return np.clip(idx, 0, len(self.segments) - 1).astype(np.int64)

    def evaluate(self, times: Array) -> tuple[Array, Array, Array, Array]:
        """Position, velocity, acceleration and jerk, each (N, dof), at times (N,) s from the
        chain's start; times past the end hold the final state (zero jerk)."""
        times = np.asarray(times, float)
        n = times.size
        q, qd, qdd, jerk = (np.empty((n, self.dof)) for _ in range(4))
        seg = self.segment_of(times)
        for k in np.unique(seg):
            rows = np.flatnonzero(seg == k)
            local = np.clip(times[rows] - self.starts[k], 0.0, self.durations[k])
            q[rows], qd[rows], qdd[rows], jerk[rows] = self._tables[k].states(local)
            if local[-1] >= self.durations[k]:  # the end of a move: its target state exactly
                end = rows[local >= self.durations[k]]
                q[end], qd[end], qdd[end] = self._tables[k].target()
        past = times > self.duration
        jerk[past] = 0.0
        return q, qd, qdd, jerk

    def position_extrema(self) -> tuple[Array, Array]:
        """Exact smallest and largest position (dof,) rad each joint reaches.

        Computed from the profiles (each phase's position is a cubic in time; its extrema
        are at the phase ends or where the velocity crosses zero). Ruckig's own
        ``Trajectory.position_extrema`` (0.19) misses a velocity zero inside a
        constant-acceleration phase, so it is not used."""
        lo = np.full(self.dof, np.inf)
        hi = np.full(self.dof, -np.inf)
        for traj in self.segments:
            for d, prof in enumerate(traj.profiles[0][: self.dof]):
                a, b = profile_extrema(prof)
                lo[d] = min(lo[d], a)
                hi[d] = max(hi[d], b)
        return lo, hi


def profile_extrema(prof: ruckig.Profile) -> tuple[float, float]:
    """Smallest and largest position (rad) of one joint's profile."""
    ps, vs, as_ = prof.p, prof.v, prof.a
    lo = hi = float(prof.pf)
    for k, (dt, j) in enumerate(zip(prof.t, prof.j, strict=True)):
        p0, v0, a0 = ps[k], vs[k], as_[k]
        lo, hi = min(lo, p0), max(hi, p0)
        if dt <= 0.0:
            continue
        # Velocity zeros inside the phase: v0 + a0 t + j t^2 / 2 = 0 on (0, dt).
        if j != 0.0:
            disc = a0 * a0 - 2.0 * j * v0
            if disc < 0.0:
                continue
            root = math.sqrt(disc)
            candidates: tuple[float, ...] = ((-a0 - root) / j, (-a0 + root) / j)
        elif a0 != 0.0:
            candidates = (-v0 / a0,)
        else:
            continue
        for t in candidates:
            if 0.0 < t < dt:
                p = p0 + v0 * t + 0.5 * a0 * t * t + j * t * t * t / 6.0
                lo, hi = min(lo, p), max(hi, p)
    return lo, hi
