"""A designed show's hold points as a formation sequence (the `planner.methods.sequence`
JSON), with its colours, for the planner to plan the transitions between them.

A hold point is a stretch of the show where every drone is at rest (each drone's segments
there start and end at one point, controls included, within `REST_TOLERANCE_M`). The show's
start and end, and every hold point at least `min_hold` long in between, become formations:
each drone's position there, its colour there (one colour per position, or one for all when
they agree), the hold's length as `hold`, and the time from the hold before as the leg's
`duration` (both rounded to whole steps of `dt`). How the lights change on a leg is read from
its middle: the mean of the two colours (`fade`), the colour before (`hold`) or black
(`black`), whichever is nearest. The design's moves between hold points are not kept: the
planner plans them. Given `times`, formations are taken at those times instead (no holds).
A show whose first hold point has every drone on the ground (z <= `GROUND_HEIGHT_M`) starts
with a `takeoff` from those homes; when its last one does too, it ends with a `landing` on
those slots (`planner.methods.ground`); the formations are the hold points in the air.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gcs.export.lightcode import colors_at
from gcs.show.tracks import DesignTrack, ShowFileError, positions_at
from planner.errors import ScenarioError
from planner.methods.lights import color_hex
from planner.methods.sequence import parse_sequence
from planner.model.scenario import AUTO_STEPS, check_id
from planner.types import FloatArray

__all__ = ["DEFAULT_DT", "DEFAULT_LIMIT", "ImportOptions", "to_sequence"]

#: How far a drone may move inside a segment that still counts as at rest (m).
REST_TOLERANCE_M = 1e-4
#: The step of an imported sequence unless asked otherwise (s): Skybrush times in ms.
DEFAULT_DT = 0.2
#: Speed (m/s) and acceleration (m/s^2) bound per axis when the show states none.
DEFAULT_LIMIT = 3.0
#: Room around the show's points in the workspace box (m).
MARGIN_M = 2.0
#: The transitions a leg's middle is compared with, the first preferred on a tie.
_HOW = ("fade", "hold", "black")


@dataclass(frozen=True)
class ImportOptions:
    """How a show becomes a sequence (the `fleetplan import` options)."""

    dt: float = DEFAULT_DT
    min_separation: float | None = None
    """R; None: the show's `minDistance`, else 1 m."""
    times: tuple[float, ...] | None = None
    """Formations at these times (s) instead of the hold points."""
    min_hold: float = 0.5
    """Shortest stretch at rest that counts as a hold point (s)."""
    auto_durations: bool = False
    """Let the planner choose every leg's duration instead of keeping the design's."""
    assignment: str = "fixed"
    velocity_max: float | None = None
    acceleration_max: float | None = None


def _rest_intervals(track: DesignTrack) -> list[tuple[float, float]]:
    """The drone's stretches at rest, merged, including before its first keyframe and after
    its last (-inf, +inf ends)."""
    spread = np.abs(track.curves - track.curves[:, :1]).max(axis=(1, 2))
    rest = spread <= REST_TOLERANCE_M
    out: list[tuple[float, float]] = [(-math.inf, float(track.times[0]))]
    for k in np.flatnonzero(rest).tolist():
        start, end = float(track.times[k]), float(track.times[k + 1])
        if start <= out[-1][1] + 1e-9:
            out[-1] = (out[-1][0], max(out[-1][1], end))
        else:
            out.append((start, end))
    last = float(track.times[-1])
    if last <= out[-1][1] + 1e-9:
        out[-1] = (out[-1][0], math.inf)
    else:
        out.append((last, math.inf))
    return out


def _intersect(a: list[tuple[float, float]], b: list[tuple[float, float]]
               ) -> list[tuple[float, float]]:
    out, i, j = [], 0, 0
    while i < len(a) and j < len(b):
        low, high = max(a[i][0], b[j][0]), min(a[i][1], b[j][1])
        if low <= high:
            out.append((low, high))
        if a[i][1] < b[j][1]:
            i += 1
        else:
            j += 1
    return out


