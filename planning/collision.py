"""Sphere-based collision checking of configurations and edges: the numpy reference.

A configuration is valid when it is inside the joint limits, every sphere (except those of
``world_ignored_links``) clears the world by the margin, and no two spheres of links that
may touch overlap.

An edge is valid (*certified*) when the whole continuous motion along it keeps those
conditions, not only some samples of it. It is walked from q0 to q1 with conservative
advancement. Over the whole edge, sphere s moves at most ``reach_s`` and the centre distance
of self pair p changes by at most ``preach_p`` (displacement bounds, linear in the joint
motion; a joint that moves both spheres of a pair carries them rigidly and does not count).
At each sample every world-checked sphere has clearance v_s and every self pair gap g_p
(both capped at :data:`CLEARANCE_CAP`), and

    f = min(min_s (v_s - margin) / reach_s, min_p g_p / preach_p)

is how far along the edge nothing can lose its margin. ``reach_s`` takes each joint's lever
at its longest (the chain from the joint to the sphere), so the walk also bounds sphere s's
motion from where it is: over a fraction tau of the edge from a sample, it moves at most

    tau A_s + tau^2 B_s,   A_s = sum_j |dq_j| l_sj,   B_s = 1/2 sum_j |dq_j| sum_k |dq_k| d_sk

where l_sj is the centre's distance from the axis of revolute joint j at the sample (the
chain bound d_sj for a prismatic joint) and k runs over the joints between j and the sphere:
only those change the distance from j's axis, each at a rate of at most its own bound, so
that over tau the distance grows by at most tau sum_k |dq_k| d_sk (integrated: the 1/2; a
prismatic joint's lever is its bound and has no such term). For each sphere
the larger of the two fractions counts, (v_s - margin) / reach_s and the largest tau with
tau A_s + tau^2 B_s <= v_s - margin. Near the shelves this bound is 2-3x the tighter, and the
walk takes 2-3x fewer samples. If f is at least one resolution step (no sphere centre moves
more than ``resolution`` in a step), the walk jumps by f. Otherwise it steps by
dt = min(step, 2 f), and the two samples a, b must satisfy

    v_s(a) + v_s(b) >= 2 margin + min(reach_s dt, dt A_s(a) + dt^2 B_s)
    g_p(a) + g_p(b) >= preach_p dt

or the walk takes the jump f instead; a step below 1/:data:`MIN_STEP_DIVISOR` of the
resolution step is not taken, and the edge is refused (it grazes the margin too closely to
be certified). Distances are 1-Lipschitz in the path length of a centre, so every point
between a and b keeps clearance >= margin and gap >= 0. Every sample must be valid as well.
A path whose edges a planner certified therefore passes any finer sampled check
(:meth:`SphereCollisionChecker.edges_valid_sampled`, the harness's). Cloud worlds answer with
a lower bound of the true distance, so there the guarantee holds for the true geometry; the
bound itself is not continuous (it rounds to a lattice point), and a sample between two
certified ones can read inside the margin while its true clearance keeps it (measured on
``gaide demo``: 4.0 mm read, >= 14.7 mm true, margin 5 mm). Reports of executed motion take
the true distance there (:func:`execution.simulate.report_validity`).

An edge of at least :data:`DENSE_MIN_STEPS` resolution steps is offered a *dense
certificate* before the walk, on :data:`DENSE_SAMPLES` evenly spaced samples (the ends
included). All must be valid, and every two neighbours a, b satisfy the two-sample bound
above with dt = t_b - t_a (the same Lipschitz argument, interval by interval). Where a
coarse interval can pass (:func:`coarse_first`), every :data:`DENSE_STRIDE`-th sample is
taken first: all must be valid, each interval between two of them that satisfies the bound
is certified whole, and only the intervals that fail it are refined (their inner samples
taken, all valid, each fine interval satisfying the bound). This holds for most long edges
clear of the obstacles, where the walk's jumps stay short because every clearance above
:data:`CLEARANCE_CAP` counts as the cap. A sample that is invalid refuses the edge (no
certificate can pass a point below the margin); otherwise, where the bound fails between
fine samples k and k + 1, that interval is split :data:`DENSE_SPLIT` ways the same way (its
inner samples taken, all valid, each part that satisfies the bound certified), and the walk
certifies the parts that still fail, each from its first sample to its second (a run of
such parts in one walk). The others are certified by the dense samples: an edge that leaves
a start close to an obstacle is walked only near that start.

:class:`~planning.compiled.checker.CompiledChecker` runs the same algorithms in compiled code
and is the default everywhere; this class is the reference the tests compare it with.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from gaide_core.errors import PlanningError
from gaide_core.types import Array
from planning.kinematics import BatchKinematics
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel
from planning.world import EmptyWorld, World

if TYPE_CHECKING:
    from planning.compiled.tables import Tables

Mask = npt.NDArray[np.bool_]

# Edges of at least this many sub-steps get a coarse pass first, at every this many sub-steps.
COARSE_MIN_STEPS = 32
COARSE_STRIDE = 8
# Clearances and gaps (m) are needed exactly only up to this: conservative advancement then
# jumps at most (CAP - margin) / reach at a time, and the compiled checker's bounding-sphere
# tests skip whatever is farther. rrtc on the task families ran as fast with 0.2 m.
CLEARANCE_CAP = 0.1
# Certification gives up on steps smaller than the resolution step over this (module
# docstring): a motion that needs finer steps slides along the margin.
MIN_STEP_DIVISOR = 64
# The dense certificate (module docstring): its samples per edge, the edges long enough to
# try it first (in resolution steps), and the stride of its coarse samples ((DENSE_SAMPLES -
# 1) a multiple of it). The compiled checker takes the samples of each pass together, one
# per SIMD lane (planning.compiled.lanes); on the shelves' long edges the walk takes a
# median of 46 samples, one after the other. On 300 random 1 rad edges of the benchmark
# workcell (simulated in numpy), every edge that one of the 64 samples refuses was refused
# by a coarse sample, and coarse-first took 35% of the samples with a stride of 3, 18% with
# 7, 29% with 9. A pass of few lanes costs more per sample (LLVM's vector loops want tens of
# lanes), so coarse-first pays only where few coarse intervals fail (coarse_first). Edges of
# 16-63 steps take it too: near a board the walk creeps over them where the 64 samples'
# bound often holds (rrtc on the 20 balanced problems a family: 2-4% less summed time than
# with 64, the same paths; docs/results.md).
DENSE_SAMPLES = 64
DENSE_MIN_STEPS = 16
DENSE_STRIDE = 7
assert (DENSE_SAMPLES - 1) % DENSE_STRIDE == 0
# A fine interval whose bound fails is split into this many before the walk: its inner
# samples are taken together (8 lanes with its ends), and the walk covers only the parts
# whose bound still fails. The walk takes ~3 us a sample, one after the other.
DENSE_SPLIT = 7
#: The dense certificate's finest unit, and the most intervals it can leave to the walk.
DENSE_UNITS = (DENSE_SAMPLES - 1) * DENSE_SPLIT


def _split(ks: npt.NDArray[np.int64], c: int) -> npt.NDArray[np.int64]:
    """The samples of the intervals ``ks`` split c ways, ends included, in units c times
    finer (shared ends once)."""
    return np.unique((c * ks[:, None] + np.arange(c + 1)).ravel())


def coarse_first(top_reach: float, margin: float) -> bool:
    """Does the dense certificate of an edge whose fastest sphere moves ``top_reach`` (m)
    take its coarse samples first (module docstring)? Only where that sphere could pass a
    coarse interval's bound at all, its clearance at the cap at both ends: beyond that, the
    coarse intervals fail for it and are refined, and one pass of all the samples costs
    less. (Measured on the shelves' long edges: below the limit (1.7 m for the UR5's 5 mm
    margin) 22-28% of the coarse intervals failed, above it 92-100%.)"""
    return top_reach * DENSE_STRIDE / (DENSE_SAMPLES - 1) < 2.0 * (CLEARANCE_CAP - margin)


@dataclass(frozen=True)
class Diagnosis:
    """Why one configuration is invalid (empty lists: it is valid)."""

    outside_limits: list[str]  # joint names
    world_contacts: list[str]  # link names touching the world
    self_contacts: list[tuple[str, str]]  # link pairs overlapping

    @property
    def valid(self) -> bool:
        return not (self.outside_limits or self.world_contacts or self.self_contacts)

    def __str__(self) -> str:
        parts = []
        if self.outside_limits:
            parts.append(f"joints outside limits: {self.outside_limits}")
        if self.world_contacts:
            parts.append(f"links in collision with the world: {self.world_contacts}")
        if self.self_contacts:
            parts.append(f"self-collision between {self.self_contacts}")
        return "; ".join(parts) or "valid"


class CollisionChecker(Protocol):
    """What planners, the oracle, path processing, timing and simulation need of a checker:
    batched validity of configurations and of certified straight edges (module docstring),
    and why a configuration is invalid. :func:`planning.checker.make_checker` makes one.

    Optional: ``kernel_tables()``, the checker exported for the compiled kernels
    (:class:`KernelTablesSource`). Both sphere checkers have it; the compiled planners
    (``rrtc``, its shortcut pass) refuse a checker without it."""

    robot: RobotModel
    spheres: SphereModel
    world: World
    margin: float  # m
    resolution: float  # m
    radii: Array  # (S,) m, the spheres' radii in the sphere model's order
    # (S,) m, the radii the world checks take: radii plus each sphere's world raise
    world_radii: Array
    backend: str  # "compiled" or "numpy"

    def config_valid(self, Q: Array) -> Mask:
        """(B,) validity of configurations Q (B, dof)."""
        ...

    def edges_valid(self, Q0: Array, Q1: Array) -> Mask:
        """(E,) certification of the straight edges Q0[e] -> Q1[e] (E, dof)."""
        ...

    def edge_valid(self, q0: Array, q1: Array) -> bool: ...

    def config_valid_one(self, q: Array) -> bool:
        """Validity of one finite float64 configuration (dof,), for per-state callbacks."""
        ...

    def edge_valid_one(self, q0: Array, q1: Array) -> bool:
        """Certification of one edge between finite float64 (dof,) arrays."""
        ...

    def first_invalid_edge(self, path: Array) -> int | None: ...

    def edges_valid_sampled(self, Q0: Array, Q1: Array) -> Mask:
        """(E,) every resolution sample valid (a necessary condition of certification)."""
        ...

    def edge_steps(self, Q0: Array, Q1: Array) -> npt.NDArray[np.int64]: ...

    def diagnose(self, q: Array) -> Diagnosis: ...

    def world_clearance(self, Q: Array, links: tuple[str, ...] | None = None) -> Array: ...

    def sphere_clearance(self, Q: Array) -> Array:
        """(B, S) distance - radius (m) of each world-checked sphere, +inf for the others."""
        ...

    def sphere_centers(self, Q: Array) -> Array: ...

    @property
    def max_margin(self) -> float:
        """The largest margin (m) the world's distances are exact for (inf: any)."""
        ...

    def with_margin(self, margin: float) -> CollisionChecker:
        """This checker at another margin (m); PlanningError outside [0, max_margin]."""
        ...

    def with_world_raise(self, raise_: Array) -> CollisionChecker:
        """This checker with sphere s kept ``raise_[s]`` m (S,) further from the world than
        the margin; PlanningError for a negative or non-finite raise, or one the world's
        distances are not exact for."""
        ...


