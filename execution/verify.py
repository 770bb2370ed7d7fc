"""Independent checks of a timed trajectory: limits at every sample, distance from its path,
collisions of its swept volume.

They re-sample the trajectory from its Ruckig segments (exact states at any time, not an
interpolation of the controller-rate samples), at 1 kHz by default.
"""

from __future__ import annotations

import numpy as np

from execution.limits import JointLimits
from execution.trajectory import TimedTrajectory
from gaide_core.errors import TimingError
from gaide_core.types import Array
from planning.collision import CollisionChecker


def resample(traj: TimedTrajectory, rate_hz: float) -> tuple[Array, Array, Array, Array, Array]:
    """Times (N,) s and position, velocity, acceleration, jerk (N, dof) every 1/rate_hz s
    over the trajectory, end included, from its Ruckig segments."""
    if traj.chain is None:
        raise TimingError("this trajectory has no Ruckig segments (read from a file?)")
    if not rate_hz > 0:
        raise TimingError(f"rate_hz must be > 0, got {rate_hz}")
    t = np.append(np.arange(0.0, traj.chain.duration, 1.0 / rate_hz), traj.chain.duration)
    return (t, *traj.chain.evaluate(t))


def limit_violations(
    traj: TimedTrajectory,
    limits: JointLimits | None = None,
    *,
    rate_hz: float = 1000.0,
    tol: float = 1e-6,
) -> int:
    """Number of samples (at ``rate_hz``) where any joint exceeds its velocity, acceleration
    or jerk limit or leaves its position limits by more than ``tol``."""
    lim = limits or traj.limits
    if lim is None:
        raise TimingError("no limits to check against")
    _, q, qd, qdd, jerk = resample(traj, rate_hz)
    bad = (
        (q < lim.lower - tol)
        | (q > lim.upper + tol)
        | (np.abs(qd) > lim.velocity + tol)
        | (np.abs(qdd) > lim.acceleration + tol)
        | (np.abs(jerk) > lim.jerk + tol)
    )
    return int(np.count_nonzero(bad.any(axis=1)))


def distance_to_path(Q: Array, path: Array) -> Array:
    """(N,) joint-space distance (rad) from each configuration of Q (N, dof) to the nearest
    point of the polyline ``path`` (K, dof)."""
    p0, p1 = path[:-1], path[1:]
    d = p1 - p0  # (E, dof)
    rel = Q[:, None, :] - p0[None]  # (N, E, dof)
    lam = np.clip(np.einsum("ned,ed->ne", rel, d) / np.einsum("ed,ed->e", d, d), 0.0, 1.0)
    gap = rel - lam[..., None] * d[None]
    return np.sqrt(np.einsum("ned,ned->ne", gap, gap)).min(axis=1)


def path_deviation(traj: TimedTrajectory, *, rate_hz: float = 1000.0) -> float:
    """Largest distance (rad) of a sample (at ``rate_hz``) from the trajectory's path."""
    if traj.path is None:
        raise TimingError("this trajectory has no path to compare with")
    _, q, *_ = resample(traj, rate_hz)
    return float(distance_to_path(q, traj.path).max())


def swept_collisions(
    traj: TimedTrajectory, checker: CollisionChecker, *, rate_hz: float = 1000.0
) -> int:
    """Number of invalid motions between consecutive samples at ``rate_hz``: each pair is
    checked as an edge (both samples and every step between them at the checker's
    resolution), the whole trajectory, straight parts included."""
    _, q, *_ = resample(traj, rate_hz)
    return int(np.count_nonzero(~checker.edges_valid(q[:-1], q[1:])))
