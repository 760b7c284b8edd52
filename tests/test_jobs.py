"""`make test`'s number of test processes (tests/jobs.py)."""

from __future__ import annotations

import pytest

from tests.jobs import idle_fraction, jobs


@pytest.mark.parametrize(("cores", "idle", "expected"), [
    (2, 0.9, 3),   # idle: one more than the cores
    (2, 0.3, 2),   # busy (two CPU hogs): one per core
    (2, None, 2),  # load unknown: one per core
    (1, 0.9, 2),
    (8, 0.9, 3),   # at most 3
    (8, 0.1, 3),
])
def test_one_per_core_and_one_more_only_when_idle(cores: int, idle: float | None,
                                                  expected: int) -> None:
    assert jobs(cores, idle) == expected


def test_the_idle_share_is_a_fraction() -> None:
    idle = idle_fraction(0.05)
    assert idle is None or 0.0 <= idle <= 1.0
