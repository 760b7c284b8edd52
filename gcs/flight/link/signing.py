"""MAVLink 2 signing on the GCS side: one `LinkSigning` per key (fleet-wide or per vehicle).

- Outgoing: a pymavlink `MAVLinkSigning` state shared by the packers of every vehicle using the
  key, so the GCS's signing timestamps (10 us units since 2015) never repeat across them.
- The timestamp never goes backwards, including across restarts: it starts at
  max(clock, persisted value) and the value persisted next to the key file
  (``KEYFILE.timestamp``, mode 0600) is always *ahead* of every timestamp used, by reserving
  `RESERVE` (10 s) at a time; a crash therefore skips at most a reservation, never reuses one.
- Incoming (`verify`): unsigned -> ``unsigned``; wrong signature -> ``bad_signature``; a
  timestamp not newer than the last accepted one of its stream (link id, system, component),
  or a new stream more than a minute behind the wall clock -> ``replayed``. (The wall clock,
  not our own counter: after a restart that counter may run ahead of time by a reservation,
  and the MAVLink spec's "behind our timestamp" would then refuse honest vehicles.) The
  signature is checked *before* any state changes (pymavlink's own check records the timestamp
  first, which lets one forged packet with a huge timestamp lock a stream out).
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20.common import MAVLinkSigning

from gcs import wire
from gcs.wire import SigningKey, signature_of, signing_timestamp

__all__ = ["NEW_STREAM_WINDOW", "REPEATED_TIMESTAMPS", "RESERVE", "LinkSigning",
           "timestamp_path"]

REPEATED_TIMESTAMPS = ("from the vehicle's address (as the packets claim): PX4 signs with old "
                       "timestamps for a few seconds after it boots and now and then repeats "
                       "one later, which MAVLink drops as replays")
"""What a drops note adds when every drop is a replay (`gcs.flight.safety.monitor.drops_text`). A
replay from another address is refused as such first, and PX4 sends them on its own: after a
boot it signs from the timestamp stored with its key until it has heard the GCS (about 400
packets a vehicle on SIH SITL), and as it signs from more than one thread it repeats a
timestamp about once a vehicle every half minute. A steady rate later in a flight is recorded
traffic played back, from the vehicle's address or one forged to look like it."""

#: Timestamps reserved (persisted ahead) at a time: 10 s.
RESERVE = 10 * 100_000
#: A new stream's first timestamp may lag our clock by this much (MAVLink spec: one minute).
NEW_STREAM_WINDOW = 60 * 100_000


def timestamp_path(key: SigningKey) -> Path:
    """Where the last reserved signing timestamp of `key` is kept."""
    return key.path.with_name(key.path.name + ".timestamp")


class LinkSigning:
    """Signing with one key: outgoing state, persisted timestamp, incoming replay window."""

    def __init__(self, key: SigningKey, link_id: int = 0) -> None:
        self.key = key
        self.state = MAVLinkSigning()
        """pymavlink's outgoing signing state, shared by every packer using this key."""
        self.state.secret_key = key.secret
        self.state.link_id = link_id
        self.state.sign_outgoing = True
        self._streams: dict[tuple[int, int, int], int] = {}
        self._path = timestamp_path(key)
        self._reserved = self._read_reserved()
        self.state.timestamp = max(signing_timestamp(time.time()), self._reserved + 1)
        self.persist_errors = 0
        """Reservations that could not be written after the first (signing goes on: the
        timestamp stays monotonic in this process, but a restart could reuse some)."""
        self._write(self.state.timestamp + RESERVE)  # raises OSError: no signing without it

    def _read_reserved(self) -> int:
        try:
            return int(self._path.read_text().strip() or 0)
        except FileNotFoundError:
            return 0
        except (OSError, ValueError) as exc:
            raise OSError(f"cannot read the signing timestamp {self._path}: {exc}") from None

    def reserve(self) -> None:
        """Persist a reservation ahead of the current timestamp when it runs low (cheap
        otherwise: call it often, e.g. with the heartbeats)."""
        if self.state.timestamp + RESERVE // 2 < self._reserved:
            return
        try:
            self._write(self.state.timestamp + RESERVE)
        except OSError:
            self.persist_errors += 1

    def _write(self, value: int) -> None:
        tmp = self._path.with_name(self._path.name + ".tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as f:
            f.write(f"{value}\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self._path)
        self._reserved = value

    def pack(self, msg: Any, packer: Any) -> bytes:
        """`msg` packed and signed by `packer` (a pymavlink MAVLink using `self.state`)."""
        if self.state.timestamp >= self._reserved:  # never sign beyond what is persisted
            self.reserve()
        return wire.pack(msg, packer)

    def verify(self, msg: Any) -> str | None:
        """None if `msg` (decoded without a key) is correctly signed and new; else the reason:
        ``unsigned``, ``bad_signature`` or ``replayed``."""
        return self.verify_packet(bytes(msg._msgbuf), msg.get_srcSystem(),
                                  msg.get_srcComponent())

    def verify_packet(self, packet: bytes, system: int, component: int) -> str | None:
        """`verify` on one whole packet's bytes from (`system`, `component`): for packets
        an endpoint hands on undecoded (`gcs.flight.link.endpoints`)."""
        signature = signature_of(packet, self.key.secret)
        if signature is None:
            return "unsigned"
        if not signature.valid:
            return "bad_signature"
        stream = (signature.link_id, system, component)
        last = self._streams.get(stream)
        if last is not None:
            if signature.timestamp <= last:
                return "replayed"
        elif signature.timestamp + NEW_STREAM_WINDOW < signing_timestamp(time.time()):
            return "replayed"
        self._streams[stream] = signature.timestamp
        # Like the MAVLink spec: we never sign with a timestamp older than one accepted.
        self.state.timestamp = max(self.state.timestamp, signature.timestamp)
        return None
