"""The compiled checker against the numpy reference (exact agreement), against Pinocchio
(forward kinematics) and against dense sampling (the certified edge keeps the margin)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from gaide_core.errors import ConfigError, PlanningError, RobotModelError
from gaide_core.transforms import from_xyz_rpy
from planning.checker import make_checker
from planning.collision import (
    CLEARANCE_CAP,
    DENSE_MIN_STEPS,
    DENSE_SAMPLES,
    DENSE_STRIDE,
    DENSE_UNITS,
    SphereCollisionChecker,
    coarse_first,
)
from planning.compiled import lanes, validity
from planning.compiled.checker import CompiledChecker
from planning.compiled.layout import BLOCK
from planning.compiled.tables import block_minima
from planning.distance_field import CloudWorld
from planning.kinematics import reference_points
from planning.primitives import Box, Cylinder, PrimitiveWorld, Sphere
from planning.robot_model import RobotModel, load_robot
from planning.sphere_model import SphereModel


def _workcell() -> PrimitiveWorld:
    """A table under the robot, a shelf-like box, a post and a ball: every primitive kind."""
    return PrimitiveWorld(
        [
            Box(np.array([1.4, 1.4, 0.04]), from_xyz_rpy([0.1, 0, -0.04], [0, 0, 0])),
            Box(np.array([0.3, 0.6, 0.02]), from_xyz_rpy([0.55, 0.1, 0.35], [0, 0, 0.3])),
            Cylinder(0.05, 0.6, from_xyz_rpy([-0.3, 0.4, 0.3], [0.2, 0, 0])),
            Sphere(0.08, np.array([0.2, -0.45, 0.4])),
        ]
    )


@pytest.fixture(scope="module")
def worlds(spheres: SphereModel) -> dict[str, object]:
    prims = _workcell()
    rng = np.random.default_rng(3)
    return {
        "empty": None,
        "primitives": prims,
        "cloud": CloudWorld(prims.sample_surface(20_000, rng), voxel=0.01),
    }


def _both(
    robot: RobotModel, spheres: SphereModel, world: object
) -> tuple[SphereCollisionChecker, CompiledChecker]:
    """The numpy reference and the compiled checker of one world."""
    return (
        SphereCollisionChecker(robot, spheres, world),  # type: ignore[arg-type]
        CompiledChecker(robot, spheres, world),  # type: ignore[arg-type]
    )


def _near(checker: SphereCollisionChecker, rng: np.random.Generator, n: int) -> np.ndarray:
    """n configurations whose nearest sphere is within 5 cm of the world (valid or not)."""
    out = []
    while sum(len(o) for o in out) < n:
        Q = checker.robot.sample_uniform(rng, 4000)
        out.append(Q[checker.world_clearance(Q) < 0.05])
    return np.concatenate(out)[:n]


def _valid_near(
    checker: SphereCollisionChecker, rng: np.random.Generator, candidates: int, n: int
) -> np.ndarray:
    """The valid ones among ``candidates`` configurations near the world (:func:`_near`),
    at most n: starts of edges that graze the obstacles."""
    starts = _near(checker, rng, candidates)
    return starts[checker.config_valid(starts)][:n]


@pytest.mark.parametrize("kind", ["empty", "primitives", "cloud"])
def test_configurations_agree_exactly(
    kind: str, worlds: dict[str, object], robot: RobotModel, spheres: SphereModel
) -> None:
    world = worlds[kind]
    ref, fast = _both(robot, spheres, world)
    rng = np.random.default_rng(0)
    Q = robot.sample_uniform(rng, 4000)
    if kind != "empty":
        Q = np.concatenate([Q, _near(ref, rng, 4000)])
    expected = ref.config_valid(Q)
    np.testing.assert_array_equal(fast.config_valid(Q), expected)
    assert 0.05 < expected.mean() < 0.95, "both valid and invalid configurations are tested"
    singles = [fast.config_valid_one(q) for q in Q[:300]]
    np.testing.assert_array_equal(singles, expected[:300])


@pytest.mark.parametrize("kind", ["empty", "primitives", "cloud", "small cloud"])
def test_batches_of_any_size_agree_with_the_single_check(
    kind: str, worlds: dict[str, object], robot: RobotModel, spheres: SphereModel
) -> None:
    # Batches go through the lane kernel (planning.compiled.lanes), single configurations
    # through the scalar one: the same answer for every lane of a full or partial pass,
    # outside the joint limits, and (small cloud) for spheres outside the cloud's lattice.
    rng = np.random.default_rng(6)
    if kind == "small cloud":
        world = CloudWorld(rng.normal([0.45, 0.1, 0.35], 0.06, size=(400, 3)), voxel=0.01)
    else:
        world = worlds[kind]  # type: ignore[assignment]
    ref, fast = _both(robot, spheres, world)
    Q = robot.sample_uniform(rng, 1400)
    if kind != "empty":
        Q[:700] = _near(ref, rng, 700)
    Q[::9, 2] = robot.upper[2] + 0.01  # outside the limits
    Q[::13, 0] = 2.0e5  # beyond the sine reduction's range (the library's sin and cos)
    expected = np.array([fast.config_valid_one(q) for q in Q])
    np.testing.assert_array_equal(ref.config_valid(Q), expected)
    assert 0.05 < expected.mean() < 0.95, "both valid and invalid configurations are tested"
    start = 0
    for size in (1, 63, 64, 65, 130, 1077):
        batch = Q[start : start + size]
        np.testing.assert_array_equal(fast.config_valid(batch), expected[start : start + size])
        start += size
    assert start == len(Q)


def test_block_minima_are_the_smallest_value_of_each_block() -> None:
    rng = np.random.default_rng(7)
    field = rng.random((13, 9, 17)).astype(np.float32)  # no side a multiple of the block
    minima = block_minima(field).reshape(2, 2, 3)
    for idx in np.ndindex(*minima.shape):
        block = field[tuple(slice(i * BLOCK, (i + 1) * BLOCK) for i in idx)]
        assert minima[idx] == block.min()


@pytest.mark.parametrize("kind", ["empty", "primitives", "cloud"])
def test_edges_agree_exactly(
    kind: str, worlds: dict[str, object], robot: RobotModel, spheres: SphereModel
) -> None:
    world = worlds[kind]
    ref, fast = _both(robot, spheres, world)
    rng = np.random.default_rng(1)
    Q = robot.sample_uniform(rng, 3000)
    if kind != "empty":
        Q = np.concatenate([Q, _near(ref, rng, 3000)])
    starts = Q[ref.config_valid(Q)][:150]
    # Long random edges, and short ones that stay near the obstacles.
    ends = np.concatenate(
        [
            starts[:75] + rng.normal(size=(75, 6)) * 0.8,
            starts[75:] + rng.normal(size=(len(starts) - 75, 6)) * 0.15,
        ]
    )
    ends = np.clip(ends, robot.lower, robot.upper)
    expected = ref.edges_valid(starts, ends)
    np.testing.assert_array_equal(fast.edges_valid(starts, ends), expected)
    assert 0.05 < expected.mean() < 0.95
    singles = [fast.edge_valid_one(a, b) for a, b in zip(starts[:40], ends[:40], strict=True)]
    np.testing.assert_array_equal(singles, expected[:40])
    path = np.concatenate([starts[:1], ends[:6]])
    assert fast.first_invalid_edge(path) == ref.first_invalid_edge(path)
    np.testing.assert_array_equal(fast.edge_steps(starts, ends), ref.edge_steps(starts, ends))


def test_the_planners_screen_is_the_validity_of_its_points(
    worlds: dict[str, object], robot: RobotModel, spheres: SphereModel
) -> None:
    # rrtc and the shortcut pass screen an edge by its points at 1/2, 1/4 and 3/4 before
    # certifying it: the screen is exactly the reference's validity of those points (that
    # the planners' paths stay certified is held in test_rrtc.py).
    from planning.compiled import validity

    world = worlds["cloud"]
    ref, fast = _both(robot, spheres, world)
    rng = np.random.default_rng(4)
    starts = _valid_near(ref, rng, 2000, 200)
    ends = np.clip(starts + rng.normal(size=starts.shape) * 0.6, robot.lower, robot.upper)
    screened = np.empty(len(starts), bool)
    validity.edges_screened(*fast.tables.args(), starts, ends, fast.margin, screened)
    expected = [
        bool(ref.config_valid(np.stack([a + f * (b - a) for f in (0.5, 0.25, 0.75)])).all())
        for a, b in zip(starts, ends, strict=True)
    ]
    np.testing.assert_array_equal(screened, expected)
    assert 0.1 < screened.mean() < 0.9, "edges the screen passes and rejects are tested"


def test_a_certified_edge_keeps_the_margin_at_every_point(
    worlds: dict[str, object], robot: RobotModel, spheres: SphereModel
) -> None:
    # Dense sampling (a tenth of the resolution) of certified edges near the obstacles: every
    # sample keeps the margin from the exact primitives and no self pair overlaps.
    world = worlds["primitives"]
    fast = CompiledChecker(robot, spheres, world)  # type: ignore[arg-type]
    fine = SphereCollisionChecker(
        robot,
        spheres,
        world,
        resolution=robot.config.edge_resolution / 10,  # type: ignore[arg-type]
    )
    rng = np.random.default_rng(2)
    starts = _valid_near(fast, rng, 3000, 120)
    ends = np.clip(starts + rng.normal(size=starts.shape) * 0.3, robot.lower, robot.upper)
    ok = fast.edges_valid(starts, ends)
    assert ok.sum() >= 30
    assert fine.edges_valid_sampled(starts[ok], ends[ok]).all()
    clearance = np.concatenate(
        [
            fine.world_clearance(a + np.linspace(0, 1, 400)[:, None] * (b - a))
            for a, b in zip(starts[ok], ends[ok], strict=True)
        ]
    )
    assert clearance.min() >= fast.margin


@pytest.mark.parametrize("kind", ["primitives", "cloud"])
def test_a_world_raise_agrees_exactly_and_keeps_each_sphere_its_own_clearance(
    kind: str, worlds: dict[str, object], robot: RobotModel, spheres: SphereModel
) -> None:
    # The oracle keeps each sphere its own extra clearance from the world (self pairs keep
    # the radii): both backends agree on it exactly, a configuration is valid under it when
    # it is valid and every sphere clears the margin by its raise, and a certified edge keeps
    # each sphere's raised margin at every point.
    world = worlds[kind]
    rng = np.random.default_rng(6)
    plain = SphereCollisionChecker(robot, spheres, world)  # type: ignore[arg-type]
    # No raise for the spheres that stay by the table in every pose (as the oracle does).
    farthest = plain.sphere_clearance(robot.sample_uniform(rng, 500)).max(axis=0)
    raise_ = np.where(farthest > 0.04, rng.uniform(0.0, 0.03, len(spheres.radii)), 0.0)
    assert np.count_nonzero(raise_) >= len(raise_) // 2
    ref = plain.with_world_raise(raise_)
    fast = CompiledChecker(robot, spheres, world).with_world_raise(raise_)  # type: ignore[arg-type]
    Q = np.concatenate([robot.sample_uniform(rng, 2000), _near(plain, rng, 3000)])
    expected = ref.config_valid(Q)
    np.testing.assert_array_equal(fast.config_valid(Q), expected)
    kept = (plain.sphere_clearance(Q) - raise_ >= plain.margin).all(axis=1)
    np.testing.assert_array_equal(expected, plain.config_valid(Q) & kept)
    assert 0.05 < expected.mean() < 0.95 and np.any(plain.config_valid(Q) & ~kept)
    starts = Q[expected][:150]
    ends = np.clip(starts + rng.normal(size=starts.shape) * 0.3, robot.lower, robot.upper)
    ok = ref.edges_valid(starts, ends)
    np.testing.assert_array_equal(fast.edges_valid(starts, ends), ok)
    assert ok.sum() >= 30
    dense = np.concatenate(
        [
            a + np.linspace(0, 1, 400)[:, None] * (b - a)
            for a, b in zip(starts[ok], ends[ok], strict=True)
        ]
    )
    if kind == "primitives":  # exact distances (a cloud's lattice is exact at its voxels)
        assert (plain.sphere_clearance(dense) - raise_).min() >= plain.margin
    with pytest.raises(PlanningError, match="one finite value >= 0"):
        plain.with_world_raise(-raise_)
    if kind == "cloud":
        with pytest.raises(PlanningError, match="exact only up to"):
            fast.with_world_raise(np.full(len(raise_), 1.0))


def test_the_dense_certificate_proves_what_it_claims(
    worlds: dict[str, object], robot: RobotModel, spheres: SphereModel
) -> None:
    # Long edges from near the obstacles: some certified by the dense certificate alone,
    # some refused by one of its samples, some walked where its bound fails; and short ones,
    # walked whole. The compiled certificate finds the same, the compiled checker answers as
    # the reference, and every edge the certificate passes keeps the margin at a tenth of the
    # resolution.
    world = worlds["primitives"]
    ref, fast = _both(robot, spheres, world)
    rng = np.random.default_rng(8)
    starts = _valid_near(ref, rng, 4000, 340)
    scale = np.repeat([0.25, 0.8, 0.5, 0.04], [100, 100, 100, 40])[:, None]
    ends = np.clip(starts + rng.normal(size=starts.shape) * scale, robot.lower, robot.upper)
    # and long edges through configurations 6-20 mm from the obstacles
    near = _near(ref, rng, 3000)
    clearance = ref.world_clearance(near)
    graze = near[(clearance > 0.006) & (clearance < 0.02) & ref.config_valid(near)][:150]
    way = rng.normal(size=graze.shape)
    way /= np.linalg.norm(way, axis=1, keepdims=True)
    before = np.clip(graze - way, robot.lower, robot.upper)
    after = np.clip(graze + way, robot.lower, robot.upper)
    ends_valid = ref.config_valid(before) & ref.config_valid(after)
    # and 1 rad edges leaving a configuration 1 mm above the margin: the finest parts of the
    # dense certificate fail there, and the walk takes them
    leave, away = _from_the_margin(ref, rng, _valid_near(ref, rng, 4000, 340), 0.001)
    starts = np.concatenate([starts, before[ends_valid], leave])
    ends = np.concatenate([ends, after[ends_valid], away])
    steps = ref.edge_steps(starts, ends)
    long = steps >= DENSE_MIN_STEPS
    expected, found = _dense_answers(ref, fast, starts[long], ends[long])
    assert expected.count(()) >= 10, "edges the certificate passes"
    assert expected.count(None) >= 10, "edges one of its samples refuses"
    assert sum(bool(e) for e in expected) >= 4, "edges walked where its bound fails"
    assert (~long).sum() >= 10, "short edges, walked from the start"
    # both kinds of dense certificate (coarse_first): one pass of all the samples, and coarse
    # samples first with some coarse intervals certified whole and some refined
    coarse = np.array(
        [
            coarse_first(float(_reaches(ref, a, b)[0].max()), ref.margin)
            for a, b in zip(starts, ends, strict=True)
        ]
    )
    assert (long & ~coarse).sum() >= 10, "long edges sampled in one pass"
    strided = np.arange(0, DENSE_SAMPLES, DENSE_STRIDE)
    mixed = [
        holds is not None and 0 < holds.sum() < len(holds)
        for holds in (
            ref._dense_bounds(a, b, strided, DENSE_SAMPLES - 1, *_reaches(ref, a, b))
            for a, b in zip(starts[long & coarse], ends[long & coarse], strict=True)
        )
    ]
    assert sum(mixed) >= 10, "coarse intervals certified whole beside refined ones"
    # the compiled certificate leaves out the links and pair groups whose bounding balls
    # already pass (lanes._link_clear, lanes._self_values) and must find the same
    assert found == expected
    valid = ref.edges_valid(starts, ends)
    np.testing.assert_array_equal(fast.edges_valid(starts, ends), valid)
    refused = np.array([e is None for e in expected])
    passed = np.array([e == () for e in expected])
    assert not valid[long][refused].any()
    assert valid[long][passed].all()
    fine = SphereCollisionChecker(
        robot,
        spheres,
        world,
        resolution=robot.config.edge_resolution / 10,  # type: ignore[arg-type]
    )
    assert fine.edges_valid_sampled(starts[long][passed], ends[long][passed]).all()


def test_a_pass_capped_lower_decides_every_bound_as_the_reference_cap() -> None:
    # The dense certificate's passes cap the world values at lanes._world_cap, the
    # reference at CLEARANCE_CAP: for two valid neighbours (values >= margin) of any sphere
    # whose reach is at most the pass's top, at most the pass's largest dt apart, the
    # two-sample bound must come out the same. Drawn at its edges: a value at the margin,
    # the fastest sphere, the widest interval.
    rng = np.random.default_rng(12)
    for _ in range(3000):
        margin = float(rng.choice([0.0, 0.005, rng.uniform(0, 0.02)]))
        top = float(rng.choice([0.0, rng.uniform(0, 0.5), rng.uniform(0, 3.0)]))
        n = int(rng.integers(1, 65))
        dt = np.zeros(64)
        dt[: n - 1] = rng.uniform(0, 1 / 9, n - 1) * (rng.random(n - 1) < 0.8)
        cap = lanes._world_cap(top, margin, dt, n)
        assert margin < cap <= CLEARANCE_CAP
        far = dt[: n - 1].max(initial=0.0)
        reach = np.array([top, rng.uniform(0, top)])[:, None]
        gap = np.array([far, rng.uniform(0, far)])[None, :, None]
        a = np.array([margin, rng.uniform(margin, 0.15)])[None, None, :, None]
        b = np.array([margin, rng.uniform(margin, 0.15), 0.15])[None, None, None, :]
        need = 2.0 * margin + reach[..., None, None] * gap[..., None]
        ours = np.minimum(a, cap) + np.minimum(b, cap) >= need
        theirs = np.minimum(a, CLEARANCE_CAP) + np.minimum(b, CLEARANCE_CAP) >= need
        np.testing.assert_array_equal(ours, theirs)


def test_the_dense_certificate_near_self_contact_finds_what_the_reference_finds(
    robot: RobotModel, spheres: SphereModel
) -> None:
    # In the empty world only the self pairs decide. The compiled certificate leaves out the
    # pair groups whose links' bounding spheres already pass (lanes._self_values), which the
    # reference does not. Long edges through configurations near self contact (below) must
    # give the same first failing interval (or -1, or none) and the same answer.
    ref, fast = _both(robot, spheres, None)
    rng = np.random.default_rng(11)
    i, j = ref.pairs[:, 0], ref.pairs[:, 1]
    bound_a = np.array([g[0] for g in ref._link_groups])
    bound_b = np.array([g[1] for g in ref._link_groups])
    bound_reach = np.sqrt([g[3] for g in ref._link_groups])
    # configurations with two links' bounding spheres 0-10 mm apart, two spheres 0.5-5 mm
    # apart, two spheres overlapping by 0.5-5 mm, two spheres 0.05-0.5 mm apart (where even
    # the certificate's finest parts fail)
    kinds: list[list[np.ndarray]] = [[], [], [], []]
    while min(sum(map(len, k)) for k in kinds) < 300:
        Q = robot.sample_uniform(rng, 4000)
        points = ref.kin.points(Q, ref.point_joint, ref.point_local)
        link_gap = np.linalg.norm(points[:, bound_a] - points[:, bound_b], axis=2) - bound_reach
        gaps = np.linalg.norm(points[:, i] - points[:, j], axis=2) - (ref.radii[i] + ref.radii[j])
        low = gaps.min(axis=1)
        kinds[0].append(Q[((link_gap > 0) & (link_gap < 0.01)).any(axis=1)])
        kinds[1].append(Q[(low > 0.0005) & (low < 0.005)])
        kinds[2].append(Q[(low > -0.005) & (low < -0.0005)])
        kinds[3].append(Q[(low > 0.00005) & (low < 0.0005)])
    mid = np.concatenate([np.concatenate(k)[:300] for k in kinds])
    way = rng.normal(size=mid.shape)
    # short edges keep every lane near the configuration; long ones sweep past it
    way *= (
        np.tile(np.repeat([0.05, 0.7, 1.4], 100), 4)[:, None] / np.linalg.norm(way, axis=1)[:, None]
    )
    before = np.clip(mid - way, robot.lower, robot.upper)
    after = np.clip(mid + way, robot.lower, robot.upper)
    keep = ref.config_valid(before) & ref.config_valid(after)
    before, after = before[keep], after[keep]
    expected, found = _dense_answers(ref, fast, before, after)
    assert expected.count(()) >= 10, "edges the certificate passes"
    assert sum(bool(e) for e in expected) >= 10, "edges walked where its bound fails"
    assert sum(e is not None and len(e) > 1 for e in expected) >= 5, "in several parts"
    assert expected.count(None) >= 10, "edges one of its samples refuses"
    assert found == expected
    valid = ref.edges_valid(before, after)
    assert 10 <= valid.sum() <= len(valid) - 10, "edges certified and edges refused"
    np.testing.assert_array_equal(fast.edges_valid(before, after), valid)
    # where the bound fails in runs apart, each run is walked on its own: as the reference.
    # Edges between two configurations 0.05-0.5 mm from self contact fail at both ends.
    touching = np.concatenate(kinds[3])[:300]
    a, b = touching[:-1], touching[1:]
    expected, found = _dense_answers(ref, fast, a, b)
    assert found == expected
    assert sum(_runs(e) > 1 for e in expected) >= 2, "edges failing in two runs or more"
    np.testing.assert_array_equal(fast.edges_valid(a, b), ref.edges_valid(a, b))


def test_pair_groups_whose_balls_are_apart_but_fail_the_bound_are_not_left_out(
    robot: RobotModel, spheres: SphereModel
) -> None:
    # A pair group may be left out only when its links' balls are apart in every lane AND
    # pass the two-sample bound. Edges where some group is apart in every lane of the
    # certificate's first pass but fails the bound are where a skip that forgot the bound
    # would answer otherwise. Random long edges in the empty world take one pass of all the
    # samples (coarse_first); a quarter of them are such edges (310 of 1,317), and on 4% of
    # those the forgotten bound changed the first failing interval (measured with the bound
    # removed from lanes._self_values). The same edges cut to a fifth mostly take the coarse
    # samples first, and a fifth of those are such edges there (183 of 855). A group's balls
    # overlapping in a lane need no edges of their own: the gap cannot change by more than
    # the reach between lanes, so an overlap in one lane already fails the bound with its
    # neighbour.
    ref, fast = _both(robot, spheres, None)
    rng = np.random.default_rng(5)
    starts, ends = robot.sample_uniform(rng, 1500), robot.sample_uniform(rng, 1500)
    ends = np.concatenate([ends, starts + 0.2 * (ends - starts)])
    starts = np.concatenate([starts, starts])
    keep = ref.config_valid(starts) & ref.config_valid(ends)
    starts, ends = starts[keep], ends[keep]
    coarse = np.array(
        [
            coarse_first(float(_reaches(ref, a, b)[0].max()), ref.margin)
            for a, b in zip(starts, ends, strict=True)
        ]
    )
    groups = ref._link_groups
    ball_a, ball_b = [g[0] for g in groups], [g[1] for g in groups]
    pair_reach = np.abs(ends - starts) @ ref._pair_displacement.T  # (edges, pairs), as _reaches
    group_reach = np.stack([pair_reach[:, g[2]].max(axis=1) for g in groups], axis=1)
    edge = np.zeros(len(starts), bool)
    for kind, stride in ((~coarse, 1), (coarse, DENSE_STRIDE)):
        # each group's ball gap in the first pass's lanes, capped as the certificate caps it
        t = np.arange(0, DENSE_SAMPLES, stride) / (DENSE_SAMPLES - 1)
        a, b = starts[kind], ends[kind]
        lanes = a[:, None] + t[None, :, None] * (b - a)[:, None]
        points = ref.kin.points(lanes.reshape(-1, robot.dof), ref.point_joint, ref.point_local)
        points = points.reshape(len(a), len(t), -1, 3)
        ball_gap = np.linalg.norm(points[:, :, ball_a] - points[:, :, ball_b], axis=3)
        ball_gap = np.minimum(ball_gap - np.sqrt([g[3] for g in groups]), CLEARANCE_CAP)
        apart = (ball_gap >= 0).all(axis=1)
        reach = group_reach[kind][:, None]
        bound = (ball_gap[:, :-1] + ball_gap[:, 1:] >= reach * t[1]).all(axis=1)
        edge[kind] = (apart & ~bound).any(axis=1)
    assert (edge & ~coarse).sum() >= 150, "one-pass edges where a group is apart but fails"
    assert (edge & coarse).sum() >= 150, "coarse-first edges where a group is apart but fails"
    expected, found = _dense_answers(ref, fast, starts[edge], ends[edge])
    assert found == expected
    np.testing.assert_array_equal(
        fast.edges_valid(starts[edge], ends[edge]), ref.edges_valid(starts[edge], ends[edge])
    )


def _from_the_margin(
    checker: SphereCollisionChecker, rng: np.random.Generator, Q: np.ndarray, room: float
) -> tuple[np.ndarray, np.ndarray]:
    """Edges of 1 rad from the configurations ``room`` (m) above the margin that ``Q``
    reaches in a random direction within 0.3 rad, away from the obstacle the other way."""
    robot = checker.robot
    way = rng.normal(size=Q.shape)
    way /= np.linalg.norm(way, axis=1, keepdims=True)

    def clear(t: np.ndarray) -> np.ndarray:
        q = np.clip(Q + t[:, None] * way, robot.lower, robot.upper)
        return checker.config_valid(q) & (checker.world_clearance(q) >= checker.margin + room)

    lo, hi = np.zeros(len(Q)), np.full(len(Q), 0.3)
    meets = ~clear(hi)
    for _ in range(30):  # bisection: lo clears, hi does not
        mid = (lo + hi) / 2
        ok = clear(mid)
        lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
    start = np.clip(Q + lo[:, None] * way, robot.lower, robot.upper)[meets]
    end = np.clip(start - way[meets], robot.lower, robot.upper)
    valid = checker.config_valid(end)
    return start[valid], end[valid]


def _dense_answers(
    ref: SphereCollisionChecker, fast: CompiledChecker, starts: np.ndarray, ends: np.ndarray
) -> tuple[list[tuple[int, ...] | None], list[tuple[int, ...] | None]]:
    """The dense certificate's answer for each edge, by the reference and by the compiled
    kernel: None where one of its samples refuses the edge, else the first samples of the
    intervals whose bound fails (none: certified)."""
    I, F, field = fast.kernel_tables().args()  # noqa: E741 (layout names)
    expected, found = [], []
    fails = np.empty(DENSE_UNITS, np.int64)
    for a, b in zip(starts, ends, strict=True):
        ks = ref._dense_fails(a, b, *_reaches(ref, a, b))
        expected.append(None if ks is None else tuple(ks))
        m = validity.dense_certificate(I, F, field, a, b, ref.margin, ref.resolution, fails)
        found.append(None if m < 0 else tuple(int(k) for k in fails[:m]))
    return expected, found


def _runs(fails: tuple[int, ...] | None) -> int:
    """How many runs of neighbouring intervals ``fails`` holds (each is one walk)."""
    if not fails:
        return 0
    return 1 + sum(b > a + 1 for a, b in itertools.pairwise(fails))


def _reaches(
    ref: SphereCollisionChecker, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sphere and self-pair reach and sphere slack (m) over the edge a -> b, as the walk
    computes them."""
    motion = np.abs(b - a)
    return (
        (motion * ref._displacement).sum(axis=1),
        (motion * ref._pair_displacement).sum(axis=1),
        ref._slack(motion),
    )


