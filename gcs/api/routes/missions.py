"""/api/missions: create (plan), list, read, delete missions; progress; trajectory and show
exports; the geofence as a QGroundControl .plan file.

Long: the routes of one resource (missions), each short, sharing its helpers.

A mission is a validated scenario plus, once its worker answers, the plan. POST waits up to
``wait`` seconds (default: the `plan_wait_s` setting) for the plan and answers 201 with it;
a plan still computing by then is answered 202 with the mission (status ``planning``) to poll
at its ``Location``, and its SCP iterations stream from ``/events`` (server-sent events).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
from collections.abc import AsyncIterable
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Response
from fastapi.responses import StreamingResponse
from fastapi.sse import EventSourceResponse, ServerSentEvent
from starlette.concurrency import run_in_threadpool

from gcs.api.deps import (
    EventStreamSlot,
    ExportSlot,
    FleetDep,
    JsonBody,
    LastEventId,
    MissionDep,
    PlanCacheDep,
    PlanningDep,
    SettingsDep,
    SharedJsonDep,
    StoreDep,
)
from gcs.api.errors import ErrorItem, Unprocessable, error_responses
from gcs.api.schemas import (
    MissionList,
    MissionOut,
    MissionSummary,
    TrajectoryOut,
    ref,
    shape_errors,
)
from gcs.errors import ExportError, InvalidRequest, StateConflict
from gcs.export.qgc_plan import QGC_PLAN_MEDIA_TYPE, qgc_plan
from gcs.export.skyc import SKYC_MEDIA_TYPE, keyframe_count, parse_origin, skyc_chunks
from gcs.frames import Geodetic
from gcs.geofence import build_fence
from gcs.service.limits import (
    WorkBounds,
    scenario_bound_errors,
    sequence_bound_errors,
    trajectory_sample_count,
    with_server_horizon,
)
from gcs.service.plan_worker import finite_json, plan_json
from gcs.service.planning import PlanJob, PlanningService
from gcs.service.plans import trajectory_csv_chunks, trajectory_json_chunks
from gcs.service.settings import Settings
from gcs.service.statuses import FLIGHT_ACTIVE, MissionStatus
from gcs.service.store import MissionRow, Store
from gcs.service.uploaded_plan import is_plan_body, plan_document, uploaded_plan
from planner import Plan, Scenario
from planner.errors import FieldError
from planner.methods.sequence import FormationSequence, parse_sequence, timeline_scenario
from planner.methods.sequence import trajectory_csv as show_csv
from planner.verification.verify import refusal

__all__ = ["mission_document", "router"]

router = APIRouter(prefix="/missions", tags=["missions"])

def _links(mission_id: str) -> dict[str, str]:
    base = f"/api/missions/{mission_id}"
    return {
        "self": base,
        "events": f"{base}/events",
        "plan": f"{base}/plan",
        "trajectory": f"{base}/trajectory?rate=20",
        "trajectory_csv": f"{base}/trajectory?rate=20&format=csv",
        "show_skyc": f"{base}/show.skyc",
        "flights": f"{base}/flights",
        "executions": f"{base}/executions",  # the same, under the former name
    }


def mission_document(row: MissionRow, job: PlanJob | None) -> str:
    """The `MissionOut` JSON text. The plan text is spliced in as stored: parsing and
    re-serialising a multi-megabyte plan per request would hold the interpreter for tens of
    milliseconds."""
    planning = job is not None and row.status == MissionStatus.PLANNING
    head = {
        **row.summary(),
        "progress": list(job.progress) if planning and job is not None else [],
        "planning": job.summary() if planning and job is not None else None,
        "scenario": row.scenario,
        "links": _links(row.id),
    }
    text = json.dumps(finite_json(head), separators=(",", ":"), allow_nan=False)
    return f'{text[:-1]},"plan":{row.plan_json or "null"}}}'


async def _admit(store: Store, planning: PlanningService, scenario: dict[str, Any],
                 sequence: FormationSequence | None, time_limit_s: float
                 ) -> tuple[MissionRow, PlanJob]:
    """Store the mission and start its job, or neither: a place in the queue is reserved
    before the row is written (503 otherwise, nothing stored), and a row whose job could not
    start is deleted again."""
    reservation = planning.reserve()
    try:
        row = await run_in_threadpool(store.create_mission, scenario, reservation.mission_id)
        if sequence is not None:
            job = planning.submit_sequence(row.id, sequence, time_limit_s=time_limit_s,
                                           reservation=reservation)
        else:
            job = planning.submit(row.id, scenario, time_limit_s=time_limit_s,
                                  reservation=reservation)
    except BaseException:
        # The row may exist (written, then no job): never leave it `planning` without one.
        with contextlib.suppress(Exception):
            await asyncio.shield(run_in_threadpool(store.delete_mission,
                                                   reservation.mission_id))
        raise
    finally:
        reservation.release()
    return row, job


def _json(text: str, status_code: int = 200, headers: dict[str, str] | None = None) -> Response:
    return Response(text, status_code=status_code, media_type="application/json",
                    headers=headers)


async def _document(store: Store, planning: PlanningService, mission_id: str) -> str | None:
    row = await run_in_threadpool(store.get_mission, mission_id, with_plan=True)
    return None if row is None else mission_document(row, planning.job(mission_id))


def _validated(body: Any, settings: Settings) -> Scenario:
    """The scenario of a request body: every shape problem at once, then every work bound
    exceeded, then the planner's own validation (every problem of the settings at once, then
    the first problem of the vehicles)."""
    shape = shape_errors(body)
    if shape:
        raise Unprocessable.of(shape, body)
    work = WorkBounds.from_settings(settings)
    bounds = scenario_bound_errors(body, work)
    if bounds:
        raise Unprocessable.of([ErrorItem(field=e.field, reason=e.reason) for e in bounds],
                               body)
    try:
        return Scenario.from_dict(with_server_horizon(body, work))
    except FieldError as exc:
        raise Unprocessable.of([ErrorItem(field=e.field, reason=e.reason)
                                for e in getattr(exc, "errors", [exc])], body) from None


def _uploaded(body: Any, settings: Settings) -> tuple[dict[str, Any], str, Plan]:
    """A plan body's scenario, plan text and plan, verified again here; 422 with every
    problem found (each under `vehicles[i]` naming its vehicle) otherwise."""
    plan, problems = uploaded_plan(body, WorkBounds.from_settings(settings))
    if plan is None:
        document = plan_document(body)
        raise Unprocessable.of(
            [ErrorItem(field=e.field, reason=e.reason) for e in problems],
            document.get("scenario") if any(e.field.startswith("scenario.") for e in problems)
            else document)
    return plan.scenario.to_dict(), plan_json(plan), plan


async def _store_uploaded(body: Any, store: Store, settings: Settings) -> Response:
    """Store a plan made elsewhere, verified again, as a planned mission (201)."""
    scenario, text, plan = await run_in_threadpool(_uploaded, body, settings)
    row = await run_in_threadpool(store.create_mission, scenario)
    try:
        await run_in_threadpool(store.finish_planning, row.id, plan_json=text,
                                plan_status=plan.status, plan_ok=True,
                                steps=plan.scenario.steps)
    except BaseException:  # never a mission left `planning` without a job
        with contextlib.suppress(Exception):
            await asyncio.shield(run_in_threadpool(store.delete_mission, row.id))
        raise
    document = await run_in_threadpool(store.get_mission, row.id, with_plan=True)
    assert document is not None
    return _json(mission_document(document, None), 201, {"Location": f"/api/missions/{row.id}"})


def is_sequence(body: Any) -> bool:
    """A formation sequence (`planner.methods.sequence` JSON) rather than a scenario."""
    return isinstance(body, dict) and "formations" in body


def _validated_sequence(body: Any, settings: Settings) -> FormationSequence:
    """A sequence request: every work bound exceeded at once (before anything is parsed or
    allocated), then the sequence's own validation (the first problem, by field)."""
    work = WorkBounds.from_settings(settings)
    bounds = sequence_bound_errors(body, work)
    if bounds:
        raise Unprocessable.of([ErrorItem(field=e.field, reason=e.reason) for e in bounds])
    return parse_sequence(with_server_horizon(body, work))


