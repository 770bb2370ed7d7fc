"""Obstacle primitives (box, cylinder, sphere) with poses, and their analytic distances.

Distances are signed: negative inside an obstacle. Poses are ``T_world_obstacle`` (4, 4);
a cylinder's axis is its local z.

:meth:`PrimitiveWorld.from_dict` reads obstacles as problem files write them (every key
checked, see :mod:`planning.problem`)::

    {type: box, size: [x, y, z], pose: POSE}            # full edge lengths (m)
    {type: cylinder, radius: r, height: h, pose: POSE}  # m; axis along the local z
    {type: sphere, radius: r, center: [x, y, z]}        # m

where ``POSE`` is ``{xyz: [x, y, z], quat_xyzw: [x, y, z, w]}`` or ``{xyz: [x, y, z],
rpy: [roll, pitch, yaw]}``: metres, and radians about the fixed axes x, then y, then z (as
URDF: ``R = Rz(yaw) Ry(pitch) Rx(roll)``). A quaternion's norm must be within
``QUAT_NORM_TOL`` of 1 (rounded values pass); it is normalized. Every number is finite and
every length > 0.
"""

from __future__ import annotations

import math
import reprlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from gaide_core.errors import PlanningError
from gaide_core.transforms import to_xyz_quat
from gaide_core.types import Array

QUAT_NORM_TOL = 1e-3  # |norm - 1| a file's quaternion may have (6 printed digits pass)
_RIGID_TOL = 1e-6  # orthonormality and det of a pose's rotation
OBSTACLE_KEYS: dict[str, tuple[str, ...]] = {
    "box": ("type", "size", "pose"),
    "cylinder": ("type", "radius", "height", "pose"),
    "sphere": ("type", "radius", "center"),
}
POSE_KEYS = ("xyz", "quat_xyzw", "rpy")
_POSE_FORMS = "{xyz: [x, y, z], quat_xyzw: [x, y, z, w]} or {xyz: [x, y, z], rpy: [r, p, y]}"

_short = reprlib.Repr()
_short.maxlevel, _short.maxlist, _short.maxdict, _short.maxstring = 2, 8, 4, 40


def show(value: Any) -> str:
    """A short one-line rendering of a value read from a file, for error messages (bounded
    however large or deeply nested the value is)."""
    return "null" if value is None else _short.repr(value)


def _check_pose(pose: Array, what: str) -> None:
    # In plain floats: numpy's calls on a 4x4 (gaide_core.transforms.is_rigid) cost 4x more than
    # the arithmetic, and every obstacle of every problem file passes here.
    try:
        T = np.asarray(pose, dtype=float)
    except (TypeError, ValueError) as err:
        raise PlanningError(f"{what}: pose must be a 4x4 rigid transform") from err
    values = T.ravel().tolist()
    ok = T.shape == (4, 4) and all(map(math.isfinite, values))
    if ok:
        a, b, c, _, d, e, f, _, g, h, i, _, l0, l1, l2, l3 = values
        det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
        # |R^T R - I| entry by entry (columns (a, d, g), (b, e, h), (c, f, i))
        worst = max(
            abs(a * a + d * d + g * g - 1.0), abs(b * b + e * e + h * h - 1.0),
            abs(c * c + f * f + i * i - 1.0), abs(a * b + d * e + g * h),
            abs(a * c + d * f + g * i), abs(b * c + e * f + h * i),
            abs(det - 1.0), abs(l0), abs(l1), abs(l2), abs(l3 - 1.0),
        )  # fmt: skip
        ok = worst < _RIGID_TOL
    if not ok:
        raise PlanningError(f"{what}: pose must be a 4x4 rigid transform")


def _finite_positive(x: Any) -> bool:
    try:
        return math.isfinite(x) and x > 0
    except (TypeError, ValueError, OverflowError):
        return False


@dataclass(frozen=True)
class Box:
    size: Array  # (3,) full edge lengths (m)
    pose: Array = field(default_factory=lambda: np.eye(4))  # T_world_box, centre of the box

    def __post_init__(self) -> None:
        size = np.asarray(self.size)
        if (
            size.shape != (3,)
            or size.dtype.kind not in "iuf"
            or not np.isfinite(size).all()
            or (size <= 0).any()
        ):
            raise PlanningError(f"box size must be 3 finite lengths > 0 (m), got {self.size}")
        _check_pose(self.pose, "box")


