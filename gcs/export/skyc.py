"""A plan as a Skybrush compiled show (``.skyc``): a ZIP archive holding one ``show.json``.

The format, as Skybrush's public sources read it (skybrush.js ``packages/show-format``,
skybrush-server ``flockwave/server/show``, Skybrush Live's show loader)::

    {"version": 1,
     "environment": {"type": "outdoor", "location": {"origin": [lat 1e-7 deg, lon 1e-7 deg,
                     amsl mm], "orientation": deg}},        # location only with an origin
     "settings": {"geofence": {...}, "validation": {...}, "cues": {...}},
     "meta": {"title": ..., "id": ..., "segments": {"show": [start, end]}},
     "swarm": {"drones": [{"type": "generic", "settings": {
         "name": ..., "home": [x, y, z],
         "trajectory": {"version": 1, "points": [[t, [x, y, z], [control points]], ...],
                        "takeoffTime": 0, "landingHeight": z},
         "lights": {"version": 1, "data": base64 light program}}}]}}

Each drone's light program is Skybrush's light bytecode (`gcs.export.lightcode`) made from
the sequence's light design (`gcs.export.lights`); a plan without one writes one END.

A keyframe after the first ends the Bezier segment that starts at the keyframe before it;
its control points lie between (none: a straight segment; two: a cubic); the first keyframe
has none. Times are seconds from ``takeoffTime``; Skybrush counts segment durations in whole
milliseconds. Positions are in the show frame (`gcs.frames.world_to_show`: the world frame
itself, x east, y north, z up, as Skybrush's "nwu" frame with its x axis heading east).

Each planner step holds its acceleration constant, so the motion inside it is a quadratic in
time; it is written as the cubic Bezier of the same curve (degree elevation): from p_k with
controls p_k + dt/3 v_k and p_k + 2dt/3 v_k + dt^2/6 a_k to p_k+1. The file reproduces the
plan's motion to its rounding (`DECIMALS`), and a run of steps at rest becomes one constant
segment. The archive is written as it is made (`skyc_chunks`), one drone at a time, so a
large show never sits in memory whole.
"""

from __future__ import annotations

import base64
import math
import os
import tempfile
import zipfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import orjson

from gcs.errors import ExportError
from gcs.export.lightcode import encode
from gcs.export.lights import light_changes
from gcs.frames import SHOW_ORIENTATION_DEG, Geodetic, world_to_show
from planner.model.scenario import Scenario
from planner.result import Plan
from planner.types import FloatArray
from planner.verification.ground import airborne, starts_on_the_ground

__all__ = [
    "DECIMALS",
    "SKYC_MEDIA_TYPE",
    "check_exportable",
    "flight_span",
    "keyframe_count",
    "parse_origin",
    "show_head",
    "skyc_chunks",
    "trajectory_points",
    "write_skyc",
]

#: What an HTTP answer calls a .skyc file: its container, a ZIP archive (Skybrush Studio's
#: client takes compiled shows as application/zip).
SKYC_MEDIA_TYPE = "application/zip"
#: The one archive entry Skybrush reads first.
SHOW_ENTRY = "show.json"
#: Version of the show specification, and of its trajectory, geofence, cue and light blocks.
FORMAT_VERSION = 1
#: Decimals of every coordinate written (1 um): far below the 1 cm the export promises and
#: the millimetre that Skybrush's binary show format keeps.
DECIMALS = 6
#: Decimals of every time written: Skybrush times its segments in whole milliseconds.
TIME_DECIMALS = 3
#: The light program of every drone of a plan without a light design: one END instruction
#: (what the Skybrush server assumes for a drone without a program).
NO_LIGHTS = {"version": FORMAT_VERSION, "data": "AA=="}
#: The archive entries' timestamp: fixed, so the same plan always gives the same bytes.
ZIP_DATE = (1980, 1, 1, 0, 0, 0)
#: An upper bound of one keyframe's JSON size (bytes), to decide whether the entry needs
#: ZIP64 before it is written.
_KEYFRAME_BYTES_MAX = 400


