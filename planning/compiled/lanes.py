"""Batches of configurations checked together, one configuration per SIMD lane.

:func:`configs_valid` answers what :func:`~planning.compiled.validity.config_ok` answers
for each configuration of a batch (the tests hold them to exact agreement), by another
route. The scalar check places one configuration joint by joint and stops at its first
collision; here :data:`LANES` configurations go through each step together, in loops over
the lanes that LLVM compiles to vector instructions (AVX-512 or AVX2, whichever the CPU
has). Each lane runs the scalar check's arithmetic, operation for operation, and makes its
decisions: a bounding-sphere test skips a primitive or a self pair exactly where the scalar
check skips it. No lane stops early; a whole step is skipped when no lane needs it.

Why a second formulation instead of one check: a single configuration (a planner's sample,
an edge's point) has no lanes to fill, and there the scalar check's early exits win, while
a batch (the benchmark, the data generator, the neural planner's proposals) is bound by
arithmetic and look-ups that vectorize. Measured on the UR5, 10,000 uniform configurations
(``gaide bench collision`` and the same batch in the empty world, the 2-core machine, the
scalar loop and the lanes run back to back): 1.2 -> 2.7-2.9M configurations/s against 20
primitives, 2.2 -> 4.0-4.6M against a 50,000-point cloud, 2.0 -> 9.0M in the empty world.

:func:`dense_fails` puts the same steps to a second use: a long edge's evenly spaced
samples, one per lane (where it pays, every DENSE_STRIDE-th first, then those of the
intervals that need them, then those of the fine intervals split), with their capped
clearances and self-pair gaps, for the dense
certificate of :mod:`planning.collision` (the walk takes its samples one after the other,
each placed by the last; these are placed in advance, so they can go together).

How the loops are written so that they vectorize: numba cannot tell LLVM that two arrays do
not overlap, so LLVM checks it at run time before a vector loop, and gives up beyond a
handful of such checks. Each loop over the lanes therefore writes one array and reads at
most eight; a joint's pose is twelve loops, one per entry, each from the parent's row and
constants (a revolute joint's entry: 9 products with its three rotation terms,
``F_PLACE_K``). Boolean masks are
combined with ``&`` and ``|``, never ``and``/``or``, which would branch per lane.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from gaide_core.types import BoolArray, FloatArray, IntArray
from planning.collision import (
    CLEARANCE_CAP,
    DENSE_SAMPLES,
    DENSE_SPLIT,
    DENSE_STRIDE,
    DENSE_UNITS,
    coarse_first,
)
from planning.compiled.geometry import is_cloud_lattice, lever_term
from planning.compiled.layout import (
    BLOCK,
    JOINT_PRISMATIC,
    JOINT_REVOLUTE,
    PRIM_BOX,
    PRIM_CYLINDER,
    Field,
    Off,
    offsets,
)
from planning.compiled.trig import REDUCED_UP_TO, sincos

# Configurations per pass: 8 AVX-512 vectors of float64, and the whole pass's poses, spheres
# and values (~140 kB for the UR5) stay in the 1 MB L2 cache.
LANES = 64

_sincos = njit(cache=True, inline="always")(sincos)
_coarse_first = njit(cache=True, inline="always")(coarse_first)
# m: what a pass's world cap (_world_cap) keeps above the bound it must pass, far above the
# rounding of values of centimetres
CAP_SLACK = 1e-9

# A cloud look-up's per-lane values (_cloud_values): nearest value's index, its block's, the
# way to it, the block's minimum, the value, and whether it is read.
Scratch = namedtuple("Scratch", ["cell", "block", "way", "low", "fine", "look"])
Vec3 = tuple[float, float, float]


@njit(cache=True, inline="always")
def _scratch(K: int) -> Scratch:
    """A cloud look-up's per-lane values for K lanes."""
    return Scratch(np.empty(K, np.int64), np.empty(K, np.int64), np.empty(K), np.empty(K),
                   np.empty(K), np.empty(K, np.bool_))  # fmt: skip


@njit(cache=True, inline="always")
def _angles(I: IntArray, o: Off, qv: FloatArray, sn: FloatArray, cs: FloatArray, nj: int,
            n: int) -> None:  # fmt: skip
    """``sn[j, k]``, ``cs[j, k]``: sine and cosine of revolute joint j < nj's angle in lane
    k (as :func:`~planning.compiled.geometry.place_root`: the library beyond the reduction's
    range)."""
    for j in range(1, nj):
        if I[o.jtype + j] != JOINT_REVOLUTE:
            continue
        v, s_, c_ = qv[I[o.idxq + j]], sn[j], cs[j]
        far = False
        for k in range(n):
            s, c = _sincos(v[k])
            s_[k] = s
            c_[k] = c
            far |= not (abs(v[k]) <= REDUCED_UP_TO)
        if far:
            for k in range(n):
                if not (abs(v[k]) <= REDUCED_UP_TO):
                    s_[k] = math.sin(v[k])
                    c_[k] = math.cos(v[k])


