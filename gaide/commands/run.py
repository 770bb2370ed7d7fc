"""``gaide run`` (a bag to an exported, simulated trajectory, with a report) and
``gaide config show`` (the effective settings). ``gaide demo`` shares the flags."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from gaide.common import add_robot_option, print_table, seed
from gaide.pipeline.config import RunCfg
from gaide.pipeline.config_io import dump_cfg, load_cfg, parse_assignment
from gaide.pipeline.runner import StageRecord, StageRunner

ENDPOINT_HELP = (
    "'recorded' (the bag's joint state), a named configuration (home), a,b,c,d,e,f (rad), "
    "pose:x,y,z,qx,qy,qz,qw or xyz:x,y,z (m, base frame; collision-free IK)"
)


def add_setting_flags(p: argparse.ArgumentParser) -> None:
    """The flags that override settings (precedence: defaults < --config < flags)."""
    p.add_argument(
        "--config", action="append", default=[], help="settings YAML (see gaide/data/run.yaml)"
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="any setting, e.g. --set planning.budget_s=5 --set perception.voxel=0.02",
    )
    add_robot_option(p)
    cam = p.add_mutually_exclusive_group()
    cam.add_argument("--calib", help="calibration YAML from `gaide calibrate` (skip calibrating)")
    cam.add_argument(
        "--T-base-cam",
        dest="T_base_cam",
        help="color camera pose in the base frame, x,y,z,qx,qy,qz,qw (m): no calibration",
    )
    p.add_argument("--target-pose", help="fixed target and its pose YAML (default: beside BAG)")
    p.add_argument("--start", help=f"start: {ENDPOINT_HELP}")
    p.add_argument("--goal", help=f"goal: {ENDPOINT_HELP}")
    p.add_argument(
        "--planner",
        help="planner name (default auto: gaide-hybrid when its weights fit the robot, else "
        "rrtc; rrtconnect, ...)",
    )
    p.add_argument("--checkpoint", help="weights for a neural planner")
    p.add_argument("--budget", type=float, help="planning seconds per attempt")
    p.add_argument("--attempts", type=int, help="planning attempts")
    p.add_argument("--seed", type=seed, help="random seed")
    p.add_argument(
        "--checker", choices=["compiled", "numpy"], help="collision checker (default compiled)"
    )
    p.add_argument("--timing-mode", choices=["blended", "exact"])
    p.add_argument("--rate", type=float, help="controller rate (Hz)")
    p.add_argument("--no-sim", action="store_true", help="skip the simulation")
    p.add_argument("--no-report", action="store_true", help="skip report.html")


#: flag attribute -> setting key
FLAG_KEYS = {
    "bag": "bag",
    "out": "out",
    "robot": "robot",
    "calib": "calibration.calib",
    "T_base_cam": "calibration.T_base_cam",
    "target_pose": "calibration.target_pose",
    "start": "planning.start",
    "goal": "planning.goal",
    "planner": "planning.planner",
    "checkpoint": "planning.checkpoint",
    "budget": "planning.budget_s",
    "attempts": "planning.attempts",
    "seed": "planning.seed",
    "checker": "planning.checker",
    "timing_mode": "timing.mode",
    "rate": "timing.rate_hz",
}


def overrides(args: argparse.Namespace) -> list[tuple[str, Any]]:
    """--set assignments, then the dedicated flags (which win)."""
    out = [parse_assignment(text) for text in args.set]
    for attr, key in FLAG_KEYS.items():
        value = getattr(args, attr, None)
        if value is not None:
            out.append((key, value))
    if args.no_sim:
        out.append(("simulate.enabled", False))
    if args.no_report:
        out.append(("report.enabled", False))
    return out


def cfg_from_args(args: argparse.Namespace, files: list[str] | None = None) -> RunCfg:
    return load_cfg([*(files or []), *args.config], overrides(args))


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    run = sub.add_parser(
        "run",
        help="bag -> calibration -> cloud -> GAIDE path -> Ruckig trajectory -> export, "
        "simulation, report.html",
        epilog="Write a value that begins with a minus sign with '=': "
        "--T-base-cam=-0.7,-0.3,0.7,0.65,-0.5,0.35,-0.45, --start=-1.2,-1.5,1.5,-1.5,-1.5,0. "
        "Every setting: gaide/data/run.yaml; the effective ones: gaide config show.",
    )
    run.add_argument("bag", nargs="?", help="RealSense bag (ROS1 .bag, ROS2 folder or .mcap)")
    run.add_argument("-o", "--out", help="output folder (default out/run)")
    add_setting_flags(run)
    run.add_argument("--progress", action="store_true", help="progress bars even without a TTY")
    run.set_defaults(func=cmd_run)

    cfg = sub.add_parser("config", help="settings of `gaide run`")
    csub = cfg.add_subparsers(dest="config_cmd", required=True)
    show = csub.add_parser("show", help="print the effective settings as YAML")
    show.add_argument("bag", nargs="?", help="the bag (as `gaide run` takes it)")
    show.add_argument("-o", "--out", help="output folder")
    add_setting_flags(show)
    show.set_defaults(func=cmd_config_show)


def cmd_config_show(args: argparse.Namespace) -> int:
    print(dump_cfg(cfg_from_args(args)), end="")
    return 0


class StageBars:
    """A progress bar per stage on stderr (tqdm; off without a TTY unless forced)."""

    def __init__(self, force: bool = False) -> None:
        self.disable = None if not force else False
        self._bar: Any = None

    def _new(self, name: str, index: int, total: int) -> Any:
        from tqdm import tqdm

        return tqdm(
            total=1,
            desc=f"[{index + 1}/{total}] {name:<11}",
            bar_format="{desc} |{bar:20}| {elapsed} {postfix}",
            disable=self.disable,
            file=sys.stderr,
        )

    def started(self, name: str, index: int, total: int) -> None:
        self._bar = self._new(name, index, total)

    def finished(self, record: StageRecord) -> None:
        bar = self._bar
        if bar is None:
            return
        bar.set_postfix_str(record.status.value, refresh=False)
        bar.update(1)
        bar.close()
        self._bar = None


def print_summary(runner: StageRunner, title: str) -> None:
    from gaide.pipeline.summary import output_rows, summary_rows

    print_table(summary_rows(runner), title)
    print_table(output_rows(runner), "outputs")


def run_with_bars(cfg: RunCfg, title: str, force_bars: bool) -> int:
    from gaide.pipeline.run import run_pipeline

    runner = run_pipeline(cfg, hooks=StageBars(force_bars), title=title)
    print_summary(runner, title)
    report = Path(cfg.out) / "report.html"
    if report.is_file():
        print(f"report: {report}")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    cfg = cfg_from_args(args)
    return run_with_bars(cfg, f"gaide run {cfg.bag}", args.progress)
