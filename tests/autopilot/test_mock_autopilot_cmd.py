"""`fleetplan mock --autopilot`: the mock's autopilot by name, or one per vehicle."""

from __future__ import annotations

import pytest

from gcs.cli.main import main
from tests.flight.support import mock_ports


def test_an_unknown_or_miscounted_autopilot_is_one_line_error(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["mock", "-n", "2", "--autopilot", "apm", "--duration", "0"]) == 2
    assert "--autopilot must be px4 or ardupilot" in capsys.readouterr().err
    assert main(["mock", "-n", "3", "--autopilot", "px4,ardupilot", "--duration", "0"]) == 2
    assert "one of them per vehicle (3)" in capsys.readouterr().err


def test_a_mixed_mock_fleet_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    ports = mock_ports(2)
    assert main(["mock", "-n", "2", "--autopilot", "ardupilot,px4", "--duration", "0.2",
                 "--base-port", str(ports["gcs_base_port"]),
                 "--listen-base-port", str(ports["listen_base_port"])]) == 0
    assert "2 PX4- and ArduCopter-like vehicles" in capsys.readouterr().out
