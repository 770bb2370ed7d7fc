"""Checks of single settings, for every configuration class of the project.

Each refusal names the key and what is valid, as the caller's stage error (``error``,
ConfigError by default): ``TimingCfg`` refuses with TimingError, a ``gaide run`` section with
ConfigError. Values may come from YAML (so ``1e-3`` can arrive as a string) or from code.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Sequence
from typing import Any

from gaide_core.errors import ConfigError, GaideError


def number(
    value: Any,
    key: str,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    unit: str = "",
    error: type[GaideError] = ConfigError,
) -> float:
    """``value`` as a finite float in [lo, hi] (or (lo, hi] with ``lo_open``)."""
    left = "(" if lo_open else "["
    span = f"{left}{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"
    what = f"a number in {span}{' ' + unit if unit else ''}"
    if isinstance(value, str):  # YAML 1.1 reads 1e-3 (no dot) as a string
        with contextlib.suppress(ValueError):
            value = float(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise error(f"{key} must be {what}, got {value!r}")
    v = float(value)
    ok = math.isfinite(v)
    ok = ok and (lo is None or (v > lo if lo_open else v >= lo))
    ok = ok and (hi is None or v <= hi)
    if not ok:
        raise error(f"{key} must be {what}, got {value!r}")
    return v


def integer(
    value: Any, key: str, *, lo: int, hi: int | None = None, error: type[GaideError] = ConfigError
) -> int:
    """``value`` as an int in [lo, hi]."""
    span = f"[{lo}, {'inf' if hi is None else hi}]"
    if isinstance(value, bool) or not isinstance(value, int):
        raise error(f"{key} must be an integer in {span}, got {value!r}")
    if value < lo or (hi is not None and value > hi):
        raise error(f"{key} must be an integer in {span}, got {value!r}")
    return int(value)


def flag(value: Any, key: str, *, error: type[GaideError] = ConfigError) -> bool:
    if not isinstance(value, bool):
        raise error(f"{key} must be true or false, got {value!r}")
    return value


def choice(
    value: Any, key: str, valid: Sequence[str], *, error: type[GaideError] = ConfigError
) -> str:
    if value not in valid:
        raise error(f"{key} must be one of {list(valid)}, got {value!r}")
    return str(value)


def text(
    value: Any, key: str, *, optional: bool = True, error: type[GaideError] = ConfigError
) -> str | None:
    """A non-empty string (a path, a spec), or None when ``optional``."""
    if value is None and optional:
        return None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = str(value)
    if not isinstance(value, str) or not value.strip():
        what = "a non-empty string" + (" or null" if optional else "")
        raise error(f"{key} must be {what}, got {value!r}")
    return value.strip()


def vector(
    value: Any,
    key: str,
    *,
    length: int | None = None,
    positive: bool = False,
    unit: str = "",
    error: type[GaideError] = ConfigError,
) -> tuple[float, ...] | None:
    """A list of finite numbers (also ``"a,b,c"``), or None. ``length``: exactly that many;
    ``positive``: each > 0."""
    if value is None:
        return None
    if isinstance(value, str):
        try:
            value = [float(v) for v in value.split(",") if v.strip()]
        except ValueError as err:
            raise error(f"{key} must be comma-separated numbers, got {value!r}") from err
    what = "a list of " + (f"{length} " if length else "") + "numbers"
    what += " > 0" if positive else ""
    what += f" ({unit})" if unit else ""
    if not isinstance(value, (list, tuple)) or not value:
        raise error(f"{key} must be {what}, got {value!r}")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise error(f"{key} must be {what}, got {value!r}")
        if positive and v <= 0:
            raise error(f"{key} must be {what}, got {value!r}")
        out.append(float(v))
    if length is not None and len(out) != length:
        raise error(f"{key} must be {what}, got {len(out)} values")
    return tuple(out)


__all__ = ["choice", "flag", "integer", "number", "text", "vector"]
