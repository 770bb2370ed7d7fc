"""Scenes named on the command line, for timing, simulation and comparison.

A scene spec is one of:

- ``none`` (or ``empty``): no obstacles (joint limits and self-collision only);
- ``FAMILY:SEED``, ``family:FAMILY:SEED`` or ``FAMILY seed SEED`` (what ``gaide plan`` writes
  into a path file): the task-family problem of that seed, as analytic primitives;
- a ``.ply`` point cloud in the base frame (``gaide perceive``'s output);
- a problem file (``.yaml``/``.yml``/``.json``, :mod:`planning.problem`): its only problem,
  or ``FILE#NAME`` for the problem named NAME.

A path file (``plan.json``) names its scene file relative to its own folder
(:func:`relative_to`), so an output folder can move; :func:`next_to` finds it again.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from gaide_core.errors import ConfigError
from gaide_core.types import Array
from planning.family_names import FAMILIES

if TYPE_CHECKING:  # the command line imports this module for HELP: keep it light
    from planning.primitives import PrimitiveWorld
    from planning.robot_model import RobotModel
    from planning.sphere_model import SphereModel
    from planning.world import World

_FAMILY = re.compile(r"^(?:family:)?(?P<family>[a-z_]+)(?::|\s+seed\s+)(?P<seed>\d+)$")
HELP = (
    "'none', FAMILY:SEED (e.g. tabletop:2000000, as `gaide plan` names it: 'tabletop seed "
    "2000000'), a .ply cloud, or a problem file (.yaml/.json, FILE#NAME for one of several)"
)


@dataclass(frozen=True)
class Scene:
    label: str  # what the user named
    world: World | None  # for the collision checker; None: no obstacles
    primitives: PrimitiveWorld | None = None  # for the simulator
    cloud: Array | None = None  # (N, 3) m, base frame, for the simulator


_FILE_SUFFIXES = (".ply", ".yaml", ".yml", ".json")


def _file_part(spec: str) -> tuple[str, str] | None:
    """(file, '#NAME' or '') of a spec that names a file, else None."""
    file_part, hash_, name = spec.strip().partition("#")
    if Path(file_part).suffix.lower() not in _FILE_SUFFIXES:
        return None
    return file_part, hash_ + name


def relative_to(spec: str, folder: str | os.PathLike[str]) -> str:
    """``spec`` as a path file in ``folder`` stores it: a scene file's path relative to that
    folder (other specs unchanged)."""
    parts = _file_part(spec)
    if parts is None:
        return spec
    return os.path.relpath(Path(parts[0]).resolve(), Path(folder).resolve()) + parts[1]


def next_to(spec: str, folder: str | os.PathLike[str]) -> str:
    """A path file's scene ``spec`` for loading: a relative scene file found in ``folder``
    (the path file's own) is taken from there; otherwise the spec as written (relative to
    the working directory, as older path files name it)."""
    parts = _file_part(spec)
    if parts is None or Path(parts[0]).is_absolute():
        return spec
    beside = Path(folder) / parts[0]
    return str(beside) + parts[1] if beside.is_file() else spec


def load_scene(spec: str, robot: RobotModel, spheres: SphereModel) -> Scene:
    """The scene ``spec`` names (ConfigError listing the valid forms otherwise)."""
    text = spec.strip()
    if text.lower() in ("none", "empty"):
        return Scene(label="none", world=None)
    match = _FAMILY.match(text)
    if match and match["family"] in FAMILIES:
        from planning.families import generate_problem

        problem = generate_problem(match["family"], int(match["seed"]), robot, spheres)
        return Scene(label=text, world=problem.world, primitives=problem.world)
    file_part, _, name = text.partition("#")
    path = Path(file_part)
    if path.suffix == ".ply":
        from perception.cloud import load_ply
        from planning.distance_field import CloudWorld

        points = load_ply(str(path))
        return Scene(label=text, world=CloudWorld(points), cloud=points)
    if path.suffix in (".yaml", ".yml", ".json"):
        from planning.problem import load_problems

        problems = load_problems(path, dof=robot.dof)
        if name:
            chosen = [p for p in problems if p.name == name]
            if not chosen:
                raise ConfigError(
                    f"scene {spec}: no problem named '{name}' in {path}; names: "
                    f"{[p.name for p in problems]}"
                )
        elif len(problems) > 1:
            raise ConfigError(
                f"scene {spec}: {path} holds {len(problems)} problems; name one as "
                f"{path}#NAME ({[p.name for p in problems][:5]}...)"
            )
        else:
            chosen = problems
        return Scene(label=text, world=chosen[0].world, primitives=chosen[0].world)
    if match:
        raise ConfigError(f"scene {spec}: unknown family '{match['family']}'; valid: {FAMILIES}")
    raise ConfigError(f"scene '{spec}' is not understood; give {HELP}")