@pytest.mark.parametrize("kind", ["primitives", "cloud"])
def test_speed_does_not_come_from_leniency(
    kind: str, worlds: dict[str, object], robot: RobotModel, spheres: SphereModel
) -> None:
    # Certified edges are a subset of the edges whose resolution samples are all valid.
    world = worlds[kind]
    fast = CompiledChecker(robot, spheres, world)  # type: ignore[arg-type]
    rng = np.random.default_rng(4)
    Q = robot.sample_uniform(rng, 2000)
    starts = Q[fast.config_valid(Q)][:200]
    ends = np.clip(starts + rng.normal(size=starts.shape) * 0.5, robot.lower, robot.upper)
    certified = fast.edges_valid(starts, ends)
    sampled = fast.edges_valid_sampled(starts, ends)
    assert not np.any(certified & ~sampled)


def test_make_checker_picks_the_backend(robot: RobotModel, spheres: SphereModel) -> None:
    assert make_checker(robot, spheres).backend == "compiled"
    assert type(make_checker(robot, spheres, backend="numpy")) is SphereCollisionChecker
    with pytest.raises(ConfigError, match="valid: compiled, numpy"):
        make_checker(robot, spheres, backend="gpu")


def test_an_unknown_world_is_refused_by_name(robot: RobotModel, spheres: SphereModel) -> None:
    class Fog:
        def distance(self, points: np.ndarray) -> np.ndarray:
            return np.full(len(points), 1.0)

    with pytest.raises(PlanningError, match=r"not Fog.*--checker numpy"):
        CompiledChecker(robot, spheres, Fog())  # type: ignore[arg-type]
    assert SphereCollisionChecker(robot, spheres, Fog()).config_valid(np.zeros((1, 6)))[0]  # type: ignore[arg-type]


