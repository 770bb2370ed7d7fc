"""Compile every kernel once, so that later processes load them from numba's cache.

``python -m planning.compiled.warmup`` is part of ``make setup``: a kernel compiles on its
first call (tens of seconds for all of them on a 2-core machine), and numba caches the
machine code beside the sources, keyed by their contents. Each world kind and entry point is
called once on a tiny problem with the argument types the project uses.
"""

from __future__ import annotations

import time

import numpy as np

from planning.checker import make_checker
from planning.compiled import rrtc_kernel
from planning.distance_field import CloudWorld
from planning.path_ops import BandCfg, tighten
from planning.primitives import Box, Cylinder, PrimitiveWorld, Sphere
from planning.robot_model import load_robot
from planning.rrtc import CompiledRRTConnect, RRTCCfg, kernel_tables, shorten
from planning.sphere_model import SphereModel


def warm_up() -> float:
    """Call every compiled entry point once; returns the seconds it took."""
    t0 = time.perf_counter()
    robot = load_robot()
    assert robot.config.spheres is not None
    spheres = SphereModel.load_for(robot.config.spheres, robot)
    prims = PrimitiveWorld(
        [Box(np.array([0.2, 0.2, 0.2])), Cylinder(0.05, 0.2), Sphere(0.05, np.array([0.5, 0, 0]))]
    )
    cloud = CloudWorld(np.array([[0.6, 0.0, 0.3], [0.6, 0.1, 0.3]]), voxel=0.02)
    rng = np.random.default_rng(0)
    Q = robot.sample_uniform(rng, 4)
    home, up = robot.named_configuration("home"), robot.named_configuration("up")
    planner = CompiledRRTConnect(RRTCCfg(max_iterations=50, simplify=False))
    # Every entry point for every world kind: the cloud's lattice is float32 where the other
    # worlds pass a float64 placeholder, so each compiles (and is cached) twice.
    for world in (None, prims, cloud):
        checker = make_checker(robot, spheres, world)
        checker.config_valid(Q)
        checker.config_valid_one(Q[0])
        checker.edges_valid(Q[:2], Q[2:])
        checker.edge_valid_one(Q[0], Q[1])
        checker.first_invalid_edge(Q)
        checker.edge_steps(Q[:2], Q[2:])
        checker.sphere_centers(Q)
        planner.search(checker, Q[0], Q[1], rng)  # may join at once: the search kernel is next
        nodes = np.zeros((2, 8, robot.dof))
        nodes[0, 0], nodes[1, 0] = home, up
        I, F, field = kernel_tables(checker).args()
        rrtc_kernel.grow(
            I, F, field, nodes, np.full((2, 8), -1, np.int64), np.ones(2, np.int64),
            rng.random((2, robot.dof)), 0, checker.margin, checker.resolution, 0.1,
            np.array([0, 0, 0, 0, 0, 0, 0, 0, -1, 0]), np.empty((16, robot.dof)),
        )  # fmt: skip
        shorten(checker, np.stack([home, (home + up) / 2, up]), rng, 4)
        tighten(checker, np.stack([home, up]), BandCfg(iterations=2))  # the band's penalty
    return time.perf_counter() - t0


if __name__ == "__main__":
    print(f"compiled kernels ready ({warm_up():.1f} s)")
