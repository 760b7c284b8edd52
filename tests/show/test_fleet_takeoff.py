"""A fleet file's homes as a show's takeoff grid: `takeoff.fleet` or `fleetplan plan
--takeoff-fleet` fill takeoff.homes in the sequence's vehicle order, and a fleet that cannot
give them is refused naming the vehicle."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from gcs.cli.main import main
from gcs.errors import FleetFileError
from gcs.fleet.fleetfile import FleetSpec
from gcs.fleet.takeoff import with_fleet_homes
from tests.support.shows import FLEET_HOMES as HOMES
from tests.support.shows import fleet_dict
from tests.support.shows import ground_show as _show

#: The test show's 3 x 3 grid (rows 0.8 m apart, closer than R), as fleet homes.


def ground_sequence() -> dict[str, Any]:
    """The test show with its takeoff homes left to a fleet file."""
    data = _show(landing={})
    data["takeoff"] = {"fleet": "fleet.json"}
    return data


def test_the_homes_come_in_the_sequences_vehicle_order() -> None:
    data = ground_sequence()
    fleet = FleetSpec.from_dict(fleet_dict(data["vehicles"], HOMES))
    filled = with_fleet_homes(data, fleet)
    assert filled["takeoff"] == {"homes": [home[:2] for home in HOMES]}
    assert data["takeoff"] == {"fleet": "fleet.json"}  # the caller's document is left alone


@pytest.mark.parametrize(("change", "words"), [
    (lambda f: f["vehicles"].pop(0), "is not in the fleet file"),
    (lambda f: f["vehicles"][0].update(home=[0.0, 0.0, 0.4]), "has its home at z = 0.4 m"),
    (lambda f: (f["vehicles"][0].pop("home"),
                f.update(world_origin={"lat": 47.4, "lon": 8.5, "alt": 488.0})),
     "has no home in the fleet file"),
])
def test_a_fleet_that_cannot_give_a_home_is_refused_naming_the_vehicle(change, words) -> None:
    data = ground_sequence()
    raw = fleet_dict(data["vehicles"], HOMES)
    change(raw)
    named = data["vehicles"][-1]  # the fleet file lists the show's last vehicle first
    with pytest.raises(FleetFileError) as caught:
        with_fleet_homes(data, FleetSpec.from_dict(raw))
    assert caught.value.field == "takeoff.fleet"
    assert f"vehicle {named!r} {words}" in caught.value.reason


def test_homes_given_twice_are_refused() -> None:
    data = ground_sequence()
    data["takeoff"]["grid"] = {"origin": [0, 0], "columns": 3, "rows": 3, "spacing": [2, 2]}
    with pytest.raises(FleetFileError, match=r"drop takeoff\.grid"):
        with_fleet_homes(data, FleetSpec.from_dict(fleet_dict(data["vehicles"], HOMES)))


def test_plan_takes_off_from_the_fleet_files_homes(tmp_path: Path, capsys) -> None:
    data = ground_sequence()
    (tmp_path / "fleet.json").write_text(json.dumps(fleet_dict(data["vehicles"], HOMES)))
    (tmp_path / "show.json").write_text(json.dumps(data))
    plan_path = tmp_path / "show.plan.json"
    assert main(["plan", str(tmp_path / "show.json"), "-o", str(plan_path), "-q"]) == 0
    capsys.readouterr()
    homes = json.loads(plan_path.read_text())["sequence"]["ground"]["takeoff"]["homes"]
    assert [homes[vid] for vid in data["vehicles"]] == HOMES


def test_plan_refuses_a_fleet_without_the_vehicle(tmp_path: Path, capsys) -> None:
    data = _show(landing={})
    del data["takeoff"]
    (tmp_path / "fleet.json").write_text(json.dumps(fleet_dict(data["vehicles"][1:],
                                                               HOMES[1:])))
    (tmp_path / "show.json").write_text(json.dumps(data))
    assert main(["plan", str(tmp_path / "show.json"), "--takeoff-fleet",
                 str(tmp_path / "fleet.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: --takeoff-fleet: vehicle {data['vehicles'][0]!r} is not "
                          f"in the fleet file")
    # a broken fleet file is named with its field
    (tmp_path / "fleet.json").write_text(json.dumps({"vehicles": [{"id": "x"}]}))
    assert main(["plan", str(tmp_path / "show.json"), "--takeoff-fleet",
                 str(tmp_path / "fleet.json")]) == 2
    assert "--takeoff-fleet: " in capsys.readouterr().err


def test_the_service_asks_for_homes_instead() -> None:
    from planner.errors import ScenarioError
    from planner.methods.sequence import parse_sequence

    with pytest.raises(ScenarioError) as caught:
        parse_sequence(ground_sequence())
    assert caught.value.field == "takeoff.fleet"
    assert "give takeoff.homes" in caught.value.reason
