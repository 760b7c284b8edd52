"""Read a Skybrush compiled show (`.skyc`) as design tracks: each drone's keyframes (Bezier
segments, times from its `takeoffTime`) and its light program, plus the limits its
`settings.validation` states. The layout is the one `gcs.export.skyc` writes (its docstring
and docs/planning/show.md); a segment may have none, one or two control points."""

from __future__ import annotations

import base64
import binascii
import math
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import orjson

from gcs.export.lightcode import LightCodeError, decode
from gcs.show.tracks import (
    MAX_FILE_BYTES,
    MAX_TOTAL_BYTES,
    DesignTrack,
    ShowFileError,
    read_bounded,
)

__all__ = ["SkycShow", "read_skyc"]

_ENTRY = "show.json"


@dataclass(frozen=True)
class SkycShow:
    """What a .skyc says: its title, tracks and the limits of `settings.validation` (each
    None when absent): minimum distance (m), top altitude (m), horizontal and vertical speed
    (m/s) and acceleration (m/s^2)."""

    title: str
    tracks: tuple[DesignTrack, ...]
    validation: dict[str, float]


def read_skyc(path: Path, *, unpacked: int = MAX_TOTAL_BYTES // 2) -> SkycShow:
    """The show in `path`; `ShowFileError` naming the file and the field for anything a
    show tool would not have written (not a ZIP, no show.json, a drone without keyframes,
    a non-finite number, a light program that cannot be read, too large: its show.json
    unpacking to more than `unpacked` bytes)."""
    name = path.name
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise ShowFileError(name, "file", f"cannot read it: {exc.strerror or exc}") from None
    if size > MAX_FILE_BYTES:
        raise ShowFileError(name, "size", f"{size >> 20} MiB is more than the "
                                          f"{MAX_FILE_BYTES >> 20} MiB fleetplan reads")
    try:
        with zipfile.ZipFile(path) as archive:
            if _ENTRY not in archive.namelist():
                raise ShowFileError(name, _ENTRY, "the archive has no show.json: is it a "
                                                  "Skybrush compiled show?")
            with archive.open(_ENTRY) as entry:
                data = read_bounded(entry, unpacked, f"{name}:{_ENTRY}")
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError) as exc:
        raise ShowFileError(name, "file", f"not a readable ZIP archive ({exc}): a .skyc is "
                                          f"a ZIP holding show.json") from None
    try:
        show = orjson.loads(data)
    except orjson.JSONDecodeError as exc:
        raise ShowFileError(f"{name}:{_ENTRY}", "JSON", f"not valid JSON ({exc})",
                            line=getattr(exc, "lineno", None)) from None
    return _show(show, f"{name}:{_ENTRY}", path.stem)


def _get(value: Any, key: str, where: str, file: str, kind: type | tuple[type, ...]) -> Any:
    if not isinstance(value, Mapping) or not isinstance(value.get(key), kind):
        what = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
        raise ShowFileError(file, f"{where}.{key}" if where else key,
                            f"is missing or not a {what.replace('dict', 'JSON object')}")
    return value[key]


def _object(value: Any) -> Mapping[str, Any]:
    """An optional JSON object: itself, or empty when absent or not an object."""
    return value if isinstance(value, Mapping) else {}


def _show(show: Any, file: str, stem: str) -> SkycShow:
    swarm = _get(show, "swarm", "", file, dict)
    drones = _get(swarm, "drones", "swarm", file, list)
    if not drones:
        raise ShowFileError(file, "swarm.drones", "the show has no drones")
    meta = _object(show.get("meta"))
    title = meta.get("title") if isinstance(meta.get("title"), str) else stem
    validation = _object(_object(show.get("settings")).get("validation"))
    limits = {key: float(value) for key, value in validation.items()
              if isinstance(value, int | float) and math.isfinite(value) and value > 0}
    tracks = tuple(_track(drone, f"swarm.drones[{i}]", file) for i, drone in enumerate(drones))
    names = [t.name for t in tracks]
    if len(set(names)) != len(names):
        twice = next(n for n in names if names.count(n) > 1)
        raise ShowFileError(file, "swarm.drones", f"two drones are named {twice!r}: rename "
                                                  f"one in the show tool")
    return SkycShow(title=title or stem, tracks=tracks, validation=limits)


def _track(drone: Any, where: str, file: str) -> DesignTrack:
    settings = _get(drone, "settings", where, file, dict)
    where = f"{where}.settings"
    name = settings.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ShowFileError(file, f"{where}.name", "every drone needs a name")
    trajectory = _get(settings, "trajectory", where, file, dict)
    points = _get(trajectory, "points", f"{where}.trajectory", file, list)
    offset = trajectory.get("takeoffTime", 0.0)
    if not isinstance(offset, int | float) or not math.isfinite(offset):
        raise ShowFileError(file, f"{where}.trajectory.takeoffTime",
                            f"drone {name!r}: must be a finite number of seconds")
    if not points:
        raise ShowFileError(file, f"{where}.trajectory.points",
                            f"drone {name!r} has no keyframes: give it at least one")
    fast = _curves_fast(points)
    times, curves = fast if fast is not None else _curves(points, f"{where}.trajectory.points",
                                                           file, name)
    lights = settings.get("lights")
    changes = _lights(lights, f"{where}.lights", file, name, float(times[-1] + offset))
    return DesignTrack(name=name, source=f"{file} ({name})", times=times + float(offset),
                       curves=curves, lights=changes)


