"""One definition per contract: the API's scenario and plan schemas come from the planner's
dataclasses, a flight's events and live state from gcs.documents' TypedDicts, and the status
sets the service uses are the ones it publishes."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from fastapi.testclient import TestClient
from typing_extensions import get_type_hints

from gcs.api import create_app
from gcs.api.schemas import planner_schemas, shape_errors
from gcs.documents import FlightEvent, FlightSnapshot, VehicleSnapshot
from gcs.phases import EventKind, FlightPhase, VehiclePhase, vocabulary
from gcs.service.settings import Settings
from gcs.service.statuses import FLIGHT_ACTIVE, FlightStatus, MissionStatus, status_sets
from planner import Plan, Scenario
from planner.model.scenario import DEFAULTS, Limits, Vehicle
from planner.result import STATUSES as PLAN_STATUSES
from tests.api.support import EXAMPLES, example


def _json_fields(cls: type) -> set[str]:
    return {f.name for f in dataclasses.fields(cls) if f.repr}  # type: ignore[arg-type]


def test_scenario_schema_has_exactly_the_planners_fields() -> None:
    schemas = planner_schemas()
    for name, cls in (("Scenario", Scenario), ("Limits", Limits), ("Vehicle", Vehicle)):
        assert set(schemas[name]["properties"]) == _json_fields(cls), name
        for key in schemas[name]["required"]:
            assert key not in DEFAULTS  # a key with a default is never required
    # What a scenario round-trips through the planner is what the schema names.
    echoed = Scenario.from_dict(schemas["Scenario"]["examples"][0]).to_dict()
    assert set(echoed) <= set(schemas["Scenario"]["properties"])
    assert schemas["Scenario"]["properties"]["dt"]["description"] == "Step length (s)."
    assert schemas["Scenario"]["properties"]["max_iterations"]["default"] == 30


def test_plan_schema_matches_a_real_plan_document() -> None:
    schemas = planner_schemas()
    plan = schemas["Plan"]
    assert plan["properties"]["status"]["enum"] == list(PLAN_STATUSES)
    example = plan["examples"][0]
    assert set(plan["required"]) == set(Plan.__dataclass_fields__)
    assert set(example) == set(plan["properties"])
    trajectory = schemas["VehicleTrajectory"]["properties"]
    assert trajectory["t"]["items"] == {"type": "number"}  # (K+1,)
    assert trajectory["position"]["items"]["maxItems"] == 3  # (K+1, 3)


def test_openapi_publishes_the_derived_components_and_readable_operation_ids() -> None:
    schema = create_app(Settings(database_url="sqlite://", mock_vehicles=0)).openapi()
    components = schema["components"]["schemas"]
    assert {"Scenario", "Limits", "Vehicle", "Plan", "IterationRecord"} <= set(components)
    assert "ScenarioIn" not in components and "PlanOut" not in components
    post = schema["paths"]["/api/missions"]["post"]
    assert post["operationId"] == "createMission"
    body = post["requestBody"]["content"]["application/json"]["schema"]
    assert body == {"$ref": "#/components/schemas/Scenario"}
    ids = [op["operationId"] for path in schema["paths"].values() for op in path.values()]
    assert len(ids) == len(set(ids))
    assert all("_" not in i for i in ids), ids


def test_a_flights_events_and_live_state_are_the_flights_documents() -> None:
    """FlightOut's events and live state are `FlightEvent` and `FlightSnapshot` (its vehicles
    `VehicleSnapshot`), key for key, their kinds and phases the flight's own enums."""
    components = create_app(Settings(database_url="sqlite://", mock_vehicles=0)).openapi()[
        "components"]["schemas"]

    def ref(name: str) -> dict[str, str]:
        return {"$ref": f"#/components/schemas/{name}"}

    flight = components["FlightOut"]["properties"]
    assert flight["events"]["items"] == ref("FlightEvent")
    assert ref("FlightSnapshot") in flight["live"]["anyOf"]
    for cls in (FlightEvent, FlightSnapshot, VehicleSnapshot):
        assert set(components[cls.__name__]["properties"]) == set(get_type_hints(cls)), cls
    assert components["FlightSnapshot"]["properties"]["vehicles"]["items"] == \
        ref("VehicleSnapshot")
    for document, key, enum in (("FlightSnapshot", "phase", FlightPhase),
                                ("VehicleSnapshot", "phase", VehiclePhase)):
        assert components[document]["properties"][key] == ref(enum.__name__), document
        assert components[enum.__name__]["enum"] == [e.value for e in enum]
    # an event's kind: one of the kinds, or one a record from another version stored
    kind = components["FlightEvent"]["properties"]["kind"]
    assert ref("EventKind") in kind["anyOf"] and {"type": "string"} in kind["anyOf"], kind
    assert components["EventKind"]["enum"] == [e.value for e in EventKind]


