"""Shared dependencies of the routes, as `Annotated` aliases (one place to change them).

The services live on `app.state` (created by the app's lifespan in `gcs.api.app`); these
aliases hand them to the routes. `MissionDep` and `FlightDep` turn a `{mission_id}` /
`{flight_id}` path parameter into the stored row or a 404 (one row-or-404 rule, `_found`)
before a route (or a stream) starts.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Annotated, Any, TypeVar

import orjson
from fastapi import Depends, Header, Path, Request
from starlette.concurrency import run_in_threadpool

from gcs.api.errors import BadRequest, Unprocessable
from gcs.api.fanout import SharedJson
from gcs.errors import NotFound
from gcs.service.flights import FleetService
from gcs.service.planning import PlanningService
from gcs.service.plans import PlanCache
from gcs.service.settings import Settings
from gcs.service.store import FlightRow, MissionRow, Store

__all__ = [
    "EventStreamSlot",
    "ExportSlot",
    "FleetDep",
    "FlightDep",
    "FlightIdPath",
    "JsonBody",
    "LastEventId",
    "MissionDep",
    "MissionIdPath",
    "PlanCacheDep",
    "PlanningDep",
    "SettingsDep",
    "SharedJsonDep",
    "StoreDep",
]


def _settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def _store(request: Request) -> Store:
    store: Store = request.app.state.store
    return store


def _planning(request: Request) -> PlanningService:
    planning: PlanningService = request.app.state.planning
    return planning


def _plans(request: Request) -> PlanCache:
    plans: PlanCache = request.app.state.plans
    return plans


def _fleet(request: Request) -> FleetService:
    fleet: FleetService = request.app.state.fleet
    return fleet


def _export_slot(request: Request) -> Iterator[None]:
    """One of the `max_concurrent_exports` slots while the export is computed and sent."""
    with request.app.state.exports.hold():
        yield


def _event_stream_slot(request: Request) -> Iterator[None]:
    """One of the event-stream slots (in total, and on this path's resource) while the
    stream is open."""
    with request.app.state.streams.hold(request.url.path):
        yield


def _shared_json(request: Request) -> SharedJson:
    shared: SharedJson = request.app.state.shared_json
    return shared


SettingsDep = Annotated[Settings, Depends(_settings)]
ExportSlot = Annotated[None, Depends(_export_slot)]
EventStreamSlot = Annotated[None, Depends(_event_stream_slot)]
SharedJsonDep = Annotated[SharedJson, Depends(_shared_json)]
StoreDep = Annotated[Store, Depends(_store)]
PlanningDep = Annotated[PlanningService, Depends(_planning)]
PlanCacheDep = Annotated[PlanCache, Depends(_plans)]
FleetDep = Annotated[FleetService, Depends(_fleet)]

MissionIdPath = Annotated[
    str, Path(description="Mission id, as returned by POST /api/missions.", max_length=64)
]


Row = TypeVar("Row")


async def _found(load: Callable[[str], Row | None], key: str, field: str, noun: str) -> Row:
    """The stored row `load(key)` (read in a thread), or NotFound naming the path parameter."""
    row = await run_in_threadpool(load, key)
    if row is None:
        raise NotFound(field, f"no {noun} with id {key!r}")
    return row


async def _mission(mission_id: MissionIdPath, store: StoreDep) -> MissionRow:
    return await _found(store.get_mission, mission_id, "mission_id", "mission")


FlightIdPath = Annotated[str, Path(description="Flight id.", max_length=64)]


async def _flight(flight_id: FlightIdPath, store: StoreDep) -> FlightRow:
    return await _found(store.get_flight, flight_id, "flight_id", "flight")


MissionDep = Annotated[MissionRow, Depends(_mission)]
FlightDep = Annotated[FlightRow, Depends(_flight)]


#: Bodies larger than this are parsed on a worker thread, not the event loop (a 128-vehicle
#: plan to fly is about 6 MB: tens of milliseconds of parsing).
PARSE_OFF_LOOP_BYTES = 1_000_000


async def _json_body(request: Request) -> Any:
    """The request body parsed as strict JSON (NaN and Infinity are not JSON). The security
    middleware has already refused bodies not declared as JSON (415) and bodies over the
    size limit (413)."""
    raw = await request.body()
    if not raw.strip():
        raise Unprocessable("body", "is required")
    try:
        if len(raw) > PARSE_OFF_LOOP_BYTES:  # a plan to fly: megabytes, parsed aside
            return await run_in_threadpool(orjson.loads, raw)
        return orjson.loads(raw)
    except orjson.JSONDecodeError as exc:
        raise BadRequest("body", f"request body is not valid JSON: {exc}") from None


#: A route's JSON body, for routes that validate it themselves (the scenario).
JsonBody = Annotated[Any, Depends(_json_body)]


def _last_event_id(
    last_event_id: Annotated[str | None, Header(
        alias="Last-Event-ID", description="Resume an event stream after this event id (an "
        "EventSource sends it by itself when it reconnects).")] = None,
) -> int | None:
    """The sequence number a reconnecting event-stream client last received; anything that
    is not one (absent, garbage) means from the start."""
    if last_event_id is None or not last_event_id.strip().isdigit():
        return None
    return int(last_event_id.strip())


#: The `Last-Event-ID` of a reconnecting event-stream client, as a number (None: all).
LastEventId = Annotated[int | None, Depends(_last_event_id)]
