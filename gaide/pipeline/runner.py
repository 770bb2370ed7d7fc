"""Runs the stages of a pipeline one after the other, recording each one's outputs, time and
figures, and keeping the output folder consistent.

- A stage's files are written together at its end (:meth:`StageRunner.commit`): each to a
  temporary sibling, then all renamed into place; a failure leaves none of them.
- ``summary.json`` is rewritten (atomically) after every stage and every commit, so a failed
  run still says which stages succeeded, what they wrote, and which stage failed and why.
  Its ``status`` is ``running`` until the run ends (``success`` or ``failed``): a run that
  was killed reads as unfinished. It lists every file the run wrote, which is how the next
  run into the folder knows what it may replace (:func:`claim_folder`).
- One run at a time per folder: a lock file (``.gaide-run.lock``, holding the process id)
  refuses a second run while the first one lives.
- A stage's failure is re-raised as that stage's exception (its exit code) with the stage's
  name in front of the message: ``planning: start is in collision ...``. Errors about
  settings, the bag file and model weights keep their own class (and code): they name the
  input to fix, whichever stage met them.
"""

from __future__ import annotations

import contextlib
import enum
import json
import math
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from gaide_core.atomic import Content, write_bytes_atomic, write_files_atomic
from gaide_core.errors import (
    BagError,
    CalibrationError,
    ConfigError,
    ExecutionError,
    GaideError,
    ModelError,
    PerceptionError,
    PlanningError,
    RobotModelError,
    TimingError,
)

#: The exception (and so the exit code) of each stage.
STAGE_ERRORS: dict[str, type[GaideError]] = {
    "setup": RobotModelError,  # the robot model and what depends on it
    "calibration": CalibrationError,
    "perception": PerceptionError,
    "planning": PlanningError,
    "timing": TimingError,
    "export": ExecutionError,
    "simulation": ExecutionError,
    "report": ExecutionError,
}
#: Errors that keep their class whichever stage raised them.
OWN_CODE: tuple[type[GaideError], ...] = (ConfigError, BagError, ModelError)


class StageStatus(enum.Enum):
    SUCCESS = "success"
    FAILED = "failed"
    SKIPPED = "skipped"  # switched off, or not needed (e.g. a calibration was given)
    NOT_RUN = "not_run"  # an earlier stage failed


@dataclass
class StageRecord:
    """What one stage did (filled in while it runs)."""

    name: str
    status: StageStatus = StageStatus.NOT_RUN
    seconds: float = 0.0  # wall time
    outputs: list[str] = field(default_factory=list)  # files written, paths as given
    figures: dict[str, Any] = field(default_factory=dict)  # numbers for the summary
    message: str = ""  # the error, or why it was skipped

    def as_dict(self) -> dict[str, Any]:
        return {
            "status": self.status.value,
            "seconds": round(self.seconds, 3),
            "outputs": self.outputs,
            "figures": self.figures,
            "message": self.message,
        }


class StageHooks(Protocol):
    """Progress callbacks (the CLI draws a bar per stage)."""

    def started(self, name: str, index: int, total: int) -> None: ...

    def finished(self, record: StageRecord) -> None: ...


def stage_error(err: GaideError, stage: str) -> GaideError:
    """``err`` as the stage's exception, the stage named in front of the message."""
    cls = type(err) if isinstance(err, (*OWN_CODE, STAGE_ERRORS[stage])) else STAGE_ERRORS[stage]
    return cls(f"{stage}: {err}")


