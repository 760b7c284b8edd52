"""Page playback benchmark: a lit show of --vehicles drones played on the page, frame by frame.

Starts `fleetplan serve` (no mock vehicles), posts `bench/show.py`'s show (--vehicles drones
taking off from a 2 m ground grid, five formations with colours, landing) for the service to
plan, opens the page in headless Chromium (Playwright, Debian's /usr/bin/chromium or
FLEETPLAN_CHROMIUM) and shows the mission. Then, for --seconds each, records every gap
between two animation frames (requestAnimationFrame) and the browser's long tasks (over
50 ms): with the page idle (the control: what the busy machine alone costs a frame), playing
from a third into the show (its formations with a colour per drone, and fades) with the fly
view on screen, and again with the 3-D view scrolled into view (it redraws its markers only
when on screen). Prints one JSON document: per run the longest, median and 99th-percentile
frame (ms), the frames over 200 ms, the frames that drew a new sample, the longest frame
after playing stops (the views drawn at the slider's time), the samples played
against the plan's rate, the distinct colours the drones showed in the fly view, and the
load average before and after (the machine is shared).

    python bench/playback.py
    python bench/playback.py --vehicles 1000 --seconds 20
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

# Run as `python bench/playback.py`, this folder comes first on sys.path: the repository's
# root goes before it.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.api.support import ServiceProcess

#: Every gap between two animation frames and every long task, from the page's first script.
WATCH = """
window.__frames = []; window.__steps = []; window.__longTasks = [];
new PerformanceObserver((list) => {
  for (const e of list.getEntries()) window.__longTasks.push(e.duration);
}).observe({ type: "longtask", buffered: true });
let last = performance.now();
const tick = (now) => {
  const slider = document.querySelector('#time-slider');
  window.__frames.push(now - last); window.__steps.push(slider ? Number(slider.value) : -1);
  last = now; requestAnimationFrame(tick);
};
requestAnimationFrame(tick);
"""

SHOW = "(id) => import('/planning.js').then((m) => m.showMission(id, null))"
#: Put the slider at a third of the show; the sample it is at.
START = """() => import('/flyscreen.js').then((m) => {
    const slider = document.querySelector('#time-slider');
    m.moveSlider(Math.floor(Number(slider.max) / 3));
    return Number(slider.value); })"""
#: The distinct fills of the fly view's drones (the plan's "now" markers) at this instant.
COLOURS = """() => new Set([...document.querySelectorAll(
    '#fly-view path.planned-icons, #fly-view circle.planned-icon')]
    .map((e) => e.getAttribute('stroke'))).size"""


def lit_show(vehicles: int) -> dict[str, Any]:
    """`bench/show.py`'s show: a 2 m ground grid, five formations with colours, landing."""
    spec = importlib.util.spec_from_file_location("bench_show", Path(__file__).with_name("show.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    data: dict[str, Any] = module.lit_show(vehicles, (2.0, 2.0))
    return data


def _chromium() -> str:
    path = os.environ.get("FLEETPLAN_CHROMIUM", "/usr/bin/chromium")
    if not Path(path).exists():
        raise SystemExit(f"Chromium not found at {path}: apt-get install chromium, or set "
                         f"FLEETPLAN_CHROMIUM")
    return path


def plan_on_service(service: ServiceProcess, data: dict[str, Any], timeout: float) -> str:
    """POST the show and wait until the service has planned it; its mission id."""
    answer = httpx.post(f"{service.base_url}/api/missions?wait=0", json=data, timeout=120)
    if answer.status_code not in (201, 202):
        raise SystemExit(f"the service refused the show: {answer.status_code} "
                         f"{answer.text[:500]}")
    mission_id: str = answer.json()["id"]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        listed = httpx.get(f"{service.base_url}/api/missions?limit=10", timeout=60).json()
        row = next(m for m in listed["missions"] if m["id"] == mission_id)
        if row["status"] != "planning":
            if not row.get("plan_ok"):
                raise SystemExit(f"the show was not planned: {row}")
            return mission_id
        time.sleep(2.0)
    raise SystemExit(f"the show was not planned within {timeout:g} s")


RESET = "() => { window.__frames = []; window.__steps = []; window.__longTasks = []; }"
#: Press play (or stop) without scrolling the page to the button, as a click would.
PLAY = "() => document.querySelector('#play').click()"
#: Whether the 3-D view is on screen (it redraws its markers only then).
ON_SCREEN = """() => { const r = document.getElementById('plot3d').getBoundingClientRect();
    return r.bottom > 0 && r.top < innerHeight; }"""


def _frames(frames: list[float], steps: list[int] | None = None) -> dict[str, Any]:
    """The figures of one run of frame gaps (ms); with the slider's sample at each frame,
    the frames that drew a new sample and the one after each (it carries their paint)."""
    frames = frames[1:]  # the first gap spans the reset
    ordered = sorted(frames)
    out: dict[str, Any] = {
        "frames": len(frames), "frame_max_ms": round(max(frames), 1),
        "frame_median_ms": round(statistics.median(frames), 1),
        "frame_p99_ms": round(ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))], 1),
        "frames_over_200_ms": sum(f > 200 for f in frames)}
    if steps is not None:
        steps = steps[1:]
        moved = [i + 1 for i in range(len(steps) - 1) if steps[i + 1] != steps[i]]
        out["step_frames_ms"] = [round(max(frames[i:i + 2]), 1) for i in moved]
    return out