# -- any serial chain: revolute (aligned or not), prismatic, a base pose ---------------------

CHAIN = """<robot name="chain">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <joint name="yaw" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <link name="l1"/>
  <joint name="slide" type="prismatic"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.05 0 0.2" rpy="0 0.3 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.4" velocity="0.5" effort="1"/></joint>
  <link name="l2"/>
  <joint name="tilt" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.1 0 0" rpy="0.2 0 0.4"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
  <link name="l3"/>
  <joint name="fix" type="fixed"><parent link="l3"/><child link="tip"/>
    <origin xyz="0.25 0 0"/></joint>
  <link name="tip"/>
</robot>"""

CHAIN_SPHERES = """collision_spheres:
  base: [{center: [0, 0, 0], radius: 0.08}]
  l1: [{center: [0, 0, 0.05], radius: 0.05}, {center: [0, 0, 0.15], radius: 0.05}]
  l2: [{center: [0.05, 0, 0], radius: 0.04}, {center: [0.15, 0, 0], radius: 0.04}]
  l3: [{center: [0.05, 0, 0], radius: 0.03}, {center: [0.15, 0.02, 0], radius: 0.03}]
  tip: [{center: [0.02, 0, 0], radius: 0.02}]
"""


@pytest.fixture(scope="module")
def chain(tmp_path_factory: pytest.TempPathFactory) -> tuple[RobotModel, SphereModel]:
    d: Path = tmp_path_factory.mktemp("chain")
    (d / "chain.urdf").write_text(CHAIN)
    (d / "spheres.yaml").write_text(CHAIN_SPHERES)
    (d / "chain.yaml").write_text(
        "urdf: chain.urdf\nspheres: spheres.yaml\nend_effector: tip\n"
        "base_pose: {xyz: [0.3, -0.2, 0.5], rpy: [0.1, -0.2, 0.7]}\n"
        "world_ignored_links: [base]\n"
    )
    robot = load_robot(d / "chain.yaml")
    return robot, SphereModel.load(d / "spheres.yaml")


