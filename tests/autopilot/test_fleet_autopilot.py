"""The fleet file's `autopilot`: fleet-wide, per vehicle, and refused when unknown."""

from __future__ import annotations

import pytest

from gcs.errors import FleetFileError
from gcs.fleet.fleetfile import FleetSpec


def _fleet(**extra: object) -> dict[str, object]:
    return {"vehicles": [{"id": "a", "connection": "udpin:127.0.0.1:14540", "system_id": 1,
                          "home": [0, 0, 0]},
                         {"id": "b", "connection": "udpin:127.0.0.1:14541", "system_id": 2,
                          "home": [2, 0, 0], "autopilot": "px4"}], **extra}


def test_absent_is_auto_and_not_written() -> None:
    fleet = FleetSpec.from_dict(_fleet())
    assert [v.autopilot for v in fleet.vehicles] == ["auto", "px4"]
    assert "autopilot" not in fleet.to_dict()["vehicles"][0]
    assert fleet.to_dict()["vehicles"][1]["autopilot"] == "px4"


def test_fleet_wide_with_a_vehicle_overriding_it() -> None:
    fleet = FleetSpec.from_dict(_fleet(autopilot="ardupilot"))
    assert [v.autopilot for v in fleet.vehicles] == ["ardupilot", "px4"]
    again = FleetSpec.from_dict(fleet.to_dict())
    assert [v.autopilot for v in again.vehicles] == ["ardupilot", "px4"]


@pytest.mark.parametrize(("extra", "field"), [({"autopilot": "apm"}, "autopilot")])
def test_unknown_is_refused_by_field(extra: dict[str, object], field: str) -> None:
    with pytest.raises(FleetFileError) as err:
        FleetSpec.from_dict(_fleet(**extra))
    assert err.value.field == field and "auto, px4, ardupilot" in str(err.value)
    bad = _fleet()
    bad["vehicles"][0]["autopilot"] = "PX4"  # type: ignore[index]
    with pytest.raises(FleetFileError) as err:
        FleetSpec.from_dict(bad)
    assert err.value.field == "vehicles[0].autopilot"
