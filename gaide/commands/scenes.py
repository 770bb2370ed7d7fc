"""``gaide scenes``: the paper's task families: draw one, or export problem files."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from gaide.common import add_robot_option, print_table, robot_and_spheres, seed
from planning.family_names import FAMILIES, parse_families, split_seed


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("scenes", help="the task families: draw a problem, export problem files")
    ssub = p.add_subparsers(dest="scenes_cmd", required=True)
    show = ssub.add_parser("show", help="draw a problem's scene with its start and goal poses")
    show.add_argument("family", choices=FAMILIES)
    show.add_argument("--seed", type=seed, help="problem seed (default: the first test seed)")
    show.add_argument(
        "--view",
        choices=["surface", "camera"],
        default="surface",
        help="scene cloud: obstacle surfaces, or a virtual camera's partial view",
    )
    add_robot_option(show)
    show.add_argument("-o", "--output", required=True, help="PNG file")
    show.set_defaults(func=cmd_show)
    exp = ssub.add_parser("export", help="write generated problems to a YAML/JSON problem file")
    exp.add_argument("--families", default="all", help="comma-separated names or 'all'")
    exp.add_argument("--split", choices=["train", "val", "test"], default="test")
    exp.add_argument("--problems", type=int, default=10, help="problems per family")
    add_robot_option(exp)
    exp.add_argument("-o", "--output", required=True, help="problem file (.yaml or .json)")
    exp.set_defaults(func=cmd_export)
    imp = ssub.add_parser(
        "import-moveit",
        help="MoveIt scene/request YAML pairs (MotionBenchMaker's sets) to a problem file",
    )
    imp.add_argument(
        "folders", nargs="+", help="folders of sceneNNNN.yaml / requestNNNN.yaml pairs"
    )
    add_robot_option(imp, " whose world frame the scenes use")
    imp.add_argument("-o", "--output", required=True, help="problem file (.yaml or .json)")
    imp.set_defaults(func=cmd_import_moveit)


def cmd_show(args: argparse.Namespace) -> int:
    from gaide.pictures import render_meshes_png
    from planning.families import generate_problem
    from planning.primitives import primitive_mesh
    from planning.scene_views import camera_view, posed_link_meshes, surface_cloud

    robot, spheres = robot_and_spheres(args.robot)
    seed = args.seed if args.seed is not None else split_seed("test", 0)
    problem = generate_problem(args.family, seed, robot, spheres)
    rng = np.random.default_rng(seed)
    cloud = (
        surface_cloud(problem.world, 20_000, rng)
        if args.view == "surface"
        else camera_view(problem.world, rng)
    )
    meshes = [(primitive_mesh(p), (0.72, 0.62, 0.5)) for p in problem.world.primitives]
    meshes += [(m, (0.25, 0.45, 0.85)) for m in posed_link_meshes(robot, problem.start)]
    meshes += [(m, (0.95, 0.55, 0.15)) for m in posed_link_meshes(robot, problem.goal)]
    render_meshes_png(
        Path(args.output),
        meshes,
        points=cloud if args.view == "camera" else None,
        eye=(-0.7, -1.2, 1.45),
        lookat=(0.45, 0.05, 0.2),
    )
    print_table(
        [
            ("problem", problem.name),
            ("difficulty", problem.difficulty),
            ("obstacles", str(len(problem.world))),
            ("start (blue)", np.round(problem.start, 3).tolist()),  # type: ignore[list-item]
            ("goal (orange)", np.round(problem.goal, 3).tolist()),  # type: ignore[list-item]
            ("picture", args.output),
        ],
        "scene",
    )
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from planning.families import family_problems
    from planning.problem import save_problems

    robot, spheres = robot_and_spheres(args.robot)
    problems = [
        p
        for fam in parse_families(args.families)
        for p in family_problems(fam, robot, spheres, split=args.split, count=args.problems)
    ]
    save_problems(args.output, problems)
    print(f"{len(problems)} problems -> {args.output}")
    return 0


def cmd_import_moveit(args: argparse.Namespace) -> int:
    from planning.checker import make_checker
    from planning.moveit_import import import_moveit_sets
    from planning.problem import save_problems

    robot, spheres = robot_and_spheres(args.robot)
    problems = import_moveit_sets(args.folders, robot.joint_names)
    # What the harness will count apart: an end outside the limits or in collision.
    invalid = 0
    for p in problems:
        checker = make_checker(robot, spheres, p.world)
        invalid += not (
            checker.config_valid(p.start[None])[0] and checker.config_valid(p.goals).any()
        )
    save_problems(args.output, problems)
    print(
        f"{len(problems)} problems from {len(args.folders)} folder(s) -> {args.output}; "
        f"{invalid} with the start or every goal invalid for this robot"
    )
    return 0
