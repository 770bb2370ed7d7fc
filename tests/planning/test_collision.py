from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from gaide_core.errors import PlanningError
from gaide_core.transforms import from_xyz_rpy
from planning.collision import SphereCollisionChecker
from planning.distance_field import CloudWorld
from planning.primitives import Box, Cylinder, PrimitiveWorld, Sphere
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel
from tests.conftest import ROOT


def test_distance_field_is_a_tight_lower_bound(rng: np.random.Generator) -> None:
    world = PrimitiveWorld(
        [Box(np.array([0.6, 0.8, 0.05]), from_xyz_rpy([0.4, 0, 0], [0, 0, 0.3]))]
    )
    cloud = world.sample_surface(20_000, rng)
    field = CloudWorld(cloud, voxel=0.01)
    queries = rng.uniform([-0.1, -0.6, -0.2], [0.9, 0.6, 0.2], size=(20_000, 3))
    truth = cKDTree(cloud).query(queries)[0]
    lower = field.distance(queries)
    assert np.all(lower <= truth + 1e-9)  # never optimistic
    near = truth < field.exact_up_to
    # within the band, off by at most the lattice slack (two half-diagonals)
    assert np.all(truth[near] - lower[near] <= 0.01 * np.sqrt(3) + 1e-6)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-1, 1), min_size=3, max_size=3),
    st.lists(st.floats(0.05, 0.5), min_size=3, max_size=3),
    st.floats(-np.pi, np.pi),
)
def test_primitive_distances_match_their_meshes(
    center: list[float], size: list[float], yaw: float
) -> None:
    import trimesh

    from planning.primitives import primitive_mesh

    pose = from_xyz_rpy(center, [0.3, 0.0, yaw])
    for prim in (
        Box(np.asarray(size), pose),
        Cylinder(size[0], size[1], pose),
        Sphere(size[2], np.asarray(center)),
    ):
        world = PrimitiveWorld([prim])
        mesh = primitive_mesh(prim)
        pts = np.asarray(center) + np.random.default_rng(0).uniform(-0.8, 0.8, size=(50, 3))
        ours = world.distance(pts)
        ref = -trimesh.proximity.signed_distance(mesh, pts)  # trimesh: positive inside
        # cylinders and spheres are faceted meshes: allow the facet sagitta
        tol = 1e-9 if isinstance(prim, Box) else 0.01 * max(size)
        np.testing.assert_allclose(ours, ref, atol=tol)


def test_edge_through_a_thin_wall_is_caught(robot: RobotModel, spheres: SphereModel) -> None:
    # a 2 mm wall in the plane x = 0.5, far enough from the base that the arm swings through
    wall = PrimitiveWorld(
        [Box(np.array([0.002, 2.0, 2.0]), from_xyz_rpy([0.5, 0, 0.5], [0, 0, 0]))]
    )
    checker = SphereCollisionChecker(robot, spheres, wall)
    q0 = np.array([0.0, -1.2, 0.6, -1.0, -1.57, 0.0])  # reaching forward, through the wall
    a = q0.copy()
    a[0] = np.pi / 2
    b = q0.copy()
    b[0] = -np.pi / 2
    assert checker.config_valid(np.stack([a, b])).all(), "both ends face sideways, clear of it"
    assert not checker.config_valid(q0[None])[0], "midway the arm crosses the wall"
    assert not checker.edge_valid(a, b)
    # the samples are fine enough: no sphere centre moves more than the resolution per step
    steps = checker.edge_steps(a[None], b[None])[0]
    fine = a + np.linspace(0, 1, 4 * steps + 1)[:, None] * (b - a)
    centers = checker.sphere_centers(fine)
    assert np.linalg.norm(np.diff(centers, axis=0), axis=-1).max() * 4 <= checker.resolution + 1e-9


