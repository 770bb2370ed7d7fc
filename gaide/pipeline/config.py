"""The settings of one ``gaide run``: frozen sections, each value checked on construction.

The defaults live in one place: the dataclasses. The sections that configure a library stage
extend that stage's own settings (perception's :class:`~perception.cloud_cfg.CloudCfg`,
timing's :class:`~execution.timing_cfg.TimingCfg`, export's
:class:`~execution.urscript.UrScriptCfg` and :class:`~execution.ros2_goal.Ros2GoalCfg`,
simulation's :class:`~execution.sim_cfg.SimCfg`), so ``gaide run``, ``gaide perceive``,
``gaide time`` and ``gaide simulate`` start from the same values. ``gaide/data/run.yaml``
documents every key with its default, and a test holds it equal to ``RunCfg()``.
:mod:`gaide.pipeline.config_io` merges defaults < a user's file < flags and builds a
:class:`RunCfg`. Units: m, rad, s; poses in the robot's base frame.
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass, field
from typing import Any, ClassVar

from execution.ros2_goal import Ros2GoalCfg
from execution.sim_cfg import SimCfg
from execution.timing_cfg import TimingCfg
from execution.urscript import UrScriptCfg
from gaide_core import settings as checks
from gaide_core.errors import ConfigError, GaideError
from perception.cloud_cfg import CloudCfg
from planning.checker import CHECKERS
from planning.registry import CLASSICAL, COMPILED, HYBRID, NEURAL

# auto: gaide-hybrid when its weights fit the robot, else the compiled RRT-Connect.
PLANNERS = ("auto", *COMPILED, *CLASSICAL, *NEURAL, *HYBRID)
EXPORT_NAMES = {  # format -> the run's output of it
    "csv": "trajectory.csv",
    "json": "trajectory.json",
    "bag": "trajectory.bag",
    "ros2": "trajectory_ros2",  # a ROS2 bag is a folder
    "urscript": "trajectory.script",  # a URScript program (a UR's six joints)
    "ros2_goal": "trajectory_goal.yaml",  # a ros2_control FollowJointTrajectory goal
}
EXPORT_FORMATS = tuple(EXPORT_NAMES)


def _set(obj: object, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)


@dataclass(frozen=True, kw_only=True)
class CalibrationCfg:
    """Where ``T_base_cam`` comes from: a calibration file, a given pose, or the bag."""

    SECTION: ClassVar[str] = "calibration"
    calib: str | None = None  # calibration YAML from `gaide calibrate`
    T_base_cam: tuple[float, ...] | None = None  # x, y, z (m), qx, qy, qz, qw: camera in base
    mode: str = "fixed"  # fixed | hand-eye
    target_pose: str | None = None  # fixed: target + its pose YAML (None: beside the bag)
    target: str | None = None  # hand-eye: target spec
    max_frames: int | None = None  # color frames used at most (None: all)

    def __post_init__(self) -> None:
        k = self.SECTION
        _set(self, "calib", checks.text(self.calib, f"{k}.calib"))
        _set(self, "T_base_cam", checks.vector(self.T_base_cam, f"{k}.T_base_cam", length=7))
        checks.choice(self.mode, f"{k}.mode", ("fixed", "hand-eye"))
        _set(self, "target_pose", checks.text(self.target_pose, f"{k}.target_pose"))
        _set(self, "target", checks.text(self.target, f"{k}.target"))
        if self.max_frames is not None:
            checks.integer(self.max_frames, f"{k}.max_frames", lo=1)
        if self.calib is not None and self.T_base_cam is not None:
            raise ConfigError(
                f"{k}.calib and {k}.T_base_cam are both set; give one (--calib or --T-base-cam)"
            )


@dataclass(frozen=True, kw_only=True)
class PerceptionCfg(CloudCfg):
    """The scene cloud (:class:`~perception.cloud_cfg.CloudCfg`: crop box, depth range,
    downsampling, outliers) and the self-filter's inputs."""

    SECTION: ClassVar[str] = "perception"
    self_filter: bool = True  # remove the robot's own points (needs joint states)
    joints: tuple[float, ...] | None = None  # rad, for the self-filter when the bag has none
    # Robot config of the arm recorded in the bag (its joint states, the self-filter's spheres)
    # when it is not the run's robot; None: the run's robot.
    bag_robot: str | None = None
    default_extrinsics: bool = False  # no depth-to-color extrinsics in the bag: assume identity

    def __post_init__(self) -> None:
        super().__post_init__()
        k = self.SECTION
        checks.flag(self.self_filter, f"{k}.self_filter")
        checks.flag(self.default_extrinsics, f"{k}.default_extrinsics")
        _set(self, "joints", checks.vector(self.joints, f"{k}.joints", unit="rad"))
        _set(self, "bag_robot", checks.text(self.bag_robot, f"{k}.bag_robot"))


