"""A timed joint trajectory sampled at the controller rate, and how it was made."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from execution.limits import JointLimits
from execution.ruckig_segments import SegmentChain
from execution.timing_cfg import TimingMode
from gaide_core.errors import TimingError
from gaide_core.types import Array


class TimingStatus(enum.Enum):
    SUCCESS = "success"  # every segment as the mode asks
    FELL_BACK = "fell_back"  # blended: some corners' blends collided; those corners stop


@dataclass(frozen=True)
class SegmentInfo:
    """One Ruckig move of the trajectory."""

    kind: str  # "straight": along edge ``index`` (path[index] -> path[index + 1]) on the
    # straight line; "blend": around corner ``index`` (path[index]), off the path, re-checked
    index: int
    start_s: float  # s from the trajectory's start
    duration_s: float  # s

    @property
    def blended(self) -> bool:
        return self.kind == "blend"

    def as_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "index": self.index,
            "start_s": self.start_s,
            "duration_s": self.duration_s,
        }


@dataclass(frozen=True, kw_only=True)
class TimedTrajectory:
    """Samples at ``rate_hz`` from t = 0; the last sample holds the goal at rest.

    ``chain`` is the Ruckig segments themselves (exact states at any time); it is None for
    a trajectory read back from a file, which only has its samples."""

    t: Array  # (N,) s, uniform at rate_hz from 0
    q: Array  # (N, dof) rad
    qd: Array  # (N, dof) rad/s
    qdd: Array  # (N, dof) rad/s^2
    jerk: Array | None = None  # (N, dof) rad/s^3; None when unknown (a file without it)
    joint_names: tuple[str, ...]
    rate_hz: float  # Hz
    mode: TimingMode | None = None  # None: unknown (read from a CSV file)
    status: TimingStatus = TimingStatus.SUCCESS
    path: Array | None = None  # (K, dof) rad, the waypoints timed (after shortcutting)
    segments: tuple[SegmentInfo, ...] = ()
    limits: JointLimits | None = None  # the limits the trajectory keeps
    figures: dict[str, float] = field(default_factory=dict)  # counts and stage times (ms)
    notes: tuple[str, ...] = ()  # what a user should know (fallbacks)
    chain: SegmentChain | None = None

    def __post_init__(self) -> None:
        n, dof = len(self.t), len(self.joint_names)
        if n < 1 or dof < 1:
            raise TimingError(f"a trajectory needs samples and joints, got {n} x {dof}")
        for name in ("q", "qd", "qdd", "jerk"):
            arr = getattr(self, name)
            if arr is None:
                continue
            if arr.shape != (n, dof):
                raise TimingError(f"{name} has shape {arr.shape}; expected ({n}, {dof})")
        if not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise TimingError(f"rate_hz must be > 0, got {self.rate_hz}")

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def duration(self) -> float:
        """Time (s) of the last sample."""
        return float(self.t[-1])

    def summary(self) -> dict[str, Any]:
        """Figures for reports and JSON (no sample arrays)."""
        return {
            "mode": None if self.mode is None else self.mode.value,
            "status": self.status.value,
            "rate_hz": self.rate_hz,
            "duration_s": self.duration,
            "samples": len(self.t),
            "waypoints": 0 if self.path is None else len(self.path),
            "blends": sum(s.blended for s in self.segments),
            **self.figures,
        }
