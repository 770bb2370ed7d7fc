"""Small planning problems for the OMPL, shortcut and oracle tests, built from primitives."""

from __future__ import annotations

import numpy as np

from gaide_core.transforms import from_xyz_rpy
from gaide_core.types import Array
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.primitives import Box, Primitive, PrimitiveWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel


def wall_checker(robot: RobotModel, spheres: SphereModel) -> CollisionChecker:
    """A 2 cm wall, 1.2 m wide and 0.6 m tall, standing on z = 0 at x = 0.45 m in front of
    the base: the arm must reach over it or fold to swing past it."""
    wall = Box(np.array([0.02, 1.2, 0.6]), from_xyz_rpy([0.45, 0.0, 0.3], [0.0, 0.0, 0.0]))
    return make_checker(robot, spheres, PrimitiveWorld([wall]))


def wall_problem() -> tuple[Array, Array]:
    """Start and goal (rad) on either side of the wall; only joint 0 differs (3.6 rad), and
    the straight edge between them sweeps the forearm through the wall."""
    start = np.array([1.8, -1.0, 2.0, -1.9, -1.57, 0.0])
    goal = start.copy()
    goal[0] = -1.8
    return start, goal


def tube_checker(robot: RobotModel, spheres: SphereModel) -> CollisionChecker:
    """A closed-top square tube (inner half-width 0.25 m) from z = 0.3 m to 1.3 m around the
    base. The arm pointing straight up ("up") fits inside; to get out, the upper arm would
    have to tilt below the tube's rim, which its 0.425 m length does not allow without
    crossing a wall."""
    h, t, z0, z1 = 0.25, 0.02, 0.3, 1.3
    mid = (z0 + z1) / 2
    level = [0.0, 0.0, 0.0]
    boxes: list[Primitive] = [
        Box(np.array([t, 2 * h + 2 * t, z1 - z0]), from_xyz_rpy([s * (h + t / 2), 0, mid], level))
        for s in (-1, 1)
    ]
    boxes += [
        Box(np.array([2 * h + 2 * t, t, z1 - z0]), from_xyz_rpy([0, s * (h + t / 2), mid], level))
        for s in (-1, 1)
    ]
    boxes.append(Box(np.array([2 * h + 2 * t, 2 * h + 2 * t, t]), from_xyz_rpy([0, 0, z1], level)))
    return make_checker(robot, spheres, PrimitiveWorld(boxes))


def edges_all_valid(checker: CollisionChecker, path: Array) -> bool:
    """Every edge of ``path`` (K, dof) passes the checker's own edge check."""
    return bool(np.all(checker.edges_valid(path[:-1], path[1:])))
