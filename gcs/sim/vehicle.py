"""One PX4-like vehicle of a mock fleet (`MockVehicle`): what it receives, and where each kind
of message is handled.

It speaks what a PX4 quadrotor speaks for our purposes: HEARTBEAT (MAV_TYPE_QUADROTOR,
MAV_AUTOPILOT_PX4, custom mode main << 16 | sub << 24, armed flag), SYS_STATUS (sensors present,
enabled, healthy; the pre-arm bit healthy once settled), HOME_POSITION, GPS_GLOBAL_ORIGIN,
EXTENDED_SYS_STATE, LOCAL_POSITION_NED, ATTITUDE, GLOBAL_POSITION_INT, AUTOPILOT_VERSION,
STATUSTEXT and COMMAND_ACK, and what ground stations ask of PX4: parameters, missions, fences
and rally points, TIMESYNC, PROTOCOL_VERSION, MAVFTP (no files). The parts, one module each:

- `gcs.sim.core`: state, flight rules (failsafes, RTL, auto-disarm) and output;
- `gcs.sim.messages`: how each message is encoded; `gcs.sim.telemetry`: the periodic streams
  and their rates (``minimal``, or PX4's offboard-link set of about 410 messages/s with
  ``MockConfig.telemetry_profile = "px4"``);
- `gcs.sim.commands`: COMMAND_LONG and COMMAND_INT (arming, modes, takeoff, RTL, land,
  requests, ACKs); `gcs.sim.automodes`: AUTO.TAKEOFF and AUTO.RTL;
- `gcs.sim.setpoints`: SET_POSITION_TARGET_LOCAL_NED (offboard);
- `gcs.sim.protocols`: parameters (`gcs.sim.params`, the set `gcs.sim.paramdefs`), missions,
  fences and rally points (`gcs.sim.missions`), TIMESYNC, MANUAL_CONTROL;
- `gcs.sim.geofence`: the stored fence checked, GF_ACTION on a breach;
- `gcs.sim.links`: its UDP links (offboard, optional GCS link) and their latched partners;
- `gcs.sim.signing`: SETUP_SIGNING and the signing key;
- `gcs.sim.receiver`: what comes in, as PX4 takes it: the partner latched by the first
  datagram, the signing rules, every rejection counted;
- `gcs.sim.statustext`: STATUSTEXT chunks and repeats;
- `gcs.sim.config`: the settings (`MockConfig`) and injected faults (`MockFaults`).

Each datagram is decoded by a fresh parser with the vehicle's signing state; an exception while
handling one is counted (`errors`) and logged, never raised into asyncio (which would close the
vehicle's socket and silence it). Each link latches the source of the first datagram it
hears, whatever it holds, and keeps it, as PX4's UDP links do; with a key only signed packets
(and PX4's unsigned allowlist) reach the handlers (`gcs.sim.receiver`).

It speaks MAVLink through pymavlink directly, never through `gcs.flight`: a wire-level mistake
in our link must not be repeated by the stand-in that should catch it. It shares on purpose only
constants and pure functions: the PX4 facts table (`gcs.autopilot.px4`: modes, timeouts), frame
conversions (`gcs.frames`) and the MAVLink facts of `gcs.wire` (dialect, type-mask bits,
`time_boot_ms`, the datagram adapter).

The motion is `gcs.sim.model.FleetModel`, integrated at `physics_rate` (>= 100 Hz) for the
whole fleet at once. The battery drains while armed (`MockConfig.battery_drain`); messages
carry counting sequence numbers, so a lost one leaves a gap the GCS can count.

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
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from gcs.autopilot import px4
from gcs.sim import geofence, protocols, signing
from gcs.sim.commands import handle_command
from gcs.sim.core import VehicleContext, VehicleCore
from gcs.sim.links import UdpLink
from gcs.sim.missions import VehicleMissions
from gcs.sim.params import VehicleParams
from gcs.sim.receiver import MavlinkIntake
from gcs.sim.setpoints import ReceivedSetpoint, read_setpoint, refusal_text
from gcs.wire import addressed_to, mavlink

__all__ = ["MockVehicle"]


class MockVehicle(VehicleCore):
    """One PX4-like vehicle: protocol, flight-mode rules, failsafes. Owned by a `MockFleet`,
    which gives it its `VehicleContext` and, once its socket is bound, its transport
    (`attach`)."""

    def __init__(self, context: VehicleContext, index: int, home_world: ArrayLike,
                 gcs_address: tuple[str, int], listen_address: tuple[str, int]) -> None:
        super().__init__(context, index, home_world, gcs_address, listen_address)
        self.received: list[ReceivedSetpoint] = []
        """Every accepted setpoint, with `MockConfig.record_setpoints` (for tests)."""
        self.setpoints_accepted = 0
        self.setpoints_ignored = 0
        self.setpoints_invalid = 0
        """Setpoints refused for a used field not finite or absurd (`setpoint_problem`)."""
        self.intake = MavlinkIntake(self.signing)
        """What came in and what became of it, as PX4 decides it: accepted, rejected by the
        signing rules (by kind), garbage (`gcs.sim.receiver`)."""
        self.params = VehicleParams(self)
        """Its PX4 parameters and the parameter protocol (`gcs.sim.params`)."""
        self.missions = VehicleMissions(self)
        """Its mission, fence and rally lists and the mission protocol (`gcs.sim.missions`)."""
        self.geofence = geofence.Geofence(self.origin)
        """Its fence in LOCAL_NED and breach state (`gcs.sim.geofence`)."""
        self.missions.changed = self._mission_changed

    @property
    def rejected(self) -> int:
        """Incoming packets rejected: bad CRC, truncated, or (with a key) unsigned or badly
        signed (`intake.counters` says which)."""
        counters = self.intake.counters
        return counters.rejected + counters.garbage

    def tick(self, now: float) -> None:
        """The flight rules (`VehicleCore.tick`), then the protocols' own timers."""
        super().tick(now)
        self.params.drain()
        self.missions.tick(now)
        geofence.check(self, now)

    def _mission_changed(self, mission_type: int) -> None:
        if mission_type == mavlink.MAV_MISSION_TYPE_FENCE:
            self.geofence.load(self.missions.fence)

    # ---------------------------------------------------------------- signing

    @property
    def signing_key(self) -> bytes | None:
        """The key it holds (None: signing off)."""
        key: bytes | None = self.signing.secret_key
        return key

    def set_signing_key(self, key: bytes | None, initial_timestamp: int = 0) -> None:
        """Install (or with None clear) the signing key, as PX4 does on SETUP_SIGNING."""
        signing.install_key(self.signing, key, initial_timestamp)

    # ---------------------------------------------------------------- messages in

    def received_datagram(self, data: bytes, address: tuple[str, int],
                          link: UdpLink | None = None) -> None:
        """One datagram from `address` on `link` (default: the offboard link; the fleet's
        socket calls this): dropped while booting or by the injected loss, delayed by the
        injected delay, then handled."""
        if self.booting() or self.lost():
            return
        if link is None:
            if not self.links:
                return
            link = self.links[0]
        delay = self.faults.delay
        if delay > 0.0:
            asyncio.get_running_loop().call_later(delay, self._process_guarded, data, address,
                                                  link)
        else:
            self._process_guarded(data, address, link)

    def _process_guarded(self, data: bytes, address: tuple[str, int], link: UdpLink) -> None:
        """`_process`, counting and logging any exception instead of raising it into asyncio
        (which would close this vehicle's socket: one bad packet must not silence it)."""
        self._reply_link = link
        try:
            self._process(data, address, link)
        except Exception:
            self.record_error("handling a datagram")
        finally:
            self._reply_link = None

    def _process(self, data: bytes, address: tuple[str, int], link: UdpLink) -> None:
        for msg in self.intake.receive(data, address, link):  # PX4's partner, signing rules
            kind = msg.get_type()
            if kind == "SET_POSITION_TARGET_LOCAL_NED":
                self._on_setpoint(msg)
            elif kind in ("COMMAND_LONG", "COMMAND_INT"):
                handle_command(self, msg)
            elif kind == "SETUP_SIGNING":
                self._on_setup_signing(msg)
            elif kind in protocols.HANDLED:
                protocols.handle(self, msg)

    def _on_setpoint(self, msg: Any) -> None:
        """Take a setpoint (`gcs.sim.setpoints`): proof of life; it moves the vehicle only in
        OFFBOARD."""
        if (msg.target_system not in (0, self.system_id)
                or msg.target_component not in (0, self.component_id)):
            return
        got = read_setpoint(msg, self.yaw, self.now())
        if isinstance(got, str):  # refused: keeps holding the last valid setpoint
            if got == "invalid":
                self.setpoints_invalid += 1
            else:
                self.setpoints_ignored += 1
                text = refusal_text(msg)
                if text is not None:  # PX4 says why (repeats suppressed: `statustext`)
                    self.statustext(mavlink.MAV_SEVERITY_CRITICAL, text)
            return
        self.last_setpoint_time = got.time
        self.setpoints_accepted += 1
        if self.config.record_setpoints:
            self.received.append(got)
        if self.mode == px4.OFFBOARD:
            i = self.index
            self.model.position_sp[i] = got.position + np.asarray(self.faults.offset_ned)
            self.model.velocity_sp[i] = got.velocity
            self.model.acceleration_sp[i] = got.acceleration
            if not math.isnan(got.yaw):
                self.yaw = got.yaw

    def _on_setup_signing(self, msg: Any) -> None:
        """Reaching here it passed pymavlink's checks: with a key set, it was signed with it."""
        if not addressed_to(msg, self.system_id, self.component_id):
            return
        if self.armed:
            self.statustext(mavlink.MAV_SEVERITY_WARNING, "Signing change denied: armed")
            return
        key = signing.setup_signing_key(msg)
        self.set_signing_key(key, msg.initial_timestamp)
        self.event("signing disabled" if key is None else "signing key set")
