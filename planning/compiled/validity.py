"""Compiled validity of configurations and certified straight edges.

The definitions and algorithms are those of :mod:`planning.collision` (the numpy reference,
which runs the same steps; the tests hold the two to exact agreement).

A configuration is checked joint by joint: each joint's links are tested against the world
as soon as the joint is placed, so most invalid configurations cost a part of the forward
kinematics; self-collision pairs come last.

An edge is certified by conservative advancement along it (see :mod:`planning.collision`):
jumps as long as every sphere's clearance allows, resolution steps with the two-sample bound
where it does not, every sample valid, stopping at the first failure. A long edge is first
offered the dense certificate, its samples checked together
(:func:`~planning.compiled.lanes.dense_fails`, which splits each fine interval whose bound
fails into finer parts), and the walk covers each part whose bound still fails. The
reference's coarse pre-pass (every 8th resolution sample) is left out here: it never
changes the answer, and with the jumps it cost more than it saved (measured on the
benchmark workcell: 17.8k vs 20.3k edges/s with primitives, 14.7k vs 17.6k with the cloud).

Entry points (the functions without a leading underscore that take ``I, F, field``) are
called from Python; the rest are inlined into them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gaide_core.types import FloatArray, IntArray
from planning.collision import CLEARANCE_CAP, DENSE_MIN_STEPS, DENSE_UNITS, MIN_STEP_DIVISOR
from planning.compiled.geometry import (
    _reach_apart,
    edge_slack,
    group_gaps,
    lever_sum,
    link_world_values,
    local_fraction,
    place_all,
    place_joint,
    place_links_of_joint,
    place_root,
)
from planning.compiled.lanes import dense_fails
from planning.compiled.layout import Field, Off, offsets

# The planners' screen (edge_screen): the configurations at these fractions of an edge.
SCREEN_FRACTIONS = (0.5, 0.25, 0.75)


@njit(cache=True, inline="always")
def within_limits(F: FloatArray, X: FloatArray, o: Off) -> bool:
    """Is the configuration in ``X[o.xq:]`` inside the joint limits?"""
    for j in range(o.dof):
        v = X[o.xq + j]
        if not (F[o.lower + j] <= v <= F[o.upper + j]):
            return False
    return True


@njit(cache=True, inline="always")
def self_overlap(I: IntArray, F: FloatArray, X: FloatArray, o: Off) -> bool:
    """Do the spheres of any self-collision pair overlap (all spheres placed)?"""
    for g in range(o.G):
        a, b = I[o.glinks + 2 * g], I[o.glinks + 2 * g + 1]
        A, B = o.xlc + 3 * a, o.xlc + 3 * b
        dx, dy, dz = X[A] - X[B], X[A + 1] - X[B + 1], X[A + 2] - X[B + 2]
        reach = F[o.lradius + a] + F[o.lradius + b]
        if dx * dx + dy * dy + dz * dz >= reach * reach:
            continue
        last, far = -1, False
        for p in range(I[o.gstart + g], I[o.gstart + g + 1]):
            i, j = I[o.pairs + 2 * p], I[o.pairs + 2 * p + 1]
            if i != last:  # pairs come grouped by their first sphere, which is in link a
                last = i
                far = _reach_apart(X, F, o, i, b)
            if far:
                continue
            A, B = o.xc + 3 * i, o.xc + 3 * j
            dx, dy, dz = X[A] - X[B], X[A + 1] - X[B + 1], X[A + 2] - X[B + 2]
            r = F[o.radii + i] + F[o.radii + j]
            if dx * dx + dy * dy + dz * dz < r * r:
                return True
    return False


def _config_ok(
    I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off, margin: float
) -> bool:
    """Is the configuration in ``X[o.xq:]`` valid?

    A joint's links are all tested before the check returns: LLVM compiled a return from
    inside the loop over them into code that cost 140 ns more a configuration (750 vs
    610 ns in the empty world, the UR5)."""
    if not within_limits(F, X, o):
        return False
    place_root(I, F, X, o)
    hit = False
    for j in range(o.J):
        if j > 0:
            place_joint(I, F, X, o, j)
        place_links_of_joint(I, F, X, o, j)
        for lk in range(I[o.jlstart + j], I[o.jlstart + j + 1]):
            if link_world_values(I, F, field, X, o, lk, margin, o.xwv) < margin:
                hit = True
        if hit:
            return False
    return not self_overlap(I, F, X, o)


# Compiled as a function of its own: inlined into its callers, the kernels took 3.7x as long
# to compile (184 s against 49 s). Batches of configurations go through
# planning.compiled.lanes instead, many configurations at a time.
config_ok = njit(cache=True)(_config_ok)


@njit(cache=True)
def sample_values(
    I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off, margin: float, row: int
) -> bool:
    """Capped clearances (S,) at ``X[o.xwv + row S]``, gaps (P,) at ``X[o.xpv + row P]``
    and 1 at ``X[o.xgcapped + row G + g]`` where every gap of pair group g is the cap
    for the configuration in ``X[o.xq:]``; False as soon as it is found invalid (outside the
    limits, a clearance below the margin, an overlap)."""
    if not within_limits(F, X, o):
        return False
    place_all(I, F, X, o)
    wv, pv = o.xwv + row * o.S, o.xpv + row * o.P
    for lk in range(o.L):
        if link_world_values(I, F, field, X, o, lk, CLEARANCE_CAP, wv) < margin:
            return False
    for g in range(o.G):
        low = group_gaps(I, F, X, o, g, CLEARANCE_CAP, pv)
        if low < 0.0:
            return False
        X[o.xgcapped + row * o.G + g] = 1.0 if low >= CLEARANCE_CAP else 0.0
    return True


@njit(cache=True, inline="always")
def _sphere_reach(F: FloatArray, X: FloatArray, o: Off, q0: FloatArray, q1: FloatArray) -> float:
    """``X[o.xreach + s]`` = sphere s's bound (m) on its motion over the edge q0 -> q1;
    returns the largest."""
    top = 0.0
    for s in range(o.S):
        acc = 0.0
        for j in range(o.dof):
            acc += abs(q1[j] - q0[j]) * F[o.disp + s * o.dof + j]
        X[o.xreach + s] = acc
        top = max(top, acc)
    return top


@njit(cache=True, inline="always")
def edge_steps(
    I: IntArray, F: FloatArray, X: FloatArray, o: Off, q0: FloatArray, q1: FloatArray,
    resolution: float,
) -> int:  # fmt: skip
    """Sub-steps of the edge q0 -> q1 so that no sphere centre moves more than
    ``resolution`` (m) between samples. Over the whole edge, ``X[o.xreach + s]`` receives
    sphere s's bound (m) on its motion, ``X[o.xpreach + p]`` pair p's on the change of its
    centre distance, ``X[o.xgreach + g]`` the largest of pair group g's, and
    ``X[o.xslack + s]`` sphere s's slack (:func:`~planning.compiled.geometry.edge_slack`)."""
    top = _sphere_reach(F, X, o, q0, q1)
    edge_slack(I, F, X, o, q0, q1)
    for g in range(o.G):
        group_top = 0.0
        for p in range(I[o.gstart + g], I[o.gstart + g + 1]):
            acc = 0.0
            for j in range(o.dof):
                acc += abs(q1[j] - q0[j]) * F[o.pdisp + p * o.dof + j]
            X[o.xpreach + p] = acc
            group_top = max(group_top, acc)
        X[o.xgreach + g] = group_top
    return max(math.ceil(top / resolution), 1)


