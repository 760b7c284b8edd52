"""Every scenario family × sizes × seeds × methods, each plan in a child process of its own
with a time limit (JSON on stdout: wall and CPU time, status, verification, cost, SCP
iterations, method, load average per run, and the medians per family, size and method).

    nice -n 10 python bench/families.py                     # the default matrix
    nice -n 10 python bench/families.py --cases antipodal-sphere:100 window-rooms:50 \
        --seeds 0 1 2 --methods whole prioritized --timeout 120
    python bench/families.py --cases facing-grids:100:spacing=2.5:pairing=across
    python bench/families.py --quick                         # a tiny matrix (the test's)

A case is FAMILY:SIZE[:KEY=VALUE...]; the keys are the generator's keyword arguments
(numbers or words). --markdown prints the medians as a table instead of the JSON.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import resource
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from planner import plan  # noqa: E402
from planner.families.generators import (  # noqa: E402
    antipodal_circle,
    antipodal_sphere,
    facing_grids,
    grid_to_sphere,
    random_dense,
    sideways,
)
from planner.families.obstacle_generators import (  # noqa: E402
    forest,
    pillar_circle,
    shelving,
    window_rooms,
    window_wall,
)
from planner.result import Plan  # noqa: E402
from planner.scp.loop import thrust_cost  # noqa: E402

EXAMPLES = ROOT / "planner" / "examples"
#: The methods compared; `run_method` maps each name to one planner call.
METHODS = ("auto", "whole", "prioritized")


def run_method(scenario: dict[str, Any], method: str) -> Plan:
    """Plan `scenario` by the method named: the one place a method name meets the planner."""
    return plan(scenario, method=method)


def _paper(kind: str) -> Callable[..., dict[str, Any]]:
    def build(size: int, seed: int) -> dict[str, Any]:
        data: dict[str, Any] = json.loads((EXAMPLES / f"paper-{kind}{size}.json").read_text())
        return data
    return build


def _forest(size: int, seed: int, **extra: Any) -> dict[str, Any]:
    """forest50 (40 trees, 30 m) and forest200 (150 trees, 60 m) as in bench/planner.py;
    other sizes at forest200's density. Keywords `pillars` and `side` (m) override them."""
    trees, side = {50: (40, 30.0), 200: (150, 60.0)}.get(
        size, (max(4, round(150 * size / 200)), 60.0 * (max(size, 20) / 200) ** 0.5))
    return forest(size, extra.pop("pillars", trees), size=extra.pop("side", side), seed=seed,
                  **extra)


def _forest_hold(size: int, seed: int, **extra: Any) -> dict[str, Any]:
    """A forest crossing in which the first vehicle holds in place (its goal is its start)."""
    data = _forest(size, seed, **extra)
    data["vehicles"][0]["goal"] = list(data["vehicles"][0]["start"])
    data["name"] += "-hold"
    return data


#: Family name -> (generator of (size, seed, **keywords), default sizes).
FAMILIES: dict[str, tuple[Callable[..., dict[str, Any]], tuple[int, ...]]] = {
    "paper-circle": (_paper("circle"), (2, 4, 6, 8)),
    "paper-random": (_paper("random"), (2, 4, 6, 8)),
    # seed 0: the shell's lattice as built (the bench/planner.py case), else a rotation
    "sideways": (lambda n, seed, **kw: sideways(n, seed=seed or None, **kw), (100,)),
    "grid-sphere": (lambda n, seed, **kw: grid_to_sphere(n, seed=seed, **kw), (100, 256)),
    "random": (lambda n, seed, **kw: random_dense(n, seed=seed, **kw), (256, 1000)),
    "forest": (_forest, (50,)),
    "forest-hold": (_forest_hold, (50,)),
    "pillar-circle": (lambda n, seed, **kw: pillar_circle(n, seed=seed, **kw), (8,)),
    "window": (lambda n, seed, **kw: window_wall(n, seed=seed, **kw), (8,)),
    "shelving": (lambda n, seed, **kw: shelving(n, seed=seed, **kw), (16,)),
    "antipodal-sphere": (lambda n, seed, **kw: antipodal_sphere(n, seed=seed, **kw),
                         (32, 100)),
    "antipodal-circle": (lambda n, seed, **kw: antipodal_circle(n, seed=seed, **kw),
                         (24, 50)),
    "facing-grids": (lambda n, seed, **kw: facing_grids(n, seed=seed, **kw), (100,)),
    "window-rooms": (lambda n, seed, **kw: window_rooms(n, seed=seed, **kw), (36, 50)),
}
#: The --quick matrix: one small instance of each crowd family and of the bug's shape.
QUICK = ("paper-circle:4", "antipodal-sphere:8", "antipodal-circle:8", "facing-grids:8",
         "window-rooms:6", "forest-hold:6:pillars=4:side=12")


def _value(text: str) -> Any:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse_case(case: str) -> tuple[str, int, dict[str, Any]]:
    """FAMILY:SIZE[:KEY=VALUE...] -> (family, size, keywords); SystemExit naming the fault."""
    family, *rest = case.split(":")
    if family not in FAMILIES:
        raise SystemExit(f"error: unknown family {family!r} in case {case!r}: one of "
                         f"{', '.join(FAMILIES)}")
    if not rest or not rest[0].isdigit():
        raise SystemExit(f"error: case {case!r} needs a size: {family}:SIZE")
    extra = {}
    for item in rest[1:]:
        key, sep, value = item.partition("=")
        if not sep:
            raise SystemExit(f"error: {item!r} in case {case!r} is not KEY=VALUE")
        extra[key] = _value(value)
    return family, int(rest[0]), extra


