"""Corner cutting: a shortcut across each corner of a path, for blending.

Corner ``P[i]`` is replaced by two points on its edges, ``a = P[i] - m u_in`` and
``b = P[i] + m u_out`` with ``m = f * min(|e_in|, |e_out|)``, when the chord ``a -> b`` is
valid for the checker (full edge check); ``f`` is the largest of ``fractions`` that works,
and a corner no fraction clears is kept. The path gets shorter (triangle inequality) and
each corner's turn is split in two gentler ones, which blending passes faster. Every new
edge is either a piece of an old edge or a checked chord, so the result is as valid as the
input; with f <= 0.45 the two cuts on one edge never overlap.
"""

from __future__ import annotations

import numpy as np

from gaide_core.types import Array
from planning.collision import CollisionChecker

FRACTIONS = (0.45, 0.25, 0.12)
# Corners that turn less than this (rad) are left alone: blending passes them at speed.
MIN_TURN = np.radians(2.0)


def cut_corners(
    path: Array, checker: CollisionChecker, fractions: tuple[float, ...] = FRACTIONS
) -> Array:
    """The path (K, dof) rad with its corners cut where a checked chord allows."""
    K = len(path)
    if K < 3:
        return path
    if not all(0 < f <= 0.45 for f in fractions):
        raise ValueError(f"fractions must be in (0, 0.45], got {fractions}")
    d = np.diff(path, axis=0)
    length = np.linalg.norm(d, axis=1)
    u = d / length[:, None]
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", u[:-1], u[1:]), -1.0, 1.0))
    # A path that turns straight back has nothing to cut (both points would coincide).
    wanted = np.r_[False, (turn > MIN_TURN) & (turn < np.pi - MIN_TURN), False]
    done = np.zeros(K, bool)
    A = np.zeros_like(path)
    B = np.zeros_like(path)
    for f in fractions:
        idx = np.flatnonzero(wanted & ~done)
        if idx.size == 0:
            break
        m = f * np.minimum(length[idx - 1], length[idx])[:, None]
        a = path[idx] - m * u[idx - 1]
        b = path[idx] + m * u[idx]
        ok = checker.edges_valid(a, b)
        A[idx[ok]], B[idx[ok]] = a[ok], b[ok]
        done[idx[ok]] = True
    rows: list[Array] = [path[0]]
    for i in range(1, K - 1):
        rows.extend((A[i], B[i]) if done[i] else (path[i],))
    rows.append(path[-1])
    return np.asarray(rows)
