"""A mock vehicle's state, flight rules and output (`VehicleCore`), and what it is given by
its fleet (`VehicleContext`).

The rules, as in PX4's commander: AUTO.TAKEOFF and AUTO.RTL as PX4's navigator flies them
(`gcs.sim.automodes`); offboard loss (no setpoint for COM_OF_LOSS_T) triggers the failsafe:
Position mode (hold) for COM_FAIL_ACT_T (`failsafe_action_delay`), then COM_OBL_RC_ACT
(`offboard_loss_action`; there being no RC, the modes that need it fall back to AUTO.LAND);
auto-disarm COM_DISARM_LAND after landing, COM_DISARM_PRFLT after arming without taking off
(a negative value: never). The output: the periodic streams
(`gcs.sim.telemetry`, their intervals changed by MAV_CMD_SET_MESSAGE_INTERVAL), STATUSTEXT
(`gcs.sim.statustext`), COMMAND_ACK, each packed with the vehicle's own pymavlink instance
(counting sequence numbers, signed with its key) and subject to the injected faults, sent on
every link (`gcs.sim.links`); a reply goes only to the link its request came from.
"""

from __future__ import annotations

import asyncio
import copy
import logging
import math
import random
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gcs import frames, wire
from gcs.autopilot import px4
from gcs.sim import automodes, telemetry
from gcs.sim.config import MockConfig, MockFaults
from gcs.sim.links import UdpLink
from gcs.sim.model import FleetModel
from gcs.sim.statustext import StatusTextOut
from gcs.wire import mavlink

__all__ = ["VehicleContext", "VehicleCore"]

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class VehicleContext:
    """What a vehicle takes from its fleet: the shared clock, model and settings."""

    clock: Callable[[], float]
    """Mock time (s since the fleet started: the vehicles' boot clock)."""
    model: FleetModel
    """The whole fleet's motion; the vehicle is its row `index`."""
    config: MockConfig
    world_origin: frames.Geodetic
    """Geodetic origin of the world frame."""
    seed: int
    """Seed of the fleet's random processes."""


