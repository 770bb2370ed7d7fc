"""The task families' names, seed ranges and problem categories, and the parsers of the
lists users give: light to import (the command line shows them in its help), apart from the
generator in :mod:`planning.families`.
"""

from __future__ import annotations

from gaide_core.errors import PlanningError

__all__ = [
    "CATEGORIES",
    "FAMILIES",
    "SEED_RANGES",
    "parse_categories",
    "parse_families",
    "split_seed",
]

FAMILIES = ("tabletop", "box", "bins", "shelf_i", "shelf_ii", "shelf_iii")
SEED_RANGES = {
    "train": (0, 1_000_000),
    "val": (1_000_000, 1_100_000),
    "test": (2_000_000, 2_100_000),
}
# Problem categories by the hand's clearance at each end (tight: under TIGHT_BELOW in
# planning.families).
CATEGORIES = ("free2free", "free2tight", "tight2free", "tight2tight")


def parse_families(text: str) -> list[str]:
    """'all' or a comma-separated list of family names (PlanningError listing valid ones)."""
    return _parse_names(text, FAMILIES, "families")


def parse_categories(text: str) -> list[str]:
    """'all' or a comma-separated list of categories (PlanningError listing valid ones)."""
    return _parse_names(text, CATEGORIES, "categories")


def _parse_names(text: str, valid: tuple[str, ...], what: str) -> list[str]:
    names = (
        list(valid) if text.strip() == "all" else [t.strip() for t in text.split(",") if t.strip()]
    )
    bad = [n for n in names if n not in valid]
    if bad:
        raise PlanningError(f"unknown {what} {bad}; valid: {list(valid)} or 'all'")
    if not names or len(set(names)) != len(names):
        raise PlanningError(f"{what} must be distinct, among {list(valid)} or 'all'; got {text!r}")
    return names


def split_seed(split: str, index: int) -> int:
    """The problem seed of problem ``index`` of ``split`` (train, val or test)."""
    if split not in SEED_RANGES:
        raise PlanningError(f"unknown split '{split}'; valid: {list(SEED_RANGES)}")
    lo, hi = SEED_RANGES[split]
    if not 0 <= index < hi - lo:
        raise PlanningError(
            f"problem index {index} is outside the {split} range (0..{hi - lo - 1})"
        )
    return lo + index
