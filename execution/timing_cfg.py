"""How a path is timed: the controller rate, the mode, the limits' scale factors and overrides."""

from __future__ import annotations

import enum
from dataclasses import dataclass

from gaide_core import settings
from gaide_core.errors import TimingError

# Hz: robot controllers run at 125-1,000 Hz (UR 500, Franka 1,000); a higher rate only makes
# the files and the simulation longer (100 kHz wrote 160 MB and simulated for 10 minutes).
MAX_RATE_HZ = 2_000.0
# Samples of one trajectory: over 2 h at 500 Hz. More is a mistake in the limits or scales.
MAX_SAMPLES = 4_000_000


class TimingMode(enum.Enum):
    """``EXACT``: stop at every waypoint; each segment is a straight joint-space line (Ruckig,
    phase-synchronized, rest to rest), so the trajectory follows the checked path exactly.
    ``BLENDED``: pass through the waypoints without stopping; the swept trajectory is
    re-checked for collision and a colliding blend falls back to exact segments."""

    EXACT = "exact"
    BLENDED = "blended"

    @staticmethod
    def parse(text: str) -> TimingMode:
        try:
            return TimingMode(text)
        except ValueError as err:
            raise TimingError(
                f"unknown timing mode '{text}'; valid: {[m.value for m in TimingMode]}"
            ) from err


@dataclass(frozen=True, kw_only=True)
class TimingCfg:
    """Settings of a time parameterization."""

    rate_hz: float = 500.0  # Hz, controller rate: the trajectory's sample rate
    mode: TimingMode = TimingMode.BLENDED  # or its name, parsed
    velocity_scale: float = 1.0  # (0, 1], multiplies the velocity limits
    acceleration_scale: float = 1.0  # (0, 1], multiplies the acceleration limits
    jerk_scale: float = 1.0  # (0, 1], multiplies the jerk limits
    max_velocity: tuple[float, ...] | None = None  # rad/s per joint; None: robot config
    max_acceleration: tuple[float, ...] | None = None  # rad/s^2 per joint; None: robot config
    max_jerk: tuple[float, ...] | None = None  # rad/s^3 per joint; None: robot config
    shortcut: bool = True  # shorten the path (checked straight edges) before timing it
    blend_levels: int = 8  # waypoint speeds tried per waypoint (blended mode)
    blend_sweeps: int = 2  # passes over the waypoints when choosing their speeds
    blend_retries: int = 2  # halvings of a colliding blend's speeds before it becomes exact

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        put(
            "rate_hz",
            settings.number(
                self.rate_hz, "rate_hz", lo=1.0, hi=MAX_RATE_HZ, unit="Hz", error=TimingError
            ),
        )
        put("mode", self.mode if isinstance(self.mode, TimingMode) else TimingMode.parse(self.mode))
        for name in ("velocity_scale", "acceleration_scale", "jerk_scale"):
            scale = settings.number(
                getattr(self, name), name, lo=0.0, hi=1.0, lo_open=True, error=TimingError
            )
            put(name, scale)
        for name, unit in (
            ("max_velocity", "rad/s"),
            ("max_acceleration", "rad/s^2"),
            ("max_jerk", "rad/s^3"),
        ):
            limits = settings.vector(
                getattr(self, name), name, positive=True, unit=unit, error=TimingError
            )
            put(name, limits)
        settings.flag(self.shortcut, "shortcut", error=TimingError)
        settings.integer(self.blend_levels, "blend_levels", lo=2, error=TimingError)
        settings.integer(self.blend_sweeps, "blend_sweeps", lo=1, error=TimingError)
        settings.integer(self.blend_retries, "blend_retries", lo=0, error=TimingError)

    @property
    def dt(self) -> float:
        """Sample period (s)."""
        return 1.0 / self.rate_hz


def timing_phrase(mode: str | None, fallbacks: int) -> str:
    """How the trajectory passes its waypoints, in words, from its summary's ``mode`` and
    ``fallbacks`` (blended segments that collided and became exact, rest to rest)."""
    if mode != "blended":
        return "stops at every waypoint" if mode == "exact" else str(mode)
    if not fallbacks:
        return "blended through every waypoint"
    return (
        f"blended; {fallbacks} segment{'s' if fallbacks > 1 else ''} stop"
        f"{'' if fallbacks > 1 else 's'} at both ends, where a blend collided"
    )
