"""Helpers for the browser tests: type a scenario as an operator would, plan it, read ids."""

from __future__ import annotations

import json
import re
import threading
from collections.abc import Sequence
from typing import Any

import httpx
from playwright.sync_api import Page, Request, Route, expect

from tests.api.support import QUICK_CROSSING, ServiceProcess

__all__ = ["CROSSING", "CROSSING_HORIZON_S", "CROSSING_STEPS", "HEALTH", "ORIGIN", "PAD",
           "SCALE", "SPAN", "VEHICLES", "VIEW", "ServiceStarting", "assert_fits", "client_point",
           "fill_scenario", "plan", "planned_api", "shown_mission_id"]

# A 4-vehicle swap entered by hand: two pairs crossing near the centre of a 6 m square.
VEHICLES = [
    ("a", (1.0, 2.8, 1.2), (5.0, 3.4, 1.4)),
    ("b", (5.0, 3.0, 1.6), (1.0, 3.2, 1.5)),
    ("c", (2.9, 1.0, 1.3), (3.2, 5.0, 1.7)),
    ("d", (3.1, 5.0, 1.8), (2.8, 1.0, 1.2)),
]


def fill_scenario(
    page: Page, name: str = "browser-swap", steps: int = 100,
    vehicles: Sequence[tuple[str, tuple[float, ...], tuple[float, ...]]] = VEHICLES,
) -> None:
    """Type a whole scenario into the form, as an operator would."""
    page.fill("#f-name", name)
    page.fill("#f-dt", "0.2")
    page.fill("#f-steps", str(steps))
    page.fill("#f-min_separation", "1.0")
    limits = {"position_min": (0, 0, 0), "position_max": (6, 6, 3), "velocity_max": (2, 2, 2),
              "acceleration_max": (3, 3, 3), "jerk_max": (5, 5, 5)}
    for key, values in limits.items():
        for axis, value in enumerate(values):
            page.fill(f'input[data-field="limits.{key}[{axis}]"]', str(value))
    # Start from an empty table: remove every row, then add ours.
    while page.locator("#vehicle-table tr.vehicle").count():
        page.locator("#vehicle-table tr.vehicle .remove-vehicle").first.click()
    for index, (vid, start, goal) in enumerate(vehicles):
        page.click("#add-vehicle")
        page.fill(f'input[data-field="vehicles[{index}].id"]', vid)
        for axis in range(3):
            page.fill(f'input[data-field="vehicles[{index}].start[{axis}]"]', str(start[axis]))
            page.fill(f'input[data-field="vehicles[{index}].goal[{axis}]"]', str(goal[axis]))


#: QUICK_CROSSING's vehicles as form rows: with CROSSING_STEPS steps (fill_scenario's dt is
#: QUICK_CROSSING's), a flight of CROSSING_HORIZON_S for the mock fleet.
CROSSING = [(v["id"], tuple(v["start"]), tuple(v["goal"])) for v in QUICK_CROSSING["vehicles"]]
CROSSING_STEPS: int = QUICK_CROSSING["steps"]
#: The crossing's horizon (s), steps x dt, as the page's clock shows it (one decimal).
CROSSING_HORIZON_S: float = round(CROSSING_STEPS * QUICK_CROSSING["dt"], 1)


def plan(page: Page, expect_text: str = "converged") -> str:
    """Press Plan, wait for the plan to be shown; the id of the mission shown."""
    page.click("#plan-button")
    expect(page.locator("#plan-state")).to_contain_text(expect_text, timeout=60_000)
    expect(page.locator("#min-separation-value")).to_be_visible(timeout=30_000)
    expect(page.locator("#fly-view polyline.planned-path").first).to_be_attached()
    expect(page.locator("#stale-banner")).to_be_hidden()
    return shown_mission_id(page)


def shown_mission_id(page: Page) -> str:
    return page.locator("#mission-title").inner_text().split("·")[1].strip()


ORIGIN = {"lat": 47.397742, "lon": 8.545594, "alt": 488.0}
# per vehicle: battery, gps, health in GET /api/vehicles' shapes (gcs.flight.safety.health)
HEALTH = {
    0: ({"remaining_pct": 82, "voltage": 16.1},
        {"fix_type": 3, "satellites": 14, "h_acc": 0.4, "v_acc": 0.6},
        {"unhealthy": [], "prearm_ok": True, "warnings": []}),
    1: ({"remaining_pct": 15, "voltage": 14.2},
        {"fix_type": 1, "satellites": 3, "h_acc": None, "v_acc": None},
        {"unhealthy": ["3D gyro"], "prearm_ok": False, "warnings": []}),
}
#: Link quality the planned endpoint reports (`gcs.flight.link.quality`): a good link, and one
#: losing 12 % of its messages over the last seconds.
LINKS = {
    0: {"received": 900, "lost": 2, "reordered": 0, "duplicates": 0, "restarts": 0,
        "loss_pct": 0.22, "recent_loss_pct": 0.0, "latency_ms": 3.4, "jitter_ms": 0.8},
    1: {"received": 800, "lost": 110, "reordered": 4, "duplicates": 1, "restarts": 0,
        "loss_pct": 12.09, "recent_loss_pct": 12.4, "latency_ms": 35.0, "jitter_ms": 6.2},
}