@dataclass(frozen=True)
class Cylinder:
    radius: float  # m
    height: float  # m, along local z, centred
    pose: Array = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        if not (_finite_positive(self.radius) and _finite_positive(self.height)):
            raise PlanningError(
                "cylinder radius and height must be finite and > 0 m, "
                f"got {self.radius}, {self.height}"
            )
        _check_pose(self.pose, "cylinder")


@dataclass(frozen=True)
class Sphere:
    radius: float  # m
    center: Array  # (3,) m, world frame

    def __post_init__(self) -> None:
        if not _finite_positive(self.radius):
            raise PlanningError(f"sphere radius must be finite and > 0 m, got {self.radius}")
        center = np.asarray(self.center)
        if center.shape != (3,) or center.dtype.kind not in "iuf" or not np.isfinite(center).all():
            raise PlanningError(f"sphere center must be 3 finite coordinates (m), got {center}")


Primitive = Box | Cylinder | Sphere


class PrimitiveWorld:
    """A world of analytic obstacles. ``distance`` is exact and signed."""

    def __init__(self, primitives: list[Primitive] | tuple[Primitive, ...]) -> None:
        self.primitives: tuple[Primitive, ...] = tuple(primitives)
        boxes = [p for p in self.primitives if isinstance(p, Box)]
        cyls = [p for p in self.primitives if isinstance(p, Cylinder)]
        sphs = [p for p in self.primitives if isinstance(p, Sphere)]
        # Inverse poses so that local = R^T (p - t).
        self._box_R = np.stack([b.pose[:3, :3] for b in boxes]) if boxes else np.zeros((0, 3, 3))
        self._box_t = np.stack([b.pose[:3, 3] for b in boxes]) if boxes else np.zeros((0, 3))
        self._box_half = np.stack([b.size / 2 for b in boxes]) if boxes else np.zeros((0, 3))
        self._cyl_R = np.stack([c.pose[:3, :3] for c in cyls]) if cyls else np.zeros((0, 3, 3))
        self._cyl_t = np.stack([c.pose[:3, 3] for c in cyls]) if cyls else np.zeros((0, 3))
        self._cyl_rh = np.array([[c.radius, c.height / 2] for c in cyls]).reshape(-1, 2)
        self._sph_c = np.stack([s.center for s in sphs]) if sphs else np.zeros((0, 3))
        self._sph_r = np.array([s.radius for s in sphs])

    def __len__(self) -> int:
        return len(self.primitives)

    def distance(self, points: Array) -> Array:
        """Signed distance (N,) from points (N, 3) to the nearest obstacle (m); +inf if none.

        Computed on coordinate rows (3, N): numpy's reductions over a short last axis
        (``max(axis=1)`` on (N, 3)) cost more than all the arithmetic (measured 2.5x).
        """
        if points.shape[0] * len(self.primitives) <= 4096:
            return self._distance_few(points)
        out = np.full(points.shape[0], np.inf)
        pts = np.ascontiguousarray(points.T)  # (3, N)
        for R, t, half in zip(self._box_R, self._box_t, self._box_half, strict=True):
            lx, ly, lz = np.abs(R.T @ (pts - t[:, None])) - half[:, None]
            outside = np.sqrt(
                np.maximum(lx, 0.0) ** 2 + np.maximum(ly, 0.0) ** 2 + np.maximum(lz, 0.0) ** 2
            )
            inside = np.minimum(np.maximum(np.maximum(lx, ly), lz), 0.0)
            np.minimum(out, outside + inside, out=out)
        for R, t, (radius, half_h) in zip(self._cyl_R, self._cyl_t, self._cyl_rh, strict=True):
            lx, ly, lz = R.T @ (pts - t[:, None])
            dr = np.sqrt(lx**2 + ly**2) - radius
            dz = np.abs(lz) - half_h
            outside = np.sqrt(np.maximum(dr, 0.0) ** 2 + np.maximum(dz, 0.0) ** 2)
            np.minimum(out, outside + np.minimum(np.maximum(dr, dz), 0.0), out=out)
        for c, radius in zip(self._sph_c, self._sph_r, strict=True):
            d = pts - c[:, None]
            np.minimum(out, np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2) - radius, out=out)
        return out

    def _distance_few(self, points: Array) -> Array:
        """The same distances for few points (one configuration's spheres): all primitives of
        a kind at once, a handful of numpy calls instead of a handful per primitive."""
        out = np.full(points.shape[0], np.inf)
        if len(self._box_t):
            rel = points[None, :, :] - self._box_t[:, None, :]  # (M, N, 3)
            q = np.abs(np.einsum("mnj,mjk->mnk", rel, self._box_R)) - self._box_half[:, None, :]
            d = np.sqrt(np.sum(np.maximum(q, 0.0) ** 2, axis=-1)) + np.minimum(q.max(axis=-1), 0.0)
            np.minimum(out, d.min(axis=0), out=out)
        if len(self._cyl_t):
            rel = points[None, :, :] - self._cyl_t[:, None, :]
            local = np.einsum("mnj,mjk->mnk", rel, self._cyl_R)
            dr = np.hypot(local[..., 0], local[..., 1]) - self._cyl_rh[:, None, 0]
            dz = np.abs(local[..., 2]) - self._cyl_rh[:, None, 1]
            d = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0)) + np.minimum(
                np.maximum(dr, dz), 0.0
            )
            np.minimum(out, d.min(axis=0), out=out)
        if len(self._sph_c):
            d = np.linalg.norm(points[None] - self._sph_c[:, None], axis=-1) - self._sph_r[:, None]
            np.minimum(out, d.min(axis=0), out=out)
        return out

    def sample_surface(self, n: int, rng: np.random.Generator) -> Array:
        """(n, 3) points on the obstacles' surfaces, spread by area (world frame).

        The points of ``trimesh.sample.sample_surface`` on the obstacles' meshes joined, to the
        bit, computed here on the meshes' arrays: building trimesh objects took ~10 ms a scene,
        nine tenths of loading a training set (its clouds are drawn at load)."""
        from trimesh import triangles

        parts = [_mesh_arrays(p) for p in self.primitives]
        if not parts:
            raise PlanningError("the world has no obstacles to sample")
        offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
        V = np.vstack([v for v, _ in parts])
        F = np.vstack([f + o for (_, f), o in zip(parts, offsets, strict=True)])
        random = np.random.default_rng(int(rng.integers(2**31))).random
        weight_cum = np.cumsum(triangles.area(crosses=triangles.cross(V[F])))
        face = np.searchsorted(weight_cum, random(n) * weight_cum[-1])
        origins = V[F[:, 0]]
        vectors = V[F[:, 1:]] - np.tile(origins, (1, 2)).reshape((-1, 2, 3))
        origins, vectors = origins[face], vectors[face]
        lengths = random((len(vectors), 2, 1))  # a point of the parallelogram, folded
        lengths[lengths.sum(axis=1).reshape(-1) > 1.0] -= 1.0
        return (vectors * np.abs(lengths)).sum(axis=1) + origins

    # -- serialization -------------------------------------------------------------------

    def to_dict(self) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for p in self.primitives:
            if isinstance(p, Sphere):
                out.append({"type": "sphere", "radius": p.radius, "center": p.center.tolist()})
                continue
            xyz, quat = to_xyz_quat(p.pose)
            pose = {"xyz": xyz.tolist(), "quat_xyzw": quat.tolist()}
            if isinstance(p, Box):
                out.append({"type": "box", "size": p.size.tolist(), "pose": pose})
            else:
                out.append(
                    {"type": "cylinder", "radius": p.radius, "height": p.height, "pose": pose}
                )
        return out

    @staticmethod
    def from_dict(items: Any) -> PrimitiveWorld:
        """The world of a list of obstacles in the layout of the module docstring.
        PlanningError naming the obstacle (``obstacles[2].pose.rpy``), the field and what is
        valid for anything else: unknown or missing keys, non-numbers, NaN/inf, lengths
        <= 0, a quaternion that is not unit."""
        if not isinstance(items, list):
            raise PlanningError(
                f"obstacles: must be a list of obstacles ([] for none), got {show(items)}"
            )
        return PrimitiveWorld([_primitive(item, f"obstacles[{i}]") for i, item in enumerate(items)])


