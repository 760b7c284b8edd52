"""The autopilots the GCS flies, behind one seam (`base.Autopilot`), and how one is chosen.

A vehicle's autopilot is told by its HEARTBEAT.autopilot (PX4 12, ArduPilot 3), or named in
the fleet file (``autopilot: auto | px4 | ardupilot``; auto, the default, detects it).
"""

from __future__ import annotations

from gcs.autopilot.ardupilot import ARDUPILOT
from gcs.autopilot.base import Autopilot, FlightMode, LinkLossFailsafe
from gcs.autopilot.px4 import PX4

__all__ = ["AUTOPILOTS", "CHOICES", "DEFAULT", "Autopilot", "FlightMode", "LinkLossFailsafe",
           "by_heartbeat", "by_key", "choose", "decode_mode"]

#: Every autopilot the GCS flies, by its fleet-file name.
AUTOPILOTS: dict[str, Autopilot] = {a.key: a for a in (PX4, ARDUPILOT)}
#: The autopilot a vehicle is taken to be until it is heard (what a fleet file without
#: `autopilot` has always flown).
DEFAULT: Autopilot = PX4
#: The fleet file's `autopilot` values.
CHOICES = ("auto", *AUTOPILOTS)


def by_key(key: str) -> Autopilot:
    """The autopilot the fleet file names `key` (``px4`` or ``ardupilot``)."""
    return AUTOPILOTS[key]


def by_heartbeat(mav_autopilot: int | None) -> Autopilot | None:
    """The autopilot a HEARTBEAT's `autopilot` field names, or None for any other."""
    return next((a for a in AUTOPILOTS.values() if a.mav_autopilot == mav_autopilot), None)


def choose(setting: str, mav_autopilot: int | None) -> Autopilot | str:
    """The autopilot to fly a vehicle with, by the fleet file's `setting` and the autopilot
    its HEARTBEAT reports; a string saying why none when they disagree or none is known."""
    heard = by_heartbeat(mav_autopilot)
    if setting == "auto":
        if heard is None:
            known = ", ".join(f"{a.title} = {a.mav_autopilot}" for a in AUTOPILOTS.values())
            return (f"autopilot type {mav_autopilot} is neither of those it can fly ({known}); "
                    f"if it is one of them, name it in the fleet file (autopilot: "
                    f"{' | '.join(AUTOPILOTS)})")
        return heard
    named = by_key(setting)
    if heard is not None and heard is not named:
        return (f"the fleet file says autopilot {setting}, but its HEARTBEAT says {heard.title} "
                f"(autopilot type {mav_autopilot}): fix the fleet file's autopilot")
    return named


