"""What one vehicle reported, kept from its decoded messages: `Telemetry` and `SecurityCounters`.

`Telemetry.update` reads HEARTBEAT (mode, armed, age), LOCAL_POSITION_NED, EXTENDED_SYS_STATE,
GPS_GLOBAL_ORIGIN, HOME_POSITION, STATUSTEXT (chunks joined) and, for `gcs.flight.safety.health`,
SYS_STATUS, BATTERY_STATUS and GPS_RAW_INT, and TIMESYNC answers; `Telemetry.count_sequence`
counts sequence numbers for link quality (`gcs.flight.link.quality`), and LOCAL_POSITION_NED's
`time_boot_ms` gives the jitter and tells a reboot (it goes back). A non-finite position or
velocity is never stored: it is counted and timestamped (`Telemetry.invalid_estimate_time`)
for the monitor to flag. Which packets get here at all (pinned peer, component, signature)
is `gcs.flight.link.link`'s decision.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from gcs import wire
from gcs.autopilot import DEFAULT, Autopilot, FlightMode, by_heartbeat
from gcs.flight.link.quality import LinkQuality
from gcs.wire import mavlink

__all__ = ["SecurityCounters", "Telemetry"]

#: How far (ms) the vehicle's `time_boot_ms` must go back to be a reboot.
REBOOT_BACK_MS = 1000


@dataclass
class SecurityCounters:
    """Packets with this vehicle's system id that were dropped, by reason."""

    foreign_source: int = 0
    """From an address other than the pinned peer's (spoofing, hijacking)."""
    other_component: int = 0
    """From a component other than the autopilot's."""
    unsigned: int = 0
    """Unsigned although the vehicle has a key."""
    bad_signature: int = 0
    """Signed with another key, or altered."""
    replayed: int = 0
    """A correctly signed packet whose timestamp is not newer than its stream's last one."""

    def to_dict(self) -> dict[str, int]:
        """The counters by name (for the flight record and the API)."""
        return dict(vars(self))

    @property
    def total(self) -> int:
        """Every packet dropped, whatever the reason."""
        return sum(vars(self).values())

    def count(self, reason: str) -> None:
        """One more packet dropped for `reason` (a counter's name)."""
        setattr(self, reason, getattr(self, reason) + 1)