@router.post(
    "",
    status_code=201,
    response_model=None,
    summary="Plan a mission",
    responses={
        201: {"model": MissionOut, "description": "Planned (or failed) within the wait"},
        202: {"model": MissionOut, "description": "Still planning: poll the Location"},
        **error_responses(400, 401, 403, 413, 415, 422, 503),
    },
    openapi_extra={"requestBody": {
        "required": True,
        "description": "A scenario (the planner's scenario JSON contract), a formation "
                       "sequence (an object with `formations`: see the README), or a plan "
                       "made elsewhere to fly (a Plan JSON, or `{\"plan\": PLAN}`), which "
                       "is verified again before it is stored.",
        "content": {"application/json": {"schema": ref("Scenario")}},
    }},
)
async def create_mission(
    body: JsonBody,
    store: StoreDep,
    planning: PlanningDep,
    settings: SettingsDep,
    wait: Annotated[
        float | None,
        Query(ge=0, le=600, description="Seconds to wait for the plan before answering 202 "
              "(default: the plan_wait_s setting)."),
    ] = None,
    time_limit: Annotated[
        float | None,
        Query(gt=0, description="Seconds the plan may compute (default and maximum: the "
              "plan_time_limit_s setting); past it the mission fails."),
    ] = None,
) -> Response:
    """Validate a scenario, store it as a mission and plan it in a worker process.

    A formation sequence (a body with `formations`) is a mission too: its legs are planned
    as parallel Dask tasks (progress records carry their `leg`), stitched and verified as
    one plan whose scenario is the whole timeline; it flies like any mission.

    A plan made elsewhere (a Plan JSON as `fleetplan plan` writes it, or `{"plan": PLAN}`)
    is verified again on its own trajectories and stored as a planned mission (201), or
    refused with 422 naming the field (`plan` when it may not be flown, and why).

    Answers 201 with the mission and its plan when planning ends within `wait` seconds, else
    202 with the mission still `planning` (poll `GET /api/missions/{id}` or follow
    `/events`). Invalid scenarios are 422 naming each offending field and the reason (every
    type, key and server-limit problem at once); nothing is stored for them.
    """
    if is_plan_body(body):
        return await _store_uploaded(body, store, settings)
    limit = planning.job_time_limit(time_limit)
    sequence: FormationSequence | None = None
    if is_sequence(body):
        sequence = await run_in_threadpool(_validated_sequence, body, settings)
        # The mission's scenario is the whole timeline, F0 to the last formation: the one
        # its stitched plan carries and a flight re-verifies.
        scenario = timeline_scenario(sequence).to_dict()
    else:
        scenario = (await run_in_threadpool(_validated, body, settings)).to_dict()
    row, job = await _admit(store, planning, scenario, sequence, limit)
    timeout = settings.plan_wait_s if wait is None else wait
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(job.done.wait(), timeout)
    outcome = job.outcome
    error = (outcome or {}).get("error") or {}
    if outcome is not None and outcome["status"] == MissionStatus.FAILED and error.get("field"):
        # The planner found a problem with the input itself: answer like any invalid input.
        await run_in_threadpool(store.delete_mission, row.id)
        planning.forget(row.id)
        raise InvalidRequest(error["field"], error["reason"])
    text = await _document(store, planning, row.id)
    assert text is not None
    status = 202 if outcome is None else 201
    return _json(text, status, {"Location": f"/api/missions/{row.id}"})