@dataclass(frozen=True, kw_only=True)
class PlanningCfg:
    """Start, goal and the planner (see ``run.yaml`` for the endpoint forms)."""

    SECTION: ClassVar[str] = "planning"
    start: str = "recorded"
    goal: str | None = None  # required by a run
    planner: str = "auto"
    checkpoint: str | None = None  # None: the shipped weights
    budget_s: float = 10.0  # s per attempt
    attempts: int = 3
    seed: int = 0
    ik_restarts: int = 24
    world_voxel: float = 0.01  # m
    torch_threads: int = 1  # CPU threads for the network while planning; 0: torch's default
    checker: str = "compiled"  # collision checker backend: compiled | numpy

    def __post_init__(self) -> None:
        k = self.SECTION
        _set(self, "start", checks.text(self.start, f"{k}.start", optional=False))
        _set(self, "goal", checks.text(self.goal, f"{k}.goal"))
        checks.choice(self.planner, f"{k}.planner", PLANNERS)
        _set(self, "checkpoint", checks.text(self.checkpoint, f"{k}.checkpoint"))
        if self.checkpoint is not None and self.planner not in ("auto", *NEURAL, *HYBRID):
            raise ConfigError(
                f"{k}.checkpoint is for the neural planners {list(NEURAL + HYBRID)}, not "
                f"'{self.planner}'"
            )
        _set(
            self,
            "budget_s",
            checks.number(
                self.budget_s, f"{k}.budget_s", lo=0.0, hi=3600.0, lo_open=True, unit="s"
            ),
        )
        checks.integer(self.attempts, f"{k}.attempts", lo=1, hi=100)
        checks.integer(self.seed, f"{k}.seed", lo=0)
        checks.integer(self.ik_restarts, f"{k}.ik_restarts", lo=1, hi=10_000)
        checks.integer(self.torch_threads, f"{k}.torch_threads", lo=0, hi=256)
        checks.choice(self.checker, f"{k}.checker", CHECKERS)
        _set(
            self,
            "world_voxel",
            checks.number(self.world_voxel, f"{k}.world_voxel", lo=0.002, hi=0.05, unit="m"),
        )


@dataclass(frozen=True, kw_only=True)
class _ExportOutputs:
    """The first keys of the export section (a base class only to come first)."""

    formats: tuple[str, ...] = ("csv", "json", "bag")  # of EXPORT_FORMATS
    storage: str = "sqlite3"  # ROS2 bag storage


@dataclass(frozen=True, kw_only=True)
class ExportCfg(Ros2GoalCfg, UrScriptCfg, _ExportOutputs):
    """The formats a run writes, then the settings of the URScript program
    (:class:`~execution.urscript.UrScriptCfg`) and of the ros2_control goal
    (:class:`~execution.ros2_goal.Ros2GoalCfg`)."""

    SECTION: ClassVar[str] = "export"

    def __post_init__(self) -> None:
        UrScriptCfg.__post_init__(self)
        Ros2GoalCfg.__post_init__(self)
        k = self.SECTION
        if isinstance(self.formats, str):
            _set(self, "formats", tuple(f.strip() for f in self.formats.split(",") if f.strip()))
        if not isinstance(self.formats, (list, tuple)) or not self.formats:
            raise ConfigError(f"{k}.formats must be a non-empty list of {list(EXPORT_FORMATS)}")
        for f in self.formats:
            checks.choice(f, f"{k}.formats", EXPORT_FORMATS)
        _set(self, "formats", tuple(dict.fromkeys(self.formats)))
        checks.choice(self.storage, f"{k}.storage", ("sqlite3", "mcap"))


