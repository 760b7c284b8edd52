"""Fuzz every operation of the OpenAPI schema (schemathesis) against a real server: whatever
the input, the answer is never a 5xx, and it conforms to the documented schema."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis import checks

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import ServiceProcess


@pytest.fixture(scope="module")
def fuzz_service(tmp_path_factory: pytest.TempPathFactory, dask_scheduler: str
                 ) -> Iterator[ServiceProcess]:
    # Small limits keep any plan the fuzzer manages to submit cheap; no waiting for plans;
    # planning on the session's Dask cluster (no embedded cluster to start).
    env = {"FLEETPLAN_MAX_VEHICLES": "4", "FLEETPLAN_MAX_STEPS": "60",
           "FLEETPLAN_PLAN_WAIT_S": "0", "FLEETPLAN_MAX_BODY_BYTES": "100000"}
    workdir: Path = tmp_path_factory.mktemp("fuzz")
    with ServiceProcess(workdir, "--mock", "0", "--scheduler", dask_scheduler, env=env,
                        start_timeout=120) as service:
        yield service


# The schema the server publishes; building the app starts nothing (no lifespan).
schema = schemathesis.openapi.from_dict(
    create_app(Settings(database_url="sqlite://", mock_vehicles=0)).openapi()
)


#: Examples per operation: 20 reach every operation's parameters and bodies (valid and
#: invalid) in a test run; FLEETPLAN_FUZZ_EXAMPLES=500 (say) for a deep run.
EXAMPLES = int(os.environ.get("FLEETPLAN_FUZZ_EXAMPLES", "20"))


@pytest.mark.slow
@schema.parametrize()
@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck))
def test_no_server_errors_and_documented_answers(
    case: schemathesis.Case, fuzz_service: ServiceProcess
) -> None:
    response = case.call(base_url=fuzz_service.base_url, timeout=30)
    assert response.status_code < 500, f"{case.method} {case.formatted_path}: {response.text}"
    # Everything schemathesis checks (status codes, content types, bodies, headers, that
    # invalid input is rejected) except that schema-valid input is accepted: a scenario can
    # fit the schema and still be invalid (goal outside the workspace, ...), which is a 422.
    case.validate_response(response, excluded_checks=[checks.positive_data_acceptance])
