"""One PX4-like vehicle of a mock fleet (`MockVehicle`): its protocol and flight rules.

It speaks what a PX4 quadrotor speaks for our purposes: HEARTBEAT (MAV_TYPE_QUADROTOR,
MAV_AUTOPILOT_PX4, custom mode main << 16 | sub << 24, armed flag), SYS_STATUS (sensors present,
enabled, healthy; the pre-arm bit healthy once settled), HOME_POSITION, GPS_GLOBAL_ORIGIN,
EXTENDED_SYS_STATE, LOCAL_POSITION_NED, ATTITUDE, GLOBAL_POSITION_INT, AUTOPILOT_VERSION,
STATUSTEXT and COMMAND_ACK (COMMAND_LONG and COMMAND_INT), and answers
MAV_CMD_REQUEST_MESSAGE. Its periodic streams, their rates (``minimal``, or PX4's offboard-link
set of about 410 messages/s with ``MockConfig.telemetry_profile = "px4"``) and
MAV_CMD_SET_MESSAGE_INTERVAL on each are `gcs.sim.telemetry`. PX4's rules, as in its
mavlink_receiver and commander:

- SET_POSITION_TARGET_LOCAL_NED is taken only for target system = own id or 0 (component own
  or 0), frame MAV_FRAME_LOCAL_NED (BODY_NED: velocity/acceleration only); IGNORE bits become
  NaN; a message with nothing left, or with the FORCE bit and an acceleration, is ignored.
  Every accepted message is proof of life for offboard, in any mode. A setpoint with a used
  field (IGNORE bit clear) that is not finite, or beyond `SETPOINT_LIMITS` (absurd for a
  quadrotor), is refused whole and counted in `setpoints_invalid`: the vehicle keeps its last
  valid setpoint and the message is no proof of life.
- STATUSTEXT says what PX4 says ("Preflight Fail: ...", "Arming denied: Resolve system health
  failures first"), never cut: a text over 50 bytes goes as MAVLink 2 chunks (same `id`,
  counting `chunk_seq`, split after a space so no word is cut), and the same text is not
  repeated within `STATUSTEXT_REPEAT_S` (a GCS retrying arming gets it once, like PX4's
  rate-limited health reports).
- An exception while handling a datagram is counted (`errors`) and logged, never raised into
  asyncio (which would close the vehicle's socket and silence it).
- OFFBOARD is refused (TEMPORARILY_REJECTED) unless such a setpoint arrived within
  COM_OF_LOSS_T; arming is TEMPORARILY_REJECTED during `settle_time` after start.
- DO_SET_MODE and REQUEST_MESSAGE are ACKed twice, like PX4 does.
- AUTO.RTL flies back over home at its height, then lands; MAV_CMD_DO_FLIGHTTERMINATION stops
  the motors (it falls), HEARTBEAT then says MAV_STATE_FLIGHT_TERMINATION and arming is denied.
- Offboard loss (no setpoint for COM_OF_LOSS_T) triggers the failsafe: Position mode (hold),
  then, there being no RC, AUTO.LAND after `failsafe_land_delay`; auto-disarm 2 s after
  landing, and 10 s after arming without taking off.

It speaks MAVLink through pymavlink directly, never through `gcs.flight`: a wire-level mistake
in our link must not be repeated by the stand-in that should catch it. It shares on purpose only
constants and pure functions: the PX4 facts table (`gcs.px4`: modes, timeouts), frame
conversions (`gcs.frames`) and the MAVLink facts of `gcs.wire` (dialect, type-mask bits,
`time_boot_ms`, the datagram adapter).

The motion is `gcs.sim.model.FleetModel`, integrated at `physics_rate` (>= 100 Hz) for the
whole fleet at once. The battery drains while armed (`MockConfig.battery_drain`); GPS_RAW_INT
goes out at `gps_rate`; messages carry counting sequence numbers, so a lost one leaves a gap
the GCS can count.

Signing, as PX4's documentation describes it (PX4 >= 1.17, "MAVLink Message Signing"): a key
arrives with SETUP_SIGNING (accepted unsigned only while the vehicle has no key; changing or
clearing it needs a message signed with the current key; refused while armed; an all-zero key
and timestamp clears it), or is there from the start (`MockFleet(signing_key=...)`: the key
file on the SD card). While it has a key, every outgoing message is signed and incoming
unsigned or wrongly signed ones are rejected, except PX4's documented few
(`gcs.wire.PX4_UNSIGNED_ACCEPTED`). The signature checks are pymavlink's own, not ours.
Each datagram is decoded by a fresh parser.

Realism (`MockConfig.preset`): "ideal" reports the exact state; "px4" (`MockConfig.px4_like`)
reports a noisy, wandering estimate (`gcs.sim.model.EstimateNoise`) with its accuracy in
GPS_RAW_INT, lags like PX4's attitude loop, is deaf and silent for `boot_time` after start,
refuses arming for 3.5 s and sends the second ACK of a doubly-ACKed command a little later.

Faults can be injected per vehicle at any time through `MockVehicle.faults` (`MockFaults`):
packet loss, stopped heartbeats, delay, refused arming, non-finite position reports, battery
level, unhealthy sensors (SYS_STATUS), GPS fix.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import math
import random
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from gcs import frames, px4, wire
from gcs.sim import telemetry
from gcs.sim.model import EstimateNoise, FleetModel, ModelLimits
from gcs.wire import PX4_UNSIGNED_ACCEPTED, mavlink, signing_timestamp, time_boot_ms

if TYPE_CHECKING:
    from gcs.sim.fleet import MockFleet

__all__ = ["REALISMS", "SETPOINT_LIMITS", "STATUSTEXT_REPEAT_S", "MockConfig", "MockFaults",
           "MockVehicle", "ReceivedSetpoint", "setpoint_problem", "statustext_chunks"]

_log = logging.getLogger(__name__)

_SENSORS = (
    mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink.MAV_SYS_STATUS_SENSOR_GPS | mavlink.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mavlink.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | mavlink.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | mavlink.MAV_SYS_STATUS_AHRS
    | mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
)
_PREARM = mavlink.MAV_SYS_STATUS_PREARM_CHECK

# POSITION_TARGET_TYPEMASK bits (pymavlink's enum): X, Y, Z ignore are 1, 2, 4 times the
# first bit of each triple, and so on.
_IGNORE_X = mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE
_IGNORE_VX = mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE
_IGNORE_AX = mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE
_FORCE = mavlink.POSITION_TARGET_TYPEMASK_FORCE_SET
_IGNORE_YAW = mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
_IGNORE_YAW_RATE = mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE

#: Largest |component| of a used setpoint field the mock takes (LOCAL_NED, m, m/s, m/s^2):
#: far beyond any quadrotor, so only garbage is refused.
SETPOINT_LIMITS = {"position": 1e5, "velocity": 1e3, "acceleration": 1e3}
#: STATUSTEXT carries at most 50 bytes of text per message.
STATUSTEXT_LEN = 50
#: The same STATUSTEXT is not sent again within this many seconds.
STATUSTEXT_REPEAT_S = 3.0
#: PX4 v1.16.0 release: major << 24 | minor << 16 | patch << 8 | FIRMWARE_VERSION_TYPE_OFFICIAL
_PX4_VERSION = (1 << 24) | (16 << 16) | (0 << 8) | 255


def setpoint_problem(msg: Any) -> str | None:
    """Why a SET_POSITION_TARGET_LOCAL_NED must be refused (a used field not finite or absurd),
    or None. Fields whose IGNORE bit is set are not looked at."""
    mask = msg.type_mask
    groups = (("position", _IGNORE_X, (msg.x, msg.y, msg.z)),
              ("velocity", _IGNORE_VX, (msg.vx, msg.vy, msg.vz)),
              ("acceleration", _IGNORE_AX, (msg.afx, msg.afy, msg.afz)))
    for name, first_bit, values in groups:
        for k, value in enumerate(values):
            if mask & (first_bit << k):
                continue
            if not math.isfinite(value):
                return f"{name} not finite"
            if abs(value) > SETPOINT_LIMITS[name]:
                return f"{name} beyond {SETPOINT_LIMITS[name]:g}"
    if not mask & _IGNORE_YAW and not math.isfinite(msg.yaw):
        return "yaw not finite"
    if not mask & _IGNORE_YAW_RATE and not math.isfinite(msg.yaw_rate):
        return "yaw_rate not finite"
    return None


def statustext_chunks(text: str) -> list[str]:
    """`text` in pieces of at most `STATUSTEXT_LEN` bytes whose concatenation is `text`, each
    cut just after a space where there is one (MAVLink 2 STATUSTEXT chunking). With several
    pieces the last is shorter than the limit, so its NUL padding marks the end."""
    data = text.encode()
    if len(data) <= STATUSTEXT_LEN:
        return [text]
    chunks: list[str] = []
    rest = data
    while len(rest) >= STATUSTEXT_LEN:
        space = rest.rfind(b" ", 0, STATUSTEXT_LEN)
        cut = space + 1 if space > 0 else STATUSTEXT_LEN - 1
        chunks.append(rest[:cut].decode(errors="replace"))
        rest = rest[cut:]
    chunks.append(rest.decode(errors="replace"))
    return chunks


_statustext_ids = itertools.count(1)

#: The mock's behaviour presets (`MockConfig.preset`): "ideal" (exact state, no lag; the
#: default) and "px4" (PX4 v1.16 SIH SITL's measured estimate noise, lag and timings).
REALISMS = ("ideal", "px4")


@dataclass
class MockConfig:
    """Behaviour shared by every vehicle of a `MockFleet` (PX4 defaults unless said)."""

    settle_time: float = 5.0
    """Arming is TEMPORARILY_REJECTED this long after start (PX4 SITL: about 4-5 s)."""
    offboard_loss_timeout: float = px4.COM_OF_LOSS_T_S
    """COM_OF_LOSS_T (s)."""
    failsafe_land_delay: float = 1.0
    """After the offboard-loss failsafe has held position this long, land (no RC)."""
    disarm_after_land: float = px4.COM_DISARM_LAND_S
    """COM_DISARM_LAND (s)."""
    disarm_preflight: float = px4.COM_DISARM_PRFLT_S
    """COM_DISARM_PRFLT (s)."""
    land_speed: float = 0.7
    """MPC_LAND_SPEED (m/s)."""
    physics_rate: float = 200.0
    """Integration rate of the vehicle model (Hz, >= 100)."""
    position_rate: float = 30.0
    """LOCAL_POSITION_NED rate (Hz), as PX4's onboard link streams it."""
    attitude_rate: float = 20.0
    global_position_rate: float = 5.0
    status_rate: float = 1.0
    """HEARTBEAT, SYS_STATUS, EXTENDED_SYS_STATE rate (Hz)."""
    battery_drain: float = 0.05
    """Battery drain while armed (% per second; a 20-minute battery)."""
    gps_rate: float = 5.0
    """GPS_RAW_INT rate (Hz)."""
    telemetry_profile: str = "minimal"
    """What the offboard link sends (`gcs.sim.telemetry`): ``minimal`` (the rates above, about
    65 messages/s) or ``px4`` (PX4's offboard-link set and rates, about 410 messages/s)."""
    record_setpoints: bool = False
    """Keep every accepted setpoint in `MockVehicle.received` (for tests)."""
    limits: ModelLimits = field(default_factory=ModelLimits)
    realism: str = "ideal"
    """Which preset this is (`REALISMS`); set by `preset`, informational."""
    seed: int = 0
    """Seed of every random process of the fleet (estimate noise, injected loss)."""
    estimate_noise: EstimateNoise | None = None
    """The position estimate's error process (None: exact, as in the ideal mode)."""
    boot_time: float = 0.0
    """Nothing is sent or answered this long after start; the first HEARTBEAT then goes at
    the next 1 s tick (2 s for 1.5 s; PX4 SITL: 1.7-2.7 s)."""
    duplicate_ack_delay: float = 0.0
    """DO_SET_MODE and REQUEST_MESSAGE are ACKed twice; the second ACK goes this much later (s)."""

    @classmethod
    def preset(cls, realism: str = "ideal", **overrides: Any) -> MockConfig:
        """The named preset (`REALISMS`), with `overrides` applied (unknown names: TypeError)."""
        if realism not in REALISMS:
            raise ValueError(f"realism must be one of {', '.join(REALISMS)}, got {realism!r}")
        config = cls.px4_like() if realism == "px4" else cls()
        for key, value in overrides.items():
            if not hasattr(config, key):
                raise TypeError(f"unknown mock setting {key!r}")
            setattr(config, key, value)
        return config

    @classmethod
    def px4_like(cls) -> MockConfig:
        """PX4 v1.16 SIH SITL as measured (README "Mock realism" has the figures): a wandering
        position estimate (GPS-like altitude noise), the attitude loop's lag, arming refused
        for 3.5 s after boot, deaf and silent for 1.5 s (first HEARTBEAT at 2 s), PX4's
        offboard message set."""
        return cls(realism="px4", settle_time=3.5, boot_time=1.5,
                   estimate_noise=EstimateNoise(), duplicate_ack_delay=0.005,
                   telemetry_profile="px4",
                   limits=ModelLimits(thrust_time_constant=0.15))


