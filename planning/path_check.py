"""The harness's own check of a returned path, independent of the planner that made it.

Every configuration sampled at half the robot's edge resolution must be valid against the
exact primitive world (a necessary condition that every path a planner certified passes;
see :mod:`planning.collision`), and optionally the real meshes in PyBullet must not touch it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaide_core.types import Array
from planning.collision import SphereCollisionChecker
from planning.path_ops import first_invalid_sample
from planning.primitives import PrimitiveWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


@dataclass(frozen=True)
class PathCheck:
    ok: bool
    detail: str = ""  # what failed: endpoints, which edge and why
    bad_edge: int | None = None


def check_path(
    path: Array | None,
    start: Array,
    goal: Array,  # (dof,) or (G, dof): several goals, any of which ends the path
    robot: RobotModel,
    spheres: SphereModel,
    world: PrimitiveWorld,
    *,
    resolution_factor: float = 0.5,
    meshes: bool = False,
    mesh_step: float = 0.02,
) -> PathCheck:
    """Is ``path`` (K, dof) a valid path from start to goal? ``goal`` is one goal (dof,) or
    several (G, dof), of which the path must end at one. Endpoints must match (1e-6 rad),
    every configuration be inside the limits, every edge be collision-free at
    ``resolution_factor`` x the robot's edge resolution; with ``meshes``, PyBullet's mesh
    check too, every ``mesh_step`` rad along the path."""
    if path is None or len(path) < 2:
        return PathCheck(False, "no path")
    p = np.asarray(path, float)
    if p.ndim != 2 or p.shape[1] != robot.dof or not np.all(np.isfinite(p)):
        return PathCheck(False, f"path has shape {p.shape} or non-finite values")
    goals = np.asarray(goal, float)
    goals = goals[None] if goals.ndim == 1 else goals
    if goals.ndim != 2 or goals.shape[1] != robot.dof or not len(goals):
        return PathCheck(False, f"goals have shape {goals.shape}, not (G >= 1, {robot.dof})")
    end_gap = np.abs(goals - p[-1]).max(axis=1).min()  # rad, to the nearest goal
    if np.abs(p[0] - start).max() > 1e-6 or not end_gap <= 1e-6:
        which = "the goal" if len(goals) == 1 else f"one of the {len(goals)} goals"
        return PathCheck(False, f"path does not start at the start and end at {which}")
    checker = SphereCollisionChecker(
        robot, spheres, world, resolution=robot.config.edge_resolution * resolution_factor
    )
    # Sampled, not certified: this check asks whether any configuration along the path is
    # invalid, which a certified path (what every planner returns) never has.
    ok = checker.edges_valid_sampled(p[:-1], p[1:])
    if not ok.all():
        bad = int(np.flatnonzero(~ok)[0])
        hit = first_invalid_sample(checker, p[bad], p[bad + 1])
        assert hit is not None  # the edge failed at one of these samples
        return PathCheck(
            False,
            f"edge {bad} of {len(p) - 1} collides ({int((~ok).sum())} bad edges): "
            f"{checker.diagnose(hit[1])}",
            bad,
        )
    if meshes:
        from planning.mesh_reference import MeshReference

        with MeshReference(robot, world) as ref:
            for i in range(len(p) - 1):
                n = max(1, int(np.ceil(np.abs(p[i + 1] - p[i]).max() / mesh_step)))
                for f in np.linspace(0, 1, n + 1):
                    if ref.collides(p[i] + f * (p[i + 1] - p[i])):
                        return PathCheck(False, f"edge {i}: the meshes touch the world", i)
    return PathCheck(True)
