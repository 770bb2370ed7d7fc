"""Path processing in joint space, the one module for it: string pulling (contraction),
random shortcutting, corner cutting, resampling and repair.

Every operation takes a path (K, dof) rad and, where it checks anything, a
:class:`~planning.collision.CollisionChecker` (either backend); the planners, the oracle and
time parameterization all use these. Every edge an operation adds is certified by the
checker (:meth:`~planning.collision.CollisionChecker.edges_valid` or ``edge_valid``) or is a
piece of an edge of the input, so a path whose edges were certified stays certified; the
shortening operations never return a longer path (triangle inequality: only strictly
shorter replacements are taken, or waypoints are skipped).

- :func:`pull_string`: from each kept waypoint, the farthest later waypoint a certified edge
  reaches is kept next (greedy string pulling; with no skip bound, MPNet's lazy states
  contraction as the neural planner uses it). Candidates are first checked coarsely, all in
  one batch, and only those that pass are certified, farthest first.
- :func:`shortcut`: random shortcuts between points of the path (waypoints or points inside
  edges), checked in batches, then :func:`remove_redundant`.
- :func:`remove_redundant`: drops the waypoints a certified edge between their neighbours
  can skip.
- :func:`cut_corners`: a checked chord across each corner, for blending.
- :func:`repair`: skips the waypoints of edges the checker rejects, where it accepts the skip.
- :func:`resample`: evenly spaced waypoints, no step longer than a bound; the curve is kept.
- :func:`tighten`: the path pulled taut as an elastic band against a clearance penalty,
  then certified (the training oracle's optional last step).
- :func:`first_invalid_sample`: where along an edge, sampled at the checker's resolution, a
  configuration is invalid (for diagnoses).

The compiled shortcut pass of the compiled RRT-Connect (:func:`planning.rrtc.shorten`) is a
kernel of its own and stays there.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.collision import CollisionChecker, Mask
from planning.planner import path_length

#: rad; consecutive waypoints closer than this are one waypoint (no motion between them),
#: and a shortcut must save at least this much (smaller savings are rounding noise).
MIN_STEP = 1e-9

#: Corner-cut fractions of the shorter edge at a corner, tried largest first.
FRACTIONS = (0.45, 0.25, 0.12)
#: rad; corners that turn less than this are left alone: blending passes them at speed.
MIN_TURN = float(np.radians(2.0))


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


def _edge_points(
    Q0: Array, Q1: Array, steps: npt.NDArray[np.int64], *, ends: bool
) -> tuple[Array, npt.NDArray[np.int64]]:
    """The points at fractions k / steps[e] of each edge Q0[e] -> Q1[e] (E, dof), k = 0 ..
    steps[e] (``ends``) or .. steps[e] - 1, edge after edge; and the index of each edge's
    first point."""
    counts = steps + 1 if ends else steps
    edge_of = np.repeat(np.arange(len(steps)), counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    frac = (np.arange(edge_of.size) - starts[edge_of]) / steps[edge_of]
    return Q0[edge_of] + frac[:, None] * (Q1 - Q0)[edge_of], starts


# -- resampling ------------------------------------------------------------------------------


def first_invalid_sample(
    checker: CollisionChecker, q0: Array, q1: Array
) -> tuple[float, Array] | None:
    """The first invalid configuration of the edge q0 -> q1 (dof,) sampled at the checker's
    resolution, with its fraction of the edge; None where every sample is valid (an edge
    that fails certification then fails between samples). For naming what an edge hits."""
    steps = int(checker.edge_steps(q0[None], q1[None])[0])
    frac = np.linspace(0.0, 1.0, steps + 1)
    samples = q0 + frac[:, None] * (q1 - q0)
    bad = np.flatnonzero(~checker.config_valid(samples))
    return (float(frac[bad[0]]), samples[bad[0]]) if bad.size else None


def resample(path: Array, max_step: float) -> Array:
    """The path (K, dof) rad with evenly spaced waypoints inserted on each edge so that no
    step is longer than ``max_step`` rad (Euclidean, joint space). The input's waypoints are
    kept, in order; zero-length edges are dropped."""
    if not (math.isfinite(max_step) and max_step > 0):
        raise PlanningError(f"max_step must be a finite length > 0 rad, got {max_step}")
    p = _drop_repeats(_as_path(path))
    if len(p) < 2:
        return p
    lengths = np.linalg.norm(np.diff(p, axis=0), axis=1)
    n = np.maximum(np.ceil(lengths / max_step), 1).astype(np.int64)  # sub-steps per edge
    out, _ = _edge_points(p[:-1], p[1:], n, ends=False)
    return np.concatenate([out, p[-1:]])


# -- string pulling (contraction) ------------------------------------------------------------


def _coarse_valid(checker: CollisionChecker, q0: Array, Q1: Array, stride: int) -> Mask:
    """(C,) False where edge q0 -> Q1[c] certainly collides: one of its points at every
    ``stride``-th of the checker's samples (and its end) is invalid. A certified edge passes."""
    Q0 = np.broadcast_to(q0, Q1.shape)
    steps = np.maximum(np.ceil(checker.edge_steps(Q0, Q1) / stride), 1).astype(np.int64)
    samples, starts = _edge_points(Q0, Q1, steps, ends=True)
    return np.logical_and.reduceat(checker.config_valid(samples), starts)


