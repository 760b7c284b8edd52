"""The PX4-like mock autopilot (the stand-in for PX4 SITL in tests and demos).

`fleet.MockFleet` of `vehicle.MockVehicle`s (its parts: `core`, `commands`, `setpoints`,
`signing`, `statustext`, `messages`, `telemetry`, `config`), moved by `model.FleetModel`, on
the port rule of `ports`. It never imports `gcs.flight` (see `gcs.sim.vehicle`).

The names below are imported on first use (PEP 562), so a module that needs only a plain part
(`realism`'s presets for a CLI flag, `ports`) does not load the mock and numpy with it.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gcs.sim.config import MockConfig, MockFaults
    from gcs.sim.fleet import DEFAULT_WORLD_ORIGIN, MockFleet, homes_under
    from gcs.sim.setpoints import ReceivedSetpoint
    from gcs.sim.vehicle import MockVehicle

__all__ = ["DEFAULT_WORLD_ORIGIN", "MockConfig", "MockFaults", "MockFleet", "MockVehicle",
           "ReceivedSetpoint", "homes_under"]

#: The module each name lives in.
_HOMES = {"MockConfig": "config", "MockFaults": "config", "DEFAULT_WORLD_ORIGIN": "fleet",
          "MockFleet": "fleet", "homes_under": "fleet", "ReceivedSetpoint": "setpoints",
          "MockVehicle": "vehicle"}


def __getattr__(name: str) -> Any:
    """Import a name's module the first time the name is asked for."""
    if name not in _HOMES:
        raise AttributeError(f"module 'gcs.sim' has no attribute {name!r}")
    return getattr(import_module(f"gcs.sim.{_HOMES[name]}"), name)
