"""The API's error responses: one hierarchy, one JSON body shape.

Every error the API answers with has the body ``{"status": <code>, "field": <dotted path or
null>, "reason": <text>, "errors": [{"field", "reason"}, ...]}``: `field` and `reason` name the
first (usually only) problem; `errors` lists all of them (request validation may find several).

The service raises domain errors (`gcs.errors.RequestError` subclasses) and the planner
`FieldError`s; `REQUEST_ERROR_STATUS` below is the one place they become HTTP statuses (404
not found, 409 wrong state, 422 invalid, 503 busy; any other `FieldError` 422). Transport-level
problems that only exist in HTTP are `ApiError`s raised by the middleware:

- `ApiError`: carries the HTTP status, the field and the reason.
  - `BadRequest` (400): the request is malformed (e.g. the body is not JSON, a foreign Host).
  - `Unauthorized` (401): no or a wrong API token where one is required.
  - `Forbidden` (403): a cross-site request (foreign Origin), or a role that may not do this.
  - `PayloadTooLarge` (413): the body exceeds the configured size limit.
  - `UnsupportedMediaType` (415): a body that is not declared as JSON.
  - `Unprocessable` (422): invalid input, with every problem found listed in `errors`.

Request validation (query and path parameters, pydantic bodies) is reported with every error
at once, in pydantic's own words, under the offending parameter's name.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field
from sqlalchemy.exc import SQLAlchemyError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match, Mount
from starlette.types import Send

from gcs.errors import (
    InvalidRequest,
    NotFound,
    RequestError,
    ServiceBusy,
    StateConflict,
    VehicleLoopStopped,
    field_path,
    vehicle_at,
)
from gcs.service.storage_faults import is_disk_full, storage_reason
from planner.errors import FieldError

__all__ = [
    "FALLBACK",
    "REQUEST_ERROR_STATUS",
    "ApiError",
    "BadRequest",
    "ErrorBody",
    "ErrorItem",
    "Forbidden",
    "PayloadTooLarge",
    "Unauthorized",
    "Unprocessable",
    "UnsupportedMediaType",
    "allowed_methods",
    "error_responses",
    "install_error_handlers",
    "send_error",
]

log = logging.getLogger(__name__)


class ErrorItem(BaseModel):
    """One problem: which field (dotted path, e.g. ``vehicles[2].goal``) and why."""

    model_config = {"json_schema_extra": {"examples": [
        {"field": "vehicles[2].goal", "reason": "cannot be reached within the horizon"}]}}

    field: str | None = Field(description="Dotted path of the offending field, or null.")
    reason: str = Field(description="What is wrong, in words.")
    vehicle: str | None = Field(
        default=None, description="The id of the vehicle the field belongs to (`vehicles[2]` "
        "is the third vehicle of the document sent); left out when the field names none.")


class ErrorBody(BaseModel):
    """The body of every error response."""

    status: int = Field(description="The HTTP status code, repeated for convenience.")
    field: str | None = Field(description="The first offending field, or null.")
    reason: str = Field(description="Why the request failed.")
    errors: list[ErrorItem] = Field(description="Every problem found (at least one).")

    model_config = {
        "json_schema_extra": {
            "examples": [
                {
                    "status": 422,
                    "field": "vehicles[1].goal",
                    "reason": "[9.0, 1.0, 1.0] lies outside the workspace on axis x [0, 5]",
                    "errors": [
                        {
                            "field": "vehicles[1].goal",
                            "reason": "[9.0, 1.0, 1.0] lies outside the workspace on axis x "
                            "[0, 5]",
                        }
                    ],
                }
            ]
        }
    }


class ApiError(Exception):
    """An error answered with `status` and an `ErrorBody`."""

    status = 400

    def __init__(
        self, field: str | None, reason: str, *, errors: Sequence[ErrorItem] | None = None
    ) -> None:
        super().__init__(f"{field}: {reason}" if field else reason)
        self.field = field
        self.reason = reason
        self.errors = list(errors) if errors else [ErrorItem(field=field, reason=reason)]
        self.headers: dict[str, str] = {}

    def body(self) -> dict[str, Any]:
        body = ErrorBody(
            status=self.status, field=self.field, reason=self.reason, errors=self.errors
        ).model_dump()
        for item in body["errors"]:
            if item["vehicle"] is None:
                del item["vehicle"]
        return body


class BadRequest(ApiError):
    status = 400


class Unauthorized(ApiError):
    status = 401


class Forbidden(ApiError):
    status = 403


class PayloadTooLarge(ApiError):
    status = 413


class UnsupportedMediaType(ApiError):
    status = 415


class Unprocessable(ApiError):
    status = 422

    @classmethod
    def of(cls, errors: Sequence[ErrorItem], document: Any = None) -> Unprocessable:
        """Every problem at once; the first one is also the body's `field`/`reason`. With
        the `document` they were found in, each error under `vehicles[i]` names that
        vehicle's id."""
        if document is not None:
            errors = [item.model_copy(update={"vehicle": vehicle_at(item.field, document)})
                      for item in errors]
        return cls(errors[0].field, errors[0].reason, errors=errors)


