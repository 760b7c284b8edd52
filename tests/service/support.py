"""Helpers of the service tests."""

from __future__ import annotations

from typing import Any

from sqlalchemy import event

from gcs.service.store import Store

__all__ = ["fill_the_disk"]


def fill_the_disk(store: Store) -> None:
    """Make the SQLite file unable to grow (SQLITE_FULL), as a full disk would."""

    def cap(connection: Any, _record: Any) -> None:
        cursor = connection.cursor()
        pages = cursor.execute("PRAGMA page_count").fetchone()[0]
        cursor.execute(f"PRAGMA max_page_count={pages}")
        cursor.close()

    event.listen(store.engine, "connect", cap)
    store.engine.dispose()
