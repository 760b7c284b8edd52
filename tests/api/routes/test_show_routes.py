"""Shows through the API: a mission's validation report as one self-contained HTML page, and
a show file uploaded to /api/imports coming back as the sequence `fleetplan import` writes;
bad or oversized uploads are refused naming the file, the line and the field."""

from __future__ import annotations

import base64
import io
import re
import zipfile
from collections.abc import Callable
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gcs.api import create_app
from gcs.api.routes import shows
from gcs.service.settings import Settings
from planner import Plan
from planner.methods.sequence import plan_sequence
from tests.support.shows import csv_zip as _csv_zip
from tests.support.shows import ground_show as _show
from tests.support.shows import post_sequence, skyc_import


def _lit_show() -> dict:
    """The ground show of the planner's tests, its first formation orange."""
    body = _show(landing={})
    body["formations"][0]["color"] = "#ff8800"
    return body


@pytest.fixture(scope="module")
def ground_show() -> Plan:
    result = plan_sequence(_lit_show())
    assert result.ok, result.message
    return result.to_plan()


def test_a_missions_report_is_one_offline_page(make_settings: Callable[..., Settings]
                                                ) -> None:
    with TestClient(create_app(make_settings(max_trajectory_samples=1000))) as client:
        mission = post_sequence(client, _lit_show())
        response = client.get(f"/api/missions/{mission['id']}/report.html")
        samples = len(mission["scenario"]["vehicles"]) * (mission["scenario"]["steps"] + 1)
        assert samples > 1000  # this show is beyond the server's limit: refused, named
        assert response.status_code == 422 and response.json()["field"] == "mission_id"
        assert "use fleetplan report" in response.json()["reason"]
        assert client.get("/api/missions/nope/report.html").json()["field"] == "mission_id"
    with TestClient(create_app(make_settings())) as client:
        mission = post_sequence(client, _lit_show())
        response = client.get(f"/api/missions/{mission['id']}/report.html")
        assert response.status_code == 200, response.text
        assert response.headers["content-type"].startswith("text/html")
        page = response.text
        assert ": validation report</title>" in page
        assert "takes off from and lands on the ground" in page
        assert page.count("class='chart'") >= 5  # a chart per figure
        # no network requests: no script or image is fetched from elsewhere
        assert not re.search(r"""<(script|img)[^>]*\bsrc\s*=\s*["']?(https?:)?//""", page)


def _upload(client: TestClient, data: bytes, **options: object):
    """POST /api/imports of `data` (base64 in the JSON body) with these options."""
    return client.post("/api/imports",
                       json={"file": base64.b64encode(data).decode(), **options})


def test_an_uploaded_skyc_or_csv_zip_is_the_sequence_import_writes(
        ground_show: Plan, client: TestClient, tmp_path: Path) -> None:
    skyc = tmp_path / "show.skyc"
    expected = skyc_import(ground_show, skyc)
    response = _upload(client, skyc.read_bytes(), filename="show.skyc")
    assert response.status_code == 200, response.text
    assert response.json() == expected
    assert "takeoff" in expected and "landing" in expected
    assert expected["formations"][0]["color"] == "#ff8800"

    csvs = _csv_zip(ground_show, tmp_path / "show.zip")
    response = _upload(client, csvs.read_bytes(), filename="../csv/show.zip",
                       assignment="free", dt=0.1)
    assert response.status_code == 200, response.text
    sequence = response.json()
    assert sequence["assignment"] == "free" and sequence["dt"] == 0.1
    assert len(sequence["vehicles"]) == len(ground_show.vehicles)
    # posted as it is, the service plans it
    assert client.post("/api/missions", json=sequence).status_code in (201, 202)


def _zip(**files: bytes) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in files.items():
            archive.writestr(name, data)
    return buffer.getvalue()


def test_bad_uploads_are_refused_naming_the_file_line_and_field(
        client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    header = b"Time [msec],x [m],y [m],z [m],Red,Green,Blue\n"
    bad = _zip(**{"a.csv": header + b"0,0,0,0,255,0,0\n1000,nan,0,1,255,0,0\n"})
    response = _upload(client, bad, filename="design.zip")
    assert response.status_code == 422
    error = response.json()
    assert error["field"] == "x [m]" and error["reason"].startswith("design.zip:a.csv, line 3")

    assert _upload(client, b"").json()["field"] == "file"
    for text in ("no base64!", "\x80"):
        response = client.post("/api/imports", json={"file": text})
        assert response.status_code == 422 and response.json()["field"] == "file"
    response = _upload(client, b"not a zip at all", filename="x.skyc")
    assert response.status_code == 422 and "x.skyc" in response.json()["reason"]
    response = _upload(client, _zip(**{"a.csv": header}), times=[1, "soon"])
    assert response.status_code == 422 and response.json()["field"].startswith("times")
    response = _upload(client, _zip(**{"a.csv": header}), dt=0)
    assert response.status_code == 422 and response.json()["field"] == "dt"

    # a ZIP bomb stops at the unpacking bound, a large upload at the body limit
    monkeypatch.setattr(shows, "MAX_IMPORT_UNPACKED", 1 << 20)
    bomb = _zip(**{"a.csv": header + b"0,0,0,0,0,0,0\n" * 200_000})
    assert len(bomb) < 100_000
    response = _upload(client, bomb, filename="bomb.zip")
    assert response.status_code == 422
    assert "unpacks to more than 1 MiB" in response.json()["reason"]
    assert _upload(client, b"\0" * 3_000_000).status_code == 413