def _curves_fast(points: Sequence[Any]) -> tuple[np.ndarray, np.ndarray] | None:
    """`_curves` in a few array conversions, for a well-formed drone (1,000 drones of a few
    hundred keyframes each in well under a second); None at the first doubt, for `_curves`
    to say what is wrong."""
    try:
        if not all(isinstance(point, list) and len(point) == 3 for point in points):
            return None
        times = np.array([point[0] for point in points], dtype=float)
        ends = np.array([point[1] for point in points], dtype=float)
        counts = np.array([len(point[2]) for point in points])
        pairs = np.flatnonzero(counts == 2)
        ones = np.flatnonzero(counts == 1)
        two = np.array([points[k][2] for k in pairs.tolist()], dtype=float).reshape(-1, 2, 3)
        one = np.array([points[k][2] for k in ones.tolist()], dtype=float).reshape(-1, 1, 3)
    except (TypeError, ValueError, IndexError):
        return None
    count = len(points)
    if (times.shape != (count,) or ends.shape != (count, 3) or counts.max() > 2
            or counts[0] != 0 or count < 2 or not np.isfinite(times).all()
            or not np.isfinite(ends).all() or not np.isfinite(two).all()
            or not np.isfinite(one).all() or (np.diff(times) < 0).any()):
        return None
    start, end = ends[:-1], ends[1:]
    step = (end - start) / 3.0
    curves = np.stack([start, start + step, end - step, end], axis=1)
    curves[pairs - 1, 1:3] = two
    first = ones - 1
    curves[first, 1] = start[first] + 2.0 / 3.0 * (one[:, 0] - start[first])
    curves[first, 2] = end[first] + 2.0 / 3.0 * (one[:, 0] - end[first])
    return times, curves


def _curves(points: Sequence[Any], where: str, file: str, name: str
            ) -> tuple[np.ndarray, np.ndarray]:
    """Keyframe times and cubic segments of one drone's `points`, checked keyframe by
    keyframe (`ShowFileError` naming the first bad one)."""
    count = len(points)
    times = np.empty(count)
    ends = np.empty((count, 3))
    controls: list[Any] = []
    for k, point in enumerate(points):
        if (not isinstance(point, Sequence) or len(point) not in (2, 3)
                or not isinstance(point[1], Sequence) or len(point[1]) != 3):
            raise ShowFileError(file, f"{where}[{k}]", f"drone {name!r}: a keyframe is "
                                                       f"[t, [x, y, z], [control points]]")
        try:
            times[k] = point[0]
            ends[k] = point[1]
        except (TypeError, ValueError):
            raise ShowFileError(file, f"{where}[{k}]", f"drone {name!r}: t, x, y, z must "
                                                       f"be numbers") from None
        controls.append(point[2] if len(point) == 3 else [])
    if not (np.isfinite(times).all() and np.isfinite(ends).all()):
        k = int(np.flatnonzero(~(np.isfinite(times) & np.isfinite(ends).all(axis=1)))[0])
        raise ShowFileError(file, f"{where}[{k}]", f"drone {name!r}: not a finite number")
    backwards = np.flatnonzero(np.diff(times) < 0)
    if len(backwards):
        k = int(backwards[0]) + 1
        raise ShowFileError(file, f"{where}[{k}][0]", f"drone {name!r}: time {times[k]:g} s "
                                                      f"is before the keyframe before it")
    if count == 1:
        return np.array([times[0], times[0]]), np.repeat(ends[:1, None, :], 4, axis=1)
    curves = np.empty((count - 1, 4, 3))
    start, end = ends[:-1], ends[1:]
    curves[:, 0], curves[:, 3] = start, end
    straight = np.ones(count - 1, dtype=bool)
    for k in range(1, count):
        given = controls[k]
        if not given:
            continue
        try:
            c = np.array(given, dtype=float)
        except (TypeError, ValueError):
            raise ShowFileError(file, f"{where}[{k}][2]", f"drone {name!r}: control points "
                                                          f"must be [x, y, z]") from None
        if c.ndim != 2 or c.shape[1] != 3 or len(c) > 2 or not np.isfinite(c).all():
            raise ShowFileError(file, f"{where}[{k}][2]", f"drone {name!r}: one or two "
                                                          f"finite control points [x, y, z]")
        straight[k - 1] = False
        if len(c) == 1:  # a quadratic, raised to the cubic of the same curve
            curves[k - 1, 1] = start[k - 1] + 2.0 / 3.0 * (c[0] - start[k - 1])
            curves[k - 1, 2] = end[k - 1] + 2.0 / 3.0 * (c[0] - end[k - 1])
        else:
            curves[k - 1, 1:3] = c
    step = (end - start) / 3.0
    curves[straight, 1] = (start + step)[straight]
    curves[straight, 2] = (end - step)[straight]
    return times, curves


def _lights(lights: Any, where: str, file: str, name: str, until: float) -> tuple[Any, ...]:
    if lights is None:
        return ()
    data = lights.get("data") if isinstance(lights, Mapping) else None
    if not isinstance(data, str):
        raise ShowFileError(file, f"{where}.data", f"drone {name!r}: the light program must "
                                                   f"be base64 text")
    try:
        program = base64.b64decode(data, validate=True)
    except (binascii.Error, ValueError):
        raise ShowFileError(file, f"{where}.data", f"drone {name!r}: not base64") from None
    try:
        return tuple(decode(program, until=until))
    except LightCodeError as exc:
        raise ShowFileError(file, f"{where}.data", f"drone {name!r}: light program, byte "
                                                   f"{exc.offset}: {exc.reason}") from None
