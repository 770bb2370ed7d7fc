"""``gaide run`` as a function: a recorded bag to an exported, simulated trajectory.

Stages, in order (each one's exception and exit code in :data:`runner.STAGE_ERRORS`):
setup (robot, settings) -> calibration (T_base_cam) -> perception (scene cloud) ->
planning (start/goal, path) -> timing (Ruckig) -> export (files for a controller) ->
simulation (PyBullet) -> report (``report.html``). A failed stage stops the run: the files
of the stages before it stay, ``summary.json`` names the failed stage and the cause, and a
report of what succeeded is written when reports are on.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

from gaide.pipeline.config import EXPORT_NAMES, RunCfg
from gaide.pipeline.config_io import dump_cfg
from gaide.pipeline.report import report_stage
from gaide.pipeline.runner import StageHooks, StageRunner, claim_folder, folder_lock
from gaide_core.errors import BagError, ConfigError, GaideError

if TYPE_CHECKING:
    from execution.parameterizer import TimeParameterizer

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
            _stages(cfg, runner, parameterizer)
        except BaseException:
            if cfg.report.enabled:
                _partial_report(runner, config_yaml, title)
            raise
        if cfg.report.enabled:
            with runner.stage("report"):
                report_stage(runner, config_yaml, title)
        else:
            runner.skip("report", "report.enabled is false")
        runner.finish()
    return runner


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


def _stages(cfg: RunCfg, runner: StageRunner, parameterizer: TimeParameterizer | None) -> None:
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

        setup = setup_stage(cfg, rec)
    if cfg.calibration.T_base_cam is not None:
        camera = given_camera(cfg)
        runner.records["calibration"].figures.update(
            source="given", T_base_cam=list(cfg.calibration.T_base_cam)
        )
        runner.skip("calibration", "camera pose given (calibration.T_base_cam)")
    else:
        with runner.stage("calibration") as rec:
            camera = calibration_stage(cfg, setup.robot, runner, rec)
    with runner.stage("perception") as rec:
        sensed = perception_stage(cfg, setup, camera, runner, rec)
    with runner.stage("planning") as rec:
        planned = planning_stage(cfg, setup, camera, sensed, runner, rec)
    with runner.stage("timing") as rec:
        traj = timing_stage(parameterizer or ruckig_parameterizer(cfg), planned, runner, rec)
    with runner.stage("export") as rec:
        exported = export_stage(cfg, traj, runner, rec)
    if cfg.simulate.enabled:
        with runner.stage("simulation") as rec:
            simulation_stage(cfg, traj, exported, planned, sensed, runner, rec)
    else:
        runner.skip("simulation", "simulate.enabled is false")


def _partial_report(runner: StageRunner, config_yaml: str, title: str) -> None:
    """Best effort: a report of what succeeded; never hides the run's own error."""
    try:
        report_stage(runner, config_yaml, title)
        runner.write_summary()
    except (GaideError, OSError, ValueError) as err:
        log.warning("no report of the failed run: %s", err)