def _cpu() -> float:
    """CPU seconds of this process and of its reaped children (auto's racing arms)."""
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + used.ru_utime + used.ru_stime


def _child(family: str, size: int, seed: int, extra: dict[str, Any], method: str,
           out: Any) -> None:
    """One plan, in a child process: its figures through the pipe `out`."""
    scenario = FAMILIES[family][0](size, seed, **extra)
    wall, cpu = time.perf_counter(), _cpu()
    result = run_method(scenario, method)
    wall, cpu = time.perf_counter() - wall, _cpu() - cpu
    v = result.verification
    accelerations = np.stack([x.acceleration for x in result.vehicles])
    out.send({
        "scenario": scenario["name"], "vehicles": len(scenario["vehicles"]),
        "steps": scenario["steps"], "status": result.status,
        "verified": bool(v is not None and v.verified),
        "wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
        "cost": round(thrust_cost(accelerations), 4), "iterations": len(result.iterations),
        "message": result.message[:300],
    })


def run(family: str, size: int, seed: int, extra: dict[str, Any], method: str,
        timeout: float) -> dict[str, Any]:
    """One cell of the matrix, planned in a forked child killed after `timeout` s."""
    row: dict[str, Any] = {"family": family, "size": size, "seed": seed, "params": extra,
                           "method": method, "load_before": round(os.getloadavg()[0], 2)}
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(family, size, seed, extra, method, send))
    began = time.perf_counter()
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    child.start()
    send.close()
    if receive.poll(timeout):
        try:
            row.update(receive.recv())
        except EOFError:
            row.update(status="crashed", verified=False)
    else:
        row.update(status="timeout", verified=False, wall_s=round(timeout, 3))
        child.kill()
    child.join()
    if "cpu_s" not in row:  # timed out or crashed: the CPU the child had used
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        row["cpu_s"] = round(after.ru_utime + after.ru_stime - used.ru_utime - used.ru_stime, 3)
    if "wall_s" not in row:
        row["wall_s"] = round(time.perf_counter() - began, 3)
    if row["status"] == "crashed":
        row["message"] = f"the planning process exited with code {child.exitcode}"
    row["load_after"] = round(os.getloadavg()[0], 2)
    return row


def medians(runs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per family, size, parameters and method: median wall and CPU time over the seeds
    that verified, and how many did."""
    cells: dict[str, list[dict[str, Any]]] = {}
    for row in runs:
        key = json.dumps([row["family"], row["size"], row["params"], row["method"]])
        cells.setdefault(key, []).append(row)
    out = []
    for key, rows in cells.items():
        family, size, params, method = json.loads(key)
        good = [r for r in rows if r["verified"]]
        out.append({
            "family": family, "size": size, "params": params, "method": method,
            "runs": len(rows), "verified": len(good),
            "wall_s_median": round(statistics.median(r["wall_s"] for r in good), 3)
            if good else None,
            "cpu_s_median": round(statistics.median(r["cpu_s"] for r in good), 3)
            if good else None,
        })
    return out


def markdown(summary: list[dict[str, Any]]) -> str:
    """The medians as a Markdown table, one row per family, size and method."""
    lines = ["| family | size | params | method | verified | wall (s) | CPU (s) |",
             "| --- | ---: | --- | --- | ---: | ---: | ---: |"]
    for s in summary:
        params = " ".join(f"{k}={v}" for k, v in s["params"].items()) or "-"
        lines.append(f"| {s['family']} | {s['size']} | {params} | {s['method']} | "
                     f"{s['verified']}/{s['runs']} | {s['wall_s_median'] or '-'} | "
                     f"{s['cpu_s_median'] or '-'} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=None,
                        help="FAMILY:SIZE[:KEY=VALUE...] (default: every family at its "
                             "default sizes)")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--methods", nargs="+", choices=METHODS, default=list(METHODS))
    parser.add_argument("--timeout", type=float, default=300.0,
                        help="seconds a plan may take before it counts as 'timeout'")
    parser.add_argument("--quick", action="store_true",
                        help="a tiny matrix of small instances (seconds in all)")
    parser.add_argument("--markdown", action="store_true",
                        help="print the medians as a Markdown table instead of the JSON")
    args = parser.parse_args()
    cases = (list(QUICK) if args.quick else args.cases
             or [f"{f}:{n}" for f, (_, sizes) in FAMILIES.items() for n in sizes])
    parsed = [parse_case(c) for c in cases]
    runs = []
    for family, size, extra in parsed:
        seeds = [0] if family.startswith("paper-") else args.seeds
        for seed in seeds:
            for method in args.methods:
                runs.append(run(family, size, seed, extra, method, args.timeout))
                print(json.dumps(runs[-1]), file=sys.stderr, flush=True)
    summary = medians(runs)
    if args.markdown:
        print(markdown(summary))
        return
    json.dump({"benchmark": "families x sizes x seeds x methods", "cpus": os.cpu_count(),
               "load_average_at_end": list(os.getloadavg()), "runs": runs,
               "medians": summary}, sys.stdout, indent=1)


if __name__ == "__main__":
    main()