# -- reading obstacles -------------------------------------------------------------------


def _primitive(item: Any, where: str) -> Primitive:
    kinds = ", ".join(OBSTACLE_KEYS)
    if not isinstance(item, dict):
        raise PlanningError(
            f"{where}: an obstacle must be a mapping with a type ({kinds}), got {show(item)}"
        )
    kind = item.get("type")
    if not isinstance(kind, str) or kind not in OBSTACLE_KEYS:
        if "type" not in item:
            raise PlanningError(f"{where}: missing 'type'; valid: {kinds}")
        raise PlanningError(f"{where}.type: unknown type {show(kind)}; valid: {kinds}")
    _check_keys(item, OBSTACLE_KEYS[kind], where, f"a {kind}")
    if kind == "sphere":
        return Sphere(
            _positive(item["radius"], f"{where}.radius"),
            np.array(_numbers(item["center"], 3, f"{where}.center", "x, y, z in m")),
        )
    pose = parse_pose(item["pose"], f"{where}.pose")
    if kind == "box":
        size = _numbers(item["size"], 3, f"{where}.size", "full edge lengths in m")
        for axis, x in zip("xyz", size, strict=True):
            if x <= 0:
                raise PlanningError(f"{where}.size: lengths must be > 0 m, got {x} along {axis}")
        return Box(np.array(size), pose)
    return Cylinder(
        _positive(item["radius"], f"{where}.radius"),
        _positive(item["height"], f"{where}.height"),
        pose,
    )


