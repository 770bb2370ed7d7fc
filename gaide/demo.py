"""``gaide demo``: ``gaide run`` on the embedded default, the sample bag in ``bags/``.

Calibrates the camera to the robot base from the ChArUco board in the bag, builds the scene
cloud in the base frame without the robot's own points, plans with GAIDE (hybrid) from the
recorded joint state to a goal behind the board, times the path with Ruckig, exports it,
simulates it in PyBullet and writes ``report.html`` (settings: ``gaide/data/demo.yaml`` on
top of ``gaide/data/run.yaml``; every ``gaide run`` flag works here too). With ``--robot``
another arm takes the recorded UR5's place: the UR5's points are removed with its recorded
joints (``perception.bag_robot``) and the arm starts at its ``home``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from gaide.commands.run import add_setting_flags, cfg_from_args, run_with_bars
from gaide.pipeline.config_io import DATA
from planning.robot_names import DEFAULT_CONFIG, resolve_robot_config

BAGS = Path(__file__).resolve().parents[1] / "bags"
SAMPLE_BAG = BAGS / "sample_workcell.bag"
SAMPLE_TARGET = BAGS / "sample_workcell.target_pose.yaml"
DEMO_CONFIG = DATA / "demo.yaml"
#: --quick: what the tests run (less to draw and to simulate; the same stages).
QUICK = (
    ("timing.rate_hz", 100.0),
    ("simulate.settle_s", 0.0),
    ("report.poses", 3),
)


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("demo", help="gaide run on the shipped sample bag (no arguments needed)")
    p.add_argument("-o", "--out", help="output folder (default out/demo)")
    p.add_argument(
        "--quick", action="store_true", help="a lighter run for tests (100 Hz, fewer poses)"
    )
    p.add_argument("--progress", action="store_true", help="progress bars even without a TTY")
    add_setting_flags(p)
    p.set_defaults(func=cmd_demo, bag=None)


def cmd_demo(args: argparse.Namespace) -> int:
    quick = [f"{key}={value}" for key, value in QUICK] if args.quick else []
    args.set = quick + list(args.set)  # the user's --set wins
    args.bag = args.bag or str(SAMPLE_BAG)
    if args.target_pose is None and args.calib is None and args.T_base_cam is None:
        args.target_pose = str(SAMPLE_TARGET)
    robot = resolve_robot_config(args.robot)
    if args.robot is not None and robot.resolve() != DEFAULT_CONFIG.resolve():
        # The bag records a UR5: another arm stands in its place, the UR5's points are
        # removed with its recorded joints, and the new arm starts at its home.
        args.set = [f"perception.bag_robot={DEFAULT_CONFIG}", *args.set]
        args.start = args.start or "home"
    cfg = cfg_from_args(args, [str(DEMO_CONFIG)])
    return run_with_bars(cfg, "gaide demo", args.progress)
