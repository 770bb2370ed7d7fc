"""The plan file (``plan.json``): one joint path with where it came from.

``gaide plan`` writes it, ``gaide run`` writes it into its output folder, and ``gaide time``
reads either. One schema, one writer, one reader::

    {
      "planner": "rrtc",                 # who planned it
      "status": "success",
      "scene": "shelf_1 seed 3",         # what it was planned in: a scene spec, or a file
                                         # relative to this file's folder ("scene.ply")
      "joint_names": ["shoulder_pan_joint", ...],
      "time_s": 0.012,                   # planning time of the attempt that succeeded
      "cost_rad": 3.41,                  # joint-space length
      "start": [...], "goal": [...],     # (dof,) rad
      "path": [[...], ...],              # (K, dof) rad, start to goal
      "stats": {...}                     # the planner's counters (free form)
    }

Only ``path`` is required when reading; a path file written by hand may leave out the rest.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import GaideError, TimingError
from gaide_core.text_io import load_json
from gaide_core.types import Array


@dataclass(frozen=True, kw_only=True)
class PlanFile:
    """A planned joint path and its provenance (see the module doc for the JSON keys)."""

    path: Array  # (K, dof) rad
    joint_names: tuple[str, ...] | None = None
    scene: str | None = None
    planner: str = ""
    status: str = ""
    time_s: float | None = None
    cost_rad: float | None = None
    start: Array | None = None
    goal: Array | None = None
    stats: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON object, keys in the documented order; absent values are left out."""
        out: dict[str, Any] = {
            "planner": self.planner,
            "status": self.status,
            "scene": self.scene,
            "joint_names": None if self.joint_names is None else list(self.joint_names),
            "time_s": self.time_s,
            "cost_rad": self.cost_rad,
            "start": None if self.start is None else np.asarray(self.start).tolist(),
            "goal": None if self.goal is None else np.asarray(self.goal).tolist(),
            "path": np.asarray(self.path).tolist(),
            # Planner counters may hold numpy scalars or enums: store what they print as.
            "stats": json.loads(json.dumps(self.stats, default=str)),
        }
        return {k: v for k, v in out.items() if v is not None}


def write_plan(
    path: str | os.PathLike[str], plan: PlanFile, error: type[GaideError] = GaideError
) -> None:
    """Write ``plan`` atomically; ``error`` naming the file if the system refuses."""
    write_bytes_atomic(path, plan_bytes(plan), error)


def plan_bytes(plan: PlanFile) -> bytes:
    """The file's bytes (for writers that stage several outputs together)."""
    return (json.dumps(plan.to_dict(), indent=2) + "\n").encode()


def read_plan(path: str | os.PathLike[str], error: type[GaideError] = TimingError) -> PlanFile:
    """The plan file at ``path``; ``error`` naming the file and the key that is wrong.

    The path is only checked to be a list of numeric waypoints of one length here: its
    limits and collisions are the reader's business (it knows the robot)."""
    raw = load_json(path, "path file", error)
    where = f"path file {path}"
    if not isinstance(raw, dict) or "path" not in raw:
        raise error(f"{where} needs a 'path' list of waypoints (as `gaide plan` writes)")
    names = raw.get("joint_names")
    if names is not None and (
        not isinstance(names, list) or not all(isinstance(n, str) for n in names)
    ):
        raise error(f"{where}: 'joint_names' must be a list of joint names, got {names!r}")
    scene = raw.get("scene")
    if scene is not None and not isinstance(scene, str):
        raise error(f"{where}: 'scene' must be a scene spec or file name, got {scene!r}")
    return PlanFile(
        path=_waypoints(raw["path"], where, error),
        joint_names=None if names is None else tuple(names),
        scene=scene,
        planner=str(raw.get("planner", "")),
        status=str(raw.get("status", "")),
        time_s=_number(raw.get("time_s"), "time_s", where, error),
        cost_rad=_number(raw.get("cost_rad"), "cost_rad", where, error),
        start=None if raw.get("start") is None else _vector(raw["start"], "start", where, error),
        goal=None if raw.get("goal") is None else _vector(raw["goal"], "goal", where, error),
        stats=stats if isinstance(stats := raw.get("stats"), dict) else {},
    )


def _waypoints(value: Any, where: str, error: type[GaideError]) -> Array:
    rows = value if isinstance(value, list) else None
    if rows is None or not all(isinstance(r, list) and all(_is_number(v) for v in r) for r in rows):
        raise error(f"{where}: 'path' must be a list of waypoints, each a list of numbers (rad)")
    if len({len(r) for r in rows}) > 1:
        raise error(f"{where}: the waypoints of 'path' differ in length; give one per joint")
    return np.array(rows, dtype=float).reshape(len(rows), -1)


def _vector(value: Any, key: str, where: str, error: type[GaideError]) -> Array:
    if not isinstance(value, list) or not all(_is_number(v) for v in value):
        raise error(f"{where}: '{key}' must be a list of numbers (rad), got {value!r}")
    return np.array(value, dtype=float)


def _number(value: Any, key: str, where: str, error: type[GaideError]) -> float | None:
    if value is None:
        return None
    if not _is_number(value) or not math.isfinite(value):
        raise error(f"{where}: '{key}' must be a finite number, got {value!r}")
    return float(value)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


__all__ = ["PlanFile", "plan_bytes", "read_plan", "write_plan"]
