"""The service's mirror of a flight record, grown from deltas taken in the vehicle process,
equals the record itself at every step, and only what is new crosses over."""

from __future__ import annotations

import pickle

import orjson

from gcs.flight.link.setpoints import Setpoint
from gcs.flight.run.record import COLUMNS, FlightRecorder
from gcs.service.record_mirror import RecordMirror, record_delta


def _fly_a_little(recorder: FlightRecorder, start: int, ticks: int) -> None:
    for k in range(start, start + ticks):
        for i, v in enumerate(recorder.vehicles.values()):
            x = 0.1 * k + i
            v.add_setpoint(0.02 * k, k, Setpoint((x, -x, -2.0), (0.5, -0.5, 0.0),
                                                  (0.0, 0.0, 0.1 * i), 0.0))
            if k % 2 == 0:
                v.tel_t.append(0.02 * k)
                v.tel_pos.append([x, x, 2.0])
                v.tel_vel.append([0.5, 0.5, float("nan") if k == 4 else 0.0])
            if k % 7 == 0:
                v.modes.append({"t": 0.02 * k, "mode": "OFFBOARD", "armed": True})
        recorder.event(0.02 * k, None, "tick", str(k))


def test_the_mirror_equals_the_record_after_every_delta() -> None:
    recorder = FlightRecorder(["a", "b", "c"], [1, 2, 3])
    mirror = RecordMirror()
    sizes = []
    for step in range(4):
        _fly_a_little(recorder, 50 * step, 50)
        delta = record_delta(recorder, mirror.cursor())
        sizes.append(len(pickle.dumps(delta)))
        mirror.apply(pickle.loads(pickle.dumps(delta)))  # as it crosses the pipe
        got, want = mirror.snapshot(), recorder.to_dict()
        assert got["partial"] is True and got["format"] == want["format"]
        assert got["events"] == want["events"]
        for mine, theirs in zip(got["vehicles"], want["vehicles"], strict=True):
            assert mine["modes"] == theirs["modes"]
            for column in COLUMNS:
                m, t = mine[column.section][column.key], theirs[column.section][column.key]
                assert orjson.dumps(m) == orjson.dumps(t), column  # as the journal writes it
                assert len(m) == len(t) > 0
    # each delta carried only its own 50 ticks: the same size every time, not growing
    assert max(sizes) < 1.2 * min(sizes)
    # nothing new: nothing crosses but the (empty) lists
    empty = record_delta(recorder, mirror.cursor())
    assert empty["events"] == [] and empty["meta"] is None
    assert all(len(v["columns"][c.attribute]) == 0 for v in empty["vehicles"] for c in COLUMNS)


def test_the_meta_crosses_once_it_is_set() -> None:
    recorder = FlightRecorder(["a"], [1])
    mirror = RecordMirror()
    mirror.apply(record_delta(recorder, mirror.cursor()))
    recorder.meta = {"plan": {"name": "x"}, "flight_start": 1.5}
    mirror.apply(record_delta(recorder, mirror.cursor()))
    assert mirror.snapshot()["flight_start"] == 1.5
    assert record_delta(recorder, mirror.cursor())["meta"] is None
