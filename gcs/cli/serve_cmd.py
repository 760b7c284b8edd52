"""`fleetplan serve`: the REST API and browser page (uvicorn), with mock or configured vehicles.

Options override the settings (environment ``FLEETPLAN_*`` and the TOML config file; see
`gcs.service.settings`). `--mock N` runs N in-process mock PX4 vehicles; `--mock auto` (the
default) starts `mock_vehicles` and adds mocks as a plan needs them, up to
`mock_max_vehicles`; `--fleet FLEET.json` flies real vehicles or SITL instead. Nothing arms
or moves until a flight is requested.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

if TYPE_CHECKING:
    from gcs.service.settings import Settings

__all__ = ["configure", "overrides", "port_free", "run", "scheduler_problem",
           "uvicorn_server"]


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--host", help="bind address (default 127.0.0.1: this machine only)")
    parser.add_argument("--port", type=int, help="TCP port (default 8000)")
    parser.add_argument("--db", metavar="URL",
                        help="database URL (default sqlite:///fleetplan.db; or postgresql+psycopg://...)")
    vehicles = parser.add_mutually_exclusive_group()
    vehicles.add_argument("--mock", type=_mock_count, metavar="N|auto",
                          help="N: run N mock PX4 vehicles in-process; auto (the default): "
                          "start 4 and add as many as a plan needs, up to 256 (settings "
                          "mock_vehicles, mock_max_vehicles)")
    vehicles.add_argument("--fleet", type=Path, metavar="FLEET.json",
                          help="fleet file of real vehicles or SITL instances")
    parser.add_argument("--workers", type=int, metavar="N",
                        help="planner worker processes of the embedded Dask cluster "
                        "(default: CPU count - 1, at least 2)")
    parser.add_argument("--scheduler", metavar="tcp://HOST:8786",
                        help="plan on this existing Dask cluster instead of an embedded one "
                        "(setting FLEETPLAN_SCHEDULER)")
    parser.add_argument("--config", type=Path, metavar="FILE.toml",
                        help="settings file (default $FLEETPLAN_CONFIG or ./fleetplan.toml)")
    parser.add_argument("--log-level", default="info",
                        choices=("critical", "error", "warning", "info", "debug"))


def _mock_count(text: str) -> int | None:
    """`--mock`: a vehicle count, or auto (None: the settings' growing mock fleet)."""
    if text == "auto":
        return None
    try:
        count = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is neither a vehicle count nor auto") from None
    if count < 0:
        raise argparse.ArgumentTypeError(f"{count} vehicles: give 0 or more, or auto")
    return count


#: Seconds open responses (event streams) get to end once the service is told to stop.
GRACEFUL_SHUTDOWN_S = 5


def port_free(kind: int, port: int, host: str = "127.0.0.1") -> bool:
    """Can `port` be bound now? TCP is tried the way uvicorn binds (SO_REUSEADDR), so a
    TIME_WAIT left by closed client connections does not read as "in use"."""
    import socket

    with socket.socket(socket.AF_INET, kind) as sock:
        if kind == socket.SOCK_STREAM:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError:
            return False
    return True


def _database_problem(url: str) -> str | None:
    """Why the database cannot be used (missing directory, read-only, unreachable), in one
    line; None when a write could be made."""
    from sqlalchemy.exc import SQLAlchemyError

    from gcs.service.store import Store

    store = None
    try:
        store = Store(url)
        store.check_writable()
    except (SQLAlchemyError, OSError) as exc:
        reason = str(getattr(exc, "orig", None) or exc).strip().splitlines()
        return f"database {url} cannot be used: {reason[0] if reason else type(exc).__name__}"
    finally:
        if store is not None:
            store.close()
    return None


def _startup_problem(settings: Settings) -> str | None:
    """What would stop the service from starting, in one line (None: nothing), checked
    before uvicorn so a bad fleet file or a busy port is a message, not a traceback."""
    import socket

    from gcs.errors import FleetFileError
    from gcs.fleet.fleetfile import load_fleet
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
            if not port_free(socket.SOCK_DGRAM, port):
                return (f"UDP port {port} (mock vehicles, mock_base_port {base}) is in use: "
                        f"another fleetplan or PX4 SITL running? Set FLEETPLAN_MOCK_BASE_PORT")
    host, port = settings.host, settings.port
    if ":" not in host and not port_free(socket.SOCK_STREAM, port, host):
        return f"TCP port {port} on {host} is in use: choose another with --port"
    return _database_problem(settings.database_url) or scheduler_problem(settings.scheduler)


def scheduler_problem(address: str | None, timeout: float = 30.0) -> str | None:
    """Why the Dask scheduler named by the `scheduler` setting cannot be used (None: it
    answers, or none is named). Waits up to `timeout` for one that is still starting."""
    if not address:
        return None
    from distributed import Client

    try:
        with Client(address, timeout=timeout):
            return None
    except (OSError, TimeoutError, ValueError) as exc:
        return f"cannot reach the Dask scheduler at {address} (setting scheduler): {exc}"


async def _on_stop_signal(app: Any) -> None:
    """SIGTERM/SIGINT: land the flight under way now and end the event streams, so the
    server's graceful shutdown (which waits for open responses) is not held up by them."""
    from gcs.service.events import end_streams

    end_streams()
    fleet = getattr(app.state, "fleet", None)
    flight = None if fleet is None else fleet.active
    if fleet is not None and flight is not None:
        with contextlib.suppress(Exception):
            await fleet.abort(flight.id, "land", "the service is stopping")


def uvicorn_server(app: Any, settings: Settings, log_level: str) -> Any:
    """A uvicorn server whose stop signals also call `_on_stop_signal`."""
    import asyncio

    import uvicorn

    class Server(uvicorn.Server):
        loop: asyncio.AbstractEventLoop | None = None
        stopping: ClassVar[set[asyncio.Task[None]]] = set()

        async def startup(self, sockets: Any = None) -> None:
            self.loop = asyncio.get_running_loop()
            await super().startup(sockets)

        def handle_exit(self, sig: int, frame: Any) -> None:
            super().handle_exit(sig, frame)
            loop = self.loop
            if loop is not None and not loop.is_closed():
                loop.call_soon_threadsafe(self._stop_now)

        def _stop_now(self) -> None:
            task = asyncio.ensure_future(_on_stop_signal(app))
            self.stopping.add(task)
            task.add_done_callback(self.stopping.discard)

    from gcs.api.connection_timeout import request_deadline_protocol

    config = uvicorn.Config(app, host=settings.host, port=settings.port, log_level=log_level,
                            timeout_graceful_shutdown=GRACEFUL_SHUTDOWN_S,
                            http=request_deadline_protocol(settings.request_timeout_s),
                            timeout_keep_alive=max(1, round(settings.idle_timeout_s)))
    return Server(config)


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The settings the options give (None: not given); `--mock N` runs N mock vehicles and
    no more, `--mock auto` leaves the mock fleet's settings as they are."""
    return {
        key: value
        for key, value in (
            ("host", args.host),
            ("port", args.port),
            ("database_url", args.db),
            ("mock_vehicles", args.mock),
            ("mock_max_vehicles", args.mock or None),
            ("fleet_file", args.fleet),
            ("plan_workers", args.workers),
            ("scheduler", args.scheduler),
        )
        if value is not None
    }


def run(args: argparse.Namespace) -> int:
    from pydantic import ValidationError

    from gcs.service.settings import Settings, SettingsFileError

    try:
        settings = Settings.load(args.config, **overrides(args))
    except (ValidationError, SettingsFileError) as exc:
        print(f"fleetplan serve: invalid settings: {exc}", file=sys.stderr)
        return 2
    problem = _startup_problem(settings)
    if problem is not None:
        print(f"fleetplan serve: {problem}", file=sys.stderr)
        return 2
    from gcs.api import create_app  # the web stack: imported once the settings are usable

    app = create_app(settings)
    fleet = (
        f"fleet file {settings.fleet_file}"
        if settings.fleet_file
        else f"{settings.mock_vehicles} mock vehicles" + (
            f", more as a plan needs them up to {settings.mock_fleet_limit}"
            if settings.mock_fleet_grows else "")
    )
    host = f"[{settings.host}]" if ":" in settings.host else settings.host
    print(f"fleetplan: serving on http://{host}:{settings.port}/ ({fleet}, "
          f"database {settings.database_url})", flush=True)
    uvicorn_server(app, settings, args.log_level).run()
    return 0
