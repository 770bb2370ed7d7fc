"""``report.html``: one self-contained page (inline CSS, pictures embedded as base64 data
URIs, plotly.js inline) with the summary, the run in 3D (:mod:`gaide.pipeline.scene3d`),
every stage's picture and figures, and the settings of the run. It opens in any browser,
from anywhere: nothing outside the file is needed.
"""

from __future__ import annotations

import base64
import html
import json
import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from gaide.pipeline.runner import StageRunner, StageStatus
from gaide.pipeline.summary import output_rows, summary_rows

if TYPE_CHECKING:
    from planning.collision import CollisionChecker

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Picture:
    stage: str
    file: str  # name in the output folder
    caption: str


PICTURES = (
    Picture(
        "calibration",
        "calibration_overlay.png",
        "Calibration: the detected target with its axes, reprojected with the estimate.",
    ),
    Picture("perception", "scene.png", "Perception: the scene cloud in the robot's base frame."),
    Picture(
        "planning",
        "path.png",
        "Planning: the path as robot poses (collision spheres, start blue to goal red) in the "
        "cloud, and the end effector's trace.",
    ),
    Picture(
        "timing",
        "trajectory.png",
        "Timing: position, velocity, acceleration and jerk of each joint; dashed: its limits.",
    ),
    Picture(
        "simulation",
        "tracking.png",
        "Simulation: planned (solid) and simulated (dotted) joint positions, and the tracking "
        "error.",
    ),
)

CSS = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1200px; color: #222; }
h1 { margin-bottom: 0.2em; } .ok { color: #1a7f37; } .bad { color: #c62828; }
table { border-collapse: collapse; margin: 1em 0; }
td, th { border-bottom: 1px solid #ddd; padding: 0.3em 0.8em; text-align: left;
         vertical-align: top; }
figure { margin: 1.5em 0; } figure img { max-width: 100%; border: 1px solid #ccc; }
figcaption { color: #555; margin-top: 0.3em; } code, pre { background: #f5f5f5; }
pre { padding: 0.8em; overflow-x: auto; }
#view3d { border: 1px solid #ccc; }
"""

VIEW_CAPTION = (
    "The run in the robot's base frame: the scene cloud, the camera's viewing pyramid "
    "(0.3 m deep), the robot's collision spheres (42-vertex icospheres, vertices on each "
    "sphere) at the start (blue), the goal (red) and the closest approach to the scene "
    "(purple, its clearance marked in red), and moving along the trajectory (play, or "
    "drag the slider). Drag to turn, scroll to zoom; click a legend entry to hide it."
)


def _compact(text: str) -> str:
    """JSON with lists of numbers on one line."""
    number = r"-?\d[\d.eE+-]*"
    return re.sub(
        rf"\[\s*({number}(?:,\s*{number})*)\s*\]",
        lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]",
        text,
    )


def _table(rows: list[tuple[str, str]], head: tuple[str, str] | None = None) -> str:
    out = ["<table>"]
    if head:
        out.append(f"<tr><th>{html.escape(head[0])}</th><th>{html.escape(head[1])}</th></tr>")
    out += [f"<tr><td>{html.escape(a)}</td><td>{html.escape(b)}</td></tr>" for a, b in rows]
    out.append("</table>")
    return "\n".join(out)


def _figure(out: Path, pic: Picture) -> str:
    data = base64.b64encode((out / pic.file).read_bytes()).decode()
    return (
        f'<figure id="{html.escape(pic.stage)}"><img alt="{html.escape(pic.file)}" '
        f'src="data:image/png;base64,{data}">'
        f"<figcaption>{html.escape(pic.caption)} (<code>{html.escape(pic.file)}</code>)"
        "</figcaption></figure>"
    )


def _view3d(runner: StageRunner, checker: CollisionChecker | None) -> str:
    """The 3D section: the view, or one line saying why there is none (a failed view never
    costs the rest of the report)."""
    from gaide.pipeline.config import RunCfg
    from gaide.pipeline.scene3d import run_scene, scene_html

    head = "<h2>The run in 3D</h2>"
    try:
        cfg = RunCfg.from_dict(runner.header["config"])
        fragment = scene_html(run_scene(runner.out, cfg, checker))
    except FileNotFoundError as err:  # no cloud: the run stopped before perception ended
        return f"{head}\n<p>No 3D view: {html.escape(str(err))}.</p>"
    except Exception as err:  # the view is an extra: whatever breaks it, the page stands
        log.warning("report.html without the 3D view: %s: %s", type(err).__name__, err)
        return (
            f'{head}\n<p class="bad">No 3D view: {html.escape(f"{type(err).__name__}: {err}")}</p>'
        )
    return (
        f'{head}\n<figure id="view3d">{fragment}'
        f"<figcaption>{html.escape(VIEW_CAPTION)}</figcaption></figure>"
    )


def report_html(
    runner: StageRunner,
    config_yaml: str,
    title: str,
    *,
    checker: CollisionChecker | None = None,
    view3d: bool = True,
) -> str:
    """The report of the run so far (a failed run's report says where it stopped).
    ``checker``: the planning stage's, spares the 3D view building it again (seconds);
    ``view3d`` False leaves the view out (an interrupted run's report, written at once)."""
    summary = runner.summary()
    failed = summary["failed_stage"]
    status = (
        f'<p class="bad">Failed at stage <b>{html.escape(failed)}</b>: '
        f"{html.escape(summary['error'] or '')}</p>"
        if failed
        else '<p class="ok">Every stage succeeded.</p>'
    )
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        status,
        "<h2>Summary</h2>",
        _table(summary_rows(runner)),
        _view3d(runner, checker) if view3d else "",
        "<h2>Stages</h2>",
    ]
    for pic in PICTURES:
        record = runner.records.get(pic.stage)
        if record is None:
            continue
        parts.append(f"<h3>{html.escape(pic.stage)} ({record.status.value})</h3>")
        if record.status is StageStatus.SUCCESS and (runner.out / pic.file).is_file():
            parts.append(_figure(runner.out, pic))
        elif record.message:
            parts.append(f"<p>{html.escape(record.message)}</p>")
        if record.figures:
            figures = _compact(json.dumps(record.figures, indent=1, default=str))
            parts.append(
                f"<details><summary>figures</summary><pre>{html.escape(figures)}</pre></details>"
            )
    times = [
        (name, f"{r.status.value}, {r.seconds:.2f} s")
        for name, r in runner.records.items()
        if name != "report"
    ]
    parts += [
        "<h2>Stage times</h2>",
        _table(times, ("stage", "status, wall time")),
        "<h2>Files</h2>",
        _table(output_rows(runner), ("stage", "file")),
        "<h2>Settings</h2>",
        f"<pre>{html.escape(config_yaml)}</pre>",
        "</body></html>",
    ]
    return "\n".join(parts) + "\n"


def report_stage(
    runner: StageRunner,
    config_yaml: str,
    title: str,
    *,
    checker: CollisionChecker | None = None,
    view3d: bool = True,
) -> None:
    """Write ``report.html`` atomically, as the report stage's output (``checker``,
    ``view3d``: as in :func:`report_html`)."""
    record = runner.records["report"]
    # The report lists itself among the files: record it before rendering.
    record.outputs.append(str(runner.path("report.html")))
    page = report_html(runner, config_yaml, title, checker=checker, view3d=view3d).encode()
    record.outputs.pop()
    runner.commit(record, {"report.html": page})
    record.figures["bytes"] = len(page)