@dataclass
class MockFaults:
    """Faults injected into one mock vehicle; change them at any time."""

    loss: float = 0.0
    """Fraction of packets dropped, each direction independently (0..1)."""
    heartbeats: bool = True
    """False: stop sending HEARTBEAT (everything else continues)."""
    silent: bool = False
    """True: send nothing at all (a dead radio or a crashed companion link)."""
    delay: float = 0.0
    """Seconds added to every packet, both directions."""
    refuse_arming: bool = False
    """Arming answered DENIED."""
    nan_position: bool = False
    """LOCAL_POSITION_NED reports NaN position and velocity (a broken estimator)."""
    battery: float | None = None
    """Battery remaining (%) reported instead of the simulated one."""
    unhealthy: int = 0
    """SYS_STATUS sensor bits reported present and enabled but not healthy."""
    gps_fix: int | None = None
    """GPS_RAW_INT fix_type reported instead of 3 (3D fix)."""


@dataclass(frozen=True)
class ReceivedSetpoint:
    """A SET_POSITION_TARGET_LOCAL_NED the mock accepted (values after IGNORE -> NaN)."""

    time: float
    """Mock clock (s since start)."""
    time_boot_ms: int
    target_system: int
    target_component: int
    frame: int
    type_mask: int
    position: tuple[float, float, float]
    velocity: tuple[float, float, float]
    acceleration: tuple[float, float, float]
    yaw: float


