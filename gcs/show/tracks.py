"""A designed show as the readers give it: one track per drone (its motion as cubic Bezier
segments, its lights as `gcs.export.lightcode.Change`), and the errors and bounds every
reader shares.

A track's motion is the Bezier form Skybrush's shows use: keyframe times (K + 1,) and for
each segment its four points (K, 4, 3); a straight segment (a CSV's rows) is written as the
cubic of the same line. Positions are in the show frame, which is fleetplan's world frame
(`gcs.frames.world_to_show` is the identity).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import IO

import numpy as np

from gcs.export.lightcode import Change
from planner.types import FloatArray

__all__ = ["MAX_FILE_BYTES", "MAX_TOTAL_BYTES", "DesignTrack", "ShowFileError", "cubic_line",
           "positions_at", "read_bounded"]

#: Largest input file fleetplan reads (bytes): a 1,000-drone show is tens of megabytes.
MAX_FILE_BYTES = 1 << 30
#: Most bytes all of one archive's entries may unpack to (a ZIP bomb stops here).
MAX_TOTAL_BYTES = 2 << 30


class ShowFileError(ValueError):
    """A show file that cannot be imported: `file` (and `line`, when it is a text row),
    `field` (a column or a JSON path) and `reason`, which says how to fix it."""

    def __init__(self, file: str, field: str, reason: str, line: int | None = None) -> None:
        where = file if line is None else f"{file}, line {line}"
        super().__init__(f"{where}: {field}: {reason}")
        self.file = file
        self.line = line
        self.field = field
        self.reason = reason


@dataclass(frozen=True)
class DesignTrack:
    """One drone of a designed show."""

    name: str
    source: str
    """Where it was read from (a file, or a file and the drone's place in it)."""
    times: FloatArray
    """(K + 1,) keyframe times (s), non-decreasing."""
    curves: FloatArray
    """(K, 4, 3) each segment's cubic Bezier points (start, two controls, end); K >= 1 (a
    drone that never moves has one constant segment)."""
    lights: Sequence[Change] = field(default_factory=tuple)


def cubic_line(points: FloatArray) -> FloatArray:
    """The straight segments between consecutive `points` (M, 3) as cubics (M - 1, 4, 3)."""
    start, end = points[:-1], points[1:]
    step = (end - start) / 3.0
    return np.stack([start, start + step, end - step, end], axis=1)


def positions_at(track: DesignTrack, times: FloatArray) -> FloatArray:
    """Positions (M, 3) at `times`: before the first keyframe its point, after the last the
    last point, between two the Bezier segment that joins them."""
    t = np.asarray(times, dtype=float)
    index = np.clip(np.searchsorted(track.times, t, side="right") - 1, 0, len(track.curves) - 1)
    start, end = track.times[index], track.times[index + 1]
    span = np.where(end > start, end - start, 1.0)
    u = np.clip((t - start) / span, 0.0, 1.0)[:, None]
    p = track.curves[index]
    w = 1.0 - u
    return (w ** 3 * p[:, 0] + 3 * w * w * u * p[:, 1] + 3 * w * u * u * p[:, 2]
            + u ** 3 * p[:, 3])


def read_bounded(stream: IO[bytes], limit: int, file: str) -> bytes:
    """At most `limit` bytes of `stream`; `ShowFileError` when there are more (a header may
    understate what an entry unpacks to, so the bound is on what is read)."""
    data = stream.read(limit + 1)
    if len(data) > limit:
        raise ShowFileError(file, "size", f"unpacks to more than {limit >> 20} MiB, the most "
                                          f"fleetplan reads: split the show")
    return data