@njit(cache=True, inline="always")
def set_at(X: FloatArray, o: Off, q0: FloatArray, q1: FloatArray, f: float) -> None:
    """The configuration at fraction f of the edge q0 -> q1 into ``X[o.xq:]``."""
    for j in range(o.dof):
        X[o.xq + j] = q0[j] + f * (q1[j] - q0[j])


@njit(cache=True, inline="always")
def _levers(
    I: IntArray, F: FloatArray, X: FloatArray, o: Off, q0: FloatArray, q1: FloatArray,
    row: int, margin: float, dt: float,
) -> None:  # fmt: skip
    """``X[o.xlever + s]`` = A_s (:func:`~planning.compiled.geometry.lever_sum`) of each
    world-checked sphere whose two-sample bound over the next ``dt`` could fail with its
    edge-wide reach, from the sample in ``row`` (placed in ``X``); inf for the others. The
    next sample's value is at least the margin, so a sphere whose value plus the margin
    passes that bound passes it with the next value too (rounding is monotonic), and its
    local bound is not needed: :func:`_pair_bound_holds` then decides as the reference."""
    wv = o.xwv + row * o.S
    for s in range(o.S):
        if not I[o.sworld + s]:
            continue
        if X[wv + s] + margin < 2.0 * margin + X[o.xreach + s] * dt:
            X[o.xlever + s] = lever_sum(I, F, X, o, q0, q1, s)
        else:
            X[o.xlever + s] = np.inf


