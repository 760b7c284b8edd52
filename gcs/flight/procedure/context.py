"""What a flight lends the steps it runs on a vehicle: one object instead of a bundle of
callbacks.

The executor makes one `FlightContext` per flight and hands it to the procedure's endings
(`gcs.flight.procedure.endings`), the failsafe's set and restore
(`gcs.flight.procedure.failsafe`), the fault policy (`gcs.flight.safety.policy`), the planned
landing (`gcs.flight.safety.landing`) and the replans (`gcs.flight.replan.replan`). What a
step needs of one vehicle (its link, its autopilot) is on the vehicle (`VehicleStatus`); what
it needs of the flight is here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.link.station import StationStalls
from gcs.flight.procedure.vehicle import Emit

__all__ = ["FlightContext", "StopStream"]

#: Called with a vehicle id to stop streaming setpoints to it.
StopStream = Callable[[str], None]


def _nothing_streams(vehicle_id: str) -> None:
    """Outside a flight nothing streams setpoints: there is nothing to stop."""


@dataclass(frozen=True)
class FlightContext:
    """The flight a step runs in."""

    options: FlightOptions
    """The flight's options: timeouts, actions, the fleet's choices."""
    emit: Emit
    """Records an event: (vehicle id, or None for the fleet; event kind; detail)."""
    stalls: StationStalls = field(default_factory=StationStalls)
    """The station's own stalls: every timeout counts station-running time
    (`StationStalls.clock`), so a stall of the station does not use it up."""
    stop_stream: StopStream = _nothing_streams
    """Stops the setpoints streamed to a vehicle (by id). The procedure stays below the
    streamer (`gcs.flight.timeline.stream`), which only the executor holds."""

    def clock(self) -> float:
        """Station-running time (s): the clock every timeout of the flight counts on."""
        return self.stalls.clock()
