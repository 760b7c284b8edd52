"""Read Skybrush's per-drone CSV (what Skybrush Studio for Blender exports and imports as
"Skybrush CSV"): a folder or a ZIP archive of files, one per drone, named after it
(`<name>.csv`). Each file has a header `Time [msec],x [m],y [m],z [m],Red,Green,Blue` (Studio
also reads files without one, or with a `Time_msec` header) and one row per sample: time in
milliseconds, position in metres, colour as integers 0..255; without the colour columns the
drone is white. A drone moves in a straight line between rows, and shows each row's colour
until the next row (Studio's own reading)."""

from __future__ import annotations

import io
import math
import zipfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from gcs.export.lightcode import Change
from gcs.show.tracks import (
    MAX_FILE_BYTES,
    MAX_TOTAL_BYTES,
    DesignTrack,
    ShowFileError,
    cubic_line,
    read_bounded,
)
from planner.model.scenario import MAX_VEHICLES

__all__ = ["COLUMNS", "read_csv_show"]

#: The columns of a Skybrush CSV file, in order (the header Studio writes).
COLUMNS = ("Time [msec]", "x [m]", "y [m]", "z [m]", "Red", "Green", "Blue")
_WHITE = (255, 255, 255)


def _files(path: Path, unpacked: int) -> Iterator[tuple[str, bytes]]:
    """(file name, contents) of every .csv in the folder or ZIP archive, by name, at most
    `unpacked` bytes in all."""
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".csv" and p.is_file())
        if len(files) > MAX_VEHICLES:
            raise ShowFileError(path.name, "files", f"{len(files)} CSV files, more than the "
                                                    f"{MAX_VEHICLES} drones a plan may hold")
        total = 0
        for file in files:
            size = file.stat().st_size
            total += size
            if size > MAX_FILE_BYTES or total > unpacked:
                raise ShowFileError(file.name, "size", "more data than fleetplan reads in "
                                                       "one show: split the show")
            yield file.name, file.read_bytes()
        return
    try:
        if path.stat().st_size > MAX_FILE_BYTES:
            raise ShowFileError(path.name, "size", f"more than the {MAX_FILE_BYTES >> 20} MiB "
                                                   f"fleetplan reads")
        with zipfile.ZipFile(path) as archive:
            entries = sorted((e for e in archive.infolist()
                              if not e.is_dir() and e.filename.lower().endswith(".csv")
                              and not e.filename.startswith("__MACOSX/")),
                             key=lambda e: e.filename)
            if len(entries) > MAX_VEHICLES:
                raise ShowFileError(path.name, "files", f"{len(entries)} CSV files, more than "
                                                        f"the {MAX_VEHICLES} drones a plan "
                                                        f"may hold")
            left = unpacked
            for entry in entries:
                with archive.open(entry) as stream:
                    data = read_bounded(stream, left, f"{path.name}:{entry.filename}")
                left -= len(data)
                yield f"{path.name}:{entry.filename}", data
    except zipfile.BadZipFile as exc:
        raise ShowFileError(path.name, "file", f"neither a folder nor a readable ZIP archive "
                                               f"({exc}): give a .skyc, or Skybrush CSV as a "
                                               f"folder or .zip of per-drone files") from None
    except OSError as exc:
        raise ShowFileError(path.name, "file", f"cannot read it: {exc.strerror or exc}"
                            ) from None


def read_csv_show(path: Path, *, unpacked: int = MAX_TOTAL_BYTES) -> tuple[DesignTrack, ...]:
    """One track per CSV file of the folder or archive (at most `unpacked` bytes of CSV in
    all); `ShowFileError` naming the file, the line and the column of the first bad value."""
    tracks = [_track(name, data) for name, data in _files(path, unpacked)]
    if not tracks:
        raise ShowFileError(path.name, "files", "no .csv files: export the show from Skybrush "
                                                "Studio as Skybrush CSV (one file per drone)")
    return tuple(tracks)


