"""``gaide bench``: the issues' benchmark commands."""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from gaide.commands.execution import add_bench_parser
from gaide.common import (
    add_checker_option,
    add_robot_option,
    print_table,
    progress,
    robot_and_spheres,
    seed,
    write_json,
)
from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import ConfigError, ExecutionError


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("bench", help="benchmarks")
    bsub = p.add_subparsers(dest="bench_cmd", required=True)
    col = bsub.add_parser("collision", help="speed and accuracy of the collision checker")
    add_robot_option(col)
    col.add_argument("--json", help="write the figures to this JSON file")
    col.add_argument("--quick", action="store_true", help="small sizes (a smoke test)")
    col.add_argument("--seed", type=seed, default=0)
    add_checker_option(col)
    col.set_defaults(func=cmd_collision)
    per = bsub.add_parser("perception", help="calibration and cloud accuracy on synthetic bags")
    add_robot_option(per)
    per.add_argument("--json", help="write the figures to this JSON file")
    per.add_argument("--quick", action="store_true", help="fewer frames and poses (a smoke test)")
    per.add_argument("--seed", type=seed, default=0)
    per.set_defaults(func=cmd_perception)
    pla = bsub.add_parser("planning", help="planners on the task families (the paper's Table I)")
    pla.add_argument("--families", default="all", help="comma-separated families or 'all'")
    pla.add_argument("--planners", default="rrtconnect", help="comma-separated planner names")
    pla.add_argument("--problems", type=int, default=10, help="problems per family")
    pla.add_argument(
        "--budget",
        default="5",
        help="seconds per run, or 'auto' (the reference planner's mean time per family)",
    )
    pla.add_argument("--reference", default="gaide", help="the planner whose mean time 'auto' uses")
    pla.add_argument(
        "--split",
        choices=["test", "test-legacy", "train", "val"],
        default="test",
        help="test: balanced over the four categories; test-legacy: the families' own targets",
    )
    pla.add_argument("--first", type=int, default=0, help="index of the first problem in the split")
    pla.add_argument("--problem-file", help="YAML/JSON problem file instead of the families")
    pla.add_argument("--workers", type=int, help="processes (default: one per core)")
    pla.add_argument(
        "--mesh-check", action="store_true", help="also check paths against PyBullet's meshes"
    )
    add_robot_option(pla)
    add_checker_option(pla)
    pla.add_argument(
        "--weights",
        help="folder of checkpoints MODEL.pt (from `gaide train`) the neural planners load "
        "instead of the shipped weights",
    )
    pla.add_argument(
        "--json", help="write results to this JSON file (a .md table and a .png plot beside it)"
    )
    pla.set_defaults(func=cmd_planning)
    ora = bsub.add_parser(
        "oracle", help="the training oracle: its consistency, and its cost against long runs"
    )
    ora.add_argument("--families", default="all", help="comma-separated families or 'all'")
    ora.add_argument("--problems", type=int, default=2, help="problems per family")
    ora.add_argument(
        "--budget", type=float, default=5.0, help="seconds for each reference planner run"
    )
    for flag, kind, what in (
        ("--runs", int, "compiled RRT-Connect runs per label"),
        ("--refine", int, "shortest runs that get the shortcuts"),
        ("--shortcuts", int, "shortcut attempts per refined run"),
        ("--tie", float, "label the refined run within this share of the shortest that leaves "
         "the start most nearly toward the goal"),
        ("--clearance", float, "extra clearance (m, up to 0.05) each sphere of the label keeps, at most half its own at the ends beyond the margin"),
        ("--band", int, "L-BFGS iterations of the elastic band that pulls each label taut (0: none)"),
    ):  # fmt: skip
        ora.add_argument(flag, type=kind, help=f"{what} (default: the data's oracle)")
    ora.add_argument(
        "--clearance-rule",
        choices=["sphere", "tightest"],
        help="limit each sphere's extra clearance by its own at the ends, or all by the "
        "tightest sphere's (default: the data's oracle)",
    )
    ora.add_argument(
        "--band-pull",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="after the band, keep only the band's points that straight certified edges "
        "cannot skip (default: the data's oracle, which pulls)",
    )
    add_robot_option(ora)
    ora.add_argument("--json", help="write the figures to this JSON file")
    ora.set_defaults(func=cmd_oracle)
    tab = bsub.add_parser("table", help="a Markdown table of chosen planners from a bench JSON")
    tab.add_argument("json", help="JSON written by `gaide bench planning --json`")
    tab.add_argument("--planners", help="comma-separated rows, in order (default: all)")
    tab.set_defaults(func=cmd_table)
    sam = bsub.add_parser("sampler", help="forward-pass time of the neural samplers")
    sam.add_argument(
        "--models", default="gaide,gaide-v,gaide-h,mpnet,simpnet", help="comma-separated kinds"
    )
    sam.add_argument("--checkpoint", help="time this checkpoint instead of the shipped weights")
    sam.add_argument("--batches", default="1,8,32", help="rollouts per forward pass")
    sam.add_argument("--repeats", type=int, default=50)
    add_robot_option(sam)
    sam.add_argument("--json", help="write the figures to this JSON file")
    sam.set_defaults(func=cmd_sampler)
    add_bench_parser(bsub)  # gaide bench timing (issue 6)