FLIGHT_CONTROL = re.compile(r".*/api/flights/[^/]+/(pause|resume)$")


def planned_api(page: Page, service: ServiceProcess, sent: list[tuple[str, Any]]) -> None:
    """Routes giving the page the planned fleet endpoints (battery, GPS, health, a geodetic
    origin; fleet and vehicle commands answered here); requests to them land in `sent`, and
    so do pause and resume, which go to the service and really pause the flight."""
    spec = httpx.get(f"{service.base_url}/openapi.json").json()
    for path in ("/api/flights/{flight_id}/pause", "/api/flights/{flight_id}/resume",
                 "/api/fleet/commands", "/api/vehicles/{vehicle_id}/commands"):
        spec["paths"][path] = {"post": {"responses": {"202": {"description": "accepted"}}}}

    def vehicles(route: Route) -> None:
        answer = httpx.get(route.request.url).json()
        answer["fleet"]["world_origin"] = ORIGIN
        for i, v in enumerate(answer["vehicles"]):
            if i in HEALTH:
                v["battery"], v["gps"], v["health"] = HEALTH[i]
                v["link_quality"] = LINKS[i]
        route.fulfill(status=200, content_type="application/json", body=json.dumps(answer))

    def command(route: Route) -> None:
        path = route.request.url.removeprefix(service.base_url)
        sent.append((path, route.request.post_data_json))
        route.fulfill(status=202, content_type="application/json", body='{"accepted": true}')

    page.route("**/openapi.json", lambda route: route.fulfill(
        status=200, content_type="application/json", body=json.dumps(spec)))
    page.route(re.compile(r".*/api/vehicles$"), vehicles)
    page.route(re.compile(r".*/api/(fleet|vehicles/[^/]+)/commands$"), command)

    def flight_control(request: Request) -> None:
        if request.method == "POST" and FLIGHT_CONTROL.match(request.url):
            sent.append((request.url.removeprefix(service.base_url), request.post_data_json))

    page.on("request", flight_control)


NO_SIDEWAYS_SCROLL = ("() => ({doc: document.documentElement.scrollWidth, "
                      "body: document.body.scrollWidth, view: window.innerWidth})")
#: Elements poking out of the viewport, except inside a horizontally scrolling area (the
#: fleet table's wrapper) that itself fits.
WIDER_THAN_VIEW = ("() => Array.from(document.querySelectorAll('body *'))"
                   ".filter(e => e.getBoundingClientRect().right > window.innerWidth + 0.5)"
                   ".filter(e => { for (let a = e.parentElement; a; a = a.parentElement) {"
                   " const o = getComputedStyle(a).overflowX;"
                   " if ((o === 'auto' || o === 'scroll') && a !== document.documentElement"
                   " && a.getBoundingClientRect().right <= window.innerWidth + 0.5)"
                   " return false; } return true; })"
                   ".map(e => e.tagName + '#' + e.id + '.' + e.className)")


def assert_fits(page: Page) -> None:
    widths = page.evaluate(NO_SIDEWAYS_SCROLL)
    assert widths["doc"] <= widths["view"] and widths["body"] <= widths["view"], widths
    # Inner scroll areas (the fleet table's wrapper) may scroll; nothing pokes out of the page.
    wider = page.evaluate(WIDER_THAN_VIEW)
    assert wider == [], wider


#: How long a service may take to answer (a loose bound: a machine this test suite shares
#: with others can take over a minute to boot it while Chromium and another service boot).
START_TIMEOUT_S = 240.0


class ServiceStarting:
    """A `ServiceProcess` starting in a background thread: other tests run while it boots."""

    def __init__(self, service: ServiceProcess) -> None:
        self.service = service
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._start, name="service-start", daemon=True)
        self._thread.start()

    def _start(self) -> None:
        try:
            self.service.start(timeout=START_TIMEOUT_S)
        except BaseException as exc:  # handed to the test that waits for it
            self._error = exc

    def ready(self) -> ServiceProcess:
        """The service once it answers (ServiceProcess.start's own deadline applies)."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self.service

    def stop(self) -> None:
        self._thread.join()
        self.service.stop()


#: The fly view's viewBox side and padding (web/flyview.js VIEW, viewTransform's pad).
VIEW, PAD = 400, 28
#: fill_scenario's workspace: x and y from 0 to 6 m.
SPAN = 6.0
SCALE = (VIEW - 2 * PAD) / SPAN


def client_point(page: Page, x: float, y: float) -> tuple[float, float]:
    """Where world point (x, y) is on the screen, in the fly view."""
    box = page.locator("#fly-view").bounding_box()
    assert box is not None
    sx, sy = PAD + x * SCALE, VIEW - PAD - y * SCALE
    return box["x"] + sx / VIEW * box["width"], box["y"] + sy / VIEW * box["height"]