def parse_origin(text: str) -> Geodetic:
    """"LAT,LON" or "LAT,LON,AMSL" (degrees, metres) as the world origin's `Geodetic` (its
    altitude NaN when not given); `ExportError` on `origin` naming what is wrong."""
    parts = [part.strip() for part in text.split(",")]
    if len(parts) not in (2, 3):
        raise ExportError("origin", f"must be LAT,LON or LAT,LON,AMSL, got {text!r}")
    try:
        values = [float(part) for part in parts]
    except ValueError:
        raise ExportError("origin", f"must be numbers LAT,LON[,AMSL], got {text!r}") from None
    if not all(math.isfinite(x) for x in values):
        raise ExportError("origin", "must be finite numbers")
    lat, lon = values[0], values[1]
    amsl = values[2] if len(values) == 3 else math.nan
    if not -90.0 <= lat <= 90.0:
        raise ExportError("origin", f"latitude must be between -90 and 90, got {lat:g}")
    if not -180.0 <= lon <= 180.0:
        raise ExportError("origin", f"longitude must be between -180 and 180, got {lon:g}")
    if len(values) == 3 and not -1e4 <= amsl <= 1e5:
        raise ExportError("origin", f"altitude must be between -10000 and 100000 m, "
                                    f"got {amsl:g}")
    return Geodetic(lat, lon, amsl)


def _milliseconds(dt: float) -> int:
    """The step as whole milliseconds; `ExportError` when it is not one."""
    ms = round(dt * 1000.0)
    if ms < 1 or abs(dt * 1000.0 - ms) > 1e-6:
        raise ExportError("scenario.dt", f"{dt:g} s is not a whole number of milliseconds: "
                                         f"Skybrush times its segments in milliseconds")
    return ms


def check_exportable(plan: Plan) -> None:
    """`ExportError` naming the field when the plan cannot be written as a show: it has no
    trajectories, its step is not a whole number of milliseconds, or its light design is
    malformed. Whether the plan is verified is the caller's decision
    (`planner.verification.verify.refusal`)."""
    if not plan.vehicles:
        raise ExportError("vehicles", f"the plan (status {plan.status}) has no trajectories")
    _milliseconds(plan.scenario.dt)
    for track in plan.vehicles:
        light_changes(plan, track.id)


def keyframe_count(plan: Plan) -> int:
    """Most keyframes the show can hold: one per vehicle and step boundary (runs at rest
    write fewer). What a server's export bound counts."""
    return len(plan.vehicles) * (plan.scenario.steps + 1)


def _clean(values: FloatArray, decimals: int) -> FloatArray:
    """Rounded, without -0.0 (JSON readers print it as a minus sign)."""
    return np.round(values, decimals) + 0.0


def _down(x: float) -> float:
    return math.floor(x * 1000.0 + 1e-9) / 1000.0


def _up(x: float) -> float:
    return math.ceil(x * 1000.0 - 1e-9) / 1000.0


def _validation(scenario: Scenario) -> dict[str, float]:
    """Skybrush's safety checks from the scenario's bounds (rounded outwards to mm): the
    workspace top, the speeds and accelerations the per-axis boxes allow (horizontal: the
    box's diagonal), and the Euclidean distance the separation metric guarantees."""
    lim = scenario.limits
    out = {
        "maxAltitude": _up(float(world_to_show(lim.position_max)[2])),
        "minDistance": _down(scenario.min_separation * float(scenario.separation_scale.min())),
    }
    if lim.velocity_max is not None:
        out["maxVelocityXY"] = _up(math.hypot(lim.velocity_max[0], lim.velocity_max[1]))
        out["maxVelocityZ"] = _up(float(lim.velocity_max[2]))
    if lim.acceleration_max is not None:
        out["maxAccelerationXY"] = _up(math.hypot(lim.acceleration_max[0],
                                                  lim.acceleration_max[1]))
        out["maxAccelerationZ"] = _up(float(lim.acceleration_max[2]))
    return out


def _geofence(scenario: Scenario) -> dict[str, Any]:
    """The workspace box's footprint as one inclusion polygon (counter-clockwise, at z 0);
    its height bound is `validation.maxAltitude`."""
    lo, hi = scenario.limits.position_min, scenario.limits.position_max
    corners = np.array([[lo[0], lo[1], 0.0], [hi[0], lo[1], 0.0], [hi[0], hi[1], 0.0],
                        [lo[0], hi[1], 0.0]])
    points = _clean(world_to_show(corners), DECIMALS).tolist()
    return {"version": FORMAT_VERSION, "polygons": [{"isInclusion": True, "points": points}]}


