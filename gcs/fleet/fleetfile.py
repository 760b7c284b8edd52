"""The fleet file (JSON) and flight options: parsing and validation.

Long: the fleet-file contract: `FlightOptions` (a table of fields) and the parser.

A fleet file says how to reach each vehicle and where its LOCAL_NED origin (home) lies::

    {
      "world_origin": {"lat": 47.397742, "lon": 8.545594, "alt": 488.0},   (optional)
      "vehicles": [
        {"id": "uav1", "connection": "udpin:127.0.0.1:14540", "system_id": 1,
         "home": [4.5, 2.5, 0.0]},
        ...
      ],
      "flight": {"policy": "land_all", "rate_hz": 20},                       (optional)
      "signing_key": "fleet.key",                                            (optional)
      "position_error": 0.25,                                                (optional)
      "autopilot": "auto"                                                    (optional)
    }

- `id` matches a plan vehicle; `connection` is a pymavlink URL (vehicles may share one);
  `system_id` 1..254; `component_id` defaults to 1 (the autopilot).
- `home` [x, y, z]: the vehicle's home in the world frame (ENU, m). Without it, the fleet-wide
  geodetic `world_origin` {lat, lon, alt (m AMSL)} is required and the home is computed from
  what the vehicle reports (GPS_GLOBAL_ORIGIN, else HOME_POSITION).
- `flight`: `FlightOptions` fields (command-line flags override them). The same object under
  its old key `mission` is still read, with a `FleetFileWarning` saying to rename it; a file
  with both keys is refused.
- `signing_key` (fleet-wide, or per vehicle to override it): a MAVLink 2 signing key file
  (``fleetplan keys new FILE``; relative paths are relative to the fleet file). Read when the
  fleet file is loaded; a file group or others can access is refused. Only the path is ever
  written out (`to_dict`), never the key.
- `peer` (per vehicle, optional) ``"HOST:PORT"``: the vehicle's source address, pinned up front
  instead of at first contact (`gcs.flight.link.link`).
- `autopilot` (fleet-wide, or per vehicle to override it): ``auto`` (the default: told by the
  vehicle's HEARTBEAT, PX4 or ArduPilot), ``px4`` or ``ardupilot`` (`gcs.autopilot`); a
  vehicle whose HEARTBEAT names the other one is refused at connect.
- `position_error`: how far (m) a vehicle of this fleet may be from where it reports or is
  told to be (estimate and tracking error); plans for the fleet then keep 2x this margin
  (`gcs.flight.safety.margin`). Absent: not stated, no margin checked.

Every problem is a `FleetFileError` naming the field (e.g. ``vehicles[2].system_id``).
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from gcs.autopilot import AUTOPILOTS, CHOICES
from gcs.errors import FleetFileError, LinkError
from gcs.fleet.choices import (
    AT_END,
    DEFAULT_ARM_TIMEOUT,
    DEFAULT_AT_END,
    DEFAULT_CLIMB_SPEED,
    DEFAULT_HOLD_AT_GOAL,
    DEFAULT_MARGIN_CHECK,
    DEFAULT_MESSAGE_RATES,
    DEFAULT_POLICY,
    DEFAULT_PRESTREAM,
    DEFAULT_RATE_HZ,
    DEFAULT_REPLAN_LEAD_S,
    DEFAULT_START_TOLERANCE,
    DEFAULT_STREAM_PRIORITY,
    DEFAULT_TRACKING_ERROR_MAX,
    FAILSAFE,
    GEOFENCE,
    LANDING,
    MARGIN_CHECK,
    MESSAGE_RATES,
    MIN_RATE_HZ,
    OPTION_CHOICES,
    PAUSE_EXPIRY,
    POLICIES,
    PREFLIGHT,
    STREAM_PRIORITY,
    AtEnd,
    FailsafeChoice,
    GeofenceChoice,
    LandingChoice,
    MarginCheck,
    MessageRates,
    PauseExpiry,
    Policy,
    Preflight,
    StreamPriority,
)
from gcs.frames import Geodetic
from gcs.wire import (
    MAX_RATE_HZ,
    KeyFileError,
    SigningKey,
    is_udp_url,
    load_key,
    parse_host_port,
    parse_udp_url,
)
from planner.types import FloatArray

#: A link may be silent this long at most before it must count as lost (s).
MAX_LINK_TIMEOUT_S = 5.0
#: A landing plan may take this long at most (s): the fleet flies on meanwhile, so a longer
#: bound only delays the landing.
MAX_LANDING_PLAN_TIMEOUT_S = 30.0
#: Touchdown points at most this high above the workspace floor (m): PX4's Land takes over
#: there, so a higher one is no planned landing at all.
MAX_LANDING_HEIGHT_M = 10.0
#: An in-flight replan's switch instant at most this far ahead (s): the fleet flies its old
#: plan until then, so a longer lead only delays the change.
MAX_REPLAN_LEAD_S = 10.0
#: A landing descent at most this fast (m/s; PX4 allows MPC_LAND_SPEED up to 2 m/s).
MAX_LAND_SPEED = 3.0

#: Options with an upper bound: (the bound, its unit and why, for the error).
_MAXIMA: dict[str, tuple[float, str]] = {
    "link_timeout": (MAX_LINK_TIMEOUT_S, "s: a longer one hides a lost link"),
    "landing_plan_timeout": (MAX_LANDING_PLAN_TIMEOUT_S,
                             "s: the fleet flies on until the plan is ready"),
    "landing_height": (MAX_LANDING_HEIGHT_M,
                       "m above the workspace floor (PX4's Land takes over there)"),
    "replan_lead_s": (MAX_REPLAN_LEAD_S, "s: the fleet flies its old plan until the switch"),
    "land_speed": (MAX_LAND_SPEED, "m/s"),
}

# The choices (Literals, their values, MIN_RATE_HZ) are `gcs.fleet.choices`', re-exported here
# with the fleet file they belong to.
__all__ = [
    "AT_END",
    "FAILSAFE",
    "GEOFENCE",
    "LANDING",
    "MARGIN_CHECK",
    "MAX_RATE_HZ",
    "MESSAGE_RATES",
    "MIN_RATE_HZ",
    "OPTION_CHOICES",
    "PAUSE_EXPIRY",
    "POLICIES",
    "PREFLIGHT",
    "STREAM_PRIORITY",
    "AtEnd",
    "FailsafeChoice",
    "FleetFileWarning",
    "FleetSpec",
    "FlightOptions",
    "GeofenceChoice",
    "LandingChoice",
    "MarginCheck",
    "MessageRates",
    "PauseExpiry",
    "Policy",
    "Preflight",
    "StreamPriority",
    "VehicleSpec",
    "load_fleet",
]

#: The key of the flight options, and the old name still read (with a `FleetFileWarning`).
_OPTIONS_KEY = "flight"
_OLD_OPTIONS_KEY = "mission"
_TOP_KEYS = {"world_origin", "vehicles", _OPTIONS_KEY, _OLD_OPTIONS_KEY, "signing_key",
             "position_error", "autopilot"}
_VEHICLE_KEYS = {"id", "connection", "system_id", "component_id", "home", "signing_key", "peer",
                 "autopilot"}


class FleetFileWarning(UserWarning):
    """A fleet file that is read as it is but should be changed (a key under its old name).

    A `UserWarning`, so Python shows it on stderr by default (the CLI user sees it)."""


@dataclass(frozen=True)
class FlightOptions:
    """How a flight is run; defaults are for real vehicles."""

    rate_hz: float = DEFAULT_RATE_HZ
    """Setpoint stream rate (Hz), up to 100."""
    policy: Policy = DEFAULT_POLICY
    """What to do when a vehicle is flagged: hold_all, land_all, land_faulty or replan (it
    lands on its own predicted motion, the others replan around it: `gcs.flight.replan.replan`)."""
    at_end: AtEnd = DEFAULT_AT_END
    """After the plan and the hold at the goals: land, or hold (PX4 Hold mode)."""
    link_timeout: float = 1.5
    """A vehicle from which no message at all arrived for this long has lost its link and
    is flagged (s). Any message counts: PX4 sends HEARTBEAT at 1 Hz and refuses a faster
    rate, so one lost HEARTBEAT would otherwise look like a lost link."""
    heartbeat_timeout: float = 5.0
    """A vehicle whose HEARTBEAT is older than this is flagged: its mode and armed state are
    no longer known (s). Five missed at PX4's 1 Hz: at 20% packet loss that happens by chance
    with probability 0.2^5 = 3e-4 per heartbeat, while a lost link is caught in 1.5 s."""
    separation_alarm: float | None = None
    """The alarm band (m): the whole fleet is stopped (PX4 Hold) when two vehicles come
    closer than the clearance they must keep (R = min_separation - separation_margin) minus
    this, in the plan's separation metric. None: 0 for a plan with a margin (the margin is
    the tracking tolerance), 0.3 m without one (`gcs.flight.safety.margin.alarm_band`)."""
    tracking_error_max: float = DEFAULT_TRACKING_ERROR_MAX
    """A vehicle farther than this from its planned position is flagged (m)."""
    start_tolerance: float = DEFAULT_START_TOLERANCE
    """The flight clock starts when every vehicle is this close to its start (m)."""
    goal_tolerance: float = 0.2
    """A completed flight ends with every vehicle this close to its goal (m)."""
    hold_at_goal: float = DEFAULT_HOLD_AT_GOAL
    """Seconds to hold at the goals after the plan's horizon, before `at_end`."""
    goal_settle_max: float = 3.0
    """After the hold, a vehicle not yet within its goal tolerance is waited for up to this
    long (s), still held at its goal by the stream, before the goal errors are measured: a
    gust or a loaded station delays its arrival, not its verdict. 0: no wait."""
    climb_speed: float = DEFAULT_CLIMB_SPEED
    """Peak speed of the climb from home to the start (m/s)."""
    prestream: float = DEFAULT_PRESTREAM
    """Seconds of hold setpoints streamed before asking for OFFBOARD."""
    connect_timeout: float = 30.0
    """Waiting for every vehicle's first HEARTBEAT and position (s)."""
    arm_timeout: float = DEFAULT_ARM_TIMEOUT
    """Retrying TEMPORARILY_REJECTED arming for at most this long (s)."""
    gather_timeout: float = 60.0
    """Waiting for the whole fleet to reach its starts (s)."""
    land_timeout: float = 60.0
    """Waiting for landed vehicles to disarm (s)."""
    yaw: float = 0.0
    """Fixed heading in the world frame (rad, ENU: 0 = +x, counter-clockwise)."""
    pause_limit: float = 120.0
    """A paused flight may stay paused this long (s); then `pause_expiry` applies."""
    pause_expiry: PauseExpiry = "land"
    """When a pause outlasts `pause_limit`: land every vehicle, or hold (PX4 Hold); the
    flight ends aborted either way."""
    margin_check: MarginCheck = DEFAULT_MARGIN_CHECK
    """A plan whose separation margin is below 2 x the fleet's `position_error`: refuse to
    fly it, or warn (an event in the record) and fly."""
    preflight: Preflight = "check"
    """The pre-flight gate (battery, unhealthy sensors, link loss; gcs.flight.safety.health):
    check (refuse to arm an unfit vehicle) or override (fly anyway; recorded as an event)."""
    min_battery_pct: float = 30.0
    """The pre-flight gate refuses a vehicle reporting less battery than this (%)."""
    preflight_wait: float = 10.0
    """How long the gate waits for a problem to clear (PX4 reports sensors unhealthy for a
    few seconds after boot) before refusing (s)."""
    message_rates: MessageRates = DEFAULT_MESSAGE_RATES
    """leave: take the telemetry rates the vehicle sends; request: ask for what the GCS reads
    at the rates it needs and turn off PX4's fast streams it never reads
    (MAV_CMD_SET_MESSAGE_INTERVAL, `gcs.autopilot.base.Autopilot.message_rates`)."""
    position_rate_hz: float = 30.0
    """LOCAL_POSITION_NED rate asked for with `message_rates: request` (Hz)."""
    stream_priority: StreamPriority = DEFAULT_STREAM_PRIORITY
    """realtime (default): stream setpoints from a real-time thread (SCHED_RR 1) where the
    process may (`gcs.flight.timeline.stream.Streamer`; on a busy machine most send jitter is the OS
    leaving the GCS waiting for a core); refused quietly otherwise (recorded as an event).
    normal never asks."""
    goal_tolerance_k: float = 2.0
    """A vehicle counts as arrived within max(goal_tolerance, goal_tolerance_k x the fleet's
    position_error)."""
    landing: LandingChoice = "planned"
    """How an abort with land (and land_faulty) lands the fleet: planned, a verified landing
    plan flown as setpoints down to the touchdown points, then PX4's Land
    (`gcs.flight.safety.landing`); or px4, PX4's Land straight down where each vehicle is."""
    landing_plan_timeout: float = 0.5
    """The landing plan must be ready within this (s, in (0, `MAX_LANDING_PLAN_TIMEOUT_S`]),
    the lead of its switch tick; the streams follow the flying plan meanwhile. Not ready:
    PX4's Land."""
    landing_height: float = 0.3
    """Height of the touchdown points above the workspace floor (m, in [0,
    `MAX_LANDING_HEIGHT_M`]), where PX4's Land takes over; one above the workspace's ceiling
    is a fallback to PX4's Land, which the event says."""
    replan_lead_s: float = DEFAULT_REPLAN_LEAD_S
    """An in-flight replan switches at least this far ahead of its request (s, in (0,
    `MAX_REPLAN_LEAD_S`]), and at least 1.5 x the flight's last replan's planning time: the
    new plan must be ready and verified by then, or it is not flown (`gcs.flight.replan.replan`)."""
    land_speed: float = 0.7
    """The fleet's landing descent speed (m/s, PX4's MPC_LAND_SPEED, in (0,
    `MAX_LAND_SPEED`]): a vehicle a replan drops with ``land`` is streamed down at it to
    `landing_height`, and the others' replanned paths expect a faulty vehicle that PX4
    lands to descend at it."""
    geofence: GeofenceChoice | None = None
    """upload: before arming, give every vehicle the plan's fence (the workspace rectangle,
    obstacles on the ground; `gcs.geofence`), read it back and refuse the flight when it
    differs; refused when no geodetic origin places it. skip: no fence (a lab without GPS).
    None (not given): upload when an origin is known (the vehicle reports GPS_GLOBAL_ORIGIN
    or the fleet has `world_origin`), else skip with an event saying why."""
    failsafe: FailsafeChoice = "set"
    """set: before arming, read and set every vehicle's link-loss failsafe (what it does
    when the station is gone: `gcs.flight.procedure.failsafe`) and refuse the flight,
    naming the vehicle and the parameter, when one cannot be read or set. try: set it where
    the vehicle answers, and fly a vehicle that does not on its own parameters (an event
    says so)."""

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str = _OPTIONS_KEY) -> FlightOptions:
        """Validated options from a fleet file's `flight` object (errors name ``where.key``)."""
        if not isinstance(data, Mapping):
            raise FleetFileError(where, "must be a JSON object")
        known = {f.name: f for f in fields(cls)}
        values: dict[str, Any] = {}
        for key, value in data.items():
            if key not in known:
                raise FleetFileError(f"{where}.{key}", "unknown key")
            values[key] = value
        return cls().replace(where=where, **values)

    def replace(self, where: str = "options", **changes: Any) -> FlightOptions:
        """A copy with `changes`, validated (errors name ``where.field``)."""
        for key, value in changes.items():
            if key in OPTION_CHOICES:
                allowed = OPTION_CHOICES[key]
                if key == "geofence" and value is None:
                    continue  # upload when an origin is known
                if value not in allowed:
                    raise FleetFileError(f"{where}.{key}",
                                         f"must be one of {', '.join(allowed)}, got {value!r}")
            elif key == "separation_alarm" and value is None:
                pass  # the band follows the plan's margin (`gcs.flight.safety.margin.alarm_band`)
            else:
                if isinstance(value, bool) or not isinstance(value, int | float) \
                        or not math.isfinite(value):
                    raise FleetFileError(f"{where}.{key}", "must be a finite number")
                if key != "yaw" and value < 0:
                    raise FleetFileError(f"{where}.{key}", f"must not be negative, got {value}")
        out = replace(self, **changes)
        if not MIN_RATE_HZ < out.rate_hz <= MAX_RATE_HZ:
            raise FleetFileError(f"{where}.rate_hz",
                                 f"must be in ({MIN_RATE_HZ:g}, {MAX_RATE_HZ:g}] Hz (PX4 needs "
                                 f"offboard setpoints faster than 2 Hz), got {out.rate_hz:g}")
        for key, (most, why) in _MAXIMA.items():
            if getattr(out, key) > most:
                raise FleetFileError(f"{where}.{key}",
                                     f"at most {most:g} {why}, got {getattr(out, key):g}")
        for key in ("link_timeout", "heartbeat_timeout", "tracking_error_max",
                    "start_tolerance", "goal_tolerance", "climb_speed", "pause_limit",
                    "position_rate_hz", "landing_plan_timeout", "replan_lead_s",
                    "land_speed"):
            if getattr(out, key) <= 0:
                raise FleetFileError(f"{where}.{key}", "must be positive")
        return out

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class VehicleSpec:
    """One vehicle of the fleet file."""

    id: str
    connection: str
    """pymavlink URL, e.g. ``udpin:127.0.0.1:14540``."""
    system_id: int
    component_id: int
    home: FloatArray | None
    """Home (LOCAL_NED origin) in the world frame, or None to compute it from world_origin."""
    signing_key: SigningKey | None = None
    """MAVLink 2 signing key (None: unsigned link, pinning only)."""
    peer: tuple[str, int] | None = None
    """Source address pinned up front (None: pinned at first contact)."""
    autopilot: str = "auto"
    """``auto`` (told by its HEARTBEAT), ``px4`` or ``ardupilot`` (`gcs.autopilot.CHOICES`)."""

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"id": self.id, "connection": self.connection,
                               "system_id": self.system_id, "component_id": self.component_id}
        if self.home is not None:
            out["home"] = self.home.tolist()
        if self.signing_key is not None:
            out["signing_key"] = str(self.signing_key.path)  # the path only, never the key
        if self.peer is not None:
            out["peer"] = f"{self.peer[0]}:{self.peer[1]}"
        if self.autopilot != "auto":
            out["autopilot"] = self.autopilot
        return out


