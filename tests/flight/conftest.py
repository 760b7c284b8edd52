"""Fixtures for the GCS tests."""

from __future__ import annotations

import pytest

from tests.flight.support import line_scenario, smooth_plan


@pytest.fixture(scope="session")
def line3_plan():
    """Three vehicles 3 m apart flying 2 m along y at 1.5 m in 6 s (a smooth test plan)."""
    return smooth_plan(line_scenario(3))
