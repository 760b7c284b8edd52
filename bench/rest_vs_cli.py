"""The same crowd planned by `fleetplan plan` and through the REST API (JSON on stdout).

Plans the sideways crowd (default 256 vehicles) with the CLI, then starts `fleetplan serve`
(no mock vehicles, `max_vehicles` raised to fit) on a free port and posts the same scenario
to `POST /api/missions?wait=...`, each --repeats times; prints the wall times, the method
that planned and the ratio of the best REST time to the best CLI time.

    python bench/rest_vs_cli.py --vehicles 256 --repeats 2
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from planner.families.generators import sideways  # noqa: E402


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--vehicles", type=int, default=256)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp())
    scenario = tmp / "scenario.json"
    scenario.write_text(json.dumps(sideways(args.vehicles)))
    cli = []
    for _ in range(args.repeats):
        began = time.perf_counter()
        subprocess.run([sys.executable, "-m", "gcs.cli.main", "plan", str(scenario), "-o",
                        str(tmp / "plan.json")], cwd=ROOT, capture_output=True, check=True)
        cli.append(time.perf_counter() - began)
    plan = json.loads((tmp / "plan.json").read_text())
    port = _free_port()
    env = {**os.environ, "FLEETPLAN_MAX_VEHICLES": str(max(args.vehicles, 128))}
    server = subprocess.Popen([sys.executable, "-m", "gcs.cli.main", "serve", "--port", str(port),
                               "--mock", "0", "--db", f"sqlite:///{tmp}/db.sqlite"], cwd=ROOT,
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rest, statuses = [], []
    try:
        for _ in range(240):
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/api/status", timeout=1)
                break
            except OSError:
                time.sleep(0.5)
        body = scenario.read_bytes()
        for _ in range(args.repeats):
            request = urllib.request.Request(
                f"http://127.0.0.1:{port}/api/missions?wait=600", data=body, method="POST",
                headers={"Content-Type": "application/json"})
            began = time.perf_counter()
            with urllib.request.urlopen(request, timeout=900) as response:
                statuses.append(json.load(response)["status"])
            rest.append(time.perf_counter() - began)
    finally:
        server.terminate()
        server.wait(30)
    print(json.dumps({
        "vehicles": args.vehicles, "cli_s": [round(t, 3) for t in cli],
        "cli_planner_s": round(plan["timing"]["total_s"], 3), "cli_method": plan["method"],
        "rest_s": [round(t, 3) for t in rest], "rest_status": statuses,
        "ratio_rest_over_cli": round(min(rest) / min(cli), 3),
        "load_average": os.getloadavg(),
    }, indent=2))


if __name__ == "__main__":
    main()
