"""gcs.flight.link.setpoints: plan sampling, message fields, what a mock vehicle actually
receives."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from gcs import frames
from gcs.flight.link.hub import LinkHub
from gcs.flight.link.setpoints import plan_tracks, transfer_track
from gcs.flight.timeline.stream import Streamer
from gcs.sim import MockFleet
from gcs.wire import MAV_FRAME_LOCAL_NED, TYPE_MASK_POS_VEL_ACC_YAW, time_boot_ms
from tests.flight.support import mock_ports

pytestmark = pytest.mark.timeout(60)


def test_type_mask_uses_position_velocity_acceleration_and_yaw() -> None:
    # POSITION_TARGET_TYPEMASK: bits 0-8 ignore x..az, 0x200 force, 0x400 yaw, 0x800 yaw rate
    assert TYPE_MASK_POS_VEL_ACC_YAW & 0x1FF == 0  # nothing of p, v, a ignored
    assert TYPE_MASK_POS_VEL_ACC_YAW & 0x200 == 0  # acceleration, not force
    assert TYPE_MASK_POS_VEL_ACC_YAW & 0x400 == 0  # yaw used
    assert TYPE_MASK_POS_VEL_ACC_YAW & 0x800  # yaw rate ignored
    assert MAV_FRAME_LOCAL_NED == 1


def test_time_boot_ms() -> None:
    assert time_boot_ms(0.0) == 0
    assert time_boot_ms(0.06) == 60  # 0.06 * 1000 = 59.999...: rounded, not truncated
    assert time_boot_ms(-1.0) == 0
    assert time_boot_ms(2**32 / 1000 + 1.0) == 1000  # wraps like a uint32


def test_plan_tracks_sample_the_exact_motion(line3_plan) -> None:
    homes = np.array([[0.0, 0.0, 0.0], [5.0, -3.0, 0.5], [-2.0, 7.0, 0.0]])
    rate = 50.0
    tracks = plan_tracks(line3_plan, homes, rate, yaw_world=0.0, extra_s=1.0)
    horizon = line3_plan.scenario.horizon
    assert len(tracks[0]) == round((horizon + 1.0) * rate) + 1
    ticks = np.arange(len(tracks[0]))
    sample = line3_plan.sample(ticks / rate)
    for i, track in enumerate(tracks):
        np.testing.assert_allclose(frames.ned_to_world(track.position, homes[i]),
                                   sample.position[i], atol=1e-12)
        np.testing.assert_allclose(frames.ned_vector_to_world(track.velocity),
                                   sample.velocity[i], atol=1e-12)
        np.testing.assert_allclose(frames.ned_vector_to_world(track.acceleration),
                                   sample.acceleration[i], atol=1e-12)
        assert track.yaw == pytest.approx(np.pi / 2)  # ENU yaw 0 = facing east
        # past the end: the goal at rest
        sp = track.at(len(track) + 10)
        np.testing.assert_allclose(frames.ned_to_world(sp.position, homes[i]),
                                   line3_plan.scenario.goals[i], atol=1e-12)
        assert sp.velocity == (0.0, 0.0, 0.0)


def test_rate_limits(line3_plan) -> None:
    with pytest.raises(ValueError, match="rate"):
        plan_tracks(line3_plan, np.zeros((3, 3)), 101.0)
    with pytest.raises(ValueError, match="rate"):
        plan_tracks(line3_plan, np.zeros((3, 3)), 0.0)


def test_transfer_track_climbs_vertically_then_moves_and_ends_at_rest() -> None:
    start = np.array([0.0, 0.0, 0.0])
    end = np.array([1.0, 2.0, -3.0])
    track = transfer_track(start, end, speed=1.0, yaw_ned=0.0, rate=50.0)
    np.testing.assert_allclose(track.position[0], start)
    np.testing.assert_allclose(track.position[-1], end, atol=1e-12)
    np.testing.assert_allclose(track.velocity[[0, -1]], 0.0, atol=1e-12)
    # vertical first: no horizontal motion until the altitude is reached
    climbing = track.position[:, 2] > end[2] + 1e-9
    np.testing.assert_allclose(track.position[climbing, :2], 0.0)
    assert np.max(np.linalg.norm(track.velocity, axis=1)) == pytest.approx(1.0, abs=0.01)
    # consistent derivatives: velocity integrates to position
    dp = np.diff(track.position, axis=0) * 50.0
    mid_v = 0.5 * (track.velocity[1:] + track.velocity[:-1])
    np.testing.assert_allclose(dp, mid_v, atol=2e-3)


async def _stream_and_receive(plan, homes, shared: bool, rate: float, seconds: float):
    n = len(plan.vehicles)
    ports = mock_ports(n)
    async with MockFleet(homes=homes, record_setpoints=True, settle_time=0.5,
                         max_port_offset=0 if shared else None, **ports) as mock:
        async with LinkHub() as hub:
            links = [await hub.add(vid, mock.gcs_url(i), i + 1)
                     for i, vid in enumerate(plan.scenario.ids)]
            if shared:
                assert len(hub.endpoints) == 1
            for link in links:
                assert await link.wait_for(lambda t: t.heartbeat_time is not None, 5.0)
            tracks = plan_tracks(plan, homes, rate)
            streamer = Streamer(rate)
            start_tick = streamer.next_tick() + 2
            # time_boot_ms counts from 1 s before flight time 0 (tick `start_tick`); ticks
            # before it are sent the track's first setpoint, the plan's start at rest
            streamer.boot_epoch = streamer.tick_time(start_tick) - 1.0
            for vid, link, track in zip(plan.scenario.ids, links, tracks, strict=True):
                streamer.assign(vid, link, track, start_tick)
            streamer.start()
            await asyncio.sleep(seconds)
            await streamer.stop()
            await asyncio.sleep(0.2)
            sent = [link.setpoints_sent for link in links]
        return [list(v.received) for v in mock.vehicles], sent


@pytest.mark.parametrize("shared", [False, True], ids=["own-ports", "shared-connection"])
def test_received_setpoints_equal_the_plan(line3_plan, shared: bool) -> None:
    """What each mock vehicle receives, converted back to the world frame with its own home,
    equals the plan at the sampled instants within 1e-6 m."""
    homes = np.array([[0.5, 0.0, 0.0], [4.0, 1.0, 0.0], [8.5, 0.2, 0.3]])
    rate = 50.0
    received, sent = asyncio.run(_stream_and_receive(line3_plan, homes, shared, rate, 2.0))
    for i, messages in enumerate(received):
        # nothing lost, nothing misrouted (a starved stream skips ticks, never sends them late)
        assert len(messages) == sent[i] >= 50
        times = (np.array([m.time_boot_ms for m in messages]) - 1000) / 1000.0
        assert np.all(np.diff(times) > 0)
        np.testing.assert_allclose(times * rate, np.round(times * rate), atol=1e-9)
        expected = line3_plan.sample(times)
        got = frames.ned_to_world(np.array([m.position for m in messages]), homes[i])
        assert np.max(np.abs(got - expected.position[i])) < 1e-6
        got_v = frames.ned_vector_to_world(np.array([m.velocity for m in messages]))
        assert np.max(np.abs(got_v - expected.velocity[i])) < 1e-6
        got_a = frames.ned_vector_to_world(np.array([m.acceleration for m in messages]))
        assert np.max(np.abs(got_a - expected.acceleration[i])) < 1e-5
        assert {m.target_system for m in messages} == {i + 1}
        assert {m.target_component for m in messages} == {1}
        assert {m.frame for m in messages} == {MAV_FRAME_LOCAL_NED}
        assert {m.type_mask for m in messages} == {TYPE_MASK_POS_VEL_ACC_YAW}
        # the plan moves during the window, so this is not a constant being compared
        assert np.ptp(got[:, 1]) > 0.1
