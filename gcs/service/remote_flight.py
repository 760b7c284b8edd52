"""The service's side of one flight flown in the vehicle process: pause, resume, replan,
abort, its latest snapshot, the record so far and, once it ended, its record.

The flight itself (`gcs.flight.host.flight_handle.FlightHandle`) runs in the vehicle process and
is reached through `gcs.service.vehicle_host.FleetHost`'s methods; its snapshots arrive as
notices (`posted`), and its record so far is mirrored in pieces (`gcs.service.record_mirror`).
"""

from __future__ import annotations

import asyncio
from typing import Any

from gcs.documents import FlightSnapshot, ReplanDocument
from gcs.flight.host.vehicle_process import VehicleProcess
from gcs.phases import DropAction
from gcs.service.record_mirror import RecordMirror
from gcs.service.replan_handle import Segment

__all__ = ["RemoteFlight"]


class RemoteFlight:
    """One flight in the vehicle process, driven from the service's loop."""

    def __init__(self, process: VehicleProcess, flight_id: str) -> None:
        self._process = process
        self._flight_id = flight_id
        self._snapshot: FlightSnapshot | None = None
        self._mirror = RecordMirror()
        self._mirroring = asyncio.Lock()  # one delta at a time: each is taken at the cursor
        self.record: dict[str, Any] | None = None
        """The flight record once the flight ended (also after an error or abort)."""
        self.scheduling = process.scheduling
        """The vehicle thread's scheduling (`VehicleLoop.scheduling`)."""

    def posted(self, snapshot: FlightSnapshot) -> None:
        """A snapshot the vehicle process posted."""
        self._snapshot = snapshot

    def snapshot(self) -> FlightSnapshot | None:
        """The latest live state the vehicle process posted (`FlightExecutor.snapshot`)."""
        return self._snapshot

    async def pause(self) -> float:
        """Stop the flight clock; the flight time it holds."""
        return float(await self._process.call("pause", self._flight_id))

    async def resume(self) -> float:
        """Restart the flight clock; the flight time it restarts at."""
        return float(await self._process.call("resume", self._flight_id))

    async def replan(self, goals: dict[str, list[float]] | None, drop: list[str],
                     drop_action: DropAction, reason: str) -> ReplanDocument:
        """Start an in-flight replan (`FlightExecutor.replan`); the replan object at once
        (status planning). StateConflict / FieldError as the flight raised them."""
        replan: ReplanDocument = await self._process.call(
            "replan", self._flight_id, goals, drop, drop_action, reason)
        return replan

    async def replanned(self) -> list[Segment]:
        """The switched replans' plans and switch times, in order."""
        segments: list[Segment] = await self._process.call("replanned", self._flight_id)
        return segments

    async def request_abort(self, action: str, reason: str) -> None:
        """Accept an abort by the commands' precedence (`gcs.flight.run.precedence`), or refuse
        it (StateConflict); returns before the vehicles are secured."""
        await self._process.call("request_abort", self._flight_id, action, reason)

    async def abort(self, action: str = "land", reason: str = "operator abort") -> None:
        """Every vehicle to `action` now; returns once the commands were answered."""
        await self._process.call("abort", self._flight_id, action, reason)

    async def result(self) -> dict[str, Any]:
        """The flight record once the flight ended; the error it ended on is raised here
        (after `record` holds what was recorded)."""
        record, error = await self._process.call("flight_result")
        self.record = record
        if error is not None:
            raise error
        return dict(record)

    async def refresh(self) -> None:
        """Bring the record's mirror up to date (only what is new crosses over); called about
        once a second, so each piece stays small."""
        async with self._mirroring:
            self._mirror.apply(await self._process.call("record_delta", self._flight_id,
                                                        self._mirror.cursor()))

    async def record_so_far(self) -> dict[str, Any]:
        """The flight record so far, ``"partial": true``."""
        await self.refresh()
        return self._mirror.snapshot()
