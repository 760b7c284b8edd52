"""`fleetplan plan SCENARIO.json -o PLAN.json`: plan, print progress and a summary, save.

Long: one command: its options, progress lines and summary table.

A formation sequence (a document with a `formations` key, see `planner.methods.sequence`) is planned
leg by leg (in parallel: a local process pool, or Dask tasks with --scheduler), stitched and
verified as a whole; the stitched plan is written (flyable with `fleetplan fly`) and, with
--csv-dir, one show-tool CSV per vehicle.

Exit status: 0 for a converged, verified plan; 1 when the plan was computed but did not
converge or failed verification (the plan is still written, for inspection); 2 for bad
input (unreadable file, invalid JSON, an invalid scenario: the message names the field).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import re
import sys
from pathlib import Path
from typing import Any

__all__ = ["configure", "run"]

EXIT_OK, EXIT_NOT_VERIFIED, EXIT_BAD_INPUT = 0, 1, 2
#: Environment variable naming the Dask scheduler (the service's `scheduler` setting).
SCHEDULER_ENV = "FLEETPLAN_SCHEDULER"
#: Vehicle ids that can name a CSV file as they are (no path separators, no '..').
_SAFE_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scenario", type=Path, help="scenario JSON file")
    parser.add_argument(
        "-o", "--output", type=Path, default=None,
        help="where to write the plan JSON (default: <scenario name>.plan.json)",
    )
    parser.add_argument(
        "--solver", choices=("piqp", "clarabel", "osqp"), default=None,
        help="QP solver (default: piqp, the fastest accurate one measured)",
    )
    parser.add_argument(
        "--csv-dir", type=Path, default=None,
        help="sequences: also write one CSV per vehicle here (time ms, x, y, z; show tools)",
    )
    parser.add_argument(
        "--csv-rate", type=float, default=None, metavar="HZ",
        help="sequences: CSV sample rate (default: one row per planner step)",
    )
    parser.add_argument(
        "--method", default=None, metavar="{auto,whole,prioritized}",
        help="how to plan (default: the scenario's method, else auto): auto races "
             "prioritized batches against the whole fleet on two cores where both apply and "
             "takes the first verified plan; whole plans the whole fleet at once; "
             "prioritized plans in batches, each around the earlier ones, and the whole "
             "fleet if they fail",
    )
    parser.add_argument(
        "--decompose", default=None, metavar="{none,prioritized}",
        help="the same as --method: none is whole, prioritized is prioritized",
    )
    parser.add_argument(
        "--batch-size", type=int, default=None, metavar="N",
        help="vehicles per prioritized batch (methods auto and prioritized; default: the "
             "planner's, by the fleet's motion: planner.methods.prioritized.batch_size)",
    )
    parser.add_argument(
        "--takeoff-fleet", type=Path, default=None, metavar="FLEET.json",
        help="sequences: take off from this fleet file's homes (world frame, z = 0), in the "
             "sequence's vehicle order: fills takeoff.homes (as the sequence's own "
             "takeoff.fleet does, a path relative to the sequence file)",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="no per-iteration lines")
    parser.add_argument(
        "--scheduler", metavar="tcp://HOST:8786", default=os.environ.get(SCHEDULER_ENV) or None,
        help=f"plan as a task on this Dask cluster (default ${SCHEDULER_ENV}; unset: here)",
    )
    parser.add_argument(
        "--fleet", type=Path, default=None,
        help="plan for this fleet: min_separation R + 2 x its position_error, stated in the "
             "plan as separation_margin (gcs.flight.safety.margin)",
    )


def _fail(message: str) -> int:
    """Print every line of `message` as an error (one per problem found); bad input."""
    for line in message.splitlines() or [message]:
        print(f"error: {line}", file=sys.stderr)
    return EXIT_BAD_INPUT


def load_json(path: Path) -> Any:
    """Read a JSON file, raising ValueError with a message fit for the user."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise ValueError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path} is not valid JSON: {exc.msg} at line {exc.lineno}, "
                         f"column {exc.colno}") from None


def _number(value: float | None, fmt: str) -> str:
    """A figure for a table: "-" when there is none (never "nan" or "None")."""
    return "-" if value is None or not math.isfinite(value) else fmt.format(value)


