"""Compiled RRT-Connect: sampling, nearest neighbour, extend and connect, certified edges.

The trees live in arrays the caller owns (so a run can stop between calls and resume):
``nodes`` (2, cap, dof), ``parents`` (2, cap) (-1 for a root) and ``sizes`` (2,); tree 0
holds the start roots, tree 1 the goal roots. :func:`grow` runs iterations until it joins
the trees, fills them, or uses the uniform samples it was given (``u`` (n, dof) in [0, 1),
drawn by the caller from its seeded generator: the same seed gives the same trees however
the iterations are split between calls). When the trees join, :func:`grow` also writes the
path into the caller's ``path`` (rows: at least the two trees' nodes together), so that no
Python runs between the search and the shortcut pass (in Python, tracing the path and
measuring it took ~30 us of a ~1 ms shelf plan).

Iteration i (counted from the run's start, ``it0 + i``) extends tree ``(it0 + i) % 2``
toward a uniform sample by at most ``step`` rad (joint space, Euclidean) and then greedily
connects the other tree to the new node, as Kuffner and LaValle's RRT-Connect. A move is
taken when its end configuration is valid, its points at 1/2, 1/4 and 3/4 pass
:func:`~planning.compiled.validity.edge_screen` (a blocked move is then refused for a few
configuration checks) and the edge is certified. Nearest neighbours are
found by brute force: trees stay small (hundreds to a few thousand nodes) and a scan of
contiguous rows beats a k-d tree's bookkeeping at that size.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gaide_core.types import FloatArray, IntArray
from planning.compiled.layout import Field, Off, offsets
from planning.compiled.validity import config_ok, edge_ok, edge_screen

RUNNING = 0
JOINED = 1
FULL = 2  # a tree reached its capacity: the caller grows the arrays and calls again


@njit(cache=True, inline="always")
def _nearest(nodes: FloatArray, tree: int, size: int, q: FloatArray, dof: int) -> int:
    best, best_d = 0, np.inf
    for k in range(size):
        d = 0.0
        for j in range(dof):
            e = nodes[tree, k, j] - q[j]
            d += e * e
            if d >= best_d:
                break
        if d < best_d:
            best, best_d = k, d
    return best


@njit(cache=True, inline="always")
def _toward(
    nodes: FloatArray, tree: int, k: int, target: FloatArray, step: float, out: FloatArray,
    dof: int,
) -> bool:  # fmt: skip
    """out = node k moved toward ``target`` by at most ``step``; True if it reaches it."""
    d2 = 0.0
    for j in range(dof):
        e = target[j] - nodes[tree, k, j]
        d2 += e * e
    d = math.sqrt(d2)
    if d <= step:
        for j in range(dof):
            out[j] = target[j]
        return True
    s = step / d
    for j in range(dof):
        out[j] = nodes[tree, k, j] + s * (target[j] - nodes[tree, k, j])
    return False


@njit(cache=True, inline="always")
def _valid_move(
    I: IntArray, F: FloatArray, field: Field, X: FloatArray, o: Off, nodes: FloatArray,
    tree: int, k: int, q: FloatArray, a: FloatArray, margin: float, resolution: float,
) -> bool:  # fmt: skip
    """Is q valid and the edge from node k to q certified? (``a``: scratch (dof,))"""
    for j in range(o.dof):
        X[o.xq + j] = q[j]
    if not config_ok(I, F, field, X, o, margin):
        return False
    for j in range(o.dof):
        a[j] = nodes[tree, k, j]
    if not edge_screen(I, F, field, X, o, a, q, margin):
        return False
    return edge_ok(I, F, field, X, o, a, q, margin, resolution)


@njit(cache=True, inline="always")
def _add(
    nodes: FloatArray, parents: IntArray, sizes: IntArray, tree: int, q: FloatArray, parent: int
) -> int:
    k = sizes[tree]
    for j in range(q.shape[0]):
        nodes[tree, k, j] = q[j]
    parents[tree, k] = parent
    sizes[tree] = k + 1
    return k


@njit(cache=True, inline="always")
def _trace(
    nodes: FloatArray, parents: IntArray, a: int, b: int, path: FloatArray, out: IntArray
) -> None:
    """path[:n] = root(tree 0) .. node a, then node b's ancestors .. root(tree 1) (nodes a
    and b are the same configuration: the trees met there); out[5:8] = n and the two roots."""
    n, k = 0, a
    while k >= 0:  # count the start side, to write it from its root
        n += 1
        out[6] = k
        k = parents[0, k]
    k, i = a, n - 1
    while k >= 0:
        path[i] = nodes[0, k]
        i -= 1
        k = parents[0, k]
    out[7], k = b, parents[1, b]
    while k >= 0:
        path[n] = nodes[1, k]
        n += 1
        out[7] = k
        k = parents[1, k]
    out[5] = n


@njit(cache=True)
def grow(I, F, field, nodes, parents, sizes, u, it0, margin, resolution, step, out, path):  # type: ignore[no-untyped-def]
    """Run up to len(u) iterations. ``out`` (10,) receives [status, iterations run, joining
    node of tree 0, joining node of tree 1, edge checks] and, once JOINED, [path rows, start
    root, goal root], the path in ``path`` (see the module docstring). A tree that fills up
    in the middle of a connect returns FULL with the connect's state in out[8:10] (the new
    node of the extended tree, the node the other tree goes on from; out[8] is -1 when no
    connect is pending, and the caller sets it so before the first call): the next call,
    with the same samples from that iteration on, goes on where it stopped, so the trees
    are those of a run that never filled up."""
    o = offsets(I)
    X = np.empty(o.xsize)
    dof = o.dof
    cap = nodes.shape[1]
    lo = F[o.lower : o.lower + dof]
    hi = F[o.upper : o.upper + dof]
    target = np.empty(dof)
    q = np.empty(dof)
    a = np.empty(dof)
    checks = 0
    for i in range(u.shape[0]):
        ta = (it0 + i) % 2
        tb = 1 - ta
        if out[8] >= 0:  # the connect a full tree stopped (only ever for i = 0)
            new_a, k = out[8], out[9]
            out[8] = -1
            for j in range(dof):
                target[j] = nodes[ta, new_a, j]
        else:
            if sizes[0] + 1 >= cap or sizes[1] + 1 >= cap:
                out[0], out[1], out[4] = FULL, i, checks
                return
            for j in range(dof):
                target[j] = lo[j] + u[i, j] * (hi[j] - lo[j])
            near = _nearest(nodes, ta, sizes[ta], target, dof)
            _toward(nodes, ta, near, target, step, q, dof)
            checks += 1
            if not _valid_move(I, F, field, X, o, nodes, ta, near, q, a, margin, resolution):
                continue
            new_a = _add(nodes, parents, sizes, ta, q, near)
            # connect: grow tree b toward the new node, one step at a time, until blocked
            for j in range(dof):
                target[j] = q[j]
            k = _nearest(nodes, tb, sizes[tb], target, dof)
        while True:
            if sizes[tb] + 1 >= cap:
                out[0], out[1], out[4] = FULL, i, checks
                out[8], out[9] = new_a, k
                return
            reached = _toward(nodes, tb, k, target, step, q, dof)
            checks += 1
            if not _valid_move(I, F, field, X, o, nodes, tb, k, q, a, margin, resolution):
                break
            k = _add(nodes, parents, sizes, tb, q, k)
            if reached:
                out[0], out[1], out[4] = JOINED, i + 1, checks
                out[2], out[3] = (new_a, k) if ta == 0 else (k, new_a)
                _trace(nodes, parents, out[2], out[3], path, out)
                return
    out[0], out[1], out[4] = RUNNING, u.shape[0], checks


@njit(cache=True)
def straight_ok(I, F, field, q0, q1, margin, resolution):  # type: ignore[no-untyped-def]
    """Is the edge q0 -> q1 (dof,) certified? Screened first, as the planners' moves
    (:func:`~planning.compiled.validity.edge_screen`): a blocked straight edge between a
    problem's ends is then refused for three configuration checks, while a free one pays
    ~2 us more."""
    o = offsets(I)
    X = np.empty(o.xsize)
    if not edge_screen(I, F, field, X, o, q0, q1, margin):
        return False
    return edge_ok(I, F, field, X, o, q0, q1, margin, resolution)
