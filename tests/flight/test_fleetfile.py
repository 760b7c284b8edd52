"""gcs.flight.fleetfile: fleet file validation names the offending field."""

from __future__ import annotations

import pytest

from gcs.errors import FleetFileError
from gcs.flight.fleetfile import FleetSpec, FlightOptions


def _fleet(**vehicle_changes):
    vehicle = {"id": "uav1", "connection": "udpin:127.0.0.1:14540", "system_id": 1,
               "home": [0.0, 0.0, 0.0]} | vehicle_changes
    return {"vehicles": [vehicle]}


def test_valid_fleet_with_shared_connection() -> None:
    spec = FleetSpec.from_dict({"vehicles": [
        {"id": "a", "connection": "udpin:127.0.0.1:14549", "system_id": 11, "home": [0, 0, 0]},
        {"id": "b", "connection": "udpin:127.0.0.1:14549", "system_id": 12, "home": [2, 0, 0]},
    ], "mission": {"policy": "land_faulty", "rate_hz": 50}})
    assert [v.system_id for v in spec.vehicles] == [11, 12]
    assert spec.options.policy == "land_faulty" and spec.options.rate_hz == 50
    assert [v.id for v in spec.for_plan(["b", "a"])] == ["b", "a"]


@pytest.mark.parametrize(("data", "field"), [
    (_fleet(system_id=0), "vehicles[0].system_id"),
    (_fleet(system_id="1"), "vehicles[0].system_id"),
    (_fleet(connection="udpin:localhost"), "vehicles[0].connection"),
    (_fleet(home=[0, 0]), "vehicles[0].home"),
    (_fleet(colour="red"), "vehicles[0].colour"),
    ({"vehicles": [{"id": "uav1", "connection": "udpin:127.0.0.1:1", "system_id": 1}]},
     "vehicles[0].home"),
    ({"vehicles": []}, "vehicles"),
    ({"vehicles": _fleet()["vehicles"] * 2}, "vehicles[1].id"),
    (_fleet() | {"mission": {"policy": "panic"}}, "mission.policy"),
    (_fleet() | {"mission": {"rate_hz": 500}}, "mission.rate_hz"),
    (_fleet() | {"mission": {"rate_hz": 2}}, "mission.rate_hz"),  # PX4 needs > 2 Hz
    (_fleet() | {"mission": {"link_timeout": 60}}, "mission.link_timeout"),
    (_fleet() | {"mission": {"separation_alarm": -1}}, "mission.separation_alarm"),
    (_fleet() | {"world_origin": {"lat": 95, "lon": 0, "alt": 0}}, "world_origin.lat"),
])
def test_errors_name_the_field(data, field: str) -> None:
    with pytest.raises(FleetFileError) as info:
        FleetSpec.from_dict(data)
    assert info.value.field == field


def test_same_system_id_twice_on_one_connection() -> None:
    vehicles = [_fleet()["vehicles"][0], _fleet(id="uav2")["vehicles"][0]]
    with pytest.raises(FleetFileError, match="already used") as info:
        FleetSpec.from_dict({"vehicles": vehicles})
    assert info.value.field == "vehicles[1].system_id"


def test_plan_vehicle_missing_from_fleet() -> None:
    spec = FleetSpec.from_dict(_fleet())
    with pytest.raises(FleetFileError, match="'uav9'"):
        spec.for_plan(["uav1", "uav9"])


def test_options_replace_validates() -> None:
    with pytest.raises(FleetFileError, match=r"option\.heartbeat_timeout"):
        FlightOptions().replace(where="option", heartbeat_timeout=-1)
