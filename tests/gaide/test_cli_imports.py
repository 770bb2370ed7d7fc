"""The command line answers ``--help`` and input mistakes without loading the heavy libraries.

Counted, not timed (timings belong to benchmarks): a subprocess builds every command's parser,
prints each one's help, and reports which of the heavy modules it imported; a missing input
file is said before any of them loads.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

HEAVY = (
    "open3d",
    "torch",
    "pinocchio",
    "trimesh",
    "matplotlib",
    "cv2",
    "pybullet",
    "ompl",
    "numba",
    "scipy",
    "rosbags",
    "ruckig",
    "ray",
)

# Runs each command line given (JSON lists of arguments) in one interpreter; prints the exit
# codes and the heavy modules loaded by then.
_PROBE = """
import contextlib, io, json, sys
from gaide.cli import main
codes = []
for argv in json.loads(sys.argv[1]):
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        codes.append(main(argv))
heavy = json.loads({heavy!r})
print(json.dumps({{"codes": codes, "loaded": [m for m in heavy if m in sys.modules]}}))
"""


def _probe(*argvs: list[str]) -> dict[str, object]:
    proc = subprocess.run(
        [sys.executable, "-c", _PROBE.format(heavy=json.dumps(HEAVY)), json.dumps(argvs)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    result: dict[str, object] = json.loads(proc.stdout.strip().splitlines()[-1])
    return result


def _commands() -> list[list[str]]:
    from gaide.cli import build_parser

    def walk(parser: object, prefix: list[str]) -> list[list[str]]:
        found = [prefix]
        for action in getattr(parser, "_actions", []):
            choices = getattr(action, "choices", None)
            if isinstance(choices, dict):  # a sub-command's parsers
                for name, child in choices.items():
                    found += walk(child, [*prefix, name])
        return found

    return walk(build_parser(), [])


def test_every_help_loads_no_heavy_module() -> None:
    commands = _commands()
    assert ["time"] in commands and ["bench", "planning"] in commands
    result = _probe(*([*argv, "--help"] for argv in commands))
    assert result["codes"] == [0] * len(commands)
    assert result["loaded"] == [], f"--help of some command imported {result['loaded']}"


@pytest.mark.parametrize(
    ("argv", "code"),
    [
        (["time", "missing.json", "-o", "out.csv"], 8),
        (["simulate", "missing.csv"], 9),
        (["compare", "missing.csv", "missing_log.csv"], 9),
        (["run", "missing.bag", "--goal", "home", "-o", "out"], 3),
    ],
)
def test_a_missing_input_is_said_before_the_heavy_modules_load(
    tmp_path: Path, argv: list[str], code: int
) -> None:
    paths = [
        str(tmp_path / a) if a.startswith("missing") or a.startswith("out") else a for a in argv
    ]
    result = _probe(paths)
    assert result["codes"] == [code]
    assert result["loaded"] == []
