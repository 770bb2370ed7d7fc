"""``gaide data generate``, ``gaide train`` and ``gaide plan``: GAIDE's training data, its
training, and planning one problem with any planner."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from gaide.common import (
    JobProgress,
    add_checker_option,
    add_robot_option,
    print_table,
    robot_and_spheres,
    seed,
)
from gaide.pipeline.config import PlanningCfg
from gaide_core.errors import ConfigError, ExecutionError, PlanningError
from gaide_core.plan_file import PlanFile, write_plan
from planning.family_names import FAMILIES, parse_families, split_seed


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    data = sub.add_parser("data", help="GAIDE's training data (oracle paths)")
    dsub = data.add_subparsers(dest="data_cmd", required=True)
    gen = dsub.add_parser("generate", help="oracle paths on the training seed range")
    gen.add_argument("--families", default="all", help="comma-separated families or 'all'")
    gen.add_argument("--paths", type=int, required=True, help="number of path indices")
    gen.add_argument("--out", required=True, help="data directory (resumed if it exists)")
    gen.add_argument("--shard-size", type=int, help="paths per shard file (default 48)")
    gen.add_argument(
        "--categories",
        default="all",
        help="problem categories cycled over each scene's paths: 'all' or a comma-separated "
        "list of free2free, free2tight, tight2free, tight2tight",
    )
    gen.add_argument(
        "--ray",
        metavar="auto|ADDRESS",
        help="make the shards as Ray tasks on this cluster (auto: the running one, or a "
        "local instance); default: local processes",
    )
    gen.add_argument("--max-step", type=float, default=0.3, help="path step (rad)")
    gen.add_argument("--oracle-runs", type=int, help="compiled RRT-Connect runs per path (6)")
    gen.add_argument("--oracle-iterations", type=int, help="iterations per oracle run (20,000)")
    gen.add_argument("--oracle-refine", type=int, help="shortest runs that get the shortcuts (2)")
    gen.add_argument("--oracle-shortcuts", type=int, help="shortcut attempts per refined run (250)")
    gen.add_argument(
        "--oracle-tie",
        type=float,
        help="among refined runs within this share of the shortest, label the one leaving "
        "the start most nearly toward the goal (0: the shortest)",
    )
    gen.add_argument(
        "--oracle-clearance",
        type=float,
        help="extra clearance (m, up to 0.05) each sphere of the labels keeps: at most half "
        "of how far that sphere clears the margin at the start and the goal (0: none)",
    )
    gen.add_argument(
        "--oracle-clearance-rule",
        choices=["sphere", "tightest"],
        help="limit each sphere's extra clearance by its own at the ends (sphere, the "
        "default) or all by the tightest sphere's (tightest: sets made before the rule)",
    )
    gen.add_argument(
        "--oracle-band",
        type=int,
        help="L-BFGS iterations of the elastic band that pulls each label taut (500, the "
        "default, makes two labels of a problem agree; 0: none; docs/results.md)",
    )
    gen.add_argument(
        "--oracle-band-pull",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="after the band, keep only the band's points that straight certified edges "
        "cannot skip (string pulling: a polyline on the taut curve; the default)",
    )
    # The oracle was budgeted in seconds; it is budgeted by work now (the same seed gives
    # the same labels under load). The old flags are still accepted and say so.
    for old_flag in ("--oracle-budget", "--oracle-rescue"):
        gen.add_argument(old_flag, type=float, help=argparse.SUPPRESS)
    gen.add_argument("--workers", type=int, help="processes (default: all cores)")
    add_checker_option(gen)
    add_robot_option(gen)
    gen.set_defaults(func=cmd_data_generate)

    tr = sub.add_parser("train", help="train GAIDE, an ablation or a neural baseline")
    tr.add_argument(
        "--model", required=True, choices=["gaide", "gaide-v", "gaide-h", "mpnet", "simpnet"]
    )
    tr.add_argument("--data", required=True, help="data directory from `gaide data generate`")
    tr.add_argument("--out", required=True, help="checkpoint file (a .card.json goes beside it)")
    tr.add_argument("--steps", type=int, default=3000)
    tr.add_argument("--batch", type=int, default=128)
    tr.add_argument("--lr", type=float, default=1e-3)
    tr.add_argument("--seed", type=seed, default=0)
    tr.add_argument("--val-every", type=int, default=250, help="steps between loss records")
    tr.add_argument("--device", default="auto", help="auto (CUDA if present), cpu or cuda[:N]")
    tr.add_argument(
        "--threads", type=int, default=0, help="CPU threads (default: all; 1 when sharing cores)"
    )
    sizes = tr.add_argument_group("model size (default: the shipped size, see docs/results.md)")
    for flag, help_text in (
        ("--hidden", "token width H"),
        ("--heads", "attention heads"),
        ("--ff", "feed-forward width"),
        ("--enc-layers", "encoder layers (message-passing rounds for simpnet)"),
        ("--dec-layers", "decoder layers"),
        ("--scene-points", "scene points the set abstraction reads"),
        ("--scene-tokens", "scene tokens K_w"),
        ("--modes", "steps the head proposes at once (relaxed winner-takes-all when > 1)"),
    ):
        sizes.add_argument(flag, type=int, help=help_text)
    tr.add_argument(
        "--family-weights",
        type=_family_weights,
        default={},
        metavar="FAMILY=W,...",
        help="draw a family's training pairs W times as often as the others' (default 1 each)",
    )
    tr.add_argument(
        "--state-noise",
        type=float,
        default=0.0,
        metavar="RAD",
        help="jitter q_t of half the training pairs by a Gaussian of this spread, the label "
        "still the oracle's next waypoint (default 0: off)",
    )
    tr.add_argument("--resume", action="store_true", help="continue from --out if it exists")
    add_robot_option(tr)
    tr.set_defaults(func=cmd_train)

    pl = sub.add_parser("plan", help="plan one problem and write the path as JSON")
    src = pl.add_mutually_exclusive_group(required=True)
    src.add_argument("--scene", help="scene cloud (.ply, base frame)")
    src.add_argument("--family", choices=FAMILIES, help="a generated task-family problem")
    pl.add_argument("--seed", type=seed, help="problem seed (default: the first test seed)")
    pl.add_argument("--start", help="start configuration: comma-separated rad, or a named one")
    pl.add_argument("--goal", help="goal configuration: comma-separated rad, or a named one")
    pl.add_argument(
        "--planner", default="gaide-hybrid", help="planner name (see `gaide bench planning`)"
    )
    pl.add_argument(
        "--checkpoint",
        help="weights for a neural planner, of its model (default: the shipped ones)",
    )
    pl.add_argument(
        "--budget", type=float, default=PlanningCfg().budget_s, help="seconds (gaide run's default)"
    )
    add_checker_option(pl)
    add_robot_option(pl)
    pl.add_argument("-o", "--output", required=True, help="path JSON")
    pl.set_defaults(func=cmd_plan)


def cmd_data_generate(args: argparse.Namespace) -> int:
    from planning.family_names import parse_categories
    from planning.neural.data import DataCfg
    from planning.neural.data_backends import generate
    from planning.oracle import OracleCfg

    cfg = DataCfg(
        families=tuple(parse_families(args.families)),
        paths=args.paths,
        max_step=args.max_step,
        oracle=OracleCfg(
            **{
                key: value
                for key, value in (
                    ("runs", args.oracle_runs),
                    ("iterations", args.oracle_iterations),
                    ("refine", args.oracle_refine),
                    ("shortcuts", args.oracle_shortcuts),
                    ("tie", args.oracle_tie),
                    ("clearance", args.oracle_clearance),
                    ("clearance_rule", args.oracle_clearance_rule),
                    ("band", args.oracle_band),
                    ("band_pull", args.oracle_band_pull),
                )
                if value is not None
            }
        ),
        checker=args.checker,
        categories=tuple(parse_categories(args.categories)),
        **({"shard_size": args.shard_size} if args.shard_size else {}),
    )
    if args.oracle_budget is not None or args.oracle_rescue is not None:
        print(
            "gaide data generate: note: --oracle-budget/--oracle-rescue are ignored; the oracle "
            "is budgeted by work (--oracle-runs, --oracle-iterations, --oracle-shortcuts)",
            file=sys.stderr,
        )
    cfg.check()  # before the progress bar: a bad setting is the only line printed
    t0 = time.perf_counter()
    bar = JobProgress("gaide data generate", "shard")

    def progress(done: int, total: int) -> None:
        bar.update(done, total)

    manifest = generate(
        cfg,
        args.out,
        robot_config=args.robot,
        workers=args.workers,
        ray=args.ray,
        progress=progress,
    )
    bar.close()
    print_table(
        [
            ("paths", str(manifest["paths"])),
            ("failures", str(manifest["failures"])),
            ("shards", str(len(manifest["shards"]))),
            ("wall", f"{time.perf_counter() - t0:.1f} s"),
        ],
        f"data in {args.out}",
    )
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from planning.neural.train import Dist, TrainCfg, Trainer

    robot, _ = robot_and_spheres(args.robot)
    cfg = TrainCfg(
        steps=args.steps,
        batch=args.batch,
        lr=args.lr,
        seed=args.seed,
        device=args.device,
        threads=args.threads,
        val_every=args.val_every,
        family_weights=args.family_weights,
        state_noise=args.state_noise,
    )
    from planning.neural.data import read_manifest
    from planning.neural.models import ModelCfg

    given = {
        k: getattr(args, k)
        for k in (
            "hidden",
            "heads",
            "ff",
            "enc_layers",
            "dec_layers",
            "scene_points",
            "scene_tokens",
            "modes",
        )
        if getattr(args, k) is not None
    }
    step = float(read_manifest(args.data)["settings"]["max_step"])
    model_cfg = ModelCfg(**given, step=step) if given else None
    if args.resume and model_cfg is None and Path(args.out).exists():
        from planning.neural.checkpoint import load_checkpoint

        model_cfg = load_checkpoint(args.out, robot, args.model).cfg  # resume at its sizes
    # under torchrun every process loads the data, and rank 0 reports
    loading = (
        JobProgress(f"train {args.model}: load {args.data}", "shard")
        if Dist.from_env().main
        else None
    )
    trainer = Trainer(
        args.model, robot, args.data, cfg, model_cfg, None if loading is None else loading.update
    )
    if loading is not None:
        loading.close()
    if args.resume and Path(args.out).exists():
        trainer.resume(args.out)
    main = trainer.dist.main  # under torchrun, rank 0 reports
    bar = JobProgress(f"train {args.model}", "step", cfg.steps, trainer.step) if main else None

    def progress(step: int, entry: dict[str, float]) -> None:
        if bar is not None:
            bar.update(step, train=f"{entry['train']:.4f}", val=f"{entry['val']:.4f}")

    digest = trainer.run(args.out, progress)
    if bar is not None:
        bar.close()
    if not main:
        return 0
    last = trainer.history[-1] if trainer.history else {}
    print_table(
        [
            ("checkpoint", f"{args.out} (sha256 {digest[:12]})"),
            ("device", f"{trainer.device} x {trainer.dist.world} process(es)"),
            ("steps", str(trainer.step)),
            ("train loss", f"{last.get('train', float('nan')):.4f}"),
            ("val loss", f"{last.get('val', float('nan')):.4f}"),
            ("wall", f"{trainer.wall_s:.1f} s"),
        ],
        f"trained {args.model}",
    )
    return 0


def _family_weights(text: str) -> dict[str, float]:
    """``shelf_i=2,shelf_ii=2`` as {family: weight}; the names are checked against the data."""
    out: dict[str, float] = {}
    for item in filter(None, text.split(",")):
        name, _, value = item.partition("=")
        try:
            weight = float(value)
        except ValueError:
            weight = float("nan")
        if not 0 < weight < float("inf"):
            raise argparse.ArgumentTypeError(
                f"'{item}' is not FAMILY=W with a finite weight W > 0 (e.g. shelf_iii=2)"
            )
        out[name.strip()] = weight
    return out


def _configuration(text: str | None, robot: Any, what: str) -> np.ndarray:
    if text is None:
        raise ConfigError(
            f"--{what} is needed with --scene (comma-separated rad or a named configuration)"
        )
    return robot.configuration_from_text(text, what)


def cmd_plan(args: argparse.Namespace) -> int:
    from gaide.scene_spec import relative_to
    from planning.checker import make_checker
    from planning.distance_field import CloudWorld
    from planning.families import generate_problem
    from planning.registry import make_planner

    robot, spheres = robot_and_spheres(args.robot)
    if args.family:
        seed = args.seed if args.seed is not None else split_seed("test", 0)
        problem = generate_problem(args.family, seed, robot, spheres)
        world: Any = problem.world
        start = problem.start if args.start is None else _configuration(args.start, robot, "start")
        goal = problem.goal if args.goal is None else _configuration(args.goal, robot, "goal")
        source = f"{args.family} seed {seed}"
    else:
        from perception.cloud import load_ply

        points = load_ply(args.scene)
        world = CloudWorld(points)
        start = _configuration(args.start, robot, "start")
        goal = _configuration(args.goal, robot, "goal")
        source = args.scene
    planner = make_planner(args.planner, checkpoint=args.checkpoint)
    checker = make_checker(robot, spheres, world, backend=args.checker)
    rng = np.random.default_rng(0 if args.seed is None else args.seed)
    result = planner.plan(checker, start, goal, budget_s=args.budget, rng=rng)
    if result.path is None:
        raise PlanningError(f"{args.planner} on {source}: {result.status.value}: {result.detail}")
    write_plan(
        args.output,
        PlanFile(
            planner=result.planner,
            status=result.status.value,
            scene=relative_to(source, Path(args.output).parent),
            joint_names=robot.joint_names,
            time_s=result.time_s,
            cost_rad=result.cost,
            start=start,
            goal=goal,
            path=result.path,
            stats=result.stats,
        ),
        ExecutionError,
    )
    print(
        f"{result.planner}: {len(result.path)} waypoints, {result.cost:.3f} rad in "
        f"{result.time_s:.3f} s -> {args.output}"
    )
    return 0
