"""A servo model of a real arm's joint controller, for :func:`execution.simulate.simulate`.

What a UR-class controller does to a streamed trajectory, cycle by cycle (period
``1 / rate_hz``, PyBullet's time step):

1. **Setpoint.** At cycle k the trajectory is sampled at t_k = k / rate_hz (from its Ruckig
   segments when it has them, else by quintic Hermite interpolation of its samples'
   positions, velocities and accelerations): the target a client would stream with
   ``servoj`` at that cycle.
2. **Delay.** Targets go through a FIFO of ``delay_cycles``: the one sent at cycle k reaches
   the joint controller at cycle k + delay_cycles (before that it holds the first target).
3. **Limits.** The delayed targets become the commanded motion under per-joint velocity and
   acceleration limits (a rate limiter that brakes in time to stop on a lagging target; a
   trajectory inside the limits passes unchanged).
4. **Joint control.** Torques from the measured state: computed torque,
   ``tau = ID(q_m, qd_m, qdd_c + kp (q_c - q_m) + kd (qd_c - qd_m))`` with PyBullet's inverse
   dynamics (``calculateInverseDynamics``: gravity compensation, Coriolis and inertia
   feed-forward of the commanded acceleration), a PD loop of natural frequency
   ``bandwidth_hz`` and damping ratio ``damping_ratio`` (kp = w^2, kd = 2 zeta w), each torque
   clipped to the URDF's effort limit; applied with PyBullet's TORQUE_CONTROL (the default
   velocity motors are off, :class:`~execution.sim_world.SimWorld` disables them).
5. **Measurement.** Encoder positions carry Gaussian noise (``encoder_noise_rad``, from a
   seeded generator); velocities are their backward differences. The PD loop and the log see
   these measurements, not PyBullet's exact state.

The commanded motion (1-3) does not depend on the arm, so it is computed before the physics
runs (:func:`servo_command`); :class:`ServoLoop` runs 4-5 around PyBullet's steps.

Not modelled: ``servoj``'s ``lookahead_time`` smoothing (0.03-0.2 s) and ``gain``
(100-2000), joint friction, gear elasticity, payload errors: the arm's dynamics are the
URDF's and the controller knows them exactly, so the error left after the delay is the
encoder noise and what the limits or effort saturation impose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from gaide_core import settings
from gaide_core.errors import ExecutionError
from gaide_core.types import Array

if TYPE_CHECKING:
    from execution.sim_world import SimWorld


@dataclass(frozen=True, kw_only=True)
class ServoCfg:
    """The arm controller's settings; defaults model a UR e-Series arm (UR5).

    Sources:
    - ``rate_hz`` 500: the e-Series controller's real-time loop, which RTDE and ``servoj``
      follow (UR's RTDE guide; CB3 arms run at 125 Hz).
    - ``delay_cycles`` 3 (6 ms at 500 Hz): engineering estimate. UR publishes no
      command-to-motion latency; a streamed ``servoj`` target moves the joints a few control
      cycles later.
    - ``max_velocity`` None: the robot config's velocity limits (the UR5 URDF's 3.15 rad/s for
      every joint: the UR5 spec sheet's 180 deg/s for all joints).
    - ``max_acceleration`` None: the robot config's acceleration limits (8 rad/s^2 for the UR5,
      ``planning/data/ur5.yaml``: a conservative engineering value; UR publishes none).
    - ``bandwidth_hz`` 20, ``damping_ratio`` 1: engineering estimates of a stiff,
      critically damped joint position loop (UR publishes no gains).
    - ``encoder_noise_rad`` 1e-5: engineering estimate, one count of a 19-bit absolute joint
      encoder (2 pi / 2^19 = 1.2e-5 rad); UR publishes no resolution.
    """

    rate_hz: float = 500.0  # Hz, control cycle (PyBullet's time step), in [50, 2000]
    delay_cycles: int = 3  # cycles from a target to the joint controller, in [0, 100]
    max_velocity: tuple[float, ...] | None = None  # rad/s per joint, > 0; None: the robot's
    max_acceleration: tuple[float, ...] | None = None  # rad/s^2 per joint; None: the robot's
    bandwidth_hz: float = 20.0  # Hz, PD natural frequency, in (0, rate_hz / 20]
    damping_ratio: float = 1.0  # PD damping ratio, in [0.1, 2]
    encoder_noise_rad: float = 1e-5  # rad, std of the measured positions' noise, in [0, 0.01]
    seed: int = 0  # the noise generator's seed, >= 0

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        err = ExecutionError
        put(
            "rate_hz",
            settings.number(
                self.rate_hz, "servo.rate_hz", lo=50.0, hi=2000.0, unit="Hz", error=err
            ),
        )
        put(
            "delay_cycles",
            settings.integer(self.delay_cycles, "servo.delay_cycles", lo=0, hi=100, error=err),
        )
        for name, unit in (("max_velocity", "rad/s"), ("max_acceleration", "rad/s^2")):
            put(
                name,
                settings.vector(
                    getattr(self, name), f"servo.{name}", positive=True, unit=unit, error=err
                ),
            )
        # Discrete stability of the PD loop at the cycle period: w dt <= 2 pi / 20 keeps the
        # closed loop's poles well inside the unit circle for every allowed damping ratio.
        put(
            "bandwidth_hz",
            settings.number(
                self.bandwidth_hz,
                "servo.bandwidth_hz",
                lo=0.0,
                hi=self.rate_hz / 20.0,
                lo_open=True,
                unit=f"Hz (rate_hz / 20 at rate_hz = {self.rate_hz:g} Hz)",
                error=err,
            ),
        )
        put(
            "damping_ratio",
            settings.number(self.damping_ratio, "servo.damping_ratio", lo=0.1, hi=2.0, error=err),
        )
        put(
            "encoder_noise_rad",
            settings.number(
                self.encoder_noise_rad,
                "servo.encoder_noise_rad",
                lo=0.0,
                hi=0.01,
                unit="rad",
                error=err,
            ),
        )
        put("seed", settings.integer(self.seed, "servo.seed", lo=0, error=err))

    @property
    def delay_s(self) -> float:
        """The command-to-motion delay (s)."""
        return self.delay_cycles / self.rate_hz

    def joint_limits(self, velocity: Array, acceleration: Array) -> tuple[Array, Array]:
        """The limits (dof,) each the servo enforces: its own, or the robot's given ones."""
        out = []
        for name, robot in (("max_velocity", velocity), ("max_acceleration", acceleration)):
            own = getattr(self, name)
            if own is None:
                out.append(np.asarray(robot, float))
                continue
            if len(own) != len(robot):
                raise ExecutionError(
                    f"servo.{name} must give one value per joint ({len(robot)}), got {len(own)}"
                )
            out.append(np.asarray(own, float))
        return out[0], out[1]


