"""Flights: POST /api/missions/{id}/flights flies a mission on the configured fleet;
/api/flights/{id} is its status and summary, /events its live telemetry and events
(server-sent events), /abort lands (or holds) every vehicle at once, /pause and /resume stop
and restart its flight clock, /replan changes goals or drops vehicles in flight, /trajectory
the plans it flies (the first, then each switched replan's), /record the flight record.

Long: the routes of one resource (flights), each short, sharing its helpers.

`/api/executions` and `/api/missions/{id}/executions` are the same routes under their former
name, kept working and marked deprecated in the OpenAPI document (`gcs.api.routes`).
"""

from __future__ import annotations

from collections.abc import AsyncIterable
from typing import Annotated, Any, Literal

import orjson
from fastapi import APIRouter, Body, Query, Response
from fastapi.sse import EventSourceResponse, ServerSentEvent
from pydantic import BaseModel, ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from gcs.api.deps import (
    EventStreamSlot,
    FleetDep,
    FlightDep,
    LastEventId,
    MissionDep,
    PlanCacheDep,
    SettingsDep,
    SharedJsonDep,
    StoreDep,
)
from gcs.api.errors import error_responses
from gcs.documents import FlightEvent, FlightSnapshot, ReplanDocument
from gcs.errors import InvalidRequest, StateConflict
from gcs.fleet.fleetfile import (
    MAX_RATE_HZ,
    MAX_REPLAN_LEAD_S,
    MIN_RATE_HZ,
    AtEnd,
    FailsafeChoice,
    GeofenceChoice,
    MarginCheck,
    MessageRates,
    Policy,
    Preflight,
    StreamPriority,
)
from gcs.phases import AbortAction, EventKind
from gcs.replan_request import ReplanRequest, checked
from gcs.service.events import Event
from gcs.service.flights import LiveFlight, flight_document
from gcs.service.flown_trajectory import flown_trajectory
from gcs.service.replan_handle import Segment
from gcs.service.statuses import FLIGHT_ACTIVE, FLIGHT_FINISHED, FlightStatus
from gcs.service.store import FlightRow

__all__ = ["executions_router", "flights_router", "mission_router", "router"]

#: One flight's routes (`/{flight_id}/...`), mounted under /flights and /executions.
router = APIRouter(tags=["flights"])
#: The list of flights, /flights ...
flights_router = APIRouter(prefix="/flights", tags=["flights"])
#: ... and its deprecated alias, /executions, with the page's former key.
executions_router = APIRouter(prefix="/executions", tags=["flights"], deprecated=True)
mission_router = APIRouter(prefix="/missions", tags=["flights"])


