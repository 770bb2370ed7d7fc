"""``gaide run`` as a function: a recorded bag to an exported, simulated trajectory.

Stages, in order (each one's exception and exit code in :data:`runner.STAGE_ERRORS`):
setup (robot, settings) -> calibration (T_base_cam) -> perception (scene cloud) ->
planning (start/goal, path) -> timing (Ruckig) -> export (files for a controller) ->
simulation (PyBullet) -> report (``run.mcap``, the run for Foxglove, and ``report.html``). A
failed stage stops the run: the files of the stages before it stay, ``summary.json`` names the
failed stage and the cause, and a report (and ``run.mcap``) of what succeeded is written when
reports are on.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from gaide.pipeline.config import EXPORT_NAMES, RunCfg
from gaide.pipeline.config_io import dump_cfg
from gaide.pipeline.report import report_stage
from gaide.pipeline.runner import StageHooks, StageRunner, claim_folder, folder_lock
from gaide_core.errors import BagError, ConfigError, GaideError

if TYPE_CHECKING:
    from execution.parameterizer import TimeParameterizer
    from execution.trajectory import TimedTrajectory
    from gaide.pipeline.motion import Planned
    from gaide.pipeline.runner import StageRecord
    from gaide.pipeline.sense import CameraPose, Sensed, Setup
    from perception.frames import Frames

log = logging.getLogger(__name__)

STAGES = (
    "setup",
    "calibration",
    "perception",
    "planning",
    "timing",
    "export",
    "simulation",
    "report",
)


def ruckig_parameterizer(cfg: RunCfg) -> TimeParameterizer:
    """The configured time parameterization (Ruckig)."""
    from execution.ruckig_timing import RuckigParameterizer

    return RuckigParameterizer(cfg.timing)


def run_pipeline(
    cfg: RunCfg,
    *,
    hooks: StageHooks | None = None,
    title: str = "gaide run",
    parameterizer: TimeParameterizer | None = None,
) -> StageRunner:
    """Run every stage into ``cfg.out``; returns the runner (records, summary). A stage's
    failure raises that stage's exception after the partial outputs are written."""
    config_yaml = dump_cfg(cfg)
    out = Path(cfg.out)
    made = Made(start_ns=time.time_ns())
    with folder_lock(out):
        # Before anything is written: the earlier run's files go (all of them, so that a
        # failure leaves only this run's), anyone else's stay and stop the run.
        claim_folder(out, OUTPUTS)
        runner = StageRunner(
            out,
            STAGES,
            hooks=hooks,
            header={"title": title, "bag": cfg.bag, "config": cfg.as_dict()},
        )
        runner.write_summary()  # "running"
        try:
            _stages(cfg, runner, parameterizer, made)
        except BaseException as err:
            if cfg.report.enabled:
                done = made if isinstance(err, Exception) else None
                _partial_report(runner, config_yaml, title, cfg, done)
            raise
        if cfg.report.enabled:
            with runner.stage("report") as rec:
                if _mcap_enabled(cfg):
                    mcap_output(cfg, runner, rec, made)
                checker = made.planned.checker if made.planned else None
                report_stage(runner, config_yaml, title, checker=checker)
        else:
            runner.skip("report", "report.enabled is false")
        runner.finish()
    return runner


#: The run as one MCAP file (Foxglove), written by the report stage before ``report.html``.
MCAP = "run.mcap"
#: Highest rate (Hz) of the robot's /tf and sphere markers in run.mcap (the trajectory's
#: joint states keep every sample).
MCAP_MAX_RATE_HZ = 100.0
#: Every file (or folder) a run may write, besides ``summary.json``.
OUTPUTS = (
    "calibration.yaml",
    "calibration_overlay.png",
    "scene.ply",
    "scene.png",
    "plan.json",
    "path.png",
    "trajectory.png",
    *EXPORT_NAMES.values(),
    "sim_log.csv",
    "simulation.json",
    "tracking.png",
    MCAP,
    "report.html",
)


def check_inputs(cfg: RunCfg) -> None:
    """What the settings alone can show wrong (a bag that is not there, no goal): said
    before the stages load their libraries."""
    if cfg.bag is None:
        raise ConfigError("no bag given: `gaide run BAG ...` (or bag: in the config file)")
    if not Path(cfg.bag).exists():
        raise BagError(f"bag {cfg.bag} does not exist")
    if cfg.planning.goal is None:
        raise ConfigError(
            "no goal given: --goal NAME, --goal a,b,c,d,e,f (rad) or --goal xyz:x,y,z (m)"
        )


