"""The robot's collision spheres: per link, centres (link frame, m) and radii (m).

Stored in cuRobo's ``collision_spheres`` YAML layout so that users can bring their own::

    collision_spheres:
      upper_arm_link:
        - center: [0.0, 0.0, 0.1]
          radius: 0.07
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import yaml

from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import RobotModelError
from gaide_core.text_io import load_yaml
from gaide_core.types import Array
from planning.robot_model import RobotModel


@dataclass(frozen=True)
class SphereModel:
    """S spheres: ``links[s]`` carries sphere s at ``centers[s]`` (its link frame, m)."""

    links: tuple[str, ...]  # (S,) link names
    centers: Array  # (S, 3) m, in the link frame
    radii: Array  # (S,) m

    def __post_init__(self) -> None:
        n = len(self.links)
        if self.centers.shape != (n, 3) or self.radii.shape != (n,):
            raise RobotModelError(
                f"sphere model needs centers (S, 3) and radii (S,) for S={n} links; got "
                f"{self.centers.shape} and {self.radii.shape}"
            )
        if n == 0:
            raise RobotModelError("sphere model has no spheres")
        if not (np.all(np.isfinite(self.centers)) and np.all(np.isfinite(self.radii))):
            raise RobotModelError("sphere model has non-finite centres or radii")
        if np.any(self.radii <= 0):
            raise RobotModelError("sphere radii must be > 0 m")

    def __len__(self) -> int:
        return len(self.links)

    @property
    def link_names(self) -> tuple[str, ...]:
        """Links with at least one sphere, in order of first appearance."""
        return tuple(dict.fromkeys(self.links))

    def of_link(self, link: str) -> npt.NDArray[np.int64]:
        """Indices of the spheres of ``link``."""
        return np.flatnonzero(np.asarray(self.links) == link)

    def check_against(self, robot: RobotModel) -> None:
        """RobotModelError if a sphere names a link the robot does not have."""
        unknown = sorted(set(self.links) - set(robot.links))
        if unknown:
            raise RobotModelError(
                f"sphere model names links {unknown} that the robot does not have; "
                f"valid links: {sorted(robot.links)}"
            )

    # -- YAML (cuRobo layout) ------------------------------------------------------------

    def to_yaml(self) -> str:
        """cuRobo's layout, to the micrometre. Radii are rounded *up* by the centre's
        rounding error so that a covering model stays covering once written."""
        spheres: dict[str, list[dict[str, object]]] = {}
        for link, c, r in zip(self.links, self.centers, self.radii, strict=True):
            centre = np.round(c, 6)
            grow = float(np.linalg.norm(centre - c))
            radius = float(np.ceil((r + grow) * 1e6 - 1e-6) / 1e6)
            spheres.setdefault(link, []).append(
                {"center": [float(v) for v in centre], "radius": radius}
            )
        return yaml.safe_dump({"collision_spheres": spheres}, sort_keys=False)

    def save(self, path: str | Path) -> None:
        """Write the cuRobo YAML layout atomically."""
        write_bytes_atomic(path, self.to_yaml().encode(), RobotModelError)

    @staticmethod
    def load(path: str | Path) -> SphereModel:
        """Read cuRobo's layout: ``collision_spheres`` at the top level or under
        ``robot_cfg.kinematics``."""
        source = Path(path)
        raw = load_yaml(source, "sphere file", RobotModelError)
        if isinstance(raw, dict) and "robot_cfg" in raw:
            raw = (raw.get("robot_cfg") or {}).get("kinematics") or {}
        table = raw.get("collision_spheres") if isinstance(raw, dict) else None
        if not isinstance(table, dict):
            raise RobotModelError(
                f"sphere file {source} has no 'collision_spheres' mapping (cuRobo layout: "
                "collision_spheres: {link: [{center: [x, y, z], radius: r}, ...]})"
            )
        links: list[str] = []
        centers: list[list[float]] = []
        radii: list[float] = []
        for link, entries in table.items():
            for i, entry in enumerate(entries or []):
                try:
                    c = [float(v) for v in entry["center"]]
                    r = float(entry["radius"])
                except (KeyError, TypeError, ValueError) as err:
                    raise RobotModelError(
                        f"sphere file {source}: {link}[{i}] needs center [x, y, z] and radius"
                    ) from err
                if len(c) != 3:
                    raise RobotModelError(
                        f"sphere file {source}: {link}[{i}] center needs 3 values"
                    )
                if not all(map(math.isfinite, [*c, r])):
                    raise RobotModelError(
                        f"sphere file {source}: {link}[{i}] has a value that is not finite "
                        f"(center {c}, radius {r}): a NaN sphere would never collide"
                    )
                if r <= 0:
                    # cuRobo marks unused slots with negative radii; they carry no geometry.
                    continue
                links.append(str(link))
                centers.append(c)
                radii.append(r)
        return SphereModel(tuple(links), np.asarray(centers, float), np.asarray(radii, float))

    @staticmethod
    def load_for(path: str | Path, robot: RobotModel) -> SphereModel:
        """A robot config's ``spheres:`` file: a spherized URDF (``.urdf``, see
        :meth:`from_spherized_urdf`) or cuRobo's YAML layout (:meth:`load`)."""
        if Path(path).suffix.lower() == ".urdf":
            return SphereModel.from_spherized_urdf(path, robot)
        return SphereModel.load(path)

    # -- spherized URDFs -----------------------------------------------------------------

    @staticmethod
    def from_spherized_urdf(path: str | Path, robot: RobotModel) -> SphereModel:
        """Import the ``<collision><sphere>`` elements of a spherized URDF.

        Each sphere is re-expressed in the frame of the robot's link that rides on the same
        joint (joints matched by name), so a spherized URDF with extra fixed links (a gripper,
        a tool) imports onto the bare arm. Link frames must match the robot's; see
        :func:`frame_mismatch`.
        """
        source = Path(path)
        if not source.is_file():
            raise RobotModelError(f"spherized URDF {source} does not exist")
        try:
            model = pin.buildModelFromUrdf(str(source))
            root = _parse_xml(source)
        except (RuntimeError, ValueError) as err:
            raise RobotModelError(f"spherized URDF {source} does not parse: {err}") from err
        carrier = _carrier_links(robot)
        links: list[str] = []
        centers: list[Array] = []
        radii: list[float] = []
        for link_el in root.iter("link"):
            name = link_el.attrib.get("name", "")
            for col in link_el.iter("collision"):
                sphere = col.find("geometry/sphere")
                if sphere is None:
                    continue
                origin = col.find("origin")
                try:
                    xyz = _floats(
                        origin.attrib.get("xyz", "0 0 0") if origin is not None else "0 0 0"
                    )
                    radius = float(sphere.attrib["radius"])
                except (KeyError, ValueError) as err:
                    raise RobotModelError(
                        f"spherized URDF {source}: link '{name}' has a sphere without a numeric "
                        f"radius and origin xyz ({err})"
                    ) from err
                if len(xyz) != 3 or not all(map(math.isfinite, [*xyz, radius])) or radius <= 0:
                    raise RobotModelError(
                        f"spherized URDF {source}: link '{name}' has a sphere of radius {radius} "
                        f"at {xyz}: it needs a finite radius > 0 m and 3 finite coordinates"
                    )
                frame = model.frames[model.getFrameId(name)]
                joint_name = model.names[frame.parentJoint]
                p_joint = frame.placement.act(np.asarray(xyz, float))
                target = carrier.get(joint_name)
                if target is None:
                    raise RobotModelError(
                        f"spherized URDF {source}: link '{name}' rides on joint '{joint_name}', "
                        f"which the robot does not have; robot joints: {list(robot.joint_names)}"
                    )
                if model.existFrame(target) and (
                    model.frames[model.getFrameId(target)].parentJoint == frame.parentJoint
                ):
                    # The carrier link is in the URDF too, on the same joint: place the
                    # sphere in that link's own frame. This drops whatever fixed offset the
                    # URDF puts between its root and the robot's base (a mount height).
                    carrier_frame = model.frames[model.getFrameId(target)]
                    p_link = np.asarray(carrier_frame.placement.actInv(p_joint), float)
                else:
                    T_joint_link = robot.links[target].T_joint_link
                    p_link = (np.linalg.inv(T_joint_link) @ np.append(p_joint, 1.0))[:3]
                links.append(target)
                centers.append(p_link)
                radii.append(radius)
        if not links:
            raise RobotModelError(f"spherized URDF {source} has no <sphere> collision elements")
        return SphereModel(tuple(links), np.asarray(centers), np.asarray(radii))


