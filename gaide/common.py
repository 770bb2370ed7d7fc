"""Helpers shared by the CLI commands: loading the robot and its spheres, writing JSON."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import ExecutionError
from planning.checker import CHECKERS, DEFAULT_CHECKER
from planning.robot_names import shipped_robots

if TYPE_CHECKING:
    from planning.robot_model import RobotModel
    from planning.sphere_model import SphereModel

T = TypeVar("T")

__all__ = [
    "JobProgress",
    "add_checker_option",
    "add_robot_option",
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


class JobProgress:
    """Progress of a long job (training, data generation) on stderr. On a terminal, a tqdm
    bar. Elsewhere (``nohup ... > log``, a pipe, a CI log), where a bar's carriage-return
    redraws would pile up on one line, a plain line each time another ``1/lines`` of the job
    is done (so one at its end): ``train gaide: 500/5000 steps (10%), val=0.0415, 121 s``."""

    def __init__(
        self, desc: str, unit: str, total: int | None = None, initial: int = 0, lines: int = 20
    ) -> None:
        self.desc, self.unit, self.total, self.lines = desc, unit, total, lines
        self.done = initial
        self._t0 = time.perf_counter()
        self._printed = self._bucket(initial)
        self._bar: Any = None
        if sys.stderr.isatty():
            from tqdm import tqdm

            self._bar = tqdm(total=total, initial=initial, desc=desc, unit=unit)

    def _bucket(self, done: int) -> int:
        return done * self.lines // self.total if self.total else done

    def update(self, done: int, total: int | None = None, **postfix: str) -> None:
        """``done`` units of ``total`` (if it is known only now) are finished."""
        if total is not None:
            self.total = total
        if self._bar is not None:
            self._bar.total = self.total
            self._bar.update(done - self.done)
            if postfix:
                self._bar.set_postfix(postfix)
        elif self._bucket(done) > self._printed:  # the last unit always starts a bucket
            self._printed = self._bucket(done)
            share = f" ({100 * done // self.total}%)" if self.total else ""
            fields = "".join(f", {k}={v}" for k, v in postfix.items())
            elapsed = time.perf_counter() - self._t0
            of = f"/{self.total}" if self.total else ""
            print(
                f"{self.desc}: {done}{of} {self.unit}s{share}{fields}, {elapsed:.0f} s",
                file=sys.stderr,
                flush=True,
            )
        self.done = done

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


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


def add_robot_option(parser: argparse.ArgumentParser, what: str = "") -> None:
    """``--robot``: a robot config YAML, or a shipped robot's name (``panda``);
    ``what`` says what the robot is for, where that needs saying."""
    names = ", ".join(shipped_robots())
    parser.add_argument(
        "--robot",
        help=f"robot config YAML{what}, or a shipped robot: {names} (default: ur5)",
    )


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
