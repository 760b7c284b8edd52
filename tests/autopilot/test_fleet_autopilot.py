"""The fleet file's `autopilot`: fleet-wide, per vehicle, and refused when unknown."""

from __future__ import annotations

import warnings
from typing import Any

import pytest

from gcs.errors import FleetFileError
from gcs.fleet.fleetfile import FleetFileWarning, FleetSpec
from gcs.wire import new_key_file


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


def test_a_signed_link_on_ardupilots_serial0_is_warned_about(tmp_path: Any) -> None:
    """ArduPilot's SERIAL0 (SITL TCP 5760 + 10 i, a board's USB) lets unsigned packets in
    whatever the key: a signed vehicle there is warned about, naming the port to use."""
    key = new_key_file(tmp_path / "k.key")
    fleet = {"signing_key": str(key.path), "vehicles": [
        {"id": "a", "connection": "tcp:127.0.0.1:5770", "system_id": 2, "home": [0, 0, 0]},
        {"id": "b", "connection": "tcp:127.0.0.1:5772", "system_id": 3, "home": [2, 0, 0]}]}
    with pytest.warns(FleetFileWarning, match=r"vehicles\[0\].*SERIAL0.*5772") as caught:
        FleetSpec.from_dict(fleet)
    assert len(caught) == 1
    fleet["vehicles"][0]["autopilot"] = "px4"  # PX4 checks signatures on every link
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        FleetSpec.from_dict(fleet)
