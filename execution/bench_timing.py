"""``gaide bench timing``: time parameterization on the harness's paths.

Paths: the task-family problems of the test split (families in turn, problem i of family f
is test seed i), planned by the harness's reference baseline, OMPL RRT-Connect, with the
project's checker. Each path is timed in exact and in blended mode at 500 Hz, and each
result is checked independently by re-sampling its Ruckig segments at 1 kHz:

- ``limit_violations``: samples of either mode over any limit (position, velocity,
  acceleration, jerk; tolerance 1e-6);
- ``exact_path_dev_rad``: the largest distance of an exact-mode sample from its path;
- ``blended_over_exact_duration``: the median ratio of the two durations over the paths
  that keep at least 3 segments after shortcutting;
- ``blended_collisions``: blended trajectories with an invalid motion between consecutive
  1 kHz samples (each pair checked as an edge at the checker's resolution, straight parts
  included);
- ``ms_per_path``: median over the paths of the wall time of a blended-mode
  parameterization, everything included (path check, shortcut, blends, collision re-check,
  sampling); each path is timed ``repeats`` times and counts with its median (the machines
  are shared);
- ``sim_tracking_rms_rad``, ``sim_tracking_max_rad``: RMS and largest tracking error of the
  simulated controller (``sim``, default the servo model of :mod:`execution.servo`) over
  every joint and cycle of every simulated blended trajectory, in the problem's scene,
  against the plan at the same time (the servo's delay included;
  ``sim_tracking_max_after_delay_rad`` takes it out). No target: they describe the
  controller model, not the timing. Contacts are counted apart, as paths whose contacts the
  URDF meshes confirm and paths where only PyBullet's convex hulls touch;
- ``sim_delay_recovered_ms``: the median over the paths of the delay
  :func:`execution.compare.compare` finds between each plan and its simulated log, beside
  ``sim_delay_configured_ms`` (the servo's ``delay_cycles / rate_hz``);
  ``sim_delay_error_ms_max`` is the largest difference of a path;
- ``sim_min_clearance_m``: the smallest sphere-world clearance of the achieved
  configurations over every path (the problem's checker), and ``sim_clearance_violations``
  the paths whose executed motion came closer than the checker's margin.

Runs in one process, one path at a time, so that the times are not shared with other work
of the benchmark.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from execution.compare import compare
from execution.ruckig_timing import RuckigParameterizer
from execution.sim_cfg import SimCfg
from execution.simulate import SimResult, simulate
from execution.timing_cfg import TimingCfg, TimingMode
from execution.trajectory import TimedTrajectory
from execution.verify import limit_violations, path_deviation, swept_collisions
from gaide_core.errors import PlanningError
from planning.checker import make_checker
from planning.families import generate_problem
from planning.family_names import FAMILIES, split_seed
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel

Progress = Callable[..., Any]


@dataclass(frozen=True, kw_only=True)
class TimingBenchCfg:
    paths: int = 60  # problems, spread over the families in turn
    families: tuple[str, ...] = FAMILIES
    budget_s: float = 5.0  # s, RRT-Connect budget per problem
    rate_hz: float = 500.0  # Hz, controller rate
    verify_rate_hz: float = 1000.0  # Hz, independent re-sampling
    simulate: bool = True
    sim: SimCfg = field(default_factory=SimCfg)  # the simulated controller (servo by default)
    repeats: int = 3  # blended parameterizations timed per path (their median counts)

    def __post_init__(self) -> None:
        if self.paths < 1 or not self.families or self.budget_s <= 0 or self.repeats < 1:
            raise PlanningError(
                f"need paths >= 1, families, budget_s > 0 and repeats >= 1; got {self.paths}, "
                f"{self.families}, {self.budget_s}, {self.repeats}"
            )


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def run_timing_benchmark(
    robot: RobotModel,
    spheres: SphereModel,
    cfg: TimingBenchCfg | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]:
    from planning.registry import make_planner

    cfg = cfg or TimingBenchCfg()
    t_start = time.perf_counter()
    planner = make_planner("rrtconnect")
    exact = RuckigParameterizer(TimingCfg(rate_hz=cfg.rate_hz, mode=TimingMode.EXACT))
    blended = RuckigParameterizer(TimingCfg(rate_hz=cfg.rate_hz, mode=TimingMode.BLENDED))
    jobs = [(cfg.families[i % len(cfg.families)], i // len(cfg.families)) for i in range(cfg.paths)]
    runs: list[dict[str, Any]] = []
    failures: list[str] = []
    squared, samples = 0.0, 0
    iterator = progress(jobs, desc="timing", unit="path") if progress else jobs
    for family, index in iterator:
        seed = split_seed("test", index)
        problem = generate_problem(family, seed, robot, spheres)
        checker = make_checker(robot, spheres, problem.world)
        plan = planner.plan(
            checker, problem.start, problem.goal, budget_s=cfg.budget_s,
            rng=np.random.default_rng(seed),
        )  # fmt: skip
        if plan.path is None:
            failures.append(f"{problem.name}: {plan.status.value}")
            continue
        te = exact.parameterize(plan.path, checker)
        times = []
        for _ in range(cfg.repeats):  # the machine is shared: the median of a few runs
            t0 = time.perf_counter()
            tb = blended.parameterize(plan.path, checker)
            times.append(1e3 * (time.perf_counter() - t0))
        ms = float(np.median(times))
        segments = len(te.path) - 1 if te.path is not None else 0
        run: dict[str, Any] = {
            "problem": problem.name,
            "family": family,
            "input_waypoints": len(plan.path),
            "segments_after_shortcut": segments,
            "exact_s": te.duration,
            "blended_s": tb.duration,
            "ratio": tb.duration / te.duration,
            "ms": ms,
            "ms_stages": {
                k: tb.figures[k]
                for k in ("ms_check", "ms_shortcut", "ms_timing", "ms_recheck", "ms_sample")
            },
            "recheck_samples": int(tb.figures["recheck_samples"]),
            "fallbacks": int(tb.figures["fallbacks"]),
            "limit_violations": limit_violations(te, rate_hz=cfg.verify_rate_hz)
            + limit_violations(tb, rate_hz=cfg.verify_rate_hz),
            "exact_path_dev_rad": path_deviation(te, rate_hz=cfg.verify_rate_hz),
            "blended_invalid_motions": swept_collisions(tb, checker, rate_hz=cfg.verify_rate_hz),
        }
        if cfg.simulate:
            sim = simulate(tb, robot, primitives=problem.world, cfg=cfg.sim, checker=checker)
            squared += float(np.sum(sim.error**2))
            samples += sim.error.size
            run.update(_simulation_figures(sim, tb))
        runs.append(run)
    tracking_rms = float(np.sqrt(squared / samples)) if samples else None
    summary = _summary(cfg, runs, failures, tracking_rms)
    summary["wall_s"] = time.perf_counter() - t_start
    return summary


def _simulation_figures(sim: SimResult, traj: TimedTrajectory) -> dict[str, Any]:
    """One path's simulated execution: tracking, the delay recovered from the log, the
    executed clearance and contacts."""
    clearance = sim.executed_min_clearance_m  # inf in an empty world: JSON has none
    return {
        "sim_rms_rad": sim.rms_all_rad,
        "sim_max_rad": sim.max_all_rad,
        "sim_max_after_delay_rad": sim.max_after_delay_all_rad,
        "sim_delay_recovered_ms": 1e3 * compare(traj, sim.log).delay_s,
        "sim_min_clearance_m": clearance if np.isfinite(clearance or np.nan) else None,
        "sim_clearance_ok": sim.clearance_ok,
        "sim_limited_cycles": sim.limited_cycles,
        "sim_contacts": len(sim.contacts),
        "sim_status": sim.status.value,
    }


def _summary(
    cfg: TimingBenchCfg,
    runs: list[dict[str, Any]],
    failures: list[str],
    tracking_rms: float | None,
) -> dict[str, Any]:
    """The benchmark's figures over its paths (``runs``, each path's record, included)."""
    multi = [r for r in runs if r["segments_after_shortcut"] >= 3]
    simulated = [r for r in runs if "sim_rms_rad" in r]
    configured = 1e3 * (cfg.sim.servo.delay_s if cfg.sim.controller == "servo" else 0.0)
    recovered = [r["sim_delay_recovered_ms"] for r in simulated]
    stages = {
        k: _median([r["ms_stages"][k] for r in runs])
        for k in ("ms_check", "ms_shortcut", "ms_timing", "ms_recheck", "ms_sample")
    }
    return {
        "limit_violations": sum(r["limit_violations"] for r in runs),
        "exact_path_dev_rad": max((r["exact_path_dev_rad"] for r in runs), default=None),
        "blended_over_exact_duration": _median([r["ratio"] for r in multi]),
        "blended_collisions": sum(r["blended_invalid_motions"] > 0 for r in runs),
        "ms_per_path": _median([r["ms"] for r in runs]),
        "sim_tracking_rms_rad": tracking_rms,
        "sim_tracking_max_rad": max((r["sim_max_rad"] for r in simulated), default=None),
        "sim_tracking_max_after_delay_rad": max(
            (r["sim_max_after_delay_rad"] for r in simulated), default=None
        ),
        "sim_delay_configured_ms": configured if simulated else None,
        "sim_delay_recovered_ms": _median(recovered),
        "sim_delay_error_ms_max": max((abs(d - configured) for d in recovered), default=None),
        "sim_min_clearance_m": min(
            (r["sim_min_clearance_m"] for r in simulated if r["sim_min_clearance_m"] is not None),
            default=None,
        ),
        "sim_clearance_violations": sum(r["sim_clearance_ok"] is False for r in simulated),
        "n_paths": len(runs),
        "n_multi_segment": len(multi),
        "planning_failures": failures,
        "blended_over_exact_duration_all": _median([r["ratio"] for r in runs]),
        "ms_per_path_p90": float(np.percentile([r["ms"] for r in runs], 90)) if runs else None,
        "ms_stages_median": stages,
        "fallbacks": sum(r["fallbacks"] for r in runs),
        "sim_contact_paths": sum(r.get("sim_status") == "contact" for r in runs),
        "sim_hull_only_paths": sum(r.get("sim_status") == "hull_only" for r in runs),
        "sim_controller": cfg.sim.controller if simulated else None,
        "rate_hz": cfg.rate_hz,
        "verify_rate_hz": cfg.verify_rate_hz,
        "families": list(cfg.families),
        "runs": runs,
    }
