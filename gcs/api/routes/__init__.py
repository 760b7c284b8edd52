"""The API's routers, one module per resource, all under the `/api` prefix."""

from __future__ import annotations

from fastapi import APIRouter

from gcs.api.routes import examples, executions, fleet, missions, status, vehicles

__all__ = ["api_router"]

api_router = APIRouter(prefix="/api")
api_router.include_router(missions.router)
api_router.include_router(executions.mission_router)
api_router.include_router(executions.router)
api_router.include_router(vehicles.router)
api_router.include_router(fleet.router)
api_router.include_router(examples.router)
api_router.include_router(status.router)
