"""The service tests share the API tests' fixtures (isolated settings, a temporary database),
and the planning tests' Dask cluster of two worker processes and plan store."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import pytest
from distributed import LocalCluster

from gcs.service.store import Store
from tests.api.conftest import isolated_settings, make_settings, mock_settings

__all__ = ["isolated_settings", "make_settings", "mock_settings"]


@pytest.fixture(scope="module")
def cluster() -> Iterator[LocalCluster]:
    """Two worker processes with nannies (so a worker can be restarted), shared by the
    module."""
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      scheduler_port=0, dashboard_address=None,
                      silence_logs=logging.ERROR) as local:
        yield local


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    store = Store(f"sqlite:///{tmp_path / 'plans.db'}")
    yield store
    store.close()