def _summary_rows(plan: Any) -> list[tuple[str, str]]:
    v = plan.verification
    rows = [
        ("status", plan.status),
        ("vehicles", str(len(plan.vehicles))),
        ("SCP iterations", str(max(len(plan.iterations) - 1, 0)) if plan.sequence is None
         else " + ".join(str(leg["iterations"]) for leg in plan.sequence["legs"])),
        ("horizon", _horizon_text(plan)),
        ("cost (sum ||a+g||^2)", _number(plan.cost, "{:.4f}")),
        ("time total / first QP", f"{plan.timing['total_s']:.3f} s / "
                                  f"{plan.timing['first_qp_s']:.3f} s"),
        ("solver", plan.solver),
    ]
    if plan.method is not None:
        rows.append(("method", _method_summary(plan)))
    if v is not None:
        sep = plan.scenario.min_separation
        if v.min_separation is not None:
            rows += [
                ("min separation (steps)", f"{v.min_separation:.4f} m (R = {sep:g} m)"),
                ("min separation (continuous)",
                 f"{_number(v.min_separation_continuous, '{:.4f}')} m, "
                 f"{' & '.join(v.closest_pair)} at t = {v.closest_time:.2f} s"),
            ]
        elif len(plan.vehicles) > 1:
            rows.append(("min separation", f"undefined (R = {sep:g} m)"))
        if plan.scenario.obstacles:
            near = v.closest_obstacle or {}
            rows.append(("obstacle clearance (continuous)",
                         f"{_number(v.obstacle_distance_min, '{:.4f}')} m (clearance "
                         f"{plan.scenario.clearance:g} m), {near.get('vehicle')} from "
                         f"'{near.get('id')}' at t = {_number(near.get('time'), '{:.2f}')} s"))
        worst = max(v.max_violation.items(), key=lambda kv: -1.0 if kv[1] is None else kv[1])
        boundary = [x for x in v.boundary_error.values() if x is not None]
        rows += [
            ("max box violation", f"{_number(worst[1], '{:.2e}')} ({worst[0]})"),
            ("max boundary error", f"{_number(max(boundary, default=None), '{:.2e}')} m"),
            ("thrust range", f"{_number(v.thrust_range[0], '{:.2f}')} .. "
                             f"{_number(v.thrust_range[1], '{:.2f}')} m/s^2"),
            ("peak body rate", f"{_number(v.body_rate_peak, '{:.3f}')} rad/s"),
            ("flyable", "yes" if v.flyable else "no"),
            ("checks", "pass" if v.verified else "FAIL"),
        ]
    # the verdict: the same `Plan.problems` as the exit status and the error line
    problems = plan.problems()
    rows.append(("verified", "yes" if not problems else "NO: " + "; ".join(problems)))
    return rows


def _horizon_text(plan: Any) -> str:
    """The plan's horizon, and for `steps: "auto"` the candidates the search tried."""
    scenario = plan.scenario
    text = f"{scenario.horizon:g} s ({scenario.steps} steps of {scenario.dt:g} s)"
    search = plan.horizon
    if search is None:
        return text
    tried = ", ".join(f"{c['steps']} {c['status']}" for c in search["tried"])
    if search["chosen_steps"] is None:
        return (f"none verified up to max_horizon {search['max_horizon']:g} s "
                f"(steps tried: {tried})")
    return f"{text}, chosen (steps tried: {tried})"
def _method_summary(plan: Any) -> str:
    """The method that planned, and what became of the others that ran."""
    others = [f"{a.method} {a.outcome} after {a.seconds:.2f} s" for a in plan.attempts
              if a.outcome in ("failed", "cancelled")]
    text: str = plan.method + (f" ({'; '.join(others)})" if others else "")
    return text


def _label(record: Any) -> str:
    """An iteration line's tail: the method whose iteration it is, and its batch of how many
    with prioritized batches ("  [prioritized batch 3/8]")."""
    parts = [] if record.method is None else [record.method]
    if record.batch is not None:
        parts.append(f"batch {record.batch}/{record.batches}")
    return f"  [{' '.join(parts)}]" if parts else ""


def _verdict(plan: Any) -> int:
    """Exit status from the plan's one verdict (`Plan.problems`, as in the table)."""
    problems = plan.problems()
    if not problems:
        return EXIT_OK
    print(f"error: plan not verified: {'; '.join(problems)}", file=sys.stderr)
    return EXIT_NOT_VERIFIED