def _stages(
    cfg: RunCfg, runner: StageRunner, parameterizer: TimeParameterizer | None, made: Made
) -> None:
    with runner.stage("setup") as rec:
        check_inputs(cfg)
        # The stages' modules load Open3D, OpenCV, Pinocchio, Ruckig: only once the inputs
        # are known to be there.
        from gaide.pipeline.execute import export_stage, simulation_stage
        from gaide.pipeline.motion import planning_stage, timing_stage
        from gaide.pipeline.sense import (
            calibration_stage,
            given_camera,
            perception_stage,
            setup_stage,
        )

        setup = made.setup = setup_stage(cfg, rec)
    if cfg.calibration.T_base_cam is not None:
        camera = made.camera = given_camera(cfg)
        runner.records["calibration"].figures.update(
            source="given", T_base_cam=list(cfg.calibration.T_base_cam)
        )
        runner.skip("calibration", "camera pose given (calibration.T_base_cam)")
    else:
        with runner.stage("calibration") as rec:
            camera = made.camera = calibration_stage(cfg, setup.robot, runner, rec)
    with runner.stage("perception") as rec:
        sensed = made.sensed = perception_stage(cfg, setup, camera, runner, rec)
    with runner.stage("planning") as rec:
        planned = made.planned = planning_stage(cfg, setup, camera, sensed, runner, rec)
    with runner.stage("timing") as rec:
        traj = made.traj = timing_stage(
            parameterizer or ruckig_parameterizer(cfg), planned, runner, rec
        )
    with runner.stage("export") as rec:
        exported = export_stage(cfg, traj, runner, rec)
    if cfg.simulate.enabled:
        with runner.stage("simulation") as rec:
            simulation_stage(cfg, traj, exported, planned, sensed, runner, rec)
        made.sim_log = runner.path("sim_log.csv")
    else:
        runner.skip("simulation", "simulate.enabled is false")


def _partial_report(
    runner: StageRunner, config_yaml: str, title: str, cfg: RunCfg, made: Made | None
) -> None:
    """Best effort: ``run.mcap`` (unless the run was interrupted: ``made`` None) and a
    report of what succeeded; never hides the run's own error."""
    if made is not None and _mcap_enabled(cfg) and made.anything:
        try:
            mcap_output(cfg, runner, runner.records["report"], made)
        except (GaideError, OSError, ValueError) as err:
            log.warning("no %s of the failed run: %s", MCAP, err)
    try:
        # An interrupted run (made None) reports at once, without the 3D view.
        checker = made.planned.checker if made is not None and made.planned else None
        report_stage(runner, config_yaml, title, checker=checker, view3d=made is not None)
        runner.write_summary()
    except (GaideError, OSError, ValueError) as err:
        log.warning("no report of the failed run: %s", err)


@dataclass
class Made:
    """What the stages have made so far: ``run.mcap`` shows it, whichever stage failed."""

    start_ns: int  # the run's start (ns, wall clock): time 0 when the bag gives no stamp
    setup: Setup | None = None
    camera: CameraPose | None = None
    sensed: Sensed | None = None
    planned: Planned | None = None
    traj: TimedTrajectory | None = None
    sim_log: Path | None = None  # the simulation's joint log (sim_log.csv)

    @property
    def anything(self) -> bool:
        return self.setup is not None


def _mcap_enabled(cfg: RunCfg) -> bool:
    """``report.mcap``: write run.mcap."""
    return cfg.report.mcap


def mcap_output(cfg: RunCfg, runner: StageRunner, record: StageRecord, made: Made) -> None:
    """``run.mcap``: what the stages made (:mod:`gaide.pipeline.run_mcap`), written with the
    stage's other outputs; its topics and message counts go into the stage's figures."""
    from execution.joint_log import read_log_csv
    from gaide.pipeline.run_mcap import RunMcap, write_run_mcap

    frames = _used_frames(cfg) if made.setup is not None else None
    # Trajectory time 0: the first image's stamp (the bag's clock), else the run's start.
    streams = [] if frames is None else [frames.color, frames.depth]
    stamps = [int(s.stamps_ns.min()) for s in streams if s is not None and len(s)]
    start_ns = min(stamps, default=made.start_ns)
    cloud = made.sensed.cloud if made.sensed is not None else None
    simulated = read_log_csv(made.sim_log) if made.sim_log is not None else None
    shown = (frames, made.camera, cloud, made.planned, made.traj, simulated)
    if all(x is None for x in shown):
        # a run that failed before any stage made something to show, in a bag without
        # images: no file, and no warning (the run's own error says what went wrong)
        return
    written: list[RunMcap] = []

    def write(tmp: Path) -> None:
        written.append(
            write_run_mcap(
                tmp,
                start_ns=start_ns,
                frames=frames,
                cloud_points=None if cloud is None else cloud.points,
                cloud_colors=None if cloud is None else cloud.colors,
                T_base_cam=None if made.camera is None else made.camera.T_base_cam,
                robot=None if made.setup is None else made.setup.robot,
                spheres=None if made.setup is None else made.setup.spheres,
                path_q=None if made.planned is None else made.planned.path,
                trajectory=made.traj,
                simulated=simulated,
                max_rate_hz=MCAP_MAX_RATE_HZ,
            )
        )

    runner.commit(record, {MCAP: write})
    record.figures["mcap"] = written[-1].figures()


def _used_frames(cfg: RunCfg) -> Frames | None:
    """The images perception used, read again from the bag (both streams when the bag has
    them, else the one it has); None when the bag gives none."""
    from perception.bag_reader import read_bag

    assert cfg.bag is not None  # check_inputs
    p = cfg.perception
    for streams in (("depth", "color"), ("depth",), ("color",)):
        try:
            return read_bag(
                cfg.bag,
                streams=streams,
                max_frames=p.max_frames,
                default_extrinsics=p.default_extrinsics,
            )
        except BagError:
            continue
    return None
