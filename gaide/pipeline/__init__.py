"""``gaide run``: the end-to-end pipeline, bag -> calibration -> cloud -> plan -> timing ->
exports -> simulation -> report, one stage per module, with its configuration, output folder
rules and summary."""

__all__ = [
    "config",
    "config_io",
    "endpoints",
    "execute",
    "figures",
    "motion",
    "report",
    "run",
    "run_mcap",
    "runner",
    "scene3d",
    "sense",
    "summary",
]