def cmd_collision(args: argparse.Namespace) -> int:
    from planning.bench_collision import CollisionBenchCfg, run_collision_benchmark

    robot, spheres = robot_and_spheres(args.robot)
    cfg = (
        CollisionBenchCfg(
            batch=1000, edges=30, mesh_samples=300, repeats=2, single_calls=2000, seed=args.seed
        )
        if args.quick
        else CollisionBenchCfg(seed=args.seed)
    )
    cfg = replace(cfg, checker=args.checker)
    t0 = time.perf_counter()
    res = run_collision_benchmark(robot, spheres, cfg, progress=progress)
    res["wall_s"] = time.perf_counter() - t0
    rows = [
        ("checker", res["checker"]),
        ("configs_per_s_cloud", f"{res['configs_per_s_cloud']:,.0f}  (target >= 3,000,000)"),
        (
            "configs_per_s_primitives",
            f"{res['configs_per_s_primitives']:,.0f}  (target >= 1,000,000)",
        ),
        ("single_call_us", f"{res['single_call_us']:.2f}  (target <= 10)"),
        (
            "edges_per_s",
            f"{res['edges_per_s']:,.0f}  (target >= 50,000; 1 rad, "
            f"{res['edge_valid_share']:.0%} valid; primitives {res['edges_per_s_primitives']:,.0f})",
        ),
        ("agreement", f"{res['agreement']:.6f} of {res['agreement_cases']:,}  (must be 1.0)"),
        ("fk_max_err_m", f"{res['fk_max_err_m']:.2e}  (target <= 1e-9)"),
        ("mesh_missed", f"{res['mesh_missed']} of {res['mesh_samples']} x 2 worlds  (target 0)"),
        ("mesh_false_alarm_rate", f"{res['mesh_false_alarm_rate']:.3f}  (target <= 0.10)"),
        ("mesh_false_alarm_rate_cloud", f"{res['mesh_false_alarm_rate_cloud']:.3f}"),
        ("margin / voxel", f"{res['margin_m']} m / {res['voxel_m']} m, {res['n_spheres']} spheres"),
        ("machine", "{cpu}, {simd}, {cores} cores, numba {numba}".format(**res["machine"])),
        ("wall time", f"{res['wall_s']:.1f} s"),
    ]
    print_table(rows, "collision benchmark")
    if args.json:
        write_json(args.json, res)
    return 0


