"""Compiled geometry: joint poses, sphere centres, and sphere-to-world and sphere-to-sphere
clearances.

Every function mirrors a numpy reference, so that the two agree to rounding, operation for
operation except where a docstring says how it differs:
:class:`~planning.kinematics.BatchKinematics` (joint chain, Rodrigues rotation),
:meth:`~planning.distance_field.CloudWorld.distance` (lattice look-up lower bound) and
:meth:`~planning.primitives.PrimitiveWorld.distance` (signed box, cylinder and sphere
distances). They read the tables ``I``, ``F`` (and the cloud's ``field``) through the offsets
``o`` of :mod:`planning.compiled.layout`, write into the scratch ``X``, and allocate nothing.

Clearances are *capped*: a function asked for values up to ``cap`` reports
``min(clearance, cap)`` and may skip, by bounding-sphere tests, whatever cannot be below the
cap. The capped value is exact by definition, so the skipping never changes an answer.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import overload

from gaide_core.types import FloatArray, IntArray
from planning.compiled.layout import (
    JOINT_PRISMATIC,
    JOINT_REVOLUTE,
    PRIM_BOX,
    PRIM_CYLINDER,
    Field,
    Off,
)
from planning.compiled.trig import REDUCED_UP_TO, sincos

# The reference kinematics' sine and cosine (planning.compiled.trig), compiled for scalars.
_sincos = njit(cache=True, inline="always")(sincos)


@njit(cache=True, inline="always")
def place_root(I: IntArray, F: FloatArray, X: FloatArray, o: Off) -> None:
    """Joint 0 (the universe) at the robot's base pose, and the sine and cosine of every
    revolute joint's angle at ``X[o.xsc + 2 j]`` (all first: they do not depend on each
    other, where each joint's pose waits for its parent's)."""
    for j in range(1, o.J):
        if I[o.jtype + j] == JOINT_REVOLUTE:
            v = X[o.xq + I[o.idxq + j]]
            if abs(v) <= REDUCED_UP_TO:
                s, c = _sincos(v)
            else:
                s, c = math.sin(v), math.cos(v)
            X[o.xsc + 2 * j] = s
            X[o.xsc + 2 * j + 1] = c
    for a in range(3):
        for b in range(3):
            X[o.xR + 3 * a + b] = F[o.base + 4 * a + b]
        X[o.xt + a] = F[o.base + 4 * a + 3]


@njit(cache=True, inline="always")
def _rotated(X: FloatArray, p: int, F: FloatArray, K: int, col: int, s: float, c: float) -> float:
    """Column ``col`` of the parent's rotation row at ``X[p:p + 3]`` times a revolute joint's
    rotation terms at ``F[K:]`` (``F_PLACE_K``), combined with the angle's sine and cosine."""
    r0, r1, r2 = X[p], X[p + 1], X[p + 2]
    return (
        (r0 * F[K + col] + r1 * F[K + 3 + col] + r2 * F[K + 6 + col])
        + c * (r0 * F[K + 9 + col] + r1 * F[K + 12 + col] + r2 * F[K + 15 + col])
        + s * (r0 * F[K + 18 + col] + r1 * F[K + 21 + col] + r2 * F[K + 24 + col])
    )