@router.get("", response_model=MissionList, summary="List missions")
def list_missions(
    store: StoreDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=1_000_000_000)] = 0,
) -> dict[str, Any]:
    """Missions newest first, without scenarios and plans."""
    rows, total = store.list_missions(limit=limit, offset=offset)
    return {
        "total": total,
        "limit": limit,
        "offset": offset,
        "missions": [MissionSummary.model_validate(r.summary()) for r in rows],
    }


@router.get(
    "/{mission_id}",
    response_model=None,
    summary="Get a mission (and its plan)",
    responses={200: {"model": MissionOut}, **error_responses(404)},
)
async def get_mission(mission: MissionDep, store: StoreDep, planning: PlanningDep) -> Response:
    """The mission with its scenario, progress while planning, and its plan once planned."""
    text = await _document(store, planning, mission.id)
    if text is None:  # deleted between the two reads
        raise StateConflict("mission_id", f"mission {mission.id!r} was just deleted")
    return _json(text)


@router.delete(
    "/{mission_id}",
    status_code=204,
    summary="Delete a mission",
    responses=error_responses(404, 409),
)
async def delete_mission(
    mission: MissionDep, store: StoreDep, planning: PlanningDep, plans: PlanCacheDep
) -> Response:
    """Delete a mission, its plan and its flight records; a plan still computing is cancelled
    first (its worker is freed). Refused (409) while the mission is flying."""
    if mission.status == MissionStatus.PLANNING:
        await _stop_planning(planning, store, mission.id, "the mission was deleted")
    flights = await run_in_threadpool(store.list_flights, mission.id)
    flying = [f.id for f in flights if f.status in FLIGHT_ACTIVE]
    if flying:
        raise StateConflict("mission_id", f"mission {mission.id!r} is flying (flight "
                       f"{flying[0]}); abort or wait for the flight to end first")
    await run_in_threadpool(store.delete_mission, mission.id)
    planning.forget(mission.id)
    plans.forget(mission.id)
    return Response(status_code=204)