def _print_summary(plan: Any) -> None:
    try:
        from rich.console import Console
        from rich.table import Table
    except ImportError:  # pragma: no cover - rich is a dependency; plain text fallback
        for key, value in _summary_rows(plan):
            print(f"{key:>28}  {value}")
        return
    table = Table(title=f"plan: {plan.scenario.name}", show_header=False)
    table.add_column(justify="right", style="bold")
    table.add_column()
    for key, value in _summary_rows(plan):
        table.add_row(key, value)
    Console().print(table)


def _write_plan(plan: Any, output: Path) -> None:
    """Write the plan JSON to `output`, streamed (`Plan.write_json`: a 16,000-vehicle plan is
    ~1 GB of text); OSError when it cannot."""
    with output.open("w", encoding="utf-8") as stream:
        plan.write_json(stream)


#: `--decompose` values and the methods they stand for.
_DECOMPOSE = {"none": "whole", "prioritized": "prioritized"}


def _method(args: argparse.Namespace) -> str | None:
    """The method `--method` or `--decompose` asks for (None: the scenario's); ValueError
    naming the flag for a value the planner does not know or two that disagree."""
    from planner.model.scenario import METHODS

    if args.method is not None and args.method not in METHODS:
        raise ValueError(f"--method: must be one of {', '.join(METHODS)}, got {args.method!r}")
    if args.decompose is None:
        method: str | None = args.method
        return method
    if args.decompose not in _DECOMPOSE:
        raise ValueError(f"--decompose: must be one of {', '.join(_DECOMPOSE)}, "
                         f"got {args.decompose!r}")
    method = _DECOMPOSE[args.decompose]
    if args.method is not None and args.method != method:
        raise ValueError(f"--decompose {args.decompose} asks for method {method}, "
                         f"--method for {args.method}: give one of them")
    return method


def _options(args: argparse.Namespace, method: str) -> Any:
    """The planning options `--batch-size` asks for (None: the planner's defaults);
    ValueError naming the flag when the planner refuses them."""
    from planner.options import PlanningOptions

    if args.batch_size is None:
        return None
    if method == "whole":
        raise ValueError("--batch-size: applies with --method auto or prioritized")
    try:
        return PlanningOptions(batch_size=args.batch_size)
    except ValueError as exc:  # "batch_size: must be ..." -> "--batch-size: must be ..."
        field, _, reason = str(exc).partition(": ")
        raise ValueError(f"--{field.replace('_', '-')}: {reason}") from None


def _plan_on_cluster(address: str, scenario: dict[str, Any], solver: str | None,
                     progress: Any, working: Any, options: Any = None) -> Any:
    """Plan as one Dask task on the cluster at `address`, iterations printed as they come;
    returns the Plan. ValueError with a message for the user when it cannot."""
    import threading
    import uuid

    from distributed import Client, Event

    import planner
    from gcs.service import plan_worker

    try:
        client = Client(address, timeout=10)
    except (OSError, TimeoutError) as exc:
        raise ValueError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
    ended = threading.Event()
    topic = f"fleetplan-cli-{uuid.uuid4().hex[:12]}"

    def on_event(event: Any) -> None:
        message = event[1]
        if message["kind"] == "iteration":
            progress(planner.IterationRecord(**message["record"]))
        elif message["kind"] == "working":
            working(planner.IterationProgress(**message["record"]))
        elif message["kind"] == "started":
            print(f"planning on Dask worker {message['worker']}", flush=True)
        elif message["kind"] == "end":
            ended.set()

    with client:
        client.subscribe_topic(topic, on_event)
        future = client.submit(plan_worker.run_plan, topic, scenario, solver, topic=topic,
                               cancel_event=f"{topic}-cancel", options=options, pure=False)
        try:
            result = future.result()
        except KeyboardInterrupt:  # stop the task too (after its current SCP iteration)
            Event(f"{topic}-cancel", client=client).set()
            future.cancel()
            raise
        ended.wait(5.0)  # the last iterations travel apart from the result
    if result.error is not None:
        error = result.error
        where = f"{error['field']}: " if error.get("field") else ""
        raise ValueError(f"{where}{error['reason']}")
    if result.plan_json is None:
        raise ValueError("the planning task returned neither a plan nor an error")
    return planner.Plan.from_dict(json.loads(result.plan_json))


