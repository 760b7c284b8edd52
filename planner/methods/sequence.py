"""Formation sequences: F0 -> F1 -> ... with hold times, one planning problem per leg.

Long: the formation-sequence contract: its parser, the legs and their stitching.

A sequence is parsed (`parse_sequence`) into independent leg scenarios: goal assignments
(free legs) are resolved up front in order, so leg k's starts are known without planning leg
k - 1, and every leg is a pure function of picklable inputs (`plan_leg(scenario, solver)`),
ready to be mapped over by any executor. The legs' plans are stitched at rest (each leg starts
and ends at rest, the holds keep every vehicle still on its formation point) and the whole
timeline is verified again (`planner.verification.verify` plus the stitched dynamics).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.errors import ScenarioError
from planner.methods.assignment import assign_goals
from planner.methods.ground import (
    GroundLegs,
    ground_legs,
    landing_motion,
    parse_takeoff,
    takeoff_motion,
)
from planner.methods.lights import Colors, color_hex, formation_colors, leg_transition
from planner.model.flatness import body_rates, jerk_from_accelerations, thrust
from planner.model.scenario import (
    AUTO_STEPS,
    DEFAULTS,
    MAX_STEPS,
    Scenario,
    Vehicle,
    check_id,
    check_keys,
    check_number,
    check_vector,
)
from planner.result import Plan, VehicleTrajectory, Verification
from planner.types import FloatArray
from planner.verification.verify import BOUND_TOLERANCE, verify

__all__ = [
    "FormationSequence",
    "SequencePlan",
    "parse_sequence",
    "plan_leg",
    "plan_sequence",
    "timeline_scenario",
    "timeline_steps",
    "trajectory_csv",
]


_TOP_KEYS = {
    "name", "dt", "min_separation", "separation_scale", "cost_threshold", "max_iterations",
    "limits", "assignment", "vehicles", "formations", "max_horizon", "method", "takeoff",
    "landing",
}
_FORMATION_KEYS = {"name", "positions", "duration", "hold", "assignment", "color", "lights"}
#: Leg settings copied from the sequence into every leg scenario.
_SHARED = ("dt", "min_separation", "separation_scale", "cost_threshold", "max_iterations",
           "limits", "method")
#: Most formations in one sequence (bounds the work one request can ask for).
MAX_FORMATIONS = 100


@dataclass(frozen=True)
class FormationSequence:
    """A validated sequence: its legs as fixed-assignment scenario dicts (the JSON contract,
    picklable), and for every formation which of its points each vehicle takes."""

    name: str
    dt: float
    ids: tuple[str, ...]
    formation_names: tuple[str, ...]
    holds: tuple[int, ...]
    """Steps held at rest on each formation (F0 before the first leg)."""
    legs: tuple[dict[str, Any], ...]
    """Leg k (F_k -> F_k+1) as a scenario dict whose goals are the assigned points."""
    slots: tuple[tuple[int, ...], ...]
    """slots[f][n]: index of the point of formation f that vehicle n takes."""
    points: tuple[FloatArray, ...]
    """Each formation's positions in vehicle order (after assignment)."""
    shared: dict[str, Any]
    """The settings every leg shares (dt, separation, limits, ...), as in the input."""
    least_steps: tuple[int, ...] = ()
    """Each leg's steps; for a leg of `duration: "auto"` (`steps: "auto"`, its horizon
    searched when it is planned) the fewest its moves allow under the boxes."""
    colors: tuple[Colors, ...] | None = None
    """Each formation's colours in vehicle order (`planner.methods.lights`), None for a
    sequence without a light design."""
    transitions: tuple[str, ...] = ()
    """How each leg changes the lights ("fade", "hold", "black"); empty without a design."""
    ground: GroundLegs | None = None
    """The takeoff from and landing on the ground (`planner.methods.ground`), or None for a
    show that starts and ends in the air."""

    @property
    def jobs(self) -> tuple[dict[str, Any], ...]:
        """Every scenario to plan, in the order `plan_sequence` takes their plans: the
        formations' legs, then for a show on the ground its climbs, takeoff and landing."""
        if self.ground is None:
            return self.legs
        return (*self.legs, *self.ground.climbs, self.ground.takeoff_leg,
                self.ground.landing_leg)


