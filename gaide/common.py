"""Helpers shared by the CLI commands: loading the robot and its spheres, writing JSON."""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import ExecutionError
from planning.checker import CHECKERS, DEFAULT_CHECKER

if TYPE_CHECKING:
    from planning.robot_model import RobotModel
    from planning.sphere_model import SphereModel

T = TypeVar("T")

__all__ = [
    "add_checker_option",
    "print_table",
    "progress",
    "robot_and_spheres",
    "seed",
    "write_json",
]


def robot_and_spheres(config: str | None) -> tuple[RobotModel, SphereModel]:
    """The robot of ``config`` (default UR5) and its sphere model (Pinocchio loads here, not
    when the command line is parsed)."""
    from planning.robot_setup import robot_and_spheres as load

    return load(config)


def progress(iterable: Iterable[T] | None = None, **kwargs: Any) -> Iterable[T]:
    """A tqdm progress bar on a terminal; nothing where stderr is a file or a pipe (a CI
    log, ``2> log``), which would otherwise fill with carriage-return redraws."""
    from tqdm import tqdm

    bar: Iterable[T] = tqdm(iterable, disable=None, **kwargs)
    return bar


def seed(text: str) -> int:
    """An argparse type: a random seed, a whole number from 0 to 2^63 - 1."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(
            f"invalid seed {text!r}: give a whole number from 0 to 2^63 - 1"
        )
    return value


def add_checker_option(parser: argparse.ArgumentParser) -> None:
    """``--checker compiled|numpy``: the collision checker's backend."""
    parser.add_argument(
        "--checker",
        choices=CHECKERS,
        default=DEFAULT_CHECKER,
        help="collision checker: compiled (default) or the numpy reference",
    )


def _jsonable(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def write_json(path: str | Path, payload: dict[str, Any]) -> None:
    """Write JSON atomically (temporary file, then rename); ExecutionError naming the file
    when the system refuses (a full disk, no permission)."""
    text = json.dumps(_jsonable(payload), indent=2) + "\n"
    write_bytes_atomic(path, text.encode(), ExecutionError)


def print_table(rows: list[tuple[str, str]], title: str = "") -> None:
    if title:
        print(title)
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        print(f"  {key:<{width}}  {value}")
