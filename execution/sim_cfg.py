"""How the simulator tracks a trajectory: the controller (a servo model of a real arm, or
PyBullet's ideal position motor), gravity, the hold at the end, and the size of the boxes a
point-cloud scene becomes.

Its own module, light to import: ``gaide simulate`` shows these defaults in its help, and
``gaide run``'s simulate section extends it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields

from execution.servo import ServoCfg
from gaide_core import settings
from gaide_core.errors import ExecutionError

#: ``servo``: :mod:`execution.servo`'s model of a real arm controller (delay, limits, PD
#: torques, encoder noise); ``ideal``: PyBullet's position motor with velocity feed-forward
#: at the trajectory's rate (tracks to ~1e-6 rad: a bound on what the physics allows).
CONTROLLERS = ("servo", "ideal")


@dataclass(frozen=True, kw_only=True)
class SimCfg:
    """Settings of :func:`execution.simulate.simulate`."""

    position_gain: float = 1.0  # ideal: PyBullet positionGain of the joint motors, in (0, 1]
    velocity_gain: float = 1.0  # ideal: PyBullet velocityGain (feed-forward weight), in [0, 1]
    settle_s: float = 0.0  # s, extra time holding the last sample (logged too)
    gravity: bool = True
    voxel_m: float = 0.02  # m, box size when the scene is a point cloud
    controller: str = "servo"  # servo | ideal (CONTROLLERS)
    # The servo model's settings (a mapping of ServoCfg's fields is accepted, as YAML gives).
    servo: ServoCfg = field(default_factory=ServoCfg)

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        err = ExecutionError
        put(
            "position_gain",
            settings.number(
                self.position_gain, "position_gain", lo=0.0, hi=1.0, lo_open=True, error=err
            ),
        )
        put(
            "velocity_gain",
            settings.number(self.velocity_gain, "velocity_gain", lo=0.0, hi=1.0, error=err),
        )
        put(
            "settle_s",
            settings.number(self.settle_s, "settle_s", lo=0.0, hi=60.0, unit="s", error=err),
        )
        settings.flag(self.gravity, "gravity", error=err)
        put(
            "voxel_m",
            settings.number(self.voxel_m, "voxel_m", lo=0.005, hi=0.2, unit="m", error=err),
        )
        settings.choice(self.controller, "controller", CONTROLLERS, error=err)
        put("servo", _servo_cfg(self.servo))


def _servo_cfg(value: object) -> ServoCfg:
    """``value`` as a ServoCfg: one already, or a mapping of its fields."""
    if isinstance(value, ServoCfg):
        return value
    valid = [f.name for f in fields(ServoCfg)]
    if not isinstance(value, Mapping):
        raise ExecutionError(f"servo must be a mapping of settings {valid}, got {value!r}")
    unknown = sorted(str(k) for k in value if k not in valid)
    if unknown:
        raise ExecutionError(f"servo: unknown keys {unknown}; valid: {valid}")
    return ServoCfg(**{str(k): v for k, v in value.items()})


__all__ = ["CONTROLLERS", "SimCfg"]