def _field_error(field: str, reason: str) -> ScenarioError:
    return ScenarioError(field, reason)


def _seconds(value: Any, field: str, *, positive: bool) -> float:
    """A finite number of seconds, positive or not negative (integers of any size too)."""
    return check_number(value, field, positive=positive, nonneg=not positive)


def _steps(seconds: float, dt: float, field: str) -> int:
    if seconds > MAX_STEPS * 10 * dt:
        raise _field_error(field, f"must be at most {MAX_STEPS * 10} steps of dt = {dt:g} s")
    steps = round(seconds / dt)
    if abs(steps * dt - seconds) > 1e-6 * max(1.0, seconds):
        raise _field_error(field, f"must be a whole number of steps of dt = {dt:g} s")
    return steps


def _positions(value: Any, field: str, count: int) -> FloatArray:
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != count:
        raise _field_error(field, f"must list {count} positions [x, y, z], one per vehicle")
    out = np.empty((count, 3))
    for n, point in enumerate(value):
        out[n] = check_vector(point, f"{field}[{n}]")
    return out


def _header(data: Mapping[str, Any]) -> tuple[str, list[str], str, Sequence[Any]]:
    """(name, vehicle ids, default assignment, formations) of a sequence document."""
    name = data.get("name", "sequence")
    if not isinstance(name, str) or not name.strip():
        raise _field_error("name", "must be a non-empty string")
    ids = data["vehicles"]
    if (not isinstance(ids, Sequence) or isinstance(ids, str) or not ids
            or not all(isinstance(i, str) and i.strip() for i in ids)):
        raise _field_error("vehicles", "must be a non-empty list of vehicle ids (strings)")
    for n, vid in enumerate(ids):
        check_id(vid, f"vehicles[{n}]")
    if len(set(ids)) != len(ids):
        raise _field_error("vehicles", "ids must be unique")
    default_assignment = data.get("assignment", DEFAULTS["assignment"])
    if default_assignment not in ("fixed", "free"):
        raise _field_error("assignment", f"must be 'fixed' or 'free', got {default_assignment!r}")
    formations = data["formations"]
    if not isinstance(formations, Sequence) or isinstance(formations, str):
        raise _field_error("formations", "must be a list of formations")
    if not 2 <= len(formations) <= MAX_FORMATIONS:
        raise _field_error("formations", f"must hold 2 to {MAX_FORMATIONS} formations")
    return name, list(ids), default_assignment, formations


def _leg(data: Mapping[str, Any], name: str, shared: Mapping[str, Any], steps: int | str,
         ids: Sequence[str], starts: FloatArray, goals: FloatArray) -> dict[str, Any]:
    """One leg's scenario document: the shared settings, its steps (and the sequence's
    `max_horizon` for an "auto" duration) and every vehicle from its start to its goal."""
    return {
        "name": name, **shared, "steps": steps,
        "vehicles": [{"id": vid, "start": s.tolist(), "goal": g.tolist()}
                     for vid, s, g in zip(ids, starts, goals, strict=True)],
    } | ({"max_horizon": data["max_horizon"]}
         if steps == AUTO_STEPS and "max_horizon" in data else {})