@dataclass(frozen=True)
class FleetSpec:
    """A validated fleet file."""

    vehicles: tuple[VehicleSpec, ...]
    world_origin: Geodetic | None
    options: FlightOptions
    position_error: float | None = None
    """Expected position error of a vehicle of this fleet (m), or None if not stated."""

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], base_dir: str | Path | None = None) -> FleetSpec:
        """Validate a fleet document; relative key paths are relative to `base_dir`
        (default: the working directory)."""
        return _parse(data, Path(base_dir) if base_dir is not None else None)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"vehicles": [v.to_dict() for v in self.vehicles]}
        if self.world_origin is not None:
            o = self.world_origin
            out["world_origin"] = {"lat": o.lat, "lon": o.lon, "alt": o.alt}
        out[_OPTIONS_KEY] = self.options.to_dict()
        if self.position_error is not None:
            out["position_error"] = self.position_error
        return out

    def for_plan(self, plan_ids: Sequence[str]) -> list[VehicleSpec]:
        """The fleet's vehicles in plan order; every plan vehicle must be in the fleet."""
        by_id = {v.id: v for v in self.vehicles}
        missing = [vid for vid in plan_ids if vid not in by_id]
        if missing:
            raise FleetFileError(
                "vehicles", f"no entry for plan vehicle(s) {', '.join(map(repr, missing))} "
                f"(the fleet has {', '.join(map(repr, by_id)) or 'none'}): add them to the "
                f"fleet file, or fly the plan on {len(plan_ids)} mock vehicles (fleetplan fly "
                f"PLAN.json --mock; a service: fleetplan serve --mock {len(plan_ids)})")
        return [by_id[vid] for vid in plan_ids]