def test_any_serial_chain_matches_pinocchio_and_the_reference(
    chain: tuple[RobotModel, SphereModel],
) -> None:
    robot, spheres = chain
    world = PrimitiveWorld(
        [Box(np.array([0.3, 0.3, 0.3]), from_xyz_rpy([0.6, -0.1, 0.9], [0, 0, 0]))]
    )
    ref, fast = _both(robot, spheres, world)
    rng = np.random.default_rng(5)
    Q = robot.sample_uniform(rng, 3000)
    for q in Q[:50]:
        centres = fast.sphere_centers(q[None])[0]
        truth = reference_points(robot, q, fast.sphere_joint, fast.sphere_local)
        np.testing.assert_allclose(centres, truth, atol=1e-12)
    expected = ref.config_valid(Q)
    assert 0.05 < expected.mean() < 0.95
    np.testing.assert_array_equal(fast.config_valid(Q), expected)
    starts = Q[expected][:100]
    ends = np.clip(starts + rng.normal(size=starts.shape) * 0.4, robot.lower, robot.upper)
    np.testing.assert_array_equal(fast.edges_valid(starts, ends), ref.edges_valid(starts, ends))


@pytest.mark.parametrize(
    ("joint", "kind"),
    [("floating", "floating"), ("planar", "planar"), ("continuous", "continuous")],
)
def test_joints_no_checker_can_represent_are_refused_by_name(
    tmp_path: Path, joint: str, kind: str
) -> None:
    urdf = CHAIN.replace('name="tilt" type="revolute"', f'name="tilt" type="{joint}"')
    (tmp_path / "chain.urdf").write_text(urdf)
    (tmp_path / "chain.yaml").write_text("urdf: chain.urdf\nend_effector: tip\n")
    with pytest.raises(RobotModelError, match=f"joint 'tilt' is {kind}"):
        load_robot(tmp_path / "chain.yaml")