def pull_string(
    path: Array,
    checker: CollisionChecker,
    *,
    max_skip: int | None = 16,
    stride: int = 8,
    tick: Callable[[], None] | None = None,
) -> Array:
    """The path (K, dof) rad with the waypoints that certified straight edges can skip
    removed: from each kept waypoint, the farthest of the next ``max_skip`` waypoints (None:
    all of them, MPNet's lazy states contraction) that a certified edge reaches is kept next.

    ``path``'s own edges must be valid (they are kept where no shortcut is found); the
    result's waypoints are a subsequence of the input's, first and last kept, so it is
    never longer. A shortcut to a waypoint within :data:`MIN_STEP` of the current one is
    never taken: a path that comes back to a waypoint keeps its loop rather than get a
    waypoint with no motion to time. Candidates are checked coarsely first (every
    ``stride``-th of the checker's samples, all in one batch, a necessary condition of
    certification) and certified farthest first only if they pass, so the answer is the
    farthest certified edge at a fraction of the cost. ``tick`` is called once per kept
    waypoint (a planner's deadline check, which may raise)."""
    if (max_skip is not None and max_skip < 1) or stride < 1:
        raise PlanningError(
            f"need max_skip >= 1 (or None) and stride >= 1; got {max_skip}, {stride}"
        )
    K = len(path)
    keep = [0]
    i = 0
    while i < K - 1:
        if tick is not None:
            tick()
        nxt = i + 1
        last = K - 1 if max_skip is None else min(K - 1, i + max_skip)
        cand = np.arange(last, i + 1, -1)  # farthest first
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


# -- random shortcutting ---------------------------------------------------------------------


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
    cand = np.flatnonzero((ib > ia) & (saving > MIN_STEP))
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
        for i in np.flatnonzero(skip_ok & (saving >= -MIN_STEP)) + 1:
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
    every new edge accepted by the checker (the stretch of an edge kept next to a shortcut
    included).

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


# -- corner cutting --------------------------------------------------------------------------


def cut_corners(
    path: Array, checker: CollisionChecker, fractions: tuple[float, ...] = FRACTIONS
) -> Array:
    """The path (K, dof) rad with its corners cut where a checked chord allows.

    Corner ``P[i]`` is replaced by two points on its edges, ``a = P[i] - m u_in`` and
    ``b = P[i] + m u_out`` with ``m = f * min(|e_in|, |e_out|)``, when the chord ``a -> b``
    is certified; ``f`` is the largest of ``fractions`` that works, and a corner no fraction
    clears is kept. The path gets shorter (triangle inequality) and each corner's turn is
    split in two gentler ones, which blending passes faster. Every new edge is a piece of an
    old edge or a certified chord; with f <= 0.45 the two cuts on one edge never overlap.
    Corners that turn less than :data:`MIN_TURN`, or turn straight back, are kept."""
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


# -- repair ----------------------------------------------------------------------------------


def repair(path: Array, checker: CollisionChecker) -> tuple[Array, int, int | None]:
    """``path`` (K, dof) with the edges the checker rejects replaced by skipping one of their
    waypoints (the edge's far end, else its near end; never the first or last waypoint),
    where the checker certifies the skip. Returns the path, the number of waypoints dropped,
    and the index of an edge that could not be repaired (None if none); every edge of a
    fully repaired result has been certified.

    For OMPL's path simplifier (run by AORRTC on every solution, and by ``simplify=True``),
    which puts waypoints in the middle of edges it has checked and does not check the
    pieces again: a piece's own certification can fail where the whole edge's did not.
    Skipping the inserted waypoint restores the checked edge or another certified one.
    """
    dropped = 0
    bad = checker.first_invalid_edge(path)
    while bad is not None:
        for k, (a, b) in ((bad + 1, (bad, bad + 2)), (bad, (bad - 1, bad + 1))):
            if 0 < k < len(path) - 1 and checker.edge_valid(path[a], path[b]):
                path = np.delete(path, k, axis=0)
                dropped += 1
                break
        else:
            return path, dropped, bad
        bad = checker.first_invalid_edge(path)
    return path, dropped, None


