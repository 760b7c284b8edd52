"""The FastAPI application factory: services, routers, error handlers, the browser page.

`create_app(settings)` builds an app whose lifespan opens the store, starts the planning
worker pool (and the fleet, when configured) and closes them again; nothing starts at import
time, so tests build as many apps (and databases) as they like.
"""

from __future__ import annotations

import json
import logging
from collections.abc import AsyncIterator, Callable
from contextlib import AbstractAsyncContextManager, asynccontextmanager
from importlib import metadata
from pathlib import Path
from typing import Any

import fastapi_offline
import plotly
from fastapi import FastAPI, Request
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse
from fastapi.routing import APIRoute
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException as StarletteHTTPException

import gcs
from gcs.api.errors import FALLBACK, allowed_methods, install_error_handlers
from gcs.api.fanout import SharedJson, Slots, StreamSlots
from gcs.api.limits import BodyLimitMiddleware
from gcs.api.routes import api_router
from gcs.api.schemas import planner_schemas
from gcs.api.security import AccessPolicy, SecurityMiddleware
from gcs.errors import NotFound
from gcs.service.flights import FleetService
from gcs.service.planning import PlanningService
from gcs.service.plans import PlanCache
from gcs.service.settings import Settings
from gcs.service.store import Store
from gcs.service.vehicle_host import ORPHAN_ERROR

__all__ = ["PLOTLY_JS", "SWAGGER_UI", "create_app", "web_directory"]

log = logging.getLogger(__name__)

ALL_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")

#: plotly.js as bundled in the Python `plotly` package: served locally, never from a CDN.
PLOTLY_JS = Path(plotly.__file__).parent / "package_data" / "plotly.min.js"
#: Swagger UI 5.x as shipped by the `fastapi-offline` package (swagger-ui-bundle 1.1 ships
#: 4.15, which cannot render OpenAPI 3.1): served locally, never from a CDN.
SWAGGER_UI = Path(fastapi_offline.__file__).parent / "static"

DESCRIPTION = """\
Plan collision-free trajectories for a quadcopter fleet and fly them on PX4 vehicles
(real, SITL or the built-in mock).

Errors always have the body `{"status", "field", "reason", "errors": [...]}`: `field` is the
dotted path of the offending input (e.g. `vehicles[2].goal`), `reason` says what is wrong.
"""


def web_directory(settings: Settings) -> Path:
    """Where the browser page is: the setting, else inside the installed package (wheel),
    else the source checkout's ``web/`` (editable install)."""
    if settings.web_dir is not None:
        return settings.web_dir
    package = Path(gcs.__file__).resolve().parent
    for candidate in (package / "web", package.parent / "web"):
        if (candidate / "index.html").is_file():
            return candidate
    raise FileNotFoundError(f"browser page not found next to {package}")


def _version() -> str:
    try:
        return metadata.version("fleetplan")
    except metadata.PackageNotFoundError:  # running from a bare checkout
        return "0+unknown"


def create_app(settings: Settings | None = None) -> FastAPI:
    """A fresh application configured by `settings` (default: environment and config file)."""
    settings = settings or Settings()
    app = FastAPI(
        title="fleetplan",
        version=_version(),
        description=DESCRIPTION,
        lifespan=_lifespan(settings),
        docs_url=None,  # served below from local files: FastAPI's default loads a CDN
        redoc_url=None,
        generate_unique_id_function=_operation_id,
    )
    app.state.settings = settings
    install_error_handlers(app)
    # Added last, runs first: a forged or unauthorised request is refused before its body
    # is even counted.
    app.add_middleware(BodyLimitMiddleware, max_bytes=settings.max_body_bytes,
                       larger={("POST", "/api/missions"): (settings.max_plan_body_bytes,
                                                            "max_plan_body_bytes")})
    app.add_middleware(SecurityMiddleware, policy=AccessPolicy.from_settings(settings))
    app.include_router(api_router)
    _add_api_fallback(app)
    _add_pages(app, settings)
    _complete_openapi(app)
    return app


