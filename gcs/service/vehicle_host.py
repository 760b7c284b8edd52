"""The service's vehicle side, hosted in the vehicle process (`gcs.flight.host.vehicle_process`).

`FleetHost` owns the configured fleet (`gcs.service.fleet.Fleet`: the fleet file's vehicles
or the mocks, the monitor links, the fleet commands) and the one flight under way (a
`gcs.service.replan_handle.ReplanHandle`, a `FlightHandle` that also replans, on the
process's vehicle loop). The service calls its
public methods by name (`gcs.service.flights.FleetService`); everything it answers is plain
data. It tells the service of a flight's events and live snapshots by notices tagged with the
flight's id: ``event`` ({flight, event}) in order, and ``snapshot`` ({flight, snapshot})
`snapshot_hz` times a second.

When the service goes away without asking (its process died, or SIGTERM reached this one),
`close` lands a flight under way before the process exits: a fleet is never left streaming
from nowhere. It then writes that flight's events and record to the store itself (status
`interrupted`, as a restarted service marks it), so that the landing it flew after the
service was gone is not lost.

It imports the mock (`gcs.sim`), which the service may only where it hosts it
(`tests/test_layout.py`, `ALLOWED`): the mock vehicles run here, in the vehicle process, and it
answers their configuration (`mock_config`) and injects a demo's or a test's faults into them.
The mock imports only the bottom layer, so this import runs downward.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

from gcs.documents import ReplanDocument
from gcs.errors import StateConflict
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.host.vehicle_process import HostContext
from gcs.flight.timeline.realtime import settle_heap
from gcs.service.fleet import Fleet
from gcs.service.journal import write_final
from gcs.service.record_mirror import RecordDelta, record_delta
from gcs.service.replan_handle import ReplanHandle, Segment
from gcs.service.settings import Settings
from gcs.service.statuses import FlightStatus
from gcs.service.store import Store
from gcs.sim import MockConfig
from planner import Plan

__all__ = ["ORPHAN_ERROR", "PRELOAD", "FleetHost"]

log = logging.getLogger(__name__)

#: Modules the vehicle process's fork server imports once (each child then starts at once).
PRELOAD = ("gcs.service.vehicle_host",)
#: How long `close` waits for a flight under way to land (s).
CLOSE_LANDING_S = 60.0
#: Why a flight the service did not see to its end is `interrupted` (also what a restarted
#: service says of one it finds still flying in the store).
ORPHAN_ERROR = "the service stopped during this flight"


class FleetHost:
    """The fleet and its flight, in the vehicle process; see the module."""

    def __init__(self, context: HostContext, settings: Settings) -> None:
        self._vehicles = context.vehicles
        self._notify = context.notify
        self.fleet = Fleet(settings)
        self._settings = settings
        self._flight: ReplanHandle | None = None
        self._flight_id: str | None = None
        self._result: asyncio.Future[dict[str, Any]] | None = None
        self._ticker: asyncio.Task[None] | None = None

    # ------------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        """Load the fleet file or start the mocks, and watch the links."""
        await self.fleet.start()

    async def close(self) -> None:
        """Land a flight under way (waiting for it up to CLOSE_LANDING_S), then release the
        links and stop the mocks."""
        if self._flying():
            # kept here: the flight's end (`flight_result`, still pending) forgets them
            flight, result, flight_id = self._flight, self._result, self._flight_id
            assert flight is not None and result is not None and flight_id is not None
            log.warning("vehicle process closing during a flight: landing every vehicle")
            with contextlib.suppress(Exception):
                await flight.abort("land", "the service is stopping")
            try:
                await asyncio.wait_for(asyncio.shield(result), CLOSE_LANDING_S)
                outcome = "the flight ended"
            except TimeoutError:
                outcome = f"still flying after {CLOSE_LANDING_S:g} s"
            except Exception as exc:
                outcome = f"{type(exc).__name__}: {exc}"
            await self._store_orphan(flight_id, flight, outcome)
        await self.fleet.close()

    async def _store_orphan(self, flight_id: str, flight: ReplanHandle, outcome: str) -> None:
        """Write the flight's events and record to the store from here: the service that
        would have is gone (a restarted one reads them as stored)."""
        record = flight.record
        if record is None:
            return
        store = Store(self._settings.database_url)
        try:
            await write_final(store, flight_id, status=FlightStatus.INTERRUPTED,
                              events=list(record.get("events", [])),
                              summary=record.get("summary"), record=record,
                              error=f"{ORPHAN_ERROR}; the vehicle process landed the fleet "
                                    f"({outcome})")
            log.warning("flight %s: events and record stored by the vehicle process",
                        flight_id)
        except Exception:
            log.exception("flight %s: could not store its record", flight_id)
        finally:
            store.close()

    # ------------------------------------------------------------------ the fleet

    def describe(self) -> dict[str, Any]:
        """`Fleet.describe`: kind, ids, world origin."""
        return self.fleet.describe()

    def monitored(self) -> list[dict[str, Any]]:
        """`Fleet.monitored`: every vehicle's link state between flights."""
        return self.fleet.monitored()

    async def command(self, command: str, vehicles: list[str] | None, *, force: bool,
                      confirm: bool) -> dict[str, Any]:
        """`Fleet.command`, refused while a flight has the links."""
        if self._flying():
            raise StateConflict("fleet", "a flight is under way: use its abort instead")
        return await self.fleet.command(command, vehicles, force=force, confirm=confirm)

    def flight_options(self, plan: Plan, options: dict[str, Any]) -> FlightOptions:
        """`Fleet.flight_options`: the options a flight of `plan` would fly with."""
        return self.fleet.flight_options(plan, options)

    def mock_config(self) -> MockConfig | None:
        """The mock vehicles' configuration (None without mocks)."""
        return None if self.fleet.mock is None else self.fleet.mock.config

    def inject_mock_fault(self, index: int, fault: str, value: Any) -> None:
        """Set `fault` of mock vehicle `index` (`gcs.sim` faults: battery, link cut, ...), as
        a demo or a test injects a failure into the in-process mocks."""
        mock = self.fleet.mock
        if mock is None or not 0 <= index < len(mock.vehicles):
            raise StateConflict("fleet", f"no mock vehicle {index}")
        faults = mock.vehicles[index].faults
        if not hasattr(faults, fault) or fault.startswith("_"):
            raise StateConflict("fault", f"no mock fault {fault!r}")
        setattr(faults, fault, value)

    # ------------------------------------------------------------------ a flight

    async def fly(self, flight_id: str, plan: Plan, options: FlightOptions,
                  snapshot_hz: float) -> dict[str, Any]:
        """Take the links from the monitor (set the mocks down under the plan's starts) and
        start flying `plan`; the fleet's description as it now is. The executor's checks
        raise here (PlanRejected), and the monitor is reopened then."""
        if self._flying():
            raise StateConflict("fleet", f"flight {self._flight_id} is flying")
        await self.fleet.close_monitor()
        try:
            if self.fleet.kind == "mock":
                await self.fleet.rehome_mock(plan)
            spec = self.fleet.configured()
            flight = await ReplanHandle.create(
                self._vehicles, plan, spec, options, snapshot_hz=snapshot_hz,
                on_event=lambda event: self._notify(
                    "event", {"flight": flight_id, "event": event}))
        except BaseException:
            await self.fleet.open_monitor()
            raise
        self._flight, self._flight_id = flight, flight_id
        settle_heap()  # before the stream starts, not in the middle of it
        self._result = flight.start()
        self._ticker = asyncio.ensure_future(self._post_snapshots(flight, flight_id,
                                                                  1.0 / snapshot_hz))
        return self.fleet.describe()

    async def flight_result(self) -> tuple[dict[str, Any] | None, BaseException | None]:
        """Once the flight ended: (its record, None), or (the record so far, the error it
        ended on: FlightAborted, VehicleTimeout, ...). The monitor is open again after."""
        flight, result = self._flight, self._result
        if flight is None or result is None:
            raise StateConflict("fleet", "no flight")
        try:
            return await asyncio.shield(result), None
        except asyncio.CancelledError:
            raise
        except Exception as exc:
            return flight.record, exc
        finally:
            if result.done():
                await self._ended(flight)

    async def _ended(self, flight: ReplanHandle) -> None:
        if self._flight is not flight:
            return
        if self._ticker is not None:
            self._ticker.cancel()
        self._notify("snapshot", {"flight": self._flight_id, "snapshot": flight.snapshot()})
        self._flight, self._result, self._ticker = None, None, None
        settle_heap()  # between flights: what earlier flights left in cycles is freed
        await self.fleet.open_monitor()

    def _flying(self) -> bool:
        return self._result is not None and not self._result.done()

    async def _post_snapshots(self, flight: ReplanHandle, flight_id: str,
                              period: float) -> None:
        while True:
            self._notify("snapshot", {"flight": flight_id, "snapshot": flight.snapshot()})
            await asyncio.sleep(period)

    def _current(self, flight_id: str) -> ReplanHandle:
        if self._flight is None or self._flight_id != flight_id:
            raise StateConflict("flight_id", f"flight {flight_id!r} is not flying here")
        return self._flight

    async def pause(self, flight_id: str) -> float:
        """`FlightHandle.pause` of the flight under way; its snapshot is posted before the
        answer, so the service shows the pause once the call returns."""
        flight = self._current(flight_id)
        held = await flight.pause()
        self._notify("snapshot", {"flight": flight_id, "snapshot": flight.snapshot()})
        return held

    async def resume(self, flight_id: str) -> float:
        """`FlightHandle.resume` of the flight under way; its snapshot is posted before the
        answer."""
        flight = self._current(flight_id)
        restarted = await flight.resume()
        self._notify("snapshot", {"flight": flight_id, "snapshot": flight.snapshot()})
        return restarted

    async def replan(self, flight_id: str, goals: dict[str, list[float]] | None,
                     drop: list[str], drop_action: str, reason: str) -> ReplanDocument:
        """`ReplanHandle.replan` of the flight under way: the replan object (status
        planning) at once; StateConflict / FieldError cross as raised. Its snapshot is
        posted before the answer, so the service shows the replan once the call returns."""
        flight = self._current(flight_id)
        replan = await flight.replan(goals, drop, drop_action, reason)
        self._notify("snapshot", {"flight": flight_id, "snapshot": flight.snapshot()})
        return replan

    async def replanned(self, flight_id: str) -> list[Segment]:
        """The switched replans' plans of the flight under way (`ReplanHandle.replanned`)."""
        return await self._current(flight_id).replanned()

    async def request_abort(self, flight_id: str, action: str, reason: str) -> None:
        """`FlightHandle.request_abort` of the flight under way: accepted, or refused
        (StateConflict across) by the commands' precedence."""
        await self._current(flight_id).request_abort(action, reason)

    async def abort(self, flight_id: str, action: str, reason: str) -> None:
        """`FlightHandle.abort` of the flight under way."""
        await self._current(flight_id).abort(action, reason)

    async def record_delta(self, flight_id: str, cursor: dict[str, Any]) -> RecordDelta:
        """What the flight's record holds beyond `cursor` (`gcs.service.record_mirror`)."""
        return await self._current(flight_id).with_recorder(
            lambda recorder: record_delta(recorder, cursor))