@njit(cache=True, inline="always")
def place_joint(I: IntArray, F: FloatArray, X: FloatArray, o: Off, j: int) -> None:
    """World pose of joint j >= 1 at the configuration in ``X[o.xq:]``, from its parent's
    (already placed) and its angle's sine and cosine (by :func:`place_root`): rotation at
    ``X[o.xR + 9 j]``, translation at ``X[o.xt + 3 j]``.

    A revolute joint's rotation is the parent's times P R(q), the placement's rotation times
    the rotation about the axis (the numpy reference's product), taken as the three constant
    terms of ``F_PLACE_K`` combined with cos q and sin q: the same to rounding, in 9 products
    an entry instead of 21."""
    p = o.xR + 9 * I[o.parent + j]
    tp = o.xt + 3 * I[o.parent + j]
    P = o.place_R + 9 * j
    u = o.place_t + 3 * j
    a0, a1, a2 = X[p], X[p + 1], X[p + 2]
    b0, b1, b2 = X[p + 3], X[p + 4], X[p + 5]
    c0, c1, c2 = X[p + 6], X[p + 7], X[p + 8]
    tx = X[tp] + (a0 * F[u] + a1 * F[u + 1] + a2 * F[u + 2])
    ty = X[tp + 1] + (b0 * F[u] + b1 * F[u + 1] + b2 * F[u + 2])
    tz = X[tp + 2] + (c0 * F[u] + c1 * F[u + 1] + c2 * F[u + 2])
    kind = I[o.jtype + j]
    R = o.xR + 9 * j
    if kind == JOINT_REVOLUTE:
        s, c = X[o.xsc + 2 * j], X[o.xsc + 2 * j + 1]
        K = o.place_K + 27 * j
        for row in range(3):
            for col in range(3):
                X[R + 3 * row + col] = _rotated(X, p + 3 * row, F, K, col, s, c)
    else:
        r00 = a0 * F[P] + a1 * F[P + 3] + a2 * F[P + 6]
        r01 = a0 * F[P + 1] + a1 * F[P + 4] + a2 * F[P + 7]
        r02 = a0 * F[P + 2] + a1 * F[P + 5] + a2 * F[P + 8]
        r10 = b0 * F[P] + b1 * F[P + 3] + b2 * F[P + 6]
        r11 = b0 * F[P + 1] + b1 * F[P + 4] + b2 * F[P + 7]
        r12 = b0 * F[P + 2] + b1 * F[P + 5] + b2 * F[P + 8]
        r20 = c0 * F[P] + c1 * F[P + 3] + c2 * F[P + 6]
        r21 = c0 * F[P + 1] + c1 * F[P + 4] + c2 * F[P + 7]
        r22 = c0 * F[P + 2] + c1 * F[P + 5] + c2 * F[P + 8]
        X[R], X[R + 1], X[R + 2] = r00, r01, r02
        X[R + 3], X[R + 4], X[R + 5] = r10, r11, r12
        X[R + 6], X[R + 7], X[R + 8] = r20, r21, r22
        if kind == JOINT_PRISMATIC:
            x, y, z = F[o.axis + 3 * j], F[o.axis + 3 * j + 1], F[o.axis + 3 * j + 2]
            v = X[o.xq + I[o.idxq + j]]
            tx += (r00 * x + r01 * y + r02 * z) * v
            ty += (r10 * x + r11 * y + r12 * z) * v
            tz += (r20 * x + r21 * y + r22 * z) * v
    t = o.xt + 3 * j
    X[t], X[t + 1], X[t + 2] = tx, ty, tz


@njit(cache=True, inline="always")
def _carry(F: FloatArray, X: FloatArray, o: Off, j: int, src: int, dst: int) -> None:
    """X[dst:dst + 3] = R_j @ F[src:src + 3] + t_j (a point of joint j's frame, in world)."""
    R = o.xR + 9 * j
    t = o.xt + 3 * j
    x, y, z = F[src], F[src + 1], F[src + 2]
    X[dst] = X[R] * x + X[R + 1] * y + X[R + 2] * z + X[t]
    X[dst + 1] = X[R + 3] * x + X[R + 4] * y + X[R + 5] * z + X[t + 1]
    X[dst + 2] = X[R + 6] * x + X[R + 7] * y + X[R + 8] * z + X[t + 2]


@njit(cache=True, inline="always")
def place_links_of_joint(I: IntArray, F: FloatArray, X: FloatArray, o: Off, j: int) -> None:
    """World centres of the bounding spheres and spheres of the links joint j carries."""
    for lk in range(I[o.jlstart + j], I[o.jlstart + j + 1]):
        _carry(F, X, o, j, o.lcentre + 3 * lk, o.xlc + 3 * lk)
        for i in range(I[o.lstart + lk], I[o.lstart + lk + 1]):
            s = I[o.lsph + i]
            _carry(F, X, o, j, o.slocal + 3 * s, o.xc + 3 * s)


@njit(cache=True, inline="always")
def place_all(I: IntArray, F: FloatArray, X: FloatArray, o: Off) -> None:
    """Every joint, link bound and sphere at the configuration in ``X[o.xq:]``."""
    place_root(I, F, X, o)
    place_links_of_joint(I, F, X, o, 0)
    for j in range(1, o.J):
        place_joint(I, F, X, o, j)
        place_links_of_joint(I, F, X, o, j)


