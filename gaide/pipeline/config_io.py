"""Settings in layers: the shipped defaults < YAML files < ``KEY=VALUE`` overrides.

Every layer may set only keys the defaults have (a typo is refused with the valid keys).
Input paths in a file (the bag, the robot config, a calibration, a target pose, a
checkpoint) are relative to that file's folder; paths given as overrides are used as given
(relative to the working directory), and so is ``out`` everywhere.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import yaml

from gaide.pipeline.config import RunCfg
from gaide_core.errors import ConfigError
from gaide_core.text_io import load_yaml, parse_yaml
from planning.robot_names import shipped_robots

DATA = Path(__file__).resolve().parents[1] / "data"
DEFAULTS = DATA / "run.yaml"
#: Keys holding input paths, resolved against the folder of the file that sets them.
PATH_KEYS = (
    "bag",
    "robot",
    "calibration.calib",
    "calibration.target_pose",
    "perception.bag_robot",
    "planning.checkpoint",
)
#: Of those, the keys that also take a shipped robot's name (``panda``).
ROBOT_KEYS = ("robot", "perception.bag_robot")


def read_yaml(path: str | Path) -> dict[str, Any]:
    """A YAML file holding a mapping (ConfigError naming the file otherwise)."""
    source = Path(path)
    raw = load_yaml(source, "config file", ConfigError)
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise ConfigError(f"config file {source} must hold a mapping of settings (see run.yaml)")
    return raw


def default_dict() -> dict[str, Any]:
    """Every setting at its default (the config classes'; ``run.yaml`` documents them)."""
    return RunCfg().as_dict()


def merge(base: dict[str, Any], layer: dict[str, Any], where: str) -> dict[str, Any]:
    """``base`` with ``layer``'s values, key by key; a key ``base`` lacks is refused."""
    out = copy.deepcopy(base)

    def walk(dst: dict[str, Any], src: dict[str, Any], prefix: str) -> None:
        for key, value in src.items():
            dotted = f"{prefix}{key}"
            if key not in dst:
                raise ConfigError(
                    f"{where}: unknown key '{dotted}'; valid keys"
                    f"{' in ' + prefix.rstrip('.') if prefix else ''}: {sorted(dst)}"
                )
            if isinstance(dst[key], dict):
                if not isinstance(value, dict):
                    raise ConfigError(f"{where}: '{dotted}' must be a mapping of settings")
                walk(dst[key], value, dotted + ".")
            else:
                dst[key] = copy.deepcopy(value)

    walk(out, layer, "")
    return out


def nest(dotted: str, value: Any) -> dict[str, Any]:
    """``{"a": {"b": value}}`` for ``"a.b"``."""
    parts = [p for p in dotted.strip().split(".") if p]
    if not parts:
        raise ConfigError(f"empty setting name in '{dotted}'")
    out: dict[str, Any] = {parts[-1]: value}
    for p in reversed(parts[:-1]):
        out = {p: out}
    return out


def parse_assignment(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` with a dotted key and a YAML value (``planning.budget_s=5``,
    ``perception.workspace_max=[1,1,1]``)."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set '{text}': give KEY=VALUE, e.g. planning.budget_s=5")
    return key.strip(), parse_yaml(value, f"--set '{text}': the value", ConfigError)


def _get(raw: dict[str, Any], dotted: str) -> Any:
    node: Any = raw
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def _resolve_paths(layer: dict[str, Any], folder: Path) -> dict[str, Any]:
    out = copy.deepcopy(layer)
    for dotted in PATH_KEYS:
        value = _get(out, dotted)
        if isinstance(value, str) and value and not Path(value).expanduser().is_absolute():
            here = folder / value
            if dotted in ROBOT_KEYS and not here.exists() and value in shipped_robots():
                continue  # a shipped robot's name, not a file beside the settings
            out = merge_loose(out, nest(dotted, str(here)))
    return out


def merge_loose(base: dict[str, Any], layer: dict[str, Any]) -> dict[str, Any]:
    """Deep merge without key checks (for building layers)."""
    out = copy.deepcopy(base)
    for key, value in layer.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge_loose(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def effective_dict(
    files: Sequence[str | Path] = (),
    overrides: Iterable[tuple[str, Any]] = (),
) -> dict[str, Any]:
    """The merged settings: defaults, then each file, then each override in order."""
    raw = default_dict()
    for f in files:
        layer = _resolve_paths(read_yaml(f), Path(f).resolve().parent)
        raw = merge(raw, layer, str(f))
    for key, value in overrides:
        raw = merge(raw, nest(key, value), f"setting '{key}'")
    return raw


def load_cfg(
    files: Sequence[str | Path] = (),
    overrides: Iterable[tuple[str, Any]] = (),
) -> RunCfg:
    """The effective, checked settings (ConfigError naming the key otherwise)."""
    return RunCfg.from_dict(effective_dict(files, overrides))


class _Dumper(yaml.SafeDumper):
    """Block mappings, lists of scalars on one line (as ``run.yaml`` writes them)."""


def _list(dumper: yaml.SafeDumper, data: list[Any]) -> yaml.Node:
    flow = all(not isinstance(v, (list, dict)) for v in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_Dumper.add_representer(list, _list)


def dump_cfg(cfg: RunCfg) -> str:
    """The settings as YAML, in ``run.yaml``'s order (what ``gaide config show`` prints)."""
    return yaml.dump(cfg.as_dict(), Dumper=_Dumper, sort_keys=False, default_flow_style=False)