class FlyRequest(BaseModel):
    """How to fly (every field optional; the fleet file's `flight` options otherwise)."""

    model_config = ConfigDict(
        extra="forbid", strict=True,
        json_schema_extra={"examples": [{"policy": "land_all", "at_end": "land"}]},
    )

    policy: Policy | None = Field(
        None, description="What to do when a vehicle is flagged (lost heartbeat, left "
        "OFFBOARD, tracking error): hold or land everyone, land the faulty one, or replan: "
        "the faulty one lands on its own and the others are replanned around it to their "
        "goals."
    )
    replan_lead_s: float | None = Field(
        None, gt=0, le=MAX_REPLAN_LEAD_S,
        description="An in-flight replan switches at least this far ahead of its request "
        "(s, default 1); a new plan not verified by then is not flown.")
    at_end: AtEnd | None = Field(
        None, description="After the plan and the hold at the goals: land, or PX4 Hold."
    )
    rate_hz: float | None = Field(
        None, gt=MIN_RATE_HZ, le=MAX_RATE_HZ,
        description=f"Setpoint rate (Hz): above {MIN_RATE_HZ:g} (PX4 leaves OFFBOARD at a "
        f"slower stream), at most {MAX_RATE_HZ:g}.")
    hold_at_goal: float | None = Field(None, ge=0, le=600, description="Seconds at the goals.")
    goal_settle_max: float | None = Field(
        None, ge=0, le=60,
        description="After the hold, seconds more to wait for a vehicle still arriving.")
    climb_speed: float | None = Field(
        None, gt=0, le=5, description="Peak speed of the climb from home to the start (m/s)."
    )
    prestream: float | None = Field(
        None, ge=0, le=10, description="Seconds of hold setpoints streamed before OFFBOARD "
        "is asked for (PX4 refuses OFFBOARD without a live stream)."
    )
    tracking_error_max: float | None = Field(
        None, gt=0, le=100, description="Flag a vehicle this far from its plan (m)."
    )
    preflight: Preflight | None = Field(
        None, description="The pre-flight gate (battery, unhealthy sensors, link loss): "
        "check (default: 409 naming the vehicle and the reason) or override (fly anyway; "
        "recorded as a preflight_override event)."
    )
    message_rates: MessageRates | None = Field(
        None, description="request: ask each vehicle for the telemetry the GCS reads at the "
        "rates it needs and turn PX4's fast streams off (MAV_CMD_SET_MESSAGE_INTERVAL)."
    )
    stream_priority: StreamPriority | None = Field(
        None, description="realtime (the default): stream setpoints at SCHED_RR priority "
        "where the vehicle process may (root or CAP_SYS_NICE; recorded as an event either "
        "way), which keeps a large fleet's stream on time on a busy computer; normal: never "
        "ask."
    )
    geofence: GeofenceChoice | None = Field(
        None, description="upload: give every vehicle the plan's geofence before arming and "
        "read it back (the flight fails naming a vehicle that refuses it, or when no "
        "geodetic origin places it); skip: no fence. Default: upload when an origin is known."
    )
    failsafe: FailsafeChoice | None = Field(
        None, description="set (default): before arming, read and set every vehicle's "
        "link-loss failsafe (Land by altitude layer, Hold where the plan stacks columns "
        "closer than R) and fail the flight naming the vehicle and the parameter when one "
        "cannot be; try: fly a vehicle that does not answer on its own parameters."
    )
    margin_check: MarginCheck | None = Field(
        None, description="A plan whose separation margin is below 2 x the fleet's "
        "position_error: refuse (default, 409) or fly it with a warning in the record."
    )


class AbortRequest(BaseModel):
    """What every vehicle of the flight does now."""

    model_config = ConfigDict(extra="forbid", strict=True,
                              json_schema_extra={"examples": [{"action": "land"}]})

    action: AbortAction = Field(
        "land", description="land: every vehicle lands now; hold: every vehicle holds where "
        "it is (PX4 Hold, ArduCopter BRAKE)."
    )


class ReplanOut(BaseModel):
    """The replan started (202): its outcome follows on the flight's event stream as
    `replan_started`, then `replan_switched` or `replan_missed`."""

    model_config = ConfigDict(json_schema_extra={"examples": [{"replan": {
        "id": 1, "status": "planning", "requested_at": 3.2, "switch_time": 4.2,
        "switch_tick": 84, "lead_s": 1.0, "planning_s": None, "goals": {"uav2": [4.0, 1.5, 2.0]},
        "drop": ["uav3"], "drop_action": "land", "reason": "operator",
        "vehicles": ["uav1", "uav2"], "fixed": ["uav3"], "faulty": [], "why": None,
        "horizon": None}}]})

    replan: ReplanDocument = Field(description="The replan, as the flight's live state "
                                   "carries it (times are flight time, s).")


_FLIGHT_EXAMPLE: dict[str, Any] = {
    "id": "a41c03e9b2f1", "mission_id": "3f2a9c81d0b4", "status": FlightStatus.COMPLETED,
    "created_at": "2026-11-23T08:40:00+00:00", "finished_at": "2026-11-23T08:41:02+00:00",
    "fleet": "mock: uav1, uav2, uav3, uav4",
    "summary": {"completed": True, "goal_error_max": 0.04, "tracking_error_max": 0.12,
                "min_separation_measured": 0.97, "setpoint_rate_hz": 20.0,
                "jitter_p99_ms": 1.3},
    "error": None, "has_record": True, "event_count": 1,
    "links": {"self": "/api/flights/a41c03e9b2f1"},
}


