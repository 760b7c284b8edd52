"""Fixtures shared by every test package."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest
from hypothesis import settings

#: The property tests draw the same examples on every run (`derandomize`), so a run's time
#: and outcome do not depend on luck; HYPOTHESIS_PROFILE=explore draws new ones each run.
settings.register_profile("suite", derandomize=True, database=None)
settings.register_profile("explore", database=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "suite"))


@pytest.fixture(scope="session")
def dask_scheduler() -> Iterator[str]:
    """One Dask cluster (2 worker processes) for the whole run: the in-process apps of the
    API tests plan on it (setting `scheduler`) instead of each starting an embedded cluster,
    which costs about 5 s per app. The embedded cluster itself is tested in tests/service."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        yield cluster.scheduler_address


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Every test that drives Chromium is marked `browser`, so `make test-fast` can leave it
    out without each file having to say so. (The order of the files is pytest-xdist's: the
    files with the most tests first, which runs the planner's CPU-bound files beside the
    flights' real-time waits; long files first measured 5-10 % slower.)"""
    for item in items:
        if "browser" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.browser)
