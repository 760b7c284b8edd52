"""The mock autopilot's vehicle model: every mock vehicle's motion, integrated together.

A cascaded controller shaped like PX4's multicopter position controller, with its default
gains, and a first-order thrust response, for N vehicles at once (arrays (N, 3), LOCAL_NED,
z down, ground at z = 0 = home):

    v_ref = v_sp + K_p (p_sp - p)          clamped to the velocity limits
    a_cmd = a_ff + K_v (v_ref - v)         clamped to the acceleration (tilt) limits
    a'    = (a_cmd - a) / tau              thrust lag
    v'    = a,  p' = v                     ground contact at z = 0

NaN in a setpoint component means "not controlled" (PX4 turns IGNORE bits into NaN): a NaN
position gives no position feedback on that axis, a NaN velocity or acceleration no
feed-forward. With the feed-forward of a smooth plan and zero initial error the model tracks
the plan to within centimetres; a step in position is followed with overshoot-free second-order
dynamics (damping about 0.7 horizontally). `step` is called at the physics rate (>= 100 Hz).

A vehicle whose state would become non-finite in a step (an absurd setpoint that slipped
through, a bad limit) is put back where it was, at rest, holding that point: one vehicle's
arithmetic can never poison the others' or the telemetry encoders (`FleetModel.recovered`).

With `EstimateNoise` (the mock's "px4" realism) `position` is the vehicle's *estimate*, what it
reports and what its controller feeds back on, and `truth` is where it really is: estimate =
truth + a slowly wandering bias per axis (first-order Gauss-Markov, like GPS errors) + white
noise, all from a seeded generator. The controller holds the estimate on the setpoint, so the
estimate stays close to it while the truth wanders with the bias. Ground contact acts on the
truth. Without noise `truth` *is* `position` (the same array) and nothing else changes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.model.flatness import GRAVITY  # the one gravity constant (the planner's world frame)
from planner.types import FloatArray

__all__ = ["GRAVITY", "EstimateNoise", "FleetModel", "ModelLimits"]

#: A state component beyond this (m, m/s, m/s^2) is garbage: the step is undone.
_FAR = 1e6


@dataclass(frozen=True)
class ModelLimits:
    """Gains and limits (PX4 defaults where PX4 has a parameter of that name)."""

    pos_gain_xy: float = 0.95
    """MPC_XY_P (1/s)."""
    pos_gain_z: float = 1.0
    """MPC_Z_P (1/s)."""
    vel_gain_xy: float = 1.8
    """MPC_XY_VEL_P_ACC (1/s)."""
    vel_gain_z: float = 4.0
    """MPC_Z_VEL_P_ACC (1/s)."""
    velocity_xy_max: float = 12.0
    """MPC_XY_VEL_MAX (m/s)."""
    velocity_up_max: float = 3.0
    """MPC_Z_VEL_MAX_UP (m/s)."""
    velocity_down_max: float = 1.5
    """MPC_Z_VEL_MAX_DN (m/s)."""
    acceleration_xy_max: float = 6.9
    """Horizontal acceleration from the tilt limit, about g * tan(35 deg) (m/s^2)."""
    acceleration_up_max: float = 8.0
    """Upward acceleration from the thrust margin (m/s^2)."""
    acceleration_down_max: float = 7.0
    """Downward acceleration (thrust cannot go below zero) (m/s^2)."""
    thrust_time_constant: float = 0.04
    """First-order lag of the achieved acceleration (s)."""


@dataclass(frozen=True)
class EstimateNoise:
    """The position estimate's error process (m, s): bias (Gauss-Markov, stationary standard
    deviation and correlation time per axis) plus white noise. Defaults fitted to PX4 v1.16 SIH
    SITL with GPS as height reference (at rest the estimated altitude ranges -1.2..+0.65 m, x/y
    wander +-0.3 m; hovering, the estimate holds the setpoint within about +-0.2 m and the
    vehicle drifts < 0.45 m sideways): a slow z bias is what keeps hover tight while the
    altitude at rest wanders."""

    bias_std_xy: float = 0.12
    bias_std_z: float = 0.4
    bias_time_xy: float = 10.0
    bias_time_z: float = 45.0
    white_xy: float = 0.01
    white_z: float = 0.02

    def __post_init__(self) -> None:
        for name in ("bias_std_xy", "bias_std_z", "white_xy", "white_z"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 10.0):
                raise ValueError(f"{name} must be within [0, 10] m, got {value}")
        for name in ("bias_time_xy", "bias_time_z"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.1 <= value <= 1e4):
                raise ValueError(f"{name} must be within [0.1, 1e4] s, got {value}")

    @property
    def horizontal_accuracy(self) -> float:
        """1-sigma horizontal error of the estimate (m), as GPS_RAW_INT h_acc reports it."""
        return math.sqrt(2.0) * math.hypot(self.bias_std_xy, self.white_xy)

    @property
    def vertical_accuracy(self) -> float:
        """1-sigma vertical error of the estimate (m), as GPS_RAW_INT v_acc reports it."""
        return math.hypot(self.bias_std_z, self.white_z)


class FleetModel:
    """The state and setpoints of N vehicles; `step(dt)` advances them all."""

    def __init__(self, count: int, limits: ModelLimits | None = None,
                 noise: EstimateNoise | None = None, seed: int = 0) -> None:
        self.limits = limits or ModelLimits()
        self.noise = noise
        self.position = np.zeros((count, 3))
        """Estimated position (what the vehicle reports and controls); = `truth` without noise."""
        self.truth = self.position
        """True position: the same array as `position` unless `noise` is set."""
        self.bias = np.zeros((count, 3))
        """Estimate minus truth, without the white noise (zero without `noise`)."""
        self.velocity = np.zeros((count, 3))
        self.acceleration = np.zeros((count, 3))
        self.position_sp = np.full((count, 3), np.nan)
        self.velocity_sp = np.zeros((count, 3))
        self.acceleration_sp = np.zeros((count, 3))
        self.powered = np.zeros(count, dtype=bool)
        """Motors running (armed); an unpowered vehicle falls and rests on the ground."""
        lim = self.limits
        self.velocity_xy_max = np.full(count, lim.velocity_xy_max)
        """Each vehicle's horizontal speed limit (m/s; MPC_XY_VEL_MAX, set per vehicle)."""
        self.velocity_up_max = np.full(count, lim.velocity_up_max)
        """Each vehicle's climb speed limit (m/s; MPC_Z_VEL_MAX_UP)."""
        self.velocity_down_max = np.full(count, lim.velocity_down_max)
        """Each vehicle's descent speed limit (m/s; MPC_Z_VEL_MAX_DN)."""
        self._kp = np.array([lim.pos_gain_xy, lim.pos_gain_xy, lim.pos_gain_z])
        self._kv = np.array([lim.vel_gain_xy, lim.vel_gain_xy, lim.vel_gain_z])
        self.recovered = 0
        """Vehicle steps undone because the state would have become non-finite."""
        self._rng = np.random.default_rng(seed)
        if noise is not None:  # start where the error process settles (seeded)
            self._bias_std = np.array([noise.bias_std_xy, noise.bias_std_xy, noise.bias_std_z])
            self._bias_time = np.array([noise.bias_time_xy, noise.bias_time_xy,
                                        noise.bias_time_z])
            self._white = np.array([noise.white_xy, noise.white_xy, noise.white_z])
            self.truth = np.zeros((count, 3))
            self.bias = self._bias_std * self._rng.standard_normal((count, 3))
            self._update_estimate()

    def hold(self, index: int, position: FloatArray) -> None:
        """Hold `position` at rest."""
        self.position_sp[index] = position
        self.velocity_sp[index] = 0.0
        self.acceleration_sp[index] = 0.0

    def descend(self, index: int, speed: float) -> None:
        """Hold the current horizontal position and descend at `speed` (m/s)."""
        self.position_sp[index] = (self.position[index, 0], self.position[index, 1], np.nan)
        self.velocity_sp[index] = (0.0, 0.0, speed)
        self.acceleration_sp[index] = 0.0

    def step(self, dt: float) -> None:
        before = self.truth.copy()
        with np.errstate(all="ignore"):
            self._integrate(dt)
            if self.noise is not None:
                self._advance_bias(dt)
                self._update_estimate()
        state = np.hstack((self.position, self.truth, self.velocity, self.acceleration))
        bad = ~np.all(np.isfinite(state) & (np.abs(state) < _FAR), axis=1)
        if np.any(bad):  # undo those vehicles' step and hold them where they were
            self.recovered += int(np.count_nonzero(bad))
            back = np.nan_to_num(before[bad], nan=0.0, posinf=_FAR, neginf=-_FAR)
            # the last position if it was sane, else the nearest sane one
            self.truth[bad] = np.clip(back, -0.1 * _FAR, 0.1 * _FAR)
            if self.noise is not None:
                self.bias[bad] = 0.0
                self.position[bad] = self.truth[bad]
            self.velocity[bad] = 0.0
            self.acceleration[bad] = 0.0
            self.position_sp[bad] = self.position[bad]
            self.velocity_sp[bad] = 0.0
            self.acceleration_sp[bad] = 0.0

    def _advance_bias(self, dt: float) -> None:
        """One exact step of the Gauss-Markov bias (stationary std kept for any dt)."""
        decay = np.exp(-dt / self._bias_time)
        spread = self._bias_std * np.sqrt(1.0 - decay * decay)
        self.bias = decay * self.bias + spread * self._rng.standard_normal(self.bias.shape)

    def _update_estimate(self) -> None:
        white = self._white * self._rng.standard_normal(self.truth.shape)
        self.position[:] = self.truth + self.bias + white

    def _integrate(self, dt: float) -> None:
        # Feedback on the estimate (`position`), motion of the truth (`truth`; the same array
        # without noise).
        lim = self.limits
        p_err = np.nan_to_num(self.position_sp - self.position, nan=0.0)
        v_ref = np.nan_to_num(self.velocity_sp, nan=0.0) + self._kp * p_err
        horizontal = np.linalg.norm(v_ref[:, :2], axis=1)
        scale = np.minimum(1.0, self.velocity_xy_max / np.maximum(horizontal, 1e-12))
        v_ref[:, :2] *= scale[:, None]
        v_ref[:, 2] = np.clip(v_ref[:, 2], -self.velocity_up_max, self.velocity_down_max)
        a_cmd = np.nan_to_num(self.acceleration_sp, nan=0.0) + self._kv * (v_ref - self.velocity)
        horizontal = np.linalg.norm(a_cmd[:, :2], axis=1)
        scale = np.minimum(1.0, lim.acceleration_xy_max / np.maximum(horizontal, 1e-12))
        a_cmd[:, :2] *= scale[:, None]
        a_cmd[:, 2] = np.clip(a_cmd[:, 2], -lim.acceleration_up_max, lim.acceleration_down_max)
        a_cmd[~self.powered] = (0.0, 0.0, GRAVITY)  # motors off: free fall
        alpha = min(1.0, dt / lim.thrust_time_constant)
        self.acceleration += alpha * (a_cmd - self.acceleration)
        self.velocity += self.acceleration * dt
        self.truth += self.velocity * dt
        on_ground = self.truth[:, 2] >= 0.0
        if np.any(on_ground):
            self.truth[on_ground, 2] = 0.0
            self.velocity[on_ground, 2] = np.minimum(self.velocity[on_ground, 2], 0.0)
            resting = on_ground & ~self.powered
            self.velocity[resting] = 0.0
            self.acceleration[resting] = 0.0
            pushing_down = on_ground & (self.acceleration[:, 2] > 0.0)
            self.acceleration[pushing_down, 2] = 0.0
            # friction on the ground: no sliding while the thrust does not lift
            sliding = on_ground & (self.velocity[:, 2] >= 0.0)
            self.velocity[sliding, :2] = 0.0