def _check_keys(item: dict[Any, Any], valid: tuple[str, ...], where: str, what: str) -> None:
    """PlanningError for keys of ``item`` outside ``valid`` (listing the valid ones), or for
    a missing one (all of ``valid`` are required)."""
    unknown = [k for k in item if k not in valid]
    if unknown:
        hint = ""
        if any(
            str(k).startswith(("position", "orientation", "quat", "rpy", "xyz")) for k in unknown
        ):
            hint = f" (a pose is written pose: {_POSE_FORMS})"
        names = ", ".join(show(k) for k in unknown)
        raise PlanningError(
            f"{where}: unknown key{'s' * (len(unknown) > 1)} {names}; valid for {what}: "
            f"{', '.join(valid)}{hint}"
        )
    missing = [k for k in valid if k not in item]
    if missing:
        raise PlanningError(
            f"{where}: missing {', '.join(repr(k) for k in missing)}; {what} needs {', '.join(valid)}"
        )


def number(value: Any, where: str) -> float:
    """``value`` as a finite float; PlanningError unless it is a finite int or float."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise PlanningError(f"{where}: must be a number, got {show(value)}")
    try:
        x = float(value)
    except OverflowError as err:
        raise PlanningError(f"{where}: must be a finite number, got {show(value)}") from err
    if not math.isfinite(x):
        raise PlanningError(f"{where}: must be a finite number, got {x}")
    return x


def _numbers(value: Any, n: int, where: str, what: str) -> list[float]:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise PlanningError(f"{where}: must be {n} numbers ({what}), got {show(value)}")
    return numbers(value, where)


def numbers(values: list[Any] | tuple[Any, ...], where: str) -> list[float]:
    """``values`` as finite floats; PlanningError naming the first bad one (``where[i]``)."""
    # The common case in one pass (exact types: a bool is an int but not a number here).
    if all(type(v) is float or type(v) is int for v in values):
        try:
            out = list(map(float, values))
        except OverflowError:  # an int beyond float's range; named below
            pass
        else:
            if all(map(math.isfinite, out)):
                return out
    return [number(v, f"{where}[{i}]") for i, v in enumerate(values)]


def _positive(value: Any, where: str) -> float:
    x = number(value, where)
    if x <= 0:
        raise PlanningError(f"{where}: must be > 0 m, got {x}")
    return x


def parse_pose(raw: Any, where: str) -> Array:
    """T_world_obstacle (4, 4) of a pose mapping (module docstring)."""
    if not isinstance(raw, dict):
        raise PlanningError(f"{where}: must be {_POSE_FORMS}, got {show(raw)}")
    unknown = [k for k in raw if k not in POSE_KEYS]
    if unknown:
        names = ", ".join(show(k) for k in unknown)
        raise PlanningError(
            f"{where}: unknown key{'s' * (len(unknown) > 1)} {names}; valid: xyz and one of "
            f"quat_xyzw, rpy: {_POSE_FORMS}"
        )
    if "xyz" not in raw:
        raise PlanningError(f"{where}: missing 'xyz' (position, m); a pose is {_POSE_FORMS}")
    if ("quat_xyzw" in raw) == ("rpy" in raw):
        which = "both quat_xyzw and rpy" if "rpy" in raw else "no orientation"
        raise PlanningError(
            f"{where}: has {which}; give the orientation once: quat_xyzw [x, y, z, w] or rpy "
            "[roll, pitch, yaw] (rad, fixed axes x, y, z)"
        )
    x, y, z = _numbers(raw["xyz"], 3, f"{where}.xyz", "position in m")
    if "rpy" in raw:
        R = _rpy_matrix(*_numbers(raw["rpy"], 3, f"{where}.rpy", "roll, pitch, yaw in rad"))
    else:
        q = _numbers(raw["quat_xyzw"], 4, f"{where}.quat_xyzw", "a unit quaternion x, y, z, w")
        norm = math.sqrt(sum(c * c for c in q))
        if abs(norm - 1.0) > QUAT_NORM_TOL:
            raise PlanningError(
                f"{where}.quat_xyzw: must be a unit quaternion (norm within {QUAT_NORM_TOL} "
                f"of 1), got norm {norm:.6g}"
            )
        R = _quat_matrix(*(c / norm for c in q))
    return np.array([[*R[0], x], [*R[1], y], [*R[2], z], [0.0, 0.0, 0.0, 1.0]])


def _quat_matrix(x: float, y: float, z: float, w: float) -> list[list[float]]:
    """Rotation matrix of a unit quaternion (x, y, z, w), in plain floats (one obstacle's
    numpy or scipy call costs more than this)."""
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> list[list[float]]:
    """Rz(yaw) Ry(pitch) Rx(roll): URDF's fixed-axis roll, pitch, yaw (rad)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]


