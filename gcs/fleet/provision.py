"""Provisioning the fleet file's signing keys on the vehicles (`fleetplan keys provision`).

Per vehicle with a `signing_key`, over its configured link and as PX4 (v1.17 and later) takes
it: listen unsigned first; refuse an armed vehicle; a vehicle that sends unsigned has no key
and gets SETUP_SIGNING unsigned; one that signs already is left alone when it signs with the
fleet's key, and otherwise needs the key it has (`old_key`), with which the SETUP_SIGNING is
signed. Then the vehicle's traffic must arrive signed with the new key. The key is never
printed: outcomes name key files only.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from gcs.fleet.fleetfile import FleetSpec, VehicleSpec
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.link import VehicleLink
from gcs.wire import SigningKey, mavlink, signing_timestamp

__all__ = ["ProvisionOutcome", "provision_fleet", "provision_vehicle"]


@dataclass(frozen=True)
class ProvisionOutcome:
    """What provisioning did for one vehicle."""

    vehicle: str
    status: str
    """provisioned, changed, already (it signs with the fleet's key), or failed."""
    detail: str

    @property
    def ok(self) -> bool:
        """Whether the vehicle's traffic is signed with its key."""
        return self.status != "failed"

    def line(self) -> str:
        return f"{self.vehicle}: {self.status}: {self.detail}"


@dataclass
class _Heard:
    """The first HEARTBEAT a link heard: whether it carried a signature, and armed."""

    signed: bool | None = None
    armed: bool = False


def _listen(link: VehicleLink, heard: _Heard) -> None:
    def on_message(_link: VehicleLink, msg: Any, _now: float) -> None:
        if heard.signed is None and msg.get_type() == "HEARTBEAT":
            heard.signed = bool(msg._msgbuf[2] & mavlink.MAVLINK_IFLAG_SIGNED)
            heard.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
    link.listeners.append(on_message)


async def _link(hub: LinkHub, spec: VehicleSpec, key: SigningKey | None) -> VehicleLink:
    """The vehicle's configured link, signed with `key` (None: unsigned)."""
    return await hub.add(spec.id, spec.connection, spec.system_id, spec.component_id,
                         signing_key=key, peer=spec.peer)


async def _heard(spec: VehicleSpec, key: SigningKey | None, timeout: float) -> _Heard | None:
    """The vehicle's first HEARTBEAT admitted by a link signed with `key` (None: unsigned,
    which admits signed packets too), or None within `timeout`."""
    async with LinkHub() as hub:
        link = await _link(hub, spec, key)
        heard = _Heard()
        _listen(link, heard)
        await link.wait_for(lambda t: t.heartbeat_time is not None, timeout)
        return heard if heard.signed is not None else None


async def _send_setup(spec: VehicleSpec, new: SigningKey, signer: SigningKey | None,
                      timeout: float) -> None:
    """SETUP_SIGNING with `new`, on a link signed with `signer` (None: unsigned), sent once
    the vehicle is heard on that link (its address pinned) and repeated twice: it has no
    acknowledgement; the check that follows tells whether it took."""
    async with LinkHub() as hub:
        link = await _link(hub, spec, signer)
        await link.wait_for(lambda t: t.heartbeat_time is not None, timeout)
        for _ in range(3):
            link.send_setup_signing(new, signing_timestamp(time.time()))
            await asyncio.sleep(0.1)


async def provision_vehicle(spec: VehicleSpec, old_key: SigningKey | None = None,
                            timeout: float = 5.0) -> ProvisionOutcome:
    """Provision `spec.signing_key` on one vehicle (see the module)."""
    new = spec.signing_key
    if new is None:
        return ProvisionOutcome(spec.id, "failed",
                                "the fleet file gives this vehicle no signing_key")
    heard = await _heard(spec, None, timeout)
    if heard is None:
        return ProvisionOutcome(spec.id, "failed",
                                f"no HEARTBEAT within {timeout:g} s on {spec.connection} "
                                f"(system id {spec.system_id}): is it on and connected?")
    if heard.armed:
        return ProvisionOutcome(spec.id, "failed",
                                "armed: keys are changed only on a disarmed vehicle")
    if heard.signed:
        if await _heard(spec, new, timeout) is not None:
            return ProvisionOutcome(spec.id, "already",
                                    f"its traffic is signed with {new.path}")
        if old_key is None:
            return ProvisionOutcome(spec.id, "failed",
                                    f"it signs with another key than {new.path}: give the key "
                                    "it has (--old-key FILE) to change it")
        if await _heard(spec, old_key, timeout) is None:
            return ProvisionOutcome(spec.id, "failed",
                                    f"it signs with neither {new.path} nor {old_key.path}")
        await _send_setup(spec, new, old_key, timeout)
        status = "changed"
    else:
        await _send_setup(spec, new, None, timeout)
        status = "provisioned"
    if await _heard(spec, new, timeout) is None:
        return ProvisionOutcome(spec.id, "failed",
                                f"sent SETUP_SIGNING, but its traffic is not signed with "
                                f"{new.path} within {timeout:g} s (some PX4 versions take "
                                "SETUP_SIGNING on USB only)")
    return ProvisionOutcome(spec.id, status, f"its traffic is now signed with {new.path}")


async def provision_fleet(fleet: FleetSpec, vehicle_ids: Sequence[str] = (),
                          old_key: SigningKey | None = None,
                          timeout: float = 5.0) -> list[ProvisionOutcome]:
    """`provision_vehicle` for the named vehicles (all with a key when none is named), one
    after the other: each listens on its own configured link."""
    by_id = {v.id: v for v in fleet.vehicles}
    unknown = [vid for vid in vehicle_ids if vid not in by_id]
    if unknown:
        raise ValueError(f"no vehicle {', '.join(map(repr, unknown))} in the fleet file "
                       f"(it has {', '.join(map(repr, by_id))})")
    chosen = ([by_id[vid] for vid in vehicle_ids] if vehicle_ids
              else [v for v in fleet.vehicles if v.signing_key is not None])
    return [await provision_vehicle(spec, old_key, timeout) for spec in chosen]
