"""The PX4-like mock autopilot (the stand-in for PX4 SITL in tests and demos).

`fleet.MockFleet` of `vehicle.MockVehicle`s, moved by `model.FleetModel`, on the port rule of
`ports`. It never imports `gcs.flight` (see `gcs.sim.vehicle`).
"""

from gcs.sim.fleet import DEFAULT_WORLD_ORIGIN, MockFleet, homes_under
from gcs.sim.vehicle import MockConfig, MockFaults, MockVehicle, ReceivedSetpoint

__all__ = ["DEFAULT_WORLD_ORIGIN", "MockConfig", "MockFaults", "MockFleet", "MockVehicle",
           "ReceivedSetpoint", "homes_under"]
