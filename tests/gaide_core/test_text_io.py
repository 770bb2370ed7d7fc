from __future__ import annotations

from pathlib import Path

import pytest

from gaide_core.errors import ConfigError
from gaide_core.text_io import MAX_YAML_ALIAS_NODES, load_json, load_yaml, parse_yaml, read_text

BILLION_LAUGHS = "\n".join(
    ["a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    + [f"{chr(98 + k)}: &{chr(98 + k)} [{', '.join([f'*{chr(97 + k)}'] * 9)}]" for k in range(8)]
)


def test_yaml_reads_as_the_safe_loader_does(tmp_path: Path) -> None:
    f = tmp_path / "ok.yaml"
    f.write_text("a: [1, 2.5, x]\nb: {c: true}\nd: &d [1, 2]\ne: *d\n")
    assert load_yaml(f, "settings", ConfigError) == {
        "a": [1, 2.5, "x"], "b": {"c": True}, "d": [1, 2], "e": [1, 2],
    }  # fmt: skip
    assert parse_yaml("", "empty", ConfigError) is None


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "is a binary file"),
        (b"a: caf\xe9\n", "is not UTF-8 text (byte 6"),
        (BILLION_LAUGHS.encode(), f"more than {MAX_YAML_ALIAS_NODES:,} nodes"),
        (b"a: &a [*a]\n", "cycle"),
        (b"a: " + b"[" * 100_000, "nests deeper than 32 levels"),
        (b"a: [1, 2\n", "is not valid YAML"),
        (b"!!python/object/apply:os.system ['echo hi']\n", "is not valid YAML"),
    ],
    ids=["binary", "latin-1", "alias-bomb", "alias-cycle", "deep", "syntax", "python-tag"],
)
def test_bad_files_are_one_error_naming_the_file(
    tmp_path: Path, content: bytes, message: str
) -> None:
    f = tmp_path / "bad.yaml"
    f.write_bytes(content)
    with pytest.raises(ConfigError) as err:
        load_yaml(f, "config file", ConfigError)
    assert message in str(err.value) and str(f) in str(err.value)
    assert "\n" not in str(err.value)


def test_size_limit_missing_file_and_folder(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    big.write_text("a: 1\n" * 100)
    with pytest.raises(ConfigError, match="is 500 bytes; the largest accepted is 100"):
        read_text(big, "config file", ConfigError, max_bytes=100)
    with pytest.raises(ConfigError, match="does not exist"):
        load_yaml(tmp_path / "none.yaml", "config file", ConfigError)
    with pytest.raises(ConfigError, match="is a folder"):
        load_json(tmp_path, "path file", ConfigError)
    (tmp_path / "bad.json").write_text("{1: 2}")
    with pytest.raises(ConfigError, match="is not valid JSON"):
        load_json(tmp_path / "bad.json", "path file", ConfigError)
