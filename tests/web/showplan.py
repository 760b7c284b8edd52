"""A show-sized plan for the page, built in a second: a vertical grid of N vehicles flying to
a sphere shell, each on a straight rest-to-rest move (constant acceleration, then the same
deceleration), served to the page through Playwright routes in the service's own formats
(the mission document and GET /trajectory's JSON, written by `gcs.service.plans`).

The planner is not run: the page's cost at show scale is drawing, not planning, and a real
2,000-vehicle plan takes longer than the browser test may.
"""

from __future__ import annotations

import json
import re
from typing import Any
from urllib.parse import parse_qs, urlparse

import numpy as np
import pytest
from playwright.sync_api import Page, Route

import planner.model.scenario
from gcs.service.plans import trajectory_json_chunks
from planner import Plan
from planner.families.generators import grid_to_sphere

__all__ = ["ShowPlan", "show_plan"]

G = 9.81


class ShowPlan:
    """The plan of `vehicles` vehicles, its mission document and how the page is served it."""

    def __init__(self, vehicles: int, steps: int = 20, dt: float = 1.5,
                 mission_id: str = "show-scale") -> None:
        scenario = grid_to_sphere(vehicles, seed=None, steps=steps, dt=dt)
        starts = np.array([v["start"] for v in scenario["vehicles"]], dtype=float)
        goals = np.array([v["goal"] for v in scenario["vehicles"]], dtype=float)
        horizon = steps * dt
        # Rest to rest: +a for the first half, -a for the second (steps is even).
        accel = 4.0 * (goals - starts) / horizon**2  # (N, 3)
        sign = np.where(np.arange(steps) < steps // 2, 1.0, -1.0)  # (K,)
        acceleration = sign[None, :, None] * accel[:, None, :]  # (N, K, 3)
        velocity = np.concatenate([np.zeros((vehicles, 1, 3)),
                                   np.cumsum(acceleration * dt, axis=1)], axis=1)
        steps_moved = velocity[:, :-1] * dt + 0.5 * acceleration * dt**2
        position = starts[:, None, :] + np.concatenate(
            [np.zeros((vehicles, 1, 3)), np.cumsum(steps_moved, axis=1)], axis=1)
        jerk = np.diff(np.concatenate([np.zeros((vehicles, 1, 3)), acceleration], axis=1),
                       axis=1) / dt
        thrust = np.linalg.norm(acceleration + np.array([0.0, 0.0, G]), axis=2)
        t = np.arange(steps + 1) * dt
        verification = {
            "min_separation": 1.0, "min_separation_continuous": 1.0,
            "closest_pair": [scenario["vehicles"][0]["id"], scenario["vehicles"][1]["id"]],
            "closest_time": 0.0, "max_violation": {"position": 0.0}, "boundary_error": {},
            "thrust_range": [float(thrust.min()), float(thrust.max())],
            "body_rate_peak": 0.0, "flyable": True, "separated": True, "within_bounds": True,
            "separation_tolerance": 1e-6, "bound_tolerance": 1e-6,
        }
        self.document: dict[str, Any] = {
            "status": "converged", "message": "", "solver": "synthetic", "infeasible_groups": [],
            "scenario": scenario, "iterations": [], "timing": {"total_s": 0.0, "first_qp_s": 0.0},
            "vehicles": [{
                "id": spec["id"], "t": t.tolist(), "position": position[i].tolist(),
                "velocity": velocity[i].tolist(), "acceleration": acceleration[i].tolist(),
                "jerk": jerk[i].tolist(), "thrust": thrust[i].tolist(),
                "body_rates": np.zeros((steps, 3)).tolist(),
            } for i, spec in enumerate(scenario["vehicles"])],
            "verification": verification, "sequence": None,
        }
        self.vehicles = vehicles
        self.mission_id = mission_id
        with pytest.MonkeyPatch.context() as patch:  # the planner's own bound, if lower
            patch.setattr(planner.model.scenario, "MAX_VEHICLES", max(vehicles,
                                                                planner.model.scenario.MAX_VEHICLES))
            self.plan = Plan.from_dict(self.document)
        self.mission = json.dumps({
            "id": mission_id, "name": f"show-{vehicles}", "status": "planned",
            "plan_status": "converged", "plan_ok": True, "vehicle_count": vehicles,
            "created_at": "2026-01-01T00:00:00Z", "scenario": scenario, "progress": [],
            "plan": self.document,
        })
        #: The trajectory answers the page asked for: rate -> bytes.
        self.served: dict[float, int] = {}

    def trajectory(self, rate: float) -> bytes:
        """GET /trajectory?rate= as the service writes it (no sample limit here)."""
        return b"".join(trajectory_json_chunks(self.mission_id, self.plan, rate, 10**12))

    def route(self, page: Page) -> None:
        """Serve this mission (document, trajectories, no flights) to `page`."""
        base = re.escape(f"/api/missions/{self.mission_id}")

        def mission(route: Route) -> None:
            route.fulfill(status=200, content_type="application/json", body=self.mission)

        def trajectory(route: Route) -> None:
            rate = float(parse_qs(urlparse(route.request.url).query)["rate"][0])
            body = self.trajectory(rate)
            self.served[rate] = len(body)
            route.fulfill(status=200, content_type="application/json", body=body)

        page.route(re.compile(f".*{base}$"), mission)
        page.route(re.compile(f".*{base}/trajectory\\?.*"), trajectory)
        page.route(re.compile(f".*/api/flights\\?mission_id={self.mission_id}&.*"),
                   lambda route: route.fulfill(
                       status=200, content_type="application/json",
                       body='{"total": 0, "limit": 500, "offset": 0, "flights": []}'))


def show_plan(vehicles: int) -> ShowPlan:
    return ShowPlan(vehicles)