@runtime_checkable
class KernelTablesSource(Protocol):
    """The optional part of :class:`CollisionChecker` that the compiled planners need: the
    checker's robot, spheres and world as the kernels' tables."""

    def kernel_tables(self) -> Tables: ...


class SphereCollisionChecker:
    """Checks configurations of ``robot``, modelled by ``spheres``, against ``world``."""

    backend = "numpy"
    # Configurations per vectorized pass: small enough that the working arrays stay in cache
    # (measured: 2k runs ~30% faster than 20k per configuration).
    chunk = 2048

    def __init__(
        self,
        robot: RobotModel,
        spheres: SphereModel,
        world: World | None = None,
        *,
        margin: float | None = None,  # m, default: the robot config's collision margin
        resolution: float | None = None,  # m, default: the robot config's edge resolution
        world_ignored_links: tuple[str, ...] | None = None,
    ) -> None:
        spheres.check_against(robot)
        self.robot = robot
        self.spheres = spheres
        self.world: World = world if world is not None else EmptyWorld()
        self.margin = robot.config.collision_margin if margin is None else float(margin)
        self.resolution = robot.config.edge_resolution if resolution is None else float(resolution)
        self.radii = spheres.radii.astype(float)
        self.world_radii = self.radii
        self._check_margin()
        self.kin = BatchKinematics(robot)
        link_of = [robot.links[name] for name in spheres.links]
        self.sphere_joint = np.array([lk.joint_id for lk in link_of], np.int64)
        # Sphere centres in their joint frames.
        self.sphere_local = np.stack(
            [
                lk.T_joint_link[:3, :3] @ c + lk.T_joint_link[:3, 3]
                for lk, c in zip(link_of, spheres.centers, strict=True)
            ]
        )
        ignored = (
            robot.config.world_ignored_links if world_ignored_links is None else world_ignored_links
        )
        for name in ignored:
            robot.link(name)
        self.world_spheres = np.flatnonzero(~np.isin(np.asarray(spheres.links), list(ignored)))
        disabled = robot.disabled_link_pairs
        names = spheres.links
        pairs = [
            (i, j)
            for i in range(len(names))
            for j in range(i + 1, len(names))
            if names[i] != names[j] and frozenset((names[i], names[j])) not in disabled
        ]
        self.pairs = np.array(pairs, np.int64).reshape(-1, 2)
        self.pair_reach = (self.radii[self.pairs[:, 0]] + self.radii[self.pairs[:, 1]]) ** 2
        self._link_groups = self._group_pairs_by_link()
        self._displacement = self._displacement_bounds()
        self._pair_displacement = self.pair_displacement()

    def _check_margin(self) -> None:
        if self.margin < 0 or self.resolution <= 0:
            raise PlanningError(
                f"need margin >= 0 and resolution > 0 (m); got {self.margin}, {self.resolution}"
            )
        if self.margin > self.max_margin:
            exact = getattr(self.world, "exact_up_to", np.inf)
            reach = self.world_radii.max() + self.margin
            raise PlanningError(
                f"the world's distances are exact only up to {exact:.3f} m, less than the "
                f"largest sphere radius (with its world raise) + margin ({reach:.3f} m): build "
                "it with a wider band, or ask for less"
            )

    @property
    def max_margin(self) -> float:
        """The largest margin (m) the world's distances are exact for (inf: any), given the
        world checks' radii."""
        return float(getattr(self.world, "exact_up_to", np.inf) - self.world_radii.max())

    def with_margin(self, margin: float) -> SphereCollisionChecker:
        """This checker at another margin (m), sharing everything else (the kernels take the
        margin per call); PlanningError for one outside [0, max_margin]."""
        other = copy.copy(self)
        other.margin = float(margin)
        other._check_margin()
        return other

    def with_world_raise(self, raise_: Array) -> SphereCollisionChecker:
        """This checker with sphere s kept ``raise_[s]`` m (S,) further from the world than
        the margin (its world checks take radius + raise; self pairs keep the radii), sharing
        everything else; PlanningError for a raise of another shape, negative or not finite,
        or one the world's distances are not exact for."""
        raise_ = np.asarray(raise_, float)
        if raise_.shape != self.radii.shape or not np.all(np.isfinite(raise_) & (raise_ >= 0)):
            raise PlanningError(
                f"a world raise needs one finite value >= 0 (m) per sphere, shape "
                f"{self.radii.shape}; got shape {raise_.shape}"
            )
        other = copy.copy(self)
        other.world_radii = self.radii + raise_
        other._check_margin()
        return other

    def _group_pairs_by_link(self) -> list[tuple[int, int, Array, float]]:
        """Self-collision pairs grouped by link pair, with one bounding sphere per link (an
        extra point after the S spheres): a link pair whose bounds are apart needs no
        sphere-pair test. Returns (bound_a, bound_b, pair indices, reach^2) per link pair."""
        links = list(self.spheres.link_names)
        names = np.asarray(self.spheres.links)
        bound_local, bound_joint, bound_radius = [], [], []
        for link in links:
            idx = np.flatnonzero(names == link)
            centre = self.sphere_local[idx].mean(axis=0)
            reach = np.linalg.norm(self.sphere_local[idx] - centre, axis=1) + self.radii[idx]
            bound_local.append(centre)
            bound_joint.append(self.sphere_joint[idx[0]])
            bound_radius.append(float(reach.max()))
        S = len(self.radii)
        self.point_joint = np.concatenate([self.sphere_joint, bound_joint]).astype(np.int64)
        self.point_local = np.concatenate([self.sphere_local, np.asarray(bound_local)])
        groups: dict[tuple[int, int], list[int]] = {}
        for k, (i, j) in enumerate(self.pairs):
            key = (links.index(names[i]), links.index(names[j]))
            groups.setdefault(key, []).append(k)
        return [
            (S + a, S + b, np.asarray(ks), (bound_radius[a] + bound_radius[b]) ** 2)
            for (a, b), ks in groups.items()
        ]

    # -- configurations ------------------------------------------------------------------

    def sphere_centers(self, Q: Array) -> Array:
        """(B, S, 3) world positions of the sphere centres for configurations Q (B, dof)."""
        return self.kin.points(Q, self.sphere_joint, self.sphere_local)

    def _clearance(self, Q: Array, idx: npt.NDArray[np.int64]) -> Array:
        """(B, len(idx)) distance - radius (m) of spheres ``idx`` at configurations Q."""
        centers = self.sphere_centers(Q)[:, idx]
        B, S, _ = centers.shape
        return self.world.distance(centers.reshape(-1, 3)).reshape(B, S) - self.radii[idx]

    def sphere_clearance(self, Q: Array) -> Array:
        """(B, S) distance - radius (m) of each world-checked sphere, +inf for the others."""
        out = np.full((len(Q), len(self.radii)), np.inf)
        out[:, self.world_spheres] = self._clearance(Q, self.world_spheres)
        return out

    def world_clearance(self, Q: Array, links: tuple[str, ...] | None = None) -> Array:
        """(B,) smallest (distance - radius) over the world-checked spheres (m), or over the
        spheres of ``links`` only."""
        idx = self.world_spheres
        if links is not None:
            for name in links:
                self.robot.link(name)
            idx = idx[np.isin(np.asarray(self.spheres.links)[idx], list(links))]
        return np.min(self._clearance(Q, idx), axis=1)

    def config_valid(self, Q: Array) -> Mask:
        """(B,) True where configuration Q[b] is valid (limits, world, self)."""
        Q = self._batch(Q)
        if Q.shape[0] <= 2:  # planners' one-state queries: a leaner path (~8x faster)
            return np.array([self._valid_one(q) for q in Q], bool)
        out = np.empty(Q.shape[0], bool)
        for s in range(0, Q.shape[0], self.chunk):
            out[s : s + self.chunk] = self._valid_chunk(Q[s : s + self.chunk])
        return out

    def _valid_chunk(self, Q: Array) -> Mask:
        ok = self.robot.within_limits(Q)
        points = self.kin.points(Q, self.point_joint, self.point_local)
        B = Q.shape[0]
        w = points[:, self.world_spheres].reshape(-1, 3)
        d = self.world.distance(w).reshape(B, -1) - self.world_radii[self.world_spheres]
        ok &= np.all(d >= self.margin, axis=1)
        for a, b, ks, reach in self._link_groups:
            gap = points[:, a] - points[:, b]
            near = np.flatnonzero(np.einsum("bi,bi->b", gap, gap) < reach)
            if near.size == 0:
                continue
            sub = points[near]
            diff = sub[:, self.pairs[ks, 0]] - sub[:, self.pairs[ks, 1]]
            hit = np.any(np.einsum("bpi,bpi->bp", diff, diff) < self.pair_reach[ks], axis=1)
            ok[near[hit]] = False
        return ok

    def _valid_one(self, q: Array) -> bool:
        if np.any(q < self.robot.lower) or np.any(q > self.robot.upper):
            return False
        centers = self.kin.points_one(q, self.sphere_joint, self.sphere_local)
        d = self.world.distance(centers[self.world_spheres]) - self.world_radii[self.world_spheres]
        if d.min() < self.margin:
            return False
        if len(self.pairs):
            diff = centers[self.pairs[:, 0]] - centers[self.pairs[:, 1]]
            if np.any(np.einsum("pi,pi->p", diff, diff) < self.pair_reach):
                return False
        return True

    def config_valid_one(self, q: Array) -> bool:
        """Validity of one configuration (dof,), a finite float64 array: for per-state
        callbacks."""
        return self._valid_one(q)

    def edge_valid_one(self, q0: Array, q1: Array) -> bool:
        """Certification of one edge between finite float64 (dof,) arrays."""
        return bool(self.edges_valid(q0[None], q1[None])[0])

    def kernel_tables(self) -> Tables:
        """This checker's robot, spheres and world as the compiled kernels' tables
        (:class:`KernelTablesSource`), exported on each call."""
        from planning.compiled.tables import checker_tables

        return checker_tables(self)

    def diagnose(self, q: Array) -> Diagnosis:
        """Which joints, links or link pairs make configuration q (dof,) invalid."""
        q = self.robot.as_configuration(q)
        names = self.robot.joint_names
        outside = [
            names[i] for i in np.flatnonzero((q < self.robot.lower) | (q > self.robot.upper))
        ]
        centers = self.sphere_centers(q[None])[0]
        d = self.world.distance(centers[self.world_spheres]) - self.world_radii[self.world_spheres]
        hit = self.world_spheres[d < self.margin]
        world_links = list(dict.fromkeys(self.spheres.links[i] for i in hit))
        self_pairs: list[tuple[str, str]] = []
        if len(self.pairs):
            diff = centers[self.pairs[:, 0]] - centers[self.pairs[:, 1]]
            bad = self.pairs[np.sum(diff * diff, axis=1) < self.pair_reach]
            links = self.spheres.links
            self_pairs = list(dict.fromkeys((links[i], links[j]) for i, j in bad))
        return Diagnosis(outside, world_links, self_pairs)

    # -- edges ---------------------------------------------------------------------------

    def _displacement_bounds(self) -> Array:
        """(S, dof) bound on how far sphere s moves per unit motion of joint j, for every
        configuration: the chain length from joint j to the sphere (revolute) or 1
        (prismatic). Zero where joint j does not carry the sphere."""
        kin, robot = self.kin, self.robot
        bounds = np.zeros((len(self.radii), robot.dof))
        for s, (js, local) in enumerate(zip(self.sphere_joint, self.sphere_local, strict=True)):
            length = float(np.linalg.norm(local))
            j = int(js)
            while j > 0:
                col = kin.idx_q[j]
                if kin.prismatic[j]:
                    bounds[s, col] = 1.0
                    span = max(abs(robot.lower[col]), abs(robot.upper[col]))
                    length += span
                else:
                    bounds[s, col] = length
                length += float(np.linalg.norm(kin.placements_t[j]))
                j = kin.parents[j]
        return bounds

    def pair_displacement(self, pairs: npt.NDArray[np.int64] | None = None) -> Array:
        """(P, dof) bound on how fast the centre distance of each self pair (i, j) changes
        per unit motion of each joint: a joint that moves both spheres carries them rigidly
        and changes nothing; one that moves only one moves it by at most its lever."""
        pairs = self.pairs if pairs is None else pairs
        a = self._displacement[pairs[:, 0]]
        b = self._displacement[pairs[:, 1]]
        return a * (b == 0) + b * (a == 0)

    def edge_steps(self, Q0: Array, Q1: Array) -> npt.NDArray[np.int64]:
        """(E,) number of sub-steps per edge so that no sphere centre moves more than the
        resolution between consecutive samples."""
        reach = np.abs(Q1 - Q0) @ self._displacement.T  # (E, S)
        return np.maximum(np.ceil(reach.max(axis=1) / self.resolution), 1).astype(np.int64)

    def edges_valid(self, Q0: Array, Q1: Array, *, coarse: bool = True) -> Mask:
        """(E,) True where the straight joint-space edge Q0[e] -> Q1[e] is certified: along
        the whole motion every world-checked sphere keeps the margin and no self pair
        overlaps (no margin there; module docstring), endpoints included.

        ``coarse``: check the long edges at every 8th of their samples (and their end) first,
        a necessary condition, so the answer is the same; most edges a planner asks about
        are blocked, and the coarse pass rejects those at an eighth of the cost."""
        Q0, Q1 = self._edge_batch(Q0, Q1)
        steps = self.edge_steps(Q0, Q1)
        ok = np.ones(len(steps), bool)
        if coarse:
            long = np.flatnonzero(steps >= COARSE_MIN_STEPS)
            if long.size:
                ok[long] = self._sampled_valid(Q0[long], Q1[long], steps[long], COARSE_STRIDE)
        for e in np.flatnonzero(ok):
            ok[e] = self._certified(Q0[e], Q1[e], int(steps[e]))
        return ok

    def edges_valid_sampled(self, Q0: Array, Q1: Array) -> Mask:
        """(E,) True where every sample of edge e (at the checker's resolution) is a valid
        configuration: a necessary condition of :meth:`edges_valid`, which a certified edge
        passes at any resolution. The harness checks returned paths this way."""
        Q0, Q1 = self._edge_batch(Q0, Q1)
        return self._sampled_valid(Q0, Q1, self.edge_steps(Q0, Q1), 1)

    def _edge_batch(self, Q0: Array, Q1: Array) -> tuple[Array, Array]:
        Q0, Q1 = self._batch(Q0), self._batch(Q1)
        if Q0.shape != Q1.shape:
            raise PlanningError(f"edge endpoints differ in shape: {Q0.shape} vs {Q1.shape}")
        return Q0, Q1

    def _certified(self, q0: Array, q1: Array, n: int) -> bool:
        """Does the edge q0 -> q1, of n resolution steps, pass conservative advancement
        (module docstring)? One sample at a time, every sphere and pair exact."""
        reach = (np.abs(q1 - q0) * self._displacement).sum(axis=1)  # (S,) m over the edge
        pair_reach = (np.abs(q1 - q0) * self._pair_displacement).sum(axis=1)  # (P,) m
        slack = self._slack(np.abs(q1 - q0))  # (S,) m
        if n < DENSE_MIN_STEPS:
            return self._walk(q0, q1, n, reach, pair_reach, slack, 0.0, 1.0)
        fails = self._dense_fails(q0, q1, reach, pair_reach, slack)
        if fails is None:
            return False
        # the dense samples certify every other interval; a run of neighbouring ones is
        # walked whole, so that the walk's jumps can cross their ends
        runs: list[list[int]] = []
        for k in fails:
            if runs and runs[-1][1] == k:
                runs[-1][1] = k + 1
            else:
                runs.append([k, k + 1])
        return all(
            self._walk(q0, q1, n, reach, pair_reach, slack, a / DENSE_UNITS, b / DENSE_UNITS)
            for a, b in runs
        )

    def _walk(
        self, q0: Array, q1: Array, n: int, reach: Array, pair_reach: Array, slack: Array,
        t: float, end: float,
    ) -> bool:  # fmt: skip
        """Conservative advancement over the fractions [t, end] of the edge q0 -> q1, of n
        resolution steps (module docstring), from a sample at t. ``reach``, ``pair_reach``
        and ``slack`` are the edge's (m)."""
        ws = self.world_spheres[reach[self.world_spheres] > 0]
        wsa = self.world_spheres
        moving = pair_reach > 0
        step = 1.0 / n
        smallest = step / MIN_STEP_DIVISOR
        dq = np.abs(q1 - q0)
        values = self._sample_values(q0, q1, t)
        if values is None:
            return False
        while t < end:
            v, g = values
            lever = self._lever_sums((q0 + t * (q1 - q0))[None], dq)[0]
            room = v[ws] - self.margin
            with np.errstate(divide="ignore", invalid="ignore"):  # den 0: the sphere stays
                den = lever[ws] + np.sqrt(lever[ws] * lever[ws] + 4.0 * slack[ws] * room)
                local = np.where(den > 0.0, 2.0 * room / den, np.inf)
            f = min(
                np.min(np.maximum(room / reach[ws], local), initial=np.inf),
                np.min(g[moving] / pair_reach[moving], initial=np.inf),
            )
            if f >= step:  # a jump: nothing can lose its margin before t + f
                t_next = min(t + f, end)
                values = self._sample_values(q0, q1, t_next)
                if values is None:
                    return False
            else:  # a step the two-sample bound must certify, else the jump f
                if 2.0 * f < smallest:
                    return False
                t_next = min(t + min(step, 2.0 * f), end)
                values = self._sample_values(q0, q1, t_next)
                if values is None:
                    return False
                dt = t_next - t
                v2, g2 = values
                motion = np.minimum(reach[wsa] * dt, dt * (lever[wsa] + dt * slack[wsa]))
                if np.any(v[wsa] + v2[wsa] < 2.0 * self.margin + motion) or np.any(
                    g + g2 < pair_reach * dt
                ):
                    if f < smallest:
                        return False
                    t_next = min(t + f, end)
                    values = self._sample_values(q0, q1, t_next)
                    if values is None:
                        return False
            t = t_next
        return True

    def _lever_sums(self, Q: Array, dq: Array) -> Array:
        """(B, S) A_s (m) at the configurations Q (B, dof) (module docstring): per joint
        carrying sphere s, the joint's motion over the edge ``dq`` (dof,) times the sphere
        centre's distance from its axis (revolute) or its bound (prismatic), summed from the
        base."""
        kin, disp = self.kin, self._displacement
        R, t = kin.joint_poses(Q)
        c = self.sphere_centers(Q)  # (B, S, 3)
        acc = np.zeros(c.shape[:2])
        for j in range(1, kin.njoints):
            col = kin.idx_q[j]
            w, d = disp[:, col], dq[col]
            if kin.prismatic[j]:
                acc = acc + d * w
                continue
            Rj, (x, y, z) = R[j][:, :, :, None], kin.axes[j]  # (B, 3, 3, 1)
            ax = Rj[:, 0, 0] * x + Rj[:, 0, 1] * y + Rj[:, 0, 2] * z  # (B, 1)
            ay = Rj[:, 1, 0] * x + Rj[:, 1, 1] * y + Rj[:, 1, 2] * z
            az = Rj[:, 2, 0] * x + Rj[:, 2, 1] * y + Rj[:, 2, 2] * z
            tj = t[j][:, :, None]  # (B, 3, 1)
            dx, dy, dz = c[..., 0] - tj[:, 0], c[..., 1] - tj[:, 1], c[..., 2] - tj[:, 2]
            p = dx * ax + dy * ay + dz * az
            ex, ey, ez = dx - p * ax, dy - p * ay, dz - p * az
            acc = np.where(w != 0.0, acc + d * np.sqrt(ex * ex + ey * ey + ez * ez), acc)
        return acc

    def _slack(self, dq: Array) -> Array:
        """(S,) B_s (m) of an edge whose joints move ``dq`` (dof,) (module docstring): half
        the sum, over the revolute joints carrying sphere s, of a joint's motion times the
        bounds of the joints between it and the sphere (from the sphere's end of the chain)."""
        kin, disp = self.kin, self._displacement
        tail = np.zeros(len(self.radii))
        acc = np.zeros(len(self.radii))
        for j in range(kin.njoints - 1, 0, -1):
            col = kin.idx_q[j]
            w, d = disp[:, col], dq[col]
            carried = w != 0.0
            if not kin.prismatic[j]:
                acc = np.where(carried, acc + d * tail, acc)
            tail = np.where(carried, tail + d * w, tail)
        return 0.5 * acc

    def _dense_fails(
        self, q0: Array, q1: Array, reach: Array, pair_reach: Array, slack: Array
    ) -> list[int] | None:
        """The dense certificate of the edge q0 -> q1 (module docstring), each pass's samples
        as one batch: None if one of them is invalid, else the k (ascending) whose samples
        k and k + 1 of the finest split (:data:`DENSE_UNITS` intervals) fail the two-sample
        bound (none: the edge is certified). ``reach`` (S,), ``pair_reach`` (P,) and
        ``slack`` (S,) are the edge's (m)."""
        K = DENSE_SAMPLES
        c = DENSE_STRIDE if coarse_first(float(reach.max()), self.margin) else 1
        coarse = np.arange(0, K, c)
        holds = self._dense_bounds(q0, q1, coarse, K - 1, reach, pair_reach, slack)
        if holds is None:
            return None
        if c == 1 or holds.all():  # one pass, or every coarse interval certified whole
            fails = [int(c * k) for k in np.flatnonzero(~holds)]
        else:
            fine = _split(np.flatnonzero(~holds), c)
            holds = self._dense_bounds(q0, q1, fine, K - 1, reach, pair_reach, slack)
            if holds is None:
                return None
            fails = [int(k) for k in fine[:-1][~holds & (np.diff(fine) == 1)]]
        if not fails:
            return []
        split = _split(np.array(fails), DENSE_SPLIT)  # the failing intervals, split
        holds = self._dense_bounds(q0, q1, split, DENSE_UNITS, reach, pair_reach, slack)
        if holds is None:
            return None
        return [int(k) for k in split[:-1][~holds & (np.diff(split) == 1)]]

    def _dense_bounds(
        self, q0: Array, q1: Array, idx: npt.NDArray[np.int64], units: int, reach: Array,
        pair_reach: Array, slack: Array,
    ) -> Mask | None:  # fmt: skip
        """The dense certificate's samples ``idx`` / ``units`` (ascending) of the edge
        q0 -> q1: None if one is invalid, else whether each two consecutive ones satisfy the
        two-sample bound (a sphere's motion from each sample bounded as in the walk)."""
        t = idx / units
        Q = q0 + t[:, None] * (q1 - q0)
        if not np.all(self.robot.within_limits(Q)):
            return None
        centres = self.sphere_centers(Q)  # (K, S, 3)
        ws = self.world_spheres
        v = self.world.distance(centres[:, ws].reshape(-1, 3)).reshape(len(t), -1)
        v = np.minimum(v - self.world_radii[ws], CLEARANCE_CAP)
        if np.any(v < self.margin):
            return None
        diff = centres[:, self.pairs[:, 0]] - centres[:, self.pairs[:, 1]]
        g = np.sqrt(np.einsum("kpi,kpi->kp", diff, diff)) - (
            self.radii[self.pairs[:, 0]] + self.radii[self.pairs[:, 1]]
        )
        if np.any(g < 0.0):
            return None
        g = np.minimum(g, CLEARANCE_CAP)
        dt = (t[1:] - t[:-1])[:, None]
        lever = self._lever_sums(Q[:-1], np.abs(q1 - q0))[:, ws]
        motion = np.minimum(reach[ws] * dt, dt * (lever + dt * slack[ws]))
        holds: Mask = np.all(v[:-1] + v[1:] >= 2.0 * self.margin + motion, axis=1) & np.all(
            g[:-1] + g[1:] >= pair_reach * dt, axis=1
        )
        return holds

    def _sample_values(self, q0: Array, q1: Array, t: float) -> tuple[Array, Array] | None:
        """Capped clearances (S,) (+cap for spheres the world ignores) and gaps (P,) (m) at
        the point ``t`` of the edge q0 -> q1; None if that configuration is invalid."""
        q = q0 + t * (q1 - q0)
        if not self.robot.within_limits(q[None])[0]:
            return None
        centres = self.sphere_centers(q[None])[0]
        v = np.full(len(self.radii), CLEARANCE_CAP)
        ws = self.world_spheres
        v[ws] = np.minimum(self.world.distance(centres[ws]) - self.world_radii[ws], CLEARANCE_CAP)
        if np.any(v < self.margin):
            return None
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        diff = centres[i] - centres[j]
        g = np.sqrt(np.einsum("pi,pi->p", diff, diff)) - (self.radii[i] + self.radii[j])
        if np.any(g < 0.0):
            return None
        return v, np.minimum(g, CLEARANCE_CAP)

    def _sampled_valid(
        self, Q0: Array, Q1: Array, steps: npt.NDArray[np.int64], stride: int
    ) -> Mask:
        """(E,) validity of sub-steps k = 0, stride, 2 stride, ... and k = steps of each edge
        (sample k at fraction k / steps), as one batch."""
        counts = steps // stride + 1 + (steps % stride != 0)
        edge_of = np.repeat(np.arange(len(steps)), counts)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        k = np.minimum((np.arange(edge_of.size) - starts[edge_of]) * stride, steps[edge_of])
        frac = k / steps[edge_of]
        samples = Q0[edge_of] + frac[:, None] * (Q1 - Q0)[edge_of]
        return np.logical_and.reduceat(self.config_valid(samples), starts)

    def edge_valid(self, q0: Array, q1: Array) -> bool:
        """Is the straight edge q0 -> q1 valid (see :meth:`edges_valid`)?"""
        return bool(self.edges_valid(np.asarray(q0)[None], np.asarray(q1)[None])[0])

    def first_invalid_edge(self, path: Array) -> int | None:
        """Index i of the first invalid edge path[i] -> path[i+1], or None if all are valid."""
        path = self._batch(path)
        if len(path) < 2:
            return None if bool(self.config_valid(path).all()) else 0
        ok = self.edges_valid(path[:-1], path[1:])
        bad = np.flatnonzero(~ok)
        return int(bad[0]) if bad.size else None

    def _batch(self, Q: Array) -> Array:
        arr = np.asarray(Q, dtype=float)
        if arr.ndim != 2 or arr.shape[1] != self.robot.dof:
            raise PlanningError(
                f"expected configurations of shape (B, {self.robot.dof}), got {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise PlanningError("configurations contain NaN or inf")
        return arr
