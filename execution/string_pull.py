"""Greedy shortcutting ("string pulling") of a checked path before it is timed.

From each kept waypoint, the farthest later waypoint that a valid straight edge reaches is
kept next. Candidate edges are first checked coarsely (every ``stride``-th of the checker's
samples, all candidates in one batch): most invalid ones fail there, at a fraction of the
cost; only a candidate that passes is checked at the checker's full resolution, and only a
fully checked edge is used. The result's edges are therefore the input's edges (checked by
the caller) or edges the checker accepted, and its waypoints are a subsequence of the
input's, so it is never longer (triangle inequality).

This is cheaper than :func:`planning.shortcut.shortcut` (random shortcuts between points
inside edges, tens of full edge checks per round), which is too slow for a time budget of
tens of milliseconds per path on long RRT edges.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from execution.path_input import MIN_STEP
from gaide_core.types import Array
from planning.collision import CollisionChecker


def _coarse_valid(
    checker: CollisionChecker, q0: Array, Q1: Array, stride: int
) -> npt.NDArray[np.bool_]:
    """(C,) False where edge q0 -> Q1[c] certainly collides (a coarse sample is invalid)."""
    Q0 = np.broadcast_to(q0, Q1.shape)
    steps = np.maximum(np.ceil(checker.edge_steps(Q0, Q1) / stride), 1).astype(np.int64)
    counts = steps + 1
    edge_of = np.repeat(np.arange(len(steps)), counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    frac = (np.arange(edge_of.size) - starts[edge_of]) / steps[edge_of]
    samples = Q0[edge_of] + frac[:, None] * (Q1 - Q0)[edge_of]
    return np.logical_and.reduceat(checker.config_valid(samples), starts)


def pull_string(
    path: Array, checker: CollisionChecker, *, stride: int = 8, max_skip: int = 16
) -> Array:
    """The path (K, dof) rad with the waypoints that valid straight edges can skip removed.

    ``path``'s own edges must be valid (they are kept where no shortcut is found).
    ``max_skip`` bounds how many waypoints one shortcut may skip (the coarse batch is
    O(K * max_skip) edges)."""
    K = len(path)
    keep = [0]
    i = 0
    while i < K - 1:
        nxt = i + 1
        cand = np.arange(min(K - 1, i + max_skip), i + 1, -1)  # farthest first
        # A path that comes back to a waypoint keeps its loop: a zero-length shortcut would
        # leave a waypoint with no motion to time.
        cand = cand[np.linalg.norm(path[cand] - path[i], axis=1) > MIN_STEP]
        if cand.size:
            coarse = _coarse_valid(checker, path[i], path[cand], stride)
            for j in cand[coarse]:
                if checker.edge_valid(path[i], path[j]):
                    nxt = int(j)
                    break
        keep.append(nxt)
        i = nxt
    return path[keep]