class MockVehicle:
    """One PX4-like vehicle: protocol, flight-mode rules, failsafes. Owned by a `MockFleet`."""

    def __init__(self, fleet: MockFleet, index: int, home_world: ArrayLike,
                 gcs_address: tuple[str, int], listen_address: tuple[str, int]) -> None:
        self.fleet = fleet
        self.index = index
        self.system_id = index + 1
        self.component_id = 1
        self.home_world = np.asarray(home_world, dtype=float)
        self.origin = frames.enu_to_geodetic(self.home_world, fleet.world_origin)
        """Geodetic EKF origin (= home) reported in GPS_GLOBAL_ORIGIN and HOME_POSITION."""
        self.gcs_address = gcs_address
        """Where telemetry goes: the configured GCS port until someone speaks to us."""
        self.gcs_port = gcs_address[1]
        self.listen_address = listen_address
        self.faults = MockFaults()
        self.mode = px4.HOLD
        self.armed = False
        self.in_air = False
        self.failsafe = False
        self.terminated = False
        """MAV_CMD_DO_FLIGHTTERMINATION received: motors off until restart."""
        self.yaw = 0.0
        self.received: list[ReceivedSetpoint] = []
        self.setpoints_accepted = 0
        self.setpoints_ignored = 0
        self.setpoints_invalid = 0
        """Setpoints refused for a used field not finite or absurd (`setpoint_problem`)."""
        self.errors = 0
        """Exceptions caught while handling this vehicle (datagrams, rules, telemetry)."""
        self._said: dict[str, float] = {}
        self.statustexts: list[str] = []
        self.events: list[tuple[float, str]] = []
        """(mock time, what happened): mode changes, arming, failsafes."""
        self._last_setpoint_time = -math.inf
        self._armed_time = 0.0
        self.battery = 100.0
        self._battery_t = 0.0
        """Simulated battery remaining (%): drains while armed (`MockConfig.battery_drain`)."""
        self._landed_since: float | None = None
        self._failsafe_since: float | None = None
        self._mav = mavlink.MAVLink(None, srcSystem=self.system_id,
                                    srcComponent=self.component_id)
        self.rejected = 0
        """Incoming packets rejected: bad CRC, truncated, or (with a key) unsigned or badly
        signed (pymavlink's signing counters say which)."""
        self._transport: asyncio.DatagramTransport | None = None
        self._rng = random.Random(fleet.seed * 1000 + index)
        self._defaults = telemetry.default_rates(fleet.config)
        self.intervals: dict[int, float | None] = {
            msg_id: (1.0 / hz if hz > 0 else None) for msg_id, hz in self._defaults.items()}
        """Period (s) of each stream of `gcs.sim.telemetry.STREAMS` by message id (None: off);
        MAV_CMD_SET_MESSAGE_INTERVAL changes it."""
        self._next = dict.fromkeys(self.intervals, 0.0)
        self.sent: dict[int, int] = dict.fromkeys(self.intervals, 0)
        """Messages sent per stream (counted before any injected loss)."""

    # ------------------------------------------------------------------ state

    @property
    def model(self) -> FleetModel:
        return self.fleet.model

    @property
    def position_ned(self) -> np.ndarray:
        return self.model.position[self.index].copy()

    @property
    def velocity_ned(self) -> np.ndarray:
        return self.model.velocity[self.index].copy()

    @property
    def position_world(self) -> np.ndarray:
        """Where it reports it is (its estimate; exact in the ideal mode), world frame."""
        return frames.ned_to_world(self.model.position[self.index], self.home_world)

    @property
    def true_position_world(self) -> np.ndarray:
        """Where it really is, world frame (= `position_world` in the ideal mode)."""
        return frames.ned_to_world(self.model.truth[self.index], self.home_world)

    @property
    def config(self) -> MockConfig:
        return self.fleet.config

    def _now(self) -> float:
        return self.fleet.now()

    def _event(self, what: str) -> None:
        self.events.append((self._now(), what))

    def _set_mode(self, mode: px4.Px4Mode) -> None:
        if mode == self.mode:
            return
        self._event(f"mode {self.mode.name} -> {mode.name}")
        self.mode = mode
        i = self.index
        if mode == px4.LAND:
            self.model.descend(i, self.config.land_speed)
        elif mode == px4.RTL:  # back over home at the current height, then down (tick)
            self.model.hold(i, np.array([0.0, 0.0, self.model.position[i, 2]]))
        elif mode in (px4.HOLD, px4.POSITION):
            self.model.hold(i, self.model.position[i].copy())
        if mode != px4.POSITION:
            self._failsafe_since = None
            self.failsafe = False

    def _arm(self) -> None:
        self.armed = True
        self._armed_time = self._now()
        self.model.powered[self.index] = True
        if self.mode in (px4.HOLD, px4.POSITION):
            self.model.hold(self.index, self.model.position[self.index].copy())
        self._event("armed")

    def _disarm(self, why: str) -> None:
        if not self.armed:
            return
        self.armed = False
        self.model.powered[self.index] = False
        self._landed_since = None
        self._event(f"disarmed ({why})")
        self.statustext(mavlink.MAV_SEVERITY_INFO, f"Disarmed by {why}")

    # ---------------------------------------------------------------- periodic

    def forgive_stall(self, seconds: float) -> None:
        """The mock's own process did not run for `seconds` (a real PX4 runs on): that time
        does not count towards the offboard-loss timeout."""
        self._last_setpoint_time += seconds

    def tick(self, now: float) -> None:
        """Rules that run with the clock: failsafes, landing detection, auto-disarm."""
        cfg = self.config
        i = self.index
        z = self.model.truth[i, 2]  # PX4's land detector goes by thrust and motion, not the
        vz = self.model.velocity[i, 2]  # estimated altitude (which wanders on the ground)
        if self.armed and z < -0.3:
            self.in_air = True
        if self.armed:
            self.battery = max(0.0, self.battery - cfg.battery_drain * (now - self._battery_t))
        self._battery_t = now
        if self.mode == px4.OFFBOARD and now - self._last_setpoint_time > cfg.offboard_loss_timeout:
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL,
                            "Failsafe activated: offboard signal lost")
            self._set_mode(px4.POSITION)
            self.failsafe = True
            self._failsafe_since = now
            self._event("failsafe: offboard loss")
        if (self.failsafe and self._failsafe_since is not None
                and now - self._failsafe_since >= cfg.failsafe_land_delay):
            self._failsafe_since = None
            if self.in_air:
                self.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Failsafe: no RC, landing")
                self._set_mode(px4.LAND)
                self.failsafe = True
        if (self.mode == px4.RTL and self.armed and np.isfinite(self.model.position_sp[i, 2])
                and np.linalg.norm(self.model.position[i, :2]) < 0.2):
            self.model.descend(i, cfg.land_speed)  # RTL's landing phase
        if not self.armed:
            if self.terminated and z >= -0.05:
                self.in_air = False
            return
        on_ground = z >= -0.05 and abs(vz) < 0.2
        if self.in_air:
            if on_ground and self.mode in (px4.LAND, px4.RTL):
                if self._landed_since is None:
                    self._landed_since = now
                    self.statustext(mavlink.MAV_SEVERITY_INFO, "Landing detected")
                elif now - self._landed_since >= cfg.disarm_after_land:
                    self.in_air = False
                    self._disarm("auto disarm on land")
            else:
                self._landed_since = None
        elif now - self._armed_time >= cfg.disarm_preflight:
            self._disarm("auto preflight disarming")

    def send_telemetry(self, now: float) -> None:
        """Every stream due at `now` (`gcs.sim.telemetry`), at most one message each: a
        stream that fell behind by more than a period restarts from now (no burst)."""
        due = self._next
        for msg_id, period in self.intervals.items():
            if period is None or now < due[msg_id]:
                continue
            nxt = due[msg_id] + period
            due[msg_id] = nxt if nxt > now else now + period
            msg = telemetry.BY_ID[msg_id].build(self, now)
            if msg is not None:
                self.sent[msg_id] += 1
                self._send(msg)

    # ---------------------------------------------------------------- messages out

    def _heartbeat(self) -> Any:
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.mode.main in (px4.MainMode.AUTO, px4.MainMode.OFFBOARD):
            base |= mavlink.MAV_MODE_FLAG_AUTO_ENABLED | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
        elif self.mode.main == px4.MainMode.POSCTL:
            base |= (mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
                     | mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED)
        if self.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        state = (mavlink.MAV_STATE_FLIGHT_TERMINATION if self.terminated else
                 mavlink.MAV_STATE_CRITICAL if self.failsafe else
                 mavlink.MAV_STATE_ACTIVE if self.armed else mavlink.MAV_STATE_STANDBY)
        return self._mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                          base, self.mode.custom_mode, state)

    def _sys_status(self, now: float) -> Any:
        settled = now >= self.config.settle_time
        present = _SENSORS | _PREARM
        health = (_SENSORS | (_PREARM if settled or self.armed else 0)) & ~self.faults.unhealthy
        remaining = self.battery if self.faults.battery is None else self.faults.battery
        voltage = round(1000 * (13.2 + 3.6 * remaining / 100.0))  # 4S: 13.2 V empty, 16.8 full
        return self._mav.sys_status_encode(present, present, health, 250, voltage, 1200,
                                           round(remaining), 0, 0, 0, 0, 0, 0)

    def _gps_raw(self, now: float) -> Any:
        g = self._geodetic_now()
        fix = 3 if self.faults.gps_fix is None else self.faults.gps_fix
        noise = self.config.estimate_noise
        h_acc, v_acc = (50, 80) if noise is None else (  # mm: ideal, or the noise's 1 sigma
            round(noise.horizontal_accuracy * 1000), round(noise.vertical_accuracy * 1000))
        return self._mav.gps_raw_int_encode(
            int(now * 1e6), fix, round(g.lat * 1e7), round(g.lon * 1e7), round(g.alt * 1000),
            80, 120, 0, 0, 12 if fix >= 3 else 0, 0, h_acc, v_acc, 100, 0, 0)

    def _geodetic_now(self) -> frames.Geodetic:
        offset = frames.ned_vector_to_world(self.model.position[self.index])
        return frames.enu_to_geodetic(self.home_world + offset, self.fleet.world_origin)

    def _global_position(self, now: float) -> Any:
        g = self._geodetic_now()
        v = self.model.velocity[self.index]
        heading = int(math.degrees(self.yaw) % 360.0 * 100)
        return self._mav.global_position_int_encode(
            time_boot_ms(now), round(g.lat * 1e7), round(g.lon * 1e7), round(g.alt * 1000),
            round(-self.model.position[self.index, 2] * 1000), round(v[0] * 100),
            round(v[1] * 100), round(v[2] * 100), heading)

    def _home_position(self, now: float) -> Any:
        o = self.origin
        return self._mav.home_position_encode(
            round(o.lat * 1e7), round(o.lon * 1e7), round(o.alt * 1000), 0.0, 0.0, 0.0,
            [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, int(now * 1e6))

    def _gps_origin(self, now: float) -> Any:
        o = self.origin
        return self._mav.gps_global_origin_encode(
            round(o.lat * 1e7), round(o.lon * 1e7), round(o.alt * 1000), int(now * 1e6))

    def _autopilot_version(self) -> Any:
        caps = (mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | mavlink.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
                | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT)
        return self._mav.autopilot_version_encode(
            caps, _PX4_VERSION, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, self.system_id)

    def statustext(self, severity: int, text: str) -> None:
        """Send `text` whole (in chunks if long), unless it was sent in the last
        `STATUSTEXT_REPEAT_S` seconds."""
        now = self._now()
        if now - self._said.get(text, -math.inf) < STATUSTEXT_REPEAT_S:
            return
        self._said[text] = now
        self.statustexts.append(text)
        chunks = statustext_chunks(text)
        text_id = 0 if len(chunks) == 1 else next(_statustext_ids) % 65535 + 1
        for seq, chunk in enumerate(chunks):
            self._send(self._mav.statustext_encode(severity, chunk.encode(), text_id, seq))

    def _send(self, msg: Any) -> None:
        if self._transport is None:
            return
        faults = self.faults
        if faults.silent or self._booting():
            return
        buf = wire.pack(msg, self._mav)  # packed first: a lost message leaves a sequence gap
        if faults.loss > 0.0 and self._rng.random() < faults.loss:
            return
        if faults.delay > 0.0:
            asyncio.get_running_loop().call_later(faults.delay, self._sendto, buf)
        else:
            self._sendto(buf)

    def _sendto(self, buf: bytes) -> None:
        if self._transport is not None:
            self._transport.sendto(buf, self.gcs_address)

    def _booting(self) -> bool:
        """Still booting (`MockConfig.boot_time`): deaf and silent, like PX4 before its first
        HEARTBEAT."""
        return self.config.boot_time > 0.0 and self._now() < self.config.boot_time

    def _ack(self, msg: Any, command: int, result: int, times: int = 1) -> None:
        """COMMAND_ACK `times` times; repeats `MockConfig.duplicate_ack_delay` apart."""
        ack = self._mav.command_ack_encode(command, result, 0, 0, msg.get_srcSystem(),
                                           msg.get_srcComponent())
        self._send(ack)
        delay = self.config.duplicate_ack_delay
        for k in range(1, times):
            if delay > 0.0:
                asyncio.get_running_loop().call_later(k * delay, self._send, ack)
            else:
                self._send(ack)

    # ---------------------------------------------------------------- messages in

    def received_datagram(self, data: bytes, address: tuple[str, int]) -> None:
        faults = self.faults
        if self._booting():
            return
        if faults.loss > 0.0 and self._rng.random() < faults.loss:
            return
        if faults.delay > 0.0:
            asyncio.get_running_loop().call_later(faults.delay, self._process_guarded, data,
                                                  address)
        else:
            self._process_guarded(data, address)

    def _process_guarded(self, data: bytes, address: tuple[str, int]) -> None:
        """`_process`, counting and logging any exception instead of raising it into asyncio
        (which would close this vehicle's socket: one bad packet must not silence it)."""
        try:
            self._process(data, address)
        except Exception:
            self.record_error("handling a datagram")

    def record_error(self, doing: str) -> None:
        """Count an exception caught while `doing` something; log the first ones in full."""
        self.errors += 1
        if self.errors <= 3:
            _log.exception("mock vehicle %d: error %s (count %d)", self.system_id, doing,
                           self.errors)

    @property
    def signing_key(self) -> bytes | None:
        """The key it holds (None: signing off)."""
        return self._mav.signing.secret_key

    def set_signing_key(self, key: bytes | None, initial_timestamp: int = 0) -> None:
        """Install (or with None clear) the signing key, as PX4 does on SETUP_SIGNING."""
        signing = self._mav.signing
        if key is None:
            signing.secret_key = None
            signing.sign_outgoing = False
            signing.allow_unsigned_callback = None
            return
        signing.secret_key = bytes(key)
        signing.sign_outgoing = True
        signing.timestamp = max(signing.timestamp, initial_timestamp,
                                signing_timestamp(time.time()))
        signing.allow_unsigned_callback = lambda _mav, msg_id: msg_id in PX4_UNSIGNED_ACCEPTED
        signing.stream_timestamps.clear()

    def _process(self, data: bytes, address: tuple[str, int]) -> None:
        # A fresh parser per datagram (a packet never spans datagrams), with this vehicle's
        # signing state: pymavlink checks signatures and timestamps in `decode`.
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        parser.signing = self._mav.signing
        try:
            messages = parser.parse_buffer(data) or []
        except mavlink.MAVError:
            self.rejected += 1
            return
        for msg in messages:
            kind = msg.get_type()
            if kind == "BAD_DATA":
                self.rejected += 1
                continue
            self.gcs_address = address  # PX4 answers whoever last spoke to it
            if kind == "SET_POSITION_TARGET_LOCAL_NED":
                self._on_setpoint(msg)
            elif kind in ("COMMAND_LONG", "COMMAND_INT"):
                self._on_command(msg, kind == "COMMAND_INT")
            elif kind == "SETUP_SIGNING":
                self._on_setup_signing(msg)

    def _on_setup_signing(self, msg: Any) -> None:
        """Reaching here it passed pymavlink's checks: with a key set, it was signed with it."""
        if msg.target_system != self.system_id or msg.target_component not in (
                0, self.component_id):
            return
        if self.armed:
            self.statustext(mavlink.MAV_SEVERITY_WARNING, "Signing change denied: armed")
            return
        key = bytes(msg.secret_key)
        if not any(key) and msg.initial_timestamp == 0:
            self.set_signing_key(None)
            self._event("signing disabled")
        else:
            self.set_signing_key(key, msg.initial_timestamp)
            self._event("signing key set")

    def _on_setpoint(self, msg: Any) -> None:
        if (msg.target_system not in (0, self.system_id)
                or msg.target_component not in (0, self.component_id)):
            return
        mask = msg.type_mask
        now = self._now()
        if setpoint_problem(msg) is not None:  # keep holding the last valid setpoint
            self.setpoints_invalid += 1
            return

        def field3(first_bit: int, values: tuple[float, float, float]) -> tuple[float, ...]:
            return tuple(math.nan if mask & (first_bit << k) else float(values[k])
                         for k in range(3))

        pos = field3(_IGNORE_X, (msg.x, msg.y, msg.z))
        vel = field3(_IGNORE_VX, (msg.vx, msg.vy, msg.vz))
        acc = field3(_IGNORE_AX, (msg.afx, msg.afy, msg.afz))
        if msg.coordinate_frame == mavlink.MAV_FRAME_BODY_NED:
            c, s = math.cos(self.yaw), math.sin(self.yaw)

            def rotate(v: tuple[float, ...]) -> tuple[float, ...]:
                if all(math.isnan(x) for x in v):
                    return v
                x, y, z = (0.0 if math.isnan(e) else e for e in v)
                return (c * x - s * y, s * x + c * y, z)

            pos, vel, acc = (math.nan,) * 3, rotate(vel), rotate(acc)
        elif msg.coordinate_frame != mavlink.MAV_FRAME_LOCAL_NED:
            self.setpoints_ignored += 1
            return
        has_acc = not all(math.isnan(x) for x in acc)
        usable = has_acc or not all(math.isnan(x) for x in pos + vel)
        if not usable or (has_acc and mask & _FORCE):
            self.setpoints_ignored += 1
            return
        self._last_setpoint_time = now
        self.setpoints_accepted += 1
        yaw = math.nan if mask & _IGNORE_YAW else msg.yaw
        if self.config.record_setpoints:
            self.received.append(ReceivedSetpoint(
                now, msg.time_boot_ms, msg.target_system, msg.target_component,
                msg.coordinate_frame, mask, pos, vel, acc, yaw))  # type: ignore[arg-type]
        if self.mode == px4.OFFBOARD:
            i = self.index
            self.model.position_sp[i] = pos
            self.model.velocity_sp[i] = vel
            self.model.acceleration_sp[i] = acc
            if not math.isnan(yaw):
                self.yaw = yaw

    def _on_command(self, msg: Any, is_int: bool) -> None:
        if msg.target_system != self.system_id or msg.target_component not in (
                0, self.component_id):
            return
        cmd = msg.command
        p1, p2, p3 = msg.param1, msg.param2, msg.param3
        now = self._now()
        if cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if p1 >= 0.5:
                self._on_arm(msg, now)
            elif not self.armed or not self.in_air or p2 == px4.DISARM_FORCE_MAGIC:
                self._disarm("external command")
                self.in_air = False
                self._ack(msg, cmd, mavlink.MAV_RESULT_ACCEPTED)
            else:
                self.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Disarming denied: not landed")
                self._ack(msg, cmd, mavlink.MAV_RESULT_DENIED)
        elif cmd == mavlink.MAV_CMD_DO_SET_MODE:
            result = self._on_set_mode(int(p1), round(p2), round(p3), now)
            self._ack(msg, cmd, result, times=2)
        elif cmd == mavlink.MAV_CMD_DO_FLIGHTTERMINATION and p1 >= 0.5:
            self.terminated = True
            self._disarm("flight termination")
            self._ack(msg, cmd, mavlink.MAV_RESULT_ACCEPTED)
        elif cmd == mavlink.MAV_CMD_NAV_LAND:
            self._set_mode(px4.LAND)
            self._ack(msg, cmd, mavlink.MAV_RESULT_ACCEPTED)
        elif cmd == mavlink.MAV_CMD_REQUEST_MESSAGE:
            reply = self._requested(round(p1), now)
            result = mavlink.MAV_RESULT_ACCEPTED if reply is not None \
                else mavlink.MAV_RESULT_UNSUPPORTED
            self._ack(msg, cmd, result, times=2 if reply is not None else 1)
            if reply is not None:
                self._send(reply)
        elif cmd == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            self._ack(msg, cmd, mavlink.MAV_RESULT_ACCEPTED)
            self._send(self._autopilot_version())
        elif cmd == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            self._ack(msg, cmd, self._set_interval(round(p1), p2))
        elif cmd == mavlink.MAV_CMD_GET_HOME_POSITION:
            self._ack(msg, cmd, mavlink.MAV_RESULT_ACCEPTED)
            self._send(self._home_position(now))
        else:
            self._ack(msg, cmd, mavlink.MAV_RESULT_UNSUPPORTED)

    def _set_interval(self, message_id: int, interval_us: float) -> int:
        """MAV_CMD_SET_MESSAGE_INTERVAL as PX4's `MavlinkReceiver::set_message_interval`:
        HEARTBEAT cannot be changed and an id with no stream is refused (FAILED); for every
        stream of `gcs.sim.telemetry`, an interval < 0 stops it, 0 restores its default
        rate, > 0 sets it (at most the mock's physics rate)."""
        if message_id == mavlink.MAVLINK_MSG_ID_HEARTBEAT or message_id not in self.intervals:
            return mavlink.MAV_RESULT_FAILED
        if not math.isfinite(interval_us):
            return mavlink.MAV_RESULT_DENIED
        if interval_us < 0:
            period = None
        elif interval_us == 0:
            hz = self._defaults[message_id]
            period = 1.0 / hz if hz > 0 else None
        else:
            period = max(interval_us * 1e-6, 1.0 / self.config.physics_rate)
        self.intervals[message_id] = period
        if period is not None:
            self._next[message_id] = min(self._next[message_id], self._now() + period)
        return mavlink.MAV_RESULT_ACCEPTED

    def _on_arm(self, msg: Any, now: float) -> None:
        cmd = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
        if self.armed:
            self._ack(msg, cmd, mavlink.MAV_RESULT_ACCEPTED)
        elif self.terminated:
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Arming denied: flight terminated")
            self._ack(msg, cmd, mavlink.MAV_RESULT_DENIED)
        elif self.faults.refuse_arming:
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL, "Arming denied: injected fault")
            self._ack(msg, cmd, mavlink.MAV_RESULT_DENIED)
        elif now < self.config.settle_time:  # PX4: the failed check, then the denial
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL,
                            "Preflight Fail: heading estimate not stable")
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL,
                            "Arming denied: Resolve system health failures first")
            self._ack(msg, cmd, mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
        else:
            self._arm()
            self._ack(msg, cmd, mavlink.MAV_RESULT_ACCEPTED)

    def _on_set_mode(self, base_mode: int, main: int, sub: int, now: float) -> int:
        if not base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return mavlink.MAV_RESULT_UNSUPPORTED
        wanted = px4.Px4Mode(main, sub if main == px4.MainMode.AUTO else 0)
        if wanted == px4.OFFBOARD:
            if now - self._last_setpoint_time > self.config.offboard_loss_timeout:
                self.statustext(mavlink.MAV_SEVERITY_CRITICAL,
                                "Switching to Offboard is currently not available")
                return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
            self._set_mode(px4.OFFBOARD)
            # hold where it is until the next setpoint arrives (PX4 only uses setpoints
            # received while in OFFBOARD)
            self.model.hold(self.index, self.model.position[self.index].copy())
            return mavlink.MAV_RESULT_ACCEPTED
        if wanted in (px4.HOLD, px4.LAND, px4.POSITION, px4.RTL):
            self._set_mode(wanted)
            return mavlink.MAV_RESULT_ACCEPTED
        self.statustext(mavlink.MAV_SEVERITY_CRITICAL, f"Mode {wanted.name} not supported")
        return mavlink.MAV_RESULT_TEMPORARILY_REJECTED

    def _requested(self, message_id: int, now: float) -> Any:
        if message_id == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            return self._autopilot_version()
        if message_id == mavlink.MAVLINK_MSG_ID_HOME_POSITION:
            return self._home_position(now)
        if message_id == mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN:
            return self._gps_origin(now)
        if message_id == mavlink.MAVLINK_MSG_ID_HEARTBEAT:
            return self._heartbeat()
        if message_id == mavlink.MAVLINK_MSG_ID_SYS_STATUS:
            return self._sys_status(now)
        return None
