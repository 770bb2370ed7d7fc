"""The report's 3D view (gaide/pipeline/scene3d.py): its geometry against references, a
failed view that keeps the rest of the page, and the page opened in a real browser.

The browser is Debian's headless chromium (.ci/system-deps installs it), drawing WebGL with
SwiftShader (no GPU), with every host name unresolvable: the page must work offline. A
probe script, put first in the page, collects uncaught errors, failed loads and
``console.error`` calls, and writes them into the DOM, which ``--dump-dom`` reads back;
the screenshot shows whether the plot was drawn (the robot's orange spheres, many colours).
"""

from __future__ import annotations

import json
import logging
import os
import re
import shutil
import signal
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gaide.pipeline.config_io import load_cfg
from gaide.pipeline.report import report_html
from gaide.pipeline.run import STAGES
from gaide.pipeline.runner import StageRunner
from gaide.pipeline.scene3d import (
    DIV_ID,
    MAX_FRAMES,
    CameraView,
    Closest,
    Scene3D,
    closest_approach,
    frustum,
    run_scene,
    scene_figure,
    scene_html,
    spheres_mesh,
    spheres_triangles,
)
from gaide_core.transforms import from_xyz_quat
from planning.checker import make_checker
from planning.distance_field import CloudWorld
from planning.robot_model import RobotModel
from planning.sphere_model import SphereModel

# The run of test_run_pipeline.py (a small synthetic bag through `gaide run`), made once for
# this module too.

K = np.array([[600.0, 0.0, 320.0], [0.0, 610.0, 240.0], [0.0, 0.0, 1.0]])
T_BASE_CAM = from_xyz_quat([1.1, -0.7, 0.65], np.array([0.78, 0.40, -0.22, -0.43]) / 0.9852)


# -- geometry ----------------------------------------------------------------------------


def test_the_frustum_reaches_the_image_corners_at_its_depth() -> None:
    cam = CameraView(T_base_cam=T_BASE_CAM, K=K, width=640, height=480)
    poly = frustum(cam, depth=0.3)
    pts = poly[np.isfinite(poly).all(axis=1)]
    R, t = T_BASE_CAM[:3, :3], T_BASE_CAM[:3, 3]
    local = (pts - t) @ R  # back into the optical frame
    np.testing.assert_allclose(local[0], 0.0, atol=1e-12)  # the apex is the camera
    ends = local[np.linalg.norm(local, axis=1) > 1e-9]
    np.testing.assert_allclose(ends[:, 2], 0.3, atol=1e-12)
    pixels = ends @ K.T
    pixels = pixels[:, :2] / pixels[:, 2:]
    corners = {(0.0, 0.0), (640.0, 0.0), (640.0, 480.0), (0.0, 480.0)}
    assert {tuple(np.round(p, 9) + 0.0) for p in pixels} == corners


def test_each_icosphere_lies_on_its_sphere() -> None:
    centres = np.array([[0.1, 0.2, 0.3], [-0.4, 0.0, 1.0]])
    radii = np.array([0.05, 0.12])
    verts = spheres_mesh(centres, radii).reshape(2, -1, 3)
    for c, r, v in zip(centres, radii, verts, strict=True):
        np.testing.assert_allclose(np.linalg.norm(v - c, axis=1), r, rtol=1e-12)
    tri = spheres_triangles(2)
    assert tri.shape == (160, 3) and tri.min() == 0 and tri.max() == 83
    # Every face of the second sphere uses only its own vertices, wound outwards, and lies
    # at least 0.93 r from the centre (as scene3d's docstring says).
    flat = spheres_mesh(centres, radii)
    a, b, c = (flat[tri[80:, k]] for k in range(3))
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    depth = np.einsum("ij,ij->i", normal, a - centres[1])
    assert np.all(depth > 0.93 * radii[1])


