"""A crowded service flies: while a mock flight runs in a real `fleetplan serve` (4 mock
vehicles), CSV exports past `max_concurrent_exports`, more event streams on the flight than
`max_event_streams_per_resource` and plan submissions arrive at once. The flight completes and
every refusal is a 503 with Retry-After (the benchmark of the same mix at scale, with its
timing figures, is bench/fanout.py)."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.api.support import QUICK_CROSSING, QUICK_PAIR, ServiceProcess, free_udp_base
from tests.support.waiting import until

pytestmark = pytest.mark.timeout(300)

EXPORTS = 8
EXPORT_SLOTS = 4
STREAMS = 6
STREAMS_PER_RESOURCE = 2
PLANS = 5

#: (status code, Retry-After header) of one request.
Answer = tuple[int, str | None]


async def _export(client: httpx.AsyncClient, url: str) -> Answer:
    async with client.stream("GET", url) as response:
        async for _ in response.aiter_bytes():
            pass
        return response.status_code, response.headers.get("retry-after")


async def _stream(client: httpx.AsyncClient, url: str) -> Answer:
    """Follow an event stream to its end (the flight's `done`)."""
    async with client.stream("GET", url) as response:
        async for _ in response.aiter_bytes():
            pass
        return response.status_code, response.headers.get("retry-after")


async def _plan(client: httpx.AsyncClient, index: int) -> Answer:
    scenario = {**QUICK_PAIR, "name": f"crowd-{index}"}
    response = await client.post("/api/missions?wait=0", json=scenario)
    return response.status_code, response.headers.get("retry-after")


@pytest.mark.flight
def test_a_crowded_service_flies_and_refuses_only_with_503(
    tmp_path: Path, dask_scheduler: str
) -> None:
    env = {"FLEETPLAN_MOCK_BASE_PORT": str(free_udp_base(4)), "FLEETPLAN_MOCK_SETTLE_S": "0.5",
           "FLEETPLAN_MAX_CONCURRENT_EXPORTS": str(EXPORT_SLOTS),
           "FLEETPLAN_MAX_EVENT_STREAMS_PER_RESOURCE": str(STREAMS_PER_RESOURCE)}

    async def crowd(base_url: str) -> tuple[dict[str, Any], dict[str, list[Answer]]]:
        limits = httpx.Limits(max_connections=None, max_keepalive_connections=None)
        async with httpx.AsyncClient(base_url=base_url, timeout=120, limits=limits) as client:
            mission = (await client.post("/api/missions?wait=120", json=QUICK_CROSSING)).json()
            assert mission["status"] == "planned", mission
            started = await client.post(f"/api/missions/{mission['id']}/flights",
                                        json={"hold_at_goal": 0.5})
            assert started.status_code == 201, started.text
            url = f"/api/flights/{started.json()['id']}"

            async def flying() -> bool:
                return ((await client.get(url)).json()["live"] or {}).get("phase") == "flying"

            await until(flying, "the flight to fly its plan", timeout=60.0)
            export_url = f"/api/missions/{mission['id']}/trajectory?rate=100&format=csv"
            exports, streams, plans = await asyncio.gather(
                asyncio.gather(*(_export(client, export_url) for _ in range(EXPORTS))),
                asyncio.gather(*(_stream(client, f"{url}/events") for _ in range(STREAMS))),
                asyncio.gather(*(_plan(client, i) for i in range(PLANS))),
            )

            async def ended() -> dict[str, Any] | None:
                got = (await client.get(url)).json()
                return None if got["finished_at"] is None else got

            flight = await until(ended, "the flight to end", timeout=120.0, poll=0.1)
            return flight, {"exports": list(exports), "streams": list(streams),
                               "plans": list(plans)}

    with ServiceProcess(tmp_path, "--mock", "4", "--scheduler", dask_scheduler, env=env,
                        start_timeout=120, quick_mocks=True) as service:
        flight, answers = asyncio.run(crowd(service.base_url))

    assert flight["status"] == "completed", (flight["status"], flight["error"])
    assert flight["summary"]["completed"] is True
    assert not flight["summary"]["faults"]
    expected = {"exports": {200}, "streams": {200}, "plans": {201, 202}}
    for crowd_name, codes in answers.items():
        for code, retry_after in codes:
            if code == 503:
                assert retry_after is not None and int(retry_after) > 0, (crowd_name, codes)
            else:
                assert code in expected[crowd_name], (crowd_name, codes)
    # More streams than the bound were open on the flight at once: the rest were refused.
    streamed = [code for code, _ in answers["streams"]]
    assert streamed.count(200) <= STREAMS_PER_RESOURCE and 503 in streamed, streamed