def _holds(tracks: Sequence[DesignTrack], options: ImportOptions, start: float, end: float
           ) -> list[tuple[float, float]]:
    """(from, to) of every formation: the start, the long enough holds, the end."""
    if options.times is not None:
        return [(t, t) for t in options.times]
    common = _rest_intervals(tracks[0])
    for track in tracks[1:]:
        common = _intersect(common, _rest_intervals(track))
    clipped = [(max(a, start), min(b, end)) for a, b in common if b >= start and a <= end]
    holds = [h for h in clipped if h[1] - h[0] >= options.min_hold - 1e-9
             or h[0] <= start or h[1] >= end]
    if not holds or holds[0][0] > start:
        holds.insert(0, (start, start))
    if holds[-1][1] < end:
        holds.append((end, end))
    return holds


#: A drone at most this high (m) at a hold point is on the ground.
GROUND_HEIGHT_M = 0.05


def _on_ground(tracks: Sequence[DesignTrack], hold: tuple[float, float]
               ) -> list[list[float]] | None:
    """Every drone's [x, y] at the hold point when all of them stand on the ground there."""
    at = 0.5 * (hold[0] + hold[1]) if math.isfinite(hold[1] - hold[0]) else hold[0]
    points = np.array([positions_at(t, np.array([at]))[0] for t in tracks])
    if np.abs(points[:, 2]).max() > GROUND_HEIGHT_M:
        return None
    grid: list[list[float]] = np.round(points[:, :2], 6).tolist()
    return grid


def _check_times(times: Sequence[float], start: float, end: float, file: str) -> None:
    for t in times:
        if not (math.isfinite(t) and start <= t <= end):
            raise ShowFileError(file, "--times", f"{t:g} s is outside the show ({start:g} to "
                                                 f"{end:g} s)")
    if list(times) != sorted(set(times)) or len(times) < 2:
        raise ShowFileError(file, "--times", "give at least two increasing times")


def _colors(tracks: Sequence[DesignTrack], t: float) -> np.ndarray:
    """Each drone's colour at `t` (N, 3), 0..255."""
    return np.array([colors_at(track.lights, np.array([t]))[0] for track in tracks])


def _color_value(colors: np.ndarray) -> Any:
    """One "#rrggbb" when every drone shows it, else one per position."""
    rounded = np.clip(np.rint(colors), 0, 255).astype(np.uint8)
    if (rounded == rounded[0]).all():
        return color_hex(rounded[0])
    return [color_hex(c) for c in rounded]


def _how(before: np.ndarray, middle: np.ndarray, after: np.ndarray) -> str:
    """Which transition the design's middle of a leg looks most like."""
    guesses = {"fade": 0.5 * (before + after), "hold": before, "black": np.zeros_like(before)}
    errors = {how: float(np.abs(middle - guess).sum()) for how, guess in guesses.items()}
    return min(_HOW, key=lambda how: errors[how] - (1e-6 if how == "fade" else 0.0))


def _limits(points: FloatArray, validation: dict[str, float], options: ImportOptions
            ) -> dict[str, Any]:
    low = points.min(axis=0) - MARGIN_M
    high = points.max(axis=0) + MARGIN_M
    low[2] = min(0.0, float(points[:, 2].min()))
    if "maxAltitude" in validation:
        high[2] = max(high[2], validation["maxAltitude"])
    speed_xy = validation.get("maxVelocityXY")
    accel_xy = validation.get("maxAccelerationXY")
    v = options.velocity_max
    a = options.acceleration_max
    velocity = ([v] * 3 if v is not None else
                [speed_xy / math.sqrt(2.0)] * 2 + [validation.get("maxVelocityZ", speed_xy)]
                if speed_xy else [DEFAULT_LIMIT] * 3)
    acceleration = ([a] * 3 if a is not None else
                    [accel_xy / math.sqrt(2.0)] * 2
                    + [validation.get("maxAccelerationZ", accel_xy)]
                    if accel_xy else [DEFAULT_LIMIT] * 3)
    return {"position_min": np.round(low, 3).tolist(), "position_max": np.round(high, 3).tolist(),
            "velocity_max": [_mm(x) for x in velocity],
            "acceleration_max": [_mm(x) for x in acceleration]}


def _mm(x: float) -> float:
    """Rounded down to the mm (the export rounds its limits up to the mm; this undoes it)."""
    return math.floor(x * 1000.0 + 1e-6) / 1000.0


