"""The last stages of a run: the trajectory exported for a controller, and its simulated
execution (PyBullet tracks it in the perceived scene; the achieved states are logged and
compared with the plan)."""

from __future__ import annotations

import json
import time
from pathlib import Path

from execution.trajectory import TimedTrajectory
from gaide.pipeline.config import EXPORT_NAMES, RunCfg
from gaide.pipeline.motion import Planned
from gaide.pipeline.runner import StageRecord, StageRunner
from gaide.pipeline.sense import Sensed
from gaide_core.errors import ExecutionError


def export_stage(
    cfg: RunCfg, traj: TimedTrajectory, runner: StageRunner, record: StageRecord
) -> list[Path]:
    """The trajectory in every configured format (``EXPORT_NAMES``), all written or none;
    the URScript program and the ros2_control goal with the export section's settings. The
    run's robot (its config, loaded again: milliseconds) checks the joint names and gives the
    tool positions of movej's blends."""
    from execution.export import write_trajectory
    from planning.robot_model import load_robot

    targets = [runner.path(EXPORT_NAMES[f]) for f in cfg.export.formats]
    written = write_trajectory(
        traj,
        targets,
        storage=cfg.export.storage,
        urscript=cfg.export,
        goal=cfg.export,
        robot=load_robot(cfg.robot),
    )
    record.outputs.extend(str(p) for p in written)
    record.figures.update(formats=list(cfg.export.formats), samples=len(traj.t))
    return written


def simulation_stage(
    cfg: RunCfg,
    traj: TimedTrajectory,
    exported: list[Path],
    planned: Planned,
    sensed: Sensed,
    runner: StageRunner,
    record: StageRecord,
) -> None:
    """Track the trajectory in PyBullet; fail past the tracking bound (or on a contact
    when so configured). Writes the joint log, the tracking report and its plot."""
    from execution.compare import compare
    from execution.export import write_log
    from execution.plots import comparison_png
    from execution.simulate import SimStatus, cloud_near_motion, simulate

    s = cfg.simulate
    robot = planned.checker.robot
    cloud = cloud_near_motion(sensed.cloud.points, traj, planned.checker, s.crop_m)
    result = simulate(
        traj,
        robot,
        cloud=cloud if len(cloud) else None,
        cfg=s,
        start_ns=time.time_ns(),
        checker=planned.checker,
    )
    rms, worst = result.rms_all_rad, result.max_all_rad
    # The bound is on the error apart from the controller's fixed delay (a known latency,
    # not a deviation from the path); the figures keep both.
    gated = result.rms_after_delay_all_rad
    gated = rms if gated is None else gated
    figures = result.summary()
    record.figures.update(
        status=result.status.value,
        controller=result.controller,
        delay_ms=1e3 * result.delay_s,
        tracking_rms_rad=rms,
        tracking_max_rad=worst,
        tracking_rms_after_delay_rad=result.rms_after_delay_all_rad,
        tracking_max_after_delay_rad=result.max_after_delay_all_rad,
        executed_min_clearance_m=figures["executed_min_clearance_m"],
        executed_clearance_ok=result.clearance_ok,
        clearance_margin_m=result.clearance_margin_m,
        contacts=len(result.contacts),
        cloud_points_simulated=len(cloud),
        precheck_invalid_samples=result.precheck_invalid,
        sim_wall_s=round(result.wall_s, 3),
    )
    if gated > s.max_tracking_rms_rad:
        raise ExecutionError(
            f"the simulated robot tracks the trajectory with an RMS error of {gated:.3g} rad "
            f"(after its {1e3 * result.delay_s:.3g} ms delay), above "
            f"simulate.max_tracking_rms_rad = {s.max_tracking_rms_rad:g} rad; slow the "
            "trajectory down (timing.*_scale) or raise the bound"
        )
    if result.contacts and s.fail_on_contact and result.status is not SimStatus.HULL_ONLY:
        c = result.contacts[0]
        raise ExecutionError(
            f"the simulated robot touched the scene: {c.link} with {c.obstacle} from "
            f"{c.first_s:.3f} s to {c.last_s:.3f} s ({len(result.contacts)} contacts)"
        )
    report = {"trajectory": [str(p) for p in exported], **result.summary()}
    extra = {
        runner.path("simulation.json"): (json.dumps(report, indent=2) + "\n").encode(),
        runner.path("tracking.png"): comparison_png(compare(traj, result.log)),
    }
    written = write_log(result.log, [runner.path("sim_log.csv")], extra=extra)
    record.outputs.extend(str(p) for p in [*written, *extra])
    record.figures["contact_list"] = [
        f"{c.link} with {c.obstacle}, {c.first_s:.3f}-{c.last_s:.3f} s" for c in result.contacts
    ]
