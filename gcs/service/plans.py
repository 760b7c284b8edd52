"""Stored plans as `planner.Plan` objects, and their sampled trajectories (JSON and CSV).

Reading a large plan back (JSON parse + `Plan.from_dict`) costs tens of milliseconds, so the
last few are kept in a small LRU cache. Sampling is `Plan.sample`, the planner's one
definition of the motion between steps; nothing here interpolates by itself.
"""

from __future__ import annotations

import io
import threading
from collections import OrderedDict
from collections.abc import Iterator

import numpy as np
import orjson

from gcs.errors import ExportError, InvalidRequest, NotFound, StateConflict
from gcs.export.lights import has_lights, light_changes
from gcs.service.limits import trajectory_sample_count
from gcs.service.statuses import MissionStatus
from gcs.service.store import Store
from planner import Plan, PlanFormatError
from planner.methods.lights import color_hex

__all__ = ["PlanCache", "csv_text_field", "light_rows", "sample_times", "trajectory_csv",
           "trajectory_csv_chunks", "trajectory_json_chunks"]


class PlanCache:
    """The `size` most recently used plans, loaded from the store on demand (thread-safe)."""

    def __init__(self, store: Store, size: int = 4) -> None:
        self._store = store
        self._size = size
        self._plans: OrderedDict[str, Plan] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, mission_id: str) -> Plan:
        """The plan of a planned mission; NotFound / StateConflict (still planning, failed)."""
        with self._lock:
            plan = self._plans.get(mission_id)
            if plan is not None:
                self._plans.move_to_end(mission_id)
                return plan
        row = self._store.get_mission(mission_id, with_plan=True)
        if row is None:
            raise NotFound("mission_id", f"no mission with id {mission_id!r}")
        if row.status == MissionStatus.PLANNING:
            raise StateConflict("mission_id", f"mission {mission_id!r} is still planning; "
                           f"poll GET /api/missions/{mission_id} until status is 'planned'")
        if row.status == MissionStatus.FAILED or row.plan_json is None:
            reason = (row.error or {}).get("reason", "no plan")
            raise StateConflict("mission_id", f"mission {mission_id!r} has no plan: {reason}")
        try:
            plan = Plan.from_dict(orjson.loads(row.plan_json))
        except PlanFormatError as exc:  # a stored plan from an incompatible version
            raise StateConflict(f"plan.{exc.field}",
                                f"stored plan unreadable: {exc.reason}") from None
        with self._lock:
            self._plans[mission_id] = plan
            while len(self._plans) > self._size:
                self._plans.popitem(last=False)
        return plan

    def forget(self, mission_id: str) -> None:
        with self._lock:
            self._plans.pop(mission_id, None)


def sample_times(horizon: float, rate: float) -> np.ndarray:
    """0, 1/rate, 2/rate, ... up to the horizon, which is always the last sample."""
    count = int(np.floor(horizon * rate + 1e-9)) + 1
    times = np.arange(count) / rate
    if horizon - times[-1] > 1e-9:
        times = np.append(times, horizon)
    return times


def _check_size(plan: Plan, rate: float, max_rows: int) -> np.ndarray:
    if not plan.vehicles:
        raise StateConflict("mission_id", f"the plan (status {plan.status}) has no trajectories")
    # Counted before anything is allocated: a long horizon at a high rate is gigabytes.
    rows = trajectory_sample_count(plan.scenario.horizon, rate, len(plan.vehicles))
    if rows > max_rows:
        highest = max_rows / len(plan.vehicles) / max(plan.scenario.horizon, 1e-9)
        raise InvalidRequest(
            "rate",
            f"{rate:g} Hz gives {rows} samples ({len(plan.vehicles)} vehicles x "
            f"{rows // len(plan.vehicles)} times), more than the limit {max_rows} (setting "
            f"max_trajectory_samples); use rate <= {highest:.3g}",
        )
    return sample_times(plan.scenario.horizon, rate)


def trajectory_json_chunks(mission_id: str, plan: Plan, rate: float, max_rows: int
                           ) -> Iterator[bytes]:
    """The `TrajectoryOut` document as JSON (every vehicle's setpoints at `rate` Hz, world
    ENU) in pieces of one vehicle each, for a response that sends them as they are made
    instead of holding the whole document. The size is checked here, before the first piece.
    orjson writes the numpy arrays directly (~30x faster than lists + json.dumps)."""
    times = _check_size(plan, rate, max_rows)
    return _json_pieces(mission_id, plan, times, rate)