class FlightSummary(BaseModel):
    """One flight as listed: status and summary; its events are in the flight itself
    (`links.self`) and its event stream (`links.events`)."""

    model_config = ConfigDict(json_schema_extra={"examples": [_FLIGHT_EXAMPLE]})

    id: str
    mission_id: str
    status: FlightStatus = Field(
        description=f"{', '.join(FLIGHT_ACTIVE)} while flying; then one of "
        f"{', '.join(FLIGHT_FINISHED)} ({FlightStatus.INCOMPLETE}: ran to its end "
        "without completing)."
    )
    created_at: str
    finished_at: str | None
    fleet: str
    summary: dict[str, Any] | None = Field(
        description="completed, goal_error_max, tracking_error_max, min_separation_measured, "
        "setpoint_rate_hz, jitter_p99_ms (the flight record's summary)."
    )
    error: str | None
    has_record: bool
    event_count: int = Field(description="How many events the flight has recorded so far.")
    storage: str | None = Field(
        None, description="Why the ended flight's final state is not stored yet (\"disk "
        "full: ...\"): the service holds it in memory, serves it from there and retries; "
        "null once stored.")
    links: dict[str, str]


class FlightOut(FlightSummary):
    """One flight: stored status, events and summary; live state while it flies."""

    model_config = ConfigDict(json_schema_extra={"examples": [{
        **_FLIGHT_EXAMPLE, "live": None,
        "events": [{"t": 0.8, "vehicle": "uav1", "kind": EventKind.CONNECTED,
                    "detail": "mode HOLD"}],
    }]})

    events: list[FlightEvent] = Field(description="{t, vehicle, kind, detail} each.")
    live: FlightSnapshot | None = Field(
        description="While flying: phase, flight_time, per vehicle position (world frame), "
        "mode, armed, heartbeat age, tracking error; live minimum separation."
    )


class _Page(BaseModel):
    total: int
    limit: int
    offset: int


class FlightList(_Page):
    """A page of flights, newest first, without their events."""

    model_config = ConfigDict(json_schema_extra={"examples": [
        {"total": 1, "limit": 50, "offset": 0, "flights": [_FLIGHT_EXAMPLE]}]})

    flights: list[FlightSummary]


class ExecutionList(_Page):
    """The deprecated `GET /api/executions`: the same page, its flights under `executions`."""

    executions: list[FlightSummary]


def _document(row: FlightRow, flight: LiveFlight | None) -> dict[str, Any]:
    """The `FlightOut` document (the service's, with its event count: the stored count of a
    row listed without its events, unless the flight is live)."""
    document = flight_document(row, flight)
    live_events = flight is not None and (flight.active or flight.unstored is not None)
    document["event_count"] = (row.event_count if row.event_count is not None and not live_events
                               else len(document.get("events") or ()))
    return document


def _summary(document: dict[str, Any]) -> dict[str, Any]:
    """A `FlightOut` document as listed: without its events and live state."""
    return {k: v for k, v in document.items() if k not in ("events", "live")}


@mission_router.post(
    "/{mission_id}/executions", status_code=201, response_model=FlightOut, deprecated=True,
    summary="Fly a mission (deprecated: POST /api/missions/{mission_id}/flights)",
    responses=error_responses(400, 404, 409, 413, 422),
)
@mission_router.post(
    "/{mission_id}/flights",
    status_code=201,
    response_model=FlightOut,
    summary="Fly a mission on the configured fleet",
    responses=error_responses(400, 404, 409, 413, 422),
)
async def fly_mission(
    mission: MissionDep,
    store: StoreDep,
    plans: PlanCacheDep,
    fleet: FleetDep,
    request: Annotated[FlyRequest | None, Body()] = None,
) -> dict[str, Any]:
    """Arm and fly the mission's plan on the fleet (mock vehicles, SITL or real): this is the
    only request that moves a vehicle. 201 with the flight (status `starting`); follow it
    at `links.events`. 409 if the plan is not verified, cannot be flown from the ground
    (`gcs.flight.run.ground`: a show's own takeoff and landing waves are flown), the fleet
    lacks a plan vehicle, or another flight is under way."""
    plan = await run_in_threadpool(plans.get, mission.id)
    options = {} if request is None else request.model_dump(exclude_none=True)
    row = await fleet.fly(mission.id, plan, options)
    return _document(row, fleet.flight(row.id))


