"""Planner names, as the CLI and the harness spell them, and how to make each planner."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from gaide_core.errors import ConfigError, PlanningError

if TYPE_CHECKING:
    from planning.planner import Planner

CLASSICAL = ("rrtconnect", "rrtstar", "informed_rrtstar", "bitstar", "aorrtc")
# Compiled whole (planning/compiled): RRT-Connect with its shortcut pass.
COMPILED = ("rrtc",)
# Neural planners, paper mode (no fallback), with the repository's shipped weights; and in
# hybrid mode (RRT-Connect for what the network cannot repair): GAIDE, and its ablations for
# Table II in both modes.
NEURAL = ("gaide", "gaide-v", "gaide-h", "mpnet", "simpnet")
HYBRID = ("gaide-hybrid", "gaide-v-hybrid", "gaide-h-hybrid")


def is_neural(name: str) -> bool:
    """Does planner ``name`` load network weights?"""
    return name in NEURAL or name in HYBRID


def planner_names() -> list[str]:
    return [*COMPILED, *CLASSICAL, *NEURAL, *HYBRID]


def make_planner(name: str, *, checkpoint: str | Path | None = None, threads: int = 1) -> Planner:
    """The planner called ``name``. Neural planners (paper mode, or hybrid for the
    ``-hybrid`` names) load ``checkpoint``, by default the shipped weights of their model,
    which it must hold (``gaide-hybrid`` a GAIDE checkpoint, ``mpnet`` an MPNet one), and run
    torch on ``threads`` intra-op threads (0: torch's setting, untouched)."""
    if name not in planner_names():
        raise PlanningError(f"unknown planner '{name}'; valid: {planner_names()}")
    if name in COMPILED or name in CLASSICAL:
        if checkpoint is not None:
            raise ConfigError(
                f"a checkpoint is for the neural planners {[*NEURAL, *HYBRID]}, not {name}"
            )
        if name == "rrtc":
            from planning.rrtc import CompiledRRTConnect

            return CompiledRRTConnect()
        from planning.ompl_planners import OmplPlanner

        return OmplPlanner(name)
    from planning.neural.checkpoint import shipped_checkpoint
    from planning.neural_planner import NeuralPlanner

    kind = name.removesuffix("-hybrid")
    return NeuralPlanner(
        name,
        shipped_checkpoint(kind) if checkpoint is None else checkpoint,
        mode="hybrid" if name in HYBRID else "paper",
        threads=threads,
        kind=kind,
    )


def parse_planners(text: str) -> list[str]:
    names = [t.strip() for t in text.split(",") if t.strip()]
    valid = planner_names()
    bad = [n for n in names if n not in valid]
    if bad or not names:
        raise PlanningError(f"unknown planners {bad or [text]}; valid: {valid}")
    return names
