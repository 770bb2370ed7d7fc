"""The project's exceptions: one root, one subclass per stage.

Library errors are translated at the boundary (``raise BagError(msg) from err``) so that a
user sees one kind of error per stage, with a message naming the bad input and what would be
valid. The CLI prints ``str(err)`` on one line and exits with ``err.exit_code``.
"""


class GaideError(Exception):
    """Root of every error the project raises on purpose."""

    #: Process exit code the CLI uses for this stage (distinct per stage).
    exit_code = 1


class ConfigError(GaideError):
    """A configuration file or value is missing, malformed or out of range."""

    exit_code = 2


class BagError(GaideError):
    """A bag cannot be read: not a bag, truncated, or missing a needed topic."""

    exit_code = 3


class CalibrationError(GaideError):
    """Camera-to-base calibration failed (no target, degenerate motion, ...)."""

    exit_code = 4


class PerceptionError(GaideError):
    """A point cloud could not be built (no valid depth, empty after cropping, ...)."""

    exit_code = 5


class RobotModelError(GaideError):
    """The robot description or a joint vector is invalid (URDF, mesh, frame, limits)."""

    exit_code = 6


class PlanningError(GaideError):
    """Planning could not run or found no path (start/goal invalid, timeout, ...)."""

    exit_code = 7


class TimingError(GaideError):
    """Time parameterization failed (bad path, bad limits, colliding edge)."""

    exit_code = 8


class ExecutionError(GaideError):
    """Export, simulation or log comparison failed."""

    exit_code = 9


class ModelError(GaideError):
    """A network checkpoint, its training data or a model setting: missing, corrupt, for
    another robot or model kind, or out of range."""

    exit_code = 10