def light_rows(plan: Plan) -> dict[str, list[tuple[float, float, str]]] | None:
    """Each vehicle's light changes as (start s, end s, "#rrggbb") rows, the lights reaching
    the colour linearly over [start, end] (`gcs.export.lights`, the changes the `.skyc`
    writes), so the page colours each drone at any time without deriving them again. None
    for a plan without a light design, or with one too malformed to export."""
    if not has_lights(plan):
        return None
    try:
        changes = {v.id: light_changes(plan, v.id) or [] for v in plan.vehicles}
    except ExportError:
        return None
    return {vid: [(c.start, c.end, color_hex(c.color)) for c in rows]
            for vid, rows in changes.items()}


def _json_pieces(mission_id: str, plan: Plan, times: np.ndarray, rate: float
                 ) -> Iterator[bytes]:
    lights = light_rows(plan)
    head = orjson.dumps({"mission_id": mission_id, "rate": rate, "frame": "world_enu"})
    yield head[:-1] + b',"t":' + orjson.dumps(times, option=orjson.OPT_SERIALIZE_NUMPY) \
        + b',"vehicles":['
    for k, vehicle in enumerate(plan.vehicles):
        motion = vehicle.sample(plan.scenario.dt, times)
        piece = orjson.dumps({
            "id": vehicle.id,
            "position": np.ascontiguousarray(motion.position),
            "velocity": np.ascontiguousarray(motion.velocity),
            "acceleration": np.ascontiguousarray(motion.acceleration),
            **({"lights": lights[vehicle.id]} if lights is not None else {}),
        }, option=orjson.OPT_SERIALIZE_NUMPY)
        yield piece if k == 0 else b"," + piece
    yield b"]}"


CSV_HEADER = "vehicle,t,x,y,z,vx,vy,vz,ax,ay,az\n"


#: Leading characters that make a spreadsheet read a cell as a formula (OWASP CSV injection).
FORMULA_TRIGGERS = ("=", "+", "-", "@", "\t", "\r")


def csv_text_field(text: str) -> str:
    """A text cell (such as a vehicle id) safe to open in a spreadsheet: a leading formula
    trigger is neutralised with a single quote (OWASP), then the cell is quoted if needed.
    Numbers never go through here: a negative coordinate stays a number."""
    if text.startswith(FORMULA_TRIGGERS):
        text = "'" + text
    if any(c in text for c in ',"\r\n'):
        return '"' + text.replace('"', '""') + '"'
    return text


def trajectory_csv_chunks(plan: Plan, rate: float, max_rows: int) -> Iterator[str]:
    """The trajectory CSV (`trajectory_csv`) in pieces of at most `CSV_CHUNK_ROWS` rows, for
    a response that sends rows as they are written instead of holding the whole text. The
    size is checked here, before the first piece: a refusal is an error, not a cut stream."""
    times = _check_size(plan, rate, max_rows)
    return _csv_pieces(plan, times)


#: Rows per piece of a streamed CSV export.
CSV_CHUNK_ROWS = 5000


def _csv_pieces(plan: Plan, times: np.ndarray) -> Iterator[str]:
    yield CSV_HEADER
    for vehicle in plan.vehicles:
        prefix = csv_text_field(vehicle.id).replace("%", "%%")
        for start in range(0, len(times), CSV_CHUNK_ROWS):
            part = times[start:start + CSV_CHUNK_ROWS]
            motion = vehicle.sample(plan.scenario.dt, part)
            table = np.column_stack([part, motion.position, motion.velocity,
                                     motion.acceleration])
            # Rounded to the printed precision, then + 0.0: no "-0.000000" for tiny negatives.
            table = np.round(table, 6) + 0.0
            out = io.StringIO()
            np.savetxt(out, table, fmt=prefix + ",%.6f" + ",%.6f" * 9)
            yield out.getvalue()


def trajectory_csv(plan: Plan, rate: float, max_rows: int) -> str:
    """One row per vehicle and time: vehicle,t,x,y,z,vx,vy,vz,ax,ay,az (SI, world ENU)."""
    return "".join(trajectory_csv_chunks(plan, rate, max_rows))
