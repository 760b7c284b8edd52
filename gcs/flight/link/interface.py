"""What the flight's code uses of a vehicle's link (`Link`), so that its steps run on a link in
memory (the tests' fake) as they do on the MAVLink one (`gcs.flight.link.link.VehicleLink`).

Data members are read-only here: the flight reads them and the link keeps them up to date.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager
from typing import Any, Protocol

from gcs.flight.link.setpoints import Setpoint
from gcs.flight.link.station import Clock
from gcs.flight.link.telemetry import Telemetry

__all__ = ["DatagramCounts", "Link", "MessageHandler"]

MessageHandler = Callable[[Any, float], None]
"""Called with (message, receive time) for every message of the vehicle while it listens."""


class DatagramCounts(Protocol):
    """What the flight reads of a link's endpoint: its counts, for the record and for saying
    why a vehicle was not heard."""

    @property
    def messages_received(self) -> int:
        """Valid messages received on the endpoint, whoever sent them."""
        ...

    @property
    def dropped_unknown(self) -> int:
        """Messages dropped because their system id is 0 or not registered."""
        ...

    @property
    def garbage_datagrams(self) -> int:
        """Datagrams that were not a valid packet (junk, truncated, bad CRC)."""
        ...


class Link(Protocol):
    """One vehicle's MAVLink link as the flight uses it: its telemetry, waits on it, commands
    and the messages and setpoints the GCS sends it."""

    @property
    def vehicle_id(self) -> str: ...

    @property
    def system_id(self) -> int: ...

    @property
    def component_id(self) -> int: ...

    @property
    def mav(self) -> Any:
        """The packer that encodes messages for this vehicle (a pymavlink ``MAVLink``)."""
        ...

    @property
    def telemetry(self) -> Telemetry: ...

    @property
    def endpoint(self) -> DatagramCounts: ...

    @property
    def peer_address(self) -> Any:
        """The pinned peer's address (None until pinned; None for serial links)."""
        ...

    @property
    def claimants(self) -> Sequence[Any]:
        """Other addresses that claimed this vehicle after first contact pinned one."""
        ...

    @property
    def dropped_from(self) -> dict[str, tuple[Any, int]]:
        """Security counter name -> (address, component) of the latest packet dropped."""
        ...

    def listening(self, handler: MessageHandler) -> AbstractContextManager[None]:
        """`handler` gets every message of the vehicle inside the ``with`` block."""
        ...

    async def wait_for(self, predicate: Callable[[Telemetry], bool], timeout: float, *,
                       clock: Clock | None = None) -> bool:
        """Wait until `predicate(telemetry)` holds; False after `timeout` on `clock`."""
        ...

    def link_age(self, now: float | None = None) -> float:
        """Seconds since any message of this vehicle arrived (inf before the first)."""
        ...

    def heartbeat_age(self, now: float | None = None) -> float:
        """Seconds since the last HEARTBEAT (inf before the first)."""
        ...

    def send(self, msg: Any) -> None:
        """`msg` (made with `mav`) to the vehicle."""
        ...

    def pack_setpoint(self, setpoint: Setpoint, boot_ms: int) -> bytes:
        """SET_POSITION_TARGET_LOCAL_NED for this vehicle, encoded ahead of its send."""
        ...

    def send_packed(self, buf: bytes) -> None:
        """Send a setpoint from `pack_setpoint`."""
        ...

    async def command(self, command: int, params: tuple[float, ...] = (), *,
                      timeout: float = 1.0, retries: int = 8,
                      clock: Clock | None = None) -> int:
        """COMMAND_LONG; the final MAV_RESULT of its COMMAND_ACK (`CommandError` when none
        came after all retries)."""
        ...

    async def request_message(self, message_id: int, timeout: float = 1.0, *,
                              clock: Clock | None = None) -> int:
        """MAV_CMD_REQUEST_MESSAGE for `message_id`; returns the MAV_RESULT."""
        ...
