"""Compiled clearance penalty of a band of configurations, and its gradient, for
:func:`planning.path_ops.tighten`.

For the rows of ``P`` (n, dof), the penalty is the sum over the world-checked spheres that a
joint moves of ``max(0, need - clearance)²`` and over the self-collision pairs of
``max(0, need_self - gap)²`` (m²): zero wherever every sphere keeps ``need`` from the world
and every pair ``need_self`` from each other. (A sphere no joint moves, on the robot's base,
would add the same everywhere: it is left out.)

The distances are the checker's own (:mod:`planning.compiled.geometry`), capped at ``need``:
the bounding-sphere tests skip every primitive and pair further than that, so a row in free
space costs a fraction of a configuration check. The gradient is the chain rule through the
kinematics: a revolute joint turns a sphere's centre c by ``axis × (c - origin)`` per rad, a
prismatic one moves it by ``axis`` per metre; the world's distance is differentiated at the
centre by central differences of ``STEP`` m (a box's distance has corners and a lattice's
cells, so no closed form serves every world); a pair's gap changes along the line between
its centres.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from gaide_core.types import FloatArray, IntArray
from planning.compiled.geometry import (
    cloud_distance,
    group_gaps,
    is_cloud_lattice,
    link_world_values,
    place_all,
    primitive_distance,
)
from planning.compiled.layout import JOINT_PRISMATIC, JOINT_REVOLUTE, Field, Off, offsets

STEP = 1e-6  # m, central differences of the world's distance


@njit(cache=True, inline="always")
def _moves(F: FloatArray, o: Off, s: int) -> bool:
    """Does any joint move sphere s?"""
    for j in range(o.dof):
        if F[o.disp + s * o.dof + j] > 0.0:
            return True
    return False


@njit(cache=True, inline="always")
def _joint_of_link(I: IntArray, o: Off, lk: int) -> int:
    for j in range(o.J):
        if I[o.jlstart + j] <= lk < I[o.jlstart + j + 1]:
            return j
    return 0


@njit(cache=True, inline="always")
def _distance(I: IntArray, F: FloatArray, field: Field, o: Off, x: float, y: float, z: float) -> float:  # fmt: skip
    """Distance (m) from (x, y, z) to the world, as the checks measure it (uncapped)."""
    if is_cloud_lattice(field):
        return cloud_distance(F, field, o, x, y, z)
    d = np.inf
    for m in range(o.M):
        d = min(d, primitive_distance(I, F, o, m, x, y, z))
    return d


@njit(cache=True, inline="always")
def _push(
    I: IntArray, F: FloatArray, X: FloatArray, o: Off, s: int, j: int, n0: float, n1: float,
    n2: float, scale: float, grad: FloatArray, b: int,
) -> None:  # fmt: skip
    """``grad[b] += scale * n · (d centre of sphere s / d q)``, sphere s carried by joint j."""
    c = o.xc + 3 * s
    while j > 0:
        col = I[o.idxq + j]
        kind = I[o.jtype + j]
        if col >= 0 and kind in (JOINT_REVOLUTE, JOINT_PRISMATIC):
            R, ax = o.xR + 9 * j, o.axis + 3 * j
            w0 = X[R] * F[ax] + X[R + 1] * F[ax + 1] + X[R + 2] * F[ax + 2]
            w1 = X[R + 3] * F[ax] + X[R + 4] * F[ax + 1] + X[R + 5] * F[ax + 2]
            w2 = X[R + 6] * F[ax] + X[R + 7] * F[ax + 1] + X[R + 8] * F[ax + 2]
            if kind == JOINT_REVOLUTE:
                t = o.xt + 3 * j
                r0, r1, r2 = X[c] - X[t], X[c + 1] - X[t + 1], X[c + 2] - X[t + 2]
                w0, w1, w2 = w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0
            grad[b, col] += scale * (n0 * w0 + n1 * w1 + n2 * w2)
        j = I[o.parent + j]


@njit(cache=True)
def penalty_gradient(I, F, field, P, need, need_self, grad):  # type: ignore[no-untyped-def]
    """The summed penalty of the rows of ``P`` (n, dof) (module docstring); ``grad`` (n,
    dof) gets its derivatives."""
    o = offsets(I)
    X = np.empty(o.xsize)
    h = STEP
    total = 0.0
    for b in range(P.shape[0]):
        for j in range(o.dof):
            X[o.xq + j] = P[b, j]
            grad[b, j] = 0.0
        place_all(I, F, X, o)
        for lk in range(o.L):
            if link_world_values(I, F, field, X, o, lk, need, o.xwv) >= need:
                continue
            joint = _joint_of_link(I, o, lk)
            for i in range(I[o.lstart + lk], I[o.lstart + lk + 1]):
                s = I[o.lsph + i]
                v = need - X[o.xwv + s]
                if not (v > 0.0 and _moves(F, o, s)):
                    continue
                total += v * v
                c = o.xc + 3 * s
                x, y, z = X[c], X[c + 1], X[c + 2]
                g0 = _distance(I, F, field, o, x + h, y, z) - _distance(I, F, field, o, x - h, y, z)
                g1 = _distance(I, F, field, o, x, y + h, z) - _distance(I, F, field, o, x, y - h, z)
                g2 = _distance(I, F, field, o, x, y, z + h) - _distance(I, F, field, o, x, y, z - h)
                # d(v²)/dq = -2 v d(clearance)/dq
                _push(I, F, X, o, s, joint, g0, g1, g2, -2.0 * v / (2.0 * h), grad, b)
        for g in range(o.G):
            if group_gaps(I, F, X, o, g, need_self, o.xpv) >= need_self:
                continue
            ja = _joint_of_link(I, o, I[o.glinks + 2 * g])
            jb = _joint_of_link(I, o, I[o.glinks + 2 * g + 1])
            for p in range(I[o.gstart + g], I[o.gstart + g + 1]):
                v = need_self - X[o.xpv + p]
                if not v > 0.0:
                    continue
                total += v * v
                si, sj = I[o.pairs + 2 * p], I[o.pairs + 2 * p + 1]
                A, B = o.xc + 3 * si, o.xc + 3 * sj
                u0, u1, u2 = X[A] - X[B], X[A + 1] - X[B + 1], X[A + 2] - X[B + 2]
                norm = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
                if norm == 0.0:
                    continue
                u0, u1, u2 = u0 / norm, u1 / norm, u2 / norm
                _push(I, F, X, o, si, ja, u0, u1, u2, -2.0 * v, grad, b)
                _push(I, F, X, o, sj, jb, u0, u1, u2, 2.0 * v, grad, b)
    return total
