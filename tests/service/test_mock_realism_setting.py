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
            config = await service.vehicle_process.call("mock_config")
            assert config is not None
            return config
        finally:
            await service.close()

    return asyncio.run(run())


def test_the_default_mock_is_ideal_and_px4_realism_is_chosen_by_setting() -> None:
    ideal = _mock_config()
    assert ideal.realism == "ideal" and ideal.estimate_noise is None
    assert ideal.settle_time == 5.0  # PX4 SITL's estimator settling
    px4 = _mock_config(mock_realism="px4")
    assert px4.realism == "px4" and px4.estimate_noise == EstimateNoise()
    assert px4.settle_time == 3.5
    assert _mock_config(mock_realism="px4", mock_settle_s=0.5).settle_time == 0.5


def test_an_unknown_realism_is_refused_by_name(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FLEETPLAN_MOCK_REALISM", "gazebo")
    with pytest.raises(ValidationError, match="mock_realism"):
        Settings()


def test_the_mock_px4_timings_are_settings_over_the_realism() -> None:
    """Status rate, landing speed and disarm delay (PX4's stream rate, MPC_LAND_SPEED,
    COM_DISARM_LAND) reach the mocks; unset ones stay the realism's."""
    quick = _mock_config(mock_realism="px4", mock_status_rate_hz=5.0, mock_land_speed=1.0,
                         mock_disarm_after_land_s=0.5)
    assert (quick.status_rate, quick.land_speed, quick.disarm_after_land) == (5.0, 1.0, 0.5)
    assert quick.estimate_noise == EstimateNoise()  # still the px4 realism
    plain = _mock_config()
    assert (plain.status_rate, plain.land_speed, plain.disarm_after_land) == (1.0, 0.7, 2.0)


@pytest.mark.parametrize(("name", "value"), [("MOCK_STATUS_RATE_HZ", "0"),
                                             ("MOCK_LAND_SPEED", "10"),
                                             ("MOCK_DISARM_AFTER_LAND_S", "nan")])
def test_a_mock_timing_out_of_range_is_refused_by_name(
        monkeypatch: pytest.MonkeyPatch, name: str, value: str) -> None:
    monkeypatch.setenv(f"FLEETPLAN_{name}", value)
    with pytest.raises(ValidationError, match=name.lower()):
        Settings()