def test_the_closest_approach_is_the_true_smallest_clearance(
    robot: RobotModel, spheres: SphereModel
) -> None:
    q0 = robot.named_configuration("home")
    q1 = q0 + np.array([-1.2, 0.3, -0.3, 0.0, 0.0, 0.0])
    Q = np.linspace(q0, q1, 200)
    times = np.linspace(0.0, 2.0, 200)
    # A patch of cloud 3 cm beyond the last sphere's surface, two thirds along the motion,
    # on a coarse lattice (5 cm), whose look-up is up to 4.3 cm below the truth.
    free = make_checker(robot, spheres, backend="numpy")
    centre = free.sphere_centers(Q[130:131])[0, -1]
    rng = np.random.default_rng(3)
    offsets = rng.normal(size=(400, 3)) * [0.03, 0.03, 0.003] + [0, 0, -free.radii[-1] - 0.03]
    patch = centre + offsets
    world = CloudWorld(patch, voxel=0.05, band=0.3)
    checker = make_checker(robot, spheres, world, backend="numpy")
    c = closest_approach(checker, Q, times, patch)
    assert c is not None
    # the truth, brute force over every sample, sphere and cloud point
    centres = checker.sphere_centers(Q)  # (K, S, 3)
    checked = np.isfinite(checker.sphere_clearance(Q[:1])[0])
    gaps = np.linalg.norm(centres[:, checked, None] - patch[None, None], axis=-1).min(-1)
    truth = gaps - checker.radii[checked]
    assert c.clearance == pytest.approx(truth.min(), abs=1e-9) and 0.0 < c.clearance < 0.035
    sample, _ = np.unravel_index(np.argmin(truth), truth.shape)
    assert c.sample == sample and c.t == pytest.approx(times[c.sample])
    assert abs(c.sample - 130) < 30
    # the marked obstacle is the cloud point nearest that sphere, as far as the label says
    centre = c.centres[c.sphere]
    near = patch[np.argmin(np.linalg.norm(patch - centre, axis=1))]
    np.testing.assert_array_equal(c.obstacle, near)
    assert np.linalg.norm(c.obstacle - centre) - c.radius == pytest.approx(c.clearance, abs=1e-9)
    # the checker's own look-up reads less here: the label is not the bound
    assert checker.world_clearance(Q).min() < c.clearance - 0.005
    # far beyond the lattice's band the value is still the true distance, not the band
    away = patch + np.array([3.0, 0.0, 0.0])
    far = make_checker(robot, spheres, CloudWorld(away, voxel=0.05, band=0.3), backend="numpy")
    distant = closest_approach(far, Q, times, away)
    assert distant is not None and distant.clearance > 2.0


def _tiny_scene(frames: int = 12) -> Scene3D:
    """A table (a coloured grid), an arm of five spheres turning, a camera above."""
    g = np.linspace(-0.5, 0.5, 60)
    x, y = np.meshgrid(g + 0.4, g)
    table = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1)
    colors = np.stack([0.5 + 0.4 * (x.ravel() - 0.4), 0.45 + 0.3 * y.ravel(), np.full(x.size, 0.3)])
    angle = np.linspace(0.0, 1.2, frames)[:, None]
    reach = np.linspace(0.0, 0.6, 5)[None]
    centres = np.stack([np.cos(angle) * reach, np.sin(angle) * reach, 0.3 + 0 * angle * reach], 2)
    radii = np.full(5, 0.07)
    return Scene3D(
        points=table,
        colors=colors.T,
        camera=CameraView(T_base_cam=T_BASE_CAM, K=K, width=640, height=480),
        radii=radii,
        centres=centres,
        times=np.linspace(0.0, 1.5, frames),
        trace=centres[:, -1],
        closest=Closest(
            sample=0,
            t=0.0,
            clearance=0.23,
            centres=centres[0],
            sphere=4,
            radius=0.07,
            obstacle=np.array([0.6, 0.0, 0.0]),
        ),
    )