async def _stop_planning(planning: PlanningService, store: Store, mission_id: str,
                         reason: str) -> None:
    """Cancel a mission's plan and wait until its job has ended (and the mission is stored
    as failed). A `planning` row that no job holds (its final write was refused, or a
    previous run left it) is marked failed with the reason; 409 only for a mission whose job
    is being started this instant."""
    job = planning.job(mission_id)
    if job is not None and not job.done.is_set():
        planning.cancel(mission_id, reason)
        await job.done.wait()
        return
    if planning.holds(mission_id):
        raise StateConflict("mission_id", f"mission {mission_id!r} is being admitted to the "
                            "planning queue; retry")
    await run_in_threadpool(store.fail_stale_planning, mission_id,
                            {"field": None, "reason": f"{reason} (no plan job held it)"})


@router.post(
    "/{mission_id}/cancel",
    response_model=None,
    summary="Cancel planning",
    responses={200: {"model": MissionOut}, **error_responses(404, 409)},
)
async def cancel_mission(mission: MissionDep, store: StoreDep, planning: PlanningDep
                         ) -> Response:
    """Stop planning this mission now: the computation ends and its worker is freed. The
    mission is kept, with status `failed` and the reason (also when no job held it any
    more). 409 if it is not planning."""
    if mission.status != MissionStatus.PLANNING:
        raise StateConflict("mission_id", f"mission {mission.id!r} is not planning (status "
                            f"{mission.status})")
    await _stop_planning(planning, store, mission.id, "cancelled by the operator")
    text = await _document(store, planning, mission.id)
    if text is None:
        raise StateConflict("mission_id", f"mission {mission.id!r} was just deleted")
    return _json(text)


@router.get(
    "/{mission_id}/events",
    response_class=EventSourceResponse,
    summary="Planning progress (server-sent events)",
    responses=error_responses(404, 503, json_content=True),
)
async def mission_events(
    mission: MissionDep, planning: PlanningDep, after: LastEventId,
    _slot: EventStreamSlot, shared: SharedJsonDep,
) -> AsyncIterable[ServerSentEvent]:
    """`iteration` events (one per SCP iteration: iteration, cost, cost_change,
    separation_rows, qp_solves, groups, seconds, method, batch, batches) while planning,
    `working` events from inside long iterations (at most about once a second: the
    mission's `planning` summary, with the groups solved so far), then one `done` event
    {status, plan_status, plan_ok, error}; then the stream ends. Each `iteration` has an
    `id:` (0, 1, ...); a client reconnecting with `Last-Event-ID: n` gets the iterations
    after n, then `done`. Streams are bounded like a flight's (503 with Retry-After)."""
    job = planning.job(mission.id)
    if job is None or mission.status != MissionStatus.PLANNING:
        yield ServerSentEvent(
            event="done",
            data={"status": mission.status, "plan_status": mission.plan_status,
                  "plan_ok": mission.plan_ok, "error": mission.error},
        )
        return
    sequence = 0
    async for kind, data in job.events():
        if kind == "iteration":
            number, sequence = sequence, sequence + 1
            if after is None or number > after:
                yield ServerSentEvent(event=kind, raw_data=shared.text(data), id=str(number))
        else:
            yield ServerSentEvent(event=kind, raw_data=shared.text(data))


