"""The settings of one ``gaide run``: frozen sections, each value checked on construction.

The defaults live in one place, ``gaide/data/run.yaml`` (commented, every key present); the
dataclasses here have no defaults of their own, so the file and the code cannot drift.
:mod:`gaide.pipeline.config_io` merges defaults < a user's file < flags and builds a
:class:`RunCfg`. Units: m, rad, s; poses in the robot's base frame.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

from execution.timing_cfg import MAX_RATE_HZ, TimingCfg, TimingMode
from gaide.pipeline import checks
from gaide_core.errors import ConfigError
from planning.checker import CHECKERS
from planning.registry import CLASSICAL, COMPILED, HYBRID, NEURAL

# auto: gaide-hybrid when its weights fit the robot, else the compiled RRT-Connect.
PLANNERS = ("auto", *COMPILED, *CLASSICAL, *NEURAL, *HYBRID)
EXPORT_FORMATS = ("csv", "json", "bag", "ros2")


def _set(obj: object, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)


@dataclass(frozen=True, kw_only=True)
class CalibrationCfg:
    """Where ``T_base_cam`` comes from: a calibration file, a given pose, or the bag."""

    SECTION: ClassVar[str] = "calibration"
    calib: str | None  # calibration YAML from `gaide calibrate`
    T_base_cam: tuple[float, ...] | None  # x, y, z (m), qx, qy, qz, qw: color camera in base
    mode: str  # fixed | hand-eye
    target_pose: str | None  # fixed: target + its pose YAML (None: beside the bag)
    target: str | None  # hand-eye: target spec
    max_frames: int | None  # color frames used at most

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
class PerceptionCfg:
    """The scene cloud: crop box, depth range, downsampling, self-filter."""

    SECTION: ClassVar[str] = "perception"
    voxel: float  # m
    workspace_min: tuple[float, ...]  # m, base frame
    workspace_max: tuple[float, ...]  # m, base frame
    min_depth: float  # m
    max_depth: float  # m
    max_frames: int
    self_filter: bool
    joints: tuple[float, ...] | None  # rad, for the self-filter when the bag has none
    default_extrinsics: bool  # a bag without depth-to-color extrinsics: assume the identity

    def __post_init__(self) -> None:
        k = self.SECTION
        _set(self, "voxel", checks.number(self.voxel, f"{k}.voxel", lo=0.0, hi=0.2, unit="m"))
        lo = checks.vector(self.workspace_min, f"{k}.workspace_min", length=3, unit="m")
        hi = checks.vector(self.workspace_max, f"{k}.workspace_max", length=3, unit="m")
        if lo is None or hi is None:
            raise ConfigError(f"{k}.workspace_min and {k}.workspace_max need 3 numbers each (m)")
        if any(a >= b for a, b in zip(lo, hi, strict=True)):
            raise ConfigError(
                f"{k}.workspace_min {list(lo)} must be below {k}.workspace_max {list(hi)} on "
                "every axis"
            )
        _set(self, "workspace_min", lo)
        _set(self, "workspace_max", hi)
        _set(
            self,
            "min_depth",
            checks.number(self.min_depth, f"{k}.min_depth", lo=0.0, lo_open=True, unit="m"),
        )
        _set(
            self,
            "max_depth",
            checks.number(
                self.max_depth, f"{k}.max_depth", lo=self.min_depth, lo_open=True, unit="m"
            ),
        )
        checks.integer(self.max_frames, f"{k}.max_frames", lo=1)
        checks.flag(self.self_filter, f"{k}.self_filter")
        checks.flag(self.default_extrinsics, f"{k}.default_extrinsics")
        _set(self, "joints", checks.vector(self.joints, f"{k}.joints", unit="rad"))


@dataclass(frozen=True, kw_only=True)
class PlanningCfg:
    """Start, goal and the planner (see ``run.yaml`` for the endpoint forms)."""

    SECTION: ClassVar[str] = "planning"
    start: str
    goal: str | None
    planner: str
    checkpoint: str | None
    budget_s: float  # s per attempt
    attempts: int
    seed: int
    ik_restarts: int
    world_voxel: float  # m
    torch_threads: int  # CPU threads for the network while planning; 0: torch's default
    checker: str  # collision checker backend: compiled | numpy

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
class TimingSection:
    """Time parameterization, checked as configuration keys (:meth:`timing_cfg` gives the
    execution layer's :class:`~execution.timing_cfg.TimingCfg`)."""

    SECTION: ClassVar[str] = "timing"
    mode: str  # blended | exact
    rate_hz: float  # Hz
    velocity_scale: float
    acceleration_scale: float
    jerk_scale: float
    max_velocity: tuple[float, ...] | None  # rad/s per joint
    max_acceleration: tuple[float, ...] | None  # rad/s^2 per joint
    max_jerk: tuple[float, ...] | None  # rad/s^3 per joint
    shortcut: bool

    def __post_init__(self) -> None:
        k = self.SECTION
        checks.choice(self.mode, f"{k}.mode", ("blended", "exact"))
        _set(
            self,
            "rate_hz",
            checks.number(self.rate_hz, f"{k}.rate_hz", lo=1.0, hi=MAX_RATE_HZ, unit="Hz"),
        )
        for name in ("velocity_scale", "acceleration_scale", "jerk_scale"):
            scale = checks.number(getattr(self, name), f"{k}.{name}", lo=0.0, hi=1.0, lo_open=True)
            _set(self, name, scale)
        for name, unit in (
            ("max_velocity", "rad/s"),
            ("max_acceleration", "rad/s^2"),
            ("max_jerk", "rad/s^3"),
        ):
            value = checks.vector(getattr(self, name), f"{k}.{name}", positive=True, unit=unit)
            _set(self, name, value)
        checks.flag(self.shortcut, f"{k}.shortcut")

    def timing_cfg(self) -> TimingCfg:
        """The execution layer's settings, field for field (the blend search at its
        defaults)."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        return TimingCfg(**{**fields, "mode": TimingMode.parse(self.mode)})


@dataclass(frozen=True, kw_only=True)
class ExportCfg:
    SECTION: ClassVar[str] = "export"
    formats: tuple[str, ...]  # of EXPORT_FORMATS
    storage: str  # ROS2 bag storage

    def __post_init__(self) -> None:
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
class SimulateCfg:
    SECTION: ClassVar[str] = "simulate"
    enabled: bool
    settle_s: float  # s
    voxel_m: float  # m
    crop_m: float  # m
    max_tracking_rms_rad: float  # rad
    fail_on_contact: bool

    def __post_init__(self) -> None:
        k = self.SECTION
        checks.flag(self.enabled, f"{k}.enabled")
        _set(
            self,
            "settle_s",
            checks.number(self.settle_s, f"{k}.settle_s", lo=0.0, hi=60.0, unit="s"),
        )
        _set(
            self, "voxel_m", checks.number(self.voxel_m, f"{k}.voxel_m", lo=0.005, hi=0.2, unit="m")
        )
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
    enabled: bool
    poses: int  # robot poses drawn along the path

    def __post_init__(self) -> None:
        checks.flag(self.enabled, "report.enabled")
        checks.integer(self.poses, "report.poses", lo=2, hi=20)


SECTIONS: dict[str, type] = {
    "calibration": CalibrationCfg,
    "perception": PerceptionCfg,
    "planning": PlanningCfg,
    "timing": TimingSection,
    "export": ExportCfg,
    "simulate": SimulateCfg,
    "report": ReportCfg,
}


@dataclass(frozen=True, kw_only=True)
class RunCfg:
    """Everything ``gaide run`` needs; build it with :func:`gaide.pipeline.config_io.load_cfg`."""

    bag: str | None  # the recording
    out: str  # output folder
    robot: str | None  # robot config YAML (None: the shipped UR5)
    calibration: CalibrationCfg
    perception: PerceptionCfg
    planning: PlanningCfg
    timing: TimingSection
    export: ExportCfg
    simulate: SimulateCfg
    report: ReportCfg

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
            try:
                sections[name] = cls(**body)
            except TypeError as err:  # a key missing: only when built outside config_io
                raise ConfigError(f"{name}: {err}") from err
        return RunCfg(bag=raw.get("bag"), out=raw.get("out"), robot=raw.get("robot"), **sections)  # type: ignore[arg-type]

    def as_dict(self) -> dict[str, Any]:
        """Plain YAML-ready values, in ``run.yaml``'s order."""

        def plain(v: Any) -> Any:
            return list(v) if isinstance(v, tuple) else v

        out: dict[str, Any] = {"bag": self.bag, "out": self.out, "robot": self.robot}
        for name in SECTIONS:
            section = getattr(self, name)
            out[name] = {
                f.name: plain(getattr(section, f.name)) for f in dataclasses.fields(section)
            }
        return out