@mission_router.get(
    "/{mission_id}/executions", response_model=list[FlightOut], deprecated=True,
    summary="A mission's flights (deprecated: GET /api/missions/{mission_id}/flights)",
    responses=error_responses(404),
)
@mission_router.get(
    "/{mission_id}/flights",
    response_model=list[FlightOut],
    summary="A mission's flights",
    responses=error_responses(404),
)
def mission_flights(mission: MissionDep, store: StoreDep, fleet: FleetDep) -> list[dict[str, Any]]:
    return [_document(r, fleet.flight(r.id)) for r in store.list_flights(mission.id)]


ActiveOnly = Annotated[bool, Query(description="Only the flight under way, if any.")]
PageLimit = Annotated[int, Query(ge=1, le=500)]
PageOffset = Annotated[int, Query(ge=0, le=1_000_000_000)]


MissionFilter = Annotated[str | None, Query(
    max_length=64, description="Only this mission's flights (the page lists them so).")]


def _page(store: StoreDep, fleet: FleetDep, active: bool, limit: int,
          offset: int, mission_id: str | None = None) -> dict[str, Any]:
    """One page of flights newest first, without their events: total, limit, offset, and
    the documents under ``flights``."""
    if active:
        flight = fleet.active
        row = None if flight is None else store.get_flight(flight.id)
        rows = [] if row is None or mission_id not in (None, row.mission_id) else [row]
        total, rows = len(rows), rows[offset:offset + limit]
    else:
        rows, total = store.page_flights(limit=limit, offset=offset, mission_id=mission_id)
    flights = [_summary(_document(r, fleet.flight(r.id))) for r in rows]
    return {"total": total, "limit": limit, "offset": offset, "flights": flights}


@flights_router.get("", response_model=FlightList, summary="List flights")
def list_flights(store: StoreDep, fleet: FleetDep, active: ActiveOnly = False,
                 limit: PageLimit = 50, offset: PageOffset = 0,
                 mission_id: MissionFilter = None) -> dict[str, Any]:
    """Flights newest first, a page at a time (like missions), without their events (each
    flight's own document has them), optionally of one mission."""
    return _page(store, fleet, active, limit, offset, mission_id)


@executions_router.get("", response_model=ExecutionList,
                       summary="List flights (deprecated: GET /api/flights)")
def list_executions(store: StoreDep, fleet: FleetDep, active: ActiveOnly = False,
                    limit: PageLimit = 50, offset: PageOffset = 0) -> dict[str, Any]:
    """`GET /api/flights`'s page, its flights under `executions`."""
    page = _page(store, fleet, active, limit, offset)
    page["executions"] = page.pop("flights")
    return page


@router.get(
    "/{flight_id}",
    response_model=FlightOut,
    summary="A flight's status and summary",
    responses=error_responses(404),
)
def get_flight(row: FlightDep, store: StoreDep, fleet: FleetDep) -> dict[str, Any]:
    return _document(store.get_flight(row.id) or row, fleet.flight(row.id))


@router.get(
    "/{flight_id}/events",
    response_class=EventSourceResponse,
    summary="Live telemetry and events (server-sent events)",
    responses=error_responses(404, 503, json_content=True),
)
async def flight_events(
    row: FlightDep, store: StoreDep, fleet: FleetDep, after: LastEventId,
    _slot: EventStreamSlot, shared: SharedJsonDep,
) -> AsyncIterable[ServerSentEvent]:
    """`status` {status}, `event` {t, vehicle, kind, detail}, `telemetry` (5 per second:
    phase, flight_time, vehicles with world-frame position, mode, armed, heartbeat_age),
    then `done` {status, summary, error}; then the stream ends. Each `event` has an `id:`
    (its index in the flight's events); a client reconnecting with `Last-Event-ID: n` gets
    the current status and telemetry and only the events after n. Streams are bounded in
    total and per flight (settings `max_event_streams`, `max_event_streams_per_resource`):
    past either bound the answer is 503 with Retry-After."""
    flight = fleet.flight(row.id)
    if flight is None:
        # Finished: the store has it (read again: it may have ended a moment ago).
        stored = await run_in_threadpool(store.get_flight, row.id)
        row = stored or row
        stream: AsyncIterable[Event] = _stored_stream(row)
    else:
        stream = flight.stream()
    sequence = 0
    async for kind, data in stream:
        if kind == "event":
            number, sequence = sequence, sequence + 1
            if after is None or number > after:
                yield ServerSentEvent(event=kind, raw_data=shared.text(data), id=str(number))
        else:
            yield ServerSentEvent(event=kind, raw_data=shared.text(data))


