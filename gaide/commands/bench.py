"""``gaide bench``: the issues' benchmark commands."""

from __future__ import annotations

import argparse
import time

from tqdm import tqdm

from gaide.common import print_table, robot_and_spheres, write_json
from planning.bench_collision import CollisionBenchCfg, run_collision_benchmark


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("bench", help="benchmarks")
    bsub = p.add_subparsers(dest="bench_cmd", required=True)
    col = bsub.add_parser("collision", help="speed and accuracy of the collision checker")
    col.add_argument("--robot", help="robot config YAML (default: UR5)")
    col.add_argument("--json", help="write the figures to this JSON file")
    col.add_argument("--quick", action="store_true", help="small sizes (a smoke test)")
    col.add_argument("--seed", type=int, default=0)
    col.set_defaults(func=cmd_collision)
    per = bsub.add_parser("perception", help="calibration and cloud accuracy on synthetic bags")
    per.add_argument("--robot", help="robot config YAML (default: UR5)")
    per.add_argument("--json", help="write the figures to this JSON file")
    per.add_argument("--quick", action="store_true", help="fewer frames and poses (a smoke test)")
    per.add_argument("--seed", type=int, default=0)
    per.set_defaults(func=cmd_perception)


def cmd_collision(args: argparse.Namespace) -> int:
    robot, spheres = robot_and_spheres(args.robot)
    cfg = (
        CollisionBenchCfg(batch=1000, edges=30, mesh_samples=300, repeats=2, seed=args.seed)
        if args.quick
        else CollisionBenchCfg(seed=args.seed)
    )
    t0 = time.perf_counter()
    res = run_collision_benchmark(robot, spheres, cfg, progress=tqdm)
    res["wall_s"] = time.perf_counter() - t0
    rows = [
        ("configs_per_s_cloud", f"{res['configs_per_s_cloud']:,.0f}  (target >= 100,000)"),
        ("configs_per_s_primitives", f"{res['configs_per_s_primitives']:,.0f}"),
        (
            "edges_per_s",
            f"{res['edges_per_s']:,.0f}  (1 rad, {res['edge_samples_mean']:.0f} samples/edge)",
        ),
        ("fk_max_err_m", f"{res['fk_max_err_m']:.2e}  (target <= 1e-9)"),
        ("mesh_missed", f"{res['mesh_missed']} of {res['mesh_samples']} x 2 worlds  (target 0)"),
        ("mesh_false_alarm_rate", f"{res['mesh_false_alarm_rate']:.3f}  (target <= 0.10)"),
        ("mesh_false_alarm_rate_cloud", f"{res['mesh_false_alarm_rate_cloud']:.3f}"),
        ("margin / voxel", f"{res['margin_m']} m / {res['voxel_m']} m, {res['n_spheres']} spheres"),
        ("wall time", f"{res['wall_s']:.1f} s"),
    ]
    print_table(rows, "collision benchmark")
    if args.json:
        write_json(args.json, res)
    return 0


def cmd_perception(args: argparse.Namespace) -> int:
    from gaide.bench_perception import run_perception_benchmark

    robot, spheres = robot_and_spheres(args.robot)
    t0 = time.perf_counter()
    res = run_perception_benchmark(
        robot,
        spheres,
        seed=args.seed,
        speed_frames=5 if args.quick else 30,
        handeye_poses=8 if args.quick else 12,
        progress=tqdm,
    )
    res["wall_s"] = time.perf_counter() - t0
    print_table(
        [
            ("fixed_err_mm", f"{res['fixed_err_mm']:.2f}  (target <= 2)"),
            ("fixed_err_deg", f"{res['fixed_err_deg']:.3f}  (target <= 0.2)"),
            ("handeye_err_mm", f"{res['handeye_err_mm']:.2f}  (target <= 5)"),
            ("handeye_err_deg", f"{res['handeye_err_deg']:.3f}  (target <= 0.5)"),
            ("cloud_median_err_mm", f"{res['cloud_median_err_mm']:.2f}  (target <= 10)"),
            ("frames_per_s", f"{res['frames_per_s']:.1f}  (target >= 30; 640x480, fused)"),
            ("single_frame_clouds_per_s", f"{res['single_frame_clouds_per_s']:.1f}"),
            ("wall time", f"{res['wall_s']:.1f} s"),
        ],
        "perception benchmark",
    )
    if args.json:
        write_json(args.json, res)
    return 0
