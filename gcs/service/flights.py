"""The configured fleet as the service sees it, and its flights (executions).

`FleetService` owns one fleet: the vehicles of a fleet file (real PX4 or SITL), or mock PX4
vehicles running in-process (`gcs.sim.MockFleet`), or none. Between flights it keeps a
listen-only MAVLink monitor open on the fleet's connections so `GET /api/vehicles` shows live
link state; for a flight it closes the monitor and hands the connections to a
`gcs.flight.executor.FlightExecutor`, which does everything that talks to vehicles. One
flight at a time: the fleet is one set of aircraft.

Mock vehicles are set down under the plan's starts before each flight (as
``fleetplan fly --mock`` does), so any verified plan with at most `mock_vehicles` vehicles can
be flown on them; vehicles the plan does not use are parked beside its workspace.

Nothing arms or moves until `fly` is called (POST /api/missions/{id}/executions), which first
applies the pre-flight gate (`gcs.flight.health`) and the fleet's separation margin
(`gcs.flight.margin`); `abort` sends every vehicle of the active flight to land (or hold) at
once; `pause` / `resume` stop and restart its mission clock. Between flights, `command` sends a
fleet command (`gcs.flight.commands`: hold, land, rtl, disarm, terminate) over the monitor's
connections, so a fleet left hovering can always be landed.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import orjson

from gcs import frames
from gcs.errors import FleetFileError, GcsError, InvalidRequest, MissionAborted, StateConflict
from gcs.flight.commands import fleet_command
from gcs.flight.executor import FlightExecutor
from gcs.flight.fleetfile import FleetSpec, FlightOptions, load_fleet
from gcs.flight.health import PreflightThresholds, health_report, preflight_problems
from gcs.flight.hub import LinkHub
from gcs.flight.link import DECODED_IDS, VehicleLink
from gcs.flight.margin import check_margin
from gcs.service.events import Broadcast, Event
from gcs.service.journal import ExecutionJournal, store_failure
from gcs.service.settings import Settings
from gcs.service.statuses import EXECUTION_ACTIVE, EXECUTION_FINISHED, ExecutionStatus
from gcs.service.store import ExecutionRow, Store
from gcs.sim import MockConfig, MockFleet, homes_under
from gcs.sim.ports import mock_fleet_ports
from gcs.tasks import TaskSet
from planner import Plan

__all__ = ["FINISHED", "LIVE", "FleetService", "LiveExecution", "execution_document"]

log = logging.getLogger(__name__)

#: Execution statuses while the flight is under way, and final ones (`gcs.service.statuses`).
LIVE = EXECUTION_ACTIVE
FINISHED = EXECUTION_FINISHED
#: Live telemetry snapshots per second on an execution's event stream.
TELEMETRY_HZ = 5.0


@dataclass
class LiveExecution:
    """One execution being flown (in memory while it runs)."""

    id: str
    mission_id: str
    status: ExecutionStatus = ExecutionStatus.STARTING
    executor: FlightExecutor | None = None
    events: list[dict[str, Any]] = field(default_factory=list)
    summary: dict[str, Any] | None = None
    error: str | None = None
    abort_requested: str | None = None
    done: asyncio.Event = field(default_factory=asyncio.Event)
    listeners: Broadcast = field(default_factory=Broadcast)

    @property
    def active(self) -> bool:
        return not self.done.is_set()

    def publish(self, kind: str, data: dict[str, Any]) -> None:
        self.listeners.publish(kind, data)

    def set_status(self, status: ExecutionStatus) -> None:
        self.status = status
        self.publish("status", {"status": status})

    def snapshot(self) -> dict[str, Any] | None:
        return None if self.executor is None else self.executor.snapshot()

    def outcome(self) -> dict[str, Any]:
        return {"status": self.status, "summary": self.summary, "error": self.error}

    async def stream(self) -> AsyncIterator[Event]:
        """("status"|"event"|"telemetry", data)... then ("done", outcome); events so far
        first, then live."""
        history: list[Event] = [("status", {"status": self.status})]
        history += [("event", event) for event in self.events]
        snapshot = self.snapshot()
        if snapshot is not None:
            history.append(("telemetry", snapshot))
        done = None if self.active else ("done", self.outcome())
        async for event in self.listeners.follow(history, done):
            yield event


class FleetService:
    """The configured fleet, its live link state and its one active flight."""

    def __init__(self, settings: Settings, store: Store) -> None:
        self._settings = settings
        self._store = store
        if settings.fleet_file is not None:
            self.kind = "file"
        elif settings.mock_vehicles > 0:
            self.kind = "mock"
        else:
            self.kind = "none"
        self._spec: FleetSpec | None = None
        self._mock: MockFleet | None = None
        self._monitor: LinkHub | None = None
        self._links: dict[str, VehicleLink] = {}
        self._flights: dict[str, LiveExecution] = {}
        self._active: LiveExecution | None = None
        self._tasks = TaskSet()
        self._lock = asyncio.Lock()

    # ------------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        if self.kind == "file":
            assert self._settings.fleet_file is not None
            self._spec = load_fleet(self._settings.fleet_file)
        elif self.kind == "mock":
            count = self._settings.mock_vehicles
            await self._start_mock([[2.0 * i, -2.0, 0.0] for i in range(count)],
                                   [f"uav{i + 1}" for i in range(count)])
        await self._open_monitor()

    async def close(self) -> None:
        """Land an active flight (waiting for it up to a minute), then release everything."""
        flight = self._active
        if flight is not None and flight.active:
            log.warning("service stopping during execution %s: landing every vehicle", flight.id)
            await self.abort(flight.id, "land", "the service is stopping")
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(flight.done.wait(), 60.0)
        self._tasks.cancel_all()
        await self._tasks.wait(timeout=10.0)  # let cancelled flights store what they have
        await self._close_monitor()
        if self._mock is not None:
            await self._mock.stop()
            self._mock = None

    async def _start_mock(self, homes: list[list[float]], ids: list[str]) -> None:
        base = self._settings.mock_base_port
        config = MockConfig.preset(self._settings.mock_realism)
        if self._settings.mock_settle_s is not None:
            config.settle_time = self._settings.mock_settle_s
        mock = MockFleet(homes=homes, **mock_fleet_ports(base), config=config)
        # A just-stopped fleet's sockets close on a later loop iteration: retry briefly.
        for attempt in range(20):
            try:
                await mock.start()
                break
            except OSError:
                if attempt == 19:
                    raise
                await asyncio.sleep(0.05)
        self._mock = mock
        self._spec = FleetSpec.from_dict(mock.fleet_dict(ids))

    async def _open_monitor(self) -> None:
        if self._spec is None:
            return
        hub = LinkHub(decode_ids=DECODED_IDS)  # PX4's ~410 messages/s: decode what is read
        await hub.__aenter__()
        try:
            for v in self._spec.vehicles:
                self._links[v.id] = await hub.add(v.id, v.connection, v.system_id,
                                                  v.component_id)
        except (OSError, GcsError) as exc:
            log.error("cannot open the fleet's connections to watch them: %s", exc)
            await hub.close()
            self._links = {}
            return
        self._monitor = hub

    async def _close_monitor(self) -> None:
        if self._monitor is not None:
            await self._monitor.close()
            self._monitor = None
        self._links = {}

    # ------------------------------------------------------------------ state

    def describe(self) -> dict[str, Any]:
        """kind (mock, file or none), vehicle count and ids, the flight under way, and the
        geodetic origin of the world frame when known (the fleet file's `world_origin`, or
        the mock's), so a page can show coordinates and a scale without map tiles."""
        ids = [] if self._spec is None else [v.id for v in self._spec.vehicles]
        origin = self._spec.world_origin if self._spec is not None else None
        if origin is None and self._mock is not None:
            origin = self._mock.world_origin
        return {
            "kind": self.kind,
            "vehicles": len(ids),
            "ids": ids,
            "flying": None if self._active is None else self._active.id,
            "world_origin": None if origin is None else {
                "lat": origin.lat, "lon": origin.lon, "alt": origin.alt},
        }

    def vehicles(self) -> list[dict[str, Any]]:
        """Every vehicle's live link state: from the flight under way, else from the
        monitor (heartbeat age, mode, armed, world-frame position when the home is known)."""
        flight = self._active
        snapshot = flight.snapshot() if flight is not None else None
        if snapshot is not None:
            return [{**v, "link": "flight"} for v in snapshot["vehicles"]]
        if self._spec is None:
            return []
        now = time.monotonic()
        out = []
        for spec in self._spec.vehicles:
            link = self._links.get(spec.id)
            tel = None if link is None else link.telemetry
            age = None if link is None else link.heartbeat_age(now)
            position = None
            if tel is not None and tel.position_ned is not None and spec.home is not None:
                position = frames.ned_to_world(tel.position_ned, spec.home).tolist()
            out.append({
                "id": spec.id,
                "system_id": spec.system_id,
                "connection": spec.connection,
                "link": "monitor" if link is not None else "closed",
                "heartbeat_age": None if age is None or not np.isfinite(age) else round(age, 3),
                "mode": None if tel is None or tel.mode is None else tel.mode.name,
                "armed": None if tel is None or tel.heartbeat_time is None else bool(tel.armed),
                "position": position,
                "home": None if spec.home is None else spec.home.tolist(),
                **(health_report(tel) if tel is not None else {}),
            })
        return out

    def flight(self, execution_id: str) -> LiveExecution | None:
        """The flight while it is under way (afterwards the store has it)."""
        return self._flights.get(execution_id)

    @property
    def active(self) -> LiveExecution | None:
        return self._active if self._active is not None and self._active.active else None

    # ------------------------------------------------------------------ fleet commands

    async def command(self, command: str, vehicles: list[str] | None = None, *,
                      force: bool = False, confirm: bool = False) -> dict[str, Any]:
        """A fleet command (`gcs.flight.commands`) to `vehicles` (default all) between flights.

        StateConflict while a flight is under way (abort or pause it instead), with no fleet,
        or when the fleet's connections are not open; InvalidRequest / StateConflict from
        the command's own checks (nothing sent then). Returns {command, done, vehicles:
        [outcome...]} once every vehicle answered or timed out."""
        async with self._lock:
            self._check_fleet_free("use its abort (or pause) instead of a fleet command")
            if not self._links:
                raise StateConflict("fleet", "the fleet's connections are not open (see the "
                                             "service log)")
            outcomes = await fleet_command(self._links, command, vehicles, force=force,
                                           confirm=confirm)
        log.warning("fleet command %s to %s: %s", command,
                    ", ".join(o.vehicle for o in outcomes),
                    "; ".join(f"{o.vehicle} {'done' if o.done else 'NOT done'}: {o.detail}"
                              for o in outcomes))
        return {"command": command, "done": all(o.done for o in outcomes),
                "vehicles": [o.to_dict() for o in outcomes]}

    def _check_fleet_free(self, while_flying: str) -> None:
        """StateConflict unless there is a fleet and no flight is using it."""
        if self.active is not None:
            raise StateConflict("fleet", f"execution {self.active.id} is flying: {while_flying}")
        if self.kind == "none" or self._spec is None:
            raise StateConflict("fleet", "no fleet configured: start the service with --mock N "
                                         "or --fleet FLEET.json")

    # ------------------------------------------------------------------ flying

    async def fly(self, mission_id: str, plan: Plan, options: dict[str, Any]) -> ExecutionRow:
        """Start flying `plan` on the fleet; returns the new execution (status starting).

        StateConflict when nothing can fly it (no fleet, a flight under way, a plan that is not
        verified, vehicles missing from the fleet); InvalidRequest for bad options.
        """
        async with self._lock:
            self._check_fleet_free("abort it or wait for it to end")
            if not plan.ok:
                raise StateConflict("mission_id", f"the plan is not flyable: status {plan.status!r}"
                               f"{'' if plan.verification is None else ', verification failed'}"
                               "; only converged, verified plans are flown")
            ids = plan.scenario.ids
            if self.kind == "mock" and len(ids) > self._settings.mock_vehicles:
                raise StateConflict("fleet", f"the plan has {len(ids)} vehicles, the mock fleet "
                               f"{self._settings.mock_vehicles} (setting mock_vehicles)")
            if self.kind == "file":
                try:
                    self._spec.for_plan(ids)
                except FleetFileError as exc:
                    raise StateConflict("fleet", exc.reason) from None
            try:
                mission_options = self._spec.options.replace(where="options", **options)
            except FleetFileError as exc:
                raise InvalidRequest(exc.field, exc.reason) from None
            except TypeError as exc:
                raise InvalidRequest("options", str(exc)) from None
            self._preflight(ids, mission_options)
            margin = check_margin(plan, self._spec.position_error)
            if not margin.ok and mission_options.margin_check == "refuse":
                raise StateConflict("mission_id", margin.message())
            label = f"{self.kind}: {', '.join(ids)}"
            row = await asyncio.to_thread(self._store.create_execution, mission_id, label)
            flight = LiveExecution(row.id, mission_id)
            self._flights[row.id] = flight
            self._active = flight
            self._tasks.spawn(self._run(flight, plan, mission_options))
            return row

    def _preflight(self, ids: list[str], options: FlightOptions) -> None:
        """The pre-flight gate on what the monitor sees now (battery, unhealthy sensors, link
        loss): StateConflict naming the vehicle and the reason, unless `preflight: override`.
        A vehicle not heard from yet is left to the executor, which waits for it and names it
        if it never answers."""
        if options.preflight == "override":
            return
        limits = PreflightThresholds(min_battery_pct=options.min_battery_pct)
        assert self._spec is not None
        if self.kind == "mock":  # mock vehicle i flies plan vehicle i (see _rehome_mock)
            fleet_ids = [v.id for v in self._spec.vehicles][:len(ids)]
            names = [f"{vid} (mock vehicle {fid})" if vid != fid else vid
                     for vid, fid in zip(ids, fleet_ids, strict=True)]
        else:
            fleet_ids, names = list(ids), list(ids)
        for fid, name in zip(fleet_ids, names, strict=True):
            link = self._links.get(fid)
            if link is None or link.telemetry.heartbeat_time is None:
                continue
            problems = preflight_problems(link.telemetry, limits, require_presence=False)
            if problems:
                raise StateConflict("fleet", f"pre-flight check: {name}: {'; '.join(problems)}"
                                             " (fly with preflight: override to fly anyway)")

    async def abort(
        self, execution_id: str, action: str, reason: str = "operator abort",
        stored_status: str = "finished",
    ) -> LiveExecution:
        """Every vehicle of the flight to `action` (land or hold) now; StateConflict if it is not
        flying. Returns at once; the flight ends (status aborted) when the vehicles are safe."""
        flight = self._flights.get(execution_id)
        if flight is None or not flight.active:
            status = stored_status if flight is None else flight.status
            raise StateConflict("execution_id", f"execution {execution_id!r} is not flying "
                           f"(status {status})")
        if flight.abort_requested is None:
            flight.abort_requested = action
            flight.set_status(ExecutionStatus.ABORTING)
            if flight.executor is not None:
                self._tasks.spawn(flight.executor.abort(action, reason))
        return flight

    def pause(self, execution_id: str, stored_status: str = "finished") -> LiveExecution:
        """Stop the flight's mission clock, every vehicle holding the plan's setpoint of the
        same plan time (status paused). StateConflict unless it is running its plan."""
        flight = self._flying(execution_id, stored_status)
        if flight.status != ExecutionStatus.RUNNING or flight.executor is None:
            raise StateConflict("execution_id", f"execution {execution_id!r} cannot be "
                                                f"paused (status {flight.status})")
        flight.executor.pause()
        flight.set_status(ExecutionStatus.PAUSED)
        return flight

    def resume(self, execution_id: str, stored_status: str = "finished") -> LiveExecution:
        """Restart a paused flight's mission clock where it stopped (status running)."""
        flight = self._flying(execution_id, stored_status)
        if flight.status != ExecutionStatus.PAUSED or flight.executor is None:
            raise StateConflict("execution_id", f"execution {execution_id!r} is not paused "
                                                f"(status {flight.status})")
        flight.executor.resume()
        flight.set_status(ExecutionStatus.RUNNING)
        return flight

    def _flying(self, execution_id: str, stored_status: str) -> LiveExecution:
        flight = self._flights.get(execution_id)
        if flight is None or not flight.active:
            status = stored_status if flight is None else flight.status
            raise StateConflict("execution_id", f"execution {execution_id!r} is not flying "
                                                f"(status {status})")
        return flight

    async def _run(self, flight: LiveExecution, plan: Plan, options: Any) -> None:
        record: dict[str, Any] | None = None
        ticker: asyncio.Task[None] | None = None
        relay: asyncio.Task[None] | None = None
        task: asyncio.Task[dict[str, Any]] | None = None
        # Persistence hook (gcs.service.journal): state, events and the record so far are
        # stored about every second while flying, so a crash keeps them.
        journal = ExecutionJournal(self._store, flight.id, lambda: (
            flight.status, flight.events,
            None if flight.executor is None else flight.executor.recorder))
        journal.start()
        try:
            await self._close_monitor()
            if self.kind == "mock":
                await self._rehome_mock(plan)
            assert self._spec is not None
            executor = FlightExecutor(plan, self._spec, options)
            flight.executor = executor
            relay = asyncio.create_task(self._relay_events(flight, executor))
            ticker = asyncio.create_task(self._telemetry(flight, executor))
            task = executor.start()
            if flight.abort_requested is not None:  # aborted while starting
                await executor.abort(flight.abort_requested, "operator abort")
            else:
                flight.set_status(ExecutionStatus.RUNNING)
            record = await task
            flight.summary = record.get("summary")
            completed = bool(flight.summary and flight.summary.get("completed"))
            flight.status = (ExecutionStatus.COMPLETED if completed
                             else ExecutionStatus.INCOMPLETE)
        except MissionAborted as exc:
            flight.status, flight.error = ExecutionStatus.ABORTED, str(exc)
        except GcsError as exc:
            flight.status, flight.error = ExecutionStatus.FAILED, f"{type(exc).__name__}: {exc}"
        except asyncio.CancelledError:
            flight.status = ExecutionStatus.INTERRUPTED
            flight.error = "the service stopped during the flight"
            raise
        except Exception as exc:  # a bug: report it, keep the service up
            log.exception("execution %s failed", flight.id)
            flight.status, flight.error = ExecutionStatus.FAILED, f"{type(exc).__name__}: {exc}"
            if task is not None and not task.done() and flight.executor is not None:
                # never leave a mission flying on its own: land everyone, then wait for it
                with contextlib.suppress(Exception):
                    await flight.executor.abort("land", f"service error: {type(exc).__name__}")
                with contextlib.suppress(BaseException):
                    await task
        finally:
            for helper in (ticker, relay):
                if helper is not None:
                    helper.cancel()
            if record is None and flight.executor is not None:
                record = flight.executor.record
            if record is not None and flight.summary is None:
                flight.summary = record.get("summary")
            await journal.close()
            await self._persist(flight, record)
            if self._active is flight:
                self._active = None
            flight.done.set()
            flight.publish("done", flight.outcome())
            # Stored now: drop it (and its executor, which holds the whole record) from memory.
            self._flights.pop(flight.id, None)
            await self._open_monitor()

    async def _rehome_mock(self, plan: Plan) -> None:
        """Set the mock vehicles down under the plan's starts; park the rest beside it."""
        old = self._mock
        if old is not None:
            await old.stop()
        ids = list(plan.scenario.ids)
        homes = homes_under(plan.scenario.starts)
        lo, hi = plan.scenario.limits.position_min, plan.scenario.limits.position_max
        for spare in range(self._settings.mock_vehicles - len(ids)):
            homes.append([float(hi[0]) + 2.0 + 2.0 * spare, float(lo[1]), 0.0])
            name = f"spare{spare + 1}"
            while name in ids:
                name += "_"
            ids.append(name)
        await self._start_mock(homes, ids)
        if old is not None and self._mock is not None:
            # the same airframes set down elsewhere: their battery and injected faults remain
            for before, after in zip(old.vehicles, self._mock.vehicles, strict=False):
                after.faults, after.battery = before.faults, before.battery

    async def _relay_events(self, flight: LiveExecution, executor: FlightExecutor) -> None:
        async for event in executor.events():
            flight.events.append(event)
            flight.publish("event", event)
            if event["kind"] == "pause_limit" and flight.status == ExecutionStatus.PAUSED:
                flight.set_status(ExecutionStatus.ABORTING)

    async def _telemetry(self, flight: LiveExecution, executor: FlightExecutor) -> None:
        while True:
            flight.publish("telemetry", executor.snapshot())
            await asyncio.sleep(1.0 / TELEMETRY_HZ)

    async def _persist(self, flight: LiveExecution, record: dict[str, Any] | None) -> None:
        def write() -> None:
            text = None
            if record is not None:
                # orjson: a flight record is megabytes; json.dumps would hold the GIL longer.
                text = orjson.dumps(record, option=orjson.OPT_SERIALIZE_NUMPY).decode()
            self._store.update_execution(
                flight.id, status=flight.status, events=flight.events, summary=flight.summary,
                record_json=text, error=flight.error, finished=True,
            )

        try:
            await asyncio.to_thread(write)
        except Exception as exc:
            log.exception("could not store execution %s", flight.id)
            # Never leave it stored as flying: failed, with the reason (persistence hook).
            await store_failure(self._store, flight.id, f"the flight ({flight.status}) could "
                                f"not be stored: {type(exc).__name__}: {exc}"[:500], flight.events)


def execution_document(row: ExecutionRow, flight: LiveExecution | None) -> dict[str, Any]:
    """`ExecutionOut`: the stored execution, with live state while it flies."""
    doc = row.to_dict()
    if flight is not None and flight.active:
        # The live state, and the summary as soon as the flight has one (it is set together
        # with the final status, before the row is stored): never a final status without it.
        doc.update(status=flight.status, events=list(flight.events), live=flight.snapshot())
        if flight.summary is not None:
            doc["summary"] = flight.summary
    else:
        doc["live"] = None
    doc["links"] = {
        "self": f"/api/executions/{row.id}",
        "events": f"/api/executions/{row.id}/events",
        "abort": f"/api/executions/{row.id}/abort",
        "pause": f"/api/executions/{row.id}/pause",
        "resume": f"/api/executions/{row.id}/resume",
        "record": f"/api/executions/{row.id}/record",
        "mission": f"/api/missions/{row.mission_id}",
    }
    return doc

