"""What a failed database write means for the user: a full disk, or storage that is
unavailable for now. One definition, used by the API's error answers (507 / 503) and by the
flight service's messages while it holds a flight it could not store yet."""

from __future__ import annotations

import errno

__all__ = ["is_disk_full", "storage_reason"]

#: How SQLite (SQLITE_FULL), PostgreSQL (53100 disk_full) and the OS word a full disk.
_FULL_TEXTS = ("database or disk is full", "disk is full", "no space left on device",
               "disk full", "could not extend file")


def is_disk_full(exc: BaseException) -> bool:
    """Whether `exc` (or what caused it) says the disk or the database file is full."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, OSError) and current.errno == errno.ENOSPC:
            return True
        if getattr(current, "sqlstate", None) == "53100" or getattr(
                getattr(current, "orig", None), "sqlstate", None) == "53100":
            return True
        if any(text in str(current).lower() for text in _FULL_TEXTS):
            return True
        current = current.__cause__ or current.__context__
    return False


def storage_reason(exc: BaseException) -> str:
    """One line for the user: "disk full: ..." or "storage unavailable: ...", with the
    database's own words (bounded in length)."""
    words = str(getattr(exc, "orig", None) or exc).strip()
    detail = words.splitlines()[0][:200] if words else type(exc).__name__
    if is_disk_full(exc):
        return f"disk full: the database cannot store this ({detail})"
    return f"storage unavailable: {type(exc).__name__}: {detail}"
