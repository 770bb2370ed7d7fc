"""Waypoint velocities for blending: the trajectory passes each inner waypoint without
stopping, with a velocity chosen so that the segments join and the total time is short.

Each inner waypoint i gets a velocity along the bisector of its two edge directions,
``w_i = u_in + u_out`` (normalized): the tangent of a smooth curve through the waypoint,
which bulges to the outside of the corner, away from the obstacle a path usually bends
around. Its speed ``s_i`` is chosen among ``levels`` fractions of the largest speed the
velocity limits allow along ``w_i`` (denser near zero, where short segments need small
speeds): first one common fraction for all waypoints, then coordinate descent on the total
duration (a waypoint's speed changes only its two adjacent segments, one Ruckig call each),
then single joints of each velocity are scaled where that helps.
A speed cap per waypoint holds the start and goal at rest (cap 0) and slows blends that
collided.
"""

from __future__ import annotations

import numpy as np

from execution.ruckig_segments import SegmentPlanner
from gaide_core.types import Array

# Keep chosen velocities strictly inside the limits: Ruckig refuses a target velocity that
# exceeds its limit by a rounding error.
_INSIDE = 1.0 - 1e-9


def speed_fractions(levels: int) -> Array:
    """``levels`` fractions in [0, 1], 0 and 1 included, denser near 0."""
    return np.linspace(0.0, 1.0, levels) ** 1.5


def bisector_directions(path: Array, velocity_limits: Array) -> tuple[Array, Array]:
    """Unit bisector directions (K, dof) at the inner waypoints (zero rows at the ends and
    where the path turns straight back) and the largest speed (K,) rad/s along each that
    keeps every joint within its velocity limit."""
    K, dof = path.shape
    d = np.diff(path, axis=0)
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    W = np.zeros((K, dof))
    smax = np.zeros(K)
    if K > 2:
        w = u[:-1] + u[1:]
        n = np.linalg.norm(w, axis=1)
        ok = n > 1e-9
        W[1:-1][ok] = w[ok] / n[ok, None]
        with np.errstate(divide="ignore"):
            ratio = velocity_limits / np.abs(W[1:-1])
        smax[1:-1] = np.where(ok, ratio.min(axis=1), 0.0) * _INSIDE
    return W, smax


def choose_velocities(
    path: Array,
    planner: SegmentPlanner,
    *,
    cap: Array,
    levels: int = 12,
    sweeps: int = 3,
    initial: Array | None = None,
) -> tuple[Array, Array]:
    """Waypoint velocities (K, dof) rad/s and the resulting segment durations (K-1,) s.

    ``cap`` (K,) bounds each waypoint's speed (rad/s, joint-space norm; 0: at rest).
    ``initial`` (K, dof) is a starting guess (the previous choice after a fallback)."""
    K = len(path)
    W, smax = bisector_directions(path, planner.limits.velocity)
    smax = np.minimum(smax, cap)
    V = np.zeros_like(path) if initial is None else initial.copy()
    over = np.linalg.norm(V, axis=1) > smax
    V[over] = smax[over, None] * W[over]
    fractions = speed_fractions(levels)
    free = np.flatnonzero(smax > 0)

    def durations(V: Array) -> Array:
        return np.array(
            [planner.duration(path[k], path[k + 1], V[k], V[k + 1]) for k in range(K - 1)]
        )

    T = durations(V)
    if initial is None and free.size:
        # One common fraction first: coordinate descent alone, from rest, stalls where
        # raising one waypoint's speed only pays once its neighbours rise too.
        for f in fractions[1:]:
            trial = V.copy()
            trial[free] = f * smax[free, None] * W[free]
            Tt = durations(trial)
            if Tt.sum() < T.sum():
                V, T = trial, Tt
    for _ in range(sweeps):
        improved = False
        for i in free.tolist():
            best = (T[i - 1] + T[i], V[i], T[i - 1], T[i])
            for f in fractions:
                v = f * smax[i] * W[i]
                if np.array_equal(v, V[i]):
                    continue
                a = planner.duration(path[i - 1], path[i], V[i - 1], v)
                if a >= best[0]:
                    continue
                b = planner.duration(path[i], path[i + 1], v, V[i + 1])
                if a + b < best[0] - 1e-9:
                    best = (a + b, v, a, b)
            if best[1] is not V[i]:
                V[i], T[i - 1], T[i] = best[1], best[2], best[3]
                improved = True
        if not improved:
            break
    _refine_joints(path, planner, cap, V, T, free.tolist())
    return V, T


# Per-joint factors tried on a waypoint velocity after the bisector search.
_JOINT_FACTORS = (0.0, 0.5, 1.5)


def _refine_joints(
    path: Array, planner: SegmentPlanner, cap: Array, V: Array, T: Array, free: list[int]
) -> None:
    """Scale single joints of each free waypoint's velocity (0, 0.5, 1.5 x) where that
    shortens its two segments, within the joint's limit and the waypoint's cap; two passes.
    Updates V and T in place. (A joint that turns back at a waypoint is often best at rest
    there, which no common direction expresses.)"""
    vmax = planner.limits.velocity * _INSIDE
    for _ in range(2):
        for i in free:
            for j in range(path.shape[1]):
                if V[i, j] == 0.0:
                    continue
                for factor in _JOINT_FACTORS:
                    v = V[i].copy()
                    v[j] = np.clip(factor * v[j], -vmax[j], vmax[j])
                    if np.linalg.norm(v) > cap[i]:
                        continue
                    a = planner.duration(path[i - 1], path[i], V[i - 1], v)
                    if a >= T[i - 1] + T[i]:
                        continue
                    b = planner.duration(path[i], path[i + 1], v, V[i + 1])
                    if a + b < T[i - 1] + T[i] - 1e-9:
                        V[i], T[i - 1], T[i] = v, a, b