def _is_header(line: str) -> bool:
    first = line.split(",", 1)[0].strip()
    try:
        float(first)
    except ValueError:
        return True
    return False


def _track(file: str, data: bytes) -> DesignTrack:
    name = Path(file.rsplit(":", 1)[-1]).stem
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ShowFileError(file, "encoding", f"not UTF-8 text (byte {exc.start})") from None
    lines = text.splitlines()
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    if first is None:
        raise ShowFileError(file, "rows", f"drone {name!r} has no rows: give it at least one "
                                          f"sample (time, x, y, z)")
    header = _is_header(lines[first])
    if header:
        columns = [c.strip() for c in lines[first].split(",")]
        if len(columns) not in (4, 7):
            raise ShowFileError(file, "header", f"has {len(columns)} columns; a Skybrush CSV "
                                                f"has {', '.join(COLUMNS)} (or the first "
                                                f"four)", line=first + 1)
    start = first + 1 if header else first
    rows = [(i + 1, line) for i, line in enumerate(lines[start:], start) if line.strip()]
    if not rows:
        raise ShowFileError(file, "rows", f"drone {name!r} has no rows: give it at least one "
                                          f"sample (time, x, y, z)")
    values = _numbers(file, rows)
    times = values[:, 0] / 1000.0
    backwards = np.flatnonzero(np.diff(times) <= 0)
    if len(backwards):
        line = rows[int(backwards[0]) + 1][0]
        raise ShowFileError(file, COLUMNS[0], "times must increase from row to row", line=line)
    points = values[:, 1:4]
    if len(points) == 1:
        times = np.array([times[0], times[0]])
        points = np.repeat(points, 2, axis=0)
    if values.shape[1] == 7:
        colors = values[:, 4:7].astype(int).tolist()
        lights = [Change(float(t), float(t), (c[0], c[1], c[2]))
                  for t, c in zip(values[:, 0] / 1000.0, colors, strict=True)]
    else:
        lights = [Change(float(times[0]), float(times[0]), _WHITE)]
    return DesignTrack(name=name, source=file, times=times, curves=cubic_line(points),
                       lights=_merged(lights))


def _merged(changes: list[Change]) -> tuple[Change, ...]:
    """The changes without repeats of the colour already shown."""
    out: list[Change] = []
    for change in changes:
        if not out or change.color != out[-1].color:
            out.append(change)
    return tuple(out)


def _numbers(file: str, rows: list[tuple[int, str]]) -> np.ndarray:
    """The rows as an (M, 4 or 7) array; the first bad value named by line and column."""
    width = len(rows[0][1].split(","))
    try:
        values = np.loadtxt(io.StringIO("\n".join(line for _, line in rows)), delimiter=",",
                            ndmin=2, dtype=float)
    except ValueError:
        values = None
    if values is not None and values.shape[1] == width and width in (4, 7):
        bad = ~np.isfinite(values)
        if width == 7:
            rgb = values[:, 4:]
            bad[:, 4:] |= (rgb < 0) | (rgb > 255) | (rgb != np.round(rgb))
        if not bad.any():
            return values
    # the slow path, only to say where the file is wrong
    needed = ", ".join(COLUMNS[:width if width in (4, 7) else 7])
    for line, text in rows:
        cells = [c.strip() for c in text.split(",")]
        if len(cells) not in (4, 7) or len(cells) != width:
            raise ShowFileError(file, "row", f"has {len(cells)} values; every row needs "
                                             f"{needed}", line=line)
        for column, cell in zip(COLUMNS, cells, strict=False):
            try:
                value = float(cell)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise ShowFileError(file, column, f"{cell[:20]!r} is not a finite number",
                                    line=line)
            if column in COLUMNS[4:] and not (0 <= value <= 255 and value == round(value)):
                raise ShowFileError(file, column, f"{cell[:20]!r}: a colour channel is an "
                                                  f"integer 0..255", line=line)
    raise ShowFileError(file, "rows", "cannot be read as numbers")  # pragma: no cover
