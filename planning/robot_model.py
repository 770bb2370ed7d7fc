"""The robot as Pinocchio sees it: joints, limits, frames, links and their collision meshes.

Frames: every pose returned here is in the world frame, ``T_world_frame = T_world_base @
T_base_frame`` with ``T_world_base`` from the robot config (identity by default, so that
"world" and "base" coincide unless the user places the robot elsewhere).
"""

from __future__ import annotations

import logging
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import trimesh

from gaide_core.errors import GaideError, RobotModelError
from gaide_core.types import Array
from planning.robot_config import RobotConfig, load_robot_config

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Link:
    """A rigid link: a URDF link with its frame index and the joint that moves it."""

    name: str
    frame_id: int  # Pinocchio frame index of the link's BODY frame
    joint_id: int  # Pinocchio joint index the link is attached to (0: fixed to the base)
    T_joint_link: Array  # (4, 4) pose of the link frame in its joint frame
    parent: str | None  # the link it hangs from in the kinematic tree


# Pinocchio joint models a serial arm's planner cannot use (their configurations are not one
# bounded coordinate per degree of freedom), by the name after "JointModel".
_JOINT_KINDS = {
    "FreeFlyer": "floating (a floating base)",
    "Planar": "planar",
    "Spherical": "spherical",
    "SphericalZYX": "spherical",
    "RUBX": "continuous (unbounded)",
    "RUBY": "continuous (unbounded)",
    "RUBZ": "continuous (unbounded)",
    "RevoluteUnboundedUnaligned": "continuous (unbounded)",
    "Composite": "composite",
    "Mimic": "a mimic joint",
}


def _se3(M: pin.SE3) -> Array:
    return np.asarray(M.homogeneous, dtype=float)