def _for_fleet(data: Any, fleet_path: Path) -> Any:
    """The scenario planned for a fleet's position error (ValueError for a bad fleet file or
    one that states no position_error)."""
    from gcs.errors import FleetFileError
    from gcs.fleet.fleetfile import load_fleet
    from gcs.flight.safety.margin import scenario_for_fleet

    try:
        fleet = load_fleet(fleet_path)
    except FleetFileError as exc:
        raise ValueError(f"--fleet: {exc.field}: {exc.reason}") from None
    if fleet.position_error is None:
        raise ValueError(f"--fleet: {fleet_path} states no position_error (m)")
    if not isinstance(data, dict) or not isinstance(data.get("min_separation"), int | float):
        return data  # the scenario's own validation names what is wrong
    planned = scenario_for_fleet(data, fleet.position_error)
    print(f"planning for the fleet: min_separation {data['min_separation']:g} m + 2 x "
          f"{fleet.position_error:g} m = {planned['min_separation']:g} m", flush=True)
    return planned


def _leg_mapper(address: str | None, legs: int) -> tuple[Any, Any]:
    """(mapper for `plan_sequence`, closer): Dask tasks on the cluster at `address`, else a
    local process pool (legs are independent problems; a pool of one is just `map`)."""
    if address:
        from distributed import Client

        try:
            client = Client(address, timeout=10)
        except (OSError, TimeoutError) as exc:
            raise ValueError(f"cannot reach the Dask scheduler at {address}: {exc}") from None

        def on_cluster(fn: Any, *iterables: Any) -> Any:
            return client.gather(client.map(fn, *iterables, pure=False))

        return on_cluster, client.close
    workers = min(legs, os.cpu_count() or 1)
    if workers <= 1:
        return map, lambda: None
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(max_workers=workers)
    return pool.map, pool.shutdown


def _write_csvs(show: Any, directory: Path, rate: float | None) -> None:
    from planner.methods.sequence import trajectory_csv

    files = trajectory_csv(show.positions, show.velocities, show.accelerations,
                           show.sequence.dt, show.sequence.ids, rate_hz=rate)
    directory.mkdir(parents=True, exist_ok=True)
    for vid, text in files.items():
        (directory / f"{vid}.csv").write_text(text)


def _takeoff_from_fleet(args: argparse.Namespace, data: dict[str, Any]) -> dict[str, Any]:
    """The sequence taking off from a fleet file's homes (`gcs.fleet.takeoff`): the one named
    by --takeoff-fleet, else by the sequence's `takeoff.fleet` (relative to the sequence
    file); the sequence as it is without either. ValueError naming the field otherwise."""
    from gcs.errors import FleetFileError
    from gcs.fleet.fleetfile import load_fleet
    from gcs.fleet.takeoff import with_fleet_homes

    takeoff = data.get("takeoff")
    named = takeoff.get("fleet") if isinstance(takeoff, dict) else None
    if getattr(args, "takeoff_fleet", None) is not None:
        path, where = Path(args.takeoff_fleet), "--takeoff-fleet"
    elif named is not None:
        if not isinstance(named, str) or not named:
            raise ValueError("takeoff.fleet: must be the path of a fleet file (JSON)")
        path, where = args.scenario.parent / named, "takeoff.fleet"
    else:
        return data
    try:
        return with_fleet_homes(data, load_fleet(path), where)
    except FleetFileError as exc:
        if exc.field == where:
            raise
        raise ValueError(f"{where}: {path}: {exc.field}: {exc.reason}") from None