def load_fleet(path: str | Path) -> FleetSpec:
    """Read and validate a fleet file."""
    try:
        data = json.loads(Path(path).read_text())
    except OSError as exc:
        raise FleetFileError("fleet", f"cannot read {path}: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise FleetFileError("fleet", f"{path} is not valid JSON: {exc}") from None
    return _parse(data, Path(path).parent, source=str(path))


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise FleetFileError(where, f"must be a finite number, got {value!r}")
    return float(value)


def _key(value: Any, where: str, base_dir: Path | None) -> SigningKey:
    if not isinstance(value, str) or not value.strip():
        raise FleetFileError(where, "must be the path of a signing key file")
    path = Path(os.path.expanduser(value))
    if base_dir is not None and not path.is_absolute():
        path = base_dir / path
    try:
        return load_key(path)
    except KeyFileError as exc:
        raise FleetFileError(where, str(exc)) from None


def _peer(value: Any, where: str) -> tuple[str, int]:
    try:
        return parse_host_port(value if isinstance(value, str) else "")
    except ValueError:
        raise FleetFileError(where, f"must look like HOST:PORT, got {value!r}") from None


def _autopilot(value: Any, where: str) -> str:
    if value not in CHOICES:
        raise FleetFileError(where, f"must be one of {', '.join(CHOICES)}, "
                                    f"got {value!r}")
    return str(value)


def _warn_unsigned_ports(vehicles: Sequence[VehicleSpec], source: str) -> None:
    """A `FleetFileWarning` for each signed vehicle whose connection goes to a port its
    autopilot (or, for ``auto``, any autopilot) never checks signatures on."""
    for index, v in enumerate(vehicles):
        if v.signing_key is None:
            continue
        kinds = AUTOPILOTS.values() if v.autopilot == "auto" else [AUTOPILOTS[v.autopilot]]
        for kind in kinds:
            why = kind.unsigned_port(v.connection)
            if why is not None:
                warnings.warn(f"{source}: vehicles[{index}].connection ({v.id}) is signed, but "
                              f"{why}", FleetFileWarning, stacklevel=3)


def _options(data: Mapping[str, Any], source: str) -> FlightOptions:
    """The flight options under `_OPTIONS_KEY`, or under `_OLD_OPTIONS_KEY` with a warning
    naming `source` (the fleet file)."""
    if _OPTIONS_KEY in data and _OLD_OPTIONS_KEY in data:
        raise FleetFileError(_OLD_OPTIONS_KEY, f"is the old name of {_OPTIONS_KEY!r}: give "
                             f"the flight options once, under {_OPTIONS_KEY!r} (this file has "
                             f"both {_OPTIONS_KEY!r} and {_OLD_OPTIONS_KEY!r})")
    if _OLD_OPTIONS_KEY in data:
        warnings.warn(f"{source}: key {_OLD_OPTIONS_KEY!r} is read as {_OPTIONS_KEY!r}: rename "
                      f"it to {_OPTIONS_KEY!r}", FleetFileWarning, stacklevel=2)
        return FlightOptions.from_dict(data[_OLD_OPTIONS_KEY], _OLD_OPTIONS_KEY)
    return FlightOptions.from_dict(data.get(_OPTIONS_KEY, {}))


def _parse(data: Any, base_dir: Path | None = None, source: str = "fleet file") -> FleetSpec:
    """`FleetSpec.from_dict`; `source` names the document in warnings."""
    if not isinstance(data, Mapping):
        raise FleetFileError("fleet", "must be a JSON object")
    for key in data:
        if key not in _TOP_KEYS:
            raise FleetFileError(key, "unknown key")
    origin = _world_origin(data["world_origin"]) if "world_origin" in data else None
    fleet_key = _key(data["signing_key"], "signing_key", base_dir) \
        if "signing_key" in data else None
    fleet_autopilot = _autopilot(data.get("autopilot", "auto"), "autopilot")
    raw_vehicles = data.get("vehicles")
    if not isinstance(raw_vehicles, list) or not raw_vehicles:
        raise FleetFileError("vehicles", "must be a non-empty list")
    vehicles: list[VehicleSpec] = []
    seen_ids: dict[str, int] = {}
    seen_systems: dict[tuple[str, int], int] = {}
    for index, raw in enumerate(raw_vehicles):
        where = f"vehicles[{index}]"
        if not isinstance(raw, Mapping):
            raise FleetFileError(where, "must be a JSON object")
        for key in raw:
            if key not in _VEHICLE_KEYS:
                raise FleetFileError(f"{where}.{key}", "unknown key")
        for key in ("id", "connection", "system_id"):
            if key not in raw:
                raise FleetFileError(f"{where}.{key}", "is required")
        vid = raw["id"]
        if not isinstance(vid, str) or not vid.strip():
            raise FleetFileError(f"{where}.id", "must be a non-empty string")
        if vid in seen_ids:
            raise FleetFileError(f"{where}.id",
                                 f"duplicate id {vid!r} (also vehicles[{seen_ids[vid]}])")
        seen_ids[vid] = index
        url = _connection(raw["connection"], f"{where}.connection")
        ids = {}
        for key, lo, hi, default in (("system_id", 1, 254, None), ("component_id", 1, 255, 1)):
            value = raw.get(key, default)
            if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
                raise FleetFileError(f"{where}.{key}",
                                     f"must be an integer in [{lo}, {hi}], got {value!r}")
            ids[key] = value
        key = (url, ids["system_id"])
        if key in seen_systems:
            raise FleetFileError(
                f"{where}.system_id", f"system id {ids['system_id']} is already used on "
                f"{url} by vehicles[{seen_systems[key]}]")
        seen_systems[key] = index
        home = None
        if "home" in raw:
            value = raw["home"]
            if not isinstance(value, list) or len(value) != 3:
                raise FleetFileError(f"{where}.home", "must be a list of 3 numbers [x, y, z]")
            home = np.array([_number(c, f"{where}.home[{k}]") for k, c in enumerate(value)])
        elif origin is None:
            raise FleetFileError(f"{where}.home",
                                 "is required unless the fleet has a world_origin")
        signing_key = _key(raw["signing_key"], f"{where}.signing_key", base_dir) \
            if "signing_key" in raw else fleet_key
        peer = _peer(raw["peer"], f"{where}.peer") if "peer" in raw else None
        kind = _autopilot(raw["autopilot"], f"{where}.autopilot") if "autopilot" in raw \
            else fleet_autopilot
        vehicles.append(VehicleSpec(vid, url, ids["system_id"], ids["component_id"], home,
                                    signing_key, peer, kind))
    _warn_unsigned_ports(vehicles, source)
    options = _options(data, source)
    position_error = None
    if "position_error" in data:
        position_error = _number(data["position_error"], "position_error")
        if not 0.0 <= position_error <= 10.0:
            raise FleetFileError("position_error", f"must be within [0, 10] m, got "
                                                   f"{position_error:g}")
    return FleetSpec(tuple(vehicles), origin, options, position_error)


def _world_origin(raw: Any) -> Geodetic:
    """The fleet's `world_origin` {lat, lon, alt} (degrees, metres)."""
    if not isinstance(raw, Mapping) or set(raw) != {"lat", "lon", "alt"}:
        raise FleetFileError("world_origin", "must be an object {lat, lon, alt}")
    lat = _number(raw["lat"], "world_origin.lat")
    lon = _number(raw["lon"], "world_origin.lon")
    if not -90.0 <= lat <= 90.0:
        raise FleetFileError("world_origin.lat", f"must be within [-90, 90], got {lat}")
    if not -180.0 <= lon <= 180.0:
        raise FleetFileError("world_origin.lon", f"must be within [-180, 180], got {lon}")
    return Geodetic(lat, lon, _number(raw["alt"], "world_origin.alt"))


def _connection(url: Any, field: str) -> str:
    """A vehicle's `connection`: a pymavlink URL string, a UDP one with a host and a port."""
    if not isinstance(url, str) or not url.strip():
        raise FleetFileError(field, "must be a pymavlink URL string")
    if is_udp_url(url):
        try:
            parse_udp_url(url)
        except LinkError:
            scheme = url.partition(":")[0]
            raise FleetFileError(field, f"must look like {scheme}:HOST:PORT, got {url!r}") from None
    return url
