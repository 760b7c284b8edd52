"""A mixed mock fleet in the service: the `mock_autopilot` setting, and GET /api/vehicles
saying which autopilot each vehicle is."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest
from pydantic import ValidationError

from gcs.service.flights import FleetService
from gcs.service.settings import Settings
from tests.api.support import free_udp_base
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(60)


def test_the_vehicle_list_names_each_vehicles_autopilot() -> None:
    async def run() -> list[dict[str, Any]]:
        settings = Settings(mock_vehicles=3, mock_base_port=free_udp_base(3),
                            mock_autopilot="px4,ardupilot", mock_status_rate_hz=5.0)
        service = FleetService(settings, store=None)  # type: ignore[arg-type]
        await service.start()
        try:
            async def named() -> list[dict[str, Any]] | None:
                vehicles = await service.vehicles()
                return vehicles if all(v.get("autopilot") for v in vehicles) else None

            return await until(named, "every vehicle's autopilot heard", timeout=30.0)
        finally:
            await service.close()

    vehicles = asyncio.run(run())
    assert [v["autopilot"] for v in vehicles] == ["px4", "ardupilot", "px4"]
    assert vehicles[1]["mode"] == "STABILIZE" and vehicles[0]["mode"] == "AUTO.LOITER"


def test_an_unknown_mock_autopilot_is_refused_by_name() -> None:
    with pytest.raises(ValidationError, match="mock_autopilot"):
        Settings(mock_autopilot="px4,apm")