@njit(cache=True, inline="always")
def _safe_fraction(
    I: IntArray, F: FloatArray, X: FloatArray, o: Off, row: int, margin: float,
    q0: FloatArray, q1: FloatArray,
) -> float:  # fmt: skip
    """How far along the edge (fraction) no sphere can lose its margin nor a pair its gap,
    from the sample whose values are in ``row`` and whose placement is in ``X``. A sphere's
    local bound (:func:`~planning.compiled.geometry.lever_sum`) is computed only where its
    edge-wide bound would set the minimum so far: the larger of its two fractions counts, so
    the minimum is the same."""
    f = np.inf
    wv, pv = o.xwv + row * o.S, o.xpv + row * o.P
    for s in range(o.S):
        r = X[o.xreach + s]
        if I[o.sworld + s] and r > 0.0:
            room = X[wv + s] - margin
            edge_wide = room / r
            if edge_wide < f:
                local = local_fraction(lever_sum(I, F, X, o, q0, q1, s), X[o.xslack + s], room)
                f = min(f, max(edge_wide, local))
    for g in range(o.G):
        if X[o.xgcapped + row * o.G + g]:  # the group's pairs all at the cap: its top reach
            rr = X[o.xgreach + g]  # gives their minimum, exactly (rounding is monotonic)
            if rr > 0.0:
                f = min(f, CLEARANCE_CAP / rr)
            continue
        for p in range(I[o.gstart + g], I[o.gstart + g + 1]):
            rr = X[o.xpreach + p]
            if rr > 0.0:
                f = min(f, X[pv + p] / rr)
    return f


@njit(cache=True, inline="always")
def _pair_bound_holds(I: IntArray, X: FloatArray, o: Off, margin: float, dt: float) -> bool:
    """The two-sample bound between the samples in rows 0 and 1 (either order), ``dt`` of
    the edge apart, the spheres' lever sums (``X[o.xlever:]``) those of the earlier one."""
    for s in range(o.S):
        if not I[o.sworld + s]:
            continue
        local = dt * (X[o.xlever + s] + dt * X[o.xslack + s])
        bound = 2.0 * margin + min(X[o.xreach + s] * dt, local)
        if X[o.xwv + s] + X[o.xwv + o.S + s] < bound:
            return False
    for g in range(o.G):
        if X[o.xgcapped + g] and X[o.xgcapped + o.G + g]:  # as in _safe_fraction
            if X[o.xgreach + g] * dt > CLEARANCE_CAP + CLEARANCE_CAP:
                return False
            continue
        for p in range(I[o.gstart + g], I[o.gstart + g + 1]):
            if X[o.xpv + p] + X[o.xpv + o.P + p] < X[o.xpreach + p] * dt:
                return False
    return True


