"""gcs.flight.link.quality: loss from sequence numbers with reordering and duplicates counted
apart (wrapping at 255), latency from TIMESYNC, jitter from the vehicle's timestamps, and the
degradation judged with hysteresis; a reboot told from the vehicle's clock."""

from __future__ import annotations

import random

import pytest

from gcs.autopilot import px4
from gcs.fleet.fleetfile import FlightOptions
from gcs.flight.link.endpoints import Endpoint
from gcs.flight.link.link import VehicleLink
from gcs.flight.link.quality import (
    RECOVER_S,
    RESYNC_S,
    LinkQuality,
    LinkWatch,
    SequenceCounter,
    Timing,
)
from gcs.flight.link.telemetry import Telemetry
from gcs.flight.safety.monitor import vehicle_fault
from gcs.wire import mavlink


def _count(seqs: list[int], period: float = 0.01) -> SequenceCounter:
    counter = SequenceCounter()
    for i, seq in enumerate(seqs):
        counter.count(seq & 0xFF, i * period)
    return counter


def test_gaps_are_lost_across_the_wrap_at_255() -> None:
    counter = _count([*range(250, 256), 0, 1, 4, 5, *range(7, 300)])
    assert counter.lost == 3  # 2, 3 and 6
    assert counter.received == 6 + 2 + 2 + 293
    assert (counter.reordered, counter.duplicates, counter.restarts) == (0, 0, 0)
    assert counter.loss == pytest.approx(3 / (counter.received + 3))


def test_a_late_packet_fills_its_gap_and_is_not_lost() -> None:
    counter = _count([253, 255, 254, 1, 0, 2, 3])
    assert (counter.received, counter.lost, counter.reordered) == (7, 0, 2)
    assert counter.duplicates == 0


def test_a_packet_seen_twice_is_a_duplicate_not_a_loss() -> None:
    counter = _count([10, 11, 11, 12, 10, 13])
    assert (counter.received, counter.lost, counter.duplicates) == (4, 0, 2)


def test_shuffled_without_loss_counts_no_loss() -> None:
    """Jitter that reorders packets within a few dozen of each other loses nothing."""
    rng = random.Random(3)
    seqs = list(range(2000))
    order = sorted(seqs, key=lambda s: s + rng.uniform(0, 30))
    counter = _count(order)
    assert counter.lost == 0 and counter.received == 2000
    assert counter.reordered > 100  # bound: many came after a later one


def test_real_loss_is_counted_whatever_the_order() -> None:
    rng = random.Random(4)
    kept = [s for s in range(5000) if rng.random() >= 0.2]
    order = sorted(kept, key=lambda s: s + rng.uniform(0, 20))
    counter = _count(order)
    # every one missing, but those before the first to arrive (the count starts there)
    unseen = set(range(max(kept) + 1)) - set(kept)
    assert counter.lost == len([s for s in unseen if s > order[0]])
    assert counter.received == len(kept) and counter.duplicates == 0
    assert counter.loss == pytest.approx(0.2, abs=0.02)


def test_silence_and_a_reboot_start_the_count_again() -> None:
    counter = SequenceCounter()
    for seq in range(10):
        counter.count(seq, 0.01 * seq)
    counter.count(200, 0.1 + RESYNC_S + 0.1)  # after an outage: numbers may have wrapped
    assert counter.restarts == 1 and counter.lost == 190  # a lower bound
    counter.restart()
    counter.count(0, 2.0)
    counter.count(1, 2.01)
    assert counter.restarts == 2 and counter.lost == 190 and counter.duplicates == 0


def test_latency_is_half_the_timesync_round_trip_and_jitter_follows_the_transit() -> None:
    timing = Timing()
    ts1 = timing.request(1_000_000_000)  # 1 s on the station's clock
    timing.reply(ts1 + 1, 1.2)  # not ours: ignored
    assert timing.latency is None
    timing.reply(ts1, 1.2)
    assert timing.latency == pytest.approx(0.1)
    timing.reply(ts1, 1.4)  # answered twice: the second is no round trip
    assert timing.latency == pytest.approx(0.1)
    for k in range(200):  # 50 Hz, every other one 20 ms late
        timing.stamped(0.02 * k + (0.02 if k % 2 else 0.0), 0.02 * k)
    assert timing.jitter == pytest.approx(0.02, rel=0.05)


def test_the_watch_tells_a_degraded_link_once_and_its_recovery_after_a_while() -> None:
    told: list[tuple[str, str, str]] = []
    watch = LinkWatch(lambda vid, text: told.append(("degraded", vid, text)),
                      lambda vid, text: told.append(("recovered", vid, text)))
    quality = LinkQuality()
    clock = 0.0
    seq = 0

    def run(seconds: int, loss: float) -> None:
        nonlocal clock, seq
        for second in range(seconds):
            for s in range(seq, seq + 50):
                if not (loss and s % round(1 / loss) == 0):
                    quality.counter.count(s & 0xFF, clock)
                clock += 0.02
            seq += 50
            watch.check({"uav1": quality}, clock)
            del second

    run(8, 0.0)
    assert told == []
    run(10, 0.25)  # a quarter lost from here: told once, not every second
    assert [kind for kind, _, _ in told] == ["degraded"]
    assert told[0][1] == "uav1" and "loss 25% over the last 5 s" in told[0][2]
    run(3, 0.0)  # good again, but not for long enough
    run(2, 0.25)
    assert [kind for kind, _, _ in told] == ["degraded"]
    run(int(RECOVER_S) + 8, 0.0)
    assert [kind for kind, _, _ in told] == ["degraded", "recovered"]


