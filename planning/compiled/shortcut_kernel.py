"""Compiled path shortening: vertex reduction and random shortcutting, every new edge
certified.

:func:`shorten` works in place on ``path`` (cap, dof) whose first ``k`` rows are a path of
certified edges, and returns the new row count. It first drops every waypoint a certified
straight edge can skip (greedily, from each kept waypoint to the farthest one it reaches),
then, for each pair of uniform numbers ``u[i]`` (drawn by the caller's seeded generator),
joins the two points of the path at those arc-length fractions by a straight edge when that
edge and the two pieces of the edges it starts and ends on are certified and it saves more
than ``min_saving`` rad; a final vertex reduction follows. Every candidate edge is
screened (:func:`~planning.compiled.validity.edge_screen`) before it is certified. Only
strictly shorter replacements are taken, so the path never grows longer; its first and last
rows never change.

The two pieces a shortcut keeps (from the edge's start to its first point, from its last
point to the next waypoint) lie on edges already certified, whose certificate covers every
point of them (:mod:`planning.collision`), so they are taken without a check of their own
and flagged in ``inherited`` (edge r -> r + 1). Most are cut away by later shortcuts or the
final reduction; those that stay are certified at the end, so that every edge of the result
passes the checker's own test. Certifying every piece at once cost ~40% of the pass on the
shelf families, and every one of them passed (measured: 354 of 354 over 40 problems). One
that did not (a piece grazing the margin where its whole edge passed) would give back the
input rows unchanged; so would a result longer than the input (rounding at most).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gaide_core.types import FloatArray, IntArray
from planning.compiled.layout import Field, Off, offsets
from planning.compiled.validity import edge_ok, edge_screen


@njit(cache=True, inline="always")
def _dist(path: FloatArray, i: int, j: int) -> float:
    d = 0.0
    for c in range(path.shape[1]):
        e = path[i, c] - path[j, c]
        d += e * e
    return math.sqrt(d)


@njit(cache=True, inline="always")
def _edge(
    I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off, a: FloatArray,
    b: FloatArray, margin: float, resolution: float,
) -> bool:  # fmt: skip
    if not edge_screen(I, F, field, X, o, a, b, margin):
        return False
    return edge_ok(I, F, field, X, o, a, b, margin, resolution)


@njit(cache=True)
def _reduce(I, F, field, X, o, path, inherited, k, margin, resolution, a, b):  # type: ignore[no-untyped-def]
    """Drop the waypoints a certified edge can skip; returns the new row count."""
    out = 1
    i = 0
    while i < k - 1:
        j = k - 1
        while j > i + 1:
            for c in range(o.dof):
                a[c] = path[i, c]
                b[c] = path[j, c]
            if _edge(I, F, field, X, o, a, b, margin, resolution):
                break
            j -= 1
        # a skip is certified; a kept edge keeps its flag (read before out - 1 <= i is written)
        inherited[out - 1] = inherited[i] if j == i + 1 else False
        for c in range(o.dof):
            path[out, c] = path[j, c]
        out += 1
        i = j
    # rows were copied forward in place: row `out - 1` is the last kept waypoint
    return out


@njit(cache=True)
def _locate(arc: FloatArray, k: int, s: float) -> int:
    """Index i of the edge i -> i + 1 holding arc length s."""
    lo, hi = 0, k - 2
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if arc[mid] <= s:
            lo = mid
        else:
            hi = mid - 1
    return lo


@njit(cache=True, inline="always")
def _length(path: FloatArray, k: int) -> float:
    total = 0.0
    for i in range(1, k):
        total += _dist(path, i - 1, i)
    return total


@njit(cache=True)
def shorten(I, F, field, path, inherited, k, u, margin, resolution, min_saving, report, lengths):  # type: ignore[no-untyped-def]
    """Shorten the first ``k`` rows of ``path`` in place (module docstring); returns the
    new row count. ``inherited`` (rows,): False for the given edges; on return True for each
    edge of the result that lies on a certified one (certified at the end). ``report`` (2,)
    receives [pieces certified at the end, 1 if one failed or the result was longer and the
    input is given back]; ``lengths`` (2,) the input's and the result's length (rad)."""
    report[0] = report[1] = 0
    lengths[0] = lengths[1] = _length(path, k)
    if k <= 2:
        return k
    given = path[:k].copy()
    o = offsets(I)
    X = np.empty(o.xsize)
    m = _shortened(I, F, field, X, o, path, inherited, k, u, margin, resolution, min_saving)
    lengths[1] = _length(path, m)
    ok = lengths[1] <= lengths[0]
    for r in range(m - 1):
        if ok and inherited[r]:
            report[0] += 1
            ok = edge_ok(I, F, field, X, o, path[r], path[r + 1], margin, resolution)
    if ok:
        return m
    report[1] = 1
    path[:k] = given
    inherited[:k] = False
    lengths[1] = lengths[0]
    return k


@njit(cache=True, inline="always")
def _shortened(I, F, field, X, o, path, inherited, k, u, margin, resolution, min_saving):  # type: ignore[no-untyped-def]
    """The pass of :func:`shorten` (module docstring) on ``k`` >= 3 rows; the row count."""
    dof = o.dof
    a, b, pa, pb = np.empty(dof), np.empty(dof), np.empty(dof), np.empty(dof)
    k = _reduce(I, F, field, X, o, path, inherited, k, margin, resolution, a, b)
    arc = np.empty(path.shape[0])
    for it in range(u.shape[0]):
        if k <= 2:
            break
        arc[0] = 0.0
        for i in range(1, k):
            arc[i] = arc[i - 1] + _dist(path, i - 1, i)
        total = arc[k - 1]
        s0 = min(u[it, 0], u[it, 1]) * total
        s1 = max(u[it, 0], u[it, 1]) * total
        ia = _locate(arc, k, s0)
        ib = _locate(arc, k, s1)
        if ib <= ia:
            continue
        span_a = arc[ia + 1] - arc[ia]
        fa = (s0 - arc[ia]) / span_a if span_a > 0 else 0.0
        span_b = arc[ib + 1] - arc[ib]
        fb = (s1 - arc[ib]) / span_b if span_b > 0 else 0.0
        for c in range(dof):
            pa[c] = path[ia, c] + fa * (path[ia + 1, c] - path[ia, c])
            pb[c] = path[ib, c] + fb * (path[ib + 1, c] - path[ib, c])
        direct = 0.0
        for c in range(dof):
            e = pb[c] - pa[c]
            direct += e * e
        if (s1 - s0) - math.sqrt(direct) <= min_saving:
            continue
        if not _edge(I, F, field, X, o, pa, pb, margin, resolution):
            continue
        # rows ia+1 .. ib are replaced by pa, pb; edges ia and ia+2 are the pieces
        removed = ib - ia
        shift = 2 - removed
        if shift > 0:
            for r in range(k - 1, ib, -1):
                for c in range(dof):
                    path[r + shift, c] = path[r, c]
                inherited[r + shift] = inherited[r]
        elif shift < 0:
            for r in range(ib + 1, k):
                for c in range(dof):
                    path[r + shift, c] = path[r, c]
                inherited[r + shift] = inherited[r]
        for c in range(dof):
            path[ia + 1, c] = pa[c]
            path[ia + 2, c] = pb[c]
        inherited[ia] = True
        inherited[ia + 1] = False
        inherited[ia + 2] = True
        k += shift
    return _reduce(I, F, field, X, o, path, inherited, k, margin, resolution, a, b)