def test_first_invalid_edge_is_reported(robot: RobotModel, spheres: SphereModel) -> None:
    wall = PrimitiveWorld(
        [Box(np.array([0.002, 2.0, 2.0]), from_xyz_rpy([0.5, 0, 0.5], [0, 0, 0]))]
    )
    checker = SphereCollisionChecker(robot, spheres, wall)
    side = np.array([np.pi / 2, -1.2, 0.6, -1.0, -1.57, 0.0])
    side2 = side.copy()
    side2[1] = -1.0
    other = side.copy()
    other[0] = -np.pi / 2
    assert checker.first_invalid_edge(np.stack([side, side2, side, other])) == 2
    assert checker.first_invalid_edge(np.stack([side, side2])) is None


def test_self_collision_and_limits(robot: RobotModel, spheres: SphereModel) -> None:
    checker = SphereCollisionChecker(robot, spheres)
    folded = np.array([0.0, -1.57, 3.1, 0.0, 0.0, 0.0])  # forearm folded onto the upper arm
    diag = checker.diagnose(folded)
    assert diag.self_contacts and not diag.world_contacts
    assert not checker.config_valid(folded[None])[0]
    outside = robot.named_configuration("home")
    outside[2] = 3.5
    assert checker.diagnose(outside).outside_limits == ["elbow_joint"]
    assert checker.config_valid(robot.named_configuration("home")[None])[0]


def test_sphere_checker_never_misses_a_mesh_collision(
    robot: RobotModel, spheres: SphereModel, rng: np.random.Generator
) -> None:
    from planning.bench_collision import benchmark_workcell
    from planning.mesh_reference import MeshReference

    world = PrimitiveWorld(benchmark_workcell(rng))
    checker = SphereCollisionChecker(robot, spheres, world)
    Q = robot.sample_uniform(rng, 3000)
    near = Q[checker.world_clearance(Q) < 0.1][:300]
    free = checker.world_clearance(near) >= checker.margin
    with MeshReference(robot, world) as ref:
        truth = np.array([ref.collides(q) for q in near])
    assert 0.2 < truth.mean() < 0.95  # the sample really is near the obstacles
    assert not np.any(truth & free)
    assert np.sum(~truth & ~free) / np.sum(~truth) < 0.2


def test_bad_inputs(robot: RobotModel, spheres: SphereModel) -> None:
    checker = SphereCollisionChecker(robot, spheres)
    with pytest.raises(PlanningError, match=r"shape \(B, 6\)"):
        checker.config_valid(np.zeros((3, 5)))
    with pytest.raises(PlanningError, match="NaN"):
        checker.config_valid(np.full((1, 6), np.nan))
    with pytest.raises(PlanningError, match="wider band"):
        SphereCollisionChecker(robot, spheres, CloudWorld(np.zeros((1, 3)), voxel=0.05, band=0.1))
    with pytest.raises(PlanningError, match=r"\(N, 3\)"):
        CloudWorld(np.zeros((0, 3)))
    with pytest.raises(PlanningError, match="box size"):
        Box(np.array([0.1, -0.1, 0.1]))
    with pytest.raises(PlanningError, match="unknown type 'cone'"):
        PrimitiveWorld.from_dict([{"type": "cone"}])


@pytest.mark.parametrize("backend", ["numpy", "compiled"])
def test_a_checker_at_another_margin(robot: RobotModel, spheres: SphereModel, backend: str) -> None:
    from planning.checker import make_checker

    wall = PrimitiveWorld(
        [Box(np.array([0.02, 1.2, 0.6]), from_xyz_rpy([0.45, 0, 0.3], [0, 0, 0]))]
    )
    checker = make_checker(robot, spheres, wall, backend=backend)
    wide = checker.with_margin(checker.margin + 0.02)
    assert checker.margin == robot.config.collision_margin and wide.margin == checker.margin + 0.02
    Q = robot.sample_uniform(np.random.default_rng(0), 4000)
    clear = checker.world_clearance(Q)
    assert np.sum((clear > checker.margin) & (clear < wide.margin)) > 10  # where they differ
    expected = checker.config_valid(Q) & (clear >= wide.margin)
    np.testing.assert_array_equal(wide.config_valid(Q), expected)
    cloud = make_checker(robot, spheres, CloudWorld(np.zeros((1, 3)), voxel=0.05, band=0.2))
    assert cloud.max_margin == pytest.approx(cloud.world.exact_up_to - spheres.radii.max())
    with pytest.raises(PlanningError, match="wider band"):
        cloud.with_margin(cloud.max_margin + 0.001)
    with pytest.raises(PlanningError, match="margin >= 0"):
        checker.with_margin(-0.01)