def _run_sequence(args: argparse.Namespace, data: Any) -> int:
    """Plan a formation sequence: legs in parallel, the stitched plan and the CSVs written."""
    from planner.errors import FieldError, SolverError
    from planner.methods.sequence import parse_sequence, plan_sequence

    rate = args.csv_rate
    if rate is not None and not (math.isfinite(rate) and 0 < rate <= 1000):
        return _fail("--csv-rate: must be in (0, 1000] Hz")
    try:
        sequence = parse_sequence(data)
    except FieldError as exc:
        return _fail(str(exc))
    if args.csv_dir is not None:
        unsafe = [vid for vid in sequence.ids if not _SAFE_NAME.fullmatch(vid)]
        if unsafe:
            return _fail(f"vehicles: id {unsafe[0]!r} cannot name a CSV file "
                         f"(letters, digits, '.', '_', '-' only)")
    if not args.quiet:
        where = f"Dask at {args.scheduler}" if args.scheduler else "local processes"
        print(f"planning {len(sequence.jobs)} legs of {len(sequence.ids)} vehicles "
              f"on {where}", flush=True)
    try:
        mapper, close = _leg_mapper(args.scheduler, len(sequence.jobs))
        try:
            show = plan_sequence(sequence, solver=args.solver, mapper=mapper)
        finally:
            close()
        plan = show.to_plan()
    except (SolverError, ValueError) as exc:
        return _fail(str(exc))
    if not args.quiet and plan.sequence is not None:
        for leg in plan.sequence["legs"]:
            chosen = " (chosen)" if "horizon" in leg else ""
            print(f"leg {leg['name']}: {leg['status']}, {leg['steps']} steps{chosen}, "
                  f"{leg['iterations']} SCP iterations, {leg['seconds']:.2f} s", flush=True)
    output = args.output or Path(f"{sequence.name}.plan.json")
    try:
        _write_plan(plan, output)
        if args.csv_dir is not None:
            _write_csvs(show, args.csv_dir, rate)
    except OSError as exc:
        return _fail(f"cannot write: {exc.strerror or exc}")
    _print_summary(plan)
    print(f"plan written to {output}")
    if args.csv_dir is not None:
        print(f"{len(sequence.ids)} CSV files written to {args.csv_dir}")
    return _verdict(plan)


def run(args: argparse.Namespace) -> int:
    import planner
    from gcs.cli.scenario_check import MAX_LISTED, check_scenario, problem_line
    from planner.errors import FieldError, SolverError

    try:
        data = load_json(args.scenario)
        if isinstance(data, dict) and "formations" in data:
            if (args.method, args.decompose, args.batch_size) != (None, None, None):
                return _fail("--method, --decompose, --batch-size: apply to a scenario; a "
                             "formation sequence's legs choose their own")
            if getattr(args, "fleet", None) is not None:
                return _fail("--fleet: a fleet's margin is not applied to formation sequences "
                             "yet; add it to the sequence's min_separation")
            return _run_sequence(args, _takeoff_from_fleet(args, data))
        if getattr(args, "takeoff_fleet", None) is not None:
            return _fail("--takeoff-fleet: applies to a formation sequence (a document with "
                         "formations); a scenario's starts are its own")
        if getattr(args, "fleet", None) is not None:
            data = _for_fleet(data, args.fleet)
        check_scenario(data, args.scenario)
        try:
            scenario = planner.Scenario.from_dict(data)
        except FieldError as exc:
            return _fail("\n".join(problem_line(e.field, e.reason, data)
                                   for e in getattr(exc, "errors", [exc])[:MAX_LISTED]))
        method = _method(args)
        if method is not None:
            scenario = dataclasses.replace(scenario, method=method)
        options = _options(args, scenario.method)
    except ValueError as exc:
        return _fail(str(exc))
    except FieldError as exc:  # pragma: no cover - FieldError is a ValueError
        return _fail(str(exc))

    def progress(record: planner.IterationRecord) -> None:
        if args.quiet:
            return
        change = "" if record.cost_change is None else (
            f"  change {_number(record.cost_change, '{:.4g}')}")
        print(
            f"iteration {record.iteration:>2}: cost {_number(record.cost, '{:.4f}')}{change}  "
            f"rows {record.separation_rows}  groups {record.groups}  "
            f"QPs {record.qp_solves}  {record.seconds:.3f} s"
            + _label(record),
            flush=True,
        )

    def working(step: planner.IterationProgress) -> None:
        if not args.quiet:
            print(f"  ... iteration {step.iteration:>2}: round {step.round}, "
                  f"{step.groups_done}/{step.groups} groups solved (largest "
                  f"{step.largest_group} vehicles, rows {step.separation_rows}), QPs "
                  f"{step.qp_solves}, {step.seconds:.1f} s" + _label(step), flush=True)

    try:
        if args.scheduler:
            plan = _plan_on_cluster(args.scheduler, scenario.to_dict(), args.solver, progress,
                                    working, options)
        else:
            plan = planner.plan(scenario, solver=args.solver, progress=progress,
                                options=options, within_iterations=working)
    except (SolverError, ValueError) as exc:
        return _fail(str(exc))
    output = args.output or Path(f"{scenario.name}.plan.json")
    try:
        _write_plan(plan, output)
    except OSError as exc:
        return _fail(f"cannot write {output}: {exc.strerror or exc}")
    _print_summary(plan)
    print(f"plan written to {output}")
    return _verdict(plan)