def test_status_publishes_every_status_set(client: TestClient) -> None:
    statuses = client.get("/api/status").json()["statuses"]
    assert statuses["mission"]["all"] == [s.value for s in MissionStatus]
    assert statuses["mission"]["active"] == ["planning"]
    assert statuses["mission"]["failed"] == ["failed"]
    assert statuses["flight"]["all"] == [s.value for s in FlightStatus]
    assert statuses["flight"]["active"] == ["starting", "running", "paused", "aborting"]
    assert set(statuses["flight"]["active"]) == set(FLIGHT_ACTIVE)
    assert set(statuses["flight"]["finished"]) == set(FlightStatus) - set(FLIGHT_ACTIVE)
    assert statuses["plan"]["all"] == list(PLAN_STATUSES)


def test_status_publishes_the_phases_and_event_kinds(shared_client: TestClient) -> None:
    phases = shared_client.get("/api/status").json()["phases"]
    assert phases == vocabulary()
    assert set(phases) == {"flight", "vehicle", "airborne", "replan", "event_kinds"}
    assert EventKind.PAUSE_LIMIT.value in phases["event_kinds"]
    assert set(phases["airborne"]) <= set(phases["vehicle"])


def test_the_status_example_is_made_from_the_definitions(shared_client: TestClient) -> None:
    component = shared_client.get("/openapi.json").json()["components"]["schemas"]["StatusOut"]
    assert "phases" in component["properties"] and "phases" in component["required"]
    example = component["examples"][0]
    assert example["statuses"] == status_sets()
    assert FlightStatus.PAUSED.value in example["statuses"]["flight"]["active"]
    assert example["phases"] == vocabulary()
    assert set(example["limits"]) == set(shared_client.get("/api/status").json()["limits"])
    assert example["limits"]["max_steps"] == Settings.model_fields["max_steps"].default


def _validator(schema: dict, component: str) -> Any:
    """A JSON Schema validator for one OpenAPI component (refs rewritten to $defs)."""
    import jsonschema_rs  # schemathesis's own validator, a test dependency

    text = json.dumps(schema["components"]["schemas"]).replace("#/components/schemas/",
                                                               "#/$defs/")
    return jsonschema_rs.validator_for({"$defs": json.loads(text),
                                        "$ref": f"#/$defs/{component}"})


def test_real_documents_match_the_published_schema(client: TestClient) -> None:
    schema = client.get("/openapi.json").json()
    mission = client.post("/api/missions?wait=60", json=example("paper-circle4")).json()
    assert mission["plan"] is not None
    for component, document in [("MissionOut", mission), ("Plan", mission["plan"]),
                                ("Scenario", mission["scenario"])]:
        errors = [e.message for e in _validator(schema, component).iter_errors(document)]
        assert errors == [], (component, errors[:3])
    # Every bundled example is a valid Scenario by the schema and by the shape check.
    scenario_schema = _validator(schema, "Scenario")
    for path in sorted(EXAMPLES.glob("*.json")):
        scenario = json.loads(path.read_text())
        assert scenario_schema.is_valid(scenario), path.name
        assert shape_errors(scenario) == [], path.name
    # And a broken one is not.
    assert not scenario_schema.is_valid({**example("paper-circle2"), "dt": "fast"})
