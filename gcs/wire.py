"""MAVLink facts shared by the GCS (`gcs.flight`) and the PX4-like mock (`gcs.sim`), each once.

Long: the MAVLink facts, a table of encodings each defined once.

- the wire format: pymavlink's MAVLink 2 `common` dialect (this module is the one place that
  selects it, through the ``MAVLINK20`` environment variable);
- the GCS's own identity (system 255, MAV_COMP_ID_MISSIONPLANNER) and MAV_RESULT names, from
  pymavlink's enums;
- the setpoint encoding: frame MAV_FRAME_LOCAL_NED and the POSITION_TARGET_TYPEMASK bits, from
  pymavlink, not hand-copied numbers; `time_boot_ms`;
- UDP URLs (``udpin:HOST:PORT`` / ``udpout:HOST:PORT``): `parse_udp_url`;
- `parse_datagram`: one UDP datagram decoded by a fresh parser, so garbage in one datagram can
  never swallow the next one; `peek_packet`: the header of a one-packet datagram, CRC checked,
  without decoding it;
- `Datagrams`: the one asyncio DatagramProtocol adapter (GCS endpoints and mock vehicles);
- MAVLink 2 signing: key files (`load_key`, `new_key_file`), the signing clock
  (`signing_timestamp`), `signature_of` (a packet's signature block, checked), PX4's
  unsigned exceptions (`PX4_UNSIGNED_ACCEPTED`). The GCS's stateful part (replay window,
  persisted timestamp) is `gcs.flight.link.signing`; the mock uses pymavlink's own signing code.

Everything here is a constant, a pure function or a tiny adapter, so the mock can share it
without sharing our link code (`gcs.flight.link.link`).
"""

from __future__ import annotations

import asyncio
import hashlib
import os
import secrets
import stat
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink

from gcs.errors import LinkError

__all__ = [
    "GCS_COMPONENT_ID",
    "GCS_SYSTEM_ID",
    "KEY_BYTES",
    "MAV_FRAME_LOCAL_NED",
    "MAX_RATE_HZ",
    "PARAM_TYPES",
    "PX4_UNSIGNED_ACCEPTED",
    "SIGNING_EPOCH_UNIX",
    "TYPE_MASK_POS_VEL_ACC_YAW",
    "Datagrams",
    "KeyFileError",
    "PacketHeader",
    "ParsedDatagram",
    "Signature",
    "SigningKey",
    "addressed_to",
    "decode_param",
    "encode_param",
    "is_udp_url",
    "load_key",
    "mavlink",
    "new_key_file",
    "parse_datagram",
    "parse_host_port",
    "parse_udp_url",
    "peek_packet",
    "result_name",
    "signature_of",
    "signing_timestamp",
    "time_boot_ms",
]

#: The highest setpoint rate the station streams (Hz): a fleet file's `rate_hz` and a setpoint
#: track are held to it.
MAX_RATE_HZ = 100.0

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
    name: str = entry.name  # pymavlink's enums carry no types
    return name.removeprefix("MAV_RESULT_")


def pack(msg: Any, mav: Any) -> bytes:
    """`msg` encoded by the pymavlink `mav` (and signed, if `mav` signs), advancing `mav`'s
    sequence number as pymavlink's own `send` does: `msg.pack` alone stamps every message with
    the same number, which a receiver counting gaps (link quality) reads as loss."""
    buf: bytes = msg.pack(mav)
    mav.seq = (mav.seq + 1) & 0xFF
    return buf


#: STATUSTEXT's text field (bytes); a longer text comes in chunks of this size.
STATUSTEXT_LEN = 50


class StatusTexts:
    """Reassembles MAVLink 2 STATUSTEXT chunks: the same non-zero `id`, `chunk_seq` 0, 1, ...;
    a chunk shorter than the field ends the text (PX4 splits long texts this way). Id 0 is a
    whole text. At most `max_chunks` chunks per text are kept (a sender that never ends one
    cannot grow it without bound)."""

    def __init__(self, max_chunks: int = 8) -> None:
        self.max_chunks = max_chunks
        self._parts: dict[int, list[str]] = {}

    def add(self, msg: Any) -> str | None:
        """The whole text once `msg` completes it, else None; without the tab PX4 ends a text
        with when it also reports it as an event (a mark for ground stations, not text)."""
        text = str(msg.text).rstrip("\x00")
        ident = getattr(msg, "id", 0) or 0
        if not ident:
            return text.removesuffix("\t")
        parts = self._parts.setdefault(ident, [])
        if getattr(msg, "chunk_seq", 0) == 0:
            parts.clear()
        parts.append(text)
        if len(text.encode()) < STATUSTEXT_LEN or len(parts) >= self.max_chunks:
            del self._parts[ident]
            return "".join(parts).removesuffix("\t")
        return None


