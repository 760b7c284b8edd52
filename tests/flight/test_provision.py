"""Provisioning the fleet file's keys (`gcs.fleet.provision`, `fleetplan keys provision`)
on mock vehicles that follow PX4's signing rules (HEARTBEAT at 5 Hz, so each step hears
the vehicle within 0.2 s): unsigned SETUP_SIGNING only while a vehicle
has no key, a change signed with the old key, nothing while armed, and the traffic checked
signed afterwards. The key is never printed."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from gcs.fleet.fleetfile import FleetSpec
from gcs.fleet.provision import provision_fleet
from gcs.sim import MockFleet
from gcs.wire import SigningKey, load_key, new_key_file
from tests.flight.support import FAST_MOCK, mock_ports

pytestmark = pytest.mark.timeout(120)


def _fleet(mock: MockFleet, key: SigningKey) -> FleetSpec:
    return FleetSpec.from_dict({**mock.fleet_dict(), "signing_key": str(key.path)})


@pytest.mark.parametrize("autopilots", [["px4", "px4"], ["ardupilot", "px4"]],
                         ids=["px4", "mixed"])
def test_keys_are_provisioned_then_found_then_changed_with_the_old_key(
        tmp_path: Path, autopilots: list[str]) -> None:
    """The same on PX4 and on ArduPilot (which takes SETUP_SIGNING the same way)."""
    first = new_key_file(tmp_path / "first.key")
    second = new_key_file(tmp_path / "second.key")

    async def main() -> list[list[Any]]:
        async with MockFleet(2, settle_time=0.0, autopilots=autopilots, **mock_ports(2),
                             **FAST_MOCK) as mock:
            runs = [await provision_fleet(_fleet(mock, first), timeout=2.0)]
            assert [v.signing_key for v in mock.vehicles] == [first.secret] * 2
            runs.append(await provision_fleet(_fleet(mock, first), timeout=2.0))
            # a new key without the one they have: PX4 ignores an unsigned SETUP_SIGNING
            runs.append(await provision_fleet(_fleet(mock, second), ["uav1"], timeout=1.0))
            assert mock.vehicles[0].signing_key == first.secret
            runs.append(await provision_fleet(_fleet(mock, second), ["uav1"], old_key=first,
                                              timeout=2.0))
            assert mock.vehicles[0].signing_key == second.secret
            assert mock.vehicles[1].signing_key == first.secret  # not named: untouched
            return [[(o.vehicle, o.ok, o.status, o.detail) for o in run] for run in runs]

    provisioned, again, refused, changed = asyncio.run(main())
    assert [(v, ok, status) for v, ok, status, _ in provisioned] == \
        [("uav1", True, "provisioned"), ("uav2", True, "provisioned")]
    assert all("now signed with" in detail for *_, detail in provisioned)
    assert [(v, ok, status) for v, ok, status, _ in again] == \
        [("uav1", True, "already"), ("uav2", True, "already")]
    assert [(v, ok, status) for v, ok, status, _ in refused] == [("uav1", False, "failed")]
    assert "--old-key" in refused[0][3]
    assert [(v, ok, status) for v, ok, status, _ in changed] == [("uav1", True, "changed")]


def test_an_armed_vehicle_keeps_its_key(tmp_path: Path) -> None:
    key = new_key_file(tmp_path / "fleet.key")

    async def main() -> tuple[Any, ...]:
        async with MockFleet(1, settle_time=0.0, **mock_ports(1), **FAST_MOCK) as mock:
            mock.vehicles[0].armed = True
            [outcome] = await provision_fleet(_fleet(mock, key), timeout=2.0)
            return outcome.ok, outcome.detail, mock.vehicles[0].signing_key

    ok, detail, installed = asyncio.run(main())
    assert not ok and detail.startswith("armed")
    assert installed is None


def test_the_command_provisions_and_never_prints_the_key(tmp_path: Path) -> None:
    key = new_key_file(tmp_path / "fleet.key")
    fleet_path = tmp_path / "fleet.json"

    async def main() -> tuple[subprocess.CompletedProcess[str], bytes | None]:
        async with MockFleet(1, settle_time=0.0, **mock_ports(1), **FAST_MOCK) as mock:
            fleet_path.write_text(json.dumps({**mock.fleet_dict(), "signing_key": "fleet.key"}))
            command = [sys.executable, "-m", "gcs.cli.main", "keys", "provision", "--fleet",
                       str(fleet_path), "--timeout", "3"]
            process = await asyncio.create_subprocess_exec(
                *command, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
            out, err = await asyncio.wait_for(process.communicate(), 60)
            done = subprocess.CompletedProcess(command, process.returncode or 0,
                                               out.decode(), err.decode())
            return done, mock.vehicles[0].signing_key

    result, installed = asyncio.run(main())
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("uav1: provisioned: its traffic is now signed with ")
    assert installed == key.secret
    secret = load_key(key.path).secret
    for text in (result.stdout, result.stderr):
        assert secret.hex() not in text and str(list(secret)) not in text


_ONE = [{"id": "uav1", "connection": "udpin:127.0.0.1:14540", "system_id": 1,
         "home": [0, 0, 0]}]


@pytest.mark.parametrize(("fleet", "extra", "message"), [
    ({"vehicles": _ONE}, [], "no vehicle has a signing_key"),
    ({"vehicles": _ONE, "signing_key": "fleet.key"}, ["--vehicle", "uav9"],
     "--vehicle: no vehicle 'uav9'"),
    ({"vehicles": _ONE, "signing_key": "fleet.key"}, ["--timeout", "nan"],
     "--timeout: must be in"),
    ({"vehicles": _ONE, "signing_key": "fleet.key"}, ["--old-key", "missing.key"],
     "--old-key:"),
], ids=["no-key", "unknown-vehicle", "bad-timeout", "missing-old-key"])
def test_bad_arguments_are_one_line_errors(tmp_path: Path, fleet: dict[str, Any],
                                           extra: list[str], message: str) -> None:
    new_key_file(tmp_path / "fleet.key")
    (tmp_path / "fleet.json").write_text(json.dumps(fleet))
    result = subprocess.run([sys.executable, "-m", "gcs.cli.main", "keys", "provision",
                             "--fleet", "fleet.json", *extra], cwd=tmp_path,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and message in result.stderr, result.stderr
    assert "Traceback" not in result.stderr
