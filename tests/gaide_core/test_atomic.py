from __future__ import annotations

import os
from pathlib import Path

import pytest

from gaide_core.atomic import write_bytes_atomic
from gaide_core.errors import TimingError


def test_an_atomic_write_replaces_the_file_with_the_usual_mode(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "out.txt"
    write_bytes_atomic(target, b"old")
    write_bytes_atomic(target, b"new")
    assert target.read_bytes() == b"new"
    umask = os.umask(0)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask
    assert [p.name for p in target.parent.iterdir()] == ["out.txt"]


def test_a_failed_write_raises_the_callers_stage_error(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(TimingError, match="cannot write"):
        write_bytes_atomic(blocker / "out.txt", b"data", TimingError)
