"""The robot configs shipped in ``planning/data``, by name (``ur5``, ``panda``, ...): light to
import (the command line shows them in its help), apart from the loader in
:mod:`planning.robot_config`.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["DEFAULT_CONFIG", "resolve_robot_config", "shipped_robots"]

SHIPPED_DIR = Path(__file__).parent / "data"
DEFAULT_CONFIG = SHIPPED_DIR / "ur5.yaml"


def shipped_robots() -> dict[str, Path]:
    """The shipped robot configs by name (a sphere model's YAML beside each is not one)."""
    return {
        p.stem: p for p in sorted(SHIPPED_DIR.glob("*.yaml")) if not p.stem.endswith("_spheres")
    }


def resolve_robot_config(path: str | Path | None) -> Path:
    """The config file of ``path``: the default UR5 for None; a shipped robot's for its bare
    name (``panda``) when no such file exists here; else the path as given (a missing file
    is reported where it is read, with the shipped names)."""
    if path is None:
        return DEFAULT_CONFIG
    given = Path(path)
    shipped = shipped_robots()
    if not given.exists() and str(path) in shipped:
        return shipped[str(path)]
    return given
