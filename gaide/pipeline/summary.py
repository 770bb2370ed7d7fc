"""The run's summary as rows of text: what the CLI prints and the report shows."""

from __future__ import annotations

from typing import Any

from execution.timing_cfg import timing_phrase
from gaide.pipeline.runner import StageRecord, StageRunner, StageStatus


def _fmt_stage(r: StageRecord) -> str | None:
    """One line for a stage's headline figures (None: nothing to say)."""
    f: dict[str, Any] = r.figures
    if r.status is StageStatus.SKIPPED:
        return f"skipped: {r.message}"
    if r.status is StageStatus.FAILED:
        return f"FAILED: {r.message}"
    if r.status is not StageStatus.SUCCESS:
        return "not run (an earlier stage failed)"
    if r.name == "calibration":
        return (
            f"RMS {f['reprojection_rms_px']:.3f} px ({f['source']}, {f['frames_used']} of "
            f"{f['frames']} frames), camera at {f['T_base_cam_xyz']} m"
        )
    if r.name == "perception":
        removed = f["counts"].get("robot_removed")
        extra = f", robot removed: {removed:,}" if removed is not None else ""
        return f"{f['points']:,} points{extra}"
    if r.name == "planning":
        return (
            f"{f['planner']}: {f['planning_s']:.2f} s, {f['attempts']} attempt(s); "
            f"{f['waypoints']} waypoints, {f['path_length_rad']:.3f} rad"
        )
    if r.name == "timing":
        return (
            f"{f['duration_s']:.3f} s at {f['rate_hz']:g} Hz "
            f"({timing_phrase(f['mode'], int(f.get('fallbacks', 0)))}), "
            f"{f['limit_violations']} limit violations"
        )
    if r.name == "simulation":
        text = (
            f"tracking RMS {1e3 * f['tracking_rms_rad']:.3g} mrad, max "
            f"{1e3 * f['tracking_max_rad']:.3g} mrad"
        )
        if f.get("tracking_rms_after_delay_rad") is not None and f.get("delay_ms"):
            text += (
                f" ({f['delay_ms']:.3g} ms delay; after it RMS "
                f"{1e3 * f['tracking_rms_after_delay_rad']:.3g} mrad)"
            )
        if f.get("executed_clearance_ok") is not None:
            c = f.get("executed_min_clearance_m")
            text += (
                "; executed clearance "
                + ("unbounded" if c is None else f"{1e3 * c:.3g} mm")
                + (" >= " if f["executed_clearance_ok"] else " < ")
                + (f"margin {1e3 * f['clearance_margin_m']:.3g} mm")
            )
        return f"{text}; {f['contacts']} contacts ({f['status']})"
    if r.name == "export":
        return ", ".join(f["formats"])
    return None


LABELS = {
    "setup": "robot",
    "calibration": "calibration",
    "perception": "scene cloud",
    "planning": "planning",
    "timing": "trajectory",
    "export": "export",
    "simulation": "simulation",
    "report": "report",
}


def summary_rows(runner: StageRunner) -> list[tuple[str, str]]:
    """(label, text) per stage with something to say, then the run's wall time."""
    rows = []
    for name, record in runner.records.items():
        quiet = (StageStatus.SUCCESS, StageStatus.NOT_RUN) if name == "report" else ()
        if (name == "setup" and record.status is StageStatus.SUCCESS) or record.status in quiet:
            continue
        text = _fmt_stage(record)
        if text is not None:
            rows.append((LABELS.get(name, name), text))
    rows.append(("wall time", f"{runner.summary()['wall_s']:.1f} s"))
    return rows


def output_rows(runner: StageRunner) -> list[tuple[str, str]]:
    """(stage, file) for every file the run wrote, in stage order."""
    rows = [
        (LABELS.get(name, name), path)
        for name, record in runner.records.items()
        for path in record.outputs
    ]
    rows.append(("summary", str(runner.path("summary.json"))))
    return rows
