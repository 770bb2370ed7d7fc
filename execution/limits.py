"""Per-joint kinematic limits a trajectory must keep: position, velocity, acceleration, jerk.

The robot config supplies them (velocity from the URDF, acceleration and jerk from the config
YAML); :func:`limits_for` applies per-joint overrides and scale factors on top.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from gaide_core.errors import TimingError
from gaide_core.types import Array
from planning.robot_model import RobotModel


def _vector(value: npt.ArrayLike, n: int, what: str, names: Sequence[str]) -> Array:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (n,):
        raise TimingError(
            f"{what} has {arr.size} values; expected {n}, one per joint {list(names)}"
        )
    return arr


@dataclass(frozen=True, kw_only=True)
class JointLimits:
    """Limits of ``len(names)`` joints, each (dof,)."""

    names: tuple[str, ...]
    lower: Array  # rad, position lower limit
    upper: Array  # rad, position upper limit
    velocity: Array  # rad/s, > 0 (symmetric)
    acceleration: Array  # rad/s^2, > 0
    jerk: Array  # rad/s^3, > 0

    def __post_init__(self) -> None:
        n = len(self.names)
        if n == 0:
            raise TimingError("limits need at least one joint")
        for what in ("lower", "upper", "velocity", "acceleration", "jerk"):
            arr = _vector(getattr(self, what), n, f"{what} limits", self.names)
            object.__setattr__(self, what, arr)
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise TimingError(
                    f"{what} limit of joint {self.names[bad[0]]} is {arr[bad[0]]}: limits must "
                    "be finite numbers"
                )
        for what, unit in (("velocity", "rad/s"), ("acceleration", "rad/s^2"), ("jerk", "rad/s^3")):
            arr = getattr(self, what)
            bad = np.flatnonzero(arr <= 0)
            if bad.size:
                raise TimingError(
                    f"{what} limit of joint {self.names[bad[0]]} is {arr[bad[0]]} {unit}: "
                    "limits must be > 0"
                )
        bad = np.flatnonzero(self.lower >= self.upper)
        if bad.size:
            i = int(bad[0])
            raise TimingError(
                f"joint {self.names[i]}: position limits [{self.lower[i]}, {self.upper[i]}] rad "
                "are empty (need lower < upper)"
            )

    @property
    def dof(self) -> int:
        return len(self.names)

    def as_dict(self) -> dict[str, list[float] | list[str]]:
        return {
            "names": list(self.names),
            "lower": self.lower.tolist(),
            "upper": self.upper.tolist(),
            "velocity": self.velocity.tolist(),
            "acceleration": self.acceleration.tolist(),
            "jerk": self.jerk.tolist(),
        }


def limits_for(
    robot: RobotModel,
    *,
    velocity: Sequence[float] | None = None,
    acceleration: Sequence[float] | None = None,
    jerk: Sequence[float] | None = None,
    velocity_scale: float = 1.0,
    acceleration_scale: float = 1.0,
    jerk_scale: float = 1.0,
) -> JointLimits:
    """The robot's limits with optional per-joint overrides (rad/s, rad/s^2, rad/s^3; None
    keeps the robot config's) multiplied by scale factors in (0, 1]."""
    for what, s in (
        ("velocity_scale", velocity_scale),
        ("acceleration_scale", acceleration_scale),
        ("jerk_scale", jerk_scale),
    ):
        if not (np.isfinite(s) and 0 < s <= 1):
            raise TimingError(f"{what} must be in (0, 1], got {s}")
    names = tuple(robot.joint_names)

    def pick(override: Sequence[float] | None, default: Array, what: str) -> Array:
        if override is None:
            return default.astype(float)
        return _vector(override, len(names), f"{what} override", names)

    v = pick(velocity, robot.velocity_limits, "velocity")
    a = pick(acceleration, robot.acceleration_limits, "acceleration")
    j = pick(jerk, robot.jerk_limits, "jerk")
    # Validate the unscaled values first: the message then shows what the user gave.
    JointLimits(
        names=names, lower=robot.lower, upper=robot.upper, velocity=v, acceleration=a, jerk=j
    )
    return JointLimits(
        names=names,
        lower=robot.lower.astype(float),
        upper=robot.upper.astype(float),
        velocity=v * velocity_scale,
        acceleration=a * acceleration_scale,
        jerk=j * jerk_scale,
    )
