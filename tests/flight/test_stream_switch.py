"""Streamer.switch: a track that takes over at its start tick, the current one streaming
until then; `assign` and `unassign` meanwhile override it."""

from __future__ import annotations

import pytest

from gcs.flight.link.setpoints import hold_track
from gcs.flight.timeline.stream import Streamer
from tests.flight.fakes import fake_vehicle


def _sent(streamer: Streamer, tick: int) -> tuple[float, ...]:
    """The position streamed to uav1 at `tick`."""
    ready = {vid: sp for vid, _, sp, _ in streamer.prepare_tick(tick)}
    return ready["uav1"].position


def test_a_switch_takes_over_at_its_tick_and_assign_or_unassign_cancel_it() -> None:
    streamer = Streamer(20.0)
    link = fake_vehicle(0).linked
    here, there = hold_track((0.0, 0.0, -1.0), 0.0, 20.0), hold_track((5.0, 0.0, -1.0), 0.0, 20.0)
    streamer.assign("uav1", link, here, 0)
    streamer.switch("uav1", link, there, 100)
    assert _sent(streamer, 99) == (0.0, 0.0, -1.0)
    assert _sent(streamer, 100) == (5.0, 0.0, -1.0)
    assert streamer.assignments["uav1"].start_tick == 100 and not streamer.pending
    streamer.switch("uav1", link, here, 200)
    streamer.assign("uav1", link, there, 0)  # e.g. a fault policy's hold: the switch is off
    assert _sent(streamer, 300) == (5.0, 0.0, -1.0)
    streamer.switch("uav1", link, here, 400)
    streamer.unassign("uav1")
    assert "uav1" not in streamer.pending and not streamer.prepare_tick(500)


def test_a_switch_with_an_origin_indexes_its_track_from_there_and_can_be_cancelled() -> None:
    """A replan's spliced track counts its ticks from the flight's start tick (`origin`) but
    takes over only at the switch tick; `cancel_switch` leaves the current track on."""
    import numpy as np

    from gcs.flight.link.setpoints import SetpointTrack

    streamer = Streamer(20.0)
    link = fake_vehicle(0).linked
    here = hold_track((0.0, 0.0, -1.0), 0.0, 20.0)
    ramp = np.zeros((400, 3))
    ramp[:, 0] = np.arange(400) * 0.01  # x = 0.01 m per tick of the flight
    track = SetpointTrack(ramp, np.zeros((400, 3)), np.zeros((400, 3)), 0.0, 20.0)
    streamer.assign("uav1", link, here, 0)
    streamer.switch("uav1", link, track, 100, origin=50)
    assert _sent(streamer, 99) == (0.0, 0.0, -1.0)
    assert _sent(streamer, 100)[0] == 0.5  # tick 100 is the track's tick 50
    assert streamer.assignments["uav1"].start_tick == 50 and not streamer.pending
    streamer.switch("uav1", link, here, 300, origin=0)
    assert streamer.cancel_switch("uav1") and not streamer.cancel_switch("uav1")
    assert _sent(streamer, 301)[0] == pytest.approx(2.51)
