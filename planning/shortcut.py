"""Path post-processing in joint space: random shortcutting and resampling.

:func:`shortcut` shortens a valid path (K, dof) rad by replacing a stretch between two points
of the path (waypoints or points in the middle of an edge) with a straight edge whenever the
checker accepts it, then drops waypoints that a straight edge can skip. Every edge it adds is
checked by :meth:`~planning.collision.CollisionChecker.edges_valid`, the stretch of an
edge it keeps next to a shortcut included, so the result's edges are the input's edges
(assumed valid) or edges the checker accepted. By the triangle inequality, and because only
strictly shorter replacements are taken, the result is never longer than the input.

:func:`resample` inserts evenly spaced waypoints so that no joint-space step exceeds a bound;
the path as a curve is unchanged.
"""

from __future__ import annotations

import math
import time

import numpy as np
import numpy.typing as npt

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.planner import path_length

# A shortcut must save at least this much (rad): smaller savings are rounding noise.
_MIN_SAVING = 1e-9


def _as_path(path: Array) -> Array:
    p = np.array(path, dtype=float)  # a copy: callers keep their array
    if p.ndim != 2 or p.shape[0] < 1:
        raise PlanningError(f"a path must have shape (K, dof) with K >= 1, got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise PlanningError("the path contains NaN or inf")
    return p


def _drop_repeats(path: Array) -> Array:
    """The path without zero-length edges; the first and last waypoints are kept."""
    if len(path) < 2:
        return path
    keep = np.r_[True, np.any(path[1:] != path[:-1], axis=1)]
    keep[-1] = True
    out = path[keep]
    if len(out) > 2 and np.array_equal(out[-1], out[-2]):
        # The goal repeated its predecessor: keep the goal row itself.
        out = np.delete(out, -2, axis=0)
    return out


def resample(path: Array, max_step: float) -> Array:
    """The path (K, dof) rad with evenly spaced waypoints inserted on each edge so that no
    step is longer than ``max_step`` rad (Euclidean, joint space). The input's waypoints are
    kept, in order; zero-length edges are dropped."""
    if not (math.isfinite(max_step) and max_step > 0):
        raise PlanningError(f"max_step must be a finite length > 0 rad, got {max_step}")
    p = _drop_repeats(_as_path(path))
    if len(p) < 2:
        return p
    edges = np.diff(p, axis=0)
    lengths = np.linalg.norm(edges, axis=1)
    n = np.maximum(np.ceil(lengths / max_step), 1).astype(np.int64)  # sub-steps per edge
    edge_of = np.repeat(np.arange(len(n)), n)
    first = np.concatenate([[0], np.cumsum(n)[:-1]])
    frac = (np.arange(edge_of.size) - first[edge_of]) / n[edge_of]
    out = p[edge_of] + frac[:, None] * edges[edge_of]
    return np.concatenate([out, p[-1:]])


def _point_at(
    path: Array, arc: Array, s: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.int64], Array]:
    """For arc lengths ``s`` (N,) rad along the path: the edge index (N,) each falls on and
    the point (N, dof) there."""
    i = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, len(path) - 2)
    span = arc[i + 1] - arc[i]
    t = np.clip((s - arc[i]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    return i, path[i] + t[:, None] * (path[i + 1] - path[i])


def _shortcut_round(
    path: Array, checker: CollisionChecker, rng: np.random.Generator, batch: int
) -> Array:
    """One batched round: ``batch`` random shortcuts checked together, the best disjoint
    ones applied. Returns the new path."""
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    s = np.sort(rng.uniform(0.0, arc[-1], size=(batch, 2)), axis=1)
    ia, pa = _point_at(path, arc, s[:, 0])
    ib, pb = _point_at(path, arc, s[:, 1])
    # A shortcut within one edge saves nothing.
    saving = (s[:, 1] - s[:, 0]) - np.linalg.norm(pb - pa, axis=1)
    cand = np.flatnonzero((ib > ia) & (saving > _MIN_SAVING))
    if cand.size == 0:
        return path
    # Each shortcut adds three edges: the kept piece of edge ia up to pa, the shortcut, and
    # the kept piece of edge ib from pb. All are checked, in one batch.
    q0 = np.concatenate([path[ia[cand]], pa[cand], pb[cand]])
    q1 = np.concatenate([pa[cand], pb[cand], path[ib[cand] + 1]])
    ok = checker.edges_valid(q0, q1).reshape(3, -1).all(axis=0)
    good = cand[ok]
    if good.size == 0:
        return path
    # The largest savings first, each on edges no other taken shortcut touches.
    taken: list[int] = []
    for c in good[np.argsort(-saving[good])]:
        if all(ib[c] < ia[t] or ia[c] > ib[t] for t in taken):
            taken.append(int(c))
    taken.sort(key=lambda c: s[c, 0])
    pieces: list[Array] = []
    v = 0  # next waypoint of the old path to copy
    for c in taken:
        pieces += [path[v : ia[c] + 1], pa[c][None], pb[c][None]]
        v = int(ib[c]) + 1
    pieces.append(path[v:])
    return _drop_repeats(np.concatenate(pieces))


def remove_redundant(path: Array, checker: CollisionChecker) -> Array:
    """The path without the waypoints that a valid straight edge between their neighbours
    can skip (checked in one batch per pass, until no waypoint can go)."""
    p = _drop_repeats(_as_path(path))
    while len(p) > 2:
        skip_ok = checker.edges_valid(p[:-2], p[2:])  # skip waypoint i+1
        saving = (
            np.linalg.norm(p[1:-1] - p[:-2], axis=1)
            + np.linalg.norm(p[2:] - p[1:-1], axis=1)
            - np.linalg.norm(p[2:] - p[:-2], axis=1)
        )
        # Skips of waypoints that are not neighbours are independent.
        drop = np.zeros(len(p), bool)
        for i in np.flatnonzero(skip_ok & (saving >= -_MIN_SAVING)) + 1:
            if not drop[i - 1]:
                drop[i] = True
        if not drop.any():
            break
        p = p[~drop]
    return p


def shortcut(
    path: Array,
    checker: CollisionChecker,
    rng: np.random.Generator,
    *,
    iterations: int = 400,
    batch: int = 16,
    budget_s: float = math.inf,
    patience: int = 8,
    tolerance: float = 1e-3,
) -> Array:
    """Shorten a valid path (K, dof) rad by random shortcutting, then drop redundant
    waypoints. Returns a (K', dof) path with the same first and last rows, never longer,
    every new edge accepted by the checker.

    ``iterations`` bounds the number of candidate shortcuts drawn, ``batch`` of them per
    vectorized check; it stops earlier, converged, after ``patience`` rounds in a row that
    each shortened the path by less than ``tolerance`` rad, or when ``budget_s`` seconds of
    wall time are spent (the final waypoint removal is not counted).
    """
    if iterations < 0 or batch < 1 or patience < 1 or tolerance < 0:
        raise PlanningError(
            "need iterations >= 0, batch >= 1, patience >= 1, tolerance >= 0 rad; got "
            f"{iterations}, {batch}, {patience}, {tolerance}"
        )
    if not budget_s > 0:
        raise PlanningError(f"budget_s must be > 0 s, got {budget_s}")
    original = _as_path(path)
    p = _drop_repeats(original)
    deadline = time.perf_counter() + budget_s
    drawn, idle = 0, 0
    while len(p) > 2 and drawn < iterations and idle < patience:
        if time.perf_counter() >= deadline:
            break
        n = min(batch, iterations - drawn)
        before = path_length(p)
        p = _shortcut_round(p, checker, rng, n)
        drawn += n
        idle = 0 if before - path_length(p) >= tolerance else idle + 1
    p = remove_redundant(p, checker)
    # Rounding in the arc-length arithmetic must not make the result longer.
    return p if path_length(p) <= path_length(original) else original
