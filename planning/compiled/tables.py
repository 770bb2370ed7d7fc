"""A checker's robot, sphere model and world exported once as the arrays the kernels take
(the layout is :mod:`planning.compiled.layout`).

:func:`checker_tables` reads the joint chain from Pinocchio (through
:class:`~planning.kinematics.BatchKinematics`) and the sphere tables from the numpy reference
checker, so both backends check the same spheres, pairs and displacement bounds, and exports
an empty, cloud or primitive world; any other world is refused with a
:class:`~gaide_core.errors.PlanningError` naming it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from gaide_core.errors import PlanningError
from gaide_core.types import FloatArray, IntArray
from planning.compiled import layout as L
from planning.compiled.layout import BLOCK, Field
from planning.distance_field import CloudWorld
from planning.primitives import Box, Cylinder, PrimitiveWorld
from planning.world import EmptyWorld, World

if TYPE_CHECKING:
    from planning.collision import SphereCollisionChecker


@dataclass(frozen=True)
class Tables:
    """The kernels' leading arguments: ints, floats, and the cloud's lattice (float32,
    flattened; for other worlds one float64 0, whose dtype compiles the kernels for them)."""

    ints: IntArray
    floats: FloatArray
    field: Field

    def args(self) -> tuple[IntArray, FloatArray, Field]:
        return self.ints, self.floats, self.field


def checker_tables(checker: SphereCollisionChecker) -> Tables:
    """Robot, spheres and world of the numpy reference ``checker`` as packed tables."""
    ri, rf, lwradius = _robot_slots(checker)
    wi, wf, field = _world_slots(checker.world)
    pairs = ri[L.I_PAIRS].reshape(-1, 2)
    extra = [checker.pair_displacement(pairs), checker.world_radii, lwradius]
    extra.append(rotation_terms(checker.kin.placements_R, checker.kin.axes))
    ints, floats = L.pack(ri + wi, rf + wf + extra)
    return Tables(ints, floats, field)


def rotation_terms(placements_R: FloatArray, axes: FloatArray) -> FloatArray:
    """(J, 3, 3, 3): for each joint, its placement's rotation P times the three terms of
    the rotation about its unit axis a (Rodrigues: R(q) = a a^T + cos q (I - a a^T) +
    sin q [a]x), the ``F_PLACE_K`` slot. The same rotation as the numpy reference's
    ``P @ R(q)``, to rounding."""
    out = np.zeros((len(axes), 3, 3, 3))
    for j, (P, a) in enumerate(zip(placements_R, axes, strict=True)):
        outer = np.outer(a, a)
        cross = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
        out[j] = [P @ outer, P @ (np.eye(3) - outer), P @ cross]
    return out


def _robot_slots(
    checker: SphereCollisionChecker,
) -> tuple[list[IntArray], list[FloatArray], FloatArray]:
    """The robot and its spheres as the numpy reference ``checker`` models them, and the
    links' bounding radii over the world checks' radii (``F_LWRADIUS``)."""
    kin = checker.kin
    J = kin.njoints
    jtype = np.full(J, L.JOINT_ROOT, np.int64)
    for j in range(1, J):
        jtype[j] = L.JOINT_PRISMATIC if kin.prismatic[j] else L.JOINT_REVOLUTE
    parent = np.array([-1, *kin.parents[1:]], np.int64)
    idxq = np.array([-1, *kin.idx_q[1:]], np.int64)

    names = list(checker.spheres.links)
    # Links ordered by the joint that carries them: a kernel places joint by joint and
    # checks each joint's links as soon as they are placed.
    first = {n: checker.sphere_joint[names.index(n)] for n in checker.spheres.link_names}
    link_names = sorted(first, key=lambda n: (int(first[n]), names.index(n)))
    slink = np.array([link_names.index(n) for n in names], np.int64)
    order = np.argsort(slink, kind="stable")
    lstart = np.searchsorted(slink[order], np.arange(len(link_names) + 1)).astype(np.int64)
    ljoint = np.array([first[n] for n in link_names], np.int64)
    jlstart = np.searchsorted(ljoint, np.arange(J + 1)).astype(np.int64)
    lcentre = np.empty((len(link_names), 3))
    lradius = np.empty(len(link_names))
    lwradius = np.empty(len(link_names))
    sworld = np.zeros(len(names), np.int64)
    sworld[checker.world_spheres] = 1
    lworld = np.zeros(len(link_names), np.int64)
    for lk in range(len(link_names)):
        idx = order[lstart[lk] : lstart[lk + 1]]
        centre = checker.sphere_local[idx].mean(axis=0)
        lcentre[lk] = centre
        offset = np.linalg.norm(checker.sphere_local[idx] - centre, axis=1)
        lradius[lk] = float((offset + checker.radii[idx]).max())
        lwradius[lk] = float((offset + checker.world_radii[idx]).max())
        lworld[lk] = int(sworld[idx].any())

    groups: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for i, j in checker.pairs:
        key = (int(slink[i]), int(slink[j]))
        groups.setdefault(key, []).append((int(i), int(j)))
    glinks = np.array(list(groups), np.int64).reshape(-1, 2)
    gsizes = [len(v) for v in groups.values()]
    gstart = np.concatenate([[0], np.cumsum(gsizes)]).astype(np.int64)
    pairs = np.array([p for v in groups.values() for p in v], np.int64).reshape(-1, 2)

    robot = checker.robot
    dims = np.array([J, len(names), len(link_names), len(pairs), len(glinks), robot.dof], np.int64)
    ints = [dims, parent, jtype, idxq, sworld, order.astype(np.int64), lstart, lworld,
            jlstart, pairs, glinks, gstart]  # fmt: skip
    floats = [
        kin.placements_R, kin.placements_t, kin.axes, robot.T_world_base,
        checker.sphere_local, checker.radii, lcentre, lradius, checker._displacement,
        robot.lower, robot.upper,
    ]  # fmt: skip
    return ints, floats, lwradius


def block_minima(field: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """The smallest value of each BLOCK^3 block of a cloud's lattice (nx, ny, nz), blocks
    in row-major order, flattened: the kernels find them after the lattice itself.

    For a point whose nearest lattice point lies in block b, ``minima[b]`` minus the point's
    way to that lattice point is at most the lattice's lower bound of its distance to the
    cloud, so one look-up in this small array (1/512 of the lattice: it stays in cache)
    clears most spheres without reading the large lattice."""
    shape = np.array(field.shape)
    blocks = -(-shape // BLOCK)
    padded = np.full(blocks * BLOCK, np.inf, np.float32)
    padded[: shape[0], : shape[1], : shape[2]] = field
    b = padded.reshape(blocks[0], BLOCK, blocks[1], BLOCK, blocks[2], BLOCK)
    return np.ascontiguousarray(b.min(axis=(1, 3, 5)).ravel())


def _world_slots(
    world: World,
) -> tuple[list[IntArray], list[FloatArray], Field]:
    """An empty, cloud or primitive world as slots and a lattice; PlanningError for any
    other kind."""
    # Not a lattice: its dtype (float64, where a lattice is float32) compiles the kernels
    # for analytic worlds (geometry.link_world_values).
    no_field = np.zeros(1, np.float64)
    cloud = np.zeros(6)
    shape = [0, 0, 0]
    kinds: list[int] = []
    pR, pt, pdim, pbound = [], [], [], []
    if isinstance(world, EmptyWorld):
        field = no_field
    elif isinstance(world, CloudWorld):
        field = np.concatenate([world.field.ravel(), block_minima(world.field)])
        cloud = np.array([*world._origin_scaled, world.voxel, world.band, world._inv_voxel])
        shape = list(world.shape)
    elif isinstance(world, PrimitiveWorld):
        field = no_field
        for p in world.primitives:
            if isinstance(p, Box):
                half = np.asarray(p.size, float) / 2
                kinds.append(L.PRIM_BOX)
                pR.append(p.pose[:3, :3])
                pt.append(p.pose[:3, 3])
                pdim.append(half)
                pbound.append(float(np.linalg.norm(half)))
            elif isinstance(p, Cylinder):
                kinds.append(L.PRIM_CYLINDER)
                pR.append(p.pose[:3, :3])
                pt.append(p.pose[:3, 3])
                pdim.append(np.array([p.radius, p.height / 2, 0.0]))
                pbound.append(float(np.hypot(p.radius, p.height / 2)))
            else:
                kinds.append(L.PRIM_SPHERE)
                pR.append(np.eye(3))
                pt.append(np.asarray(p.center, float))
                pdim.append(np.array([p.radius, 0.0, 0.0]))
                pbound.append(float(p.radius))
    else:
        raise PlanningError(
            f"the compiled checker knows empty, cloud and primitive worlds, not "
            f"{type(world).__name__}; use the numpy checker (--checker numpy)"
        )
    M = len(kinds)
    ints = [np.array([*shape, M], np.int64), np.array(kinds, np.int64)]
    floats = [
        cloud,
        np.asarray(pR, float).reshape(M, 3, 3),
        np.asarray(pt, float).reshape(M, 3),
        np.asarray(pdim, float).reshape(M, 3),
        np.asarray(pbound, float).reshape(M),
    ]
    return ints, floats, field
