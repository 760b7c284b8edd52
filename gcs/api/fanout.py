"""Bounds on the requests that fan out: trajectory exports at once, and event streams in
total and per resource. Past a bound a request answers 503 with Retry-After at once and
costs nothing more; an event sent to many streams is serialised once.
"""

from __future__ import annotations

import json
import threading
from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from fastapi.encoders import jsonable_encoder

from gcs.errors import ServiceBusy
from gcs.service.plan_worker import finite_json

__all__ = ["SharedJson", "Slots", "StreamSlots"]

#: Seconds a client is told to wait before retrying a refused export or stream.
RETRY_AFTER_S = 2.0


class Slots:
    """At most `limit` holders at once (thread-safe: exports run in worker threads)."""

    def __init__(self, limit: int, setting: str, what: str) -> None:
        self.limit = limit
        self.setting = setting
        self.what = what
        self.held = 0
        self._lock = threading.Lock()

    @contextmanager
    def hold(self) -> Iterator[None]:
        """One slot for the duration of the block; ServiceBusy (503) when all are held."""
        with self._lock:
            if self.held >= self.limit:
                raise ServiceBusy(self.setting, f"{self.limit} {self.what} already running "
                                  f"(setting {self.setting}); retry later",
                                  retry_after_s=RETRY_AFTER_S)
            self.held += 1
        try:
            yield
        finally:
            with self._lock:
                self.held -= 1


class StreamSlots:
    """Event streams: at most `total` open, and `per_resource` on one mission or flight."""

    def __init__(self, total: int, per_resource: int) -> None:
        self.total = total
        self.per_resource = per_resource
        self.open: dict[str, int] = {}
        self._lock = threading.Lock()

    @contextmanager
    def hold(self, resource: str) -> Iterator[None]:
        """One stream on `resource` for the duration of the block; ServiceBusy (503) past
        either bound."""
        with self._lock:
            if sum(self.open.values()) >= self.total:
                raise ServiceBusy("max_event_streams", f"{self.total} event streams already "
                                  f"open (setting max_event_streams); retry later",
                                  retry_after_s=RETRY_AFTER_S)
            if self.open.get(resource, 0) >= self.per_resource:
                raise ServiceBusy("max_event_streams_per_resource",
                                  f"{self.per_resource} event streams already open on "
                                  f"{resource} (setting max_event_streams_per_resource); "
                                  f"retry later", retry_after_s=RETRY_AFTER_S)
            self.open[resource] = self.open.get(resource, 0) + 1
        try:
            yield
        finally:
            with self._lock:
                self.open[resource] -= 1
                if not self.open[resource]:
                    del self.open[resource]


class SharedJson:
    """The JSON text of an event's data, computed once for every stream that sends the same
    object (a broadcast hands one object to all its followers)."""

    def __init__(self, size: int = 256) -> None:
        self._size = size
        self._texts: OrderedDict[int, tuple[Any, str]] = OrderedDict()

    def text(self, data: Any) -> str:
        """`data` as JSON (non-finite numbers as null, never NaN or Infinity)."""
        key = id(data)
        cached = self._texts.get(key)
        if cached is not None and cached[0] is data:
            return cached[1]
        text = json.dumps(finite_json(jsonable_encoder(data)), allow_nan=False)
        self._texts[key] = (data, text)  # the object is kept, so its id is not reused
        while len(self._texts) > self._size:
            self._texts.popitem(last=False)
        return text