def to_sequence(tracks: Sequence[DesignTrack], *, name: str, file: str,
                options: ImportOptions | None = None,
                validation: dict[str, float] | None = None) -> dict[str, Any]:
    """The sequence JSON of the show's hold points, checked by the sequence parser; errors
    as `ShowFileError` naming the file and what to change."""
    options = options or ImportOptions()
    validation = validation or {}
    for track in tracks:
        try:
            check_id(track.name, "name")
        except ScenarioError as exc:
            raise ShowFileError(track.source, "drone name", f"{track.name[:30]!r} cannot be a "
                                                            f"vehicle id: {exc.reason}") from None
    start = min(float(t.times[0]) for t in tracks)
    end = max(float(t.times[-1]) for t in tracks)
    if options.times is not None:
        _check_times(options.times, start, end, file)
    holds = _holds(tracks, options, start, end)
    ground = {"takeoff": _on_ground(tracks, holds[0]), "landing": _on_ground(tracks, holds[-1])}
    if ground["takeoff"] is None:
        ground["landing"] = None  # a show that lands on the ground took off from it
    holds = holds[1 if ground["takeoff"] is not None else 0:
                  -1 if ground["landing"] is not None else None]
    if len(holds) < 2:
        raise ShowFileError(file, "hold points", "the show has one hold point only: give "
                                                 "formation times with --times")
    dt = options.dt
    step = [(round((a - start) / dt), round((b - start) / dt)) for a, b in holds]
    formations: list[dict[str, Any]] = []
    every: list[FloatArray] = []
    previous_colors: np.ndarray | None = None
    has_lights = any(t.lights for t in tracks)
    for f, ((a, b), (first, last)) in enumerate(zip(holds, step, strict=True)):
        at = 0.5 * (a + b)
        positions = np.array([positions_at(t, np.array([at]))[0] for t in tracks])
        every.append(positions)
        entry: dict[str, Any] = {"name": f"F{f}@{a:g}s",
                                 "positions": np.round(positions, 6).tolist()}
        if f:
            steps = first - step[f - 1][1]
            if steps < 1:
                raise ShowFileError(file, f"hold point at {a:g} s",
                                    f"less than one step (dt {dt:g} s) after the one before: "
                                    f"give a smaller --dt or other --times")
            entry["duration"] = AUTO_STEPS if options.auto_durations else round(steps * dt, 6)
        if last > first:
            entry["hold"] = round((last - first) * dt, 6)
        if has_lights:
            colors = _colors(tracks, at)
            entry["color"] = _color_value(colors)
            if previous_colors is not None:
                middle = _colors(tracks, 0.5 * (holds[f - 1][1] + a))
                entry["lights"] = _how(previous_colors, middle, colors)
            previous_colors = colors
        formations.append(entry)
    separation = options.min_separation or validation.get("minDistance") or 1.0
    sequence: dict[str, Any] = {
        "name": name, "dt": dt, "min_separation": separation,
        "limits": _limits(np.concatenate(every), validation, options),
        "assignment": options.assignment,
        "vehicles": [t.name for t in tracks],
        "formations": formations,
    }
    if ground["takeoff"] is not None:
        sequence["takeoff"] = {"homes": ground["takeoff"]}
        sequence["landing"] = ({} if ground["landing"] is None
                               else {"homes": ground["landing"]})
    try:
        parse_sequence(sequence)
    except ScenarioError as exc:
        raise ShowFileError(file, exc.field, f"{exc.reason}{_where(exc.field, holds, tracks)} "
                                             f"(as imported: change the show, or "
                                             f"--min-separation, --dt, --times, "
                                             f"--auto-durations)") from None
    return sequence


def _where(field: str, holds: Sequence[tuple[float, float]], tracks: Sequence[DesignTrack]
           ) -> str:
    """What a sequence field is in the show: the hold point's time, the drone's name."""
    match = re.match(r"formations\[(\d+)\](?:\.positions\[(\d+)\])?", field)
    if match is None:
        return ""
    f = int(match.group(1))
    out = f"; formation {f} is the hold point at {holds[f][0]:g} s" if f < len(holds) else ""
    if match.group(2) is not None and int(match.group(2)) < len(tracks):
        out += f", position {match.group(2)} is drone {tracks[int(match.group(2))].name!r}"
    return out