def _cues(sequence: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """For a stitched formation sequence: one cue per formation, when the fleet is on it (the
    first at 0, or when the takeoff ends; each next one at the end of the leg that reaches
    it), and for a show on the ground `takeoff` at 0 and `landing` when it starts. None for a
    plain plan or a timeline it cannot read (the cues are a convenience, never a reason to
    refuse)."""
    if not sequence or not isinstance(sequence.get("timeline"), list):
        return None
    items: list[dict[str, Any]] = []
    reached = 0.0
    for segment in sequence["timeline"]:
        if not isinstance(segment, Mapping):
            return None
        kind, start, end = segment.get("kind"), segment.get("start_s"), segment.get("end_s")
        if not (isinstance(start, int | float) and isinstance(end, int | float)
                and math.isfinite(start) and math.isfinite(end)):
            return None
        if kind in ("takeoff", "landing"):
            items.append({"name": kind, "time": round(float(start), TIME_DECIMALS)})
            reached = float(end)
        if kind != "leg":
            continue
        source, target = segment.get("from"), segment.get("to")
        if not (isinstance(source, str) and isinstance(target, str)):
            return None
        if not any(item["name"] not in ("takeoff", "landing") for item in items):
            items.append({"name": source, "time": round(reached, TIME_DECIMALS)})
        items.append({"name": target, "time": round(float(end), TIME_DECIMALS)})
    return {"version": FORMAT_VERSION, "items": items} if items else None


def show_head(plan: Plan, *, title: str | None = None, show_id: str | None = None,
              origin: Geodetic | None = None) -> dict[str, Any]:
    """Everything of ``show.json`` but the drones: version, environment, settings, meta."""
    scenario = plan.scenario
    environment: dict[str, Any] = {"type": "outdoor"}
    if origin is not None:
        place = [round(origin.lat * 1e7), round(origin.lon * 1e7)]
        if math.isfinite(origin.alt):
            place.append(round(origin.alt * 1e3))
        environment["location"] = {"origin": place, "orientation": SHOW_ORIENTATION_DEG}
    settings: dict[str, Any] = {"geofence": _geofence(scenario),
                                "validation": _validation(scenario)}
    cues = _cues(plan.sequence)
    if cues is not None:
        settings["cues"] = cues
    horizon = round(_milliseconds(scenario.dt) * scenario.steps / 1000.0, TIME_DECIMALS)
    meta: dict[str, Any] = {"title": title or scenario.name, "segments": {"show": [0.0, horizon]}}
    if show_id is not None:
        meta["id"] = show_id
    return {"version": FORMAT_VERSION, "environment": environment, "settings": settings,
            "meta": meta}


def trajectory_points(p: FloatArray, v: FloatArray, a: FloatArray, dt: float
                      ) -> list[list[Any]]:
    """One vehicle's keyframes [t, point, controls] from its steps: p, v (K+1, 3) and a
    (K, 3) in the world frame. One cubic per step; consecutive steps whose four points are
    all the same (at rest) merge into one segment without control points."""
    ms = _milliseconds(dt)
    steps = len(a)
    times = np.round(np.arange(steps + 1) * ms) / 1000.0
    first = p[:-1] + (dt / 3.0) * v[:-1]
    second = p[:-1] + (2.0 * dt / 3.0) * v[:-1] + (dt * dt / 6.0) * a
    points = _clean(world_to_show(p), DECIMALS)
    c1 = _clean(world_to_show(first), DECIMALS)
    c2 = _clean(world_to_show(second), DECIMALS)
    rest = (np.all(points[:-1] == points[1:], axis=1) & np.all(c1 == points[1:], axis=1)
            & np.all(c2 == points[1:], axis=1))
    # Keyframe k + 1 ends step k; it is dropped when step k and step k + 1 are both at rest
    # (the constant segment goes on), kept at the end of the plan.
    keep = np.ones(steps, dtype=bool)
    keep[:-1] = ~(rest[:-1] & rest[1:])
    out: list[list[Any]] = [[0.0, points[0].tolist(), []]]
    t_list, p_list = times.tolist(), points.tolist()
    c1_list, c2_list = c1.tolist(), c2.tolist()
    for k in np.flatnonzero(keep).tolist():
        controls = [] if rest[k] else [c1_list[k], c2_list[k]]
        out.append([t_list[k + 1], p_list[k + 1], controls])
    return out


def _lights(plan: Plan, vid: str) -> dict[str, Any]:
    """The drone's light program (`gcs.export.lights`, in `gcs.export.lightcode`'s bytecode)
    as the file carries it: base64 in a versioned block."""
    changes = light_changes(plan, vid)
    if changes is None:
        return NO_LIGHTS
    program = encode(changes, plan.scenario.horizon)
    return {"version": FORMAT_VERSION, "data": base64.b64encode(program).decode("ascii")}


def flight_span(plan: Plan, index: int) -> tuple[int, int]:
    """The steps [first, end) the drone flies: for a show on the ground from the step it
    leaves the ground to the step it stands on it again (`planner.verification.ground`),
    measured on its trajectory; else the whole plan."""
    track = plan.vehicles[index]
    steps = plan.scenario.steps
    if not starts_on_the_ground(plan.sequence):
        return 0, steps
    flying = np.flatnonzero(airborne(track.position[None], track.velocity[None],
                                     track.acceleration[None])[0])
    if not len(flying):
        return 0, steps
    return int(flying[0]), int(flying[-1]) + 1


def _drone(plan: Plan, index: int) -> dict[str, Any]:
    """One drone of the swarm: its name, home (its start), trajectory and lights. A drone
    that takes off from the ground has its keyframes from lift-off (`takeoffTime`, s from the
    show's start) to touchdown; before it stands on its home, after it on its slot."""
    track = plan.vehicles[index]
    first, end = flight_span(plan, index)
    points = trajectory_points(track.position[first:end + 1], track.velocity[first:end + 1],
                               track.acceleration[first:end], plan.scenario.dt)
    takeoff = round(first * _milliseconds(plan.scenario.dt)) / 1000.0
    home = _clean(world_to_show(track.position[0]), DECIMALS).tolist()
    return {"type": "generic", "settings": {
        "name": track.id,
        "home": home,
        "trajectory": {"version": FORMAT_VERSION, "points": points, "takeoffTime": takeoff,
                       "landingHeight": points[-1][1][2]},
        "lights": _lights(plan, track.id),
    }}


class _Sink:
    """A write-only stream that keeps what is written until taken (no tell, no seek: the
    archive is then written with data descriptors, ready to send as it grows)."""

    def __init__(self) -> None:
        self._parts: list[bytes] = []

    def write(self, data: bytes, /) -> int:
        self._parts.append(bytes(data))
        return len(data)

    def flush(self) -> None:
        """Nothing is buffered here."""

    def close(self) -> None:
        """Nothing to release: what was written stays until taken."""

    def take(self) -> bytes:
        out = b"".join(self._parts)
        self._parts.clear()
        return out


def skyc_chunks(plan: Plan, *, title: str | None = None, show_id: str | None = None,
                origin: Geodetic | None = None) -> Iterator[bytes]:
    """The .skyc archive in pieces, one drone at a time (their concatenation is the file).
    The plan is checked here, before the first piece: `ExportError` naming the field."""
    check_exportable(plan)
    head = orjson.dumps(show_head(plan, title=title, show_id=show_id, origin=origin))
    return _pieces(plan, head)


def _pieces(plan: Plan, head: bytes) -> Iterator[bytes]:
    sink = _Sink()
    entry = zipfile.ZipInfo(SHOW_ENTRY, date_time=ZIP_DATE)
    entry.compress_type = zipfile.ZIP_DEFLATED
    entry.external_attr = 0o644 << 16
    large = keyframe_count(plan) * _KEYFRAME_BYTES_MAX >= zipfile.ZIP64_LIMIT
    with (zipfile.ZipFile(sink, "w") as archive,
          archive.open(entry, "w", force_zip64=large) as out):
        out.write(head[:-1] + b',"swarm":{"drones":[')
        for index in range(len(plan.vehicles)):
            out.write((b"," if index else b"") + orjson.dumps(_drone(plan, index)))
            if piece := sink.take():
                yield piece
        out.write(b"]}}")
    yield sink.take()


def write_skyc(plan: Plan, path: Path, *, title: str | None = None,
               origin: Geodetic | None = None) -> int:
    """Write the show to `path` whole or not at all (a temporary file beside it, renamed);
    returns its size in bytes. `ExportError` for a plan that cannot be a show, `OSError`
    when the file cannot be written."""
    chunks = skyc_chunks(plan, title=title, origin=origin)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part",
                                         dir=path.parent)
    size = 0
    try:
        with os.fdopen(handle, "wb") as out:
            for chunk in chunks:
                out.write(chunk)
                size += len(chunk)
        os.chmod(temporary, 0o644)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return size
