"""How the simulator tracks a trajectory: controller gains, gravity, the hold at the end, and
the size of the boxes a point-cloud scene becomes.

Its own module, light to import: ``gaide simulate`` shows these defaults in its help, and
``gaide run``'s simulate section extends it.
"""

from __future__ import annotations

from dataclasses import dataclass

from gaide_core import settings
from gaide_core.errors import ExecutionError


@dataclass(frozen=True, kw_only=True)
class SimCfg:
    """Settings of :func:`execution.simulate.simulate`."""

    position_gain: float = 1.0  # PyBullet positionGain of the joint motors, in (0, 1]
    velocity_gain: float = 1.0  # PyBullet velocityGain (feed-forward weight), in [0, 1]
    settle_s: float = 0.0  # s, extra time holding the last sample (logged too)
    gravity: bool = True
    voxel_m: float = 0.02  # m, box size when the scene is a point cloud

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


__all__ = ["SimCfg"]