def hermite_resample(t: Array, q: Array, qd: Array, qdd: Array, times: Array) -> Array:
    """Positions (M, dof) at ``times`` (s) of the motion sampled uniformly at ``t`` (N,) with
    positions, velocities and accelerations (N, dof) each: quintic Hermite interpolation,
    held after the end. Exact at the samples; between them within 2e-7 rad of the Ruckig
    segments of a 100 Hz UR5 trajectory (their jerk switches inside an interval)."""
    if len(t) == 1:
        return np.repeat(q[:1], len(times), axis=0)
    h = float(t[1] - t[0])
    x = np.clip(times / h, 0.0, len(t) - 1.0)
    i = np.minimum(np.floor(x + 1e-9).astype(np.int64), len(t) - 2)
    s = np.clip(x - i, 0.0, 1.0)[:, None]
    s2, s3 = s * s, s * s * s
    s4, s5 = s3 * s, s3 * s2
    h0 = 1 - 10 * s3 + 15 * s4 - 6 * s5
    h1 = s - 6 * s3 + 8 * s4 - 3 * s5
    h2 = 0.5 * s2 - 1.5 * s3 + 1.5 * s4 - 0.5 * s5
    h3 = 0.5 * s3 - s4 + 0.5 * s5
    h4 = -4 * s3 + 7 * s4 - 3 * s5
    h5 = 10 * s3 - 15 * s4 + 6 * s5
    j = i + 1
    return (
        h0 * q[i]
        + h1 * h * qd[i]
        + h2 * h * h * qdd[i]
        + h3 * h * h * qdd[j]
        + h4 * h * qd[j]
        + h5 * q[j]
    )


@dataclass(frozen=True, kw_only=True)
class ServoCommand:
    """The motion the joint controller follows, one row per cycle: after the delay FIFO and
    the limits. ``qd[k]`` is the mean velocity over cycle k - 1 -> k, ``qdd[k]`` the
    acceleration that turns ``qd[k]`` into ``qd[k + 1]`` (semi-implicit Euler, as PyBullet
    integrates): an arm on (q[k], qd[k]) accelerating at qdd[k] is on q[k + 1] a cycle later."""

    q: Array  # (n, dof) rad
    qd: Array  # (n, dof) rad/s
    qdd: Array  # (n, dof) rad/s^2
    limited_cycles: int  # cycles where a velocity or acceleration limit changed the command