@dataclass
class Telemetry:
    """The latest state one vehicle reported (times are `time.monotonic()` at reception)."""

    heartbeat_time: float | None = None
    message_time: float | None = None
    """Reception of the vehicle's latest message of any kind: the link's proof of life."""
    autopilot: int | None = None
    vehicle_type: int | None = None
    autopilot_kind: Autopilot | None = None
    """The autopilot the GCS flies it as, once chosen (`gcs.autopilot.choose`); until then
    `flown_by` guesses."""
    mode: FlightMode | None = None
    armed: bool = False
    system_status: int | None = None
    landed_state: int | None = None
    """MAV_LANDED_STATE from EXTENDED_SYS_STATE (1 on ground, 2 in air, 4 landing)."""
    position_ned: tuple[float, float, float] | None = None
    velocity_ned: tuple[float, float, float] | None = None
    position_time: float | None = None
    gps_origin: tuple[float, float, float] | None = None
    """GPS_GLOBAL_ORIGIN (lat deg, lon deg, alt m)."""
    home: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    """HOME_POSITION ((lat, lon, alt), (x, y, z) local NED)."""
    statustexts: deque[str] = field(default_factory=lambda: deque(maxlen=20))
    invalid_estimate_time: float | None = None
    """Reception of the latest LOCAL_POSITION_NED with a NaN or infinite position or velocity
    (never stored as the position): a fault for the monitor."""
    invalid_estimates: int = 0
    geofence_breach: str | None = None
    """How the vehicle said its geofence is breached (SYS_STATUS's geofence bit unhealthy, or
    a STATUSTEXT naming the geofence) since it last armed; None: no breach reported."""
    security: SecurityCounters = field(default_factory=SecurityCounters)

    # --- health (read by gcs.flight.safety.health) ---
    sensors_present: int | None = None
    """SYS_STATUS onboard_control_sensors_present (MAV_SYS_STATUS_SENSOR bits)."""
    sensors_enabled: int | None = None
    sensors_health: int | None = None
    battery_remaining: int | None = None
    """Battery remaining (%) from SYS_STATUS / BATTERY_STATUS; None when not reported."""
    battery_voltage: float = math.nan
    """Battery voltage (V) from SYS_STATUS."""
    gps_fix_type: int | None = None
    """GPS_RAW_INT fix_type (GPS_FIX_TYPE: 3 = 3D fix)."""
    gps_satellites: int | None = None
    gps_h_acc: float = math.nan
    """GPS_RAW_INT h_acc (m): horizontal position uncertainty."""
    gps_v_acc: float = math.nan
    warnings: deque[str] = field(default_factory=lambda: deque(maxlen=5))
    """STATUSTEXT of severity WARNING or worse since the vehicle last armed: arming clears
    them, so "Preflight Fail: ..." from before does not stay for the whole flight."""
    skipped: int = 0
    """Messages from the pinned autopilot dropped before decoding (an id the endpoint does not
    decode, `Endpoint.decode_ids`); they count for link quality, not as proof of life."""
    quality: LinkQuality = field(default_factory=LinkQuality, repr=False, compare=False)
    """Loss, reordering and duplicates from the autopilot component's sequence numbers
    (decoded or skipped messages), latency and jitter (`gcs.flight.link.quality`)."""
    boot_ms: int | None = None
    """The vehicle's latest `time_boot_ms` (LOCAL_POSITION_NED)."""
    reboot_time: float | None = None
    """When the vehicle was last seen to reboot: its `time_boot_ms` went back (monotonic s)."""
    text_chunks: wire.StatusTexts = field(default_factory=wire.StatusTexts, init=False,
                                          repr=False, compare=False)
    """STATUSTEXT chunks waiting for the rest of their text."""

    @property
    def seq_received(self) -> int:
        """Distinct messages from the autopilot component (`LinkQuality`)."""
        return self.quality.counter.received

    @property
    def seq_lost(self) -> int:
        """Messages missing from the autopilot component's sequence numbers (not arrived
        late)."""
        return self.quality.counter.lost

    @property
    def last_seq(self) -> int | None:
        return self.quality.counter.last

    def count_sequence(self, seq: int, now: float | None = None) -> None:
        """Link quality: one message with sequence number `seq` (`SequenceCounter`)."""
        self.quality.counter.count(seq, now)

    def update(self, msg: Any, now: float, autopilot_component: int) -> bool:
        """Take in one admitted, decoded message received at `now`. False when it must not be
        passed on: a non-finite position, or a STATUSTEXT chunk before its text is whole."""
        kind = msg.get_type()
        self.message_time = now
        from_autopilot = msg.get_srcComponent() == autopilot_component
        if from_autopilot:  # every packet that arrived counts, a non-finite one too
            self.count_sequence(msg.get_seq(), now)
        if kind == "LOCAL_POSITION_NED" and not all(map(math.isfinite, (
                msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz))):
            # Proof of life, but not a position: never stored, never passed on.
            self.invalid_estimate_time = now
            self.invalid_estimates += 1
            return False
        if kind == "HEARTBEAT":
            if from_autopilot:
                self._heartbeat(msg, now)
        elif kind == "LOCAL_POSITION_NED":
            self.position_ned = (msg.x, msg.y, msg.z)
            self.velocity_ned = (msg.vx, msg.vy, msg.vz)
            self.position_time = now
            if from_autopilot:
                self._boot_clock(msg.time_boot_ms, now)
        elif kind == "TIMESYNC":
            if msg.tc1 != 0:  # an answer to the station's request (tc1 0: the vehicle asks)
                self.quality.timing.reply(msg.ts1, now)
        elif kind == "EXTENDED_SYS_STATE":
            self.landed_state = msg.landed_state
        elif kind == "GPS_GLOBAL_ORIGIN":
            self.gps_origin = (msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3)
        elif kind == "HOME_POSITION" and all(map(math.isfinite, (msg.x, msg.y, msg.z))):
            self.home = ((msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3),
                         (msg.x, msg.y, msg.z))
        elif kind == "STATUSTEXT":
            return self._statustext(msg)
        elif kind in ("SYS_STATUS", "BATTERY_STATUS", "GPS_RAW_INT"):
            self._health(kind, msg)
        return True

    @property
    def flown_by(self) -> Autopilot:
        """The autopilot its modes and commands are read as: the one chosen for it, else the
        one its HEARTBEAT names, else the default (`gcs.autopilot.DEFAULT`)."""
        return self.autopilot_kind or by_heartbeat(self.autopilot) or DEFAULT

    def _boot_clock(self, boot_ms: int, now: float) -> None:
        """The vehicle's clock: jitter from it, and a reboot when it goes back by more than
        a second (packets a little out of order do not)."""
        if self.boot_ms is not None and boot_ms + REBOOT_BACK_MS < self.boot_ms:
            self.reboot_time = now
            self.quality.counter.restart()
            self.quality.timing.restart()
        self.boot_ms = boot_ms
        self.quality.timing.stamped(now, boot_ms / 1000.0)

    def _heartbeat(self, msg: Any, now: float) -> None:
        """The autopilot's HEARTBEAT: mode, armed state, type, status."""
        self.heartbeat_time = now
        self.autopilot = msg.autopilot
        self.vehicle_type = msg.type
        self.mode = self.flown_by.decode_mode(msg.custom_mode)
        armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        if armed and not self.armed:
            self.warnings.clear()  # the pre-arm checks passed: their warnings are over
            self.geofence_breach = None
        self.armed = armed
        self.system_status = msg.system_status

    def _statustext(self, msg: Any) -> bool:
        """A STATUSTEXT or one chunk of it; True once its text is whole."""
        text = self.text_chunks.add(msg)
        if text is None:  # a chunk of a longer text: listeners get the whole one
            return False
        self.statustexts.append(text)
        if msg.severity <= mavlink.MAV_SEVERITY_WARNING:
            self.warnings.append(text)
            if "geofence" in text.lower():  # PX4: "Approaching on Geofence", "Geofence ..."
                self.geofence_breach = f"STATUSTEXT {text!r}"
        return True

    def _health(self, kind: str, msg: Any) -> None:
        """SYS_STATUS, BATTERY_STATUS and GPS_RAW_INT (UINT16_MAX / -1 = unknown)."""
        if kind == "SYS_STATUS":
            self.sensors_present = msg.onboard_control_sensors_present
            self.sensors_enabled = msg.onboard_control_sensors_enabled
            self.sensors_health = msg.onboard_control_sensors_health
            fence = mavlink.MAV_SYS_STATUS_GEOFENCE
            if (msg.onboard_control_sensors_enabled & fence
                    and not msg.onboard_control_sensors_health & fence):
                self.geofence_breach = "SYS_STATUS geofence unhealthy"
            if msg.battery_remaining >= 0:
                self.battery_remaining = int(msg.battery_remaining)
            if msg.voltage_battery not in (0, 0xFFFF):
                self.battery_voltage = msg.voltage_battery / 1000.0
        elif kind == "BATTERY_STATUS":
            if msg.battery_remaining >= 0:
                self.battery_remaining = int(msg.battery_remaining)
        else:  # GPS_RAW_INT
            self.gps_fix_type = int(msg.fix_type)
            self.gps_satellites = (None if msg.satellites_visible == 255
                                   else msg.satellites_visible)
            self.gps_h_acc = msg.h_acc / 1000.0 if msg.h_acc else math.nan
            self.gps_v_acc = msg.v_acc / 1000.0 if msg.v_acc else math.nan