def test_the_figure_animates_only_the_robot_and_holds_its_scale() -> None:
    scene = _tiny_scene()
    fig = scene_figure(scene)
    names = [t.get("name") for t in fig["data"]]
    robot = names.index(ROBOT)
    assert len(fig["frames"]) == 12
    assert all(f["traces"] == [robot] for f in fig["frames"])
    steps = fig["layout"]["sliders"][0]["steps"]
    assert [s["label"] for s in steps][-1] == "1.50"
    assert any(str(n).startswith("closest: 230.0 mm at t = 0.00 s") for n in names)
    # equal scales: the aspect ratio is the ranges' ratio, and the ranges hold every sphere
    lay = fig["layout"]["scene"]
    spans = np.array([np.ptp(lay[f"{a}axis"]["range"]) for a in "xyz"])
    ratio = np.array([lay["aspectratio"][a] for a in "xyz"])
    np.testing.assert_allclose(ratio, spans / spans.max())
    lo = np.array([lay[f"{a}axis"]["range"][0] for a in "xyz"])
    assert np.all(scene.centres.reshape(-1, 3) - 0.07 >= lo)


def test_a_run_folder_without_a_trajectory_shows_what_it_has(
    tmp_path: Path, robot: RobotModel
) -> None:
    """The fallbacks of :func:`run_scene`: the cloud and a given camera pose only (planning
    failed), then the planned path without times (timing failed)."""
    from gaide_core.plan_file import PlanFile, plan_bytes
    from perception.cloud import SceneCloud, save_ply

    scene = _tiny_scene()
    save_ply(str(tmp_path / "scene.ply"), SceneCloud(scene.points, scene.colors))
    cfg = load_cfg(overrides=[("calibration.T_base_cam", [1.1, -0.7, 0.65, 0, 0, 0, 1])])
    only = run_scene(tmp_path, cfg)
    assert only.camera is not None and only.camera.K is None and len(only.centres) == 0
    np.testing.assert_allclose(only.points, scene.points, atol=1e-12)
    fig = scene_figure(only)
    assert "frames" not in fig and "sliders" not in fig["layout"]
    assert [t["name"] for t in fig["data"]][-1] == "camera (optical axis)"

    home = robot.named_configuration("home")
    path = np.stack([home, home + 0.3, home + np.array([0.6, 0.3, 0.3, 0.3, 0.3, 0.3])])
    (tmp_path / "plan.json").write_bytes(plan_bytes(PlanFile(path=path)))
    untimed = run_scene(tmp_path, cfg)
    assert untimed.times is None and len(untimed.centres) == MAX_FRAMES
    np.testing.assert_allclose(untimed.trace[0], robot.frame_pose(home)[:3, 3], atol=1e-9)
    np.testing.assert_allclose(untimed.trace[-1], robot.frame_pose(path[-1])[:3, 3], atol=1e-9)
    slider = scene_figure(untimed)["layout"]["sliders"][0]
    assert slider["currentvalue"]["prefix"] == "along the path: "
    assert [s["label"] for s in slider["steps"]][::49] == ["0", "100"]


