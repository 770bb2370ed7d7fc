"""Stage flows that join packages (bag -> calibration, bag -> cloud): used by the CLI commands
and by the end-to-end pipeline."""

__all__ = [
    "calibrate",
    "perceive",
]
