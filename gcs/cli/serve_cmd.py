"""`fleetplan serve`: the REST API and browser page (uvicorn), with mock or configured vehicles.

Options override the settings (environment ``FLEETPLAN_*`` and the TOML config file; see
`gcs.service.settings`). `--mock N` starts N in-process mock PX4 vehicles; `--fleet
FLEET.json` flies real vehicles or SITL instead. Nothing arms or moves until an execution
is requested.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gcs.service.settings import Settings

__all__ = ["configure", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", help="bind address (default 127.0.0.1: this machine only)")
    parser.add_argument("--port", type=int, help="TCP port (default 8000)")
    parser.add_argument("--db", metavar="URL",
                        help="database URL (default sqlite:///fleetplan.db; or postgresql+psycopg://...)")
    vehicles = parser.add_mutually_exclusive_group()
    vehicles.add_argument("--mock", type=int, metavar="N",
                          help="start N mock PX4 vehicles in-process (default 4)")
    vehicles.add_argument("--fleet", type=Path, metavar="FLEET.json",
                          help="fleet file of real vehicles or SITL instances")
    parser.add_argument("--workers", type=int, metavar="N",
                        help="planner worker processes (default: CPU count - 1)")
    parser.add_argument("--config", type=Path, metavar="FILE.toml",
                        help="settings file (default $FLEETPLAN_CONFIG or ./fleetplan.toml)")
    parser.add_argument("--log-level", default="info",
                        choices=("critical", "error", "warning", "info", "debug"))


def _port_free(kind: int, port: int, host: str = "127.0.0.1") -> bool:
    import socket

    with socket.socket(socket.AF_INET, kind) as sock:
        try:
            sock.bind((host, port))
        except OSError:
            return False
    return True


def _startup_problem(settings: Settings) -> str | None:
    """What would stop the service from starting, in one line (None: nothing), checked
    before uvicorn so a bad fleet file or a busy port is a message, not a traceback."""
    import socket

    from gcs.errors import FleetFileError
    from gcs.flight.fleetfile import load_fleet
    from gcs.sim.ports import mock_port_offsets

    fleet_file = settings.fleet_file
    if fleet_file is not None:
        try:
            load_fleet(fleet_file)
        except FleetFileError as exc:
            return f"fleet file {fleet_file}: {exc.field}: {exc.reason}"
    elif settings.mock_vehicles:
        base, count = settings.mock_base_port, settings.mock_vehicles
        for port in (base + offset for offset in mock_port_offsets(count)):
            if not _port_free(socket.SOCK_DGRAM, port):
                return (f"UDP port {port} (mock vehicles, mock_base_port {base}) is in use: "
                        f"another fleetplan or PX4 SITL running? Set FLEETPLAN_MOCK_BASE_PORT")
    host, port = settings.host, settings.port
    if ":" not in host and not _port_free(socket.SOCK_STREAM, port, host):
        return f"TCP port {port} on {host} is in use: choose another with --port"
    return None


def run(args: argparse.Namespace) -> int:
    import uvicorn
    from pydantic import ValidationError

    from gcs.api import create_app
    from gcs.service.settings import Settings, SettingsFileError

    overrides = {
        key: value
        for key, value in (
            ("host", args.host),
            ("port", args.port),
            ("database_url", args.db),
            ("mock_vehicles", args.mock),
            ("fleet_file", args.fleet),
            ("plan_workers", args.workers),
        )
        if value is not None
    }
    try:
        settings = Settings.load(args.config, **overrides)
    except (ValidationError, SettingsFileError) as exc:
        print(f"fleetplan serve: invalid settings: {exc}", file=sys.stderr)
        return 2
    problem = _startup_problem(settings)
    if problem is not None:
        print(f"fleetplan serve: {problem}", file=sys.stderr)
        return 2
    app = create_app(settings)
    fleet = (
        f"fleet file {settings.fleet_file}"
        if settings.fleet_file
        else f"{settings.mock_vehicles} mock vehicles"
    )
    host = f"[{settings.host}]" if ":" in settings.host else settings.host
    print(f"fleetplan: serving on http://{host}:{settings.port}/ ({fleet}, "
          f"database {settings.database_url})", flush=True)
    uvicorn.run(app, host=settings.host, port=settings.port, log_level=args.log_level)
    return 0
