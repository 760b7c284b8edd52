"""gcs.fleet.fleetfile: fleet file validation names the offending field."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from gcs.errors import FleetFileError
from gcs.fleet.fleetfile import FleetFileWarning, FleetSpec, FlightOptions


def _fleet(**vehicle_changes):
    vehicle = {"id": "uav1", "connection": "udpin:127.0.0.1:14540", "system_id": 1,
               "home": [0.0, 0.0, 0.0]} | vehicle_changes
    return {"vehicles": [vehicle]}


def test_valid_fleet_with_shared_connection() -> None:
    spec = FleetSpec.from_dict({"vehicles": [
        {"id": "a", "connection": "udpin:127.0.0.1:14549", "system_id": 11, "home": [0, 0, 0]},
        {"id": "b", "connection": "udpin:127.0.0.1:14549", "system_id": 12, "home": [2, 0, 0]},
    ], "flight": {"policy": "land_faulty", "rate_hz": 50}})
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
    (_fleet() | {"flight": {"policy": "panic"}}, "flight.policy"),
    (_fleet() | {"flight": {"rate_hz": 500}}, "flight.rate_hz"),
    (_fleet() | {"flight": {"rate_hz": 2}}, "flight.rate_hz"),  # PX4 needs > 2 Hz
    (_fleet() | {"flight": {"link_timeout": 60}}, "flight.link_timeout"),
    (_fleet() | {"flight": {"separation_alarm": -1}}, "flight.separation_alarm"),
    (_fleet() | {"flight": {"landing_plan_timeout": 0}}, "flight.landing_plan_timeout"),
    (_fleet() | {"flight": {"landing_plan_timeout": 31}}, "flight.landing_plan_timeout"),
    (_fleet() | {"flight": {"landing_plan_timeout": 1e300}}, "flight.landing_plan_timeout"),
    (_fleet() | {"flight": {"landing_height": -0.1}}, "flight.landing_height"),
    (_fleet() | {"flight": {"landing_height": 10.5}}, "flight.landing_height"),
    (_fleet() | {"flight": {"replan_lead_s": 0}}, "flight.replan_lead_s"),
    (_fleet() | {"flight": {"replan_lead_s": 10.5}}, "flight.replan_lead_s"),
    (_fleet() | {"flight": {"land_speed": 0}}, "flight.land_speed"),
    (_fleet() | {"flight": {"land_speed": 4}}, "flight.land_speed"),
    (_fleet() | {"world_origin": {"lat": 95, "lon": 0, "alt": 0}}, "world_origin.lat"),
])
def test_errors_name_the_field(data, field: str) -> None:
    with pytest.raises(FleetFileError) as info:
        FleetSpec.from_dict(data)
    assert info.value.field == field


def test_landing_options_take_their_whole_range() -> None:
    """The landing options' bounds are inclusive where they say so: 30 s, 0 and 10 m."""
    options = FlightOptions().replace(landing_plan_timeout=30, landing_height=10)
    assert (options.landing_plan_timeout, options.landing_height) == (30, 10)
    assert FlightOptions().replace(landing_height=0).landing_height == 0


def test_replan_options() -> None:
    """Policy replan is a policy; the replan lead defaults to 1 s and takes up to 10 s."""
    spec = FleetSpec.from_dict(_fleet() | {"flight": {"policy": "replan",
                                                      "replan_lead_s": 10}})
    assert (spec.options.policy, spec.options.replan_lead_s) == ("replan", 10)
    assert FlightOptions().replan_lead_s == 1.0


def test_same_system_id_twice_on_one_connection() -> None:
    vehicles = [_fleet()["vehicles"][0], _fleet(id="uav2")["vehicles"][0]]
    with pytest.raises(FleetFileError, match="already used") as info:
        FleetSpec.from_dict({"vehicles": vehicles})
    assert info.value.field == "vehicles[1].system_id"


def test_plan_vehicle_missing_from_fleet() -> None:
    spec = FleetSpec.from_dict(_fleet())
    with pytest.raises(FleetFileError, match="'uav9'") as info:
        spec.for_plan(["uav1", "uav9"])
    # the way forward: the fleet file, or as many mock vehicles as the plan has
    assert "add them to the fleet file" in info.value.reason
    assert "fleetplan fly PLAN.json --mock" in info.value.reason
    assert "fleetplan serve --mock 2" in info.value.reason


def test_options_replace_validates() -> None:
    with pytest.raises(FleetFileError, match=r"option\.heartbeat_timeout"):
        FlightOptions().replace(where="option", heartbeat_timeout=-1)


def test_flight_options_are_written_under_flight_and_read_back() -> None:
    spec = FleetSpec.from_dict(_fleet() | {"flight": {"policy": "hold_all", "rate_hz": 40}})
    written = spec.to_dict()
    assert "mission" not in written
    assert written["flight"]["policy"] == "hold_all" and written["flight"]["rate_hz"] == 40
    assert FleetSpec.from_dict(written).options == spec.options


def test_the_old_key_mission_is_read_with_a_warning_naming_it() -> None:
    with pytest.warns(FleetFileWarning, match=r"'mission'.*rename it to 'flight'"):
        spec = FleetSpec.from_dict(_fleet() | {"mission": {"policy": "land_faulty"}})
    assert spec.options.policy == "land_faulty"
    with pytest.warns(FleetFileWarning), pytest.raises(FleetFileError) as info:
        FleetSpec.from_dict(_fleet() | {"mission": {"policy": "panic"}})
    assert info.value.field == "mission.policy"  # errors name the key the file has


def test_both_keys_are_an_error_naming_both() -> None:
    with pytest.raises(FleetFileError, match=r"'flight'.*'mission'") as info:
        FleetSpec.from_dict(_fleet() | {"flight": {}, "mission": {}})
    assert info.value.field == "mission"


def test_the_cli_user_sees_the_old_key_warning(tmp_path: Path) -> None:
    """`fleetplan plan --fleet` reads the fleet file first; the warning reaches its stderr with
    no warning filter set (the CLI sets none)."""
    fleet, scenario = tmp_path / "fleet.json", tmp_path / "scenario.json"
    fleet.write_text(json.dumps(_fleet() | {"mission": {"rate_hz": 30}}))
    scenario.write_text("{}")
    done = subprocess.run(
        [sys.executable, "-m", "gcs.cli.main", "plan", str(scenario), "--fleet", str(fleet),
         "-o", str(tmp_path / "plan.json")],
        capture_output=True, text=True, timeout=60,
        env={"PYTHONPATH": str(Path(__file__).parents[2])})
    assert done.returncode == 2  # the fleet states no position_error: refused before planning
    assert "states no position_error" in done.stderr
    assert f"{fleet}: key 'mission' is read as 'flight': rename it to 'flight'" in done.stderr