async def _stored_stream(row: FlightRow) -> AsyncIterable[Event]:
    """A finished flight's stream, from the store."""
    yield "status", {"status": row.status}
    for event in row.events:
        yield "event", event
    yield "done", {"status": row.status, "summary": row.summary,
                   "error": row.error}


@router.post(
    "/{flight_id}/abort",
    status_code=202,
    response_model=FlightOut,
    summary="Abort a flight: every vehicle lands (or holds) now",
    responses=error_responses(400, 404, 409, 413, 422),
)
async def abort_flight(
    row: FlightDep,
    store: StoreDep,
    fleet: FleetDep,
    request: Annotated[AbortRequest | None, Body()] = None,
) -> dict[str, Any]:
    """Accepted once the flight took it (202, status `aborting`); the flight ends `aborted`
    once the vehicles are safe. 409 if it is not flying, or for a hold while the flight lands
    (land overrides hold; a land while it holds is applied after the hold)."""
    action = "land" if request is None else request.action
    flight = await fleet.abort(row.id, action, stored_status=row.status)
    return _document(row, flight)


def _clock_route(pause: bool, summary: str, description: str) -> None:
    """POST /{flight_id}/pause or /resume: the flight's clock stopped or restarted
    (`FleetService.pause` / `resume`), its document in the answer."""
    command = "pause" if pause else "resume"

    async def set_clock(row: FlightDep, fleet: FleetDep) -> dict[str, Any]:
        change = fleet.pause if pause else fleet.resume
        return _document(row, await change(row.id, stored_status=row.status))

    router.post(f"/{{flight_id}}/{command}", name=f"{command}_flight", response_model=FlightOut,
                summary=summary, description=description,
                responses=error_responses(404, 409))(set_clock)


_clock_route(
    True, "Pause a flight: the flight clock stops, every vehicle holds",
    "Every vehicle flying the plan holds the plan's setpoint of the same plan time, so the "
    "fleet stays as separated as the plan is at that instant (status `paused`). After the "
    "fleet's `pause_limit` (default 120 s) its `pause_expiry` applies (land, or hold) and the "
    "flight ends aborted. 409 unless the plan is being flown.")
_clock_route(
    False, "Resume a paused flight from where its flight clock stopped",
    "The flight clock runs again from the plan time it stopped at (status `running`). 409 "
    "unless paused.")


@router.post(
    "/{flight_id}/replan",
    status_code=202,
    response_model=ReplanOut,
    summary="Replan a flight in the air: change goals, drop vehicles",
    responses=error_responses(400, 404, 409, 413, 422),
)
async def replan_flight(
    row: FlightDep, fleet: FleetDep, settings: SettingsDep, request: ReplanRequest,
) -> dict[str, Any]:
    """The flight plans anew from where its plan will be a moment ahead (the switch time)
    and switches its setpoint stream there if the new plan is verified in time; otherwise it
    flies on with its plan. 202 at once with the replan (status `planning`); the events
    `replan_started`, then `replan_switched` or `replan_missed` follow on `links.events`, and
    the live state carries the replan. 409 unless the flight is running its plan, or while
    another replan is under way (one at a time: a second is refused, not queued); 422 naming
    `goals.<id>` or `drop[n]` for an unknown vehicle, a goal outside the workspace, inside an
    obstacle's clearance or closer than R to another goal."""
    goals, drop = checked(request, settings.max_vehicles)
    replan = await fleet.replan(row.id, goals, drop, request.drop_action,
                                stored_status=row.status)
    return {"replan": replan}


class FlownTrajectoryVehicle(BaseModel):
    """One vehicle's setpoints over the flight's plans."""

    id: str
    position: list[list[float]] = Field(description="(M, 3) positions (m), world frame ENU.")
    velocity: list[list[float]] = Field(description="(M, 3) velocities (m/s).")


