"""The fleet's flights: fly, pause, resume, replan, abort, and the run of one
flight from its start to its stored record.

Long: one class, `FleetService`: a flight's commands and its run to the stored record.

`FleetService` drives the configured fleet and its one active flight: the fleet is one set of
aircraft. Everything that talks to vehicles runs in a process of its own, the vehicle process
(`gcs.flight.host.vehicle_process.VehicleProcess`): the fleet (mocks, monitor links, fleet
commands) and each flight's `gcs.flight.run.executor.FlightExecutor`, hosted there by
`gcs.service.vehicle_host.FleetHost` and reached through its methods (start, pause, resume,
replan, abort, snapshots, events, the record). So no request handler, export, event stream,
planning job or store write of the service can delay a setpoint tick, not even by holding the
interpreter's lock. The flight's state lives here in a `LiveFlight`
(`gcs.service.live_flight`), its handle is a `gcs.service.remote_flight.RemoteFlight`, and it
is journaled to the store while it flies (`gcs.service.journal`).

Nothing arms or moves until `fly` is called (POST /api/missions/{id}/flights), which first
applies the pre-flight gate (`gcs.flight.safety.health`) and the fleet's separation margin
(`gcs.flight.safety.margin`); `abort` sends every vehicle of the active flight to land (or hold) at
once; `pause` / `resume` stop and restart its flight clock; `replan` changes goals or drops
vehicles in flight (`FlightExecutor.replan`). Between flights `command` sends a fleet
command over the monitor's connections.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import time
from datetime import UTC, datetime
from typing import Any

import orjson

from gcs.documents import FlightEvent, ReplanDocument
from gcs.errors import FlightAborted, GcsError, StateConflict, VehicleLoopStopped
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.host.vehicle_process import VehicleProcess
from gcs.flight.run.precedence import abort_in_force, aborting_refusal
from gcs.phases import DropAction, EventKind, FlightPhase
from gcs.service.fleet import FleetKind, fleet_kind
from gcs.service.flown_trajectory import replanned_in
from gcs.service.journal import FlightJournal, store_failure, write_final
from gcs.service.live_flight import LiveFlight, flight_document
from gcs.service.remote_flight import RemoteFlight
from gcs.service.replan_handle import Segment
from gcs.service.settings import Settings
from gcs.service.statuses import FLIGHT_ACTIVE, FLIGHT_FINISHED, FlightStatus, status_of
from gcs.service.storage_faults import storage_reason
from gcs.service.store import FlightRow, Store
from gcs.service.vehicle_host import CLOSE_LANDING_S, PRELOAD, FleetHost
from gcs.tasks import TaskSet
from planner import Plan

__all__ = ["FINISHED", "LIVE", "FleetService", "LiveFlight", "flight_document"]

log = logging.getLogger(__name__)

#: Flight statuses while the flight is under way, and final ones (`gcs.service.statuses`).
LIVE = FLIGHT_ACTIVE
FINISHED = FLIGHT_FINISHED
#: Live telemetry snapshots per second on a flight's event stream.
TELEMETRY_HZ = 5.0
#: How often the record's mirror is brought up to date while a flight flies (s).
MIRROR_PERIOD_S = 1.0
#: A vehicle process that ended is restarted, unless the last restart was this recent (s).
RESTART_HOLDOFF_S = 30.0
#: First and longest wait between retries of an ended flight's final write (s).
STORE_RETRY_S = 1.0
STORE_RETRY_MAX_S = 10.0


class FleetService:
    """The configured fleet, its live link state and its one active flight."""

    def __init__(self, settings: Settings, store: Store) -> None:
        self._store = store
        self._settings = settings
        self.vehicle_process = self._new_process()
        """The process everything that talks to vehicles runs in (fleet, mocks, flights)."""
        self._restarted_at: float | None = None
        self._kind: FleetKind = fleet_kind(settings)
        self._described: dict[str, Any] = {"kind": self._kind, "vehicles": 0, "ids": [],
                                           "world_origin": None, "grows_to": None}
        self._flights: dict[str, LiveFlight] = {}
        self._active: LiveFlight | None = None
        self._tasks = TaskSet()
        self._lock = asyncio.Lock()
        self._closing = False

    def _new_process(self) -> VehicleProcess:
        return VehicleProcess(
            functools.partial(FleetHost, settings=self._settings),
            realtime=self._settings.vehicle_thread_priority == "realtime",
            on_notice=self._on_notice, preload=PRELOAD)

    @property
    def kind(self) -> str:
        """Where the fleet comes from: file, mock or none."""
        return self._kind

    # ------------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        """Start the vehicle process, where the fleet is loaded (or the mocks started) and
        its links watched."""
        await self.vehicle_process.start()
        if self.vehicle_process.scheduling != "ordinary":
            log.info("vehicle process scheduling: %s", self.vehicle_process.scheduling)
        self._described = await self.vehicle_process.call("describe")

    async def close(self) -> None:
        """Land an active flight (waiting for it up to a minute), then release everything
        (a flight still waiting for the store gets a last try)."""
        self._closing = True
        flight = self._active
        if flight is not None and flight.active:
            log.warning("service stopping during flight %s: landing every vehicle", flight.id)
            await self.abort(flight.id, "land", "the service is stopping")
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(flight.done.wait(), CLOSE_LANDING_S)
        self._tasks.cancel_all()
        await self._tasks.wait(timeout=10.0)  # let cancelled flights store what they have
        await self.vehicle_process.stop()  # its host lands what still flies, then the fleet

    async def _restart_vehicles(self) -> None:
        """A new vehicle process once the ended one's flight (if any) is stored as failed, so
        the fleet is watched again and a fleet left hovering can be landed with a fleet
        command. Not again within RESTART_HOLDOFF_S of the last restart (a process that dies at
        once is left stopped, and GET /api/status says so)."""
        now = time.monotonic()
        if self._restarted_at is not None and now - self._restarted_at < RESTART_HOLDOFF_S:
            log.error("the vehicle process ended again within %.0f s of its restart: left "
                      "stopped; restart the service", RESTART_HOLDOFF_S)
            return
        self._restarted_at = now
        while self._active is not None and not self._closing:
            await asyncio.sleep(0.1)  # the flight's run stores it failed first
        if self._closing:
            return
        await self.vehicle_process.stop()
        self.vehicle_process = self._new_process()
        try:
            await self.vehicle_process.start()
            self._described = await self.vehicle_process.call("describe")
        except GcsError as exc:
            log.error("could not restart the vehicle process: %s", exc)
            return
        log.warning("vehicle process restarted: the fleet is watched again")

    # ------------------------------------------------------------------ state

    def describe(self) -> dict[str, Any]:
        """kind (mock, file or none), vehicle count and ids, the flight under way, and the
        geodetic origin of the world frame when known, so a page can show coordinates and a
        scale without map tiles."""
        described = {**self._described,
                     "vehicle_process": "running" if self.vehicle_process.alive else "stopped"}
        return {**described, "flying": None if self._active is None else self._active.id}

    async def vehicles(self) -> list[dict[str, Any]]:
        """Every vehicle's live link state: from the flight under way, else from the
        monitor (heartbeat age, mode, armed, world-frame position when the home is known),
        read in the vehicle process."""
        flight = self._active
        snapshot = flight.snapshot() if flight is not None else None
        if snapshot is not None:
            return [{**v, "link": "flight"} for v in snapshot["vehicles"]]
        monitored: list[dict[str, Any]] = await self.vehicle_process.call("monitored")
        return monitored

    def flight(self, flight_id: str) -> LiveFlight | None:
        """The flight while it is under way, or ended and waiting for the store to take its
        final state (afterwards the store has it)."""
        return self._flights.get(flight_id)

    @property
    def active(self) -> LiveFlight | None:
        """The flight under way, if any."""
        return self._active if self._active is not None and self._active.active else None

    # ------------------------------------------------------------------ fleet commands

    async def command(self, command: str, vehicles: list[str] | None = None, *,
                      force: bool = False, confirm: bool = False) -> dict[str, Any]:
        """A fleet command (`gcs.fleet.commands`) to `vehicles` (default all) between flights.

        StateConflict while a flight is under way (abort or pause it instead), with no fleet,
        or when the fleet's connections are not open; InvalidRequest / StateConflict from
        the command's own checks (nothing sent then). Returns {command, done, vehicles:
        [outcome...]} once every vehicle answered or timed out."""
        async with self._lock:
            self._check_not_flying("use its abort (or pause) instead of a fleet command")
            outcome: dict[str, Any] = await self.vehicle_process.call(
                "command", command, vehicles, force=force, confirm=confirm)
            return outcome

    def _check_not_flying(self, while_flying: str) -> None:
        if self.active is not None:
            raise StateConflict("fleet", f"flight {self.active.id} is flying: {while_flying}")

    # ------------------------------------------------------------------ flying

    async def fly(self, mission_id: str, plan: Plan, options: dict[str, Any]) -> FlightRow:
        """Start flying `plan` on the fleet; returns the new flight (status starting).

        StateConflict when nothing can fly it (no fleet, a flight under way, a plan that is not
        verified, vehicles missing from the fleet); InvalidRequest for bad options.
        """
        async with self._lock:
            self._check_not_flying("abort it or wait for it to end")
            flight_options = await self.vehicle_process.call("flight_options", plan, options)
            label = f"{self.kind}: {', '.join(plan.scenario.ids)}"
            row = await asyncio.to_thread(self._store.create_flight, mission_id, label)
            flight = LiveFlight(row.id, mission_id)
            self._flights[row.id] = flight
            self._active = flight
            self._tasks.spawn(self._run(flight, plan, flight_options))
            return row

    async def abort(
        self, flight_id: str, action: str, reason: str = "operator abort",
        stored_status: FlightStatus | None = None,
    ) -> LiveFlight:
        """Every vehicle of the flight to `action` (land or hold) now; StateConflict if it is not
        flying, or when `action` loses to the abort under way (`gcs.flight.run.precedence`: land
        overrides hold). Returns once the flight accepted it; the flight ends (status
        aborted) when the vehicles are safe."""
        flight = self._flying(flight_id, stored_status)
        if flight.handle is None:  # starting: passed on once the flight exists
            abort_in_force(flight.abort_requested, action)
        else:
            await flight.handle.request_abort(action, reason)
        flight.aborts.append(action)
        if flight.active:
            flight.set_status(FlightStatus.ABORTING)
        return flight

    async def pause(self, flight_id: str, stored_status: FlightStatus | None = None) -> LiveFlight:
        """Stop the flight's clock, every vehicle holding the plan's setpoint of the same plan
        time (status paused). StateConflict unless it is running its plan."""
        return await self._set_clock(flight_id, stored_status, pause=True)

    async def resume(self, flight_id: str, stored_status: FlightStatus | None = None) -> LiveFlight:
        """Restart a paused flight's clock where it stopped (status running)."""
        return await self._set_clock(flight_id, stored_status, pause=False)

    async def _set_clock(self, flight_id: str, stored_status: FlightStatus | None, *,
                         pause: bool) -> LiveFlight:
        """`pause` (running -> paused) or resume (paused -> running) the flight's clock;
        StateConflict from any other status or while it aborts."""
        running, paused = status_of(FlightPhase.FLYING), status_of(FlightPhase.PAUSED)
        command, before, after, refusal = (
            ("pause", running, paused, "cannot be paused") if pause
            else ("resume", paused, running, "is not paused"))
        flight = self._flying(flight_id, stored_status)
        self._not_aborting(flight, command)
        if flight.status != before or flight.handle is None:
            raise StateConflict("flight_id", f"flight {flight_id!r} {refusal} "
                                             f"(status {flight.status})")
        await (flight.handle.pause() if pause else flight.handle.resume())
        if flight.status == before:  # not aborted meanwhile
            flight.set_status(after)
        return flight

    async def replan(self, flight_id: str, goals: dict[str, list[float]] | None,
                     drop: list[str], drop_action: DropAction, reason: str = "operator",
                     stored_status: FlightStatus | None = None) -> ReplanDocument:
        """Start an in-flight replan of a running flight (new goals for some vehicles, some
        dropped to land or hold on their own motion); the replan object at once (status
        planning), its outcome follows as events. StateConflict unless the flight runs its
        plan (not starting, paused or aborting) or while another replan is under way;
        FieldError naming `goals.<id>` / `drop[n]` for an unknown vehicle or a bad goal."""
        flight = self._flying(flight_id, stored_status)
        self._not_aborting(flight, "replan")
        if flight.status != FlightStatus.RUNNING or flight.handle is None:
            raise StateConflict("flight_id", f"flight {flight_id!r} cannot be "
                                                f"replanned (status {flight.status})")
        return await flight.handle.replan(goals, drop, drop_action, reason)

    async def replanned(self, flight_id: str) -> list[Segment]:
        """The switched replans' plans of a flight, with their switch times: live from the
        vehicle process while it flies, from its record once it ended (none without)."""
        flight = self._flights.get(flight_id)
        if flight is not None and flight.handle is not None:
            if flight.active:
                return await flight.handle.replanned()
            if flight.handle.record is not None:
                return replanned_in(flight.handle.record)
        elif flight is not None:
            return []  # starting: nothing flown yet
        row = await asyncio.to_thread(self._store.get_flight, flight_id,
                                      with_record=True)
        if row is None or row.record_json is None:
            return []
        return await asyncio.to_thread(replanned_in, orjson.loads(row.record_json))

    @staticmethod
    def _not_aborting(flight: LiveFlight, command: str) -> None:
        """StateConflict when `flight` aborts: an abort overrides `command`."""
        if flight.abort_requested is not None:
            conflict = aborting_refusal(command, flight.abort_requested,
                                        f"flight {flight.id!r}")
            raise StateConflict("flight_id", conflict.reason)

    def _flying(self, flight_id: str, stored_status: FlightStatus | None) -> LiveFlight:
        """The flight under way with this id; StateConflict naming its status otherwise (once
        it left memory, the stored one the caller read, `stored_status`, if it did)."""
        flight = self._flights.get(flight_id)
        if flight is None or not flight.active:
            status = stored_status if flight is None else flight.status
            known = "" if status is None else f" (status {status})"
            raise StateConflict("flight_id", f"flight {flight_id!r} is not flying{known}")
        return flight

    # ------------------------------------------------------------------ one flight's run

    async def _run(self, flight: LiveFlight, plan: Plan, options: FlightOptions) -> None:
        record: dict[str, Any] | None = None
        ticker: asyncio.Task[None] | None = None
        mirror: asyncio.Task[None] | None = None
        flying = False
        process = self.vehicle_process
        # State, events and the record so far are stored about every second while flying,
        # so a crash keeps them; the record so far is mirrored from the vehicle process.
        journal = FlightJournal(self._store, flight.id, lambda: (
            flight.status, flight.events,
            None if flight.handle is None else flight.handle.record_so_far))
        journal.start()
        try:
            handle = RemoteFlight(process, flight.id)
            self._described = await process.call("fly", flight.id, plan, options, TELEMETRY_HZ)
            flying = True
            flight.handle = handle
            ticker = asyncio.create_task(self._telemetry(flight, handle))
            mirror = asyncio.create_task(self._mirror(handle))
            for action in list(flight.aborts):  # aborted while starting: each, in order
                # (one the flight's own abort overrode meanwhile is its `command_refused`)
                with contextlib.suppress(StateConflict):
                    await handle.request_abort(action, "operator abort")
            record = await handle.result()
            flight.summary = record.get("summary")
            completed = bool(flight.summary and flight.summary.get("completed"))
            flight.status = status_of(FlightPhase.FINISHED, completed)
        except FlightAborted as exc:
            flight.status, flight.error = status_of(FlightPhase.ABORTED), str(exc)
        except VehicleLoopStopped as exc:
            # The vehicle process ended: nothing streams any more (PX4's offboard-loss
            # failsafe lands the vehicles); the operator must look at them.
            log.critical("flight %s: %s; the setpoint stream has stopped, check the fleet",
                         flight.id, exc)
            _failed(flight, exc)
        except GcsError as exc:
            _failed(flight, exc)
            await _land_if_left_flying(flight, flying, type(exc).__name__)
        except asyncio.CancelledError:
            flight.status = FlightStatus.INTERRUPTED
            flight.error = "the service stopped during the flight"
            raise
        except Exception as exc:  # a bug: report it, keep the service up
            log.exception("flight %s failed", flight.id)
            _failed(flight, exc)
            await _land_if_left_flying(flight, flying, type(exc).__name__)
        finally:
            for task in (ticker, mirror):
                if task is not None:
                    task.cancel()
            # The fleet as the flight left it (the vehicle process posts it as the flight
            # ends), before the record is stored: the stream's last telemetry follows its
            # last events, so no vehicle is left shown "armed / landing" after it disarmed.
            final = flight.snapshot()
            if final is not None:
                flight.publish("telemetry", final)
            if record is None and flight.handle is not None:
                record = flight.handle.record
            if record is not None and flight.summary is None:
                flight.summary = record.get("summary")
            await journal.close()
            stored = await self._store_final(flight, record)
            flight.finished_at = datetime.now(UTC)
            if self._active is flight:
                self._active = None
            flight.done.set()
            flight.publish("done", flight.outcome())
            if stored:
                # Stored: drop it (and its handle, which holds the whole record) from memory.
                self._flights.pop(flight.id, None)
            elif self._closing:
                await store_failure(self._store, flight.id, self._unstored_reason(flight),
                                    flight.events)
            else:
                self._tasks.spawn(self._store_later(flight, record))

    async def _store_final(self, flight: LiveFlight, record: dict[str, Any] | None) -> bool:
        """One try at the flight's final write; on failure the reason is kept on the flight
        (`unstored`) and False returned."""
        try:
            await write_final(self._store, flight.id, status=flight.status,
                              events=flight.events, summary=flight.summary, record=record,
                              error=flight.error)
        except Exception as exc:
            flight.unstored = storage_reason(exc)
            log.error("could not store flight %s (kept in memory, retrying): %s",
                      flight.id, flight.unstored)
            return False
        flight.unstored = None
        return True

    async def _store_later(self, flight: LiveFlight, record: dict[str, Any] | None) -> None:
        """Retry an ended flight's final write (backing off to `STORE_RETRY_MAX_S`) until the
        store takes it, then drop the flight from memory. If the service stops first, the
        flight is at least marked failed with the reason."""
        delay = STORE_RETRY_S
        try:
            while True:
                await asyncio.sleep(delay)
                delay = min(2 * delay, STORE_RETRY_MAX_S)
                if await self._store_final(flight, record):
                    log.info("flight %s stored after a storage fault", flight.id)
                    self._flights.pop(flight.id, None)
                    return
        except asyncio.CancelledError:
            if not await self._store_final(flight, record):
                await store_failure(self._store, flight.id, self._unstored_reason(flight),
                                    flight.events)
            raise

    @staticmethod
    def _unstored_reason(flight: LiveFlight) -> str:
        return (f"the flight ({flight.status}) could not be stored before the service "
                f"stopped: {flight.unstored}")[:500]

    def _on_notice(self, kind: str, data: dict[str, Any]) -> None:
        """What the vehicle process tells, on this loop: a flight's event or snapshot, or its
        own end."""
        if kind == "ended":
            if not self._closing:
                log.critical("%s: the fleet is not watched and no flight streams", data["reason"])
                self._tasks.spawn(self._restart_vehicles())
            return
        flight = self._flights.get(data["flight"])
        if flight is None:
            return
        if kind == "event":
            self._on_event(flight, data["event"])
        elif kind == "snapshot" and flight.handle is not None:
            flight.handle.posted(data["snapshot"])
            _leave_starting(flight, data["snapshot"]["phase"])

    def _on_event(self, flight: LiveFlight, event: FlightEvent) -> None:
        """One event of the flight (handed over from the vehicle process, in order) into the
        flight's log and stream; a pause past its limit ends the pause (the executor lands
        or holds the fleet)."""
        flight.events.append(event)
        flight.publish("event", event)
        if event["kind"] == EventKind.PAUSE_LIMIT and flight.status == FlightStatus.PAUSED:
            flight.set_status(FlightStatus.ABORTING)

    @staticmethod
    async def _mirror(handle: RemoteFlight) -> None:
        """Keep the record's mirror up to date every MIRROR_PERIOD_S, in small pieces (a
        failed refresh is retried on the next)."""
        while True:
            await asyncio.sleep(MIRROR_PERIOD_S)
            try:
                await handle.refresh()
            except (GcsError, VehicleLoopStopped) as exc:
                log.debug("record mirror: %s", exc)

    async def _telemetry(self, flight: LiveFlight, handle: RemoteFlight) -> None:
        """Live snapshots on the flight's stream at TELEMETRY_HZ (the latest the vehicle
        process posted)."""
        while True:
            snapshot = handle.snapshot()
            if snapshot is not None:
                flight.publish("telemetry", snapshot)
            await asyncio.sleep(1.0 / TELEMETRY_HZ)


def _leave_starting(flight: LiveFlight, phase: str) -> None:
    """A starting flight takes the status of the phase its executor reports (`status_of`)
    once that is no longer `starting`: running from the first snapshot that says flying.
    Later statuses are the service's own steps: a pause, a resume and the end take theirs from
    `status_of` too, an abort asked for makes it `aborting`."""
    status = status_of(FlightPhase(phase))
    if flight.status == FlightStatus.STARTING and status in FLIGHT_ACTIVE \
            and status != FlightStatus.STARTING:
        flight.set_status(status)


def _failed(flight: LiveFlight, error: BaseException) -> None:
    """The run ended in `error`: the status of a failed flight, and the error named."""
    flight.status, flight.error = status_of(FlightPhase.FAILED), f"{type(error).__name__}: {error}"


async def _land_if_left_flying(flight: LiveFlight, flying: bool, why: str) -> None:
    """A flight whose run here failed before it ended there is never left going on its own:
    every vehicle lands, and its end is awaited."""
    handle = flight.handle
    if not flying or handle is None or handle.record is not None:
        return
    with contextlib.suppress(Exception):
        await handle.abort("land", f"service error: {why}")
    with contextlib.suppress(BaseException):
        await handle.result()