def parse_sequence(data: Mapping[str, Any]) -> FormationSequence:
    """Validate a sequence document and split it into leg scenarios; `ScenarioError` names
    the field (`formations[2].positions[5]`, `formations[1].duration`, ...)."""
    check_keys(data, _TOP_KEYS, "", ("dt", "min_separation", "limits", "vehicles",
                                     "formations"), document="sequence")
    name, ids, default_assignment, formations = _header(data)
    shared = {key: data[key] for key in _SHARED if key in data}
    dt = check_number(data["dt"], "dt", positive=True, within="dt")
    # checked here, before it weighs any assignment; the legs check every other setting
    scale = check_vector(shared.get("separation_scale", DEFAULTS["separation_scale"]),
                         "separation_scale", positive=True, within="separation_scale")
    count = len(ids)
    takeoff = parse_takeoff(data, shared, scale, count)
    names: list[str] = []
    holds: list[int] = []
    points: list[FloatArray] = []
    slots: list[tuple[int, ...]] = []
    legs: list[dict[str, Any]] = []
    least_steps: list[int] = []
    colors: list[Colors | None] = []
    transitions: list[str] = []
    total = 0
    for f, raw in enumerate(formations):
        where = f"formations[{f}]"
        check_keys(raw, _FORMATION_KEYS, where,
                    ("positions",) if f == 0 else ("positions", "duration"))
        if f == 0 and ("duration" in raw or "assignment" in raw or "lights" in raw):
            bad = next(key for key in ("duration", "assignment", "lights") if key in raw)
            raise _field_error(f"{where}.{bad}", "the first formation is where the fleet "
                                                 "starts: it has no transition")
        label = raw.get("name", f"F{f}")
        if not isinstance(label, str) or not label.strip():
            raise _field_error(f"{where}.name", "must be a non-empty string")
        given = _positions(raw["positions"], f"{where}.positions", count)
        hold = _steps(_seconds(raw.get("hold", 0.0), f"{where}.hold", positive=False), dt,
                      f"{where}.hold")
        total += hold
        if f == 0:
            order = np.arange(count)
            if takeoff is not None and default_assignment == "free":
                order = assign_goals(takeoff.liftoff, given, scale)
        else:
            steps = _duration(raw["duration"], dt, f"{where}.duration")
            assignment = raw.get("assignment", default_assignment)
            if assignment not in ("fixed", "free"):
                raise _field_error(f"{where}.assignment",
                                   f"must be 'fixed' or 'free', got {assignment!r}")
            order = np.arange(count)
            if assignment == "free":
                order = assign_goals(points[-1], given, scale)
            leg = _leg(data, f"{name}: {names[-1]} -> {label}", shared, steps, ids, points[-1],
                       given[order])
            try:
                least = Scenario.from_dict(leg).steps
            except ScenarioError as exc:
                raise _leg_error(exc, f, slots[-1], order) from None
            total += least
            legs.append(leg)
            least_steps.append(least)
            transitions.append(leg_transition(raw, where))
        colors.append(formation_colors(raw, where, count, order))
        if total > MAX_STEPS * 10:
            raise _field_error(where, f"the sequence is longer than {MAX_STEPS * 10} steps")
        names.append(label)
        holds.append(hold)
        points.append(given[order])
        slots.append(tuple(int(x) for x in order))
    if "max_horizon" in data and not any(leg["steps"] == AUTO_STEPS for leg in legs):
        raise _field_error("max_horizon", f'applies only with a formation of duration '
                                          f'"{AUTO_STEPS}": remove it, or set a duration to '
                                          f'"{AUTO_STEPS}"')
    ground = None if takeoff is None else ground_legs(
        data, takeoff, name=name, ids=ids, shared=shared, scale=scale, first=points[0],
        last=points[-1])
    return FormationSequence(
        name=name, dt=dt, ids=tuple(ids), formation_names=tuple(names), holds=tuple(holds),
        legs=tuple(legs), slots=tuple(slots), points=tuple(points), shared=shared,
        least_steps=tuple(least_steps), **_light_design(colors, transitions, count),
        ground=ground,
    )


def _light_design(colors: Sequence[Colors | None], transitions: Sequence[str], count: int
                  ) -> dict[str, Any]:
    """The sequence's light design when any formation has a colour: a formation without one
    keeps the colours before it (the first: dark)."""
    if all(c is None for c in colors):
        return {}
    filled: list[Colors] = []
    for given in colors:
        filled.append(given if given is not None
                      else filled[-1] if filled else np.zeros((count, 3), dtype=np.uint8))
    return {"colors": tuple(filled), "transitions": tuple(transitions)}


def _duration(value: Any, dt: float, field: str) -> int | str:
    """A leg's `duration` as steps, or "auto" (the planner chooses its horizon)."""
    if value == AUTO_STEPS:
        return AUTO_STEPS
    if isinstance(value, str):
        raise _field_error(field, f'must be a number of seconds or "{AUTO_STEPS}" (the '
                                  f"planner chooses), got {value[:20]!r}")
    return _steps(_seconds(value, field, positive=True), dt, field)


