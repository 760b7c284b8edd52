"""The `mock_realism` setting: the service's mock vehicles behave as the named preset."""

from __future__ import annotations

import asyncio

import pytest
from pydantic import ValidationError

from gcs.service.flights import FleetService
from gcs.service.settings import Settings
from gcs.sim.model import EstimateNoise
from tests.api.support import free_udp_base

pytestmark = pytest.mark.timeout(60)


def _mock_config(**values: object):  # type: ignore[no-untyped-def]
    async def run():  # type: ignore[no-untyped-def]
        settings = Settings(mock_vehicles=2, mock_base_port=free_udp_base(2), **values)
        service = FleetService(settings, store=None)  # type: ignore[arg-type]
        await service.start()
        try:
            assert service.fleet.mock is not None
            return service.fleet.mock.config
        finally:
            await service.close()

    return asyncio.run(run())


def test_the_default_mock_is_ideal_and_px4_realism_is_chosen_by_setting() -> None:
    ideal = _mock_config()
    assert ideal.realism == "ideal" and ideal.estimate_noise is None
    assert ideal.settle_time == 5.0  # as before
    px4 = _mock_config(mock_realism="px4")
    assert px4.realism == "px4" and px4.estimate_noise == EstimateNoise()
    assert px4.settle_time == 3.5
    assert _mock_config(mock_realism="px4", mock_settle_s=0.5).settle_time == 0.5


def test_an_unknown_realism_is_refused_by_name(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FLEETPLAN_MOCK_REALISM", "gazebo")
    with pytest.raises(ValidationError, match="mock_realism"):
        Settings()
