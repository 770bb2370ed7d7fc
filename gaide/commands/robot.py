"""``gaide robot``: inspect a robot, generate its sphere model, draw it."""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np

from gaide.common import add_robot_option, print_table, robot_and_spheres
from gaide_core.errors import ConfigError


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("robot", help="inspect a robot, generate its spheres, draw it")
    rsub = p.add_subparsers(dest="robot_cmd", required=True)
    info = rsub.add_parser("info", help="joints, limits, links and spheres")
    add_robot_option(info)
    info.set_defaults(func=cmd_info)
    sph = rsub.add_parser("spherize", help="generate a sphere model from the collision meshes")
    add_robot_option(sph)
    sph.add_argument("--max-spheres", type=int, default=60)
    sph.add_argument("-o", "--output", required=True, help="sphere YAML (cuRobo layout)")
    sph.set_defaults(func=cmd_spherize)
    setup = rsub.add_parser(
        "setup",
        help="a complete robot config from a URDF: chain, limits, spheres, self-collision matrix",
    )
    setup.add_argument("urdf", help="the robot's URDF")
    setup.add_argument("--srdf", help="SRDF: its disabled pairs and named states are used too")
    setup.add_argument("--base-link", help="first link of the planning chain (default: the root)")
    setup.add_argument(
        "--tip-link", help="last link of the planning chain (default: where the arm ends or splits)"
    )
    setup.add_argument(
        "--lock",
        action="append",
        default=[],
        metavar="JOINT=VALUE",
        help="hold a joint at a value (rad or m); joints off the chain are held at 0 (clamped)",
    )
    setup.add_argument(
        "--named",
        action="append",
        default=[],
        metavar="NAME=Q1,Q2,...",
        help="a named configuration (rad or m); --named home=... sets the posture IK prefers",
    )
    setup.add_argument(
        "--package-dir",
        action="append",
        default=[],
        help="a folder holding the packages the URDF's package:// URIs name",
    )
    setup.add_argument(
        "--samples", type=int, default=10_000, help="random configurations for the matrix"
    )
    setup.add_argument("-o", "--output", required=True, help="robot config YAML to write")
    setup.set_defaults(func=cmd_setup)
    show = rsub.add_parser("show", help="draw the robot's spheres at a configuration")
    add_robot_option(show)
    show.add_argument("--q", help="joint values (rad), comma separated, or a named configuration")
    show.add_argument("-o", "--output", required=True, help="PNG file")
    show.set_defaults(func=cmd_show)


def cmd_info(args: argparse.Namespace) -> int:
    robot, spheres = robot_and_spheres(args.robot)
    rows = [("urdf", str(robot.config.urdf)), ("end effector", robot.config.end_effector)]
    for i, name in enumerate(robot.joint_names):
        rows.append(
            (
                name,
                f"[{robot.lower[i]:+.3f}, {robot.upper[i]:+.3f}] rad, "
                f"v {robot.velocity_limits[i]:.2f} a {robot.acceleration_limits[i]:.1f} "
                f"j {robot.jerk_limits[i]:.0f}",
            )
        )
    if robot.config.locked_joints:
        rows.append(
            (
                "locked",
                ", ".join(f"{k} = {v:g}" for k, v in robot.config.locked_joints.items()),
            )
        )
    counts = Counter(spheres.links)
    rows.append(("spheres", f"{len(spheres)}: " + ", ".join(f"{k} {v}" for k, v in counts.items())))
    rows.append(("margin", f"{robot.config.collision_margin} m"))
    print_table(rows, "robot")
    return 0


def cmd_spherize(args: argparse.Namespace) -> int:
    from planning.robot_model import load_robot
    from planning.spherize import SpherizeCfg, generate_spheres

    robot = load_robot(args.robot)
    spheres = generate_spheres(robot, SpherizeCfg(max_spheres=args.max_spheres))
    spheres.save(args.output)
    print(f"{len(spheres)} spheres over {len(spheres.link_names)} links -> {args.output}")
    return 0


def cmd_setup(args: argparse.Namespace) -> int:
    from planning.setup_assistant import SetupCfg, setup_robot

    locks = {}
    for item in args.lock:
        joint, sep, value = item.partition("=")
        try:
            locks[joint.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not joint.strip():
            raise ConfigError(f"--lock {item!r}: give JOINT=VALUE (rad or m)")
    named = {}
    for item in args.named:
        key, sep, values = item.partition("=")
        try:
            named[key.strip()] = tuple(float(v) for v in values.split(","))
        except ValueError:
            sep = ""
        if not sep or not key.strip():
            raise ConfigError(f"--named {item!r}: give NAME=Q1,Q2,... (rad or m)")
    if args.samples < 100:
        raise ConfigError(f"--samples must be >= 100, got {args.samples}")
    result = setup_robot(
        Path(args.urdf),
        Path(args.output),
        SetupCfg(
            srdf=Path(args.srdf) if args.srdf else None,
            base_link=args.base_link,
            tip_link=args.tip_link,
            locks=locks,
            named=named,
            package_dirs=tuple(Path(p) for p in args.package_dir),
            samples=args.samples,
        ),
    )
    robot = result.robot
    reasons = Counter(result.disabled.values())
    rows = [
        ("planning joints", f"{robot.dof}: {', '.join(robot.joint_names)}"),
        ("locked", ", ".join(f"{k}={v:g}" for k, v in result.locked.items()) or "(none)"),
        ("end effector", robot.config.end_effector),
        ("spheres", f"{len(result.spheres)} over {len(result.spheres.link_names)} links"),
        (
            "pairs not checked",
            ", ".join(f"{n} {why}" for why, n in sorted(reasons.items())) or "(none)",
        ),
        ("named", ", ".join(robot.config.named_configurations)),
        ("config", str(result.config_path)),
        ("sphere file", str(result.spheres_path)),
        *(("note", n) for n in result.notes),
    ]
    print_table(rows, "robot setup")
    return 0


def parse_configuration(text: str | None, robot) -> np.ndarray:  # type: ignore[no-untyped-def]
    """A joint vector from 'a,b,c,...' or a named configuration of the robot config."""
    if text is None:
        return (
            robot.named_configuration("home")
            if "home" in robot.config.named_configurations
            else (robot.lower + robot.upper) / 2
        )
    return robot.check_configuration(robot.configuration_from_text(text, "--q"), what="--q")


def cmd_show(args: argparse.Namespace) -> int:
    from planning.checker import make_checker
    from planning.plot import render_scene

    if not str(args.output).lower().endswith(".png"):
        raise ConfigError(f"-o {args.output}: the picture is a PNG; name it *.png")
    robot, spheres = robot_and_spheres(args.robot)
    q = parse_configuration(args.q, robot)
    checker = make_checker(robot, spheres)
    render_scene(args.output, checker, [q], title=f"{len(spheres)} spheres")
    print(f"wrote {args.output}")
    return 0
