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

from gaide_core.errors import GaideError

#: Largest text file read (bytes): settings and calibrations are a few kB.
MAX_TEXT_BYTES = 16 * 1024 * 1024
#: YAML nesting levels (a problem file needs 7), aliases, and nodes the aliases add.
MAX_YAML_DEPTH = 32
MAX_YAML_ALIASES = 10_000
MAX_YAML_ALIAS_NODES = 1_000_000

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
    """The YAML document in ``text`` (``where`` names it in errors: "config file x.yaml"),
    after :func:`check_yaml_structure`; every error is one line."""
    try:
        check_yaml_structure(text, where, error)
        return yaml.load(text, Loader=_Loader)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        at = "" if mark is None else f"line {mark.line + 1}, column {mark.column + 1}"
        what = " ".join(s for s in (err.context, err.problem) if s)
        if "nesting depth" in what:
            # libyaml's own limit (PyYAML 6.0.4's bundled libyaml) can fire before ours: its
            # scanner reads ahead of the events check_yaml_structure counts.
            raise error(f"{where} nests deeper than {MAX_YAML_DEPTH} levels ({at})") from err
        at = f"{at}: " if at else ""
        raise error(f"{where} is not valid YAML: {at}{one_line(what)}") from err
    except (yaml.YAMLError, ValueError, OverflowError) as err:  # e.g. a date out of range
        raise error(f"{where} is not valid YAML: {one_line(err)}") from err


def check_yaml_structure(text: str, where: str, error: type[GaideError]) -> None:
    """``error`` for YAML nested deeper than :data:`MAX_YAML_DEPTH` (libyaml's composer
    recurses on the C stack: 100,000 nested ``[`` crash the interpreter), or whose aliases
    exceed :data:`MAX_YAML_ALIASES` or add more than :data:`MAX_YAML_ALIAS_NODES` nodes once
    expanded (an alias bomb), judged from the parser's events before anything is built."""
    expanded: dict[str, int] = {}  # anchor -> nodes of its node, aliases expanded
    open_: list[list[Any]] = []  # collections being read: [anchor, nodes so far]
    aliases = added = 0
    for event in yaml.parse(text, Loader=_Loader):  # a safe loader
        if isinstance(event, yaml.ScalarEvent):
            anchor, n = event.anchor, 1
        elif isinstance(event, yaml.CollectionStartEvent):
            open_.append([event.anchor, 1])
            if len(open_) > MAX_YAML_DEPTH:
                raise error(f"{where} nests deeper than {MAX_YAML_DEPTH} levels ({_at(event)})")
            continue
        elif isinstance(event, yaml.CollectionEndEvent):
            anchor, n = open_.pop()
        elif isinstance(event, yaml.AliasEvent):
            aliases += 1
            if aliases > MAX_YAML_ALIASES:
                raise error(f"{where} has more than {MAX_YAML_ALIASES} YAML aliases ({_at(event)})")
            got = expanded.get(event.anchor or "")
            if got is None:
                raise error(
                    f"{where}: alias *{event.anchor} ({_at(event)}) names no anchor before it, "
                    "or one that contains it (a cycle)"
                )
            anchor, n = None, got
            added += got
            if added > MAX_YAML_ALIAS_NODES:
                raise error(
                    f"{where}: its YAML aliases expand to more than {MAX_YAML_ALIAS_NODES:,} "
                    f"nodes ({_at(event)}; an alias bomb?); write the values out"
                )
        else:  # stream and document events
            continue
        if anchor is not None:
            expanded[anchor] = n
        if open_:
            open_[-1][1] += n


def one_line(err: object) -> str:
    """``err``'s text on one line (library messages span several)."""
    return " ".join(str(err).split())


def _at(event: yaml.Event) -> str:
    mark = event.start_mark
    return "line ?" if mark is None else f"line {mark.line + 1}"


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
    except json.JSONDecodeError as err:
        raise error(
            f"{what} {path} is not valid JSON: line {err.lineno}, column {err.colno}: {err.msg}"
        ) from err
    except (ValueError, RecursionError) as err:  # too many digits, nested too deep
        raise error(f"{what} {path} is not valid JSON: {one_line(err)}") from err
