"""Shows through the API: a mission's validation report (`gcs.show.report`, the HTML
`fleetplan report` writes) and the import of a show designed in a show tool (`gcs.show`,
what `fleetplan import` does), for clients that have no files on the server.

Both are bounded like the other exports: one of `max_concurrent_exports` slots while they
run; the report at most `max_trajectory_samples` samples (vehicles x (steps + 1)); the import
(a JSON body holding the file in base64, as every request body is JSON) at most
`max_body_bytes` uploaded and `MAX_IMPORT_UNPACKED` bytes unpacked from the archive (a ZIP
bomb stops there).
"""

from __future__ import annotations

import base64
import re
import tempfile
from pathlib import Path, PurePath
from typing import Annotated, Any

from fastapi import APIRouter
from fastapi.responses import HTMLResponse
from pydantic import BaseModel, ConfigDict, Field

from gcs.api.deps import ExportSlot, MissionDep, PlanCacheDep, SettingsDep
from gcs.api.errors import error_responses
from gcs.errors import InvalidRequest, StateConflict
from gcs.show.design import read_design
from gcs.show.report import report_html
from gcs.show.to_sequence import DEFAULT_DT, ImportOptions, to_sequence
from gcs.show.tracks import ShowFileError
from planner.model.scenario import Assignment

__all__ = ["MAX_IMPORT_UNPACKED", "ImportRequest", "router"]

router = APIRouter(tags=["shows"])

#: Most bytes an uploaded archive may unpack to (a 1,000-drone show's show.json or CSV is
#: tens of megabytes).
MAX_IMPORT_UNPACKED = 256 << 20
#: What an upload's name may keep (it names the file in error messages); the rest becomes '_'.
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]")


@router.get(
    "/missions/{mission_id}/report.html",
    response_class=HTMLResponse,
    summary="The mission's validation report (one self-contained HTML page)",
    responses={200: {"content": {"text/html": {}},
                     "description": "The report fleetplan report writes: a verdict per check, "
                                    "the worst moments, charts against the limits, the lights"},
               **error_responses(404, 409, 422, 503, json_content=True)},
)
def mission_report(mission: MissionDep, plans: PlanCacheDep, settings: SettingsDep,
                   _slot: ExportSlot) -> HTMLResponse:
    """The plan's validation report, as `fleetplan report` writes it: no network requests,
    so it can be kept, sent or printed. A plan that fails a check has a report too (it says
    which). 409 for a mission without a plan or a plan without trajectories; 422 beyond
    `max_trajectory_samples`."""
    plan = plans.get(mission.id)
    if not plan.vehicles:
        raise StateConflict("mission_id", f"mission {mission.id!r}: the plan (status "
                                          f"{plan.status}) has no trajectories to report on")
    samples = len(plan.vehicles) * (plan.scenario.steps + 1)
    if samples > settings.max_trajectory_samples:
        raise InvalidRequest("mission_id", f"the plan has {samples} samples "
                             f"({len(plan.vehicles)} vehicles x {plan.scenario.steps + 1}), "
                             f"more than this server's limit {settings.max_trajectory_samples} "
                             f"(setting max_trajectory_samples); use fleetplan report")
    text, _passed = report_html(plan)
    return HTMLResponse(text, headers={
        "Content-Disposition": f'inline; filename="report-{mission.id}.html"'})


class ImportRequest(BaseModel):
    """A show file (base64, as JSON like every request body) and how to read it: the
    `fleetplan import` options."""

    model_config = ConfigDict(extra="forbid", json_schema_extra={"examples": [
        {"filename": "show.skyc", "file": "UEsDBBQ...", "assignment": "free"}]})

    file: str = Field(min_length=1, description="the show file in base64: a Skybrush "
                      "compiled show (.skyc), or a ZIP of Skybrush CSV files (one per drone)")
    filename: str = Field("show.zip", max_length=100, description="the file's name, named in "
                          "errors; .skyc (or a ZIP holding show.json) is a compiled show")
    times: list[Annotated[float, Field(ge=0, le=86_400)]] | None = Field(
        None, min_length=1, max_length=1000, description="the formations at these times (s) "
        "instead of the show's hold points")
    dt: float = Field(DEFAULT_DT, gt=0, le=10, description="the sequence's step (s)")
    min_separation: float | None = Field(None, gt=0, le=1000, description="R (m; default "
                                         "the show's minDistance, else 1)")
    min_hold: float = Field(0.5, ge=0, le=3600, description="shortest stretch with every "
                            "drone at rest that is a hold point (s)")
    assignment: Assignment = Field("fixed", description="fixed: each drone "
                                                 "keeps its place; free: the planner assigns "
                                                 "the places per leg")
    auto_durations: bool = Field(False, description="the planner chooses each leg's "
                                                    "duration instead of the design's")
    max_velocity: float | None = Field(None, gt=0, le=100, description="per-axis speed "
                                       "bound (m/s; default the show's, else 3)")
    max_acceleration: float | None = Field(None, gt=0, le=100, description="per-axis "
                                           "acceleration bound (m/s^2; default the show's, "
                                           "else 3)")


@router.post(
    "/imports",
    summary="A show designed in a show tool as a formation sequence",
    responses={200: {"description": "The formation sequence JSON (POST it to /api/missions "
                                    "to plan it)"},
               **error_responses(400, 413, 422, 503)},
)
def import_show(request: ImportRequest, _slot: ExportSlot) -> dict[str, Any]:
    """The show's hold points as formations with their colours, its ground start and
    landing as a takeoff and landing: the sequence `fleetplan import` writes. The whole
    request is at most `max_body_bytes` (the file base64-encoded); 422 naming the file, line
    and field of a bad show (`field` the column or JSON path)."""
    try:
        data = base64.b64decode(request.file, validate=True)
    except ValueError as exc:  # binascii.Error, or a character outside ASCII
        raise InvalidRequest("file", f"not base64: {exc}") from None
    options = ImportOptions(dt=request.dt, min_separation=request.min_separation,
                            times=None if request.times is None else tuple(request.times),
                            min_hold=request.min_hold, auto_durations=request.auto_durations,
                            assignment=request.assignment, velocity_max=request.max_velocity,
                            acceleration_max=request.max_acceleration)
    name = _UNSAFE.sub("_", PurePath(request.filename).name).lstrip(".") or "show.zip"
    return _import(data, name, options)


def _import(body: bytes, name: str, options: ImportOptions) -> dict[str, Any]:
    """The sequence of the uploaded show (written to a private temporary folder under its
    own name, so errors name it as the client does)."""
    with tempfile.TemporaryDirectory(prefix="fleetplan-import-") as folder:
        path = Path(folder) / name
        path.write_bytes(body)
        try:
            show = read_design(path, unpacked=MAX_IMPORT_UNPACKED)
            return to_sequence(show.tracks, name=show.title, file=name, options=options,
                               validation=show.validation)
        except ShowFileError as exc:
            where = exc.file if exc.line is None else f"{exc.file}, line {exc.line}"
            raise InvalidRequest(exc.field, f"{where}: {exc.reason}") from None