def _leg_error(exc: ScenarioError, f: int, previous: tuple[int, ...], order: NDArray[np.intp]
               ) -> ScenarioError:
    """A leg scenario's error, renamed to the sequence field that causes it."""
    field = exc.field
    if field.startswith("vehicles[") and "]." in field:
        n = int(field[len("vehicles["):field.index("]")])
        part = field[field.index("].") + 2:]
        if part == "goal" and "horizon" in exc.reason:
            return _field_error(f"formations[{f}].duration",
                                f"too short for vehicle {n}: {exc.reason}")
        if part in ("goal", "start"):
            g = f if part == "goal" else f - 1
            slot = int(order[n]) if part == "goal" else previous[n]
            return _field_error(f"formations[{g}].positions[{slot}]", exc.reason)
    if field in ("dt", "min_separation", "separation_scale", "cost_threshold",
                 "max_iterations", "method") or field.startswith("limits"):
        return _field_error(field, exc.reason)
    if field == "max_horizon":
        return _field_error(field, f"formations[{f}] (an auto duration): {exc.reason}")
    return _field_error(f"formations[{f}]", f"{field}: {exc.reason}")


def plan_leg(scenario: Mapping[str, Any], solver: str | None = None) -> Plan:
    """Plan one leg: a pure function of picklable inputs (a scenario dict, a solver name),
    so legs can run in any process or on any worker."""
    from planner.planning import plan  # the solver stack, imported when a leg is planned

    return plan(scenario, solver=solver)


