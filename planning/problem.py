"""A planning problem: a world of primitives, a start, one or more goals, and where they
came from.

Problem files (YAML or JSON) let users bring their own benchmark::

    problems:
      - name: my-problem-1          # optional text, unique in the file (default: problem-<index>)
        family: custom              # optional text
        seed: 0                     # optional integer >= 0 (the planners' randomness)
        difficulty: free2tight      # optional: free2free, free2tight, tight2free, tight2tight
        start: [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]    # rad, one value per joint
        goal: [1.0, -1.2, 1.3, -1.6, -1.57, 0.0]        # rad; or a list of goals (below)
        obstacles:                  # base frame, metres; [] for none
          - {type: box, size: [1.2, 1.2, 0.04], pose: {xyz: [0.3, 0, -0.04], quat_xyzw: [0, 0, 0, 1]}}
          - {type: cylinder, radius: 0.05, height: 0.3, pose: {xyz: [0.5, 0.2, 0.13], rpy: [0, 0, 0]}}
          - {type: sphere, radius: 0.08, center: [0.4, -0.3, 0.3]}
      - name: two-goals
        start: [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]
        goal:                       # several goals: reaching any one of them solves the problem
          - [1.0, -1.2, 1.3, -1.6, -1.57, 0.0]
          - [-1.0, -1.2, 1.3, -1.6, -1.57, 0.0]
        obstacles: []

Several goals are spelled ``goal:`` with a list of joint vectors (as MotionBenchMaker's goal
sets); there is no ``goals:`` key. :attr:`Problem.goals` holds them (K, dof) and
:attr:`Problem.goal` the first. The harness hands every valid goal to the planners that take
several (``plan_between``: rrtc and the OMPL planners) and the valid goal nearest the start
to the others (the neural planners); its path check accepts a path ending at any goal.

Every key is checked: unknown keys are refused (listing the valid ones) at the top level, in
a problem, an obstacle and a pose; a pose is ``{xyz, quat_xyzw}`` or ``{xyz, rpy}`` (rad,
URDF's fixed axes); a quaternion's norm must be within 1e-3 of 1 (it is then normalized);
every number must be finite, every length > 0, every joint vector one value per joint of
the robot (see :mod:`planning.primitives` for obstacles). Joint limits and collisions are
not checked here: the harness counts such problems apart.

Files are read as UTF-8, at most ``MAX_FILE_BYTES``; YAML through the safe loaders only
(libyaml's when installed), with :mod:`gaide_core.text_io`'s limits on nesting and aliases (an alias bomb
is refused before anything is built). Anything else is one :class:`PlanningError` line
naming the file, the problem (index and name) and the field.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import PlanningError
from gaide_core.text_io import one_line, parse_yaml, read_text
from gaide_core.types import Array
from planning.primitives import PrimitiveWorld, numbers, show

DIFFICULTIES = ("free2free", "free2tight", "tight2free", "tight2tight")
PROBLEM_KEYS = ("name", "family", "seed", "difficulty", "start", "goal", "obstacles")
_REQUIRED = ("start", "goal", "obstacles")

MAX_FILE_BYTES = 64 * 2**20

# libyaml's parser and composer (5x faster than PyYAML's own here), the safe constructor.


@dataclass(frozen=True, init=False)
class Problem:
    name: str
    family: str
    seed: int
    world: PrimitiveWorld
    start: Array  # (dof,) rad
    goals: Array  # (K, dof) rad, K >= 1: reaching any one of them solves the problem
    difficulty: str = ""

    def __init__(
        self,
        name: str,
        family: str,
        seed: int,
        world: PrimitiveWorld,
        start: npt.ArrayLike,
        goal: npt.ArrayLike | None = None,
        difficulty: str = "",
        *,
        goals: npt.ArrayLike | None = None,
    ) -> None:
        """``goal`` is one goal (dof,) or several (K, dof); ``goals`` (K, dof) says the same
        (what :func:`dataclasses.replace` passes). Give one of them."""
        if (goal is None) == (goals is None):
            raise PlanningError(f"problem {name}: give goal or goals, exactly one of them")
        q0 = np.asarray(start, dtype=float)
        qs = np.asarray(goal if goals is None else goals, dtype=float)
        qs = qs[None] if qs.ndim == 1 else qs
        if q0.ndim != 1 or qs.ndim != 2 or qs.shape[1] != len(q0) or not len(qs):
            raise PlanningError(
                f"problem {name}: start must be (dof,) and goals (K >= 1, dof), got "
                f"{q0.shape} and {qs.shape}"
            )
        if not (np.isfinite(q0).all() and np.isfinite(qs).all()):
            raise PlanningError(f"problem {name}: start and goals must be finite")
        for key, value in (
            ("name", name), ("family", family), ("seed", seed), ("world", world),
            ("start", q0), ("goals", qs), ("difficulty", difficulty),
        ):  # fmt: skip
            object.__setattr__(self, key, value)

    @property
    def goal(self) -> Array:
        """The first goal (dof,) rad (what single-goal callers use)."""
        return self.goals[0]

    def to_dict(self) -> dict[str, Any]:
        """The problem in the file layout: ``goal`` is one vector, or a list of them."""
        goal = self.goals[0].tolist() if len(self.goals) == 1 else self.goals.tolist()
        return {
            "name": self.name, "family": self.family, "seed": self.seed,
            "difficulty": self.difficulty, "start": self.start.tolist(),
            "goal": goal, "obstacles": self.world.to_dict(),
        }  # fmt: skip


def difficulty(start_clearance: float, goal_clearance: float, tight_below: float = 0.04) -> str:
    """free/tight per end, as the paper's code tags problems: tight when the robot's
    clearance from the world is under ``tight_below`` (m)."""

    def word(c: float) -> str:
        return "tight" if c < tight_below else "free"

    return f"{word(start_clearance)}2{word(goal_clearance)}"


# -- reading ------------------------------------------------------------------------------


def problem_from_dict(
    item: Any, where: str, dof: int | None = None, *, default_name: str | None = None
) -> Problem:
    """The problem of one mapping in the file layout (module docstring). ``where`` names it
    in errors (``"p.yaml: problem 3"``); ``dof``: the robot's joint count (None: the start's
    length, which the goals must share); ``default_name``: the name when it has none
    (None: ``where``)."""
    if not isinstance(item, dict):
        raise PlanningError(f"{where}: a problem must be a mapping, got {show(item)}")
    name = item.get("name", where if default_name is None else default_name)
    if not isinstance(name, str) or not name:
        raise PlanningError(
            f"{where}: name: must be non-empty text, got {show(name)} (quote numbers: name: '7')"
        )
    if "name" in item:
        where = f"{where} {show(name)}"
    try:
        return _problem(item, name, dof)
    except PlanningError as err:
        raise PlanningError(f"{where}: {err}") from err


def _problem(item: dict[Any, Any], name: str, dof: int | None) -> Problem:
    unknown = [k for k in item if k not in PROBLEM_KEYS]
    if unknown:
        hint = " (several goals are written goal: [[...], [...]])" if "goals" in unknown else ""
        raise PlanningError(
            f"unknown key{'s' * (len(unknown) > 1)} {', '.join(show(k) for k in unknown)}; "
            f"valid: {', '.join(PROBLEM_KEYS)}{hint}"
        )
    missing = [k for k in _REQUIRED if k not in item]
    if missing:
        raise PlanningError(
            f"missing {', '.join(repr(k) for k in missing)} (a problem needs start, goal, "
            f"obstacles; optional: name, family, seed, difficulty)"
        )
    family = item.get("family", "custom")
    if not isinstance(family, str) or not family:
        raise PlanningError(f"family: must be non-empty text, got {show(family)}")
    seed = item.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise PlanningError(f"seed: must be an integer >= 0, got {show(seed)}")
    diff = item.get("difficulty", "")
    if not isinstance(diff, str) or (diff and diff not in DIFFICULTIES):
        raise PlanningError(
            f"difficulty: {show(diff)} is not one of {list(DIFFICULTIES)} (or leave it out)"
        )
    start = _joints(item["start"], "start", dof)
    n = len(start)
    raw = item["goal"]
    if isinstance(raw, list) and raw and isinstance(raw[0], list):
        goals = [_joints(g, f"goal[{k}]", n) for k, g in enumerate(raw)]
    else:
        goals = [_joints(raw, "goal", n, several=True)]
    return Problem(
        name=name,
        family=family,
        seed=seed,
        world=PrimitiveWorld.from_dict(item["obstacles"]),
        start=np.array(start),
        goals=np.array(goals),
        difficulty=diff,
    )


def _joints(value: Any, where: str, dof: int | None, several: bool = False) -> list[float]:
    """A joint vector (rad) of ``dof`` finite numbers (any length >= 1 when None)."""
    if not isinstance(value, list) or not value or (dof is not None and len(value) != dof):
        count = (
            "finite joint values (rad, one per joint)"
            if dof is None
            else f"{dof} finite joint values (rad)"
        )
        either = ", or a list of such vectors" if several else ""
        length = f" ({len(value)} values)" if isinstance(value, list) else ""
        raise PlanningError(f"{where}: must be {count}{either}, got {show(value)}{length}")
    return numbers(value, where)


def load_problems(path: str | Path, dof: int | None = None) -> list[Problem]:
    """Problems from a YAML or JSON file (``.json``: JSON; else YAML) in the layout and
    under the limits of the module docstring; ``dof``: the robot's joint count."""
    source = Path(path)
    data = _read(source)
    if not isinstance(data, dict):
        raise PlanningError(
            f"problem file {source}: must be a mapping with a 'problems' list, got {show(data)}"
        )
    unknown = [k for k in data if k != "problems"]
    if unknown:
        raise PlanningError(
            f"problem file {source}: unknown top-level key{'s' * (len(unknown) > 1)} "
            f"{', '.join(show(k) for k in unknown)}; valid: problems"
        )
    items = data.get("problems")
    if not isinstance(items, list) or not items:
        raise PlanningError(f"problem file {source} needs a non-empty 'problems' list")
    problems = [
        problem_from_dict(it, f"{source}: problem {i}", dof, default_name=f"problem-{i}")
        for i, it in enumerate(items)
    ]
    counts = Counter(p.name for p in problems)
    dup = sorted(n for n, c in counts.items() if c > 1)
    if dup:
        where = [i for i, p in enumerate(problems) if p.name == dup[0]]
        raise PlanningError(
            f"problem file {source}: duplicate problem names {dup} ({show(dup[0])} is "
            f"problems {where}); names must be unique"
        )
    return problems


