"""Dependency-free foundation shared by every stage: the exception tree and rigid transforms.

Nothing here imports another package of the project; every stage may import it.
"""

from gaide_core.errors import (
    BagError,
    CalibrationError,
    ConfigError,
    ExecutionError,
    GaideError,
    PerceptionError,
    PlanningError,
    RobotModelError,
    TimingError,
)

__all__ = [
    "BagError",
    "CalibrationError",
    "ConfigError",
    "ExecutionError",
    "GaideError",
    "PerceptionError",
    "PlanningError",
    "RobotModelError",
    "TimingError",
]