@dataclass(frozen=True)
class SequencePlan:
    """A planned sequence: the legs' plans and the stitched, re-verified whole."""

    status: str
    """'converged' when every leg converged and the whole timeline verified, else the
    first failing leg's status, or 'unverified'."""
    message: str
    sequence: FormationSequence
    legs: tuple[Plan, ...]
    positions: FloatArray
    """(N, T+1, 3) the whole timeline on the step grid, vehicle order."""
    velocities: FloatArray
    accelerations: FloatArray
    """(N, T, 3) constant over each step."""
    verification: Verification
    dynamics_error: float
    """Largest residual of the double integrator over the stitched timeline (m, m/s)."""
    segments: tuple[dict[str, Any], ...]
    """The timeline: {'kind': 'hold'|'leg', 'formation' or 'leg', 'start_s', 'end_s'}, and
    for a show on the ground 'takeoff' first and 'landing' last."""
    ground_steps: tuple[tuple[int, ...], tuple[int, ...]] | None = None
    """For a show on the ground: each drone's lift-off step and touchdown step."""

    @property
    def ok(self) -> bool:
        return self.status == "converged"

    @property
    def duration(self) -> float:
        return float(self.accelerations.shape[1] * self.sequence.dt)

    def summary(self) -> dict[str, Any]:
        """The sequence details a flyable plan carries as its `sequence` block: formations
        and slots, the timeline, and one line per leg (status, iterations, time)."""
        full = {**self._header(), "dynamics_error": self.dynamics_error}
        full["legs"] = [
            {"name": leg.scenario.name, "status": leg.status, "message": leg.message,
             "iterations": max(len(leg.iterations) - 1, 0), "steps": leg.scenario.steps,
             "seconds": float(leg.timing.get("total_s", 0.0)),
             "min_separation_continuous": (None if leg.verification is None else
                                           leg.verification.min_separation_continuous)}
            | ({} if leg.horizon is None else {"horizon": leg.horizon})
            for leg in self.legs
        ]
        return full

    def to_plan(self) -> Plan:
        """The stitched timeline as one flyable `planner.Plan`: its scenario starts on F0 and
        ends on the last formation (fixed assignment, shared limits, steps = the whole
        timeline), so `fleetplan fly` and the executor's re-verification take it unchanged;
        the sequence details ride along in `Plan.sequence`. Raises `ScenarioError` when the
        timeline is longer than one scenario may be (`MAX_STEPS`)."""
        steps = self.accelerations.shape[1]
        if steps > MAX_STEPS:
            raise _field_error("formations", f"the sequence lasts {steps} steps; a flyable "
                                             f"plan holds at most {MAX_STEPS}")
        dt = self.sequence.dt
        whole = _whole_scenario(self.sequence, steps)
        p, v, a = self.positions, self.velocities, self.accelerations
        jerk = jerk_from_accelerations(a, dt)
        f = thrust(a)
        rates = body_rates(a, jerk)
        times = np.arange(steps + 1) * dt
        vehicles = tuple(
            VehicleTrajectory(id=vid, t=times, position=p[n], velocity=v[n],
                              acceleration=a[n], jerk=jerk[n], thrust=f[n],
                              body_rates=rates[n])
            for n, vid in enumerate(self.sequence.ids)
        )
        timing = {
            "total_s": float(sum(leg.timing.get("total_s", 0.0) for leg in self.legs)),
            "first_qp_s": float(sum(leg.timing.get("first_qp_s", 0.0) for leg in self.legs)),
        }
        return Plan(
            status=self.status, message=self.message, scenario=whole, vehicles=vehicles,
            iterations=(), timing=timing, verification=self.verification,
            solver=self.legs[0].solver if self.legs else "", sequence=self.summary(),
        )

    def to_dict(self) -> dict[str, Any]:
        return {**self._header(), "verification": asdict(self.verification),
                "dynamics_error": self.dynamics_error,
                "legs": [leg.to_dict() for leg in self.legs]}

    def _header(self) -> dict[str, Any]:
        """Everything of `to_dict` before its verification: not the dynamics residual and
        the legs' plans (which hold every leg's trajectories: megabytes at show scale, not
        wanted in `summary`)."""
        seq = self.sequence
        formations: list[dict[str, Any]] = [
            {"name": name, "hold_s": hold * seq.dt,
             "slots": {vid: slot for vid, slot in zip(seq.ids, slots, strict=True)}}
            for name, hold, slots in zip(seq.formation_names, seq.holds, seq.slots, strict=True)
        ]
        if seq.colors is not None:
            for f, (entry, colors) in enumerate(zip(formations, seq.colors, strict=True)):
                entry["colors"] = {vid: color_hex(c) for vid, c in zip(seq.ids, colors,
                                                                       strict=True)}
                if f:
                    entry["lights"] = seq.transitions[f - 1]
        return {
            "status": self.status,
            "message": self.message,
            "name": seq.name,
            "dt": seq.dt,
            "duration_s": self.duration,
            "vehicles": list(seq.ids),
            "formations": formations,
            "timeline": [dict(s) for s in self.segments],
        } | ({} if self.sequence.ground is None else {"ground": self._ground()})

    def _ground(self) -> dict[str, Any]:
        """Where each drone takes off and lands, in which wave, and when."""
        seq, ground, dt = self.sequence, self.sequence.ground, self.sequence.dt
        assert ground is not None and self.ground_steps is not None
        liftoff, touchdown = self.ground_steps

        def per(values: Any) -> dict[str, Any]:
            return dict(zip(seq.ids, values, strict=True))

        return {
            "takeoff": {"homes": per(ground.homes.tolist()),
                        "waves": per(ground.takeoff_waves.tolist()),
                        "liftoff_s": per([k * dt for k in liftoff])},
            "landing": {"slots": per(ground.slots.tolist()),
                        "waves": per(ground.landing_waves.tolist()),
                        "touchdown_s": per([k * dt for k in touchdown])},
        }


