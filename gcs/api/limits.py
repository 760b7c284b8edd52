"""Request body size limit, enforced before any route reads the body.

A body announced larger than the limit (Content-Length) is refused at once; a body without a
length (chunked) is read up to the limit and refused as soon as it goes over. Either way the
answer is 413 with the API's error body, naming the limit.
"""

from __future__ import annotations

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from gcs.api.errors import BadRequest, PayloadTooLarge, send_error

__all__ = ["BodyLimitMiddleware"]


class BodyLimitMiddleware:
    """Pure ASGI middleware: 413 for request bodies over `max_bytes`, or over the `larger`
    limit of a (method, path) that takes big documents (a plan to fly): (bytes, the setting
    that sets them)."""

    def __init__(self, app: ASGIApp, max_bytes: int,
                 larger: dict[tuple[str, str], tuple[int, str]] | None = None) -> None:
        self.app = app
        self.default_bytes = max_bytes
        self.larger = dict(larger or {})

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        route = (scope.get("method", ""), scope.get("path", "").rstrip("/"))
        max_bytes, setting = self.larger.get(route, (self.default_bytes, "max_body_bytes"))
        await _Limited(self.app, max_bytes, setting)(scope, receive, send)


class _Limited:
    """One request's body held to `max_bytes` (the setting `setting`)."""

    def __init__(self, app: ASGIApp, max_bytes: int, setting: str) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.setting = setting

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        headers = dict(scope.get("headers", []))
        length = headers.get(b"content-length")
        if length is not None:
            try:
                announced = int(length)
            except ValueError:
                await send_error(send, BadRequest("body", "Content-Length is not a number"))
                return
            if announced > self.max_bytes:
                await send_error(send, self._too_large(announced))
                return
            await self.app(scope, receive, send)
            return
        if scope.get("method") in ("GET", "HEAD", "DELETE", "OPTIONS"):
            await self.app(scope, receive, send)
            return
        # No length announced: buffer up to the limit, then replay to the app.
        chunks: list[bytes] = []
        size = 0
        while True:
            message = await receive()
            if message["type"] != "http.request":
                break
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > self.max_bytes:
                await send_error(send, self._too_large(None))
                return
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        replayed = False

        async def replay() -> Message:
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)

    def _too_large(self, announced: int | None) -> PayloadTooLarge:
        got = f" (got {announced} bytes)" if announced is not None else ""
        return PayloadTooLarge(
            "body", f"request body exceeds {self.max_bytes} bytes{got} (setting {self.setting})"
        )