@njit(cache=True, inline="always")
def _walk(
    I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off, q0: FloatArray,
    q1: FloatArray, margin: float, n: int, t: float, end: float,
) -> bool:  # fmt: skip
    """Conservative advancement over the fractions [t, end] of the edge q0 -> q1, of n
    resolution steps (module docstring), from a sample at t."""
    step = 1.0 / n
    smallest = step / MIN_STEP_DIVISOR
    cur = 0
    set_at(X, o, q0, q1, t)
    if not sample_values(I, F, field, X, o, margin, 0):
        return False
    while t < end:
        f = _safe_fraction(I, F, X, o, cur, margin, q0, q1)
        nxt = 1 - cur
        if f >= step:  # a jump: nothing can lose its margin before t + f
            t_next = min(t + f, end)
            set_at(X, o, q0, q1, t_next)
            if not sample_values(I, F, field, X, o, margin, nxt):
                return False
        else:  # a step the two-sample bound must certify, else the jump f
            if 2.0 * f < smallest:
                return False
            t_next = min(t + min(step, 2.0 * f), end)
            _levers(I, F, X, o, q0, q1, cur, margin, t_next - t)  # before the next is placed
            set_at(X, o, q0, q1, t_next)
            if not sample_values(I, F, field, X, o, margin, nxt):
                return False
            if not _pair_bound_holds(I, X, o, margin, t_next - t):
                if f < smallest:
                    return False
                t_next = min(t + f, end)
                set_at(X, o, q0, q1, t_next)
                if not sample_values(I, F, field, X, o, margin, nxt):
                    return False
        t, cur = t_next, nxt
    return True


@njit(cache=True)
def edge_ok(
    I: IntArray,
    F: FloatArray,
    field: Field,
    X: FloatArray,
    o: Off,
    q0: FloatArray,
    q1: FloatArray,
    margin: float,
    resolution: float,
) -> bool:
    """Is the straight edge q0 -> q1 (dof,) certified (module docstring)?"""
    n = edge_steps(I, F, X, o, q0, q1, resolution)
    fails = np.empty(DENSE_UNITS, np.int64)
    if n >= DENSE_MIN_STEPS:
        m = dense_fails(I, F, field, X, o, q0, q1, margin, fails)
        if m < 0:
            return False
        last = DENSE_UNITS  # the walk covers each part the dense samples do not
    else:
        m, last = 1, 1  # the walk covers the edge
        fails[0] = 0
    i = 0
    while i < m:  # a run of neighbouring intervals in one walk, as the reference
        a = fails[i]
        b = a + 1
        while i + 1 < m and fails[i + 1] == b:
            b += 1
            i += 1
        if not _walk(I, F, field, X, o, q0, q1, margin, n, a / last, b / last):
            return False
        i += 1
    return True


@njit(cache=True, inline="always")
def edge_screen(
    I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off, q0: FloatArray,
    q1: FloatArray, margin: float,
) -> bool:  # fmt: skip
    """False when the configuration at 1/2, 1/4 or 3/4 of the edge q0 -> q1 is invalid.

    A cheap screen for the planners, before :func:`edge_ok`: three configuration checks
    (~0.6 us each) against a certification that costs tens of microseconds on a long edge
    (the dense certificate's samples, up to 64) and, on a short one near an obstacle, can creep
    along for many samples before it reaches a collision. It can only add rejections (a
    point invalid by the lattice's lower bound might lie on an edge the certification would
    pass), so a planner that screens keeps every edge it takes certified; answers to edge
    queries never screen. A finer screen (every 8th resolution step, up to 63 points) paid
    before the dense certificate; with it, it cost more than it saved (rrtc on the 20
    balanced Shelf II / III problems, best of 3: 1.58 / 2.13 ms with it, 1.20 / 1.80 without,
    the same paths).
    """
    for f in SCREEN_FRACTIONS:
        set_at(X, o, q0, q1, f)
        if not config_ok(I, F, field, X, o, margin):
            return False
    return True


