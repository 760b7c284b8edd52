"""The narrow interface to one flight running on a `VehicleLoop`: start, pause, resume,
replan, abort, the latest snapshot, its events, and the record.

`FlightHandle` is used from another thread's loop (the REST service's, the CLI's main loop);
the `FlightExecutor` it drives lives and runs on the vehicle loop only, and nothing here reads
its state from the caller's thread: the vehicle loop posts a snapshot `snapshot_hz` times a
second, hands each event to the caller's loop (`on_event`, in order), and the record is read
once the flight ended. Each message has one definition: the snapshot is
`FlightExecutor.snapshot`, an event is `gcs.flight.run.events`', the record is `run`'s.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

from gcs.documents import FlightEvent, FlightSnapshot, ReplanDocument
from gcs.fleet.fleetfile import FleetSpec, FlightOptions
from gcs.flight.host.vehicle_loop import VehicleLoop
from gcs.flight.run.executor import FlightExecutor
from gcs.flight.run.record import FlightRecorder
from planner import Plan

__all__ = ["FlightHandle"]

T = TypeVar("T")

#: Snapshots posted per second by default.
SNAPSHOT_HZ = 5.0


class FlightHandle:
    """One flight on a vehicle loop, driven from the caller's loop; see the module."""

    def __init__(self, vehicles: VehicleLoop, executor: FlightExecutor,
                 on_event: Callable[[FlightEvent], None] | None = None,
                 snapshot_hz: float = SNAPSHOT_HZ) -> None:
        """Use `create`: the executor must have been made on the vehicle loop."""
        self._vehicles = vehicles
        self._executor = executor
        self._on_event = on_event
        self._period = 1.0 / snapshot_hz
        self._caller: asyncio.AbstractEventLoop | None = None
        self._snapshot: FlightSnapshot = executor.snapshot()
        self._task: asyncio.Future[dict[str, Any]] | None = None
        self.record: dict[str, Any] | None = None
        """The flight record once the flight ended (also after an error or abort)."""
        self.scheduling = vehicles.scheduling
        """The vehicle thread's scheduling (`VehicleLoop.scheduling`)."""

    @classmethod
    async def create(cls, vehicles: VehicleLoop, plan: Plan, fleet: FleetSpec,
                     options: FlightOptions | None = None, *,
                     on_event: Callable[[FlightEvent], None] | None = None,
                     snapshot_hz: float = SNAPSHOT_HZ) -> FlightHandle:
        """The executor made on the vehicle loop (its checks raise here: PlanRejected)."""
        executor = await vehicles.run(lambda: FlightExecutor(plan, fleet, options))
        return cls(vehicles, executor, on_event, snapshot_hz)

    # ------------------------------------------------------------------ the flight

    def start(self) -> asyncio.Future[dict[str, Any]]:
        """Start flying (once); a future on the caller's loop of the flight record, raising
        the executor's `GcsError` (after the vehicles were made safe) otherwise. Cancelling
        it cancels the flight, which still makes the vehicles safe."""
        if self._task is None:
            self._caller = asyncio.get_running_loop()
            self._task = asyncio.wrap_future(self._vehicles.submit(self._fly))
        return self._task

    async def _fly(self) -> dict[str, Any]:
        """On the vehicle loop: the run, its event relay and its snapshot posts."""
        executor = self._executor
        relay = asyncio.ensure_future(self._relay())
        ticker = asyncio.ensure_future(self._post_snapshots())
        try:
            return await executor.run()
        finally:
            self.record = executor.record
            ticker.cancel()
            self._snapshot = executor.snapshot()
            # the run closed the event stream: the relay ends once it handed on the rest
            with contextlib.suppress(BaseException):
                await asyncio.wait_for(asyncio.shield(relay), 5.0)
            relay.cancel()

    async def _relay(self) -> None:
        caller = self._caller
        async for event in self._executor.events():
            if self._on_event is not None and caller is not None:
                with contextlib.suppress(RuntimeError):  # the caller's loop has closed
                    caller.call_soon_threadsafe(self._on_event, event)

    async def _post_snapshots(self) -> None:
        while True:
            self._snapshot = self._executor.snapshot()
            await asyncio.sleep(self._period)

    def snapshot(self) -> FlightSnapshot:
        """The latest live state the vehicle loop posted (`FlightExecutor.snapshot`)."""
        return self._snapshot

    async def pause(self) -> float:
        """Stop the flight clock; the flight time it holds (StateConflict across). The
        snapshot shows the pause once this returns."""
        return await self._vehicles.run(lambda: self._posting(self._executor.pause))

    async def resume(self) -> float:
        """Restart the flight clock; the flight time it restarts at (StateConflict across).
        The snapshot shows it running once this returns."""
        return await self._vehicles.run(lambda: self._posting(self._executor.resume))

    async def replan(self, goals: Mapping[str, Sequence[float]] | None = None,
                     drop: Sequence[str] = (), drop_action: str = "land",
                     reason: str | None = "operator") -> ReplanDocument:
        """`FlightExecutor.replan` on the vehicle loop: the replan object (status planning;
        StateConflict and FieldErrors across). The snapshot shows it once this returns."""
        async def replan() -> ReplanDocument:
            try:
                return await self._executor.replan(goals, drop, drop_action, reason)
            finally:
                self._snapshot = self._executor.snapshot()

        return await self._vehicles.call(replan)

    def _posting(self, change: Callable[[], T]) -> T:
        """On the vehicle loop: `change()`, then post the snapshot it leaves."""
        try:
            return change()
        finally:
            self._snapshot = self._executor.snapshot()

    async def request_abort(self, action: str, reason: str) -> None:
        """`FlightExecutor.request_abort` on the vehicle loop: accepted (the vehicles are
        secured in the background) or refused by precedence (StateConflict across)."""
        await self._vehicles.run(lambda: self._posting(
            lambda: self._executor.request_abort(action, reason)))

    async def abort(self, action: str = "land", reason: str = "operator abort") -> None:
        """Every vehicle to `action` (land or hold) now; returns once the commands were
        answered (or timed out); the record future then raises `FlightAborted`."""
        await self._vehicles.call(lambda: self._executor.abort(action, reason))

    async def with_recorder(self, fn: Callable[[FlightRecorder], T]) -> T:
        """`fn(recorder)` run on the vehicle loop, so the lists it reads are not being
        appended to meanwhile (a partial record for the journal)."""
        return await self._vehicles.run(lambda: fn(self._executor.recorder))
