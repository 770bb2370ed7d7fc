"""Runs the stages of a pipeline one after the other, recording each one's outputs, time and
figures, and keeping the output folder consistent.

- A stage's files are written together at its end (:meth:`StageRunner.commit`): each to a
  temporary sibling, then all renamed into place; a failure leaves none of them.
- ``summary.json`` is rewritten (atomically) after every stage, so a failed run still says
  which stages succeeded, what they wrote, and which stage failed and why.
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
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from core.atomic import write_bytes_atomic
from core.errors import (
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
from execution.staging import staged_outputs

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

#: What a stage writes: bytes, or a function writing the file at the path it is given.
Output = bytes | Callable[[Path], None]


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

    def commit(self, record: StageRecord, files: Mapping[str, Output]) -> list[Path]:
        """Write ``files`` (names inside the output folder) all or none, and record them."""
        targets = [self.out / name for name in files]
        with staged_outputs(targets, STAGE_ERRORS[record.name]) as staged:
            for tmp, content in zip(staged, files.values(), strict=True):
                if isinstance(content, bytes):
                    tmp.write_bytes(content)
                else:
                    content(tmp)
        record.outputs.extend(str(t) for t in targets)
        return targets

    def path(self, name: str) -> Path:
        return self.out / name

    def summary(self) -> dict[str, Any]:
        return _jsonable(
            {
                **self.header,
                "status": "failed" if self.failed else "success",
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