def _played(page: Any, seconds: float, rate: float) -> dict[str, Any]:
    """Play from a third into the show (its formations with a colour per drone, and fades)
    for `seconds`; the frames, the long tasks, the samples played, the colours shown."""
    first = int(page.evaluate(START))
    page.wait_for_timeout(2000)  # the move's own drawing is not playing
    page.evaluate(RESET)
    page.evaluate(PLAY)
    colours = []
    for _ in range(4):
        page.wait_for_timeout(seconds * 250)
        colours.append(page.evaluate(COLOURS))
    last = int(page.eval_on_selector("#time-slider", "(e) => Number(e.value)"))
    tasks = page.evaluate("window.__longTasks")
    played = _frames(page.evaluate("window.__frames"), page.evaluate("window.__steps"))
    on_screen = page.evaluate(ON_SCREEN)
    page.evaluate(RESET)
    page.evaluate(PLAY)  # stop: every view drawn at the slider's time
    page.wait_for_timeout(2000)
    stopped = _frames(page.evaluate("window.__frames"))
    return {**played, "view_3d_on_screen": on_screen,
            "long_tasks": len(tasks), "long_task_max_ms": round(max(tasks, default=0.0), 1),
            "steps_played": last - first, "steps_expected": round(seconds * rate),
            "colours_shown": colours, "stop_frame_max_ms": stopped["frame_max_ms"]}


def play(base_url: str, mission_id: str, seconds: float) -> dict[str, Any]:
    """Show the mission on the page; measure the frames idle (the control), playing with
    the fly view on screen, and playing with the 3-D view scrolled into view."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=_chromium(), headless=True)
        try:
            page = browser.new_page(viewport={"width": 1440, "height": 900})
            page.add_init_script(WATCH)
            page.goto(base_url + "/")
            page.wait_for_selector("#plan-button:enabled", timeout=120_000)
            page.evaluate("() => import('/planview.js').then((m) => m.loadPlotly())")
            started = time.monotonic()
            page.evaluate(SHOW, mission_id)
            page.wait_for_function(
                "() => document.querySelector('#plan-state').textContent.includes('converged')",
                timeout=600_000)
            shown_s = time.monotonic() - started
            page.wait_for_timeout(1000)  # the drawing's last frames
            rate = page.evaluate("() => import('/state.js').then((m) => m.views.traj.rate)")
            page.evaluate(RESET)
            page.wait_for_timeout(seconds * 1000)
            idle = _frames(page.evaluate("window.__frames"))
            fly = _played(page, seconds, rate)
            page.locator("#plot3d").scroll_into_view_if_needed()
            page.wait_for_timeout(2000)  # the markers catch up with the slider
            view_3d = _played(page, seconds, rate)
        finally:
            browser.close()
    return {"shown_s": round(shown_s, 2), "trajectory_rate_hz": rate, "idle": idle,
            "playing": fly, "playing_3d_view": view_3d}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, default=1000)
    parser.add_argument("--seconds", type=float, default=20.0, help="playback measured (s)")
    parser.add_argument("--plan-timeout", type=float, default=900.0)
    args = parser.parse_args()
    before = list(os.getloadavg())
    data = lit_show(args.vehicles)
    with tempfile.TemporaryDirectory() as folder, \
            ServiceProcess(Path(folder), "--mock", "0",
                           env={"FLEETPLAN_MAX_TRAJECTORY_SAMPLES": str(10**9),
                                "FLEETPLAN_MAX_VEHICLES": str(max(128, args.vehicles))},
                           start_timeout=300.0) as service:
        planned = time.monotonic()
        mission_id = plan_on_service(service, data, args.plan_timeout)
        plan_s = time.monotonic() - planned
        result = play(service.base_url, mission_id, args.seconds)
    print(json.dumps({"benchmark": "playback", "vehicles": args.vehicles,
                      "service_plan_s": round(plan_s, 1), **result,
                      "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                                  "load_average_before": before,
                                  "load_average_after": list(os.getloadavg())}}, indent=2))


if __name__ == "__main__":
    main()