def _lifespan(settings: Settings) -> Callable[[FastAPI], AbstractAsyncContextManager[None]]:
    """The application's lifespan: open the store (failing what a previous run left
    unfinished), start the planning workers and the fleet, and close them all at the end."""

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        store = Store(settings.database_url)
        stale = await run_in_threadpool(
            store.fail_unfinished_planning, "the service stopped before this plan finished"
        )
        if stale:
            log.warning("%d mission(s) left planning by a previous run marked failed", stale)
        interrupted = await run_in_threadpool(
            store.fail_unfinished_flights, ORPHAN_ERROR
        )
        if interrupted:
            log.warning("%d flight(s) left running by a previous run marked interrupted",
                        interrupted)
        planning = PlanningService.from_settings(store, settings)
        await planning.start()
        fleet = FleetService(settings, store)
        app.state.settings = settings
        app.state.store = store
        app.state.planning = planning
        app.state.plans = PlanCache(store)
        app.state.fleet = fleet
        app.state.exports = Slots(settings.max_concurrent_exports, "max_concurrent_exports",
                                  "trajectory exports")
        app.state.streams = StreamSlots(settings.max_event_streams,
                                        settings.max_event_streams_per_resource)
        app.state.shared_json = SharedJson()
        try:
            await fleet.start()
            yield
        finally:
            await fleet.close()
            await planning.close()
            store.close()

    return lifespan


def _add_api_fallback(app: FastAPI) -> None:
    """Every /api path no router answers, added after the routers so that it matches last."""

    @app.api_route("/api/{rest:path}", methods=list(ALL_METHODS), include_in_schema=False,
                   name=FALLBACK)
    def api_fallback(request: Request) -> None:
        """Unknown /api paths and methods: 404 or 405 with `Allow`, never the static page
        (whose mount at "/" would otherwise answer GET for any path)."""
        allowed = allowed_methods(request)
        if not allowed or request.method in allowed:
            raise NotFound("path", f"no such API path: {request.url.path}")
        raise StarletteHTTPException(405, headers={"Allow": ", ".join(allowed)})


def _add_pages(app: FastAPI, settings: Settings) -> None:
    """What is served beside the API, all from local files: liveness, plotly.js, the API
    docs (Swagger UI) and the browser page, mounted last at "/" so that it answers only what
    nothing else does."""

    @app.get("/healthz", include_in_schema=False)
    def healthz() -> dict[str, str]:
        """Liveness for container health checks: no token needed, tells nothing."""
        return {"status": "ok"}

    @app.get("/vendor/plotly.min.js", include_in_schema=False)
    def plotly_js() -> FileResponse:
        return FileResponse(PLOTLY_JS, media_type="text/javascript")

    # Swagger UI 5 (it reads OpenAPI 3.1) from the fastapi-offline package: the API docs
    # work offline too.
    app.mount("/vendor/swagger-ui", StaticFiles(directory=SWAGGER_UI), name="swagger-ui")

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=app.openapi_url or "/openapi.json", title="fleetplan API",
            swagger_js_url="/vendor/swagger-ui/swagger-ui-bundle.js",
            swagger_css_url="/vendor/swagger-ui/swagger-ui.css",
            swagger_favicon_url="/vendor/swagger-ui/favicon.png",
        )

    app.mount("/", StaticFiles(directory=web_directory(settings), html=True), name="web")


def _operation_id(route: APIRoute) -> str:
    """operationIds that read well: the route function's name in camelCase (createMission);
    a deprecated alias of a route adds ``Deprecated`` (getFlightDeprecated)."""
    first, *rest = route.name.split("_")
    return first + "".join(word.capitalize() for word in rest) + (
        "Deprecated" if route.deprecated else "")


def _complete_openapi(app: FastAPI) -> None:
    """The published schema, finished once: the planner-derived components (Scenario, Plan,
    ...) that routes refer to, and request validation failures (422) documented with
    `ErrorBody`, the shape this API answers them with, instead of FastAPI's
    HTTPValidationError."""
    generate = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            text = json.dumps(generate()).replace(
                "#/components/schemas/HTTPValidationError", "#/components/schemas/ErrorBody"
            )
            schema = json.loads(text)
            components = schema.setdefault("components", {}).setdefault("schemas", {})
            for name in ("HTTPValidationError", "ValidationError"):
                components.pop(name, None)
            components.update(planner_schemas())
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