# -- tightening (an elastic band) ------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class BandCfg:
    """How :func:`tighten` pulls a path taut."""

    spacing: float = 0.1  # rad between the band's points as it starts (the input resampled)
    # m the penalty asks beyond the margin from the world, and between self-collision pairs:
    # the buffer that lets the certification pass between the band's samples.
    clearance: float = 0.02
    weight: float = 1e4  # of the penalties (m², rad²) against the band's energy (rad²)
    # L-BFGS-B iterations, the work budget. On 10 Shelf II and 10 Shelf III problems, two
    # oracle labels' first steps lay 12.6 / 13.0 deg apart (median) after 200 and 4.3 / 3.1
    # after 500, measured with a first form of the band (no midpoints, no edge bound).
    iterations: int = 500
    # The band may come out up to this share longer than its input: it keeps `clearance` from
    # the obstacles where a shortcut path runs on the margin. On 10 Bins validation problems,
    # requiring it shorter rejected 6 bands, and the labels kept their 14-25 deg spread.
    slack: float = 0.05

    def __post_init__(self) -> None:
        values = (self.spacing, self.clearance, self.weight)
        if not (
            all(math.isfinite(v) and v > 0 for v in values)
            and self.iterations >= 1
            and 0 <= self.slack < math.inf
        ):
            raise PlanningError(
                "the band needs spacing, clearance and weight finite and > 0, iterations >= 1 "
                f"and slack finite and >= 0; got {values[0]}, {values[1]}, {values[2]}, "
                f"{self.iterations}, {self.slack}"
            )


def tighten(checker: CollisionChecker, path: Array, cfg: BandCfg | None = None) -> Array | None:
    """``path`` (K, dof), its edges certified, pulled taut as an elastic band; None when the
    band does not come out with every edge certified and at most ``cfg.slack`` longer (the
    caller keeps its path).

    The path is resampled at ``cfg.spacing`` and its inner points move (within the joint
    limits; the ends stay) to minimise, by L-BFGS-B (scipy), the band's energy ``(n - 1) Σ
    |q[k+1] - q[k]|²`` over its n points, which is the squared length of a straight path
    with evenly spaced points and grows with every bend and uneven step, plus ``cfg.weight``
    times: the clearance penalty (:mod:`planning.compiled.band_kernel`: each sphere's
    shortfall from ``margin + cfg.clearance``, each self pair's from ``cfg.clearance``,
    squared) at every point and every edge's midpoint, and each edge's excess over 1.5
    spacings, squared, so that no edge grows long enough to jump an obstacle between the
    penalty's samples. The result is certified edge by edge before it is returned.

    Why: the random shortcuts of the oracle stop where no straight chord between two points
    of the path is free, short of the shortest path in that way round by a few percent, and
    two labels of one problem then leave the start tens of degrees apart (docs/results.md,
    "The oracle"). The band slides the path along the obstacles to where it is taut, the same
    place from either label. No kept library optimises a path against this project's sphere
    model (TrajOpt and CHOMP work on meshes or their own distance fields), so the energy is
    written here and the optimiser is scipy's."""
    # Imported here: the other operations need neither scipy's optimiser nor numba.
    from scipy.optimize import minimize
    from threadpoolctl import threadpool_limits

    from planning.compiled.band_kernel import penalty_gradient
    from planning.rrtc import kernel_tables

    cfg = cfg or BandCfg()
    p = resample(path, cfg.spacing)
    if len(p) < 3:
        return None
    I, F, field = kernel_tables(checker).args()  # noqa: E741 (layout names)
    q0, q1 = p[0], p[-1]
    n, dof = len(p) - 2, p.shape[1]  # inner points
    need, longest = checker.margin + cfg.clearance, 1.5 * cfg.spacing
    grad = np.zeros((2 * n + 1, dof))  # the inner points', then the n + 1 midpoints'

    def energy(x: Array) -> tuple[float, Array]:
        inner = x.reshape(n, dof)
        band = np.vstack([q0, inner, q1])
        d = np.diff(band, axis=0)
        rows = np.vstack([inner, 0.5 * (band[:-1] + band[1:])])
        penalty = penalty_gradient(I, F, field, rows, need, cfg.clearance, grad)
        g_pen = grad[:n] + 0.5 * (grad[n:-1] + grad[n + 1 :])
        lengths = np.linalg.norm(d, axis=1)
        over = np.maximum(0.0, lengths - longest)
        g_over = (2.0 * over / np.maximum(lengths, MIN_STEP))[:, None] * d
        g_pen += g_over[:-1] - g_over[1:]
        value = (n + 1) * float(np.sum(d * d)) + cfg.weight * (penalty + float(over @ over))
        g = 2.0 * (n + 1) * (d[:-1] - d[1:]) + cfg.weight * g_pen
        return value, g.ravel()

    lower, upper = checker.robot.lower, checker.robot.upper
    bounds = list(zip(np.tile(lower, n), np.tile(upper, n), strict=True))
    x0 = np.clip(p[1:-1], lower, upper).ravel()
    # L-BFGS-B's solves are small (a few hundred variables, 10 corrections): BLAS threads only
    # cost there, and with every core busy (data generation's workers) OpenBLAS's spinning
    # threads made the band 3.5x slower (84% of its time in L-BFGS-B; docs/results.md).
    with threadpool_limits(1, user_api="blas"):
        res = minimize(
            energy, x0, jac=True, method="L-BFGS-B", bounds=bounds,
            options={"maxiter": cfg.iterations, "maxfun": 2 * cfg.iterations},
        )  # fmt: skip
    band = np.vstack([q0, res.x.reshape(n, dof), q1])
    if not np.all(np.isfinite(band)) or path_length(band) > (1 + cfg.slack) * path_length(path):
        return None
    return band if bool(np.all(checker.edges_valid(band[:-1], band[1:]))) else None
