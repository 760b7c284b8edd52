"""The configured fleet: its vehicles, the in-process mocks, the link monitor, and what may be
sent to the vehicles between flights.

`Fleet` owns one fleet: the vehicles of a fleet file (real PX4 or ArduPilot vehicles, or
SITL), or mock vehicles running in-process (`gcs.sim.MockFleet`), or none. Between flights it
keeps a listen-only MAVLink monitor open on the fleet's connections so `GET /api/vehicles`
shows live link state; a flight closes the monitor and takes the connections
(`gcs.service.vehicle_host`). It lives in the vehicle process, on its vehicle loop
(`gcs.flight.host.vehicle_process`). Mock vehicles are set down under a plan's starts before
each flight (as ``fleetplan fly --mock`` does), with as many more as the plan needs up to
`mock_max_vehicles` (a fleet that grows, `serve --mock auto`); vehicles the plan does not use
are parked beside its workspace. `command` sends a fleet command (`gcs.fleet.commands`: hold,
land, rtl, disarm, terminate) over the monitor's connections, so a fleet left hovering can
always be landed.

It imports the mock (`gcs.sim`), which the service may only where it hosts it: ``serve --mock
N`` makes a mock fleet one of the service's fleets, started here (`tests/test_layout.py`,
`ALLOWED`). The mock imports only the bottom layer, so this import runs downward.
"""

from __future__ import annotations

import asyncio
import logging
import time
from typing import Any, Literal

import numpy as np

from gcs import frames
from gcs.errors import FleetFileError, GcsError, InvalidRequest, StateConflict
from gcs.fleet.commands import fleet_command
from gcs.fleet.fleetfile import FleetSpec, FlightOptions, load_fleet
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import DECODED_IDS, VehicleLink
from gcs.flight.run.ground import ground_refusal
from gcs.flight.safety.health import PreflightThresholds, health_report, preflight_problems
from gcs.flight.safety.margin import check_margin
from gcs.service.settings import Settings
from gcs.sim import MockConfig, MockFleet, homes_under
from gcs.sim.ports import block_free, free_udp_base, mock_fleet_ports, mock_port_offsets
from planner import Plan

__all__ = ["Fleet", "FleetKind", "fleet_kind"]

log = logging.getLogger(__name__)

#: Where the fleet comes from: a fleet file, the in-process mocks, or nothing.
FleetKind = Literal["file", "mock", "none"]
def fleet_kind(settings: Settings) -> FleetKind:
    """Where the settings' fleet comes from: a fleet file, else the mocks, else nothing."""
    if settings.fleet_file is not None:
        return "file"
    return "mock" if settings.mock_vehicles > 0 else "none"


#: The highest UDP port number.
MAX_UDP_PORT = 65535
#: A just-stopped mock fleet's sockets close on a later loop iteration: start attempts, gap.
MOCK_START_ATTEMPTS = 20
MOCK_START_RETRY_S = 0.05