def cmd_perception(args: argparse.Namespace) -> int:
    from gaide.bench_detector import run_detector_benchmark
    from gaide.bench_perception import run_perception_benchmark

    robot, spheres = robot_and_spheres(args.robot)
    t0 = time.perf_counter()
    res = run_perception_benchmark(
        robot,
        spheres,
        seed=args.seed,
        speed_frames=5 if args.quick else 30,
        handeye_poses=8 if args.quick else 12,
        progress=progress,
    )
    res.update(run_detector_benchmark(seed=args.seed))
    res["wall_s"] = time.perf_counter() - t0
    print_table(
        [
            ("fixed_err_mm", f"{res['fixed_err_mm']:.2f}  (target <= 2)"),
            ("fixed_err_deg", f"{res['fixed_err_deg']:.3f}  (target <= 0.2)"),
            ("handeye_err_mm", f"{res['handeye_err_mm']:.2f}  (target <= 5)"),
            ("handeye_err_deg", f"{res['handeye_err_deg']:.3f}  (target <= 0.5)"),
            ("eye_in_hand_err_mm", f"{res['eye_in_hand_err_mm']:.2f}  (target <= 2)"),
            ("eye_in_hand_err_deg", f"{res['eye_in_hand_err_deg']:.3f}  (target <= 0.2)"),
            (
                "eye_in_hand_std",
                f"{res['eye_in_hand_std_mm']:.2f} mm, {res['eye_in_hand_std_deg']:.3f} deg "
                "(reported by the calibration)",
            ),
            ("dict_cases_found", f"{res['dict_cases_found']:.3f}  (target 1.0)"),
            (
                "detector_recall_vs_reference",
                f"{res['detector_recall_vs_reference']:.3f}  (target >= 0.95, AprilTag 3)",
            ),
            (
                "corner_err_px",
                f"{res['corner_err_px']:.3f} median  (target <= 0.3; AprilTag 3: "
                f"{res['corner_err_px_reference']:.3f})",
            ),
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


def cmd_planning(args: argparse.Namespace) -> int:
    from pathlib import Path

    from gaide_core.errors import PlanningError
    from planning.family_names import parse_families
    from planning.harness import HarnessCfg, run_harness
    from planning.harness_report import (
        PAIRED_LEGEND,
        category_table,
        markdown_table,
        paired_table,
        plot,
        text_table,
    )
    from planning.registry import parse_planners

    if args.budget == "auto":
        budget = None
    else:
        try:
            budget = float(args.budget)
        except ValueError as err:
            raise PlanningError(f"--budget must be seconds or 'auto', got '{args.budget}'") from err
    cfg = HarnessCfg(
        families=tuple(parse_families(args.families)),
        planners=tuple(parse_planners(args.planners)),
        problems=args.problems,
        budget_s=budget,
        reference=args.reference,
        split=args.split,
        first=args.first,
        mesh_check=args.mesh_check,
        problem_file=Path(args.problem_file) if args.problem_file else None,
        robot_config=Path(args.robot) if args.robot else None,
        weights=Path(args.weights) if args.weights else None,
        checker=args.checker,
        **({"workers": args.workers} if args.workers else {}),
    )
    result = run_harness(cfg, progress=progress)
    print(text_table(result))
    print("\nsuccess per category (all families):")
    print(category_table(result))
    if len(cfg.planners) > 1:
        print(f"\n{PAIRED_LEGEND}:")
        print(paired_table(result))
    fig = result.figures()
    print(
        f"\n{fig['runs']} runs in {fig['wall_s']:.1f} s wall; planners {fig['planner_s']:.1f} s, "
        f"harness overhead {100 * (fig['overhead_share'] or 0):.1f}% of it, cores busy "
        f"{100 * (fig['core_utilisation'] or 0):.0f}%"
    )
    for note in result.notes:
        print(f"note: {note}")
    if args.json:
        out = Path(args.json)
        write_json(out, result.to_json())
        md = markdown_table(result) + "\n\nSuccess per category:\n\n" + category_table(result)
        if len(cfg.planners) > 1:
            md += f"\n\n{PAIRED_LEGEND[0].upper()}{PAIRED_LEGEND[1:]}:\n\n{paired_table(result)}"
        write_bytes_atomic(out.with_suffix(".md"), (md + "\n").encode(), ExecutionError)
        plot(result, out.with_suffix(".png"))
        print(f"wrote {out}, {out.with_suffix('.md')}, {out.with_suffix('.png')}")
    return 0


def cmd_oracle(args: argparse.Namespace) -> int:
    import numpy as np

    from gaide_core.errors import PlanningError
    from planning.checker import make_checker
    from planning.families import generate_problem
    from planning.family_names import parse_families, split_seed
    from planning.oracle import OracleCfg, oracle_consistency, oracle_quality

    if args.problems < 1 or not (0 < args.budget < math.inf):
        raise PlanningError(
            f"need --problems >= 1 and a --budget of seconds > 0; got {args.problems}, "
            f"{args.budget}"
        )
    robot, spheres = robot_and_spheres(args.robot)
    keys = (
        "runs",
        "refine",
        "shortcuts",
        "tie",
        "clearance",
        "clearance_rule",
        "band",
        "band_pull",
    )
    chosen = {k: getattr(args, k) for k in keys}
    cfg = OracleCfg(**{k: v for k, v in chosen.items() if v is not None})
    rows, runs = [], []
    families: dict[str, dict[str, float | None]] = {}
    for fam in parse_families(args.families):
        for i in progress(range(args.problems), desc=fam):
            problem = generate_problem(fam, split_seed("val", i), robot, spheres)
            checker = make_checker(robot, spheres, problem.world)
            q = oracle_quality(
                checker,
                problem.start,
                problem.goal,
                np.random.default_rng(i),
                cfg=cfg,
                reference_s=args.budget,
            )
            c = oracle_consistency(
                checker, problem.start, problem.goal, (1000 + i, 2000 + i), cfg=cfg
            )
            runs.append({"family": fam, "problem": problem.name, **q, **c})
        mine = [r for r in runs if r["family"] == fam]
        families[fam] = {
            key: _finite_median([r[src] for r in mine])
            for key, src in (
                ("first_step_disagreement_deg", "first_step_deg"),
                ("cost_spread", "cost_spread"),
                ("median_ratio", "ratio"),
            )
        }
        f = families[fam]
        rows.append(
            (
                fam,
                f"first steps {_fmt(f['first_step_disagreement_deg'], '.1f')} deg apart, "
                f"costs {_fmt(f['cost_spread'], '.3f')}x apart, oracle/reference "
                f"{_fmt(f['median_ratio'], '.3f')}",
            )
        )
    all_ratios = [r["ratio"] for r in runs if np.isfinite(r["ratio"])]
    print_table(
        rows,
        f"oracle: two independent runs per problem (targets <= 15 deg, <= 1.1x); against the "
        f"best of 3 anytime runs of {args.budget} s",
    )
    if args.json:
        write_json(
            args.json,
            {
                "families": families,
                "first_step_disagreement_deg": {
                    k: v["first_step_disagreement_deg"] for k, v in families.items()
                },
                "cost_spread": {k: v["cost_spread"] for k, v in families.items()},
                "median_ratio": float(np.median(all_ratios)) if all_ratios else None,
                "oracle": asdict(cfg),
                "runs": runs,
            },
        )
    return 0


def _finite_median(values: list[float]) -> float | None:
    import numpy as np

    ok = [v for v in values if np.isfinite(v)]
    return float(np.median(ok)) if ok else None


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def cmd_table(args: argparse.Namespace) -> int:
    from planning.harness_report import summary_markdown

    try:
        results = json.loads(Path(args.json).read_text())["results"]
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise ConfigError(
            f"{args.json}: not a JSON file written by `gaide bench planning --json` ({err})"
        ) from err
    rows = [p.strip() for p in args.planners.split(",")] if args.planners else None
    known = {p for fam in results.values() for p in fam}
    missing = [p for p in rows or [] if p not in known]
    if missing:
        raise ConfigError(f"{args.json} has no runs of {missing}; it has {sorted(known)}")
    print(summary_markdown(results, rows))
    return 0


def cmd_sampler(args: argparse.Namespace) -> int:
    import numpy as np
    import torch

    from planning.families import generate_problem
    from planning.family_names import split_seed
    from planning.neural.checkpoint import shipped_checkpoint
    from planning.neural.sampler import NeuralSampler
    from planning.scene_views import surface_cloud

    robot, spheres = robot_and_spheres(args.robot)
    problem = generate_problem("shelf_ii", split_seed("test", 0), robot, spheres)
    cloud = surface_cloud(problem.world, 2048, np.random.default_rng(0))
    batches = [int(b) for b in args.batches.split(",")]
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    kinds = [k.strip() for k in args.models.split(",") if k.strip()]
    out: dict[str, Any] = {"threads": torch.get_num_threads(), "results": {}}
    rows = []
    for kind in kinds:
        ckpt = args.checkpoint or shipped_checkpoint(kind)
        for dev in devices:
            sampler = NeuralSampler(ckpt, robot, kind if not args.checkpoint else None, device=dev)
            times: dict[str, float] = {}
            t0 = time.perf_counter()
            scene = sampler.scene(cloud)
            if dev == "cuda":
                torch.cuda.synchronize()
            times["scene_ms"] = 1e3 * (time.perf_counter() - t0)
            for b in batches:
                sampler.sample(scene, problem.start, problem.goal, b)  # warm-up
                runs = []
                for _ in range(args.repeats):
                    t0 = time.perf_counter()
                    sampler.sample(scene, problem.start, problem.goal, b)
                    if dev == "cuda":
                        torch.cuda.synchronize()
                    runs.append(time.perf_counter() - t0)
                times[f"batch_{b}_ms"] = 1e3 * float(np.median(runs))
            out["results"][f"{sampler.name}@{dev}"] = times
            rows.append(
                (
                    f"{sampler.name} {dev}",
                    ", ".join(f"{k.removesuffix('_ms')} {v:.2f} ms" for k, v in times.items()),
                )
            )
    print_table(rows, f"median forward pass ({args.repeats} repeats, {out['threads']} threads)")
    if args.json:
        write_json(args.json, out)
    return 0
