"""What to do about an error, added to the CLI's one-line messages (defined once for the
commands that meet the same error)."""

from __future__ import annotations

import errno

from gcs.documents import FlightEvent
from gcs.flight.link.signing import REPEATED_TIMESTAMPS
from gcs.phases import EventKind

__all__ = ["block_error", "live_warning", "port_error", "port_in_use_hint"]


def port_in_use_hint(exc: BaseException, options: str) -> str:
    """" (...: choose free ports with OPTIONS)" when `exc` or its cause is a UDP port that is
    already taken, else ""."""
    for error in (exc, exc.__cause__):
        if isinstance(error, OSError) and error.errno == errno.EADDRINUSE:
            return (f" (the port is taken, perhaps by another fleetplan fly or mock: choose "
                    f"free ports with {options})")
    return ""


def port_error(flag: str, port: int | None) -> str | None:
    """Why `port` given as `flag` is not a UDP port, or None (also when not given)."""
    if port is None or 1 <= port <= 65535:
        return None
    return f"{flag} must be a UDP port (1..65535), got {port}"


def block_error(flag: str, base: int | None, count: int) -> str | None:
    """Why the `count` UDP ports from `base` (given as `flag`) are not all ports, or None (also
    when not given): one vehicle each, base..base + count - 1."""
    if base is None or 1 <= base <= base + count - 1 <= 65535:
        return None
    vehicles = f"{count} vehicle{'' if count == 1 else 's'}"
    return (f"{flag} {base} with {vehicles} needs UDP ports {base}..{base + count - 1}: give a "
            f"base port from 1 to {65536 - count}")


def live_warning(event: FlightEvent, options: str) -> str | None:
    """The warning line `fleetplan fly` prints at once for a flight event the operator must
    see (packets from someone else arriving as a vehicle), naming what to change
    (`options`); None for any other event."""
    if event.get("kind") != EventKind.DROPPED_PACKETS:
        return None
    who = event.get("vehicle") or "fleet"
    if REPEATED_TIMESTAMPS in str(event.get("detail")):
        return (f"warning: {who}: {event.get('detail')} (expected right after a vehicle "
                f"boots and at a few a minute later; a steady rate in flight is recorded "
                f"traffic played back to the GCS, perhaps from a forged address)")
    return (f"warning: {who}: {event.get('detail')}: something else is sending to this "
            f"vehicle's port (another fleetplan fly or mock on the same ports? choose free "
            f"ports with {options})")
