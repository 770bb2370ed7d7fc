"""A timed trajectory as a URScript program a Universal Robots controller runs as is.

The program is ``def gaide_trajectory(): ... end`` and a call of it. It first moves to the
trajectory's start with ``movej`` at a safe speed (``approach_speed``,
``approach_acceleration``), then either

- ``servoj`` (default): streams the trajectory, one ``servoj(q, 0, 0, t, lookahead_time,
  gain)`` per sample, ``t`` the period (``servoj_period_s``; by default the trajectory's
  sample period rounded up to whole 2 ms control cycles: 2 ms at 500 Hz). At the trajectory's
  own period the samples are its own; at another they are the trajectory resampled (its Ruckig
  segments where it has them, else a quintic Hermite spline through its positions,
  velocities and accelerations). The last sample is the trajectory's end exactly; the
  program then holds it for five lookahead times (at least 0.1 s) so that the servo settles
  on it, and ends with ``stopj``;
- ``movej``: one ``movej(q, a, v, r=radius)`` per waypoint of the timed path
  (``TimedTrajectory.path``), linear in joint space as the path's checked edges are, at the
  trajectory's limits (the smallest joint's: ``v`` and ``a`` are the leading axis's), with
  blend radii (:func:`blend_radii`). The controller times these moves itself (trapezoidal
  speed profiles), so the program keeps the path, not the trajectory's timing; a blend leaves
  the checked edges near its waypoint by up to about its radius at the tool (not re-checked;
  ``blend_radius_m: 0`` stops at every waypoint and stays on the checked path).

What the program relies on, from Universal Robots' Script Manual (e-Series, SW 5.x, "Module
motion"; servoj's page:
https://www.universal-robots.com/manuals/EN/HTML/SW5_20/Content/prod-scriptmanual/G5/servoj_qavt0-008lookahead_time.htm):

- ``servoj(q, a, v, t=0.002, lookahead_time=0.1, gain=300)``: joint positions ``q`` (rad,
  base, shoulder, elbow, wrist 1, 2, 3); ``a`` and ``v`` are not used; the call controls the
  robot and blocks for ``t`` s, and a new target each control cycle is the intended use
  (0.002 s, 500 Hz, on e-Series; 0.008 s, 125 Hz, on CB3): ``servoj_period_s`` must be a
  whole number of 2 ms cycles (and of 8 ms for a CB3: set it to 0.008); ``lookahead_time``
  in [0.03, 0.2] s projects the current position ahead with the current velocity (low:
  fast reaction; high: no overshoot) and ``gain`` in [100, 2000] is the proportional gain
  towards ``q``. Defaults 0.03 s and 2000 are what Universal Robots' ROS 2 driver streams
  trajectories with (``ur.ros2_control.xacro``); a smooth 500 Hz stream suits them.
- ``movej(q, a=1.4, v=1.05, t=0, r=0)``: a move linear in joint space with a trapezoidal
  speed profile; ``a`` (rad/s^2) and ``v`` (rad/s) are the leading axis's, the other joints
  are scaled to arrive with it; ``r`` (m) is a blend radius, measured at the tool (here the
  robot config's end effector, ``tool0`` on a UR: a TCP offset set on the controller moves
  it): the robot does not stop at the waypoint but leaves it when the tool enters the sphere
  of radius ``r`` around it. A blend that overlaps the previous or the next waypoint's is not blended: the
  controller skips the move with an "Overlapping Blends" warning, so the radii here never
  overlap (``r[i] + r[i+1]`` at most the tool's distance between the waypoints), and the last
  is 0 (the robot stops at the goal).
- ``stopj(a)``: decelerate the joints to rest at ``a`` rad/s^2.

Joints: mapped by name onto UR's order (:data:`UR_JOINTS`, optionally all with one prefix,
as a ``tf_prefix`` gives them); a trajectory of other joints is refused. Numbers are written
in fixed notation (URScript floats), positions with 10 decimals (1e-10 rad).

A program holds one line per sample: about 130 bytes per sample, 65 kB per second at 500 Hz;
a controller compiles a long program for a while before it starts.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from gaide_core import settings
from gaide_core.errors import ExecutionError
from gaide_core.types import Array

if TYPE_CHECKING:  # light to import: `gaide time` shows these defaults in its help
    from execution.trajectory import TimedTrajectory

#: UR's joints in its controller's order: base, shoulder, elbow, wrist 1, wrist 2, wrist 3.
UR_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)
CONTROL_PERIOD_S = 0.002  # s, e-Series control cycle (500 Hz): servoj's smallest t
PROGRAM = "gaide_trajectory"


class UrScriptMode(enum.Enum):
    SERVOJ = "servoj"  # stream every sample
    MOVEJ = "movej"  # move through the path's waypoints with blends

    @staticmethod
    def parse(text: str) -> UrScriptMode:
        try:
            return UrScriptMode(text)
        except ValueError as err:
            raise ExecutionError(
                f"urscript_mode must be one of {[m.value for m in UrScriptMode]}, got {text!r}"
            ) from err


@dataclass(frozen=True, kw_only=True)
class UrScriptCfg:
    """Settings of :func:`urscript_program` (module doc)."""

    urscript_mode: UrScriptMode = UrScriptMode.SERVOJ  # or its name, parsed
    servoj_period_s: float | None = None  # s, servoj's t, whole 2 ms cycles (CB3: 0.008);
    # None: the trajectory's sample period, rounded up to whole cycles
    servoj_lookahead_s: float = 0.03  # s, servoj's lookahead_time, in [0.03, 0.2]
    servoj_gain: float = 2000.0  # servoj's gain, in [100, 2000]
    blend_radius_m: float = 0.01  # m, movej: largest blend radius at a waypoint (at the tool)
    approach_speed: float = 0.3  # rad/s, the first movej to the start (leading axis)
    approach_acceleration: float = 0.5  # rad/s^2, the same move

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        err = ExecutionError
        mode = self.urscript_mode
        put("urscript_mode", mode if isinstance(mode, UrScriptMode) else UrScriptMode.parse(mode))
        if self.servoj_period_s is not None:
            period = settings.number(
                self.servoj_period_s, "servoj_period_s", lo=CONTROL_PERIOD_S, hi=1.0, unit="s",
                error=err,
            )  # fmt: skip
            if not _whole_cycles(period):
                raise err(
                    f"servoj_period_s must be a whole number of {CONTROL_PERIOD_S} s control "
                    f"cycles (0.002 on e-Series, 0.008 on CB3), got {period:g}"
                )
            put("servoj_period_s", period)
        put(
            "servoj_lookahead_s",
            settings.number(
                self.servoj_lookahead_s, "servoj_lookahead_s", lo=0.03, hi=0.2, unit="s", error=err
            ),
        )
        put(
            "servoj_gain",
            settings.number(self.servoj_gain, "servoj_gain", lo=100.0, hi=2000.0, error=err),
        )
        put(
            "blend_radius_m",
            settings.number(
                self.blend_radius_m, "blend_radius_m", lo=0.0, hi=1.0, unit="m", error=err
            ),
        )
        put(
            "approach_speed",
            settings.number(
                self.approach_speed, "approach_speed", lo=0.0, hi=3.2, lo_open=True,
                unit="rad/s", error=err,
            ),
        )  # fmt: skip
        put(
            "approach_acceleration",
            settings.number(
                self.approach_acceleration, "approach_acceleration", lo=0.0, hi=40.0,
                lo_open=True, unit="rad/s^2", error=err,
            ),
        )  # fmt: skip


def _whole_cycles(period: float) -> bool:
    cycles = period / CONTROL_PERIOD_S
    return abs(cycles - round(cycles)) < 1e-6


def ur_order(names: tuple[str, ...]) -> list[int]:
    """Index into ``names`` of each of UR's joints, in UR's order (:data:`UR_JOINTS`). The
    names may all carry one prefix (``ur_shoulder_pan_joint``: a ``tf_prefix``); anything
    else is refused with ExecutionError naming them."""
    prefixes, index = set(), {}
    for i, name in enumerate(names):
        base = next((u for u in UR_JOINTS if name.endswith(u)), None)
        if base is None:
            break
        prefixes.add(name[: -len(base)])
        index[base] = i
    if len(names) != len(UR_JOINTS) or len(index) != len(UR_JOINTS) or len(prefixes) != 1:
        raise ExecutionError(
            f"a URScript program drives a UR's six joints {list(UR_JOINTS)} (the names may "
            f"all carry one prefix, as a tf_prefix gives them); the trajectory's joints are "
            f"{list(names)}"
        )
    return [index[u] for u in UR_JOINTS]


def servo_period(traj: TimedTrajectory, cfg: UrScriptCfg) -> float:
    """servoj's ``t`` (s): the setting, else the trajectory's sample period rounded up to
    whole 2 ms control cycles."""
    if cfg.servoj_period_s is not None:
        return cfg.servoj_period_s
    period = 1.0 / traj.rate_hz
    if _whole_cycles(period):
        return round(period / CONTROL_PERIOD_S) * CONTROL_PERIOD_S
    return math.ceil(period / CONTROL_PERIOD_S) * CONTROL_PERIOD_S


def servo_samples(traj: TimedTrajectory, period_s: float) -> Array:
    """Positions (M, dof) rad at ``k * period_s`` from 0 until the first sample at or after
    the trajectory's end; the last one is the trajectory's last sample exactly.

    The trajectory's own samples when ``period_s`` is its period; else its Ruckig segments
    (exact), or, read from a file without them, a quintic Hermite spline through its samples'
    positions, velocities and accelerations (exact on each polynomial piece of a Ruckig
    trajectory between samples). After the end the goal is held (a trajectory ends at rest)."""
    if abs(period_s * traj.rate_hz - 1.0) < 1e-9:
        return traj.q.copy()
    steps = math.ceil(traj.duration / period_s - 1e-9)
    times: Array = np.arange(steps + 1, dtype=np.float64) * np.float64(period_s)
    if traj.chain is not None:
        q = traj.chain.evaluate(np.minimum(times, traj.chain.duration))[0]
    else:
        q = quintic_hermite(traj.t, traj.q, traj.qd, traj.qdd, times)
    q[-1] = traj.q[-1]
    return q


def quintic_hermite(t: Array, q: Array, qd: Array, qdd: Array, times: Array) -> Array:
    """Positions (M, dof) at ``times`` (M,) s of the quintic Hermite spline through samples
    ``t`` (N,) s with positions, velocities, accelerations ``q``, ``qd``, ``qdd`` (N, dof);
    before ``t[0]`` and after ``t[-1]`` the first and the last positions."""
    times = np.asarray(times, float)
    out = np.empty((len(times), q.shape[1]))
    before, after = times <= t[0], times >= t[-1]
    out[before], out[after] = q[0], q[-1]
    inner = ~(before | after)
    if not inner.any():
        return out
    x = times[inner]
    i = np.clip(np.searchsorted(t, x, side="right") - 1, 0, len(t) - 2)
    h = (t[i + 1] - t[i])[:, None]
    s = ((x - t[i]) / h[:, 0])[:, None]
    s2, s3 = s * s, s * s * s
    s4, s5 = s3 * s, s3 * s2
    out[inner] = (
        (1 - 10 * s3 + 15 * s4 - 6 * s5) * q[i]
        + (s - 6 * s3 + 8 * s4 - 3 * s5) * h * qd[i]
        + 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * h * h * qdd[i]
        + 0.5 * (s3 - 2 * s4 + s5) * h * h * qdd[i + 1]
        + (-4 * s3 + 7 * s4 - 3 * s5) * h * qd[i + 1]
        + (10 * s3 - 15 * s4 + 6 * s5) * q[i + 1]
    )
    return out


def blend_radii(tool_xyz: Array, r_max: float) -> Array:
    """Blend radius (K,) m at each of K waypoints whose tool positions are ``tool_xyz``
    (K, 3) m: 0 at the first and the last, else ``r_max`` clipped to half the tool's
    distance to either neighbour, rounded down to 1e-6 m (as written), so that consecutive
    blends never overlap: ``r[i] + r[i + 1] <= |tool[i + 1] - tool[i]|``."""
    k = len(tool_xyz)
    r = np.zeros(k)
    if k < 3 or r_max <= 0:
        return r
    d = np.linalg.norm(np.diff(tool_xyz, axis=0), axis=1)
    r[1:-1] = np.minimum(r_max, 0.5 * np.minimum(d[:-1], d[1:]))
    return np.floor(r * 1e6) / 1e6


def move_limits(traj: TimedTrajectory) -> tuple[float, float]:
    """movej's ``v`` (rad/s) and ``a`` (rad/s^2): the smallest joint's limits the trajectory
    keeps (the leading axis may be any joint), or, without limits (a file without them), its
    largest sampled speed and acceleration."""
    if traj.limits is not None:
        return float(traj.limits.velocity.min()), float(traj.limits.acceleration.min())
    return float(np.abs(traj.qd).max()), float(np.abs(traj.qdd).max())


def urscript_program(
    traj: TimedTrajectory, cfg: UrScriptCfg | None = None, *, tool_xyz: Array | None = None
) -> str:
    """The program (module doc). ``tool_xyz`` (K, 3) m: the tool's position at each waypoint
    of ``traj.path``, for the blend radii of ``movej`` (needed when ``blend_radius_m > 0``)."""
    cfg = cfg or UrScriptCfg()
    order = ur_order(traj.joint_names)
    if not np.all(np.isfinite(traj.q)):
        raise ExecutionError("the trajectory holds NaN or inf positions")
    v, a = move_limits(traj)
    approach = (min(cfg.approach_acceleration, a), min(cfg.approach_speed, v))
    head = [
        f"def {PROGRAM}():",
        f"  # gaide trajectory: {traj.duration:.3f} s, {len(traj.t)} samples at "
        f"{traj.rate_hz:g} Hz; {cfg.urscript_mode.value}",
        "  # joints (rad): " + ", ".join(traj.joint_names[j] for j in order),
        "  # the robot moves to the start at a safe speed first",
        f"  movej({_q(traj.q[0, order])}, a={_num(approach[0])}, v={_num(approach[1])})",
    ]
    if cfg.urscript_mode is UrScriptMode.SERVOJ:
        body = _servoj_body(traj, cfg, order, a)
    else:
        body = _movej_body(traj, cfg, order, v, a, tool_xyz)
    return "\n".join([*head, *body, "end", f"{PROGRAM}()", ""])


def _servoj_body(
    traj: TimedTrajectory, cfg: UrScriptCfg, order: list[int], stop_acc: float
) -> list[str]:
    period = servo_period(traj, cfg)
    q = servo_samples(traj, period)[:, order]
    tail = f", 0, 0, {_num(period)}, {_num(cfg.servoj_lookahead_s)}, {_num(cfg.servoj_gain)})"
    hold = math.ceil(max(0.1, 5 * cfg.servoj_lookahead_s) / period - 1e-9)
    return [
        f"  # servoj every {_num(period)} s: {len(q)} samples, the last at the trajectory's end",
        *(f"  servoj({_q(row)}{tail}" for row in q),
        "  # hold the end until the servo has settled on it, then stop",
        f"  q_end = {_q(q[-1])}",
        "  hold = 0",
        f"  while hold < {hold}:",
        f"    servoj(q_end{tail}",
        "    hold = hold + 1",
        "  end",
        f"  stopj({_num(stop_acc)})",
    ]


def _movej_body(
    traj: TimedTrajectory,
    cfg: UrScriptCfg,
    order: list[int],
    v: float,
    a: float,
    tool_xyz: Array | None,
) -> list[str]:
    path = traj.path
    if path is None or len(path) < 2:
        raise ExecutionError(
            "movej needs the trajectory's waypoints (its timed path): write the program from "
            "`gaide time` or a trajectory .json, or use urscript_mode servoj"
        )
    if cfg.blend_radius_m > 0 and tool_xyz is None:
        raise ExecutionError(
            "movej's blend radii need the tool's positions at the waypoints (the robot model);"
            " or set blend_radius_m to 0"
        )
    if tool_xyz is not None and np.shape(tool_xyz) != (len(path), 3):
        raise ExecutionError(f"tool_xyz has shape {np.shape(tool_xyz)}; expected ({len(path)}, 3)")
    radii = np.zeros(len(path)) if tool_xyz is None else blend_radii(tool_xyz, cfg.blend_radius_m)
    return [
        f"  # movej to {len(path) - 1} waypoint(s) at v={_num(v)} rad/s, a={_num(a)} rad/s^2"
        f" (leading axis); blend radii (m) at most {_num(cfg.blend_radius_m)}, never overlapping",
        *(
            f"  movej({_q(path[k, order])}, a={_num(a)}, v={_num(v)}, r={_num(radii[k])})"
            for k in range(1, len(path))
        ),
    ]


def _q(row: Array) -> str:
    return "[" + ", ".join(_num(x) for x in row) + "]"


def _num(x: float) -> str:
    """Fixed notation with up to 10 decimals (URScript has no exponent notation to rely on)."""
    text = f"{float(x):.10f}".rstrip("0")
    text = text + "0" if text.endswith(".") else text
    return "0.0" if text == "-0.0" else text
