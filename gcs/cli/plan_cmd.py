"""`fleetplan plan SCENARIO.json -o PLAN.json`: plan, print progress and a summary, save.

Exit status: 0 for a converged, verified plan; 1 when the plan was computed but did not
converge or failed verification (the plan is still written, for inspection); 2 for bad
input (unreadable file, invalid JSON, an invalid scenario: the message names the field).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path
from typing import Any

__all__ = ["configure", "run"]

EXIT_OK, EXIT_NOT_VERIFIED, EXIT_BAD_INPUT = 0, 1, 2
#: Environment variable naming the Dask scheduler (the service's `scheduler` setting).
SCHEDULER_ENV = "FLEETPLAN_SCHEDULER"


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
    parser.add_argument("-q", "--quiet", action="store_true", help="no per-iteration lines")
    parser.add_argument(
        "--scheduler", metavar="tcp://HOST:8786", default=os.environ.get(SCHEDULER_ENV) or None,
        help=f"plan as a task on this Dask cluster (default ${SCHEDULER_ENV}; unset: here)",
    )
    parser.add_argument(
        "--fleet", type=Path, default=None,
        help="plan for this fleet: min_separation R + 2 x its position_error, stated in the "
             "plan as separation_margin (gcs.flight.margin)",
    )


def _fail(message: str) -> int:
    print(f"error: {message}", file=sys.stderr)
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
        ("SCP iterations", str(max(len(plan.iterations) - 1, 0))),
        ("cost (sum ||a+g||^2)", _number(plan.cost, "{:.4f}")),
        ("time total / first QP", f"{plan.timing['total_s']:.3f} s / "
                                  f"{plan.timing['first_qp_s']:.3f} s"),
        ("solver", plan.solver),
    ]
    if v is not None:
        sep = plan.scenario.min_separation
        if v.min_separation is not None:
            rows += [
                ("min separation (steps)", f"{v.min_separation:.4f} m (R = {sep:g} m)"),
                ("min separation (continuous)",
                 f"{v.min_separation_continuous:.4f} m, {' & '.join(v.closest_pair)} "
                 f"at t = {v.closest_time:.2f} s"),
            ]
        worst = max(v.max_violation.items(), key=lambda kv: kv[1])
        rows += [
            ("max box violation", f"{worst[1]:.2e} ({worst[0]})"),
            ("max boundary error", f"{max(v.boundary_error.values()):.2e} m"),
            ("thrust range", f"{v.thrust_range[0]:.2f} .. {v.thrust_range[1]:.2f} m/s^2"),
            ("peak body rate", f"{v.body_rate_peak:.3f} rad/s"),
            ("flyable", "yes" if v.flyable else "no"),
            ("verified", "yes" if v.verified else "NO"),
        ]
    return rows


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


def _plan_on_cluster(address: str, scenario: dict[str, Any], solver: str | None,
                     progress: Any) -> Any:
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
        elif message["kind"] == "started":
            print(f"planning on Dask worker {message['worker']}", flush=True)
        elif message["kind"] == "end":
            ended.set()

    with client:
        client.subscribe_topic(topic, on_event)
        future = client.submit(plan_worker.run_plan, topic, scenario, solver, topic=topic,
                               cancel_event=f"{topic}-cancel", pure=False)
        try:
            result = future.result()
        except KeyboardInterrupt:  # stop the task too (after its current SCP iteration)
            Event(f"{topic}-cancel", client=client).set()
            future.cancel()
            raise
        ended.wait(5.0)  # the last iterations travel apart from the result
    if "error" in result:
        error = result["error"]
        where = f"{error['field']}: " if error.get("field") else ""
        raise ValueError(f"{where}{error['reason']}")
    return planner.Plan.from_dict(json.loads(result["plan_json"]))


def _for_fleet(data: Any, fleet_path: Path) -> Any:
    """The scenario planned for a fleet's position error (ValueError for a bad fleet file or
    one that states no position_error)."""
    from gcs.errors import FleetFileError
    from gcs.flight.fleetfile import load_fleet
    from gcs.flight.margin import scenario_for_fleet

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


def run(args: argparse.Namespace) -> int:
    import planner
    from planner.errors import FieldError, SolverError

    try:
        data = load_json(args.scenario)
        if getattr(args, "fleet", None) is not None:
            data = _for_fleet(data, args.fleet)
        scenario = planner.Scenario.from_dict(data)
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
            f"QPs {record.qp_solves}  {record.seconds:.3f} s",
            flush=True,
        )

    try:
        if args.scheduler:
            plan = _plan_on_cluster(args.scheduler, scenario.to_dict(), args.solver, progress)
        else:
            plan = planner.plan(scenario, solver=args.solver, progress=progress)
    except (SolverError, ValueError) as exc:
        return _fail(str(exc))
    output = args.output or Path(f"{scenario.name}.plan.json")
    try:
        output.write_text(json.dumps(plan.to_dict()))
    except OSError as exc:
        return _fail(f"cannot write {output}: {exc.strerror or exc}")
    _print_summary(plan)
    print(f"plan written to {output}")
    if plan.ok:
        return EXIT_OK
    print(f"error: plan not verified: {plan.status}: {plan.message}", file=sys.stderr)
    return EXIT_NOT_VERIFIED