@njit(cache=True, inline="always")
def _rotation_entry(A0: FloatArray, A1: FloatArray, A2: FloatArray, F: FloatArray, K: int,
                    col: int, sn: FloatArray, cs: FloatArray, out: FloatArray,
                    n: int) -> None:  # fmt: skip
    """``out[k]``: column ``col`` of one row of a revolute joint's world rotation in lane k:
    the parent's row (A0, A1, A2) times the joint's three rotation terms at ``F[K:]``
    (``F_PLACE_K``), combined with the angle's cosine and sine, as in
    :func:`~planning.compiled.geometry.place_joint`."""
    a = (F[K + col], F[K + 3 + col], F[K + 6 + col])
    b = (F[K + 9 + col], F[K + 12 + col], F[K + 15 + col])
    c = (F[K + 18 + col], F[K + 21 + col], F[K + 24 + col])
    for k in range(n):
        r0, r1, r2 = A0[k], A1[k], A2[k]
        out[k] = (
            (r0 * a[0] + r1 * a[1] + r2 * a[2])
            + cs[k] * (r0 * b[0] + r1 * b[1] + r2 * b[2])
            + sn[k] * (r0 * c[0] + r1 * c[1] + r2 * c[2])
        )


@njit(cache=True, inline="always")
def _place_joints(I: IntArray, F: FloatArray, o: Off, qv: FloatArray, sn: FloatArray,
                  cs: FloatArray, W: FloatArray, nj: int, n: int) -> None:  # fmt: skip
    """``W[j, 0:9, k]``: joint j's world rotation (row-major), ``W[j, 9:12, k]`` its
    translation, in lane k, for the joints j < nj (a joint's parent comes before it):
    :func:`~planning.compiled.geometry.place_root` and
    :func:`~planning.compiled.geometry.place_joint`, lane by lane."""
    for e in range(9):
        W[0, e, :n] = F[o.base + 4 * (e // 3) + e % 3]
    for a in range(3):
        W[0, 9 + a, :n] = F[o.base + 4 * a + 3]
    for j in range(1, nj):
        A, O = W[I[o.parent + j]], W[j]
        P, u = o.place_R + 9 * j, o.place_t + 3 * j
        # the placement's columns: r_{row, col} = A_row . (F[P + col], F[P + 3 + col], ...)
        f0 = (F[P], F[P + 3], F[P + 6])
        f1 = (F[P + 1], F[P + 4], F[P + 7])
        f2 = (F[P + 2], F[P + 5], F[P + 8])
        u0, u1, u2 = F[u], F[u + 1], F[u + 2]
        x, y, z = F[o.axis + 3 * j], F[o.axis + 3 * j + 1], F[o.axis + 3 * j + 2]
        kind = I[o.jtype + j]
        for r in range(3):
            A0, A1, A2 = A[3 * r], A[3 * r + 1], A[3 * r + 2]
            if kind == JOINT_REVOLUTE:
                for col in range(3):
                    _rotation_entry(A0, A1, A2, F, o.place_K + 27 * j, col, sn[j], cs[j],
                                    O[3 * r + col], n)  # fmt: skip
            else:
                for col, f in enumerate((f0, f1, f2)):
                    out = O[3 * r + col]
                    for k in range(n):
                        out[k] = A0[k] * f[0] + A1[k] * f[1] + A2[k] * f[2]
            Tp, To = A[9 + r], O[9 + r]
            if kind == JOINT_PRISMATIC:
                v = qv[I[o.idxq + j]]
                for k in range(n):
                    a0, a1, a2 = A0[k], A1[k], A2[k]
                    t = Tp[k] + (a0 * u0 + a1 * u1 + a2 * u2)
                    r0 = a0 * f0[0] + a1 * f0[1] + a2 * f0[2]
                    r1 = a0 * f1[0] + a1 * f1[1] + a2 * f1[2]
                    r2 = a0 * f2[0] + a1 * f2[1] + a2 * f2[2]
                    To[k] = t + (r0 * x + r1 * y + r2 * z) * v[k]
            else:
                for k in range(n):
                    To[k] = Tp[k] + (A0[k] * u0 + A1[k] * u1 + A2[k] * u2)


@njit(cache=True, inline="always")
def _carry(W: FloatArray, j: int, F: FloatArray, src: int, out: FloatArray, n: int) -> None:
    """``out[a, k]`` = joint j's pose in lane k applied to the point F[src:src + 3] (as
    :func:`~planning.compiled.geometry._carry`)."""
    x, y, z = F[src], F[src + 1], F[src + 2]
    pose = W[j]
    for a in range(3):
        R0, R1, R2, T, o_ = pose[3 * a], pose[3 * a + 1], pose[3 * a + 2], pose[9 + a], out[a]
        for k in range(n):
            o_[k] = R0[k] * x + R1[k] * y + R2[k] * z + T[k]


@njit(cache=True, inline="always")
def _place_spheres(I: IntArray, F: FloatArray, o: Off, W: FloatArray, C: FloatArray,
                   LC: FloatArray, nj: int, n: int) -> None:  # fmt: skip
    """``C[s, a, k]``: sphere s's world centre, ``LC[l, a, k]`` link l's bounding centre, for
    the links of the joints j < nj."""
    for j in range(nj):
        for lk in range(I[o.jlstart + j], I[o.jlstart + j + 1]):
            _carry(W, j, F, o.lcentre + 3 * lk, LC[lk], n)
            for i in range(I[o.lstart + lk], I[o.lstart + lk + 1]):
                s = I[o.lsph + i]
                _carry(W, j, F, o.slocal + 3 * s, C[s], n)


@njit(cache=True, inline="always")
def _cloud_values(F: FloatArray, field: Field, o: Off, Cs: FloatArray, wr: float, cap: float,
                  out: FloatArray, bad: BoolArray, S: Scratch, n: int) -> None:  # fmt: skip
    """``out[k]`` = min(the cloud clearance of the sphere at ``Cs[:, k]`` (world radius wr),
    cap), by :func:`~planning.compiled.geometry.cloud_distance` in lane k; lanes already
    in ``bad`` get a value, not their own.

    The smallest value of the nearest value's block is read first: where it clears the
    sphere by the cap, so does the value (``x - way`` and then ``- wr`` round monotonically
    in x), and the large lattice is not read. Lanes already found invalid do not read it
    either. The look-ups are loops of their own: LLVM leaves a loop that reads an array at
    computed indices unvectorized here (it judges the CPU's gathers too slow), and would the
    arithmetic around it too."""
    c = o.cloud
    ox_, oy_, oz_, scale, band, inv = F[c], F[c + 1], F[c + 2], F[c + 3], F[c + 4], F[c + 5]
    nx, ny, nz = o.nx, o.ny, o.nz
    by, bz = (ny + BLOCK - 1) // BLOCK, (nz + BLOCK - 1) // BLOCK
    minima = nx * ny * nz
    X0, X1, X2 = Cs[0], Cs[1], Cs[2]
    cell, block, way, low, fine, look = S.cell, S.block, S.way, S.low, S.fine, S.look
    for k in range(n):  # the nearest value's index, -1 outside the lattice
        ix = np.rint(X0[k] * inv - ox_)
        iy = np.rint(X1[k] * inv - oy_)
        iz = np.rint(X2[k] * inv - oz_)
        inside = (ix >= 0.0) & (ix < nx) & (iy >= 0.0) & (iy < ny) & (iz >= 0.0) & (iz < nz)
        cell[k] = (int(ix) * ny + int(iy)) * nz + int(iz) if inside else -1
    for k in range(n):  # its block's index among the minima (0 outside: never used)
        lx = int(np.rint(X0[k] * inv - ox_))
        ly = int(np.rint(X1[k] * inv - oy_))
        lz = int(np.rint(X2[k] * inv - oz_))
        b = ((lx // BLOCK) * by + ly // BLOCK) * bz + lz // BLOCK
        block[k] = minima + b if cell[k] >= 0 else 0
    for k in range(n):  # the way from the point to its nearest value, plus the slack
        rx, ry, rz = X0[k] * inv - ox_, X1[k] * inv - oy_, X2[k] * inv - oz_
        dx, dy, dz = rx - np.rint(rx), ry - np.rint(ry), rz - np.rint(rz)
        way[k] = math.sqrt(dx * dx + dy * dy + dz * dz) * scale + 1e-6
    for k in range(n):
        low[k] = field[block[k]]
    for k in range(n):
        look[k] = (cell[k] >= 0) & (not bad[k]) & (low[k] - way[k] - wr < cap)
    for k in range(n):
        fine[k] = field[cell[k] if look[k] else 0]
    for k in range(n):
        value = fine[k] if look[k] else low[k]
        d = value - way[k] if cell[k] >= 0 else band
        out[k] = min(d - wr, cap)


@njit(cache=True, inline="always")
def _ball_values(I: IntArray, F: FloatArray, o: Off, m: int, X0: FloatArray, X1: FloatArray,
                 X2: FloatArray, wr: float, cap: float, need: BoolArray, out: FloatArray,
                 n: int) -> None:  # fmt: skip
    """``out[k]`` = min(``out[k]``, the clearance from primitive m of the ball of radius wr
    at (X0[k], X1[k], X2[k])) in the lanes that ``need`` it and whose ball is within cap of
    the primitive's bounding sphere (as
    :func:`~planning.compiled.geometry.link_world_values`)."""
    T = o.pt + 3 * m
    px, py, pz, pb = F[T], F[T + 1], F[T + 2], F[o.pbound + m]
    R, d = o.pR + 9 * m, o.pdim + 3 * m
    kind = I[o.ptype + m]
    if kind == PRIM_BOX:
        for k in range(n):
            dx, dy, dz = X0[k] - px, X1[k] - py, X2[k] - pz
            reach = math.sqrt(dx * dx + dy * dy + dz * dz) - pb - wr
            lx = F[R] * dx + F[R + 3] * dy + F[R + 6] * dz
            ly = F[R + 1] * dx + F[R + 4] * dy + F[R + 7] * dz
            lz = F[R + 2] * dx + F[R + 5] * dy + F[R + 8] * dz
            qx, qy, qz = abs(lx) - F[d], abs(ly) - F[d + 1], abs(lz) - F[d + 2]
            ex, ey, ez = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
            dist = math.sqrt(ex * ex + ey * ey + ez * ez) + min(max(qx, max(qy, qz)), 0.0)
            take = need[k] & (not (reach >= cap))
            out[k] = min(out[k], dist - wr if take else np.inf)
    elif kind == PRIM_CYLINDER:  # math.hypot: a library call, these lanes run one by one
        for k in range(n):
            if not need[k]:
                continue
            dx, dy, dz = X0[k] - px, X1[k] - py, X2[k] - pz
            if math.sqrt(dx * dx + dy * dy + dz * dz) - pb - wr >= cap:
                continue
            lx = F[R] * dx + F[R + 3] * dy + F[R + 6] * dz
            ly = F[R + 1] * dx + F[R + 4] * dy + F[R + 7] * dz
            lz = F[R + 2] * dx + F[R + 5] * dy + F[R + 8] * dz
            dr = math.hypot(lx, ly) - F[d]
            dh = abs(lz) - F[d + 1]
            dist = math.hypot(max(dr, 0.0), max(dh, 0.0)) + min(max(dr, dh), 0.0)
            out[k] = min(out[k], dist - wr)
    else:
        for k in range(n):
            dx, dy, dz = X0[k] - px, X1[k] - py, X2[k] - pz
            reach = math.sqrt(dx * dx + dy * dy + dz * dz) - pb - wr
            dist = math.sqrt(dx * dx + dy * dy + dz * dz) - F[d]
            take = need[k] & (not (reach >= cap))
            out[k] = min(out[k], dist - wr if take else np.inf)


@njit(cache=True, inline="always")
def _near_primitive(F: FloatArray, o: Off, m: int, L0: FloatArray, L1: FloatArray,
                    L2: FloatArray, lwr: float, cap: float, bad: BoolArray, need: BoolArray,
                    n: int) -> bool:  # fmt: skip
    """``need[k]``: lane k is valid so far and its link's bounding ball (centre L, world
    radius lwr) is within cap of primitive m's bounding sphere; True if any lane is."""
    T = o.pt + 3 * m
    px, py, pz, pb = F[T], F[T + 1], F[T + 2], F[o.pbound + m]
    any_need = False
    for k in range(n):
        dx, dy, dz = L0[k] - px, L1[k] - py, L2[k] - pz
        near = not (math.sqrt(dx * dx + dy * dy + dz * dz) - pb - lwr >= cap)
        need[k] = near & (not bad[k])
        any_need |= need[k]
    return any_need


@njit(cache=True, inline="always")
def _primitive_values(I: IntArray, F: FloatArray, o: Off, lk: int, C: FloatArray,
                      LC: FloatArray, cap: float, V: FloatArray, bad: BoolArray,
                      need: BoolArray, prims: BoolArray, n: int) -> None:  # fmt: skip
    """``V[s, k]`` = min(the clearance of world sphere s of link lk from the primitives,
    cap) in lane k, with :func:`~planning.compiled.geometry.link_world_values`'
    bounding-sphere skips (lanes already in ``bad`` get a value, not their own), from the
    primitives m with ``prims[m]`` (the others are known to be at least cap from the
    link's bounding ball in every lane still valid: see :func:`_link_clear`)."""
    lo, hi = I[o.lstart + lk], I[o.lstart + lk + 1]
    for i in range(lo, hi):
        V[I[o.lsph + i], :n] = cap
    lwr = F[o.lwradius + lk]
    for m in range(o.M):
        if not prims[m]:
            continue
        if not _near_primitive(F, o, m, LC[lk, 0], LC[lk, 1], LC[lk, 2], lwr, cap, bad, need, n):
            continue
        for i in range(lo, hi):
            s = I[o.lsph + i]
            if I[o.sworld + s]:
                _ball_values(I, F, o, m, C[s, 0], C[s, 1], C[s, 2], F[o.wradii + s], cap, need,
                             V[s], n)  # fmt: skip


@njit(cache=True, inline="always")
def _link_clear(I: IntArray, F: FloatArray, o: Off, X: FloatArray, lk: int, LC: FloatArray,
                dt: FloatArray, cap: float, margin: float, bad: BoolArray, need: BoolArray,
                low: FloatArray, one: FloatArray, prims: BoolArray, n: int) -> bool:  # fmt: skip
    """Does the bounding ball of link lk (its world radius) keep from the primitives a
    clearance >= margin in every lane, and the two-sample bound with the largest reach of
    the link's world spheres (``X[o.xreach + s]``) between every two neighbouring lanes
    (lanes k and k + 1 ``dt[k]`` of the edge apart)? Then each of its world spheres, inside
    the ball, does both (exact distances are 1-Lipschitz), and their own values cannot
    change the dense certificate's answer. (Not for cloud worlds: a lattice's lower bounds
    at two points need not differ by at most the points' distance.)

    ``prims[m]``: some lane still valid has the ball within cap of primitive m (its own
    value from m, in ``one``, below the cap); where none has, neither has any of the link's
    spheres, whose values from m would all be the cap."""
    lwr = F[o.lwradius + lk]
    L0, L1, L2 = LC[lk, 0], LC[lk, 1], LC[lk, 2]
    low[:n] = cap
    for m in range(o.M):
        prims[m] = False
        if not _near_primitive(F, o, m, L0, L1, L2, lwr, cap, bad, need, n):
            continue
        one[:n] = cap
        _ball_values(I, F, o, m, L0, L1, L2, lwr, cap, need, one, n)
        near = False
        for k in range(n):
            near |= one[k] < cap
            low[k] = min(low[k], one[k])
        prims[m] = near
    reach = 0.0
    for i in range(I[o.lstart + lk], I[o.lstart + lk + 1]):
        s = I[o.lsph + i]
        if I[o.sworld + s]:
            reach = max(reach, X[o.xreach + s])
    clear = True
    for k in range(n):
        clear &= (low[k] >= margin) | bad[k]
    for k in range(n - 1):
        clear &= low[k] + low[k + 1] >= 2.0 * margin + reach * dt[k]
    return clear


@njit(cache=True, inline="always")
def _link_world_values(I: IntArray, F: FloatArray, field: Field, o: Off, lk: int,
                       C: FloatArray, LC: FloatArray, cap: float, margin: float, V: FloatArray,
                       bad: BoolArray, need: BoolArray, prims: BoolArray, S: Scratch,
                       n: int) -> None:  # fmt: skip
    """``V[s, k]`` = min(world clearance of world sphere s of link lk in lane k, cap), and
    ``bad[k] |=`` one is below the margin (a link the world checks, in a world with
    something in it)."""
    if is_cloud_lattice(field):
        for i in range(I[o.lstart + lk], I[o.lstart + lk + 1]):
            s = I[o.lsph + i]
            if I[o.sworld + s]:
                _cloud_values(F, field, o, C[s], F[o.wradii + s], cap, V[s], bad, S, n)
    else:
        _primitive_values(I, F, o, lk, C, LC, cap, V, bad, need, prims, n)
    for i in range(I[o.lstart + lk], I[o.lstart + lk + 1]):
        s = I[o.lsph + i]
        if I[o.sworld + s]:
            Vs = V[s]
            for k in range(n):
                bad[k] |= Vs[k] < margin


@njit(cache=True, inline="always")
def _world_values(I: IntArray, F: FloatArray, field: Field, o: Off, C: FloatArray,
                  LC: FloatArray, cap: float, margin: float, V: FloatArray, bad: BoolArray,
                  need: BoolArray, prims: BoolArray, S: Scratch, lk0: int, lk1: int,
                  n: int) -> None:  # fmt: skip
    """``V[s, k]`` = min(world clearance of world sphere s in lane k, cap) (as
    :func:`~planning.compiled.validity.sample_values`), and ``bad[k] |=`` one is below
    the margin, for the spheres of the links lk0 <= lk < lk1. With cap = margin, only that
    comparison is exact (a configuration check)."""
    if o.M == 0 and not is_cloud_lattice(field):  # the empty world
        V[:, :n] = cap
        return
    for lk in range(lk0, lk1):
        if I[o.lworld + lk]:
            _link_world_values(I, F, field, o, lk, C, LC, cap, margin, V, bad, need, prims, S,
                               n)  # fmt: skip


@njit(cache=True, inline="always")
def _self_hits(I: IntArray, F: FloatArray, o: Off, C: FloatArray, LC: FloatArray,
               bad: BoolArray, open_: BoolArray, near: BoolArray, n: int) -> None:  # fmt: skip
    """``bad[k] |=`` two spheres of a self-collision pair overlap in lane k, with
    :func:`~planning.compiled.validity.self_overlap`'s bounding-sphere skips."""
    for g in range(o.G):
        a, b = I[o.glinks + 2 * g], I[o.glinks + 2 * g + 1]
        reach = F[o.lradius + a] + F[o.lradius + b]
        rr = reach * reach
        A0, A1, A2, B0, B1, B2 = LC[a, 0], LC[a, 1], LC[a, 2], LC[b, 0], LC[b, 1], LC[b, 2]
        any_near = False
        for k in range(n):
            dx, dy, dz = A0[k] - B0[k], A1[k] - B1[k], A2[k] - B2[k]
            near[k] = (not (dx * dx + dy * dy + dz * dz >= rr)) & (not bad[k])
            any_near |= near[k]
        if not any_near:
            continue
        lrb = F[o.lradius + b]
        last, any_open = -1, False
        for p in range(I[o.gstart + g], I[o.gstart + g + 1]):
            i, j = I[o.pairs + 2 * p], I[o.pairs + 2 * p + 1]
            I0, I1, I2 = C[i, 0], C[i, 1], C[i, 2]
            if i != last:  # pairs come grouped by their first sphere, which is in link a
                last, any_open = i, False
                reach = F[o.radii + i] + lrb
                rr = reach * reach
                for k in range(n):
                    dx, dy, dz = I0[k] - B0[k], I1[k] - B1[k], I2[k] - B2[k]
                    open_[k] = near[k] & (not (dx * dx + dy * dy + dz * dz >= rr))
                    any_open |= open_[k]
            if not any_open:
                continue
            r = F[o.radii + i] + F[o.radii + j]
            r2 = r * r
            J0, J1, J2 = C[j, 0], C[j, 1], C[j, 2]
            for k in range(n):
                dx, dy, dz = I0[k] - J0[k], I1[k] - J1[k], I2[k] - J2[k]
                bad[k] |= open_[k] & (dx * dx + dy * dy + dz * dz < r2)


@njit(cache=True, inline="always")
def _self_values(I: IntArray, F: FloatArray, o: Off, X: FloatArray, C: FloatArray,
                 LC: FloatArray, cap: float, dt: FloatArray, G: FloatArray, passes: BoolArray,
                 bad: BoolArray, low: FloatArray, n: int) -> None:  # fmt: skip
    """``G[p, k]`` = min(gap of self pair p in lane k, cap) and ``bad[k] |=`` a gap is
    negative (an overlap), as :func:`~planning.compiled.geometry.group_gaps`, for the pair
    groups that need them. A group ``passes[g]`` (its gaps not written) when the gap of its
    links' bounding spheres, which no pair's gap is below, is >= 0 in every lane and
    satisfies the two-sample bound with the group's largest reach (``X[o.xgreach + g]``)
    between every two neighbouring lanes (``dt[k]`` apart): then every pair of the group
    does both, and writing their gaps could not change the dense certificate's answer."""
    for g in range(o.G):
        a, b = I[o.glinks + 2 * g], I[o.glinks + 2 * g + 1]
        la, lb = F[o.lradius + a], F[o.lradius + b]
        A0, A1, A2, B0, B1, B2 = LC[a, 0], LC[a, 1], LC[a, 2], LC[b, 0], LC[b, 1], LC[b, 2]
        apart = True
        for k in range(n):
            dx, dy, dz = A0[k] - B0[k], A1[k] - B1[k], A2[k] - B2[k]
            low[k] = min(math.sqrt(dx * dx + dy * dy + dz * dz) - la - lb, cap)
            apart &= low[k] >= 0.0
        reach = X[o.xgreach + g]
        for k in range(n - 1):
            apart &= low[k] + low[k + 1] >= reach * dt[k]
        passes[g] = apart
        if apart:
            continue
        for p in range(I[o.gstart + g], I[o.gstart + g + 1]):
            i, j = I[o.pairs + 2 * p], I[o.pairs + 2 * p + 1]
            r = F[o.radii + i] + F[o.radii + j]
            I0, I1, I2, J0, J1, J2 = C[i, 0], C[i, 1], C[i, 2], C[j, 0], C[j, 1], C[j, 2]
            Gp = G[p]
            for k in range(n):
                dx, dy, dz = I0[k] - J0[k], I1[k] - J1[k], I2[k] - J2[k]
                Gp[k] = math.sqrt(dx * dx + dy * dy + dz * dz) - r
            for k in range(n):
                bad[k] |= Gp[k] < 0.0
                Gp[k] = min(Gp[k], cap)


@njit(cache=True, inline="always")
def _dense_values(I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off,
                  q0: FloatArray, q1: FloatArray, margin: float, t: FloatArray, dt: FloatArray,
                  qv: FloatArray, sn: FloatArray, cs: FloatArray, W: FloatArray, C: FloatArray,
                  LC: FloatArray, V: FloatArray, G: FloatArray, bad: BoolArray, need: BoolArray,
                  passes: BoolArray, clear: BoolArray, S: Scratch, low: FloatArray,
                  one: FloatArray, prims: BoolArray, cap: float, n: int) -> bool:  # fmt: skip
    """The clearances ``V`` (capped at ``cap``) and gaps ``G`` (at CLEARANCE_CAP) of the
    edge's samples at fractions ``t[:n]``; False as soon as one sample is found invalid.
    The values of a link's spheres are left out where the link's bounding ball passes among
    primitives (``clear``, :func:`_link_clear`), and the gaps of a pair group where its two
    links' balls pass (``passes``, :func:`_self_values`), between the neighbours ``dt``
    names (lanes k and k + 1 are ``dt[k]`` of the edge apart, 0 where they are not
    neighbouring samples)."""
    bad[:n] = False
    for j in range(o.dof):
        lo, hi, v, a, d = F[o.lower + j], F[o.upper + j], qv[j], q0[j], q1[j] - q0[j]
        for k in range(n):
            v[k] = a + t[k] * d
            bad[k] |= not ((lo <= v[k]) & (v[k] <= hi))
    for k in range(n):  # a sample outside the limits refuses the edge
        if bad[k]:
            return False
    _angles(I, o, qv, sn, cs, o.J, n)
    _place_joints(I, F, o, qv, sn, cs, W, o.J, n)
    _place_spheres(I, F, o, W, C, LC, o.J, n)
    # the world values (_world_values), none for a link whose bounding ball already passes
    # among the primitives (clear: every link in the empty world, unless its reach is long)
    clear[:] = False
    for lk in range(o.L):
        if not I[o.lworld + lk]:
            continue
        if not is_cloud_lattice(field) and _link_clear(
            I, F, o, X, lk, LC, dt, cap, margin, bad, need, low, one, prims, n
        ):
            clear[lk] = True
            continue
        _link_world_values(I, F, field, o, lk, C, LC, cap, margin, V, bad, need, prims, S, n)
        # a sample in collision refuses the edge: no more links
        hit = False
        for k in range(n):
            hit |= bad[k]
        if hit:
            return False
    _self_values(I, F, o, X, C, LC, CLEARANCE_CAP, dt, G, passes, bad, low, n)
    for k in range(n):
        if bad[k]:
            return False
    return True


@njit(cache=True, inline="always")
def _lane_lever_sum(I: IntArray, F: FloatArray, o: Off, W: FloatArray, C: FloatArray,
                    q0: FloatArray, q1: FloatArray, s: int, k: int) -> float:  # fmt: skip
    """A_s of :func:`~planning.compiled.geometry.lever_sum` at the configuration of lane k."""
    centre = (C[s, 0, k], C[s, 1, k], C[s, 2, k])
    acc = 0.0
    for j in range(1, o.J):
        rot = (W[j, 0, k], W[j, 1, k], W[j, 2, k], W[j, 3, k], W[j, 4, k], W[j, 5, k],
               W[j, 6, k], W[j, 7, k], W[j, 8, k])  # fmt: skip
        t = (W[j, 9, k], W[j, 10, k], W[j, 11, k])
        acc += lever_term(I, F, o, q0, q1, s, j, rot, t, centre)
    return acc


@njit(cache=True, inline="always")
def _bound_fails(I: IntArray, F: FloatArray, X: FloatArray, o: Off, margin: float,
                 V: FloatArray, G: FloatArray, W: FloatArray, C: FloatArray, q0: FloatArray,
                 q1: FloatArray, clear: BoolArray, passes: BoolArray, dt: float,
                 k: int) -> bool:  # fmt: skip
    """Do lanes k and k + 1 (neighbouring samples, ``dt`` of the edge apart) fail the
    two-sample bound (the links and pair groups left out pass it)? A sphere's motion is
    bounded by the smaller of its edge-wide reach and its local bound from lane k
    (:mod:`planning.collision`), the latter computed only where the former fails."""
    for lk in range(o.L):
        if clear[lk]:
            continue
        for i in range(I[o.lstart + lk], I[o.lstart + lk + 1]):
            s = I[o.lsph + i]
            if not I[o.sworld + s]:
                continue
            both = V[s, k] + V[s, k + 1]
            edge_wide = X[o.xreach + s] * dt
            if both >= 2.0 * margin + edge_wide:
                continue
            lever = _lane_lever_sum(I, F, o, W, C, q0, q1, s, k)
            if both < 2.0 * margin + min(edge_wide, dt * (lever + dt * X[o.xslack + s])):
                return True
    for g in range(o.G):
        if passes[g]:
            continue
        for p in range(I[o.gstart + g], I[o.gstart + g + 1]):
            if G[p, k] + G[p, k + 1] < X[o.xpreach + p] * dt:
                return True
    return False


@njit(cache=True, inline="always")
def _world_cap(top: float, margin: float, dt: FloatArray, n: int) -> float:
    """The cap of a pass's world values: where every sphere's reach times the largest
    neighbour distance ``dt`` is below CLEARANCE_CAP - margin, the least cap above
    margin + that bound. A valid sample's value is >= margin, so a neighbour's value capped
    there passes the two-sample bound (:func:`_bound_fails`) whenever the uncapped one
    does, as it does at CLEARANCE_CAP: the answers are the reference's. A smaller cap lets
    more primitives, and more of a cloud's lattice, go unread (their values would be the
    cap)."""
    far = 0.0
    for k in range(n - 1):
        far = max(far, dt[k])
    return min(CLEARANCE_CAP, margin + top * far + CAP_SLACK)


@njit(cache=True)
def dense_fails(I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off,
                q0: FloatArray, q1: FloatArray, margin: float, fails: IntArray) -> int:  # fmt: skip
    """The dense certificate of the edge q0 -> q1 (:mod:`planning.collision`): -1 if one of
    its samples is invalid, else the number m of parts (DENSE_UNITS to the edge) whose
    samples k and k + 1 fail the two-sample bound, their k ascending in ``fails[:m]`` (none:
    the edge is certified; ``fails`` holds DENSE_UNITS). The reach of every sphere and pair
    over the edge, and every sphere's slack, are in ``X`` (by
    :func:`~planning.compiled.validity.edge_steps`).

    One pass of all the samples, one per lane, or (:func:`~planning.collision.coarse_first`)
    two: every DENSE_STRIDE-th sample, then the samples of the coarse intervals that fail
    the bound (ends included: the lanes of a run of such intervals are neighbouring samples,
    and the last of one run and the first of the next are not, ``dt`` 0). Then the fine
    intervals that fail are split DENSE_SPLIT ways, eight of them (64 lanes) a pass. Each
    pass leaves out the values of links and pair groups whose bounding balls already pass
    (:func:`_dense_values`); each is a lower bound of the values it stands for, so it can
    only pass where they all pass, and the answer is the reference's, which computes every
    value. On rrtc's raw edges, vertex-reduction skips and
    shortcut candidates of Box, Bins and the shelves, 48% of the world spheres' values and
    56% of the pair gaps not skipped as far apart are left out (simulated in numpy, one pass
    of the 64 samples)."""
    K = DENSE_SAMPLES
    top = 0.0
    for s in range(o.S):
        top = max(top, X[o.xreach + s])
    c = DENSE_STRIDE if _coarse_first(top, margin) else 1
    qv = np.empty((o.dof, K))
    sn, cs = np.zeros((o.J, K)), np.zeros((o.J, K))
    W = np.empty((o.J, 12, K))
    C, LC = np.empty((o.S, 3, K)), np.empty((o.L, 3, K))
    V, G = np.empty((o.S, K)), np.empty((o.P, K))
    bad, need, passes = np.zeros(K, np.bool_), np.empty(K, np.bool_), np.empty(o.G, np.bool_)
    clear = np.empty(o.L, np.bool_)
    S = _scratch(K)
    t, dt, low, idx = np.empty(K), np.zeros(K), np.empty(K), np.empty(K, np.int64)
    one, prims = np.empty(K), np.empty(max(o.M, 1), np.bool_)
    ks = np.empty(K, np.int64)  # the fine intervals whose bound fails
    lanes = DENSE_SPLIT + 1  # a fine interval's samples when split, ends included
    per = K // lanes  # split intervals per pass
    n = (K - 1) // c + 1
    for k in range(n):
        idx[k] = c * k
    # 0: the coarse samples; 1: every sample, or the failing coarse intervals' ones; 2: the
    # failing fine intervals split, `per` at a time (one call site each for the two inlined
    # pass functions: a second doubled the kernels' compile time)
    stage = 0 if c > 1 else 1
    m = done = out = 0
    while True:
        if stage < 2:
            for k in range(n):
                t[k] = idx[k] / (K - 1)
            for k in range(n - 1):  # neighbours: every coarse pair, consecutive fine samples
                near = stage == 0 or idx[k + 1] == idx[k] + 1
                dt[k] = t[k + 1] - t[k] if near else 0.0
        else:
            n = 0
            for i in range(done, min(m, done + per)):
                for j in range(lanes):
                    t[n] = (DENSE_SPLIT * ks[i] + j) / DENSE_UNITS
                    n += 1
            for k in range(n - 1):  # neighbours within an interval
                dt[k] = t[k + 1] - t[k] if k % lanes != DENSE_SPLIT else 0.0
        if not _dense_values(I, F, field, X, o, q0, q1, margin, t, dt, qv, sn, cs, W, C, LC,
                             V, G, bad, need, passes, clear, S, low, one, prims,
                             _world_cap(top, margin, dt, n), n):  # fmt: skip
            return -1
        r, last = 0, -1
        for k in range(n - 1):
            if dt[k] == 0.0 or not _bound_fails(I, F, X, o, margin, V, G, W, C, q0, q1,
                                                clear, passes, dt[k], k):  # fmt: skip
                continue
            if stage == 0:  # the failing coarse interval's samples, in runs
                for f in range(c * k if last != c * k else c * k + 1, c * (k + 1) + 1):
                    idx[r] = f  # (this stage reads no index)
                    r += 1
                last = c * (k + 1)
            elif stage == 1:
                ks[m] = idx[k]
                m += 1
            else:
                fails[out] = DENSE_SPLIT * ks[done + k // lanes] + k % lanes
                out += 1
        if stage == 0:
            if r == 0:
                return 0
            n, stage = r, 1
        elif stage == 1:
            if m == 0:
                return 0
            stage = 2
        else:
            done += per
            if done >= m:
                return out


@njit(cache=True, inline="always")
def _first_stage_joints(I: IntArray, o: Off) -> int:
    """The joints whose links :func:`configs_valid` checks against the world first: the
    fewest from the base whose links hold at least a third of the world spheres."""
    total = 0
    for s in range(o.S):
        total += I[o.sworld + s]
    held = 0
    for j in range(o.J):
        for lk in range(I[o.jlstart + j], I[o.jlstart + j + 1]):
            for i in range(I[o.lstart + lk], I[o.lstart + lk + 1]):
                held += I[o.sworld + I[o.lsph + i]]
        if 3 * held >= total:
            return j + 1
    return o.J


@njit(cache=True, inline="always")
def _load(I: IntArray, F: FloatArray, o: Off, Q: FloatArray, rows: IntArray, qv: FloatArray,
          bad: BoolArray, n: int) -> None:  # fmt: skip
    """``qv[j, k]`` = ``Q[rows[k], j]``; ``bad[k]``: the row is outside the joint limits."""
    bad[:n] = False
    for j in range(o.dof):
        lo, hi, v = F[o.lower + j], F[o.upper + j], qv[j]
        for k in range(n):
            v[k] = Q[rows[k], j]
            bad[k] |= not ((lo <= v[k]) & (v[k] <= hi))


@njit(cache=True)
def configs_valid(I, F, field, Q, margin, out):  # type: ignore[no-untyped-def]
    """``out[b]`` = validity of configuration ``Q[b]`` (B, dof), LANES at a time, in two
    stages. The first places the joints nearest the base and checks their links against
    the world; the second takes the configurations still valid, LANES at a time, and checks
    the other links and the self pairs. The links near the base meet the table or floor in
    most invalid configurations (in the benchmark's 10,000 uniform ones, 56% fail on the
    UR5's shoulder and upper arm, whose 10 spheres are a third of its 31), and a pass's
    cost is the same whether its lanes are valid or not: gathering the survivors into full
    passes saves the rest of their work. A configuration's answer does not depend on the
    others in its pass, so it is the one-stage answer."""
    o = offsets(I)
    K = LANES
    js = _first_stage_joints(I, o)
    split = I[o.jlstart + js]
    qv = np.empty((o.dof, K))
    sn, cs = np.zeros((o.J, K)), np.zeros((o.J, K))
    W = np.empty((o.J, 12, K))
    C, LC, V = np.empty((o.S, 3, K)), np.empty((o.L, 3, K)), np.empty((o.S, K))
    bad, open_, near = np.empty(K, np.bool_), np.empty(K, np.bool_), np.empty(K, np.bool_)
    S = _scratch(K)
    rows = np.empty(K, np.int64)
    alive = np.empty(Q.shape[0], np.int64)
    every = np.ones(max(o.M, 1), np.bool_)  # every primitive's values
    m = 0
    for b0 in range(0, Q.shape[0], K):
        n = min(K, Q.shape[0] - b0)
        for k in range(n):
            rows[k] = b0 + k
        _load(I, F, o, Q, rows, qv, bad, n)
        _angles(I, o, qv, sn, cs, js, n)
        _place_joints(I, F, o, qv, sn, cs, W, js, n)
        _place_spheres(I, F, o, W, C, LC, js, n)
        _world_values(I, F, field, o, C, LC, margin, margin, V, bad, near, every, S, 0, split,
                      n)  # fmt: skip
        for k in range(n):
            out[b0 + k] = False
            if not bad[k]:
                alive[m] = b0 + k
                m += 1
    for a0 in range(0, m, K):
        n = min(K, m - a0)
        for k in range(n):
            rows[k] = alive[a0 + k]
        _load(I, F, o, Q, rows, qv, bad, n)
        _angles(I, o, qv, sn, cs, o.J, n)
        _place_joints(I, F, o, qv, sn, cs, W, o.J, n)
        _place_spheres(I, F, o, W, C, LC, o.J, n)
        _world_values(I, F, field, o, C, LC, margin, margin, V, bad, near, every, S, split,
                      o.L, n)  # fmt: skip
        _self_hits(I, F, o, C, LC, bad, open_, near, n)
        for k in range(n):
            out[rows[k]] = not bad[k]
