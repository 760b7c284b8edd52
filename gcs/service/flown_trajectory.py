"""What a replanned flight's plans ask of each vehicle, as one trajectory in flight time.

A flight flies its mission's plan from flight time 0 and each switched replan's plan from
its switch time (`FlightExecutor.replan`). The page draws the flight's paths and follows it
with one time slider, so it needs one document on one time grid: `flown_trajectory` samples
at `rate` Hz, from 0 to the end of the plan flown last (which may end before an earlier
one would have), each vehicle on the plan in force at each time (`Plan.sample`, the
planner's one definition of the motion between steps). A vehicle a replan dropped is on
no plan after its switch: it is shown where its last plan had it then, at rest (it lands
or holds on its own motion, which the flight's live state shows).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gcs.errors import InvalidRequest
from gcs.service.limits import trajectory_sample_count
from gcs.service.plans import sample_times
from gcs.service.replan_handle import Segment
from planner import Plan

__all__ = ["Segment", "flown_trajectory", "replanned_in"]


def replanned_in(record: dict[str, Any]) -> list[Segment]:
    """The switched replans' plans in a flight record (its ``replans`` that carry a plan,
    `gcs.flight.run.record`), in order."""
    return [Segment(float(r["switch_time"]), Plan.from_dict(r["plan"]), int(r["id"]))
            for r in record.get("replans") or () if r.get("plan")]


def flown_trajectory(segments: Sequence[Segment], rate: float,
                     max_rows: int) -> dict[str, Any]:
    """Every vehicle of the first plan (in its order) sampled at `rate` Hz over the flight's
    plans (see the module): ``{rate, frame, t, vehicles: [{id, position, velocity}],
    switches: [{replan, t}], dropped: {id: t}}``, JSON-ready. InvalidRequest naming `rate`
    when the samples would exceed `max_rows`."""
    ordered = sorted(segments, key=lambda s: s.start)
    ids = list(ordered[0].plan.scenario.ids)
    end = ordered[-1].start + ordered[-1].plan.scenario.horizon  # the plan flown last
    rows = trajectory_sample_count(end, rate, len(ids))
    if rows > max_rows:
        raise InvalidRequest("rate", f"{rate:g} Hz gives {rows} samples, more than the limit "
                                     f"{max_rows} (setting max_trajectory_samples)")
    times = sample_times(end, rate)
    position = np.zeros((len(ids), len(times), 3))
    velocity = np.zeros_like(position)
    dropped: dict[str, float] = {}
    left: dict[str, np.ndarray] = {}  # where each dropped vehicle was left
    last: dict[str, Segment] = {}  # the latest plan each vehicle was on
    for n, segment in enumerate(ordered):
        stop = ordered[n + 1].start if n + 1 < len(ordered) else np.inf
        mine = (times >= segment.start) & (times < stop) if n else times < stop
        index = {vid: k for k, vid in enumerate(segment.plan.scenario.ids)}
        for row, vid in enumerate(ids):
            if vid in index:
                last[vid] = segment
                track = segment.plan.vehicles[index[vid]]
                motion = track.sample(segment.plan.scenario.dt, times[mine] - segment.start)
                position[row, mine], velocity[row, mine] = motion.position, motion.velocity
                continue
            if vid not in left:  # off the plans from this switch on: at rest where it was
                dropped[vid] = segment.start
                was = last[vid]
                track = was.plan.vehicles[was.plan.scenario.ids.index(vid)]
                left[vid] = track.sample(was.plan.scenario.dt,
                                         [segment.start - was.start]).position[0]
            position[row, mine] = left[vid]
    return {
        "rate": rate, "frame": "world_enu", "t": times.tolist(),
        "vehicles": [{"id": vid, "position": position[row].tolist(),
                      "velocity": velocity[row].tolist()} for row, vid in enumerate(ids)],
        "switches": [{"replan": s.replan, "t": s.start} for s in ordered[1:]],
        "dropped": dropped,
    }
