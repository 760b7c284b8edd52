"""The service's settings, in one place: defaults < config file < environment < explicit values.

`Settings` is a pydantic-settings class. Every field can be set by an environment variable
named ``FLEETPLAN_<FIELD>`` (e.g. ``FLEETPLAN_DATABASE_URL``) or in a TOML config file whose
path is ``$FLEETPLAN_CONFIG`` (default ``fleetplan.toml`` in the working directory; a missing
default file is ignored, a missing named file is an error). The `fleetplan serve` options are
explicit values and win over both.

It imports the mock's settings (`gcs.sim.config`), which the service may only where it hosts
the mock (`tests/test_layout.py`, `ALLOWED`): the `mock_*` settings take the mock's own
timing bounds and realism presets, defined once there. The mock imports only the bottom layer,
so this import runs downward.
"""

from __future__ import annotations

import ipaddress
import os
from contextvars import ContextVar
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import (
    BaseSettings,
    NoDecode,
    PydanticBaseSettingsSource,
    SettingsConfigDict,
    TomlConfigSettingsSource,
)

from gcs.autopilot import px4
from gcs.sim.config import TIMING_BOUNDS, Realism

__all__ = [
    "CONFIG_ENV",
    "DEFAULT_CONFIG_FILE",
    "MIN_TOKEN_LENGTH",
    "MOCK_VEHICLES_MAX",
    "Settings",
    "SettingsFileError",
    "is_loopback",
]

#: Environment variable naming the TOML config file.
CONFIG_ENV = "FLEETPLAN_CONFIG"
#: Config file read when `CONFIG_ENV` is unset (only if it exists).
DEFAULT_CONFIG_FILE = "fleetplan.toml"


#: Most mock vehicles the service may run (each has two UDP ports, in blocks above the base).
MOCK_VEHICLES_MAX = 1024


#: Shortest API token accepted (a token is a password for the fleet).
MIN_TOKEN_LENGTH = 16


def is_loopback(host: str) -> bool:
    """Whether a bind address (or Host name) reaches this machine only."""
    name = host.strip("[]").lower()
    if name == "localhost":
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


class SettingsFileError(FileNotFoundError):
    """The config file named by ``$FLEETPLAN_CONFIG`` does not exist."""


#: The config file named explicitly (`Settings.load`), which beats $FLEETPLAN_CONFIG.
_explicit_config: ContextVar[Path | None] = ContextVar("fleetplan_config", default=None)


def _config_file() -> Path | None:
    explicit = _explicit_config.get()
    if explicit is not None:
        if not explicit.is_file():
            raise SettingsFileError(f"{explicit}: no such config file")
        return explicit
    named = os.environ.get(CONFIG_ENV)
    if named:
        path = Path(named)
        if not path.is_file():
            raise SettingsFileError(f"{CONFIG_ENV}={named}: no such config file")
        return path
    default = Path(DEFAULT_CONFIG_FILE)
    return default if default.is_file() else None