def test_a_failed_view_keeps_the_rest_of_the_report(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    cfg = load_cfg()
    runner = StageRunner(tmp_path, STAGES, header={"config": cfg.as_dict()})
    page = report_html(runner, "robot: null\n", "a run")
    assert "No 3D view: no scene cloud (scene.ply)" in page  # stopped before perception
    (tmp_path / "scene.ply").write_text("ply\nformat ascii 1.0\nelement vertex 0\nend_header\n")
    with caplog.at_level(logging.WARNING):
        page = report_html(runner, "robot: null\n", "a run")
    assert re.search(r'<p class="bad">No 3D view: ValueError: points must be', page)
    assert "without the 3D view" in caplog.text
    for part in ("<h2>Summary</h2>", "<h2>Stage times</h2>", "<h2>Settings</h2>", "robot: null"):
        assert part in page, part
    assert "</html>" in page and DIV_ID not in page


# -- in a browser ------------------------------------------------------------------------

ROBOT = "robot (collision spheres)"  # the animated trace's name

# First in the page: collects what went wrong, then writes it (and how many animation
# frames the plot holds) into the DOM once the page has loaded.
PROBE = """<script>
window.__probe = {errors: []};
window.addEventListener("error", function (e) {
  window.__probe.errors.push(e.message || ("cannot load " + (e.target.src || e.target.href)));
}, true);
(function () {
  var error = console.error;
  console.error = function () {
    window.__probe.errors.push(Array.prototype.join.call(arguments, " "));
    error.apply(console, arguments);
  };
})();
window.addEventListener("load", function () {
  var view = document.getElementById("__DIV_ID__");
  var td = view && view._transitionData;
  window.__probe.frames = td && td._frames ? td._frames.length : -1;
  window.__probe.canvases = view ? view.querySelectorAll("canvas").length : 0;
  // The slider's way to a pose: the robot's mesh moves to the last frame, faces kept.
  var full = (view && view._fullData) || [];
  var robot = full.findIndex(function (t) { return t.name === "__ROBOT__"; });
  if (robot >= 0 && td && td._frames.length) {
    var sum = function (a) {
      return Array.prototype.reduce.call(a, function (s, v) { return s + v; }, 0);
    };
    var before = sum(full[robot].x);
    var last = td._frames[td._frames.length - 1].name;
    var now = {frame: {duration: 0, redraw: true}, transition: {duration: 0}, mode: "immediate"};
    Plotly.animate(view, [last], now).then(function () {
      var mesh = view._fullData[robot];
      window.__probe.moved = [before, sum(mesh.x), mesh.x.length, mesh.i.length];
    });
  }
  setTimeout(function () {  // once the plot has its size: where it is in the screenshot
    if (view) {
      var r = view.getBoundingClientRect();
      window.__probe.box = [r.left, r.top, r.right, r.bottom];
    }
    var out = document.createElement("pre");
    out.id = "probe";
    out.textContent = JSON.stringify(window.__probe);
    document.body.appendChild(out);
  }, 1000);
});
</script>""".replace("__DIV_ID__", DIV_ID).replace("__ROBOT__", ROBOT)


TIMEOUT_S = 240  # s, for one page (about 30 s on a loaded 2-core machine)


def _chromium() -> str:
    """The chromium binary; a failure where set-up could have installed it (root, CI), a
    skip saying how to install it otherwise."""
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    advice = "chromium is not installed: run `apt-get install -y chromium` (.ci/system-deps)"
    if os.geteuid() == 0 or os.environ.get("CI"):
        pytest.fail(f"{advice}; the set-up installs it where it runs as root, as in CI")
    pytest.skip(f"{advice}; this user is not root and cannot install it")


def _open(page: Path, tmp: Path) -> tuple[dict[str, Any], np.ndarray, str]:
    """Open ``page`` (with the probe put first) headless: the probe's report, the
    screenshot (1600, 1280, 3) and chromium's log."""
    from PIL import Image

    # A fresh folder for each page and its browser profile: chromium hangs (until killed)
    # on a profile an earlier headless run has used.
    work = Path(tempfile.mkdtemp(prefix="chromium_", dir=tmp))
    probed = work / page.name
    text = page.read_text()
    head = re.search(r"<head[^>]*>", text)
    assert head is not None, "the page has a <head>"
    probed.write_text(text[: head.end()] + PROBE + text[head.end() :])
    shot = work / "shot.png"
    args = [
        _chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--use-angle=swiftshader",  # WebGL on the CPU
        "--enable-unsafe-swiftshader",
        "--host-resolver-rules=MAP * ~NOTFOUND",  # offline: any fetch fails, and says so
        f"--user-data-dir={work / 'profile'}",
        "--window-size=1280,1600",  # the report's summary, then the view
        "--virtual-time-budget=5000",
        "--enable-logging=stderr",
        "--v=0",
        f"--screenshot={shot}",
        "--dump-dom",
        probed.as_uri(),
    ]
    with subprocess.Popen(
        args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    ) as browser:
        try:
            stdout, stderr = browser.communicate(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            os.killpg(browser.pid, signal.SIGKILL)  # the browser and its helper processes
            stdout, stderr = browser.communicate()
            pytest.fail(f"chromium did not finish in {TIMEOUT_S} s: {stderr[-3000:]}")
    proc = subprocess.CompletedProcess(args, browser.returncode, stdout, stderr)
    assert proc.returncode == 0, proc.stderr[-3000:]
    found = re.search(r'<pre id="probe">(.*?)</pre>', proc.stdout)
    assert found is not None, f"the probe never reported: {proc.stderr[-3000:]}"
    probe = json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    return probe, np.asarray(Image.open(shot).convert("RGB")), proc.stderr


def _drawn(image: np.ndarray, probe: dict[str, Any]) -> tuple[int, int]:
    """Distinct colours, and pixels of the robot's orange spheres (#f0a020, shaded), where
    the probe saw the plot (all of the screenshot where it saw none)."""
    left, top, right, bottom = (round(v) for v in probe.get("box", (0, 0, 1280, 1600)))
    assert bottom <= image.shape[0], f"the plot ends below the screenshot: {probe}"
    px = image[top:bottom, left:right].reshape(-1, 3).astype(int)
    r, g, b = px.T
    orange = (r > 170) & (g > 80) & (g < 200) & (b < 90) & (r - b > 110)
    return len(np.unique(px @ [65536, 256, 1])), int(orange.sum())


def _errors(probe: dict[str, Any], log: str) -> list[str]:
    logged = [
        line
        for line in log.splitlines()
        if "CONSOLE" in line and ("Uncaught" in line or "Failed to load" in line)
    ]
    errors = probe["errors"]
    assert isinstance(errors, list)
    return [str(e) for e in errors] + logged


def test_the_view_draws_in_a_browser(tmp_path: Path) -> None:
    page = tmp_path / "view.html"
    page.write_text(
        '<!DOCTYPE html><html><head><meta charset="utf-8"></head><body>'
        f"{scene_html(_tiny_scene())}</body></html>"
    )
    probe, image, log = _open(page, tmp_path)
    assert not _errors(probe, log)
    assert probe["frames"] == 12 and probe["canvases"] >= 1
    scene = _tiny_scene()
    first, now, vertices, faces = probe["moved"]
    # the sums of the mesh's x before and after: the first pose's, then the last one's
    assert first == pytest.approx(spheres_mesh(scene.centres[0], scene.radii)[:, 0].sum(), abs=1e-3)
    assert now == pytest.approx(spheres_mesh(scene.centres[-1], scene.radii)[:, 0].sum(), abs=1e-3)
    assert vertices == 5 * 42 and faces == 5 * 80
    colors, orange = _drawn(image, probe)
    assert colors > 1000 and orange > 1000, (colors, orange)


def test_the_probe_sees_errors_and_a_blank_view(tmp_path: Path) -> None:
    page = tmp_path / "broken.html"
    page.write_text(
        f'<!DOCTYPE html><html><head></head><body><div id="{DIV_ID}"></div>'
        '<script>notAFunction();</script><img src="https://example.com/x.png"></body></html>'
    )
    probe, image, log = _open(page, tmp_path)
    errors = " ".join(_errors(probe, log))
    assert "notAFunction" in errors and "example.com" in errors
    assert probe["frames"] == -1
    colors, orange = _drawn(image, probe)
    assert colors < 1000 and orange == 0, (colors, orange)


def test_the_report_of_a_run_shows_the_run_in_3d(run_out: tuple[Path, str]) -> None:
    out, _ = run_out
    page = (out / "report.html").read_text()
    assert "No 3D view" not in page and f'id="{DIV_ID}"' in page
    assert len(re.findall(r"\* plotly\.js v\d", page)) == 1  # inline, once
    assert len(page.encode()) < 12e6  # plotly.js is 4.8 MB of it
    probe, image, log = _open(out / "report.html", out.parent)
    assert not _errors(probe, log)
    assert isinstance(probe["frames"], int) and probe["frames"] > 10
    first, now, vertices, faces = probe["moved"]
    assert abs(first - now) > 1.0 and vertices * 80 == faces * 42  # x summed over vertices
    colors, orange = _drawn(image, probe)
    assert colors > 1000 and orange > 1000, (colors, orange)
