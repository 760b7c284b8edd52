"""A designed show file, whatever its kind: a Skybrush compiled show (`.skyc`, or a ZIP
holding show.json by another name) or Skybrush CSV (a folder or ZIP of per-drone files),
read as one `SkycShow` for `gcs.show.to_sequence`; the one place that tells the kinds apart
(`fleetplan import` and the service's import both read through it)."""

from __future__ import annotations

import zipfile
from pathlib import Path

from gcs.show.csv_reader import read_csv_show
from gcs.show.skyc_reader import SkycShow, read_skyc
from gcs.show.tracks import MAX_TOTAL_BYTES

__all__ = ["is_skyc", "read_design"]


def is_skyc(path: Path) -> bool:
    """A .skyc, or a ZIP archive holding show.json (a .skyc by another name), not CSVs."""
    if path.suffix.lower() == ".skyc":
        return True
    try:
        with zipfile.ZipFile(path) as archive:
            return "show.json" in archive.namelist()
    except (zipfile.BadZipFile, OSError):
        return False


def read_design(path: Path, *, unpacked: int = MAX_TOTAL_BYTES) -> SkycShow:
    """The show in `path` (a file or a folder), unpacking at most `unpacked` bytes; CSV
    shows have no validation limits and take their title from the file's stem.
    `ShowFileError` naming the file and the field otherwise."""
    if path.is_file() and is_skyc(path):
        return read_skyc(path, unpacked=min(unpacked, MAX_TOTAL_BYTES // 2))
    return SkycShow(title=path.stem, tracks=read_csv_show(path, unpacked=unpacked),
                    validation={})