@dataclass(frozen=True, kw_only=True)
class SimulateCfg(SimCfg):
    """The simulator (:class:`~execution.sim_cfg.SimCfg`) and what fails a run. A run holds
    the goal a little and models the cloud finer than the library's defaults."""

    SECTION: ClassVar[str] = "simulate"
    settle_s: float = 0.2  # s, hold the goal after the trajectory's end
    voxel_m: float = 0.01  # m, the cloud as PyBullet boxes of this size
    enabled: bool = True
    crop_m: float = 0.15  # m, only cloud points this near the moving robot become boxes
    max_tracking_rms_rad: float = 0.01  # rad, a larger RMS tracking error fails the run
    fail_on_contact: bool = False  # a simulated contact fails the run (else a warning)

    def __post_init__(self) -> None:
        super().__post_init__()
        k = self.SECTION
        checks.flag(self.enabled, f"{k}.enabled")
        _set(self, "crop_m", checks.number(self.crop_m, f"{k}.crop_m", lo=0.0, hi=10.0, unit="m"))
        _set(
            self,
            "max_tracking_rms_rad",
            checks.number(
                self.max_tracking_rms_rad,
                f"{k}.max_tracking_rms_rad",
                lo=0.0,
                lo_open=True,
                unit="rad",
            ),
        )
        checks.flag(self.fail_on_contact, f"{k}.fail_on_contact")


@dataclass(frozen=True, kw_only=True)
class ReportCfg:
    SECTION: ClassVar[str] = "report"
    enabled: bool = True
    poses: int = 6  # robot poses drawn along the path
    mcap: bool = True  # run.mcap: the run as one MCAP file for Foxglove

    def __post_init__(self) -> None:
        checks.flag(self.enabled, "report.enabled")
        checks.flag(self.mcap, "report.mcap")
        checks.integer(self.poses, "report.poses", lo=2, hi=20)


SECTIONS: dict[str, type] = {
    "calibration": CalibrationCfg,
    "perception": PerceptionCfg,
    "planning": PlanningCfg,
    "timing": TimingCfg,
    "export": ExportCfg,
    "simulate": SimulateCfg,
    "report": ReportCfg,
}


@dataclass(frozen=True, kw_only=True)
class RunCfg:
    """Everything ``gaide run`` needs; build it with :func:`gaide.pipeline.config_io.load_cfg`."""

    bag: str | None = None  # the recording
    out: str = "out/run"  # output folder
    robot: str | None = None  # robot config YAML (None: the shipped UR5)
    calibration: CalibrationCfg = field(default_factory=CalibrationCfg)
    perception: PerceptionCfg = field(default_factory=PerceptionCfg)
    planning: PlanningCfg = field(default_factory=PlanningCfg)
    timing: TimingCfg = field(default_factory=TimingCfg)
    export: ExportCfg = field(default_factory=ExportCfg)
    simulate: SimulateCfg = field(default_factory=SimulateCfg)
    report: ReportCfg = field(default_factory=ReportCfg)

    def __post_init__(self) -> None:
        _set(self, "bag", checks.text(self.bag, "bag"))
        _set(self, "out", checks.text(self.out, "out", optional=False))
        _set(self, "robot", checks.text(self.robot, "robot"))

    @staticmethod
    def from_dict(raw: dict[str, Any]) -> RunCfg:
        """A RunCfg from a complete mapping (every key of ``run.yaml``)."""
        sections = {}
        for name, cls in SECTIONS.items():
            body = raw.get(name)
            if not isinstance(body, dict):
                raise ConfigError(f"{name} must be a mapping of settings, got {body!r}")
            unknown = sorted(set(body) - {f.name for f in dataclasses.fields(cls)})
            if unknown:
                raise ConfigError(f"{name}: unknown keys {unknown}; valid: {field_names(cls)}")
            try:
                sections[name] = cls(**body)
            except ConfigError:
                raise
            except GaideError as err:  # a library stage's settings: name the section
                raise ConfigError(f"{name}.{err}") from err
        return RunCfg(bag=raw.get("bag"), out=raw.get("out"), robot=raw.get("robot"), **sections)  # type: ignore[arg-type]

    def as_dict(self) -> dict[str, Any]:
        """Plain YAML-ready values, in ``run.yaml``'s order."""

        def plain(v: Any) -> Any:
            if isinstance(v, enum.Enum):
                return v.value
            if dataclasses.is_dataclass(v) and not isinstance(v, type):  # simulate.servo
                return {f.name: plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
            return list(v) if isinstance(v, tuple) else v

        out: dict[str, Any] = {"bag": self.bag, "out": self.out, "robot": self.robot}
        for name in SECTIONS:
            section = getattr(self, name)
            out[name] = {
                f.name: plain(getattr(section, f.name)) for f in dataclasses.fields(section)
            }
        return out


def field_names(cls: type) -> list[str]:
    """The settings of a section, in declaration order."""
    return [f.name for f in dataclasses.fields(cls)]
