"""``gaide robot``: inspect a robot, generate its sphere model, draw it."""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

from gaide.common import print_table, robot_and_spheres
from gaide_core.errors import ConfigError


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("robot", help="inspect a robot, generate its spheres, draw it")
    rsub = p.add_subparsers(dest="robot_cmd", required=True)
    info = rsub.add_parser("info", help="joints, limits, links and spheres")
    info.add_argument("--robot", help="robot config YAML (default: UR5)")
    info.set_defaults(func=cmd_info)
    sph = rsub.add_parser("spherize", help="generate a sphere model from the collision meshes")
    sph.add_argument("--robot", help="robot config YAML (default: UR5)")
    sph.add_argument("--max-spheres", type=int, default=60)
    sph.add_argument("-o", "--output", required=True, help="sphere YAML (cuRobo layout)")
    sph.set_defaults(func=cmd_spherize)
    show = rsub.add_parser("show", help="draw the robot's spheres at a configuration")
    show.add_argument("--robot", help="robot config YAML (default: UR5)")
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