_BOX_VERTICES: Array | None = None  # trimesh's unit box: vertices (8, 3) and faces (12, 3)
_BOX_FACES: npt.NDArray[np.int64] | None = None


def _mesh_arrays(p: Primitive) -> tuple[Array, npt.NDArray[np.int64]]:
    """Vertices (V, 3) and faces (F, 3) of :func:`primitive_mesh` (p): a box's by trimesh's
    own arithmetic (its unit box scaled, then ``transform_points``), without the object."""
    global _BOX_VERTICES, _BOX_FACES
    if not isinstance(p, Box):
        mesh = primitive_mesh(p)
        return np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
    from trimesh import transformations

    if _BOX_VERTICES is None or _BOX_FACES is None:
        unit = primitive_mesh(Box(np.ones(3), np.eye(4)))
        _BOX_VERTICES = (np.asarray(unit.vertices, float) + 0.5).copy()  # the corners 0 / 1
        _BOX_FACES = np.asarray(unit.faces, np.int64).copy()
    vertices = (_BOX_VERTICES - 0.5) * np.asarray(p.size, np.float64)
    return transformations.transform_points(vertices, p.pose), _BOX_FACES


def primitive_mesh(p: Primitive):  # type: ignore[no-untyped-def]
    """A trimesh of one primitive in the world frame."""
    import trimesh

    if isinstance(p, Box):
        return trimesh.creation.box(extents=p.size, transform=p.pose)
    if isinstance(p, Cylinder):
        return trimesh.creation.cylinder(
            radius=p.radius, height=p.height, transform=p.pose, sections=48
        )
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=p.radius)
    mesh.apply_translation(p.center)
    return mesh
