"""Fixtures for the API tests: settings on a temporary database, the real app, its client."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import free_udp_base
from tests.flight.support import QUICK_MOCK_SETTINGS


@pytest.fixture(autouse=True)
def isolated_settings(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """No FLEETPLAN_* variable or ./fleetplan.toml of the developer leaks into a test."""
    for name in list(os.environ):
        if name.startswith("FLEETPLAN_") and name != "FLEETPLAN_REQUIRE_BROWSER":
            monkeypatch.delenv(name)
    monkeypatch.chdir(tmp_path)


@pytest.fixture
def make_settings(tmp_path: Path, dask_scheduler: str) -> Callable[..., Settings]:
    """Settings on a SQLite file in this test's temporary directory, no vehicles, planning on
    the session's Dask cluster (`tests/conftest.py`)."""

    def make(**overrides: Any) -> Settings:
        values: dict[str, Any] = {
            "database_url": f"sqlite:///{tmp_path / 'fleetplan.db'}",
            "mock_vehicles": 0,
            "plan_workers": 1,
            "scheduler": dask_scheduler,
            # TestClient's requests carry "Host: testserver": the allow-list is configured.
            "allowed_hosts": ["testserver"],
        }
        values.update(overrides)
        return Settings(**values)

    return make


@pytest.fixture
def mock_settings(make_settings: Callable[..., Settings]) -> Callable[..., Settings]:
    """Settings with 4 in-process mock vehicles on free UDP ports, quick to arm, to confirm
    each mode change and to land (`QUICK_MOCK_SETTINGS`)."""

    def make(**overrides: Any) -> Settings:
        values: dict[str, Any] = {"mock_vehicles": 4, "mock_base_port": free_udp_base(4),
                                  "mock_settle_s": 0.5, **QUICK_MOCK_SETTINGS}
        values.update(overrides)
        return make_settings(**values)

    return make


@pytest.fixture
def client(make_settings: Callable[..., Settings]) -> Iterator[TestClient]:
    """The real app (store, planner worker pool) on a fresh database."""
    with TestClient(create_app(make_settings())) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def shared_client(tmp_path_factory: pytest.TempPathFactory, dask_scheduler: str
                  ) -> Iterator[TestClient]:
    """One app for a whole module, for tests that do not care about each other's missions."""
    path = tmp_path_factory.mktemp("shared") / "fleetplan.db"
    settings = Settings(
        database_url=f"sqlite:///{path}", mock_vehicles=0, plan_workers=1, max_vehicles=16,
        scheduler=dask_scheduler,
        max_steps=400, max_body_bytes=200_000, max_plan_body_bytes=400_000,
        allowed_hosts=["testserver"],
    )
    with TestClient(create_app(settings)) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def module_mock_settings(tmp_path_factory: pytest.TempPathFactory, dask_scheduler: str
                         ) -> Settings:
    """What `mock_settings()` gives, for a whole module: 4 mock vehicles quick to arm, on free
    UDP ports, a database of the module's own; no FLEETPLAN_* variable read."""
    path = tmp_path_factory.mktemp("module") / "fleetplan.db"
    with pytest.MonkeyPatch.context() as patch:
        for name in list(os.environ):
            if name.startswith("FLEETPLAN_") and name != "FLEETPLAN_REQUIRE_BROWSER":
                patch.delenv(name)
        return Settings(database_url=f"sqlite:///{path}", mock_vehicles=4,
                        mock_base_port=free_udp_base(4), mock_settle_s=0.5, plan_workers=1,
                        scheduler=dask_scheduler, allowed_hosts=["testserver"],
                        **QUICK_MOCK_SETTINGS)