def addressed_to(msg: Any, system_id: int, component_id: int) -> bool:
    """Whether `msg` (with target_system / target_component) is for that system and
    component: its own system id, and its own component or 0 (every component)."""
    return bool(msg.target_system == system_id and msg.target_component in (0, component_id))


def time_boot_ms(seconds: float) -> int:
    """A MAVLink `time_boot_ms` (uint32, wraps) from seconds since boot (rounded to 1 ms)."""
    return round(max(seconds, 0.0) * 1000.0) & 0xFFFFFFFF


def parse_udp_url(url: str) -> tuple[str, str, int]:
    """(kind, host, port) of a UDP URL: kind ``in`` (udpin/udp) or ``out`` (udpout).

    Raises `LinkError` saying what is wrong when `url` is not ``SCHEME:HOST:PORT``.
    """
    scheme, _, rest = url.partition(":")
    if scheme not in UDP_SCHEMES:
        raise LinkError(f"not a UDP MAVLink URL (udpin:HOST:PORT or udpout:HOST:PORT): {url!r}")
    try:
        host, port = parse_host_port(rest)
    except ValueError as exc:
        raise LinkError(f"{exc} in {url!r}") from None
    return ("out" if scheme == "udpout" else "in"), host, port


def parse_host_port(text: str) -> tuple[str, int]:
    """(host, port) of ``HOST:PORT``; ValueError saying what is wrong."""
    host, _, port_text = text.rpartition(":")
    if not host or not port_text.isdigit():
        raise ValueError("not HOST:PORT")
    port = int(port_text)
    if not 0 < port < 65536:
        raise ValueError("port out of range")
    return host, port


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


@dataclass(frozen=True)
class PacketHeader:
    """The routing fields of a datagram holding exactly one whole MAVLink packet."""

    msg_id: int
    system: int
    component: int
    seq: int
    signed: bool


_V1, _V2 = mavlink.PROTOCOL_MARKER_V1, mavlink.PROTOCOL_MARKER_V2


def peek_packet(data: bytes) -> PacketHeader | None:
    """The header of `data` if it is exactly one whole MAVLink 1 or 2 packet of a message
    this dialect knows, with a valid CRC; None otherwise (then it must be parsed in full,
    which counts any garbage). Reads no payload (a fraction of a full decode's cost: README,
    stream benchmark), so a receiver can drop the message ids it never reads before
    decoding them. The signature, if any, is NOT checked here."""
    n = len(data)
    if n < 8:
        return None
    marker, length = data[0], data[1]
    if marker == _V2:
        if n < 12 or data[2] & ~_IFLAG_SIGNED:  # a flag we do not know: parse in full
            return None
        signed = bool(data[2] & _IFLAG_SIGNED)
        end = 10 + length
        if n != end + 2 + (_SIGNATURE_LEN if signed else 0):
            return None
        msg_id = data[7] | data[8] << 8 | data[9] << 16
        seq, system, component = data[4], data[5], data[6]
    elif marker == _V1:
        end = 6 + length
        if n != end + 2:
            return None
        signed = False
        msg_id, seq, system, component = data[5], data[2], data[3], data[4]
    else:
        return None
    entry = mavlink.mavlink_map.get(msg_id)
    if entry is None:
        return None
    crc = mavlink.x25crc(data[1:end])
    crc.accumulate(bytes((entry.crc_extra,)))
    if crc.crc != (data[end] | data[end + 1] << 8):
        return None
    return PacketHeader(msg_id, system, component, seq, signed)


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
# ---------------------------------------------------------------------------- signing

#: A MAVLink 2 signing secret is 32 bytes.
KEY_BYTES = 32
#: The signing timestamp counts 10 us units since 2015-01-01T00:00:00Z.
SIGNING_EPOCH_UNIX = 1_420_070_400
#: Messages PX4 accepts unsigned while it has a key (PX4 docs "MAVLink Message Signing",
#: mavlink_sign_control): HEARTBEAT, RADIO_STATUS, ADSB_VEHICLE, COLLISION.
PX4_UNSIGNED_ACCEPTED = frozenset({
    mavlink.MAVLINK_MSG_ID_HEARTBEAT, mavlink.MAVLINK_MSG_ID_RADIO_STATUS,
    mavlink.MAVLINK_MSG_ID_ADSB_VEHICLE, mavlink.MAVLINK_MSG_ID_COLLISION,
})


class KeyFileError(ValueError):
    """A signing key file that cannot be used (message names the file and the reason)."""


