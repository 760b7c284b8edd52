"""The API's routers, one module per resource, all under the `/api` prefix.

A flight's routes are mounted twice: under `/flights`, and under `/executions`, their former
name, kept working for existing clients and marked deprecated in the OpenAPI document.
"""

from __future__ import annotations

from fastapi import APIRouter

from gcs.api.routes import examples, fleet, flights, missions, shows, status, vehicles

__all__ = ["api_router"]

api_router = APIRouter(prefix="/api")
api_router.include_router(missions.router)
api_router.include_router(shows.router)
api_router.include_router(flights.mission_router)
api_router.include_router(flights.flights_router)
api_router.include_router(flights.router, prefix="/flights")
api_router.include_router(flights.executions_router)
api_router.include_router(flights.router, prefix="/executions", deprecated=True)
api_router.include_router(vehicles.router)
api_router.include_router(fleet.router)
api_router.include_router(examples.router)
api_router.include_router(status.router)