def test_the_cli_refuses_an_unsupported_joint_in_one_line(tmp_path: Path) -> None:
    from tests.conftest import run_cli

    (tmp_path / "chain.urdf").write_text(
        CHAIN.replace('name="yaw" type="revolute"', 'name="yaw" type="floating"')
    )
    (tmp_path / "chain.yaml").write_text("urdf: chain.urdf\nend_effector: tip\n")
    out = run_cli("plan", "--family", "tabletop", "--robot", str(tmp_path / "chain.yaml"),
                  "--planner", "rrtc", "-o", str(tmp_path / "p.json"))  # fmt: skip
    assert out.returncode == 6, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "joint 'yaw' is floating" in lines[0]
    assert not (tmp_path / "p.json").exists()


def test_cached_kernels_are_dropped_when_any_source_of_the_package_changes(
    tmp_path: Path,
) -> None:
    from planning.compiled import drop_stale_kernels

    package = tmp_path / "compiled"
    package.mkdir()
    constants = tmp_path / "collision.py"  # outside the package: constants the kernels read
    constants.write_text("CAP = 0.1\n")
    (package / "geometry.py").write_text("A = 1\n")
    (package / "validity.py").write_text("B = 2\n")
    cache = package / "__pycache__"
    cache.mkdir()
    kernel = [
        cache / "validity.config_ok-80.py311.nbi",
        cache / "validity.config_ok-80.py311.1.nbc",
    ]
    bytecode = cache / "validity.cpython-311.pyc"
    bytecode.write_text("not numba's")
    for f in kernel:
        f.write_text("old machine code")
    assert drop_stale_kernels(package, (constants,))  # no stamp yet: unknown sources
    assert not any(f.exists() for f in kernel)
    for f in kernel:
        f.write_text("new machine code")
    assert not drop_stale_kernels(package, (constants,))  # same sources: the cache stays
    assert all(f.exists() for f in kernel)
    (package / "geometry.py").write_text("A = 3\n")  # not the kernel's own module
    assert drop_stale_kernels(package, (constants,))
    assert not any(f.exists() for f in kernel)
    for f in kernel:
        f.write_text("new machine code")
    assert not drop_stale_kernels(package, (constants,))
    constants.write_text("CAP = 0.2\n")  # a constant the kernels compiled in
    assert drop_stale_kernels(package, (constants,))
    assert not any(f.exists() for f in kernel)
    assert bytecode.exists()


