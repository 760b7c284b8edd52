"""Shared dependencies of the routes, as `Annotated` aliases (one place to change them).

The services live on `app.state` (created by the app's lifespan in `gcs.api.app`); these
aliases hand them to the routes, and `MissionDep` turns a `{mission_id}` path parameter into a
stored mission or a 404 before a route (or a stream) starts.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Path, Request
from starlette.concurrency import run_in_threadpool

from gcs.errors import NotFound
from gcs.service.flights import FleetService
from gcs.service.planning import PlanningService
from gcs.service.plans import PlanCache
from gcs.service.settings import Settings
from gcs.service.store import MissionRow, Store

__all__ = [
    "FleetDep",
    "MissionDep",
    "MissionIdPath",
    "PlanCacheDep",
    "PlanningDep",
    "SettingsDep",
    "StoreDep",
]


def _settings(request: Request) -> Settings:
    return request.app.state.settings


def _store(request: Request) -> Store:
    return request.app.state.store


def _planning(request: Request) -> PlanningService:
    return request.app.state.planning


def _plans(request: Request) -> PlanCache:
    return request.app.state.plans


def _fleet(request: Request) -> FleetService:
    return request.app.state.fleet


SettingsDep = Annotated[Settings, Depends(_settings)]
StoreDep = Annotated[Store, Depends(_store)]
PlanningDep = Annotated[PlanningService, Depends(_planning)]
PlanCacheDep = Annotated[PlanCache, Depends(_plans)]
FleetDep = Annotated[FleetService, Depends(_fleet)]

MissionIdPath = Annotated[
    str, Path(description="Mission id, as returned by POST /api/missions.", max_length=64)
]


async def _mission(mission_id: MissionIdPath, store: StoreDep) -> MissionRow:
    row = await run_in_threadpool(store.get_mission, mission_id)
    if row is None:
        raise NotFound("mission_id", f"no mission with id {mission_id!r}")
    return row


MissionDep = Annotated[MissionRow, Depends(_mission)]
