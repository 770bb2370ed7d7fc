"""The middle stages of a run: a collision-free path in the perceived scene (start and goal
solved and checked, the planner retried with fresh seeds), and its time parameterization."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from execution.parameterizer import TimeParameterizer
from execution.trajectory import TimedTrajectory
from gaide.pipeline import figures
from gaide.pipeline.config import PlanningCfg, RunCfg
from gaide.pipeline.endpoints import Resolved, reference_configuration, resolve
from gaide.pipeline.runner import StageRecord, StageRunner
from gaide.pipeline.sense import CameraPose, Sensed, Setup
from gaide_core.errors import PlanningError, TimingError
from gaide_core.plan_file import PlanFile, plan_bytes
from gaide_core.types import Array
from planning.checker import make_checker
from planning.collision import CollisionChecker
from planning.distance_field import CloudWorld
from planning.planner import Planner, PlanResult, PlanStatus


@dataclass(frozen=True)
class Planned:
    checker: CollisionChecker  # the perceived scene's checker
    start: Resolved
    goal: Resolved
    result: PlanResult  # the successful attempt
    attempts: int  # attempts made (the last one succeeded)
    planning_s: float  # s, all attempts together

    @property
    def path(self) -> Array:
        assert self.result.path is not None  # a Planned holds a successful attempt
        return self.result.path


def make_run_planner(name: str, p: PlanningCfg) -> Planner:
    """The planner ``name`` (the setup stage's resolution of ``p.planner``): a registry
    name, a neural one with the given weights, on the configured torch threads."""
    from planning.registry import is_neural, make_planner

    checkpoint = p.checkpoint if is_neural(name) else None
    return make_planner(name, checkpoint=checkpoint, threads=p.torch_threads)


def _attempts(
    planner: Planner, checker: CollisionChecker, start: Array, goal: Array, p: PlanningCfg
) -> list[PlanResult]:
    """Plan up to ``p.attempts`` times, a fresh seed each, until one succeeds."""
    results: list[PlanResult] = []
    for attempt in range(p.attempts):
        res = planner.plan(
            checker, start, goal, budget_s=p.budget_s, rng=np.random.default_rng([p.seed, attempt])
        )
        results.append(res)
        if res.success or res.status in (PlanStatus.START_INVALID, PlanStatus.GOAL_INVALID):
            break
    return results


def _endpoint(checker: CollisionChecker, r: Resolved) -> Resolved:
    """Refuse an endpoint outside the limits or in collision, naming the links."""
    diag = checker.diagnose(r.q)
    if not diag.valid:
        raise PlanningError(
            f"{r.endpoint.what} '{r.endpoint.text}' ({r.how}) is invalid in the perceived "
            f"scene: {diag}; choose another {r.endpoint.what}"
        )
    return r


def planning_stage(
    cfg: RunCfg,
    setup: Setup,
    camera: CameraPose,
    sensed: Sensed,
    runner: StageRunner,
    record: StageRecord,
) -> Planned:
    p = cfg.planning
    world = CloudWorld(sensed.cloud.points, voxel=p.world_voxel)
    checker = make_checker(setup.robot, setup.spheres, world, backend=p.checker)
    rng = np.random.default_rng(p.seed)
    reference = reference_configuration(setup.robot, sensed.recorded)
    kw: dict[str, Any] = {"recorded": sensed.recorded, "rng": rng, "restarts": p.ik_restarts}
    start = _endpoint(checker, resolve(setup.start, checker, reference=reference, **kw))
    goal = _endpoint(checker, resolve(setup.goal, checker, reference=start.q, **kw))
    planner = make_run_planner(setup.planner, p)
    results = _attempts(planner, checker, start.q, goal.q, p)
    total = sum(r.time_s for r in results)
    res = results[-1]
    record.figures.update(
        planner=setup.planner,
        attempts=len(results),
        planning_s=round(total, 4),
        budget_s=p.budget_s,
    )
    if not res.success or res.path is None:
        raise PlanningError(
            f"{setup.planner} found no path from start '{start.endpoint.text}' to goal "
            f"'{goal.endpoint.text}' in {len(results)} attempt(s) of {p.budget_s:g} s: "
            f"{res.status.value}: {res.detail}; raise planning.budget_s or planning.attempts, "
            "or choose another goal"
        )
    bad = checker.first_invalid_edge(res.path)
    if bad is not None:  # planners check their edges; this guards the pipeline's promise
        raise PlanningError(f"{setup.planner} returned a path whose edge {bad} collides")
    planned = Planned(checker, start, goal, res, len(results), total)
    picture = figures.path_png(
        checker,
        res.path,
        sensed.cloud.points,
        sensed.cloud.colors,
        eye=camera.T_base_cam[:3, 3],
        poses=cfg.report.poses,
        title=f"{setup.planner}: {len(res.path)} waypoints, {res.cost:.2f} rad",
    )
    plan = PlanFile(
        planner=res.planner,
        status=res.status.value,
        scene="scene.ply",  # beside plan.json in the output folder (scene_spec.next_to)
        joint_names=setup.robot.joint_names,
        time_s=res.time_s,
        cost_rad=res.cost,
        start=start.q,
        goal=goal.q,
        path=res.path,
        stats=res.stats,
    )
    runner.commit(record, {"plan.json": plan_bytes(plan), "path.png": picture})
    record.figures.update(
        start=f"{start.endpoint.text} ({start.how})",
        goal=f"{goal.endpoint.text} ({goal.how})",
        start_q=np.round(start.q, 5).tolist(),
        goal_q=np.round(goal.q, 5).tolist(),
        waypoints=len(res.path),
        path_length_rad=round(res.cost, 4),
        last_attempt_s=round(res.time_s, 4),
        direct_edge_valid=bool(checker.edge_valid(start.q, goal.q)),
        stats=json.loads(json.dumps(res.stats, default=str)),
    )
    return planned


def timing_stage(
    parameterizer: TimeParameterizer,
    planned: Planned,
    runner: StageRunner,
    record: StageRecord,
) -> TimedTrajectory:
    """A jerk-limited trajectory along the path, its limits re-checked at 1 kHz."""
    from execution.plots import trajectory_png
    from execution.verify import limit_violations

    traj = parameterizer.parameterize(planned.path, planned.checker)
    violations = limit_violations(traj) if traj.chain is not None else 0
    if violations:
        raise TimingError(
            f"{parameterizer.name} made a trajectory that breaks the joint limits at "
            f"{violations} samples (1 kHz re-sampling); lower timing.*_scale"
        )
    runner.commit(record, {"trajectory.png": trajectory_png(traj)})
    record.figures.update(
        {k: v for k, v in traj.summary().items() if not k.startswith("ms_")},
        limit_violations=violations,
        notes=list(traj.notes),
    )
    return traj