def _jsonable(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return _jsonable(value.item())
    return value


class StageRunner:
    """Stages named in ``stages`` (in order), writing into ``out``."""

    def __init__(
        self,
        out: str | Path,
        stages: Sequence[str],
        *,
        hooks: StageHooks | None = None,
        header: Mapping[str, Any] | None = None,
    ) -> None:
        unknown = [s for s in stages if s not in STAGE_ERRORS]
        if unknown:
            raise ValueError(f"unknown stages {unknown}; known: {list(STAGE_ERRORS)}")
        self.out = Path(out)
        self.records = {name: StageRecord(name) for name in stages}
        self.hooks = hooks
        self.header = dict(header or {})
        self.failed: str | None = None
        self.error = ""
        self.finished = False
        self._t0 = time.perf_counter()
        try:
            self.out.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise ConfigError(f"cannot create the output folder {self.out}: {err}") from err

    @contextlib.contextmanager
    def stage(self, name: str) -> Iterator[StageRecord]:
        """Run the body as stage ``name``; its failure is recorded and re-raised."""
        record = self.records[name]
        names = list(self.records)
        if self.hooks:
            self.hooks.started(name, names.index(name), len(names))
        t0 = time.perf_counter()
        try:
            yield record
        except BaseException as err:
            record.status = StageStatus.FAILED
            record.seconds = time.perf_counter() - t0
            record.message = str(err) or type(err).__name__
            self.failed, self.error = name, record.message
            self.write_summary()
            if self.hooks:
                self.hooks.finished(record)
            if isinstance(err, GaideError):
                raise stage_error(err, name) from err
            raise
        record.status = StageStatus.SUCCESS
        record.seconds = time.perf_counter() - t0
        self.write_summary()
        if self.hooks:
            self.hooks.finished(record)

    def skip(self, name: str, reason: str) -> None:
        record = self.records[name]
        record.status, record.message = StageStatus.SKIPPED, reason
        self.write_summary()
        if self.hooks:
            names = list(self.records)
            self.hooks.started(name, names.index(name), len(names))
            self.hooks.finished(record)

    def commit(self, record: StageRecord, files: Mapping[str, Content]) -> list[Path]:
        """Write ``files`` (names inside the output folder: bytes, or a function writing the
        file at the path it is given) all or none, and record them."""
        targets = write_files_atomic(
            [(self.out / name, content) for name, content in files.items()],
            STAGE_ERRORS[record.name],
        )
        record.outputs.extend(str(t) for t in targets)
        self.write_summary()  # the files are listed as soon as they exist
        return targets

    def path(self, name: str) -> Path:
        return self.out / name

    def summary(self) -> dict[str, Any]:
        return _jsonable(
            {
                **self.header,
                "status": "failed" if self.failed else "success" if self.finished else "running",
                "failed_stage": self.failed,
                "error": self.error or None,
                "wall_s": round(time.perf_counter() - self._t0, 3),
                "stages": {name: r.as_dict() for name, r in self.records.items()},
            }
        )

    def write_summary(self) -> Path:
        """``summary.json`` in the output folder, atomically."""
        text = json.dumps(self.summary(), indent=2) + "\n"
        return write_bytes_atomic(self.out / "summary.json", text.encode(), ExecutionError)

    def finish(self) -> None:
        """The run is over (every stage ran or was skipped): the summary says so."""
        self.finished = True
        self.write_summary()


LOCK = ".gaide-run.lock"
SUMMARY = "summary.json"


@contextlib.contextmanager
def folder_lock(out: Path) -> Iterator[None]:
    """Hold ``out``'s run lock: ConfigError if a live process holds it (a stale lock, left
    by a killed run, is taken over)."""
    import os

    lock = out / LOCK
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(f"cannot create the output folder {out}: {err}") from err
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _lock_holder(lock)
            if holder is not None:
                raise ConfigError(
                    f"another gaide run (process {holder}) is writing into {out}; wait for it "
                    "to end or choose another -o"
                ) from None
            lock.unlink(missing_ok=True)  # stale: its process is gone
            continue
        except OSError as err:
            raise ConfigError(f"cannot write into the output folder {out}: {err}") from err
        try:
            with os.fdopen(fd, "w") as f:
                f.write(str(os.getpid()))
        except OSError as err:
            lock.unlink(missing_ok=True)
            if created:
                with contextlib.suppress(OSError):
                    out.rmdir()
            raise ExecutionError(f"cannot write {lock}: {err.strerror or err}") from err
        break
    try:
        yield
    finally:
        lock.unlink(missing_ok=True)
        if created:  # a run that wrote nothing leaves no folder behind
            with contextlib.suppress(OSError):
                out.rmdir()


def _lock_holder(lock: Path) -> int | None:
    """The live process holding ``lock``, or None when it is stale or unreadable."""
    import os

    try:
        pid = int(lock.read_text().strip())
        os.kill(pid, 0)
    except (OSError, ValueError):
        return None
    return pid


def claim_folder(out: Path, names: Sequence[str]) -> None:
    """Make ``out`` ready for a new run that may write ``names``: remove the files an
    earlier run wrote there (those its ``summary.json`` lists), and refuse (ConfigError,
    nothing removed) when a file or folder of one of those names is there but no earlier
    run of this folder wrote it: it is someone else's."""
    import shutil

    earlier = _earlier_outputs(out)
    present = [
        name for name in (*names, SUMMARY) if (out / name).exists() or (out / name).is_symlink()
    ]
    foreign = [name for name in present if name not in earlier and name != SUMMARY]
    if SUMMARY in present and not earlier and not _is_run_summary(out / SUMMARY):
        foreign.append(SUMMARY)
    if foreign:
        raise ConfigError(
            f"{out} holds {', '.join(foreign)}, which no gaide run wrote there; move them or "
            "choose another -o (a run replaces only its own earlier files)"
        )
    for name in present:
        path = out / name
        try:
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            else:
                path.unlink(missing_ok=True)
        except OSError as err:
            raise ConfigError(
                f"cannot replace {path}, written by an earlier run: {err}; choose another -o"
            ) from err


def _earlier_outputs(out: Path) -> set[str]:
    """Names of the files the earlier run's summary lists (empty without one)."""
    try:
        summary = json.loads((out / SUMMARY).read_text())
        stages = summary["stages"].values()
        return {Path(p).name for st in stages for p in st.get("outputs", [])} | {SUMMARY}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return set()


def _is_run_summary(path: Path) -> bool:
    try:
        return isinstance(json.loads(path.read_text()).get("stages"), dict)
    except (OSError, ValueError, AttributeError):
        return False