@dataclass(frozen=True)
class SigningKey:
    """A 32-byte MAVLink 2 signing secret and the file it came from.

    Its repr and `str` show only the path: the secret never reaches a log or a record.
    """

    path: Path
    secret: bytes = field(repr=False)

    def __str__(self) -> str:
        return str(self.path)


def signing_timestamp(unix_time: float) -> int:
    """The signing timestamp (10 us units since 2015-01-01) of a Unix time."""
    return max(0, int((unix_time - SIGNING_EPOCH_UNIX) * 100_000))


def load_key(path: str | os.PathLike[str]) -> SigningKey:
    """Read a key file (64 hex digits, as `new_key_file` writes it).

    Refuses (`KeyFileError`) a file that group or others may read or write: a key anyone on
    the machine can read authenticates nobody.
    """
    p = Path(path)
    try:
        info = p.stat()
        text = p.read_text(encoding="ascii", errors="replace")
    except OSError as exc:
        raise KeyFileError(f"cannot read signing key file {p}: {exc.strerror}") from None
    if not stat.S_ISREG(info.st_mode):
        raise KeyFileError(f"signing key file {p} is not a regular file")
    if info.st_mode & 0o077:
        raise KeyFileError(f"signing key file {p} is accessible to group/others "
                           f"(mode {stat.S_IMODE(info.st_mode):04o}): chmod 600 {p}")
    digits = text.strip()
    if len(digits) != 2 * KEY_BYTES or any(c not in "0123456789abcdefABCDEF" for c in digits):
        raise KeyFileError(f"signing key file {p} must hold {KEY_BYTES} bytes as "
                           f"{2 * KEY_BYTES} hex digits")
    return SigningKey(p, bytes.fromhex(digits))


def new_key_file(path: str | os.PathLike[str]) -> SigningKey:
    """Create a new random key file readable by its owner only (0600); never overwrites."""
    p = Path(path)
    try:
        fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise KeyFileError(f"{p} already exists: not overwriting a key") from None
    except OSError as exc:
        raise KeyFileError(f"cannot create {p}: {exc.strerror}") from None
    secret = secrets.token_bytes(KEY_BYTES)
    with os.fdopen(fd, "w") as f:
        os.fchmod(f.fileno(), 0o600)  # whatever the umask
        f.write(secret.hex() + "\n")
    return SigningKey(p, secret)


#: incompat_flags bit of a signed MAVLink 2 packet, and the signature block's length.
_IFLAG_SIGNED = mavlink.MAVLINK_IFLAG_SIGNED
_SIGNATURE_LEN = mavlink.MAVLINK_SIGNATURE_BLOCK_LEN


@dataclass(frozen=True)
class Signature:
    """A received packet's signature block: its stream, its timestamp, whether it is valid."""

    link_id: int
    timestamp: int
    valid: bool
    """The 6-byte signature matches SHA-256(key + packet without the signature)."""


def signature_of(packet: bytes, secret: bytes) -> Signature | None:
    """The checked signature of one whole MAVLink 2 packet (None: the packet is unsigned).

    Only the cryptographic check: whether the timestamp is new for its stream (replay) is the
    receiver's state (`gcs.flight.link.signing`). Checked before anything is remembered, so a forged
    packet cannot move a stream's timestamp forward.
    """
    if len(packet) < 10 + _SIGNATURE_LEN or packet[0] != mavlink.PROTOCOL_MARKER_V2 \
            or not packet[2] & _IFLAG_SIGNED:
        return None
    block = packet[-_SIGNATURE_LEN:]
    link_id = block[0]
    timestamp = int.from_bytes(block[1:7], "little")
    digest = hashlib.sha256(secret + packet[:-6]).digest()[:6]
    return Signature(link_id, timestamp, secrets.compare_digest(digest, block[7:]))


#: PARAM_VALUE / PARAM_SET types of PX4's two parameter kinds: REAL32 ("f"), INT32 ("i").
PARAM_TYPES = {"f": mavlink.MAV_PARAM_TYPE_REAL32, "i": mavlink.MAV_PARAM_TYPE_INT32}


def encode_param(kind: str, value: float) -> float:
    """The param_value field for `value` as PX4 sends and takes it: REAL32 as the float,
    INT32 byte-wise in the float field (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE)."""
    if kind == "i":
        return float(struct.unpack("<f", struct.pack("<i", int(value)))[0])
    return float(value)


def decode_param(kind: str, field: float) -> float:
    """The value a param_value field carries for a parameter of type `kind`."""
    if kind == "i":
        return float(struct.unpack("<i", struct.pack("<f", field))[0])
    return float(field)