def _read(source: Path) -> Any:
    """The parsed document of a problem file, within the module docstring's limits."""
    # size limit, binary and non-UTF-8 files: as every text file users give
    text = read_text(source, "problem file", PlanningError, max_bytes=MAX_FILE_BYTES)
    text = text.removeprefix("\ufeff")
    if source.suffix.lower() == ".json":
        try:
            return json.loads(text)
        except json.JSONDecodeError as err:
            raise PlanningError(
                f"problem file {source} does not parse as JSON: line {err.lineno}, column "
                f"{err.colno}: {err.msg}"
            ) from err
        except (ValueError, RecursionError) as err:  # too many digits, too deep
            raise PlanningError(
                f"problem file {source} does not parse as JSON: {one_line(err)}"
            ) from err
    return parse_yaml(text, f"problem file {source}", PlanningError)


def save_problems(path: str | Path, problems: list[Problem]) -> None:
    """Write problems as YAML (or JSON for a .json path), atomically; at least one, as
    :func:`load_problems` reads."""
    target = Path(path)
    if not problems:
        raise PlanningError(f"{target}: no problems to write; a problem file holds at least one")
    payload = {"problems": [p.to_dict() for p in problems]}
    text = (
        json.dumps(payload, indent=1)
        if target.suffix.lower() == ".json"
        else yaml.safe_dump(payload, sort_keys=False)
    )
    write_bytes_atomic(target, text.encode(), PlanningError)