class VehicleCore:
    """One mock vehicle's state, flight-mode rules, failsafes and output; what it receives is
    `gcs.sim.vehicle.MockVehicle`."""

    def __init__(self, context: VehicleContext, index: int, home_world: ArrayLike,
                 gcs_address: tuple[str, int], listen_address: tuple[str, int]) -> None:
        self.context = context
        self._config = copy.copy(context.config)
        """This vehicle's own settings (PARAM_SET changes them: `gcs.sim.params`)."""
        self.index = index
        self.system_id = index + 1
        self.component_id = 1
        self.home_world = np.asarray(home_world, dtype=float)
        self.origin = frames.enu_to_geodetic(self.home_world, context.world_origin)
        """Geodetic EKF origin (= home) reported in GPS_GLOBAL_ORIGIN and HOME_POSITION."""
        self.gcs_address = gcs_address
        """The offboard link's configured remote: where it sends until it latches a partner."""
        self.links: list[UdpLink] = []
        """Its links: the offboard link, then the optional GCS link (`gcs.sim.links`)."""
        self._reply_link: UdpLink | None = None
        self.auto = automodes.AutoState()
        """Where AUTO.TAKEOFF / AUTO.RTL are going (`gcs.sim.automodes`)."""
        self.fence_breached = False
        """The geofence is breached (SYS_STATUS reports the geofence unhealthy)."""
        self.last_manual_control = -math.inf
        """Mock time of the last MANUAL_CONTROL (manual control input) addressed to it."""
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
        self.errors = 0
        """Exceptions caught while handling this vehicle (datagrams, rules, telemetry)."""
        self._texts = StatusTextOut()
        self.statustexts: list[str] = self._texts.said
        """Every STATUSTEXT it said, in order (repeats suppressed)."""
        self.events: list[tuple[float, str]] = []
        """(mock time, what happened): mode changes, arming, failsafes."""
        self.last_setpoint_time = -math.inf
        """Mock time of the last accepted setpoint (offboard's proof of life)."""
        self._armed_time = 0.0
        self.battery = 100.0
        """Simulated battery remaining (%): drains while armed (`MockConfig.battery_drain`)."""
        self._battery_t = 0.0
        self._landed_since: float | None = None
        self._failsafe_since: float | None = None
        self._mav = mavlink.MAVLink(None, srcSystem=self.system_id,
                                    srcComponent=self.component_id)
        self._rng = random.Random(context.seed * 1000 + index)
        self._defaults = telemetry.default_rates(context.config)
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
        return self.context.model

    @property
    def config(self) -> MockConfig:
        return self._config

    @property
    def world_origin(self) -> frames.Geodetic:
        return self.context.world_origin

    @property
    def signing(self) -> Any:
        """pymavlink's signing state of this vehicle (key, timestamps, counters)."""
        return self._mav.signing

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

    def now(self) -> float:
        """Mock time (s since boot)."""
        return self.context.clock()

    def event(self, what: str, at: float | None = None) -> None:
        """Record that `what` happened at `at` (the clock's tick that decided it), else now."""
        self.events.append((self.now() if at is None else at, what))

    def record_error(self, doing: str) -> None:
        """Count an exception caught while `doing` something; log the first ones in full."""
        self.errors += 1
        if self.errors <= 3:
            _log.exception("mock vehicle %d: error %s (count %d)", self.system_id, doing,
                           self.errors)

    # ------------------------------------------------------------------ rules

    def set_mode(self, mode: px4.Px4Mode) -> None:
        """Enter `mode`: LAND descends, RTL heads over home, HOLD/POSITION hold here."""
        if mode == self.mode:
            return
        self.event(f"mode {self.mode.name} -> {mode.name}")
        self.mode = mode
        i = self.index
        if mode == px4.LAND:
            self.model.descend(i, self.config.land_speed)
        elif mode in (px4.RTL, px4.TAKEOFF):
            automodes.enter(self, mode)
        elif mode in (px4.HOLD, px4.POSITION):
            self.model.hold(i, self.model.position[i].copy())
        if mode != px4.TAKEOFF:
            self.auto.takeoff_height = None
        if mode != px4.POSITION:
            self._failsafe_since = None
            self.failsafe = False

    def arm(self) -> None:
        """Motors on (the caller has checked that arming is allowed)."""
        self.armed = True
        self._armed_time = self.now()
        self.model.powered[self.index] = True
        if self.mode in (px4.HOLD, px4.POSITION):
            self.model.hold(self.index, self.model.position[self.index].copy())
        elif self.mode == px4.TAKEOFF:
            automodes.enter(self, self.mode)
        self.event("armed")

    def disarm(self, why: str) -> None:
        """Motors off, saying `why` in STATUSTEXT."""
        if not self.armed:
            return
        self.armed = False
        self.model.powered[self.index] = False
        self._landed_since = None
        self.event(f"disarmed ({why})")
        self.statustext(mavlink.MAV_SEVERITY_INFO, f"Disarmed by {why}")

    def forgive_stall(self, seconds: float) -> None:
        """The mock's own process did not run for `seconds` (a real PX4 runs on): that time
        does not count towards the offboard-loss timeout."""
        self.last_setpoint_time += seconds

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
        if self.mode == px4.OFFBOARD and now - self.last_setpoint_time > cfg.offboard_loss_timeout:
            self.statustext(mavlink.MAV_SEVERITY_CRITICAL,
                            "Failsafe activated: offboard signal lost")
            self.set_mode(px4.POSITION)
            self.failsafe = True
            self._failsafe_since = now
            self.event("failsafe: offboard loss", now)
        if (self.failsafe and self._failsafe_since is not None
                and now - self._failsafe_since >= cfg.failsafe_action_delay):
            self._failsafe_since = None
            if self.in_air:
                self._failsafe_action(now)
        if self.armed:
            automodes.tick(self, now)
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
                elif 0 <= cfg.disarm_after_land <= now - self._landed_since:
                    self.in_air = False
                    self.disarm("auto disarm on land")
            else:
                self._landed_since = None
        elif 0 <= cfg.disarm_preflight <= now - self._armed_time:
            self.disarm("auto preflight disarming")

    def _failsafe_action(self, now: float) -> None:
        """The offboard-loss failsafe's action once its delay is over (COM_OBL_RC_ACT)."""
        action = px4.OffboardLossFailsafe(action=int(self.config.offboard_loss_action)).effective
        self.event(f"failsafe: {action}", now)
        if action in ("Terminate", "Disarm"):
            self.statustext(mavlink.MAV_SEVERITY_EMERGENCY, f"Failsafe: {action.lower()}")
            self.terminated = action == "Terminate"
            self.disarm(f"failsafe {action.lower()}")
            return
        mode = {"Return": px4.RTL, "Hold": px4.HOLD}.get(action, px4.LAND)
        self.statustext(mavlink.MAV_SEVERITY_CRITICAL,
                        "Failsafe: no RC, landing" if mode == px4.LAND
                        else f"Failsafe: {action}")
        self.set_mode(mode)
        self.failsafe = True

    # ---------------------------------------------------------------- streams

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
                self.send(msg)

    def set_interval(self, message_id: int, interval_us: float) -> int:
        """MAV_CMD_SET_MESSAGE_INTERVAL as PX4's `MavlinkReceiver::set_message_interval`:
        HEARTBEAT cannot be changed and an id with no stream is refused (FAILED); for every
        stream of `gcs.sim.telemetry`, an interval < 0 stops it, 0 restores its default
        rate, > 0 sets it (at most the mock's physics rate). Returns the MAV_RESULT."""
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
            self._next[message_id] = min(self._next[message_id], self.now() + period)
        return mavlink.MAV_RESULT_ACCEPTED

    # ---------------------------------------------------------------- output

    def attach(self, transport: asyncio.DatagramTransport) -> UdpLink:
        """Add a link on `transport` (the fleet's socket for this vehicle): the first is the
        offboard link (remote `gcs_address`); use `attach_link` for another."""
        return self.attach_link(UdpLink("offboard", transport, self.gcs_address))

    def attach_link(self, link: UdpLink) -> UdpLink:
        """Send on `link` too from now on."""
        self.links.append(link)
        return link

    def detach(self) -> None:
        """Close every link: the vehicle falls silent."""
        for link in self.links:
            link.close()
        self.links = []

    def booting(self) -> bool:
        """Still booting (`MockConfig.boot_time`): deaf and silent, like PX4 before its first
        HEARTBEAT."""
        return self.config.boot_time > 0.0 and self.now() < self.config.boot_time

    def lost(self) -> bool:
        """Whether the injected loss (`MockFaults.loss`) takes this packet."""
        return self.faults.loss > 0.0 and self._rng.random() < self.faults.loss

    def send(self, msg: Any) -> None:
        """Pack `msg` and send it to the GCS, unless silent, booting or lost (delayed by
        `MockFaults.delay`)."""
        self._send(msg, self.links)

    def reply(self, msg: Any) -> None:
        """Send `msg` only on the link the message being handled came from (every link when
        none is being handled)."""
        self._send(msg, self.links if self._reply_link is None else [self._reply_link])

    def replier(self) -> Callable[[Any], None]:
        """A function sending, later too, on the link of the message being handled (`reply`
        for answers that go on after it: a parameter list, a mission upload's retries)."""
        links = self.links if self._reply_link is None else [self._reply_link]
        return lambda msg: self._send(msg, links)

    def _send(self, msg: Any, links: list[UdpLink]) -> None:
        if not links:
            return
        faults = self.faults
        if faults.silent or self.booting():
            return
        buf = wire.pack(msg, self._mav)  # packed first: a lost message leaves a sequence gap
        if self.lost():
            return
        for link in links:
            if faults.delay > 0.0:
                asyncio.get_running_loop().call_later(faults.delay, link.sendto, buf)
            else:
                link.sendto(buf)

    def statustext(self, severity: int, text: str) -> None:
        """Send `text` whole (in chunks if long), unless it was sent in the last
        `STATUSTEXT_REPEAT_S` seconds."""
        for msg in self._texts.messages(severity, text, self.now()):
            self.send(msg)

    def ack(self, msg: Any, command: int, result: int, times: int = 1) -> None:
        """COMMAND_ACK of `msg` `times` times; repeats `MockConfig.duplicate_ack_delay` apart."""
        ack = self._mav.command_ack_encode(command, result, 0, 0, msg.get_srcSystem(),
                                           msg.get_srcComponent())
        self.reply(ack)
        links = self.links if self._reply_link is None else [self._reply_link]
        delay = self.config.duplicate_ack_delay
        for k in range(1, times):
            if delay > 0.0:
                asyncio.get_running_loop().call_later(k * delay, self._send, ack, links)
            else:
                self._send(ack, links)