def servo_command(
    targets: Array, dt: float, delay_cycles: int, max_velocity: Array, max_acceleration: Array
) -> ServoCommand:
    """The commanded motion from the targets streamed at each cycle (n, dof) rad, ``dt`` s
    apart: delayed by ``delay_cycles``, then limited to ``max_velocity`` (rad/s) and
    ``max_acceleration`` (rad/s^2) per joint (dof,)."""
    n, dof = targets.shape
    # The FIFO: what the controller reads at cycle k was sent at k - delay_cycles; until the
    # first target arrives it holds the start.
    fifo = np.concatenate([np.repeat(targets[:1], delay_cycles, axis=0), targets])[:n]
    dv = max_acceleration * dt
    v_ref = np.zeros((n, dof))
    v_ref[1:] = np.diff(fifo, axis=0) / dt
    # Up to the first cycle past a limit (beyond round-off: a trajectory timed at the limits
    # reaches them to ~1e-11) the command is the delayed target itself.
    over = np.any(np.abs(v_ref) > max_velocity + 1e-6 * dv, axis=1)
    over[1:] |= np.any(np.abs(np.diff(v_ref, axis=0)) > dv * (1 + 1e-6), axis=1)
    first = int(np.argmax(over)) if over.any() else n
    q = fifo.copy()
    v = v_ref.copy()
    limited = 0
    for k in range(max(first, 1), n):
        lag = fifo[k - 1] - q[k - 1]  # how far the command trails the target
        # Close the lag as fast as the acceleration allows while still able to stop on it: in
        # steps of dt slowing by dv each, a speed m dv covers m (m + 1) / 2 dv dt. No lag:
        # the target's own motion, unchanged.
        e = np.abs(lag)
        stop = dv * (np.sqrt(0.25 + 2.0 * e / (dv * dt)) - 0.5)
        want = v_ref[k] + np.sign(lag) * np.minimum(e / dt, stop)
        got = np.minimum(np.maximum(want, v[k - 1] - dv), v[k - 1] + dv)
        got = np.minimum(np.maximum(got, -max_velocity), max_velocity)
        limited += bool(np.any(np.abs(got - want) > 1e-6 * dv))
        v[k] = got
        q[k] = q[k - 1] + got * dt
    qdd = np.zeros((n, dof))
    qdd[:-1] = np.diff(v, axis=0) / dt
    return ServoCommand(q=q, qd=v, qdd=qdd, limited_cycles=limited)


class ServoLoop:
    """The joint controller and the encoders around a :class:`SimWorld` stepping at the
    servo's rate: :meth:`measure` after each step, :meth:`drive` before the next."""

    def __init__(
        self,
        sim: SimWorld,
        cfg: ServoCfg,
        command: ServoCommand,
        rng: np.random.Generator,
    ) -> None:
        import pybullet as pb  # here: ServoCfg is read by the CLI's help, which stays light

        self.pb = pb
        self.sim, self.cfg, self.command = sim, cfg, command
        c = sim.client
        self.dt = 1.0 / cfg.rate_hz
        w = 2.0 * math.pi * cfg.bandwidth_hz
        self.kp, self.kd = w * w, 2.0 * cfg.damping_ratio * w
        n, dof = command.q.shape
        self.noise = rng.normal(0.0, cfg.encoder_noise_rad, (n, dof))
        # PyBullet's inverse dynamics takes every movable joint in index order.
        movable = [
            j
            for j in range(pb.getNumJoints(sim.body, physicsClientId=c))
            if pb.getJointInfo(sim.body, j, physicsClientId=c)[2] != pb.JOINT_FIXED
        ]
        self.movable = movable
        self.slot = np.array([movable.index(j) for j in sim.joints], np.int64)
        self.identity = len(movable) == len(self.slot) and bool(
            np.all(self.slot == np.arange(len(self.slot)))
        )
        self.effort = np.asarray(sim.effort_limits, float)
        self.q_meas = np.zeros(dof)
        self.qd_meas = np.zeros(dof)
        self.saturated_cycles = 0

    def _full(self, values: Array) -> list[float]:
        """The robot's joint values (dof,) as PyBullet's movable joints (others: 0)."""
        if self.identity:
            return values.tolist()  # type: ignore[no-any-return]
        out = np.zeros(len(self.movable))
        out[self.slot] = values
        return out.tolist()

    def measure(self, k: int) -> tuple[Array, Array, Array]:
        """The arm's true positions, measured positions (rad) and measured velocities (rad/s)
        at cycle k (dof,) each. Cycle 0 starts at rest."""
        q_true, _ = self.sim.state()
        q_meas = q_true + self.noise[k]
        self.qd_meas = np.zeros_like(q_meas) if k == 0 else (q_meas - self.q_meas) / self.dt
        self.q_meas = q_meas
        return q_true, q_meas, self.qd_meas

    def drive(self, k: int) -> None:
        """Torques for the step after cycle k, from cycle k's measurement and command."""
        cmd = self.command
        acc = cmd.qdd[k] + self.kp * (cmd.q[k] - self.q_meas) + self.kd * (cmd.qd[k] - self.qd_meas)
        pb, c = self.pb, self.sim.client
        full = pb.calculateInverseDynamics(
            self.sim.body,
            self._full(self.q_meas),
            self._full(self.qd_meas),
            self._full(acc),
            physicsClientId=c,
        )
        tau = np.asarray(full, float)[self.slot]
        clipped = np.minimum(np.maximum(tau, -self.effort), self.effort)
        if np.any(clipped != tau):
            self.saturated_cycles += 1
        pb.setJointMotorControlArray(
            self.sim.body,
            self.sim.joints,
            pb.TORQUE_CONTROL,
            forces=clipped.tolist(),
            physicsClientId=c,
        )


__all__ = ["ServoCfg", "ServoCommand", "ServoLoop", "hermite_resample", "servo_command"]
