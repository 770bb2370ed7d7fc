"""``gaide demo``: the main job on the embedded default.

Today: the robot and collision foundation on a sample workcell: the scene as a point cloud,
the collision checker on it, a collision-free IK solution, and a picture of the robot's
spheres in the scene. Later stages (bag, calibration, planning, timing) extend it.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from core.errors import PlanningError
from core.transforms import from_xyz_rpy
from gaide.common import print_table, robot_and_spheres, write_json
from planning.bench_collision import benchmark_workcell
from planning.collision import SphereCollisionChecker
from planning.distance_field import CloudWorld
from planning.ik import solve_ik
from planning.plot import render_scene
from planning.primitives import PrimitiveWorld


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("demo", help="run the main job on the shipped default")
    p.add_argument("-o", "--out", default="out/demo", help="output folder")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_demo)


def cmd_demo(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(args.seed)
    robot, spheres = robot_and_spheres(None)
    primitives = PrimitiveWorld(benchmark_workcell(rng))
    cloud = primitives.sample_surface(50_000, rng)
    world = CloudWorld(cloud)
    checker = SphereCollisionChecker(robot, spheres, world)
    home = robot.named_configuration("home")
    target = from_xyz_rpy([0.45, 0.25, 0.25], [np.pi, 0.0, 0.0])
    solutions = solve_ik(robot, target, rng, checker=checker, seed=home)
    if not solutions:
        raise PlanningError("demo: no collision-free IK solution for the sample target")
    Q = robot.sample_uniform(rng, 10_000)
    t1 = time.perf_counter()
    valid = checker.config_valid(Q)
    rate = len(Q) / (time.perf_counter() - t1)
    picture = out / "robot_scene.png"
    render_scene(
        picture,
        checker,
        [home, solutions[0]],
        cloud,
        title="UR5 spheres: home (blue), IK solution (orange)",
    )
    summary = {
        "spheres": len(spheres),
        "cloud_points": len(cloud),
        "home_valid": bool(checker.config_valid(home[None])[0]),
        "ik_solutions": len(solutions),
        "ik_solution": solutions[0].tolist(),
        "valid_share_uniform": float(valid.mean()),
        "configs_per_s": rate,
        "picture": str(picture),
        "wall_s": time.perf_counter() - t0,
    }
    write_json(out / "summary.json", summary)
    print_table(
        [
            ("sphere model", f"{len(spheres)} spheres"),
            ("scene cloud", f"{len(cloud):,} points, voxel {world.voxel} m"),
            ("home configuration", "valid" if summary["home_valid"] else "in collision"),
            ("IK to sample target", f"{len(solutions)} collision-free solutions"),
            ("uniform samples valid", f"{valid.mean():.1%}"),
            ("checks per second", f"{rate:,.0f}"),
            ("picture", str(picture)),
            ("wall time", f"{summary['wall_s']:.1f} s"),
        ],
        "gaide demo",
    )
    return 0