def test_primitive_world_round_trip(rng: np.random.Generator) -> None:
    from planning.bench_collision import benchmark_workcell

    world = PrimitiveWorld(benchmark_workcell(rng))
    back = PrimitiveWorld.from_dict(world.to_dict())
    pts = rng.uniform(-1, 1, size=(500, 3))
    np.testing.assert_allclose(back.distance(pts), world.distance(pts), atol=1e-9)


def test_the_coarse_first_pass_never_changes_the_answer(
    robot: RobotModel, spheres: SphereModel, rng: np.random.Generator
) -> None:
    from planning.families import generate_problem
    from planning.family_names import split_seed

    checker = SphereCollisionChecker(
        robot, spheres, generate_problem("shelf_i", split_seed("test", 0), robot, spheres).world
    )
    q0 = rng.uniform(robot.lower / 2, robot.upper / 2, (60, robot.dof))
    q1 = rng.uniform(robot.lower / 2, robot.upper / 2, (60, robot.dof))
    full = checker.edges_valid(q0, q1, coarse=False)
    assert np.array_equal(checker.edges_valid(q0, q1), full)
    single = np.array([checker.edge_valid(a, b) for a, b in zip(q0, q1, strict=True)])
    assert np.array_equal(single, full)
    assert full.any() and not full.all(), "the sample needs valid and invalid edges"
    assert (checker.edge_steps(q0, q1) >= 32).sum() > 30, "the sample needs long edges"


def test_the_lattice_queries_are_scipys(rng: np.random.Generator) -> None:
    from planning.distance_field import _nearest_within

    tree = cKDTree(rng.uniform(0, 0.5, (3000, 3)))
    queries = rng.uniform(-0.2, 0.7, (10_001, 3))  # not a multiple of the chunk count
    want = tree.query(queries, distance_upper_bound=0.1)[0]
    assert np.array_equal(_nearest_within(tree, queries, 0.1), want)
    assert _nearest_within(tree, queries[:0], 0.1).shape == (0,)


def test_the_lattice_queries_survive_ctrl_c() -> None:
    """Ctrl-C during the lattice's k-d tree queries unwinds; it must not crash the process.
    scipy's own threaded query (``workers=-1``) segfaults here nearly every time: its threads
    go on reading the tree the interrupt frees (``gaide demo`` died so, 1 run in 3). The
    child's handler raises only inside the queries, so no interrupt lands in its own loop."""
    child = """
import os, signal, threading, time
import numpy as np
from scipy.spatial import cKDTree
from planning.distance_field import _nearest_within
rng = np.random.default_rng(0)
cloud = rng.uniform(0, 0.6, (20000, 3))
def in_queries(signum, frame):
    while frame is not None:
        if frame.f_code is _nearest_within.__code__:
            raise KeyboardInterrupt
        frame = frame.f_back
signal.signal(signal.SIGINT, in_queries)
end = time.monotonic() + 3.0
def pester():
    while time.monotonic() < end:
        time.sleep(0.013)
        os.kill(os.getpid(), signal.SIGINT)
threading.Thread(target=pester, daemon=True).start()
interrupted = 0
while time.monotonic() < end + 0.2:
    try:
        _nearest_within(cKDTree(cloud), rng.uniform(0, 0.6, (200000, 3)), 0.15)
    except KeyboardInterrupt:
        interrupted += 1
print(interrupted)
"""
    proc = subprocess.run(
        [sys.executable, "-c", child], capture_output=True, text=True, cwd=ROOT, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert int(proc.stdout) > 5, "the interrupts reached the queries"