class Settings(BaseSettings):
    """Everything the service can be configured with (see the README's Settings table)."""

    model_config = SettingsConfigDict(env_prefix="FLEETPLAN_", extra="forbid")

    host: str = Field("127.0.0.1", description="Bind address; 127.0.0.1 keeps it local.")
    port: int = Field(8000, ge=1, le=65535, description="TCP port of the HTTP service.")
    database_url: str = Field(
        "sqlite:///fleetplan.db",
        description="SQLAlchemy URL: SQLite file by default, postgresql+psycopg://... to share.",
    )
    fleet_file: Path | None = Field(
        None, description="Fleet JSON (real vehicles or SITL); when set, no mock vehicles start."
    )
    mock_vehicles: int = Field(
        4, ge=0, le=MOCK_VEHICLES_MAX,
        description="Mock PX4 vehicles started in-process when no fleet file."
    )
    mock_max_vehicles: int = Field(
        256, ge=1, le=MOCK_VEHICLES_MAX,
        description="The mock fleet grows to as many vehicles as a plan needs, up to this many "
        "(`--mock auto`, the default); `--mock N` keeps it at N. A plan with more is refused, "
        "naming this setting."
    )
    mock_base_port: int = Field(
        px4.OFFBOARD_GCS_BASE_PORT,
        ge=1024,
        le=65000,
        description="Mock vehicle i sends to UDP base+i and listens on base+40+i (PX4 SITL's).",
    )
    mock_settle_s: float | None = Field(
        None, ge=TIMING_BOUNDS["settle_time"][0], le=TIMING_BOUNDS["settle_time"][1],
        description="Mock vehicles refuse arming this long after they start "
        "(default: the realism's, 5 s ideal, 3.5 s px4; PX4 SITL's estimator settles in 3-5 s)."
    )
    mock_status_rate_hz: float | None = Field(
        None, gt=TIMING_BOUNDS["status_rate"][0], le=TIMING_BOUNDS["status_rate"][1],
        description="Mock vehicles' HEARTBEAT, SYS_STATUS and "
        "EXTENDED_SYS_STATE rate (Hz; default the realism's, 1 Hz as PX4's `mavlink stream` "
        "default): a faster one confirms mode and arming changes sooner."
    )
    mock_land_speed: float | None = Field(
        None, ge=TIMING_BOUNDS["land_speed"][0], le=TIMING_BOUNDS["land_speed"][1],
        description="Mock vehicles' descent speed when landing (m/s; "
        "PX4's MPC_LAND_SPEED, default 0.7)."
    )
    mock_disarm_after_land_s: float | None = Field(
        None, ge=TIMING_BOUNDS["disarm_after_land"][0], le=TIMING_BOUNDS["disarm_after_land"][1],
        description="Mock vehicles disarm this long after touching down "
        "(s; PX4's COM_DISARM_LAND, default 2)."
    )
    mock_realism: Realism = Field(
        "ideal", description="Mock vehicles' behaviour: ideal (exact state) or px4 (PX4 SIH "
        "SITL's estimate noise, tracking lag and timings)."
    )
    mock_autopilot: str = Field(
        "px4", pattern=r"^(px4|ardupilot)(,(px4|ardupilot))*$",
        description="Mock vehicles' autopilot: px4, ardupilot (ArduCopter 4.7's rules), or a "
        "comma-separated list given to the vehicles in turn (px4,ardupilot: a mixed fleet)."
    )
    vehicle_thread_priority: Literal["ordinary", "realtime"] = Field(
        "realtime", description="Scheduling of the thread that talks to the vehicles "
        "(flights, mock vehicles, fleet monitor; in the vehicle process): realtime asks Linux "
        "for SCHED_RR 1 (root, CAP_SYS_NICE or an rtprio limit; refused: logged, ordinary "
        "scheduling), so a busy machine never keeps a setpoint tick waiting for a core."
    )
    max_vehicles: int = Field(128, ge=1, le=20_000, description="Largest fleet a mission may "
                              "plan (the planner's own bound is 20,000).")
    max_steps: int = Field(1000, ge=3, le=5000, description="Largest `steps` a mission may use.")
    max_obstacles: int = Field(
        200, ge=0, le=1000, description="Most obstacles a mission's scenario may hold."
    )
    dt_min: float = Field(0.01, gt=0, description="Shortest step `dt` a mission may use (s).")
    dt_max: float = Field(5.0, gt=0, le=60, description="Longest step `dt` a mission may use (s).")
    max_horizon_s: float = Field(
        900.0, gt=0, le=86_400,
        description="Longest horizon steps * dt a mission may plan, and so fly (s).",
    )
    max_coordinate_m: float = Field(
        10_000.0, gt=0, le=1_000_000,
        description="Largest distance of any workspace corner, start or goal from the origin "
        "along each axis (m).",
    )
    max_body_bytes: int = Field(
        2_000_000, ge=1024, description="Largest request body accepted (bytes)."
    )
    max_plan_body_bytes: int = Field(
        64_000_000, ge=1024, le=1_000_000_000,
        description="Largest body of POST /api/missions (bytes), which may carry a plan made "
        "elsewhere to fly (a 128-vehicle plan of 150 steps is about 6.4 MB); every other "
        "request keeps max_body_bytes.",
    )
    request_timeout_s: float = Field(
        10.0, gt=0, le=600, description="Longest a request may take to arrive in full (head "
        "and body) once started; a connection that sends nothing, or too slowly, is closed."
    )
    idle_timeout_s: float = Field(
        5.0, ge=1, le=600, description="How long a kept-alive connection may stay idle "
        "between requests before it is closed."
    )
    max_concurrent_exports: int = Field(
        4, ge=1, le=256, description="Trajectory exports computed at once; more answer 503 "
        "with Retry-After."
    )
    max_event_streams: int = Field(
        128, ge=1, le=10_000, description="Event streams (server-sent events) open at once "
        "in total; more answer 503 with Retry-After."
    )
    max_event_streams_per_resource: int = Field(
        32, ge=1, le=10_000, description="Event streams open at once on one mission or "
        "flight; more answer 503 with Retry-After."
    )
    max_trajectory_rate: float = Field(
        100.0, gt=0, le=1000, description="Highest sampling rate of /trajectory (Hz)."
    )
    max_trajectory_samples: int = Field(
        500_000, ge=1000, description="Most vehicle-time samples one /trajectory answer holds."
    )
    plan_workers: int = Field(
        max(2, (os.cpu_count() or 2) - 1),
        ge=1,
        le=64,
        description="Worker processes of the embedded Dask cluster that run the planner "
        "(never the event loop); with 2 or more, a small plan never waits behind large ones.",
    )
    plan_wait_s: float = Field(
        5.0,
        ge=0,
        le=600,
        description="How long POST /api/missions waits for a plan before answering 202.",
    )
    scheduler: str | None = Field(
        None, description="Dask scheduler address (tcp://HOST:8786) to plan on; None: an "
        "embedded local cluster of plan_workers processes."
    )
    plan_time_limit_s: float = Field(
        600.0, gt=0, le=86_400, description="Longest a plan may compute (s); a request may "
        "ask for less with ?time_limit=."
    )
    plan_queue_max: int = Field(
        16, ge=1, le=10_000, description="Plans queued or running at once; more are refused "
        "with 503."
    )
    planner_solver: str | None = Field(
        None, description="QP backend passed to the planner (None: the planner's default)."
    )
    web_dir: Path | None = Field(
        None, description="Serve the browser page from here instead of the bundled copy."
    )
    allowed_hosts: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="Host header names the service answers (comma-separated in the "
        "environment); empty: the names it is bound to. Anything else is refused (DNS "
        "rebinding). '*' answers any name.",
    )
    allowed_origins: Annotated[list[str], NoDecode] = Field(
        default_factory=list,
        description="Other origins (scheme://host:port) allowed to send state-changing "
        "requests; the service's own origin always is.",
    )
    api_token: SecretStr | None = Field(
        None, description="Operator token (plan, fly, abort, command). Required when the "
        "service binds beyond loopback; when set, every API request needs a token."
    )
    api_token_file: Path | None = Field(
        None, description="File holding the operator token (instead of api_token)."
    )
    read_token: SecretStr | None = Field(
        None, description="Read-only token: GET requests only. Needs an operator token too."
    )
    read_token_file: Path | None = Field(
        None, description="File holding the read-only token (instead of read_token)."
    )

    @classmethod
    def load(cls, config_file: Path | None = None, **values: Any) -> Settings:
        """Settings from `config_file` (instead of $FLEETPLAN_CONFIG / ./fleetplan.toml), the
        environment and `values` (the command line), in increasing priority."""
        token = _explicit_config.set(config_file)
        try:
            return cls(**values)
        finally:
            _explicit_config.reset(token)

    @field_validator("allowed_hosts", "allowed_origins", mode="before")
    @classmethod
    def _comma_separated(cls, value: Any) -> Any:
        if isinstance(value, str):
            return [part.strip() for part in value.split(",") if part.strip()]
        return value

    @model_validator(mode="after")
    def _tokens(self) -> Settings:
        """Tokens from their files; an operator token whenever the bind address is reachable
        from other machines; tokens long enough not to be guessed."""
        for name in ("api_token", "read_token"):
            path: Path | None = getattr(self, f"{name}_file")
            if path is None:
                continue
            if getattr(self, name) is not None:
                raise ValueError(f"set {name} or {name}_file, not both")
            try:
                text = path.read_text().strip()
            except OSError as exc:
                raise ValueError(f"{name}_file {path}: {exc.strerror or exc}") from None
            object.__setattr__(self, name, SecretStr(text))
        for name in ("api_token", "read_token"):
            token: SecretStr | None = getattr(self, name)
            if token is not None and len(token.get_secret_value()) < MIN_TOKEN_LENGTH:
                raise ValueError(f"{name} must be at least {MIN_TOKEN_LENGTH} characters")
        if self.api_token is None and not is_loopback(self.host):
            raise ValueError(
                f"host {self.host} is reachable from other machines: set an operator token "
                "(api_token, api_token_file or FLEETPLAN_API_TOKEN)"
            )
        if self.read_token is not None and self.api_token is None:
            raise ValueError("read_token needs an operator token (api_token) as well")
        if (self.read_token is not None and self.api_token is not None
                and self.read_token.get_secret_value() == self.api_token.get_secret_value()):
            raise ValueError("read_token must differ from api_token")
        return self

    @model_validator(mode="after")
    def _dt_range(self) -> Settings:
        if self.dt_min >= self.dt_max:
            raise ValueError(f"dt_min ({self.dt_min:g}) must be less than dt_max ({self.dt_max:g})")
        return self

    @property
    def mock_fleet_limit(self) -> int:
        """Most vehicles the mock fleet flies: it grows to `mock_max_vehicles` as plans need,
        and never has fewer than the `mock_vehicles` it starts with."""
        return max(self.mock_vehicles, self.mock_max_vehicles)

    @property
    def mock_fleet_grows(self) -> bool:
        """Mock vehicles are added as plans need them (`--mock auto`), rather than the fleet
        keeping the `mock_vehicles` it starts with (`--mock N`)."""
        return 0 < self.mock_vehicles < self.mock_max_vehicles

    @model_validator(mode="after")
    def _fleet_file_exists(self) -> Settings:
        if self.fleet_file is not None and not self.fleet_file.is_file():
            raise ValueError(f"fleet_file {self.fleet_file} does not exist")
        return self

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        """Explicit values, then environment, then the TOML config file."""
        sources: list[PydanticBaseSettingsSource] = [init_settings, env_settings]
        path = _config_file()
        if path is not None:
            sources.append(TomlConfigSettingsSource(settings_cls, toml_file=path))
        return tuple(sources)