class RobotModel:
    """Kinematics, limits and collision geometry of one robot, loaded from its URDF."""

    def __init__(self, config: RobotConfig) -> None:
        self.config = config
        urdf = config.urdf
        if not urdf.is_file():
            raise RobotModelError(f"URDF {urdf} does not exist")
        try:
            full = pin.buildModelFromUrdf(str(urdf))
        except (RuntimeError, ValueError) as err:
            raise RobotModelError(f"URDF {urdf} does not parse: {err}") from err
        self.model = _reduced(full, config.locked_joints, urdf)
        for j in range(1, self.model.njoints):
            kind = _JOINT_KINDS.get(self.model.joints[j].shortname()[len("JointModel") :])
            if kind is not None:
                raise RobotModelError(
                    f"URDF {urdf}: joint '{self.model.names[j]}' is {kind}; only revolute "
                    "(with limits), prismatic and fixed joints are supported"
                    + (": give it limits (type revolute)" if kind.startswith("continuous") else "")
                )
        self.data = self.model.createData()
        self.dof = int(self.model.nq)
        self.joint_names: tuple[str, ...] = tuple(self.model.names[1:])
        self.lower, self.upper = self._limits(config)
        self.velocity_limits = self._per_joint(
            config.velocity_limits, np.asarray(self.model.velocityLimit, float), "velocity_limits"
        )
        self.acceleration_limits = self._per_joint(
            config.acceleration_limits, np.full(self.dof, 8.0), "acceleration_limits"
        )
        self.jerk_limits = self._per_joint(
            config.jerk_limits, np.full(self.dof, 80.0), "jerk_limits"
        )
        self.T_world_base = np.asarray(config.T_world_base, float)
        self.links = self._links()
        self.ee_frame = self.frame_id(config.end_effector)
        for name, q in config.named_configurations.items():
            self.check_configuration(q, what=f"named configuration '{name}'")

    # -- construction helpers -------------------------------------------------------------

    def _per_joint(self, override: Array | None, default: Array, name: str) -> Array:
        value = default if override is None else override
        if value.shape != (self.dof,):
            raise RobotModelError(
                f"{name} has {value.size} values; the robot has {self.dof} joints "
                f"{list(self.joint_names)}"
            )
        if np.any(~np.isfinite(value)) or np.any(value <= 0):
            raise RobotModelError(f"{name} must be finite and > 0, got {value.tolist()}")
        return value.astype(float)

    def _limits(self, config: RobotConfig) -> tuple[Array, Array]:
        lower = np.asarray(self.model.lowerPositionLimit, float).copy()
        upper = np.asarray(self.model.upperPositionLimit, float).copy()
        if config.lower is not None:
            lower = self._per_joint_any(config.lower, "joint_limits.lower")
        if config.upper is not None:
            upper = self._per_joint_any(config.upper, "joint_limits.upper")
        if np.any(~np.isfinite(lower)) or np.any(~np.isfinite(upper)) or np.any(lower >= upper):
            raise RobotModelError(
                f"joint limits must be finite with lower < upper; got lower={lower.tolist()} "
                f"upper={upper.tolist()}"
            )
        return lower, upper

    def _per_joint_any(self, value: Array, name: str) -> Array:
        if value.shape != (self.dof,):
            raise RobotModelError(
                f"{name} has {value.size} values; the robot has {self.dof} joints "
                f"{list(self.joint_names)}"
            )
        return value.astype(float)

    def _links(self) -> dict[str, Link]:
        links: dict[str, Link] = {}
        frames = self.model.frames
        for fid, frame in enumerate(frames):
            if frame.type != pin.FrameType.BODY:
                continue
            parent = None
            f = frame.parentFrame
            while f != fid and f < len(frames):
                pf = frames[f]
                if pf.type == pin.FrameType.BODY and f != fid:
                    parent = pf.name
                    break
                if f == pf.parentFrame:
                    break
                f = pf.parentFrame
            links[frame.name] = Link(
                name=frame.name,
                frame_id=fid,
                joint_id=int(frame.parentJoint),
                T_joint_link=_se3(frame.placement),
                parent=parent,
            )
        return links

    # -- names and checks ------------------------------------------------------------------

    def frame_id(self, name: str) -> int:
        """Pinocchio frame index of ``name``; RobotModelError listing valid names otherwise."""
        if not self.model.existFrame(name):
            valid = sorted({f.name for f in self.model.frames})
            raise RobotModelError(f"unknown frame '{name}'; valid frames: {valid}")
        return int(self.model.getFrameId(name))

    def link(self, name: str) -> Link:
        if name not in self.links:
            raise RobotModelError(f"unknown link '{name}'; valid links: {sorted(self.links)}")
        return self.links[name]

    def as_configuration(self, q: npt.ArrayLike, what: str = "configuration") -> Array:
        """``q`` as a float (dof,) array; RobotModelError for a wrong length or NaN/inf."""
        try:
            arr = np.asarray(q, dtype=float)
        except (TypeError, ValueError) as err:
            raise RobotModelError(f"{what} is not a numeric vector: {q!r}") from err
        if arr.shape != (self.dof,):
            raise RobotModelError(
                f"{what} has shape {arr.shape}; expected ({self.dof},) for joints "
                f"{list(self.joint_names)}"
            )
        if not np.isfinite(arr).all():
            bad = np.flatnonzero(~np.isfinite(arr))
            raise RobotModelError(
                f"{what} has non-finite values at joints {[self.joint_names[i] for i in bad]}"
            )
        return arr

    def check_configuration(self, q: npt.ArrayLike, what: str = "configuration") -> Array:
        """Like :meth:`as_configuration`, and also refuse values outside the joint limits."""
        arr = self.as_configuration(q, what)
        out = np.flatnonzero((arr < self.lower) | (arr > self.upper))
        if out.size:
            i = int(out[0])
            raise RobotModelError(
                f"{what}: joint {self.joint_names[i]} = {arr[i]:.4f} rad is outside its limits "
                f"[{self.lower[i]:.4f}, {self.upper[i]:.4f}]"
            )
        return arr

    def within_limits(self, Q: Array) -> npt.NDArray[np.bool_]:
        """(B,) True where every joint of Q (B, dof) is inside its limits."""
        return np.all((self.lower <= Q) & (self.upper >= Q), axis=-1)

    def sample_uniform(self, rng: np.random.Generator, n: int) -> Array:
        """(n, dof) configurations uniform within the joint limits."""
        return rng.uniform(self.lower, self.upper, size=(n, self.dof))

    def configuration_from_text(
        self,
        text: str,
        what: str = "configuration",
        error: type[GaideError] = RobotModelError,
    ) -> Array:
        """The joint vector ``text`` names: a named configuration of the robot config, or
        dof comma-separated angles (rad). Otherwise ``error`` (a run's setting: ConfigError)
        naming the forms, or the joints when the count is wrong (limits are not checked
        here)."""
        spec = text.strip()
        named = self.config.named_configurations
        if spec in named:
            return self.named_configuration(spec)
        try:
            values = [float(v) for v in spec.split(",") if v.strip()]
        except ValueError:
            values = []
        if not values or not all(math.isfinite(v) for v in values):
            raise error(
                f"{what} '{text}': give {self.dof} comma-separated angles (rad) or one of the "
                f"named configurations {sorted(named) or '(none)'}"
            )
        if len(values) != self.dof:
            raise error(
                f"{what} '{text}' has {len(values)} values; the robot has {self.dof} joints "
                f"{list(self.joint_names)} (rad)"
            )
        return np.array(values)

    def named_configuration(self, name: str) -> Array:
        named = self.config.named_configurations
        if name not in named:
            raise RobotModelError(
                f"unknown named configuration '{name}'; valid: {sorted(named) or '(none)'}"
            )
        return named[name].copy()

    # -- kinematics ----------------------------------------------------------------------

    def frame_pose(self, q: npt.ArrayLike, frame: str | int | None = None) -> Array:
        """(4, 4) pose of ``frame`` (default: the end effector) in the world frame."""
        arr = self.as_configuration(q)
        fid = (
            self.ee_frame
            if frame is None
            else (frame if isinstance(frame, int) else self.frame_id(frame))
        )
        pin.framesForwardKinematics(self.model, self.data, arr)
        return self.T_world_base @ _se3(self.data.oMf[fid])

    def link_poses(self, q: npt.ArrayLike) -> dict[str, Array]:
        """World pose (4, 4) of every link at configuration ``q``."""
        arr = self.as_configuration(q)
        pin.framesForwardKinematics(self.model, self.data, arr)
        return {
            name: self.T_world_base @ _se3(self.data.oMf[link.frame_id])
            for name, link in self.links.items()
        }

    def frame_jacobian(self, q: Array, fid: int) -> Array:
        """(6, dof) Jacobian of frame ``fid`` in its LOCAL frame (Pinocchio convention)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return np.asarray(
            pin.getFrameJacobian(self.model, self.data, fid, pin.ReferenceFrame.LOCAL), float
        )

    # -- collision geometry ----------------------------------------------------------------

    @cached_property
    def link_meshes(self) -> dict[str, trimesh.Trimesh]:
        """Collision geometry of each link, as one mesh in the link frame (links without
        collision geometry are absent)."""
        config = self.config
        try:
            geom = pin.buildGeomFromUrdf(
                self.model,
                str(config.urdf),
                pin.GeometryType.COLLISION,
                package_dirs=[str(p) for p in config.package_dirs],
            )
        except (RuntimeError, ValueError) as err:
            raise RobotModelError(
                f"URDF {config.urdf}: collision geometry cannot be loaded ({err}); "
                f"package_dirs searched: {[str(p) for p in config.package_dirs]}"
            ) from err
        parts: dict[str, list[trimesh.Trimesh]] = {}
        frame_to_link = {link.frame_id: name for name, link in self.links.items()}
        for obj in geom.geometryObjects:
            mesh = _geometry_to_mesh(obj, config.urdf)
            link_name = frame_to_link.get(int(obj.parentFrame))
            if link_name is None:
                continue
            link = self.links[link_name]
            T_link_geom = np.linalg.inv(link.T_joint_link) @ _se3(obj.placement)
            mesh.apply_transform(T_link_geom)
            parts.setdefault(link_name, []).append(mesh)
        merged: dict[str, trimesh.Trimesh] = {}
        for name, ms in parts.items():
            joined = trimesh.util.concatenate(ms)
            if not isinstance(joined, trimesh.Trimesh):
                raise RobotModelError(f"URDF {config.urdf}: link {name} has no triangle mesh")
            merged[name] = joined
        return merged

    @cached_property
    def disabled_link_pairs(self) -> frozenset[frozenset[str]]:
        """Link pairs never checked against each other: links on the same or neighbouring
        joints (they touch by design), the SRDF's disabled pairs, the config's ignored pairs."""
        names = list(self.links)
        pairs = {
            frozenset((a, b))
            for i, a in enumerate(names)
            for b in names[i + 1 :]
            if self.chain_adjacent(a, b)
        }
        if self.config.srdf is not None:
            pairs |= _srdf_disabled_pairs(self.config.srdf)
        for a, b in self.config.ignored_link_pairs:
            self.link(a), self.link(b)
            pairs.add(frozenset((a, b)))
        return frozenset(pairs)

    def chain_adjacent(self, a: str, b: str) -> bool:
        """True if links a and b are the same or neighbours in the kinematic tree (counting
        links rigidly fixed to one joint as one body)."""
        la, lb = self.link(a), self.link(b)
        if a == b or la.joint_id == lb.joint_id:
            return True
        ja, jb = la.joint_id, lb.joint_id
        return int(self.model.parents[ja]) == jb or int(self.model.parents[jb]) == ja


def _geometry_to_mesh(obj: pin.GeometryObject, urdf: Path) -> trimesh.Trimesh:
    """A trimesh of one Pinocchio geometry object, in its own frame (scale applied)."""
    path = str(obj.meshPath)
    if path and path not in ("BOX", "SPHERE", "CYLINDER", "CAPSULE", "CONE"):
        if not Path(path).is_file():
            raise RobotModelError(f"URDF {urdf}: mesh {path} of '{obj.name}' cannot be found")
        try:
            loaded = trimesh.load(path, force="mesh")
        except Exception as err:  # trimesh raises many kinds for bad files
            raise RobotModelError(f"URDF {urdf}: mesh {path} cannot be read: {err}") from err
        mesh = loaded.copy()
        mesh.apply_scale(np.asarray(obj.meshScale, float))
        return mesh
    g = obj.geometry
    kind = type(g).__name__
    if kind == "Box":
        return trimesh.creation.box(extents=2.0 * np.asarray(g.halfSide, float))
    if kind == "Sphere":
        return trimesh.creation.icosphere(subdivisions=3, radius=float(g.radius))
    if kind == "Cylinder":
        return trimesh.creation.cylinder(radius=float(g.radius), height=2.0 * float(g.halfLength))
    if kind == "Capsule":
        return trimesh.creation.capsule(height=2.0 * float(g.halfLength), radius=float(g.radius))
    raise RobotModelError(f"URDF {urdf}: collision geometry type {kind} is not supported")


def _reduced(full: pin.Model, locked: dict[str, float], urdf: Path) -> pin.Model:
    """``full`` with the ``locked`` joints fixed at their values (Pinocchio's reduced model:
    their links stay, carried by the joint above them)."""
    if not locked:
        return full
    q_ref = pin.neutral(full)
    ids = []
    for name, value in locked.items():
        if not full.existJointName(name):
            raise RobotModelError(
                f"locked_joints: URDF {urdf} has no joint '{name}'; its joints: "
                f"{list(full.names[1:])}"
            )
        jid = int(full.getJointId(name))
        joint = full.joints[jid]
        if joint.nq != 1:
            raise RobotModelError(
                f"locked_joints: joint '{name}' has {joint.nq} coordinates; only revolute and "
                "prismatic joints can be locked"
            )
        lo, hi = full.lowerPositionLimit[joint.idx_q], full.upperPositionLimit[joint.idx_q]
        if not lo <= value <= hi:
            raise RobotModelError(
                f"locked_joints: {name} = {value} is outside its limits [{lo:.4f}, {hi:.4f}]"
            )
        q_ref[joint.idx_q] = value
        ids.append(jid)
    if len(ids) == full.njoints - 1:
        raise RobotModelError(f"locked_joints locks every joint of {urdf}; nothing is left to plan")
    return pin.buildReducedModel(full, ids, q_ref)


def read_xml(path: Path, what: str) -> ET.Element:
    """The root element of an XML file (a URDF, an SRDF); RobotModelError naming ``what``
    and the file when it is missing or does not parse."""
    if not path.is_file():
        raise RobotModelError(f"{what} {path} does not exist")
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as err:
        raise RobotModelError(f"{what} {path} does not parse: {err}") from err


def _srdf_disabled_pairs(srdf: Path) -> set[frozenset[str]]:
    root = read_xml(srdf, "SRDF")
    return {
        frozenset((el.attrib["link1"], el.attrib["link2"]))
        for el in root.iter("disable_collisions")
        if "link1" in el.attrib and "link2" in el.attrib
    }


def load_robot(config: str | Path | RobotConfig | None = None) -> RobotModel:
    """Load a robot from a config file path, a RobotConfig, or the default UR5."""
    cfg = config if isinstance(config, RobotConfig) else load_robot_config(config)
    return RobotModel(cfg)
