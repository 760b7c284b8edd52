"""Fixtures shared by the route tests."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.api.support import example


@pytest.fixture(scope="module")
def planned(shared_client: TestClient) -> dict[str, Any]:
    """The paper's 4-vehicle circle, planned on the module's shared service."""
    response = shared_client.post("/api/missions?wait=60", json=example("paper-circle4"))
    assert response.status_code == 201, response.text
    return response.json()
