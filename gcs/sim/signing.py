"""MAVLink signing on a mock vehicle, as PX4's documentation describes it (PX4 >= 1.17,
"MAVLink Message Signing").

A key arrives with SETUP_SIGNING (accepted unsigned only while the vehicle has no key;
changing or clearing it needs a message signed with the current key; refused while armed; an
all-zero key and timestamp clears it), or is there from the start (`MockFleet(signing_key=...)`:
the key file on the SD card). While a vehicle has a key, every outgoing message is signed and
incoming unsigned or wrongly signed ones are rejected, except PX4's documented few
(`gcs.wire.PX4_UNSIGNED_ACCEPTED`). The signature checks are pymavlink's own, not ours: these
functions only set pymavlink's signing state.
"""

from __future__ import annotations

import time
from typing import Any

from gcs.wire import PX4_UNSIGNED_ACCEPTED, signing_timestamp

__all__ = ["install_key", "setup_signing_key"]


def install_key(signing: Any, key: bytes | None, initial_timestamp: int = 0,
                unsigned_accepted: frozenset[int] = PX4_UNSIGNED_ACCEPTED) -> None:
    """Install `key` into pymavlink's `signing` state (None: signing off), as PX4 does on
    SETUP_SIGNING: sign everything, accept unsigned only `unsigned_accepted` (PX4's
    `PX4_UNSIGNED_ACCEPTED` unless given)."""
    if key is None:
        signing.secret_key = None
        signing.sign_outgoing = False
        signing.allow_unsigned_callback = None
        return
    signing.secret_key = bytes(key)
    signing.sign_outgoing = True
    signing.timestamp = max(signing.timestamp, initial_timestamp,
                            signing_timestamp(time.time()))
    signing.allow_unsigned_callback = lambda _mav, msg_id: msg_id in unsigned_accepted
    signing.stream_timestamps.clear()


def setup_signing_key(msg: Any) -> bytes | None:
    """The key a SETUP_SIGNING installs (None: an all-zero key and timestamp clear it)."""
    key = bytes(msg.secret_key)
    if not any(key) and msg.initial_timestamp == 0:
        return None
    return key