#: The one mapping from the service's domain errors to HTTP statuses.
REQUEST_ERROR_STATUS: dict[type[RequestError], int] = {
    NotFound: 404,
    StateConflict: 409,
    InvalidRequest: 422,
    ServiceBusy: 503,
}


def _status_of(exc: RequestError) -> int:
    for cls in type(exc).__mro__:
        if cls in REQUEST_ERROR_STATUS:
            return REQUEST_ERROR_STATUS[cls]
    return 422


def error_responses(*codes: int, json_content: bool = False) -> dict[int | str, dict[str, Any]]:
    """OpenAPI `responses=` entries documenting `ErrorBody` for these status codes.

    `json_content`: say application/json explicitly, for routes whose own media type is
    something else (an event stream): FastAPI would document the error under that type.
    """
    meaning = {
        400: "Malformed request",
        401: "API token missing or wrong",
        403: "Cross-site request, or the token's role may not do this",
        404: "Not found",
        409: "Conflict with the resource's state",
        413: "Request body too large",
        415: "The body is not declared as JSON (Content-Type: application/json)",
        422: "Invalid input: the body names the field and the reason",
        503: "Service unavailable",
        507: "Disk full: the database cannot store this",
    }
    if json_content:
        content = {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorBody"}}}
        return {code: {"description": meaning[code], "content": content} for code in codes}
    return {code: {"model": ErrorBody, "description": meaning[code]} for code in codes}


#: Name of the app's catch-all route under /api (never an allowed method of its own).
FALLBACK = "api_fallback"
#: Methods probed for the `Allow` header of a 405.
_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE")


def allowed_methods(request: Request) -> list[str]:
    """Every method some route accepts for this path, found by asking the routes (included
    routers too) whether they would take the request with each method; empty when no route
    knows the path. The static page's mount at "/" takes any path and is left out."""
    methods: set[str] = set()
    for method in _METHODS:
        scope = {**request.scope, "method": method}
        if any(route.matches(scope)[0] == Match.FULL for route in request.app.router.routes
               if not isinstance(route, Mount) and getattr(route, "name", "") != FALLBACK):
            methods.add(method)
    return sorted(methods)


def _dotted(loc: Sequence[Any]) -> str | None:
    """pydantic's error location as the planner's dotted path: body.vehicles.2.goal ->
    vehicles[2].goal; query/path parameters keep their own name."""
    parts = list(loc)
    if parts and parts[0] in ("body", "query", "path", "header", "cookie"):
        parts = parts[1:]
    return field_path(parts) or None


def _validation_items(exc: RequestValidationError) -> list[ErrorItem]:
    items = []
    for error in exc.errors():
        loc = error.get("loc", ())
        message = str(error.get("msg", "invalid"))
        if error.get("type") == "json_invalid":
            ctx = error.get("ctx") or {}
            message = f"request body is not valid JSON: {ctx.get('error', message)}"
            loc = ("body",)
        items.append(ErrorItem(field=_dotted(loc) or "body", reason=message))
    return items or [ErrorItem(field=None, reason="invalid request")]


def _respond(error: ApiError) -> JSONResponse:
    return JSONResponse(status_code=error.status, content=error.body(), headers=error.headers)


async def send_error(send: Send, error: ApiError) -> None:
    """Answer with `error` from a pure ASGI middleware (before any route ran); the
    connection is closed since the request body may not have been read."""
    body = json.dumps(error.body()).encode()
    headers = [(b"content-type", b"application/json"),
               (b"content-length", str(len(body)).encode()), (b"connection", b"close")]
    headers += [(k.lower().encode(), v.encode()) for k, v in error.headers.items()]
    await send({"type": "http.response.start", "status": error.status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


def install_error_handlers(app: FastAPI) -> None:
    """Map every error (ours, FastAPI's, Starlette's, the planner's) to an `ErrorBody`."""

    async def api_error(_request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, ApiError)
        return _respond(exc)

    async def validation_error(_request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestValidationError)
        items = _validation_items(exc)
        is_json = any(i.reason.startswith("request body is not valid JSON") for i in items)
        error = ApiError(items[0].field, items[0].reason, errors=items)
        error.status = 400 if is_json else 422
        return _respond(error)

    async def request_error(_request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, RequestError)
        error = ApiError(exc.field, exc.reason)
        error.status = _status_of(exc)
        if isinstance(exc, ServiceBusy):
            error.headers["Retry-After"] = str(max(1, math.ceil(exc.retry_after_s)))
        return _respond(error)

    async def field_error(_request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, FieldError)
        error = ApiError(exc.field, exc.reason)
        error.status = 422
        return _respond(error)

    async def http_error(request: Request, exc: Exception) -> JSONResponse:
        assert isinstance(exc, StarletteHTTPException)
        error = ApiError("path" if exc.status_code == 404 else None, str(exc.detail))
        error.status = exc.status_code
        response = _respond(error)
        if exc.headers:
            response.headers.update(exc.headers)
        if exc.status_code == 405:
            # A path no route knows is the static page's, which only reads.
            allowed = allowed_methods(request) or ["GET", "HEAD"]
            response.headers["Allow"] = ", ".join(allowed)
        return response

    async def storage_error(_request: Request, exc: Exception) -> JSONResponse:
        # The database refused a write or a read: a full disk is 507, anything else 503
        # (retry later); never a 500 that does not say why.
        log.error("storage error: %s", exc)
        error = ApiError(None, storage_reason(exc))
        error.status = 507 if is_disk_full(exc) else 503
        if error.status == 503:
            error.headers["Retry-After"] = "5"
        return _respond(error)

    async def vehicles_stopped(_request: Request, exc: Exception) -> JSONResponse:
        # The vehicle process is not running (it died, or is being restarted): the fleet
        # cannot be reached now, which is a state of the service, not a bug.
        log.error("vehicle process: %s", exc)
        error = ApiError("fleet", f"{exc}: the fleet cannot be reached now; the service "
                                  "restarts its vehicle process (GET /api/status shows it)")
        error.status = 503
        error.headers["Retry-After"] = "5"
        return _respond(error)

    async def unexpected(_request: Request, exc: Exception) -> JSONResponse:
        log.exception("unhandled error", exc_info=exc)
        error = ApiError(None, f"internal error: {type(exc).__name__}")
        error.status = 500
        return _respond(error)

    app.add_exception_handler(ApiError, api_error)
    app.add_exception_handler(RequestValidationError, validation_error)
    app.add_exception_handler(RequestError, request_error)
    app.add_exception_handler(FieldError, field_error)
    app.add_exception_handler(SQLAlchemyError, storage_error)
    app.add_exception_handler(VehicleLoopStopped, vehicles_stopped)
    app.add_exception_handler(StarletteHTTPException, http_error)
    app.add_exception_handler(Exception, unexpected)