# -- entry points (called from Python) ------------------------------------------------------


@njit(cache=True)
def config_valid(I, F, field, q, margin):  # type: ignore[no-untyped-def]
    """Validity of one configuration ``q`` (dof,)."""
    o = offsets(I)
    X = np.empty(o.xsize)
    for j in range(o.dof):
        X[o.xq + j] = q[j]
    return config_ok(I, F, field, X, o, margin)


@njit(cache=True)
def edge_valid(I, F, field, q0, q1, margin, resolution):  # type: ignore[no-untyped-def]
    """Is the edge q0 -> q1 (dof,) certified?"""
    o = offsets(I)
    return edge_ok(I, F, field, np.empty(o.xsize), o, q0, q1, margin, resolution)


@njit(cache=True)
def edges_valid(I, F, field, Q0, Q1, margin, resolution, out):  # type: ignore[no-untyped-def]
    """``out[e]`` = the edge Q0[e] -> Q1[e] (E, dof) is certified."""
    o = offsets(I)
    X = np.empty(o.xsize)
    for e in range(Q0.shape[0]):
        out[e] = edge_ok(I, F, field, X, o, Q0[e], Q1[e], margin, resolution)


@njit(cache=True)
def edges_screened(I, F, field, Q0, Q1, margin, out):  # type: ignore[no-untyped-def]
    """``out[e]``: does the edge Q0[e] -> Q1[e] pass the planners' :func:`edge_screen`?"""
    o = offsets(I)
    X = np.empty(o.xsize)
    for e in range(Q0.shape[0]):
        out[e] = edge_screen(I, F, field, X, o, Q0[e], Q1[e], margin)


@njit(cache=True)
def dense_certificate(I, F, field, q0, q1, margin, resolution, fails):  # type: ignore[no-untyped-def]
    """What the dense certificate finds on the edge q0 -> q1 (dof,), whatever its length:
    -1, or the number m of intervals whose bound fails, their first samples in
    ``fails[:m]`` (:func:`~planning.compiled.lanes.dense_fails`). The tests hold it to the
    reference's."""
    o = offsets(I)
    X = np.empty(o.xsize)
    edge_steps(I, F, X, o, q0, q1, resolution)
    return dense_fails(I, F, field, X, o, q0, q1, margin, fails)


@njit(cache=True)
def first_invalid_edge(I, F, field, path, margin, resolution):  # type: ignore[no-untyped-def]
    """Index of the first edge path[i] -> path[i + 1] that is not certified, or -1."""
    o = offsets(I)
    X = np.empty(o.xsize)
    for i in range(path.shape[0] - 1):
        if not edge_ok(I, F, field, X, o, path[i], path[i + 1], margin, resolution):
            return i
    return -1


@njit(cache=True)
def edge_step_counts(I, F, Q0, Q1, resolution, out):  # type: ignore[no-untyped-def]
    """``out[e]``: sub-steps of edge e (see :func:`edge_steps`)."""
    o = offsets(I)
    X = np.empty(o.xsize)
    for e in range(Q0.shape[0]):
        out[e] = edge_steps(I, F, X, o, Q0[e], Q1[e], resolution)


@njit(cache=True)
def sphere_centres(I, F, field, Q, out):  # type: ignore[no-untyped-def]
    """``out[b, s]``: world centre of sphere s at configuration ``Q[b]`` (B, dof)."""
    o = offsets(I)
    X = np.empty(o.xsize)
    for b in range(Q.shape[0]):
        for j in range(o.dof):
            X[o.xq + j] = Q[b, j]
        place_all(I, F, X, o)
        for s in range(o.S):
            for a in range(3):
                out[b, s, a] = X[o.xc + 3 * s + a]
