"""`fleetplan fly --mock` without port flags flies on PX4 SITL's usual ports when they are
free, and on a free block it names when they are taken (by `make run`, say); port flags
given are used as they are."""

from __future__ import annotations

import socket

import pytest

from gcs.autopilot import px4
from gcs.cli.fly_cmd import mock_ports
from gcs.sim import ports


@pytest.fixture
def usual(monkeypatch: pytest.MonkeyPatch) -> int:
    """PX4's usual ports moved to a block that is free now (the real ones may be in use on
    this machine)."""
    base = ports.free_udp_base(ports.mock_port_offsets(3))
    monkeypatch.setattr(px4, "OFFBOARD_GCS_BASE_PORT", base)
    monkeypatch.setattr(px4, "OFFBOARD_VEHICLE_BASE_PORT", base + ports.LISTEN_OFFSET)
    return base


def test_the_usual_ports_when_they_are_free(usual: int, capsys) -> None:
    assert mock_ports(None, None, 3) == (usual, usual + ports.LISTEN_OFFSET)
    assert capsys.readouterr().out == ""


def test_a_free_block_named_when_the_usual_ports_are_taken(usual: int, capsys) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", usual + ports.LISTEN_OFFSET + 2))  # the third vehicle's
        base, listen = mock_ports(None, None, 3)
        assert base != usual and listen == base + ports.LISTEN_OFFSET
        assert ports.block_free(base, ports.mock_port_offsets(3))
    out = capsys.readouterr().out
    assert f"ports {usual}.. and {usual + ports.LISTEN_OFFSET}.. are taken" in out
    assert f"the mock fleet flies on {base}.. and {listen}.. instead" in out


def test_port_flags_are_kept_even_on_taken_ports(usual: int) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", usual))
        assert mock_ports(usual, None, 3) == (usual, usual + ports.LISTEN_OFFSET)
        assert mock_ports(None, 30_000, 3) == (usual, 30_000)


def test_a_fleet_larger_than_px4s_layout_listens_after_its_gcs_block(usual: int) -> None:
    """Past 40 vehicles PX4 SITL's listen ports (base + 40 + i) would be the GCS ports of
    vehicles 40 and up: the fleet listens right after its GCS block instead, every port
    its own."""
    count = 128
    offsets = ports.mock_port_offsets(count)
    assert len(set(offsets)) == 2 * count
    base = ports.free_udp_base(offsets)
    assert ports.mock_fleet_ports(base, count) == {"gcs_base_port": base,
                                                   "listen_base_port": base + count}
    chosen, listen = mock_ports(None, None, count)  # the usual block, or a free one
    assert listen == chosen + count and ports.block_free(chosen, offsets)