def _position(mav: mavlink.MAVLink, boot_ms: int) -> object:
    msg = mav.local_position_ned_encode(boot_ms, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0)
    msg.pack(mav)
    mav.seq = (mav.seq + 1) & 0xFF
    return msg


def test_a_reboot_is_named_as_a_reboot() -> None:
    """The vehicle's clock going back is a reboot, whatever mode it came back in (PX4
    restarts in AUTO.LOITER or POSITION: not a `left_offboard`)."""
    link = VehicleLink("uav1", Endpoint("udpin:127.0.0.1:9"), 1)
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    tel = link.telemetry
    tel.heartbeat_time = tel.message_time = 0.0
    tel.mode = px4.OFFBOARD
    for k in range(5):
        link.handle(_position(mav, 60_000 + 20 * k), 0.02 * k)
    assert vehicle_fault(link, FlightOptions(), 0.1) is None
    link.handle(_position(mav, 60_050), 0.11)  # a little out of order: no reboot
    assert tel.reboot_time is None
    tel.mode = px4.HOLD
    link.handle(_position(mav, 1_200), 0.2)
    fault = vehicle_fault(link, FlightOptions(), 0.2)
    assert fault is not None and fault[0] == "rebooted"
    assert "went back to 1.2 s" in fault[1] and "mode AUTO.LOITER" in fault[1]
    assert tel.quality.counter.restarts == 1


def test_a_non_finite_position_that_arrived_is_not_counted_lost() -> None:
    """A LOCAL_POSITION_NED with NaN is refused as a position, but it arrived: its
    sequence number fills its place, so it is not a gap."""
    link = VehicleLink("uav1", Endpoint("udpin:127.0.0.1:9"), 1)
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    for k in range(3):
        link.handle(_position(mav, 1_000 + 20 * k), 0.02 * k)
    bad = mav.local_position_ned_encode(1_060, float("nan"), 0.0, -1.0, 0.0, 0.0, 0.0)
    bad.pack(mav)
    mav.seq = (mav.seq + 1) & 0xFF
    link.handle(bad, 0.06)
    link.handle(_position(mav, 1_080), 0.08)
    report = link.telemetry.quality.report()
    assert link.telemetry.invalid_estimates == 1
    assert (report["received"], report["lost"]) == (5, 0)


def test_telemetry_reports_the_figures() -> None:
    tel = Telemetry()
    for seq in [0, 1, 3, 2, 2, 5]:
        tel.count_sequence(seq, 0.0)
    report = tel.quality.report()
    assert {k: report[k] for k in ("received", "lost", "reordered", "duplicates")} == {
        "received": 5, "lost": 1, "reordered": 1, "duplicates": 1}
    assert report["loss_pct"] == pytest.approx(100 / 6, abs=0.01)


def test_packets_in_flight_are_not_recent_loss() -> None:
    """A 250 ms delay at 50 Hz keeps a dozen packets in flight: while they may still
    arrive, they are not counted lost over the last seconds."""
    quality = LinkQuality()
    rng = random.Random(5)
    arrivals = sorted((s * 0.02 + rng.uniform(0.1, 0.3), s) for s in range(50 * 12))
    second = 1.0
    in_flight = []
    for t, seq in arrivals:
        while t >= second:
            quality.sample(second)
            in_flight.append(quality.counter.lost - quality.counter.settled_lost)
            second += 1.0
        quality.counter.count(seq & 0xFF, t)
    recent = quality.recent()
    assert recent is not None and recent[1] == 0 and recent[0] > 200
    assert max(in_flight) > 0  # bound: some were due at each sample, none was lost
    assert quality.counter.lost == 0


def test_the_stations_own_stalls_are_not_the_links_jitter() -> None:
    told: list[str] = []
    watch = LinkWatch(lambda vid, text: told.append(text), lambda vid, text: None)
    quality = LinkQuality()
    for k in range(400):  # 50 Hz, every other message 100 ms late: 100 ms of jitter
        quality.counter.count(k & 0xFF, 0.02 * k)
        quality.timing.stamped(0.02 * k + (0.1 if k % 2 else 0.0), 0.02 * k)
    for second in range(1, 5):
        watch.check({"uav1": quality}, float(second), station_stalled=True)
    assert told == []
    for second in range(5, 8):
        watch.check({"uav1": quality}, float(second))
    assert len(told) == 1 and "jitter 100 ms" in told[0]
