"""A fleet file's homes as a show's takeoff grid: `takeoff.homes` of a formation sequence
(`planner.methods.ground`) filled from where each vehicle stands (its `home`, world frame ENU),
so the show takes off from the spots the fleet was set down on.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from gcs.errors import FleetFileError
from gcs.fleet.fleetfile import FleetSpec
from planner.verification.ground import GROUND_TOLERANCE

__all__ = ["with_fleet_homes"]


def with_fleet_homes(sequence: Mapping[str, Any], fleet: FleetSpec,
                     where: str = "takeoff.fleet") -> dict[str, Any]:
    """`sequence` with `takeoff.homes` = the fleet's homes in the sequence's vehicle order
    (`takeoff.fleet` dropped, its other keys kept). `FleetFileError` naming `where` and the
    vehicle: one the fleet lacks, one without a `home`, a home off the ground (z != 0), or a
    takeoff that gives its homes already. A sequence without a list of ids is left as it is,
    for the sequence parser to name."""
    ids = sequence.get("vehicles")
    if not isinstance(ids, list) or not all(isinstance(vid, str) for vid in ids):
        return dict(sequence)
    raw = sequence.get("takeoff", {})
    takeoff = {k: v for k, v in raw.items() if k != "fleet"} if isinstance(raw, Mapping) else {}
    given = [key for key in ("homes", "grid") if key in takeoff]
    if given:
        raise FleetFileError(where, f"the homes come from the fleet file: drop takeoff."
                                    f"{given[0]}, or the fleet file")
    by_id = {v.id: v for v in fleet.vehicles}
    homes = []
    for vid in ids:
        spec = by_id.get(vid)
        if spec is None:
            raise FleetFileError(where, f"vehicle {vid!r} is not in the fleet file (it has "
                                        f"{len(by_id)} vehicles); add it with its home")
        if spec.home is None:
            raise FleetFileError(where, f"vehicle {vid!r} has no home in the fleet file (its "
                                        f"home would come from GPS at connection); give it "
                                        f"home [x, y, 0]")
        x, y, z = (float(c) for c in spec.home)
        if abs(z) > GROUND_TOLERANCE:  # the ground the planner's ground rule measures
            raise FleetFileError(where, f"vehicle {vid!r} has its home at z = {z:g} m; a "
                                        f"show takes off from the ground (z = 0)")
        homes.append([x, y])
    return {**sequence, "takeoff": {**takeoff, "homes": homes}}
