"""Reading the text files users give (settings, poses, calibrations, robot configs) safely.

Every reader refuses, with the caller's exception naming the file: a file larger than a limit
(before reading it), bytes that are not UTF-8 text (a binary file given by mistake), and YAML
whose aliases expand past a limit (a "billion laughs" file: nine levels of ten aliases build
10^9 values from a few hundred bytes). YAML is only ever read with the safe loader (libyaml's
C one when it is installed).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import yaml

from core.errors import GaideError

#: Largest text file read (bytes): settings and calibrations are a few kB.
MAX_TEXT_BYTES = 16 * 1024 * 1024
#: Largest number of values a YAML document may expand to, aliases counted at each use.
MAX_YAML_VALUES = 2_000_000

_Loader: type[Any] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def read_text(
    path: str | os.PathLike[str],
    what: str,
    error: type[GaideError],
    *,
    max_bytes: int = MAX_TEXT_BYTES,
) -> str:
    """The UTF-8 text of ``path`` (``what`` names it in errors: "robot config")."""
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > max_bytes:
            raise error(
                f"{what} {p} is {size:,} bytes; the largest accepted is {max_bytes:,} (is it the "
                "right file?)"
            )
        data = p.read_bytes()
    except FileNotFoundError as err:
        raise error(f"{what} {p} does not exist") from err
    except IsADirectoryError as err:
        raise error(f"{what} {p} is a folder, not a file") from err
    except OSError as err:
        raise error(f"{what} {p} cannot be read: {err.strerror or err}") from err
    if b"\x00" in data:
        raise error(f"{what} {p} is a binary file, not text (YAML or JSON expected)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise error(
            f"{what} {p} is not UTF-8 text (byte {err.start}: {data[err.start : err.start + 1]!r})"
        ) from err


def parse_yaml(text: str, where: str, error: type[GaideError]) -> Any:
    """The YAML document in ``text`` (``where`` names it in errors), with the alias limit."""
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        values = _expanded_size(node, {}, set())
        if values > MAX_YAML_VALUES:
            raise error(
                f"{where}: its aliases expand to more than {MAX_YAML_VALUES:,} values; refused "
                "(a YAML alias bomb?)"
            )
        return loader.construct_document(node)
    except yaml.YAMLError as err:
        raise error(f"{where} is not valid YAML: {err}") from err
    except RecursionError as err:
        raise error(f"{where}: nested too deeply to read") from err
    finally:
        loader.dispose()


def load_yaml(
    path: str | os.PathLike[str],
    what: str,
    error: type[GaideError],
    *,
    max_bytes: int = MAX_TEXT_BYTES,
) -> Any:
    """The YAML document in the file ``path`` (see :func:`read_text`, :func:`parse_yaml`)."""
    return parse_yaml(read_text(path, what, error, max_bytes=max_bytes), f"{what} {path}", error)


def load_json(
    path: str | os.PathLike[str],
    what: str,
    error: type[GaideError],
    *,
    max_bytes: int = MAX_TEXT_BYTES,
) -> Any:
    """The JSON document in the file ``path`` (see :func:`read_text`)."""
    text = read_text(path, what, error, max_bytes=max_bytes)
    try:
        return json.loads(text)
    except ValueError as err:
        raise error(f"{what} {path} is not valid JSON: {err}") from err


def _expanded_size(node: yaml.Node, sizes: dict[int, int], active: set[int]) -> int:
    """How many values ``node`` becomes once every alias is expanded (each use counted)."""
    key = id(node)
    if key in sizes:
        return sizes[key]
    if key in active:
        raise yaml.YAMLError("an alias refers to a node that contains it (a cycle)")
    active.add(key)
    total = 1
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            total += _expanded_size(k, sizes, active) + _expanded_size(v, sizes, active)
            if total > MAX_YAML_VALUES:
                break
    elif isinstance(node, yaml.SequenceNode):
        for v in node.value:
            total += _expanded_size(v, sizes, active)
            if total > MAX_YAML_VALUES:
                break
    active.discard(key)
    sizes[key] = total
    return total