def _carrier_links(robot: RobotModel) -> dict[str, str]:
    """For each joint name ('universe' for the fixed base), the robot link that carries
    spheres on it: the first link with collision geometry, else the first link."""
    names = ["universe", *robot.joint_names]
    meshes = robot.link_meshes
    carrier: dict[str, str] = {}
    for link in robot.links.values():
        jname = names[link.joint_id]
        if jname not in carrier or (carrier[jname] not in meshes and link.name in meshes):
            carrier[jname] = link.name
    return carrier


def frame_mismatch(urdf: str | Path, robot: RobotModel, q: Array) -> float:
    """Largest distance (m) between the link origins that ``urdf`` and ``robot`` share, at
    configuration ``q``, both expressed relative to the robot's first link."""
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    names = [model.names[j] for j in range(1, model.njoints)]
    if sorted(names) != sorted(robot.joint_names):
        raise RobotModelError(f"{urdf} has joints {names}; the robot has {list(robot.joint_names)}")
    q_other = np.array([q[robot.joint_names.index(n)] for n in names])
    pin.framesForwardKinematics(model, data, q_other)
    pin.framesForwardKinematics(robot.model, robot.data, q)
    shared = [n for n in robot.links if model.existFrame(n)]
    if not shared:
        raise RobotModelError(f"{urdf} shares no link names with the robot")
    ref = shared[0]
    T_ref_other = np.linalg.inv(data.oMf[model.getFrameId(ref)].homogeneous)
    T_ref_ours = np.linalg.inv(robot.data.oMf[robot.model.getFrameId(ref)].homogeneous)
    worst = 0.0
    for name in shared:
        a = T_ref_other @ data.oMf[model.getFrameId(name)].homogeneous
        b = T_ref_ours @ robot.data.oMf[robot.model.getFrameId(name)].homogeneous
        worst = max(worst, float(np.linalg.norm(a[:3, 3] - b[:3, 3])))
    return worst


def _parse_xml(path: Path):  # type: ignore[no-untyped-def]
    import xml.etree.ElementTree as ET

    try:
        return ET.parse(path).getroot()
    except ET.ParseError as err:
        raise RobotModelError(f"{path} is not valid XML: {err}") from err


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split()]
