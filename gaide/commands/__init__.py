"""One module per CLI command group; each exposes ``add_parser(subparsers)``."""

__all__ = [
    "bench",
    "execution",
    "neural",
    "perception",
    "record",
    "robot",
    "run",
    "scenes",
]