def _stitch(sequence: FormationSequence, legs: Sequence[Plan]
            ) -> tuple[FloatArray, FloatArray, FloatArray, tuple[dict[str, Any], ...]]:
    n, dt = len(sequence.ids), sequence.dt
    p_parts, v_parts, a_parts, segments = [], [], [], []
    clock = 0

    def hold(f: int) -> None:
        nonlocal clock
        steps = sequence.holds[f]
        if steps:
            point = sequence.points[f][:, None, :]
            p_parts.append(np.repeat(point, steps, axis=1))
            v_parts.append(np.zeros((n, steps, 3)))
            a_parts.append(np.zeros((n, steps, 3)))
            segments.append({"kind": "hold", "formation": sequence.formation_names[f],
                             "start_s": clock * dt, "end_s": (clock + steps) * dt})
            clock += steps

    hold(0)
    for k, leg in enumerate(legs):
        steps = leg.scenario.steps
        p_parts.append(leg.positions()[:, :-1])
        v_parts.append(leg.velocities()[:, :-1])
        a_parts.append(leg.accelerations())
        segments.append({"kind": "leg", "leg": k, "from": sequence.formation_names[k],
                         "to": sequence.formation_names[k + 1], "start_s": clock * dt,
                         "end_s": (clock + steps) * dt})
        clock += steps
        hold(k + 1)
    # The final state: the last formation, at rest.
    p_parts.append(sequence.points[-1][:, None, :])
    v_parts.append(np.zeros((n, 1, 3)))
    return (np.concatenate(p_parts, axis=1), np.concatenate(v_parts, axis=1),
            np.concatenate(a_parts, axis=1), tuple(segments))


def _whole_scenario(sequence: FormationSequence, steps: int) -> Scenario:
    """The whole timeline as one scenario (F0 to the last formation) for the verifier."""
    first = Scenario.from_dict(sequence.legs[0])
    starts, goals = sequence.points[0], sequence.points[-1]
    if sequence.ground is not None:
        starts, goals = sequence.ground.homes, sequence.ground.slots
    vehicles = tuple(Vehicle(vid, s, g)
                     for vid, s, g in zip(sequence.ids, starts, goals, strict=True))
    return Scenario(
        name=sequence.name, dt=sequence.dt, steps=steps, min_separation=first.min_separation,
        separation_scale=first.separation_scale, cost_threshold=first.cost_threshold,
        max_iterations=first.max_iterations, limits=first.limits, vehicles=vehicles,
        starts=starts, goals=goals,
    )


def timeline_scenario(sequence: FormationSequence) -> Scenario:
    """The whole timeline of a parsed sequence as one scenario (F0 to the last formation,
    fixed assignment, steps = holds + legs): the scenario its stitched plan carries."""
    return _whole_scenario(sequence, timeline_steps(sequence))


def timeline_steps(sequence: FormationSequence) -> int:
    """Steps of the whole timeline: holds and legs (an auto leg at its fewest steps), and
    the takeoff and landing (each climb counted once up and once down)."""
    steps = sum(sequence.holds) + sum(sequence.least_steps)
    ground = sequence.ground
    if ground is not None:
        steps += sum(Scenario.from_dict(leg).steps
                     for leg in (ground.takeoff_leg, ground.landing_leg))
        steps += 2 * sum(Scenario.from_dict(climb).steps for climb in ground.climbs)
    return steps


def dynamics_residual(p: FloatArray, v: FloatArray, a: FloatArray, dt: float) -> float:
    """Largest error of p_k+1 = p_k + dt v_k + dt^2/2 a_k and v_k+1 = v_k + dt a_k."""
    if a.shape[1] == 0:
        return 0.0
    dp = p[:, 1:] - p[:, :-1] - dt * v[:, :-1] - 0.5 * dt * dt * a
    dv = v[:, 1:] - v[:, :-1] - dt * a
    return float(max(np.abs(dp).max(), np.abs(dv).max()))


def plan_sequence(data: Mapping[str, Any] | FormationSequence, *, solver: str | None = None,
                  mapper: Callable[..., Iterable[Plan]] | None = None) -> SequencePlan:
    """Plan every leg (through `mapper(plan_leg, sequence.jobs, solvers)`, the built-in `map` by
    default; an executor's `map` plans them in parallel), stitch them at rest with the holds,
    and verify the whole timeline. Raises `ScenarioError` for an invalid sequence."""
    sequence = data if isinstance(data, FormationSequence) else parse_sequence(data)
    ground = sequence.ground
    jobs = sequence.jobs
    plans = list((mapper or map)(plan_leg, jobs, [solver] * len(jobs)))
    legs = plans[:len(sequence.legs)]
    p, v, a, segments = _stitch(sequence, legs)
    moments = None
    if ground is not None:
        p, v, a, segments, moments = _on_the_ground(sequence, ground, plans[len(legs):],
                                                    (p, v, a), segments)
    whole = _whole_scenario(sequence, a.shape[1])
    verification = verify(whole, p, v, a, ground=ground is not None)
    residual = dynamics_residual(p, v, a, sequence.dt)
    failed = [(k, leg) for k, leg in enumerate(plans) if not leg.ok]
    if failed:
        k, leg = failed[0]
        status = leg.status if leg.status != "converged" else "unverified"
        message = f"leg {k} ({leg.scenario.name}): {leg.status}: {leg.message}"
    elif not verification.verified or residual > BOUND_TOLERANCE:
        status = "unverified"
        problems = verification.failures()
        if residual > BOUND_TOLERANCE:
            problems.append(f"stitched dynamics off by {residual:.3g}")
        message = "the stitched sequence failed verification: " + "; ".join(problems)
    else:
        status = "converged"
        message = (f"{len(plans)} legs converged; the stitched {a.shape[1] * sequence.dt:g} s "
                   f"timeline verified")
    return SequencePlan(status, message, sequence, tuple(plans), p, v, a, verification,
                        residual, segments, moments)


