"""Fixtures shared by every test package."""

from __future__ import annotations

from collections.abc import Iterator

import pytest


@pytest.fixture(scope="session")
def dask_scheduler() -> Iterator[str]:
    """One Dask cluster (2 worker processes) for the whole run: the in-process apps of the
    API tests plan on it (setting `scheduler`) instead of each starting an embedded cluster,
    which costs about 5 s per app. The embedded cluster itself is tested in tests/service."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        yield cluster.scheduler_address


#: Markers of the long tests (real-time flights, Chromium, long runs).
LONG_MARKERS = ("browser", "flight", "slow")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Every test that drives Chromium is marked `browser`, so `make test-fast` can leave it
    out without each file having to say so. Files holding long tests run first: with
    `--dist loadfile` the short files then fill the workers' last minutes, instead of one
    long file running on alone at the end."""
    for item in items:
        if "browser" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.browser)
    long_files = {item.path for item in items
                  if any(item.get_closest_marker(m) for m in LONG_MARKERS)}
    items.sort(key=lambda item: item.path not in long_files)  # stable: file order kept