class FlownSwitch(BaseModel):
    replan: int | None = Field(description="The replan's id.")
    t: float = Field(description="Its switch time (flight time, s).")


class FlownTrajectoryOut(BaseModel):
    """The plans a flight flies, on one time grid: the mission's plan from flight time 0,
    each switched replan's from its switch time."""

    model_config = ConfigDict(json_schema_extra={"examples": [{
        "flight_id": "a41c03e9b2f1", "mission_id": "3f2a9c81d0b4", "rate": 10.0,
        "frame": "world_enu", "t": [0.0, 0.1],
        "vehicles": [{"id": "uav1", "position": [[4.5, 2.5, 1.1], [4.49, 2.5, 1.1]],
                      "velocity": [[0.0, 0.0, 0.0], [-0.1, 0.0, 0.0]]}],
        "switches": [{"replan": 1, "t": 4.2}], "dropped": {"uav3": 4.2}}]})

    flight_id: str
    execution_id: str = Field(description="The same as `flight_id` (deprecated).",
                              deprecated=True)
    mission_id: str
    rate: float
    frame: Literal["world_enu"]
    t: list[float] = Field(description="M sample times (flight time, s), 0 to the end of the "
                           "last plan.")
    vehicles: list[FlownTrajectoryVehicle] = Field(
        description="Every vehicle of the mission's plan, in its order, on the plan in force "
        "at each time.")
    switches: list[FlownSwitch] = Field(description="The switched replans, in order.")
    dropped: dict[str, float] = Field(
        description="Vehicles a replan dropped -> its switch time; from then on shown at "
        "rest where their plan left them (each lands or holds on its own motion).")


@router.get(
    "/{flight_id}/trajectory",
    response_model=FlownTrajectoryOut,
    summary="The plans a flight flies, sampled (replans included)",
    responses=error_responses(404, 409, 422),
)
async def flight_trajectory(
    row: FlightDep, plans: PlanCacheDep, fleet: FleetDep, settings: SettingsDep,
    rate: Annotated[float, Query(gt=0, description="Samples per second (Hz).")] = 10.0,
) -> dict[str, Any]:
    """Every vehicle's setpoints at `rate` Hz in flight time: the mission's plan, then each
    switched replan's plan from its switch time (live while the flight flies, from its record
    once it ended). Without replans it is the mission's trajectory."""
    if rate > settings.max_trajectory_rate:
        raise InvalidRequest(
            "rate", f"must be at most {settings.max_trajectory_rate:g} Hz, got {rate:g}")
    plan = await run_in_threadpool(plans.get, row.mission_id)
    replanned = await fleet.replanned(row.id)
    document = await run_in_threadpool(
        flown_trajectory, [Segment(0.0, plan), *replanned], rate,
        settings.max_trajectory_samples)
    return {"flight_id": row.id, "execution_id": row.id, "mission_id": row.mission_id,
            **document}


@router.get(
    "/{flight_id}/record",
    response_model=None,
    summary="Download the flight record",
    responses={200: {"content": {"application/json": {}}}, **error_responses(404, 409)},
)
def get_record(row: FlightDep, store: StoreDep, fleet: FleetDep) -> Response:
    """Setpoints sent, telemetry received, events and the summary (gcs flight record)."""
    flight = fleet.flight(row.id)
    held = None if flight is None or flight.unstored is None or flight.handle is None \
        else flight.handle.record
    if held is not None:
        # ended, not stored yet (a storage fault): the record is in memory
        return Response(
            orjson.dumps(held, option=orjson.OPT_SERIALIZE_NUMPY),
            media_type="application/json",
            headers={"Content-Disposition": f'attachment; filename="flight-{row.id}.json"'})
    stored = store.get_flight(row.id, with_record=True)
    if stored is None or stored.record_json is None:
        raise StateConflict("flight_id", f"flight {row.id!r} has no flight record "
                       f"(status {row.status})")
    return Response(
        stored.record_json, media_type="application/json",
        headers={"Content-Disposition": f'attachment; filename="flight-{row.id}.json"'},
    )
