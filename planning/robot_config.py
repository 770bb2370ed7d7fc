"""Robot configuration: which URDF, its limits, its end effector, its collision settings.

A small YAML file makes any URDF usable (see ``planning/data/ur5.yaml``, the default).
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gaide_core.errors import ConfigError
from gaide_core.text_io import load_yaml
from gaide_core.transforms import from_xyz_rpy
from gaide_core.types import Array
from planning.robot_names import resolve_robot_config, shipped_robots


def example_robot_data_share() -> Path | None:
    """The ``share`` folder of the example-robot-data wheel (the root of its package:// URIs)."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    share = Path(str(dist.locate_file("cmeel.prefix/share")))
    return share if share.is_dir() else None


@dataclass(frozen=True, kw_only=True)
class RobotConfig:
    """Everything about a robot that the URDF does not say (or that overrides it)."""

    urdf: Path  # URDF file, resolved
    package_dirs: tuple[Path, ...] = ()  # roots for package:// mesh URIs
    srdf: Path | None = None  # disabled collision pairs (optional)
    spheres: Path | None = None  # cuRobo sphere YAML or a spherized URDF; generated when absent
    end_effector: str = "tool0"  # frame name
    T_world_base: Array = field(default_factory=lambda: np.eye(4))  # base pose in world
    lower: Array | None = None  # joint position limits (rad), None: from URDF
    upper: Array | None = None
    velocity_limits: Array | None = None  # rad/s, None: from URDF
    acceleration_limits: Array | None = None  # rad/s^2
    jerk_limits: Array | None = None  # rad/s^3
    collision_margin: float = 0.005  # m
    edge_resolution: float = 0.01  # m, max sphere-centre motion between edge samples
    ignored_link_pairs: tuple[tuple[str, str], ...] = ()
    world_ignored_links: tuple[str, ...] = ()  # links bolted to the mount: self-checks only
    named_configurations: dict[str, Array] = field(default_factory=dict)
    # Joints held at a value and left out of planning (grippers, fingers, a mobile base):
    # the planning model is Pinocchio's reduced model with these joints fixed.
    locked_joints: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.collision_margin < 0:
            raise ConfigError(f"collision_margin must be >= 0 m, got {self.collision_margin}")
        if self.edge_resolution <= 0:
            raise ConfigError(f"edge_resolution must be > 0 m, got {self.edge_resolution}")
        if self.T_world_base.shape != (4, 4):
            raise ConfigError("base_pose must give a 4x4 transform")
        for name in ("velocity_limits", "acceleration_limits", "jerk_limits"):
            value = getattr(self, name)
            if value is not None and (not np.all(np.isfinite(value)) or np.any(value <= 0)):
                raise ConfigError(f"{name} must be finite and > 0, got {value.tolist()}")

    def replace(self, **changes: Any) -> RobotConfig:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def resolve_uri(uri: str, base_dir: Path, package_dirs: tuple[Path, ...]) -> Path:
    """Resolve ``package://pkg/rel`` or a path relative to ``base_dir``."""
    if uri.startswith("package://"):
        rel = uri[len("package://") :]
        for root in package_dirs:
            if (root / rel).exists():
                return root / rel
        searched = ", ".join(str(p) for p in package_dirs) or "(none)"
        raise ConfigError(f"cannot resolve {uri}: not found under package_dirs {searched}")
    path = Path(uri).expanduser()
    return path if path.is_absolute() else (base_dir / path)


def _vector(raw: Any, name: str, source: Path) -> Array | None:
    if raw is None:
        return None
    try:
        arr = np.asarray(raw, dtype=float)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{source}: {name} must be a list of numbers, got {raw!r}") from err
    if arr.ndim != 1:
        raise ConfigError(f"{source}: {name} must be a flat list, got shape {arr.shape}")
    return arr


def _mapping(raw: Any, name: str, source: Path) -> dict[str, Any]:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise ConfigError(f"{source}: {name} must be a mapping, got {raw!r}")
    return raw


def _triple(raw: Any, name: str, source: Path) -> Array:
    arr = _vector(raw, name, source)
    if arr is None or arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ConfigError(f"{source}: {name} must be 3 finite numbers, got {raw!r}")
    return arr


def _number(raw: Any, name: str, unit: str, source: Path) -> float:
    try:
        value = float(raw)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{source}: {name} must be a number ({unit}), got {raw!r}") from err
    if not np.isfinite(value):  # a NaN margin or resolution would pass every check after
        raise ConfigError(f"{source}: {name} must be a finite number ({unit}), got {raw!r}")
    return value


def load_robot_config(path: str | Path | None = None) -> RobotConfig:
    """Load a robot config YAML, or a shipped robot's by name (:func:`resolve_robot_config`;
    default: the UR5 of example-robot-data)."""
    source = resolve_robot_config(path)
    if not source.exists():
        raise ConfigError(
            f"robot config {source} does not exist; give a robot config YAML or a shipped "
            f"robot's name: {', '.join(shipped_robots())}"
        )
    raw = load_yaml(source, "robot config", ConfigError)
    if not isinstance(raw, dict) or "urdf" not in raw:
        raise ConfigError(f"robot config {source} must be a mapping with at least 'urdf'")
    known = {
        "urdf", "package_dirs", "srdf", "spheres", "end_effector", "base_pose", "joint_limits",
        "velocity_limits", "acceleration_limits", "jerk_limits", "collision_margin",
        "edge_resolution", "ignored_link_pairs", "world_ignored_links", "named_configurations",
        "locked_joints",
    }  # fmt: skip
    unknown = sorted(set(raw) - known)
    if unknown:
        raise ConfigError(f"robot config {source}: unknown keys {unknown}; valid: {sorted(known)}")
    base_dir = source.parent
    dirs = [resolve_uri(str(p), base_dir, ()) for p in raw.get("package_dirs") or []]
    share = example_robot_data_share()
    if share is not None:
        dirs.append(share)
    package_dirs = tuple(dirs)

    def opt_path(key: str) -> Path | None:
        value = raw.get(key)
        return None if value is None else resolve_uri(str(value), base_dir, package_dirs)

    base = _mapping(raw.get("base_pose"), "base_pose", source)
    limits = _mapping(raw.get("joint_limits"), "joint_limits", source)
    pairs = raw.get("ignored_link_pairs") or []
    if not all(isinstance(p, (list, tuple)) and len(p) == 2 for p in pairs):
        raise ConfigError(f"{source}: ignored_link_pairs must be a list of [link_a, link_b]")
    named = {}
    for key, value in (raw.get("named_configurations") or {}).items():
        vec = _vector(value, f"named_configurations.{key}", source)
        if vec is None:
            raise ConfigError(f"{source}: named_configurations.{key} has no joint values")
        named[str(key)] = vec
    locked_raw = raw.get("locked_joints") or {}
    if not isinstance(locked_raw, dict):
        raise ConfigError(f"{source}: locked_joints must map joint names to values (rad or m)")
    locked = {}
    for key, value in locked_raw.items():
        try:
            locked[str(key)] = float(value)
        except (TypeError, ValueError) as err:
            raise ConfigError(
                f"{source}: locked_joints.{key} must be a number (rad or m), got {value!r}"
            ) from err
    return RobotConfig(
        urdf=resolve_uri(str(raw["urdf"]), base_dir, package_dirs),
        package_dirs=package_dirs,
        srdf=opt_path("srdf"),
        spheres=opt_path("spheres"),
        end_effector=str(raw.get("end_effector", "tool0")),
        T_world_base=from_xyz_rpy(
            _triple(base.get("xyz", [0, 0, 0]), "base_pose.xyz", source),
            _triple(base.get("rpy", [0, 0, 0]), "base_pose.rpy", source),
        ),
        lower=_vector(limits.get("lower"), "joint_limits.lower", source),
        upper=_vector(limits.get("upper"), "joint_limits.upper", source),
        velocity_limits=_vector(raw.get("velocity_limits"), "velocity_limits", source),
        acceleration_limits=_vector(raw.get("acceleration_limits"), "acceleration_limits", source),
        jerk_limits=_vector(raw.get("jerk_limits"), "jerk_limits", source),
        collision_margin=_number(
            raw.get("collision_margin", 0.005), "collision_margin", "m", source
        ),
        edge_resolution=_number(raw.get("edge_resolution", 0.01), "edge_resolution", "m", source),
        ignored_link_pairs=tuple((str(a), str(b)) for a, b in pairs),
        world_ignored_links=tuple(str(v) for v in raw.get("world_ignored_links") or []),
        named_configurations=named,
        locked_joints=locked,
    )
