"""Checks on the joint path handed to time parameterization; each refusal names what is wrong.

A path is (K, dof) rad with K >= 2 distinct waypoints, finite, inside the joint limits, and
every straight edge between consecutive waypoints valid for the collision checker.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from execution.limits import JointLimits
from gaide_core.errors import TimingError
from gaide_core.types import Array
from planning.collision import CollisionChecker
from planning.path_ops import MIN_STEP, first_invalid_sample


def as_path(path: npt.ArrayLike, limits: JointLimits) -> Array:
    """The path as a float (K, dof) array without repeated consecutive waypoints (closer
    than ``MIN_STEP``).

    Raises TimingError for a wrong shape, fewer than two waypoints, a non-finite value or a
    waypoint outside the joint limits (naming the waypoint, the joint and its range)."""
    try:
        arr = np.array(path, dtype=float)
    except (TypeError, ValueError) as err:
        raise TimingError(f"the path is not a numeric (K, {limits.dof}) array: {err}") from err
    if arr.size == 0:
        raise TimingError("the path is empty; need at least 2 waypoints (start and goal)")
    if arr.ndim != 2 or arr.shape[1] != limits.dof:
        raise TimingError(
            f"the path has shape {arr.shape}; expected (K, {limits.dof}) for joints "
            f"{list(limits.names)}"
        )
    if len(arr) == 1:
        raise TimingError("the path has one waypoint; need at least 2 (start and goal)")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        k, j = (int(v) for v in bad[0])
        raise TimingError(f"waypoint {k}: joint {limits.names[j]} is {arr[k, j]} (not finite)")
    out = np.argwhere((arr < limits.lower) | (arr > limits.upper))
    if out.size:
        k, j = (int(v) for v in out[0])
        raise TimingError(
            f"waypoint {k}: joint {limits.names[j]} = {arr[k, j]:.6f} rad is outside its limits "
            f"[{limits.lower[j]:.6f}, {limits.upper[j]:.6f}]"
        )
    moves = np.linalg.norm(np.diff(arr, axis=0), axis=1) > MIN_STEP
    if not moves.any():
        raise TimingError("every waypoint is the same configuration: there is no motion to time")
    keep = np.r_[True, moves]
    keep[-1] = True  # the goal itself, not a waypoint within MIN_STEP of it
    arr = arr[keep]
    if len(arr) > 2 and np.linalg.norm(arr[-1] - arr[-2]) <= MIN_STEP:
        arr = np.delete(arr, -2, axis=0)
    return arr


def check_path_valid(path: Array, checker: CollisionChecker) -> None:
    """Refuse a path with an invalid waypoint or edge (TimingError naming the edge and, from
    the checker's diagnosis, the joints or links at fault)."""
    ok = checker.config_valid(path)
    if not ok.all():
        k = int(np.flatnonzero(~ok)[0])
        raise TimingError(f"waypoint {k} is invalid: {checker.diagnose(path[k])}")
    edges = checker.edges_valid(path[:-1], path[1:])
    if edges.all():
        return
    e = int(np.flatnonzero(~edges)[0])
    raise TimingError(
        f"edge {e} (waypoint {e} -> {e + 1}) collides: {_edge_diagnosis(path[e], path[e + 1], checker)}"
    )


def _edge_diagnosis(q0: Array, q1: Array, checker: CollisionChecker) -> str:
    """The checker's diagnosis at the first invalid sample of the edge q0 -> q1."""
    hit = first_invalid_sample(checker, q0, q1)
    if hit is None:
        return "invalid between samples"
    return f"at {100 * hit[0]:.0f}% of the edge, {checker.diagnose(hit[1])}"
