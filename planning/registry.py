"""Planner names, as the CLI and the harness spell them, and how to make each planner."""

from __future__ import annotations

from collections.abc import Callable

from core.errors import PlanningError
from planning.planner import Planner

CLASSICAL = ("rrtconnect", "rrtstar", "informed_rrtstar", "bitstar", "aorrtc")
# Neural planners, paper mode (no fallback), with the repository's shipped weights; and in
# hybrid mode (RRT-Connect for what the network cannot repair): GAIDE, and its ablations for
# Table II in both modes.
NEURAL = ("gaide", "gaide-v", "gaide-h", "mpnet", "simpnet")
HYBRID = ("gaide-hybrid", "gaide-v-hybrid", "gaide-h-hybrid")


def _factories() -> dict[str, Callable[[], Planner]]:
    from planning.neural.checkpoint import shipped_checkpoint
    from planning.neural_planner import NeuralPlanner
    from planning.ompl_planners import OmplPlanner

    out: dict[str, Callable[[], Planner]] = {}
    for name in CLASSICAL:
        out[name] = lambda name=name: OmplPlanner(name)  # type: ignore[misc]
    for name in NEURAL:
        out[name] = lambda name=name: NeuralPlanner(name, shipped_checkpoint(name))  # type: ignore[misc]
    for name in HYBRID:
        kind = name.removesuffix("-hybrid")
        out[name] = lambda name=name, kind=kind: NeuralPlanner(  # type: ignore[misc]
            name, shipped_checkpoint(kind), mode="hybrid"
        )
    return out


def planner_names() -> list[str]:
    return list(_factories())


def make_planner(name: str) -> Planner:
    factories = _factories()
    if name not in factories:
        raise PlanningError(f"unknown planner '{name}'; valid: {list(factories)}")
    return factories[name]()


def parse_planners(text: str) -> list[str]:
    names = [t.strip() for t in text.split(",") if t.strip()]
    valid = planner_names()
    bad = [n for n in names if n not in valid]
    if bad or not names:
        raise PlanningError(f"unknown planners {bad or [text]}; valid: {valid}")
    return names