@router.get(
    "/{mission_id}/plan",
    response_model=None,
    summary="Download the Plan JSON",
    responses={200: {"content": {"application/json": {}}}, **error_responses(404, 409)},
)
def get_plan(mission: MissionDep, store: StoreDep) -> Response:
    """The plan alone (the Plan JSON contract), e.g. for `fleetplan fly PLAN.json`."""
    row = store.get_mission(mission.id, with_plan=True)
    if row is None or row.plan_json is None:
        state = "still planning" if mission.status == MissionStatus.PLANNING else "without a plan"
        raise StateConflict("mission_id", f"mission {mission.id!r} is {state}")
    return _json(
        row.plan_json,
        headers={"Content-Disposition": f'attachment; filename="plan-{mission.id}.json"'},
    )


@router.get(
    "/{mission_id}/trajectory",
    response_model=None,
    summary="Sampled setpoints per vehicle (JSON or CSV)",
    responses={
        200: {
            "model": TrajectoryOut,
            "content": {"text/csv": {"example": "vehicle,t,x,y,z,vx,vy,vz,ax,ay,az\n"
                                     "uav1,0.000000,4.500000,2.500000,1.100000,..."}},
        },
        **error_responses(404, 409, 422, 503),
    },
)
def get_trajectory(
    mission: MissionDep,
    plans: PlanCacheDep,
    settings: SettingsDep,
    _slot: ExportSlot,
    rate: Annotated[float, Query(gt=0, description="Samples per second (Hz).")] = 20.0,
    format: Annotated[
        Literal["json", "csv", "show-csv"],
        Query(description="json, csv, or show-csv (one vehicle: time ms, x, y, z)"),
    ] = "json",
    vehicle: Annotated[
        str | None, Query(max_length=64, description="show-csv: the vehicle id")
    ] = None,
) -> Response:
    """Every vehicle's position, velocity and acceleration at `rate` Hz from 0 to the horizon
    (world frame ENU, exact motion between steps): what the GCS streams as setpoints. CSV has
    one row per vehicle and time. Both formats are sent as they are written (JSON one vehicle
    at a time). At most `max_concurrent_exports` are computed at once; past that the answer
    is 503 with Retry-After."""
    if rate > settings.max_trajectory_rate:
        raise InvalidRequest(
            "rate", f"must be at most {settings.max_trajectory_rate:g} Hz, got {rate:g}"
        )
    plan = plans.get(mission.id)
    if format == "show-csv":
        return _show_csv(mission.id, plan, rate, vehicle, settings)
    if format == "csv":
        return StreamingResponse(
            trajectory_csv_chunks(plan, rate, settings.max_trajectory_samples),
            media_type="text/csv",
            headers={
                "Content-Disposition": f'attachment; filename="trajectory-{mission.id}.csv"'
            },
        )
    return StreamingResponse(
        trajectory_json_chunks(mission.id, plan, rate, settings.max_trajectory_samples),
        media_type="application/json",
    )


def _show_csv(mission_id: str, plan: Any, rate: float, vehicle: str | None,
              settings: Settings) -> Response:
    """One vehicle's positions in the show-tool layout (`Time [msec],x [m],y [m],z [m]`)."""
    if vehicle is None:
        raise InvalidRequest("vehicle", "is required with format=show-csv (a vehicle id)")
    ids = plan.scenario.ids
    if vehicle not in ids:
        raise InvalidRequest("vehicle", f"no vehicle {vehicle!r} in this plan")
    if not plan.vehicles:
        raise StateConflict("mission_id", f"the plan (status {plan.status}) has no "
                            f"trajectories")
    rows = trajectory_sample_count(plan.scenario.horizon, rate, 1)
    if rows > settings.max_trajectory_samples:
        raise InvalidRequest("rate", f"{rows} samples exceed this server's limit of "
                             f"{settings.max_trajectory_samples} (setting "
                             f"max_trajectory_samples)")
    n = ids.index(vehicle)
    track = plan.vehicles[n]
    text = show_csv(track.position[None], track.velocity[None], track.acceleration[None],
                    plan.scenario.dt, [vehicle], rate_hz=rate)[vehicle]
    safe = "".join(c if c.isalnum() or c in "._-" else "_" for c in vehicle)
    return Response(text, media_type="text/csv", headers={
        "Content-Disposition": f'attachment; filename="show-{mission_id}-{safe}.csv"'})