@njit(cache=True, inline="always")
def cloud_distance(F: FloatArray, field: Field, o: Off, x: float, y: float, z: float) -> float:
    """Lower bound on the distance (m) from (x, y, z) to the cloud: the nearest lattice
    point's stored distance minus the way to it (the numpy reference's formula)."""
    c = o.cloud
    inv = F[c + 5]
    rx = x * inv - F[c]
    ry = y * inv - F[c + 1]
    rz = z * inv - F[c + 2]
    ix, iy, iz = np.rint(rx), np.rint(ry), np.rint(rz)
    lx, ly, lz = int(ix), int(iy), int(iz)
    if lx < 0 or lx >= o.nx or ly < 0 or ly >= o.ny or lz < 0 or lz >= o.nz:
        return F[c + 4]
    value = np.float64(field[(lx * o.ny + ly) * o.nz + lz])
    ox, oy, oz = rx - ix, ry - iy, rz - iz
    return value - (math.sqrt(ox * ox + oy * oy + oz * oz) * F[c + 3] + 1e-6)


@njit(cache=True, inline="always")
def primitive_distance(
    I: IntArray, F: FloatArray, o: Off, m: int, x: float, y: float, z: float
) -> float:
    """Signed distance (m) from (x, y, z) to primitive ``m`` (negative inside)."""
    T = o.pt + 3 * m
    dx, dy, dz = x - F[T], y - F[T + 1], z - F[T + 2]
    R = o.pR + 9 * m
    lx = F[R] * dx + F[R + 3] * dy + F[R + 6] * dz
    ly = F[R + 1] * dx + F[R + 4] * dy + F[R + 7] * dz
    lz = F[R + 2] * dx + F[R + 5] * dy + F[R + 8] * dz
    d = o.pdim + 3 * m
    kind = I[o.ptype + m]
    if kind == PRIM_BOX:
        qx, qy, qz = abs(lx) - F[d], abs(ly) - F[d + 1], abs(lz) - F[d + 2]
        ox, oy, oz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
        return math.sqrt(ox * ox + oy * oy + oz * oz) + min(max(qx, max(qy, qz)), 0.0)
    if kind == PRIM_CYLINDER:
        dr = math.hypot(lx, ly) - F[d]
        dh = abs(lz) - F[d + 1]
        return math.hypot(max(dr, 0.0), max(dh, 0.0)) + min(max(dr, dh), 0.0)
    return math.sqrt(dx * dx + dy * dy + dz * dz) - F[d]


