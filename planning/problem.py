"""A planning problem: a world of primitives, a start and a goal, and where they came from.

Problem files (YAML or JSON) let users bring their own benchmark::

    problems:
      - name: my-problem-1          # optional, unique
        family: custom              # optional
        seed: 0                     # optional
        difficulty: free2tight      # optional: free2free, free2tight, tight2free, tight2tight
        start: [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]    # rad, one value per joint
        goal: [1.0, -1.2, 1.3, -1.6, -1.57, 0.0]
        obstacles:                  # base frame, metres
          - {type: box, size: [1.2, 1.2, 0.04], pose: {xyz: [0.3, 0, -0.04], quat_xyzw: [0, 0, 0, 1]}}
          - {type: cylinder, radius: 0.05, height: 0.3, pose: {xyz: [0.5, 0.2, 0.13]}}
          - {type: sphere, radius: 0.08, center: [0.4, -0.3, 0.3]}
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from core.errors import PlanningError
from planning.primitives import PrimitiveWorld

Array = npt.NDArray[np.float64]

DIFFICULTIES = ("free2free", "free2tight", "tight2free", "tight2tight")


@dataclass(frozen=True)
class Problem:
    name: str
    family: str
    seed: int
    world: PrimitiveWorld
    start: Array  # (dof,) rad
    goal: Array  # (dof,) rad
    difficulty: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name, "family": self.family, "seed": self.seed,
            "difficulty": self.difficulty, "start": self.start.tolist(),
            "goal": self.goal.tolist(), "obstacles": self.world.to_dict(),
        }  # fmt: skip


def difficulty(start_clearance: float, goal_clearance: float, tight_below: float = 0.04) -> str:
    """free/tight per end, as the paper's code tags problems: tight when the robot's
    clearance from the world is under ``tight_below`` (m)."""

    def word(c: float) -> str:
        return "tight" if c < tight_below else "free"

    return f"{word(start_clearance)}2{word(goal_clearance)}"


def problem_from_dict(item: Any, where: str, dof: int | None = None) -> Problem:
    if not isinstance(item, dict):
        raise PlanningError(f"{where}: a problem must be a mapping, got {type(item).__name__}")
    for key in ("start", "goal", "obstacles"):
        if key not in item:
            raise PlanningError(f"{where}: missing '{key}' (needs start, goal, obstacles)")
    start, goal = (np.asarray(item[k], dtype=float) for k in ("start", "goal"))
    for key, q in (("start", start), ("goal", goal)):
        if q.ndim != 1 or not np.all(np.isfinite(q)) or (dof is not None and len(q) != dof):
            raise PlanningError(
                f"{where}: {key} must be {dof or 'the robots'} finite joint values, got {item[key]}"
            )
    diff = str(item.get("difficulty", ""))
    if diff and diff not in DIFFICULTIES:
        raise PlanningError(f"{where}: difficulty '{diff}' is not one of {list(DIFFICULTIES)}")
    obstacles = item["obstacles"] or []
    if not isinstance(obstacles, list):
        raise PlanningError(f"{where}: obstacles must be a list")
    return Problem(
        name=str(item.get("name", where)),
        family=str(item.get("family", "custom")),
        seed=int(item.get("seed", 0)),
        world=PrimitiveWorld.from_dict(obstacles),
        start=start,
        goal=goal,
        difficulty=diff,
    )


def load_problems(path: str | Path, dof: int | None = None) -> list[Problem]:
    """Problems from a YAML or JSON file in the layout above."""
    source = Path(path)
    if not source.is_file():
        raise PlanningError(f"problem file {source} does not exist")
    try:
        text = source.read_text()
        data = json.loads(text) if source.suffix == ".json" else yaml.safe_load(text)
    except (json.JSONDecodeError, yaml.YAMLError, UnicodeDecodeError) as err:
        raise PlanningError(f"problem file {source} does not parse: {err}") from err
    items = data.get("problems") if isinstance(data, dict) else None
    if not isinstance(items, list) or not items:
        raise PlanningError(f"problem file {source} needs a non-empty 'problems' list")
    problems = [problem_from_dict(it, f"{source} problem {i}", dof) for i, it in enumerate(items)]
    names = [p.name for p in problems]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise PlanningError(f"problem file {source}: duplicate names {dup}")
    return problems


def save_problems(path: str | Path, problems: list[Problem]) -> None:
    """Write problems as YAML (or JSON for a .json path), atomically."""
    target = Path(path)
    payload = {"problems": [p.to_dict() for p in problems]}
    text = (
        json.dumps(payload, indent=1)
        if target.suffix == ".json"
        else yaml.safe_dump(payload, sort_keys=False)
    )
    tmp = target.with_name(target.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(target)
