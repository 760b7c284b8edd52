"""The PX4-like mock autopilot (the stand-in for PX4 SITL in tests and demos).

`fleet.MockFleet` of `vehicle.MockVehicle`s (its parts: `core`, `commands`, `setpoints`,
`signing`, `statustext`, `messages`, `telemetry`, `config`), moved by `model.FleetModel`, on
the port rule of `ports`. It never imports `gcs.flight` (see `gcs.sim.vehicle`).
"""

from gcs.sim.config import MockConfig, MockFaults
from gcs.sim.fleet import DEFAULT_WORLD_ORIGIN, MockFleet, homes_under
from gcs.sim.setpoints import ReceivedSetpoint
from gcs.sim.vehicle import MockVehicle

__all__ = ["DEFAULT_WORLD_ORIGIN", "MockConfig", "MockFaults", "MockFleet", "MockVehicle",
           "ReceivedSetpoint", "homes_under"]