@router.get(
    "/{mission_id}/show.skyc",
    response_model=None,
    summary="The plan as a Skybrush show file (.skyc)",
    responses={
        200: {"content": {SKYC_MEDIA_TYPE: {}},
              "description": "A ZIP archive holding show.json (Skybrush's compiled show)"},
        **error_responses(404, 409, 422, 503),
    },
)
def download_show(
    mission: MissionDep,
    plans: PlanCacheDep,
    settings: SettingsDep,
    _slot: ExportSlot,
    origin: Annotated[
        str | None,
        Query(max_length=100, description="LAT,LON[,AMSL]: where the world origin (0, 0, 0) "
              "is on the Earth (degrees, metres), written as the show's location"),
    ] = None,
) -> Response:
    """The verified plan as a Skybrush compiled show: one drone per vehicle (named by its id,
    home at its start) whose trajectory is one cubic Bezier segment per step, exact to 1 um;
    takeoff time 0 at the plan's start; the geofence and the validation limits from the
    scenario. The show frame is the world frame (x east, y north, z up). Sent as it is
    written, one drone at a time. 409 for a mission whose plan must not be flown
    (`planner.verification.verify.refusal`: not converged, failing verification anew, or starting
    moving); at most
    `max_trajectory_samples` keyframes (vehicles x (steps + 1)) and `max_concurrent_exports`
    exports at once, like `/trajectory`."""
    try:
        place = None if origin is None else parse_origin(origin)
    except ExportError as exc:
        raise InvalidRequest(exc.field, exc.reason) from None
    plan = plans.get(mission.id)
    why = refusal(plan)  # the verdict `fleetplan fly` and `fleetplan export` give
    if why is not None:
        raise StateConflict("mission_id", f"mission {mission.id!r}: refusing to export the "
                            f"plan: {why}")
    keyframes = keyframe_count(plan)
    if keyframes > settings.max_trajectory_samples:
        raise InvalidRequest("mission_id", f"the show has up to {keyframes} keyframes "
                             f"({len(plan.vehicles)} vehicles x {plan.scenario.steps + 1}), "
                             f"more than this server's limit {settings.max_trajectory_samples} "
                             f"(setting max_trajectory_samples); use fleetplan export")
    try:
        chunks = skyc_chunks(plan, show_id=mission.id, origin=place)
    except ExportError as exc:
        raise StateConflict(f"plan.{exc.field}", exc.reason) from None
    return StreamingResponse(chunks, media_type=SKYC_MEDIA_TYPE, headers={
        "Content-Disposition": f'attachment; filename="show-{mission.id}.skyc"'})


@router.get(
    "/{mission_id}/geofence",
    response_model=None,
    summary="The geofence the vehicles are given, as a QGroundControl .plan file",
    responses={200: {"content": {QGC_PLAN_MEDIA_TYPE: {}},
                     "description": "A QGroundControl plan file: fileType Plan, an empty "
                                    "mission, the geoFence section, no rally points"},
               **error_responses(404, 409, 422)},
)
def download_geofence(
    mission: MissionDep,
    plans: PlanCacheDep,
    fleet: FleetDep,
    format: Annotated[
        Literal["qgc-plan"], Query(description="qgc-plan: a QGroundControl .plan file")
    ] = "qgc-plan",
    origin: Annotated[
        str | None,
        Query(max_length=100, description="LAT,LON[,AMSL]: where the world origin (0, 0, 0) "
              "is on the Earth (degrees, metres); default: the fleet's world_origin"),
    ] = None,
) -> Response:
    """The fence `fleetplan fly` uploads before arming (the workspace's horizontal rectangle
    as an inclusion polygon, each obstacle standing on the ground as an exclusion polygon or
    circle; `gcs.geofence`), placed on the Earth from `origin` or else the fleet's
    `world_origin` (the fleet file's, or the mock's): 409 when neither is known."""
    try:
        place = None if origin is None else parse_origin(origin)
    except ExportError as exc:
        raise InvalidRequest(exc.field, exc.reason) from None
    if place is None:
        known = fleet.describe().get("world_origin")
        if known is None:
            raise StateConflict("origin", "no world origin is known (the service's fleet has "
                                "no world_origin): give ?origin=LAT,LON[,AMSL]")
        place = Geodetic(known["lat"], known["lon"], known["alt"])
    plan = plans.get(mission.id)
    document = qgc_plan(build_fence(plan.scenario.to_dict()), place)
    return _json(json.dumps(document), headers={
        "Content-Disposition": f'attachment; filename="geofence-{mission.id}.plan"'})
