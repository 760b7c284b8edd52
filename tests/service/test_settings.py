"""Settings: defaults < TOML config file < environment < explicit values; bad ones refused."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from pydantic import ValidationError

from gcs.cli.main import main
from gcs.service.settings import Settings, SettingsFileError


@pytest.fixture(autouse=True)
def _isolated(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """No FLEETPLAN_* variable or ./fleetplan.toml of the developer leaks into a test; the
    working directory is the test's own."""
    for name in [n for n in os.environ if n.startswith("FLEETPLAN_")]:
        monkeypatch.delenv(name)
    monkeypatch.chdir(tmp_path)


def test_defaults_are_local_and_safe() -> None:
    settings = Settings()
    assert settings.host == "127.0.0.1" and settings.port == 8000
    assert settings.database_url == "sqlite:///fleetplan.db"
    assert settings.fleet_file is None and settings.mock_vehicles == 4
    assert settings.max_vehicles == 128 and settings.max_body_bytes == 2_000_000


def test_config_file_then_environment_then_explicit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = tmp_path / "site.toml"
    config.write_text('port = 8100\nmax_steps = 300\ndatabase_url = "sqlite:///x.db"\n')
    monkeypatch.setenv("FLEETPLAN_CONFIG", str(config))
    settings = Settings()
    assert (settings.port, settings.max_steps, settings.database_url) == (8100, 300, "sqlite:///x.db")
    monkeypatch.setenv("FLEETPLAN_PORT", "8200")
    assert Settings().port == 8200  # environment beats the file
    assert Settings().max_steps == 300
    assert Settings(port=8300).port == 8300  # explicit (the CLI) beats both


def test_default_config_file_in_the_working_directory(tmp_path: Path) -> None:
    (tmp_path / "fleetplan.toml").write_text("max_vehicles = 12\n")  # cwd is tmp_path
    assert Settings().max_vehicles == 12


def test_a_named_config_file_must_exist(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("FLEETPLAN_CONFIG", str(tmp_path / "missing.toml"))
    with pytest.raises(SettingsFileError, match=r"missing\.toml"):
        Settings()


@pytest.mark.parametrize(
    ("values", "field"),
    [({"port": 0}, "port"), ({"max_vehicles": 0}, "max_vehicles"),
     ({"mock_vehicles": -1}, "mock_vehicles"), ({"colour": "red"}, "colour"),
     ({"fleet_file": "/nonexistent/fleet.json"}, "fleet_file"),
     ({"dt_min": 1.0, "dt_max": 0.5}, "dt_min"), ({"max_coordinate_m": 0}, "max_coordinate_m"),
     ({"max_horizon_s": -1}, "max_horizon_s")],
)
def test_invalid_values_are_refused(values: dict, field: str) -> None:
    with pytest.raises(ValidationError) as caught:
        Settings(**values)
    assert field in str(caught.value)


def test_unknown_key_in_the_config_file(tmp_path: Path) -> None:
    (tmp_path / "fleetplan.toml").write_text("prot = 8000\n")
    with pytest.raises(ValidationError, match="prot"):
        Settings()


def test_serve_refuses_bad_settings_with_a_message(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["serve", "--port", "70000"]) == 2
    assert "port" in capsys.readouterr().err
    assert main(["serve", "--config", str(tmp_path / "nope.toml")]) == 2
    assert "nope.toml" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # --mock and --fleet exclude each other
        main(["serve", "--mock", "2", "--fleet", "fleet.json"])


def test_an_explicit_config_file_beats_the_environment_variable(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "a.toml").write_text("port = 8101\n")
    (tmp_path / "b.toml").write_text("port = 8102\n")
    monkeypatch.setenv("FLEETPLAN_CONFIG", str(tmp_path / "a.toml"))
    assert Settings.load(tmp_path / "b.toml").port == 8102
    assert Settings().port == 8101  # nothing left behind


def test_serve_refuses_a_bad_fleet_file_or_busy_ports_before_starting(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import socket

    from tests.api.support import free_port, free_udp_base

    fleet = tmp_path / "fleet.json"
    fleet.write_text('{"vehicles": [], "colour": "red"}')
    assert main(["serve", "--fleet", str(fleet), "--port", str(free_port())]) == 2
    err = capsys.readouterr().err
    assert "colour: unknown key" in err and "Traceback" not in err

    base = free_udp_base(2)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as busy:
        busy.bind(("127.0.0.1", base + 1))
        monkeypatch.setenv("FLEETPLAN_MOCK_BASE_PORT", str(base))
        code = main(["serve", "--mock", "2", "--port", str(free_port())])
    assert code == 2
    assert f"UDP port {base + 1}" in capsys.readouterr().err

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        taken = busy.getsockname()[1]
        assert main(["serve", "--mock", "0", "--port", str(taken)]) == 2
    assert f"TCP port {taken}" in capsys.readouterr().err
