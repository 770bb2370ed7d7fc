"""The one way to get a collision checker: :func:`make_checker`.

Two backends answer the same questions with the same answers (the tests hold them to exact
agreement): ``compiled`` (numba kernels, :class:`~planning.compiled.checker.CompiledChecker`,
the default everywhere) and ``numpy`` (the vectorized reference,
:class:`~planning.collision.SphereCollisionChecker`), selectable with ``--checker numpy``.
Every planner, the oracle, path shortcutting, timing's re-check and the simulation's
pre-check take the :class:`~planning.collision.CollisionChecker` protocol and so either one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from gaide_core.errors import ConfigError

if TYPE_CHECKING:  # the checkers load Pinocchio and numba; the names here stay light
    from gaide_core.types import Array
    from planning.collision import CollisionChecker, SphereCollisionChecker
    from planning.robot_model import RobotModel
    from planning.sphere_model import SphereModel
    from planning.world import World

CHECKERS = ("compiled", "numpy")
DEFAULT_CHECKER = "compiled"
# m beyond the margin that endpoints chosen by IK keep: a configuration at the margin itself
# is valid, but no motion into or out of it can be certified to keep the margin (the
# displacement bounds cannot prove that the sphere at the margin moves away).
ENDPOINT_SLACK = 0.002


def check_backend(backend: str) -> str:
    """``backend`` if it names a checker; ConfigError listing the valid ones otherwise."""
    if backend not in CHECKERS:
        raise ConfigError(f"unknown checker '{backend}'; valid: {', '.join(CHECKERS)}")
    return backend


def make_checker(
    robot: RobotModel,
    spheres: SphereModel,
    world: World | None = None,
    *,
    backend: str = DEFAULT_CHECKER,
    margin: float | None = None,  # m, default: the robot config's collision margin
    resolution: float | None = None,  # m, default: the robot config's edge resolution
    world_ignored_links: tuple[str, ...] | None = None,
) -> CollisionChecker:
    """A checker of ``robot`` modelled by ``spheres`` against ``world`` (none: empty)."""
    from planning.collision import SphereCollisionChecker

    cls: type[SphereCollisionChecker] = SphereCollisionChecker
    if check_backend(backend) == "compiled":
        from planning.compiled.checker import CompiledChecker

        cls = CompiledChecker
    return cls(
        robot,
        spheres,
        world,
        margin=margin,
        resolution=resolution,
        world_ignored_links=world_ignored_links,
    )


def endpoint_checker(checker: CollisionChecker) -> CollisionChecker:
    """A checker like ``checker`` (robot, world, backend) whose margin is
    :data:`ENDPOINT_SLACK` larger: for choosing endpoints (IK solutions) that certified
    motions can leave and reach."""
    return make_checker(
        checker.robot,
        checker.spheres,
        checker.world,
        backend=checker.backend,
        margin=checker.margin + ENDPOINT_SLACK,
        resolution=checker.resolution,
    )


def true_sphere_clearance(checker: CollisionChecker, Q: Array) -> Array:
    """(B, S) distance - radius (m, the world raise included) of each world-checked sphere of
    configurations Q (B, dof), +inf for the others: the checker's own on primitives, whose
    distances are exact; on a cloud world the distance to the nearest cloud point, where the
    checker's look-up is a lower bound up to voxel * sqrt(3) below it and not continuous
    (:mod:`planning.distance_field`). The certificate of an edge keeps the true clearance
    above the margin (:mod:`planning.collision`), and reports of a motion go by this."""
    import numpy as np

    from planning.distance_field import CloudWorld

    world = checker.world
    if not isinstance(world, CloudWorld):
        return checker.sphere_clearance(Q)
    centres = checker.sphere_centers(Q)
    # The world-checked spheres are the same for every configuration: ask about one.
    checked = np.isfinite(checker.sphere_clearance(Q[:1])[0])
    true = np.full(centres.shape[:2], np.inf)
    distance = world.exact_distance(centres[:, checked].reshape(-1, 3))
    true[:, checked] = distance.reshape(len(Q), -1) - checker.world_radii[checked]
    return true