def _on_the_ground(sequence: FormationSequence, ground: GroundLegs, plans: Sequence[Plan],
                   middle: tuple[FloatArray, FloatArray, FloatArray],
                   segments: tuple[dict[str, Any], ...]
                   ) -> tuple[FloatArray, FloatArray, FloatArray, tuple[dict[str, Any], ...],
                              tuple[tuple[int, ...], tuple[int, ...]]]:
    """The formations' timeline with the takeoff before it and the landing after it."""
    climbs = dict(zip(ground.climb_heights, plans[:len(ground.climbs)], strict=True))
    up = takeoff_motion(ground, climbs, plans[-2])
    down = landing_motion(ground, climbs, plans[-1])
    p, v, a = middle
    dt = sequence.dt
    before, during = up.a.shape[1], a.shape[1]
    shift = before * dt
    moved = tuple({**s, "start_s": s["start_s"] + shift, "end_s": s["end_s"] + shift}
                  for s in segments)
    total = before + during + down.a.shape[1]
    timeline = ({"kind": "takeoff", "start_s": 0.0, "end_s": shift}, *moved,
                {"kind": "landing", "start_s": (before + during) * dt, "end_s": total * dt})
    moments = (tuple(int(k) for k in up.moment),
               tuple(int(k) + before + during for k in down.moment))
    return (np.concatenate([up.p[:, :-1], p[:, :-1], down.p], axis=1),
            np.concatenate([up.v[:, :-1], v[:, :-1], down.v], axis=1),
            np.concatenate([up.a, a, down.a], axis=1), timeline, moments)


def _csv_rows(times_ms: NDArray[np.int64], positions: FloatArray) -> Iterator[str]:
    yield "Time [msec],x [m],y [m],z [m]"
    for t, (x, y, z) in zip(times_ms.tolist(), positions.tolist(), strict=True):
        yield f"{t},{x:.4f},{y:.4f},{z:.4f}"


def trajectory_csv(positions: FloatArray, velocities: FloatArray, accelerations: FloatArray,
                   dt: float, ids: Sequence[str], rate_hz: float | None = None
                   ) -> dict[str, str]:
    """Per-vehicle CSV text {id: csv}: header `Time [msec],x [m],y [m],z [m]`, one row per
    sample (integer milliseconds from the start, metres, world frame ENU), the layout show
    tools import. Samples at the steps, or at `rate_hz` using the exact motion in between."""
    from planner.model.dynamics import interpolate

    steps = accelerations.shape[1]
    duration = steps * dt
    if rate_hz is None:
        times = np.arange(steps + 1) * dt
        sampled = positions
    else:
        if not (math.isfinite(rate_hz) and 0 < rate_hz <= 1000):
            raise ValueError("rate_hz must be in (0, 1000]")
        count = math.floor(duration * rate_hz + 1e-9) + 1
        times = np.arange(count) / rate_hz
        sampled = interpolate(positions, velocities, accelerations, dt, times).position
    times_ms = np.rint(times * 1000.0).astype(np.int64)
    return {vid: "\n".join(_csv_rows(times_ms, sampled[n])) + "\n"
            for n, vid in enumerate(ids)}