@pytest.mark.parametrize("kind", ["primitives", "cloud"])
def test_the_band_penalty_is_the_reference_clearances_shortfall_and_its_gradient(
    robot: RobotModel, spheres: SphereModel, worlds: dict[str, object], kind: str
) -> None:
    # planning.compiled.band_kernel against the numpy reference's clearances and gaps.
    from planning.compiled.band_kernel import penalty_gradient

    ref, fast = _both(robot, spheres, worlds[kind])
    rng = np.random.default_rng(11)
    Q = _near(ref, rng, 60)
    need, need_self = ref.margin + 0.03, 0.03
    I, F, field = fast.kernel_tables().args()  # noqa: E741 (layout names)
    moving = ref._displacement.sum(axis=1) > 0  # spheres some joint moves
    grad = np.zeros_like(Q)
    for b, q in enumerate(Q):
        world = np.maximum(0.0, need - ref.sphere_clearance(q[None])[0])[moving]
        c = ref.sphere_centers(q[None])[0]
        i, j = ref.pairs.T
        gaps = np.linalg.norm(c[i] - c[j], axis=1) - ref.radii[i] - ref.radii[j]
        expected = world @ world + np.sum(np.maximum(0.0, need_self - gaps) ** 2)
        got = penalty_gradient(I, F, field, q[None], need, need_self, grad[b : b + 1])
        assert got == pytest.approx(expected, rel=1e-9, abs=1e-15)
    assert np.count_nonzero(grad.any(axis=1)) > 30  # most rows are near the world
    if kind == "cloud":
        return  # a lattice's distance jumps between cells: no finite differences across them
    # the gradient against central differences of the penalty in joint space
    h, one = 1e-6, np.zeros((1, Q.shape[1]))
    for b, q in enumerate(Q[:20]):
        fd = [
            (
                penalty_gradient(I, F, field, (q + h * e)[None], need, need_self, one)
                - penalty_gradient(I, F, field, (q - h * e)[None], need, need_self, one)
            )
            / (2 * h)
            for e in np.eye(len(q))
        ]
        np.testing.assert_allclose(grad[b], fd, rtol=1e-4, atol=1e-7)


