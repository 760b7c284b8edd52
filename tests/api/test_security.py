"""Forged and unauthorised requests are refused before any route runs: foreign Host (DNS
rebinding), cross-site Origin on state-changing requests, non-JSON bodies, missing or wrong
tokens, and the read-only role changing anything."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.service.settings import Settings
from tests.api.support import OPERATOR, READER, example, refused


def _missions(client: TestClient) -> int:
    return client.get("/api/missions").json()["total"]


@pytest.fixture
def planned(client: TestClient) -> str:
    response = client.post("/api/missions?wait=60", json=example("paper-circle2"))
    assert response.status_code == 201
    return response.json()["id"]


def test_a_forged_cross_site_fly_request_is_refused(
    mock_settings: Callable[..., Settings],
) -> None:
    # text/plain, empty body, Origin http://evil.example: a browser sends this cross-site
    # without a CORS preflight; answered, it would arm the fleet.
    with TestClient(create_app(mock_settings())) as client:
        mission = client.post("/api/missions?wait=60", json=example("paper-circle2")).json()
        url = f"/api/missions/{mission['id']}/flights"
        forged = client.post(url, content=b"", headers={
            "Content-Type": "text/plain", "Origin": "http://evil.example"})
        refused(forged, 403, "Origin", "cross-site request from http://evil.example refused")
        # Without the Origin the text/plain body alone is refused too.
        refused(client.post(url, content=b"", headers={"Content-Type": "text/plain"}),
                415, "Content-Type", "must be JSON")
        assert client.get("/api/flights").json()["total"] == 0  # nothing was flown


@pytest.mark.parametrize(
    ("method", "path", "headers"),
    [
        ("DELETE", "/api/missions/{id}", {"Origin": "http://evil.example"}),
        ("POST", "/api/missions/{id}/flights", {"Origin": "null"}),
        ("POST", "/api/missions/{id}/flights", {"Origin": "http://testserver.evil.example"}),
        ("POST", "/api/missions/{id}/flights", {"Origin": "http://localhost:3000"}),
        ("DELETE", "/api/missions/{id}", {"Sec-Fetch-Site": "cross-site"}),
    ],
)
def test_cross_site_state_changes_are_refused(
    client: TestClient, planned: str, method: str, path: str, headers: dict[str, str]
) -> None:
    response = client.request(method, path.format(id=planned), headers=headers)
    refused(response, 403, "Origin", "cross-site request")
    assert client.get(f"/api/missions/{planned}").status_code == 200  # still there


def test_the_services_own_origin_and_configured_ones_may_change_state(
    make_settings: Callable[..., Settings],
) -> None:
    settings = make_settings(allowed_origins=["https://console.example"])
    with TestClient(create_app(settings)) as client:
        for origin in ("http://testserver", "https://console.example"):
            response = client.post("/api/missions?wait=60", json=example("paper-circle2"),
                                   headers={"Origin": origin})
            assert response.status_code == 201, response.text
        # Reading cross-site is harmless (no CORS headers: the browser hides the answer).
        assert client.get("/api/status", headers={"Origin": "http://evil.example"}
                          ).status_code == 200


@pytest.mark.parametrize("host", ["evil.example", "evil.example:8000", "127.0.0.2", ""])
def test_a_foreign_host_is_refused_dns_rebinding(client: TestClient, host: str) -> None:
    refused(client.get("/api/status", headers={"Host": host}), 400, "Host",
            "does not answer to the name")
    refused(client.post("/api/missions", json=example("paper-circle2"), headers={"Host": host}),
            400, "Host", "does not answer to the name")
    refused(client.get("/", headers={"Host": host}), 400, "Host", "does not answer")


def test_by_default_only_the_bound_names_are_answered(
    make_settings: Callable[..., Settings],
) -> None:
    settings = make_settings(allowed_hosts=[])  # default: bound to 127.0.0.1
    with TestClient(create_app(settings), base_url="http://127.0.0.1:8000") as client:
        assert client.get("/api/status").status_code == 200
        assert client.get("/api/status", headers={"Host": "localhost:8000"}).status_code == 200
        assert client.get("/api/status", headers={"Host": "[::1]:8000"}).status_code == 200
        refused(client.get("/api/status", headers={"Host": "testserver"}), 400, "Host", "")


@pytest.mark.parametrize(
    "content_type",
    ["text/plain", "application/x-www-form-urlencoded", "multipart/form-data; boundary=x"],
)
def test_bodies_must_be_json(client: TestClient, content_type: str) -> None:
    response = client.post("/api/missions", content=json.dumps(example("paper-circle2")),
                           headers={"Content-Type": content_type})
    refused(response, 415, "Content-Type", content_type.split(";")[0])
    assert _missions(client) == 0
    # Declared JSON is fine, with a charset too.
    response = client.post("/api/missions?wait=60", content=json.dumps(example("paper-circle2")),
                           headers={"Content-Type": "application/json; charset=utf-8"})
    assert response.status_code == 201


def test_a_body_without_a_content_type_is_415(client: TestClient) -> None:
    request = client.build_request("POST", "/api/missions",
                                   content=json.dumps(example("paper-circle2")))
    assert "content-type" not in request.headers
    refused(client.send(request), 415, "Content-Type", "got none")


@pytest.fixture
def token_client(make_settings: Callable[..., Settings]) -> Iterator[TestClient]:
    settings = make_settings(api_token=OPERATOR, read_token=READER)
    with TestClient(create_app(settings)) as client:
        yield client


def _bearer(token: str) -> dict[str, str]:
    return {"Authorization": f"Bearer {token}"}


def test_with_tokens_every_api_request_needs_one(token_client: TestClient) -> None:
    response = token_client.get("/api/status")
    refused(response, 401, "Authorization", "an API token is required")
    assert response.headers["www-authenticate"] == "Bearer"
    refused(token_client.get("/api/missions", headers=_bearer("guess-guess-guess-1")), 401,
            "Authorization", "wrong API token")
    refused(token_client.post("/api/missions", json=example("paper-circle2")), 401,
            "Authorization", "")
    # The page itself and the API docs load without a token (the page then asks for it).
    assert token_client.get("/").status_code == 200
    assert token_client.get("/docs").status_code == 200


def test_the_read_only_role_reads_and_changes_nothing(token_client: TestClient) -> None:
    created = token_client.post("/api/missions?wait=60", json=example("paper-circle2"),
                                headers=_bearer(OPERATOR))
    assert created.status_code == 201
    mission_id = created.json()["id"]
    reader = _bearer(READER)
    assert token_client.get(f"/api/missions/{mission_id}", headers=reader).status_code == 200
    assert token_client.get("/api/status", headers=reader).status_code == 200
    for method, path in [("POST", "/api/missions"), ("DELETE", f"/api/missions/{mission_id}"),
                         ("POST", f"/api/missions/{mission_id}/flights")]:
        refused(token_client.request(method, path, headers=reader, json=example("paper-circle2")
                                     if method == "POST" else None),
                403, "Authorization", "read-only token may not change anything")
    assert token_client.get(f"/api/missions/{mission_id}", headers=reader).status_code == 200
    assert token_client.delete(f"/api/missions/{mission_id}",
                               headers=_bearer(OPERATOR)).status_code == 204


def test_the_page_cookie_carries_the_token_same_site_only(token_client: TestClient) -> None:
    # EventSource cannot send headers: the page keeps the token in a SameSite=Strict cookie.
    token_client.cookies.set("fleetplan_token", OPERATOR)
    assert token_client.get("/api/status").status_code == 200
    assert token_client.post("/api/missions?wait=60", json=example("paper-circle2"),
                             headers={"Origin": "http://testserver"}).status_code == 201
    # A cookie does not make a cross-site request acceptable.
    refused(token_client.post("/api/missions", json=example("paper-circle2"),
                              headers={"Origin": "http://evil.example"}), 403, "Origin", "")


def test_binding_beyond_loopback_requires_a_token(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="set an operator token"):
        Settings(host="0.0.0.0")
    with pytest.raises(ValueError, match="at least 16 characters"):
        Settings(host="0.0.0.0", api_token="short")
    token_file = tmp_path / "token"
    token_file.write_text(OPERATOR + "\n")
    settings = Settings(host="0.0.0.0", api_token_file=token_file)
    assert settings.api_token is not None and settings.api_token.get_secret_value() == OPERATOR
    with pytest.raises(ValueError, match="read_token_file"):
        Settings(api_token=OPERATOR, read_token_file=tmp_path / "missing")
    with pytest.raises(ValueError, match="must differ"):
        Settings(api_token=OPERATOR, read_token=OPERATOR)
    assert Settings(host="::1").api_token is None  # loopback: no token needed


def test_healthz_needs_no_token_and_tells_nothing(token_client: TestClient) -> None:
    response = token_client.get("/healthz")
    assert response.status_code == 200 and response.json() == {"status": "ok"}
    refused(token_client.get("/healthz", headers={"Host": "evil.example"}), 400, "Host", "")


def test_an_empty_token_from_the_environment_is_refused(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # docker-compose passes ${FLEETPLAN_API_TOKEN:-}: unset, it is an empty string.
    monkeypatch.setenv("FLEETPLAN_API_TOKEN", "")
    with pytest.raises(ValueError, match="api_token must be at least 16 characters"):
        Settings(host="0.0.0.0")
