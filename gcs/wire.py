"""MAVLink facts shared by the GCS (`gcs.flight`) and the PX4-like mock (`gcs.sim`), each once.

- the wire format: pymavlink's MAVLink 2 `common` dialect (this module is the one place that
  selects it, through the ``MAVLINK20`` environment variable);
- the GCS's own identity (system 255, MAV_COMP_ID_MISSIONPLANNER) and MAV_RESULT names, from
  pymavlink's enums;
- the setpoint encoding: frame MAV_FRAME_LOCAL_NED and the POSITION_TARGET_TYPEMASK bits, from
  pymavlink, not hand-copied numbers; `time_boot_ms`;
- UDP URLs (``udpin:HOST:PORT`` / ``udpout:HOST:PORT``): `parse_udp_url`;
- `parse_datagram`: one UDP datagram decoded by a fresh parser, so garbage in one datagram can
  never swallow the next one;
- `Datagrams`: the one asyncio DatagramProtocol adapter (GCS endpoints and mock vehicles).

Everything here is a constant, a pure function or a tiny adapter, so the mock can share it
without sharing our link code (`gcs.flight.link`).
"""

from __future__ import annotations

import asyncio
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink

from gcs.errors import LinkError

__all__ = [
    "GCS_COMPONENT_ID",
    "GCS_SYSTEM_ID",
    "MAV_FRAME_LOCAL_NED",
    "TYPE_MASK_POS_VEL_ACC_YAW",
    "Datagrams",
    "ParsedDatagram",
    "is_udp_url",
    "mavlink",
    "parse_datagram",
    "parse_udp_url",
    "result_name",
    "time_boot_ms",
]

#: The GCS's own MAVLink identity: system 255, MAV_COMP_ID_MISSIONPLANNER (190).
GCS_SYSTEM_ID = 255
GCS_COMPONENT_ID = mavlink.MAV_COMP_ID_MISSIONPLANNER

#: SET_POSITION_TARGET_LOCAL_NED frame of every GCS setpoint.
MAV_FRAME_LOCAL_NED = mavlink.MAV_FRAME_LOCAL_NED
#: Only YAW_RATE_IGNORE set: x, y, z, vx, vy, vz, afx, afy, afz (as acceleration: FORCE_SET
#: clear) and yaw are used (PX4 mavlink_receiver).
TYPE_MASK_POS_VEL_ACC_YAW = mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE

UDP_SCHEMES = ("udpin", "udp", "udpout")


def result_name(result: int | None) -> str:
    """MAV_RESULT as a name without its prefix (``no ACK`` for None), from pymavlink's enum."""
    if result is None:
        return "no ACK"
    entry = mavlink.enums["MAV_RESULT"].get(result)
    if entry is None or entry.name.endswith("_ENUM_END"):
        return f"MAV_RESULT {result}"
    return entry.name.removeprefix("MAV_RESULT_")


def time_boot_ms(seconds: float) -> int:
    """A MAVLink `time_boot_ms` (uint32, wraps) from seconds since boot (rounded to 1 ms)."""
    return round(max(seconds, 0.0) * 1000.0) & 0xFFFFFFFF


def parse_udp_url(url: str) -> tuple[str, str, int]:
    """(kind, host, port) of a UDP URL: kind ``in`` (udpin/udp) or ``out`` (udpout).

    Raises `LinkError` saying what is wrong when `url` is not ``SCHEME:HOST:PORT``.
    """
    scheme, _, rest = url.partition(":")
    host, _, port_text = rest.rpartition(":")
    if scheme not in UDP_SCHEMES or not host or not port_text.isdigit():
        raise LinkError(f"not a UDP MAVLink URL (udpin:HOST:PORT or udpout:HOST:PORT): {url!r}")
    port = int(port_text)
    if not 0 < port < 65536:
        raise LinkError(f"port out of range in {url!r}")
    return ("out" if scheme == "udpout" else "in"), host, port


def is_udp_url(url: str) -> bool:
    """Whether `url`'s scheme is one of the UDP ones (its form may still be wrong)."""
    return url.partition(":")[0] in UDP_SCHEMES


@dataclass
class ParsedDatagram:
    """What one datagram held: its decoded messages and how much of it was garbage."""

    messages: list[Any]
    garbage_bytes: int
    """Bytes that were not part of a valid message (bad CRC, bad signature, truncation,
    junk): 0 for a clean datagram."""
    errors: list[str] = field(default_factory=list)
    """pymavlink's reasons for the garbage (e.g. ``Invalid signature``)."""


def parse_datagram(data: bytes, parser: Any | None = None) -> ParsedDatagram:
    """Decode one UDP datagram with a fresh parser (or `parser`, which must be fresh).

    A UDP datagram carries whole MAVLink packets, so no parser state may survive it: a
    truncated header at the end of one datagram would otherwise swallow the start of the
    next (real) one. Costs ~3 us for the parser.
    """
    if parser is None:
        parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    try:
        found = parser.parse_buffer(data) or []
    except mavlink.MAVError as exc:
        return ParsedDatagram([], len(data), [str(exc)])
    messages, garbage, errors = [], 0, []
    for msg in found:
        if msg.get_type() == "BAD_DATA":
            garbage += len(msg.data)
            errors.append(str(msg.reason))
        else:
            messages.append(msg)
    leftover = len(parser.buf) - parser.buf_index  # an incomplete packet at the end
    if leftover > 0:
        garbage += leftover
        errors.append("truncated packet")
    return ParsedDatagram(messages, garbage, errors)


class Datagrams(asyncio.DatagramProtocol):
    """asyncio's DatagramProtocol as two callbacks: (data, address) and (exception)."""

    def __init__(self, on_datagram: Callable[[bytes, Any], None],
                 on_error: Callable[[Exception], None] | None = None) -> None:
        self._on_datagram = on_datagram
        self._on_error = on_error

    def datagram_received(self, data: bytes, addr: Any) -> None:
        self._on_datagram(data, addr)

    def error_received(self, exc: Exception) -> None:  # ICMP port unreachable etc.
        if self._on_error is not None:
            self._on_error(exc)