@pytest.mark.parametrize("arm", ["ur5", "chain"])
def test_the_walks_local_motion_bound_holds(
    arm: str, robot: RobotModel, spheres: SphereModel, chain: tuple[RobotModel, SphereModel]
) -> None:
    # The walk bounds sphere s's path over a fraction tau of an edge, from a sample, by
    # tau A_s + tau^2 B_s (planning.collision). Measured on fine polylines of random edges:
    # the bound holds, and it is tighter than the chain bound reach_s tau where it counts.
    if arm == "chain":
        robot, spheres = chain
    ref = SphereCollisionChecker(robot, spheres, None)
    rng = np.random.default_rng(8)
    ratios = []
    for _ in range(60):
        q0, q1 = robot.sample_uniform(rng, 2)
        dq = np.abs(q1 - q0)
        reach = (dq * ref._displacement).sum(axis=1)
        t, tau = rng.uniform(0, 0.8), rng.choice([0.01, 0.05, 0.2])
        lever, slack = ref._lever_sums((q0 + t * (q1 - q0))[None], dq)[0], ref._slack(dq)
        fractions = t + np.linspace(0.0, tau, 201)
        centres = ref.sphere_centers(q0 + fractions[:, None] * (q1 - q0))  # (201, S, 3)
        path = np.linalg.norm(np.diff(centres, axis=0), axis=2).sum(axis=0)  # (S,) m
        local = tau * lever + tau * tau * slack
        assert np.all(path <= local + 1e-12)
        assert np.all(path <= reach * tau + 1e-12)
        moving = reach > 1e-9
        ratios.append(np.median(local[moving] / (reach[moving] * tau)))
    assert np.median(ratios) < 0.9, "the local bound should be the tighter one"
