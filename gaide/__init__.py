"""Command line and end-to-end wiring of the GAIDE stack. No stage package imports this."""

__all__ = [
    "bench_detector",
    "bench_perception",
    "cli",
    "commands",
    "common",
    "demo",
    "flows",
    "pictures",
    "pipeline",
    "scene_spec",
    "synthetic",
]