class Fleet:
    """The vehicles of the service (file, mock or none) and their monitor links."""

    def __init__(self, settings: Settings) -> None:
        self._settings = settings
        self.kind: FleetKind = fleet_kind(settings)
        self.spec: FleetSpec | None = None
        """The fleet as a fleet file describes it (the mocks' own, for a mock fleet)."""
        self.mock: MockFleet | None = None
        """The in-process mock vehicles, for a mock fleet."""
        self._mock_ports: list[int] = []
        """The UDP ports the mock vehicles run on (theirs and the GCS side's)."""
        self._monitor: LinkHub | None = None
        self.links: dict[str, VehicleLink] = {}
        """The monitor's link to each vehicle, by id (empty while a flight has them)."""

    # ------------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        """Load the fleet file or start the mocks, then open the monitor."""
        if self.kind == "file":
            assert self._settings.fleet_file is not None
            self.spec = load_fleet(self._settings.fleet_file)
        elif self.kind == "mock":
            count = self._settings.mock_vehicles
            await self._start_mock([[2.0 * i, -2.0, 0.0] for i in range(count)],
                                   [f"uav{i + 1}" for i in range(count)])
        await self.open_monitor()

    async def close(self) -> None:
        """Close the monitor and stop the mocks."""
        await self.close_monitor()
        if self.mock is not None:
            await self.mock.stop()
            self.mock = None

    def _mock_overrides(self) -> dict[str, float]:
        """The mock settings given, as `MockConfig` fields (the rest stay the realism's)."""
        given = {"settle_time": self._settings.mock_settle_s,
                 "status_rate": self._settings.mock_status_rate_hz,
                 "land_speed": self._settings.mock_land_speed,
                 "disarm_after_land": self._settings.mock_disarm_after_land_s}
        return {name: value for name, value in given.items() if value is not None}

    def _mock_base(self, count: int) -> int:
        """The base port of a mock fleet of `count` vehicles: `mock_base_port` when its ports
        are free (or the fleet's own, closing as the old fleet stops), else a free block
        elsewhere (a fleet grown past the block the settings leave free), logged."""
        base = self._settings.mock_base_port
        offsets = mock_port_offsets(count)
        own = set(self._mock_ports) if self.mock is not None else set()
        fresh = [offset for offset in offsets if base + offset not in own]
        if base + max(offsets) <= MAX_UDP_PORT and block_free(base, fresh):
            return base
        chosen = free_udp_base(offsets)
        log.warning("UDP ports %d.. (setting mock_base_port) are taken for %d mock vehicles: "
                    "they run on %d.. instead", base, count, chosen)
        return chosen

    async def _start_mock(self, homes: list[list[float]], ids: list[str]) -> None:
        base = self._mock_base(len(homes))
        ports = mock_fleet_ports(base, len(homes))
        config = MockConfig.preset(self._settings.mock_realism, **self._mock_overrides())
        kinds = self._settings.mock_autopilot.split(",")
        mock = MockFleet(homes=homes, gcs_base_port=ports["gcs_base_port"],
                         listen_base_port=ports["listen_base_port"], config=config,
                         autopilots=[kinds[i % len(kinds)] for i in range(len(homes))])
        for attempt in range(MOCK_START_ATTEMPTS):
            try:
                await mock.start()
                break
            except OSError:
                if attempt == MOCK_START_ATTEMPTS - 1:
                    raise
                await asyncio.sleep(MOCK_START_RETRY_S)
        self.mock = mock
        self._mock_ports = [base + offset for offset in mock_port_offsets(len(homes))]
        self.spec = FleetSpec.from_dict(mock.fleet_dict(ids))

    async def open_monitor(self) -> None:
        """Listen on every vehicle's connection (logged, and left closed, if one fails)."""
        if self.spec is None:
            return
        hub = LinkHub(decode_ids=DECODED_IDS)  # PX4's ~410 messages/s: decode what is read
        await hub.__aenter__()
        try:
            for v in self.spec.vehicles:
                self.links[v.id] = await hub.add(v.id, v.connection, v.system_id,
                                                 v.component_id)
        except (OSError, GcsError) as exc:
            log.error("cannot open the fleet's connections to watch them: %s", exc)
            await hub.close()
            self.links = {}
            return
        self._monitor = hub

    async def close_monitor(self) -> None:
        """Release the fleet's connections (before a flight opens them)."""
        if self._monitor is not None:
            await self._monitor.close()
            self._monitor = None
        self.links = {}

    async def rehome_mock(self, plan: Plan) -> None:
        """Set the mock vehicles down under the plan's starts (as many more as it needs, up
        to `grows_to`, checked by `flight_options`); park the rest beside it."""
        old = self.mock
        if old is not None:
            await old.stop()
        ids = list(plan.scenario.ids)
        homes = homes_under(list(plan.scenario.starts))
        lo, hi = plan.scenario.limits.position_min, plan.scenario.limits.position_max
        for spare in range(self._settings.mock_vehicles - len(ids)):
            homes.append([float(hi[0]) + 2.0 + 2.0 * spare, float(lo[1]), 0.0])
            name = f"spare{spare + 1}"
            while name in ids:
                name += "_"
            ids.append(name)
        await self._start_mock(homes, ids)
        if old is not None and self.mock is not None:
            # the same airframes set down elsewhere: their battery and injected faults remain
            for before, after in zip(old.vehicles, self.mock.vehicles, strict=False):
                after.faults, after.battery = before.faults, before.battery

    # ------------------------------------------------------------------ state

    def describe(self) -> dict[str, Any]:
        """kind, vehicle count and ids, the geodetic origin of the world frame when known
        (the fleet file's `world_origin`, or the mock's), and `grows_to`: the most vehicles a
        mock fleet adding mocks as plans need may have (None: the fleet keeps its size). Safe
        from any thread: it reads the spec and the mock once, and the vehicle loop replaces
        them whole."""
        spec, mock = self.spec, self.mock  # each replaced whole on the vehicle loop
        ids = [] if spec is None else [v.id for v in spec.vehicles]
        origin = spec.world_origin if spec is not None else None
        if origin is None and mock is not None:
            origin = mock.world_origin
        return {
            "kind": self.kind,
            "vehicles": len(ids),
            "ids": ids,
            "world_origin": None if origin is None else {
                "lat": origin.lat, "lon": origin.lon, "alt": origin.alt},
            "grows_to": self.grows_to,
        }

    def monitored(self) -> list[dict[str, Any]]:
        """Every vehicle's link state as the monitor sees it (heartbeat age, mode, armed,
        world-frame position when the home is known, health)."""
        if self.spec is None:
            return []
        now = time.monotonic()
        out = []
        for spec in self.spec.vehicles:
            link = self.links.get(spec.id)
            tel = None if link is None else link.telemetry
            age = None if link is None else link.heartbeat_age(now)
            position = None
            if tel is not None and tel.position_ned is not None and spec.home is not None:
                position = frames.ned_to_world(tel.position_ned, spec.home).tolist()
            row: dict[str, Any] = {
                "id": spec.id,
                "system_id": spec.system_id,
                "connection": spec.connection,
                "link": "monitor" if link is not None else "closed",
                "heartbeat_age": None if age is None or not np.isfinite(age) else round(age, 3),
                "autopilot": (tel.autopilot_named(spec.autopilot) if tel is not None
                              else None if spec.autopilot == "auto" else spec.autopilot),
                "mode": None if tel is None or tel.mode is None else tel.mode.name,
                "armed": None if tel is None or tel.heartbeat_time is None else bool(tel.armed),
                "position": position,
                "home": None if spec.home is None else spec.home.tolist(),
            }
            if tel is not None:
                row.update(health_report(tel))
            out.append(row)
        return out

    def configured(self) -> FleetSpec:
        """The fleet's spec; StateConflict when there is no fleet."""
        if self.kind == "none" or self.spec is None:
            raise StateConflict("fleet", "no fleet configured: start the service with --mock "
                                         "auto (mock vehicles as plans need them), --mock N or "
                                         "--fleet FLEET.json")
        return self.spec

    # ------------------------------------------------------------------ commands

    async def command(self, command: str, vehicles: list[str] | None, *, force: bool,
                      confirm: bool) -> dict[str, Any]:
        """A fleet command over the monitor's links (the caller checks no flight has them):
        {command, done, vehicles: [outcome...]} once every vehicle answered or timed out."""
        self.configured()
        if not self.links:
            raise StateConflict("fleet", "the fleet's connections are not open (see the "
                                         "service log)")
        outcomes = await fleet_command(self.links, command, vehicles, force=force,
                                       confirm=confirm)
        log.warning("fleet command %s to %s: %s", command,
                    ", ".join(o.vehicle for o in outcomes),
                    "; ".join(f"{o.vehicle} {'done' if o.done else 'NOT done'}: {o.detail}"
                              for o in outcomes))
        return {"command": command, "done": all(o.done for o in outcomes),
                "vehicles": [o.to_dict() for o in outcomes]}

    # ------------------------------------------------------------------ before a flight

    def flight_options(self, plan: Plan, options: dict[str, Any]) -> FlightOptions:
        """The fleet's flight options with the request's, once the fleet can fly `plan`:
        StateConflict when it cannot (plan not verified, vehicles missing, pre-flight gate,
        separation margin refused), InvalidRequest for bad options."""
        spec = self.configured()
        if not plan.ok:
            raise StateConflict("mission_id", f"the plan is not flyable: status {plan.status!r}"
                           f"{'' if plan.verification is None else ', verification failed'}"
                           "; only converged, verified plans are flown")
        if (on_ground := ground_refusal(plan)) is not None:
            raise StateConflict("mission_id", on_ground)
        ids = plan.scenario.ids
        if self.kind == "mock" and len(ids) > self._settings.mock_fleet_limit:
            raise StateConflict("fleet", self._mock_too_small(len(ids)))
        if self.kind == "file":
            try:
                spec.for_plan(ids)
            except FleetFileError as exc:
                raise StateConflict("fleet", exc.reason) from None
        try:
            flight_options = spec.options.replace(where="options", **options)
        except FleetFileError as exc:
            raise InvalidRequest(exc.field, exc.reason) from None
        except TypeError as exc:
            raise InvalidRequest("options", str(exc)) from None
        self._preflight(spec, ids, flight_options)
        margin = check_margin(plan, spec.position_error)
        if not margin.ok and flight_options.margin_check == "refuse":
            raise StateConflict("mission_id", margin.message())
        return flight_options

    def _mock_too_small(self, needed: int) -> str:
        """Why the mock fleet cannot fly a plan of `needed` vehicles, and the setting to
        change."""
        settings = self._settings
        if self.grows_to is None:
            return (f"the plan has {needed} vehicles, the mock fleet {settings.mock_vehicles} "
                    f"(setting mock_vehicles): restart the service with --mock {needed}, or "
                    "--mock auto to add mock vehicles as plans need them")
        return (f"the plan has {needed} vehicles, more than the mock fleet may grow to: "
                f"{self.grows_to} (setting mock_max_vehicles): restart the service with "
                f"FLEETPLAN_MOCK_MAX_VEHICLES={needed} (or --mock {needed})")

    @property
    def grows_to(self) -> int | None:
        """How many vehicles a mock fleet that adds mocks as plans need may grow to (setting
        mock_max_vehicles); None for a fleet that keeps its size (a fixed mock fleet, a fleet
        file, none)."""
        settings = self._settings
        grows = self.kind == "mock" and settings.mock_fleet_grows
        return settings.mock_fleet_limit if grows else None

    def _preflight(self, spec: FleetSpec, ids: list[str], options: FlightOptions) -> None:
        """The pre-flight gate on what the monitor sees now (battery, unhealthy sensors, link
        loss): StateConflict naming the vehicle and the reason, unless `preflight: override`.
        A vehicle not heard from yet is left to the executor, which waits for it and names it
        if it never answers."""
        if options.preflight == "override":
            return
        limits = PreflightThresholds(min_battery_pct=options.min_battery_pct)
        if self.kind == "mock":  # mock vehicle i flies plan vehicle i (see rehome_mock)
            fleet_ids = [v.id for v in spec.vehicles][:len(ids)]  # those the fleet adds: new
            names = [f"{vid} (mock vehicle {fid})" if vid != fid else vid
                     for vid, fid in zip(ids, fleet_ids, strict=False)]
        else:
            fleet_ids, names = list(ids), list(ids)
        for fid, name in zip(fleet_ids, names, strict=True):
            link = self.links.get(fid)
            if link is None or link.telemetry.heartbeat_time is None:
                continue
            problems = preflight_problems(link.telemetry, limits, require_presence=False)
            if problems:
                raise StateConflict("fleet", f"pre-flight check: {name}: {'; '.join(problems)}"
                                             " (fly with preflight: override to fly anyway)")