@njit(cache=True, inline="always")
def _apart(X: FloatArray, a: int, F: FloatArray, b: int) -> float:
    """Distance between the point X[a:a + 3] and the point F[b:b + 3]."""
    dx, dy, dz = X[a] - F[b], X[a + 1] - F[b + 1], X[a + 2] - F[b + 2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


def is_cloud_lattice(field: Field) -> bool:
    """Is ``field`` a cloud's lattice (float32), not the other worlds' placeholder (float64)?

    In compiled code the answer is a constant of ``field``'s type, so each kernel is
    compiled for one world kind and the other kinds' code is dropped from it. Against one
    kernel for all worlds, branching on the kind at run time, that checks cloud
    configurations 4-18% and cloud edges 8-25% faster (five A/B pairs on the idle machine,
    the benchmark workcell, the same answers): the primitives' inlined code had cost the
    cloud look-ups their registers. The price is compile time: such a kernel compiles
    twice."""
    return bool(field.dtype == np.float32)


@overload(is_cloud_lattice, inline="always")
def _is_cloud_lattice_typed(field):  # type: ignore[no-untyped-def]
    if field.dtype == types.float32:
        return lambda field: True
    return lambda field: False


@njit(cache=True, inline="always")
def link_world_values(
    I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off, lk: int, cap: float,
    out: int,
) -> float:  # fmt: skip
    """``X[out + s]`` = min(world clearance of sphere s, cap) (m) for the spheres of link lk
    (cap for those the world ignores); returns the smallest."""
    lo, hi = I[o.lstart + lk], I[o.lstart + lk + 1]
    low = cap
    for i in range(lo, hi):
        X[out + I[o.lsph + i]] = cap
    if not I[o.lworld + lk]:
        return cap
    if is_cloud_lattice(field):
        for i in range(lo, hi):
            s = I[o.lsph + i]
            if I[o.sworld + s]:
                c = o.xc + 3 * s
                v = cloud_distance(F, field, o, X[c], X[c + 1], X[c + 2]) - F[o.wradii + s]
                v = min(v, cap)
                X[out + s] = v
                low = min(low, v)
        return low
    for m in range(o.M):  # the primitives (none in an empty world)
        if _apart(X, o.xlc + 3 * lk, F, o.pt + 3 * m) - F[o.pbound + m] - F[o.lwradius + lk] >= cap:
            continue
        for i in range(lo, hi):
            s = I[o.lsph + i]
            if not I[o.sworld + s]:
                continue
            c = o.xc + 3 * s
            if _apart(X, c, F, o.pt + 3 * m) - F[o.pbound + m] - F[o.wradii + s] >= cap:
                continue
            v = primitive_distance(I, F, o, m, X[c], X[c + 1], X[c + 2]) - F[o.wradii + s]
            if v < X[out + s]:
                X[out + s] = v
                low = min(low, v)
    return low


@njit(cache=True, inline="always")
def _gap(X: FloatArray, F: FloatArray, o: Off, i: int, j: int) -> float:
    """Distance between the centres of spheres i and j minus their radii (m)."""
    a, b = o.xc + 3 * i, o.xc + 3 * j
    dx, dy, dz = X[a] - X[b], X[a + 1] - X[b + 1], X[a + 2] - X[b + 2]
    return math.sqrt(dx * dx + dy * dy + dz * dz) - (F[o.radii + i] + F[o.radii + j])


@njit(cache=True, inline="always")
def group_gaps(
    I: IntArray, F: FloatArray, X: FloatArray, o: Off, g: int, cap: float, out: int
) -> float:
    """``X[out + p]`` = min(gap between the spheres of pair p, cap) (m; negative: overlap)
    for the pairs of link-pair group g; returns the smallest."""
    a, b = I[o.glinks + 2 * g], I[o.glinks + 2 * g + 1]
    lo, hi = I[o.gstart + g], I[o.gstart + g + 1]
    A, B = o.xlc + 3 * a, o.xlc + 3 * b
    dx, dy, dz = X[A] - X[B], X[A + 1] - X[B + 1], X[A + 2] - X[B + 2]
    bound = math.sqrt(dx * dx + dy * dy + dz * dz) - F[o.lradius + a] - F[o.lradius + b]
    if bound >= cap:
        for p in range(lo, hi):
            X[out + p] = cap
        return cap
    low = cap
    last, far = -1, False
    for p in range(lo, hi):
        i = I[o.pairs + 2 * p]
        if i != last:  # pairs come grouped by their first sphere, which is in link a
            last = i
            far = _reach_gap(X, F, o, i, b) >= cap
        v = cap if far else min(_gap(X, F, o, i, I[o.pairs + 2 * p + 1]), cap)
        X[out + p] = v
        low = min(low, v)
    return low


@njit(cache=True, inline="always")
def _reach_gap(X: FloatArray, F: FloatArray, o: Off, i: int, lk: int) -> float:
    """Lower bound (m) on the gap between sphere i and any sphere of link lk: the distance
    to the link's bounding sphere."""
    a, b = o.xc + 3 * i, o.xlc + 3 * lk
    dx, dy, dz = X[a] - X[b], X[a + 1] - X[b + 1], X[a + 2] - X[b + 2]
    return math.sqrt(dx * dx + dy * dy + dz * dz) - F[o.radii + i] - F[o.lradius + lk]


@njit(cache=True, inline="always")
def _reach_apart(X: FloatArray, F: FloatArray, o: Off, i: int, lk: int) -> bool:
    """Is sphere i apart from every sphere of link lk: its centre no nearer the link's
    bounding centre than the sum of the two radii? Squared distances, no root: a test where
    :func:`_reach_gap` is a value."""
    a, b = o.xc + 3 * i, o.xlc + 3 * lk
    dx, dy, dz = X[a] - X[b], X[a + 1] - X[b + 1], X[a + 2] - X[b + 2]
    reach = F[o.radii + i] + F[o.lradius + lk]
    return dx * dx + dy * dy + dz * dz >= reach * reach


# -- the walk's local motion bound (planning.collision: tau A_s + tau^2 B_s) -----------------


@njit(cache=True, inline="always")
def edge_slack(
    I: IntArray, F: FloatArray, X: FloatArray, o: Off, q0: FloatArray, q1: FloatArray
) -> None:
    """``X[o.xslack + s]`` = B_s of the edge q0 -> q1 (m): over a fraction tau of the edge, a
    sphere's distance from the axis of a revolute joint carrying it grows at most at the rate
    of the bounds of the joints between that joint and the sphere; B_s is half the sum of
    that rate times the joint's motion over the revolute joints."""
    for s in range(o.S):
        tail = 0.0
        acc = 0.0
        for j in range(o.J - 1, 0, -1):  # from the sphere's end of the chain
            col = I[o.idxq + j]
            w = F[o.disp + s * o.dof + col] if col >= 0 else 0.0
            if w == 0.0:
                continue
            d = abs(q1[col] - q0[col])
            if I[o.jtype + j] == JOINT_REVOLUTE:
                acc += d * tail
            tail += d * w
        X[o.xslack + s] = 0.5 * acc


@njit(cache=True, inline="always")
def axis_distance(
    F: FloatArray,
    a: int,
    R: tuple,
    t: tuple,
    c: tuple,  # type: ignore[type-arg]
) -> float:
    """Distance of the point ``c`` from the axis ``F[a:a + 3]`` (joint frame) of a joint at
    world rotation ``R`` (9, row-major) and translation ``t``."""
    x, y, z = F[a], F[a + 1], F[a + 2]
    ax = R[0] * x + R[1] * y + R[2] * z
    ay = R[3] * x + R[4] * y + R[5] * z
    az = R[6] * x + R[7] * y + R[8] * z
    dx, dy, dz = c[0] - t[0], c[1] - t[1], c[2] - t[2]
    p = dx * ax + dy * ay + dz * az
    ex, ey, ez = dx - p * ax, dy - p * ay, dz - p * az
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit(cache=True, inline="always")
def lever_term(
    I: IntArray, F: FloatArray, o: Off, q0: FloatArray, q1: FloatArray, s: int, j: int,
    R: tuple, t: tuple, c: tuple,  # type: ignore[type-arg]
) -> float:  # fmt: skip
    """Joint j's term of sphere s's lever sum (:func:`lever_sum`): the joint's motion over the
    edge q0 -> q1 times the distance of the sphere centre ``c`` from its axis, the joint at
    world rotation ``R`` and translation ``t`` (revolute), or times its bound (prismatic); 0
    where the joint does not carry the sphere."""
    col = I[o.idxq + j]
    w = F[o.disp + s * o.dof + col] if col >= 0 else 0.0
    if w == 0.0:
        return 0.0
    d = abs(q1[col] - q0[col])
    if I[o.jtype + j] != JOINT_REVOLUTE:
        return d * w
    return d * axis_distance(F, o.axis + 3 * j, R, t, c)


@njit(cache=True, inline="always")
def lever_sum(
    I: IntArray, F: FloatArray, X: FloatArray, o: Off, q0: FloatArray, q1: FloatArray, s: int
) -> float:
    """A_s (m): the sum over the joints carrying sphere s of the joint's motion over the edge
    q0 -> q1 times the sphere centre's distance from its axis at the configuration placed in
    ``X`` (revolute), or times its bound (prismatic)."""
    c = o.xc + 3 * s
    centre = (X[c], X[c + 1], X[c + 2])
    acc = 0.0
    for j in range(1, o.J):
        R, t = o.xR + 9 * j, o.xt + 3 * j
        rot = (X[R], X[R + 1], X[R + 2], X[R + 3], X[R + 4], X[R + 5], X[R + 6], X[R + 7], X[R + 8])
        acc += lever_term(I, F, o, q0, q1, s, j, rot, (X[t], X[t + 1], X[t + 2]), centre)
    return acc


@njit(cache=True, inline="always")
def local_fraction(lever: float, slack: float, room: float) -> float:
    """The largest tau with tau lever + tau^2 slack <= room (>= 0)."""
    den = lever + math.sqrt(lever * lever + 4.0 * slack * room)
    return 2.0 * room / den if den > 0.0 else np.inf
