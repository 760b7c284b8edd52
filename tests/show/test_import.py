"""`fleetplan import`: a show read back from a .skyc or Skybrush CSV gives the formations,
holds, colours and light transitions it was made from, and a bad file is refused naming the
file, the line or field, and the fix (exit 2, nothing written)."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from gcs.cli.main import main
from gcs.export.skyc import write_skyc
from gcs.show.csv_reader import read_csv_show
from gcs.show.skyc_reader import read_skyc
from gcs.show.to_sequence import ImportOptions, to_sequence
from gcs.show.tracks import ShowFileError
from planner import Plan
from planner.methods.sequence import parse_sequence, plan_sequence
from tests.support.shows import csv_zip as _csv_zip
from tests.support.shows import light_design as _design


@pytest.fixture(scope="module")
def lit() -> tuple[Plan, object]:
    """A planned lit show (grid -> sphere -> grid -> sphere) and its parsed sequence."""
    shown = plan_sequence(_design())
    plan = shown.to_plan()
    assert plan.ok, plan.problems()
    return plan, shown.sequence


def _check_round_trip(sequence: dict, plan: Plan, parsed) -> None:
    """The imported formations are the planned ones, drone by drone, with their colours."""
    back = parse_sequence(sequence)
    assert back.ids == parsed.ids
    assert len(back.points) == len(parsed.points) == 4
    for got, expected in zip(back.points, parsed.points, strict=True):
        assert np.abs(got - expected).max() < 1e-3
    assert back.colors is not None and parsed.colors is not None
    for got, expected in zip(back.colors, parsed.colors, strict=True):
        assert np.abs(got.astype(int) - expected.astype(int)).max() <= 1
    assert back.transitions == ("fade", "hold", "black")
    assert all(hold >= 5 for hold in back.holds[:-1])  # the 1 s holds (5 steps) at least


def test_a_skyc_round_trip_gives_the_same_formations(lit, tmp_path: Path) -> None:
    plan, parsed = lit
    write_skyc(plan, tmp_path / "show.skyc")
    show = read_skyc(tmp_path / "show.skyc")
    assert show.validation["minDistance"] == 1.0
    sequence = to_sequence(show.tracks, name=show.title, file="show.skyc",
                           validation=show.validation)
    _check_round_trip(sequence, plan, parsed)
    # as it is, the planner plans it
    assert plan_sequence(sequence).ok


def test_a_csv_zip_round_trip_gives_the_same_formations(lit, tmp_path: Path) -> None:
    plan, parsed = lit
    tracks = read_csv_show(_csv_zip(plan, tmp_path / "show.zip"))
    assert [t.name for t in tracks] == sorted(parsed.ids)
    order = [sorted(parsed.ids).index(vid) for vid in parsed.ids]
    sequence = to_sequence([tracks[i] for i in order], name="csv", file="show.zip")
    _check_round_trip(sequence, plan, parsed)


def test_the_cli_writes_a_sequence_from_a_csv_folder(lit, tmp_path: Path, capsys) -> None:
    plan, _ = lit
    folder = tmp_path / "csv"
    with zipfile.ZipFile(_csv_zip(plan, tmp_path / "show.zip")) as archive:
        archive.extractall(folder)
    out = tmp_path / "seq.json"
    assert main(["import", str(folder), "-o", str(out), "--times", "0,40,70"]) == 0
    assert "9 drones, 3 formations with colours" in capsys.readouterr().out
    sequence = json.loads(out.read_text())
    assert [f.get("duration") for f in sequence["formations"]] == [None, 40.0, 30.0]
    assert parse_sequence(sequence).ids == tuple(sorted(plan.scenario.ids))


def test_given_times_choose_the_formations(lit, tmp_path: Path) -> None:
    plan, _ = lit
    write_skyc(plan, tmp_path / "show.skyc")
    show = read_skyc(tmp_path / "show.skyc")
    sequence = to_sequence(show.tracks, name="t", file="show.skyc",
                           options=ImportOptions(times=(0.0, 20.0), assignment="free"))
    expected = plan.sample(np.array([20.0])).position[:, 0]
    assert np.abs(np.array(sequence["formations"][1]["positions"]) - expected).max() < 1e-5
    assert sequence["assignment"] == "free"


def _zip(path: Path, files: dict[str, str]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, text in files.items():
            archive.writestr(name, text)
    return path


HEADER = "Time [msec],x [m],y [m],z [m],Red,Green,Blue\n"
GOOD = HEADER + "0,0,0,2,255,0,0\n1000,0,0,2,255,0,0\n5000,4,0,2,0,0,255\n6000,4,0,2,0,0,255\n"


@pytest.mark.parametrize(("files", "words"), [
    ({"a.csv": GOOD, "b.csv": HEADER + "0,2,0,2,1,1,1\n1000,2,0\n"},
     "show.zip:b.csv, line 3: row: has 3 values"),
    ({"a.csv": GOOD, "b.csv": HEADER + "0,2,0,2,1,1,1\n1000,2,nan,2,1,1,1\n"},
     "show.zip:b.csv, line 3: y [m]: 'nan' is not a finite number"),
    ({"a.csv": GOOD, "b.csv": HEADER + "0,2,0,2,1,1,1\n1000,2,0,2,1,300,1\n"},
     "line 3: Green: '300': a colour channel is an integer 0..255"),
    ({"a.csv": GOOD, "b.csv": HEADER}, "show.zip:b.csv: rows: drone 'b' has no rows"),
    ({"a.csv": GOOD, "b.csv": "Time [msec],x [m],y [m]\n0,1,2\n"},
     "show.zip:b.csv, line 1: header: has 3 columns"),
    ({"a.csv": GOOD, "b.csv": HEADER + "1000,2,0,2,1,1,1\n0,2,0,2,1,1,1\n"},
     "line 3: Time [msec]: times must increase"),
    ({"a.csv": GOOD, "b.csv": GOOD}, "closer than"),
    ({"readme.txt": "hi"}, "no .csv files"),
])
def test_a_bad_csv_is_refused_naming_file_line_and_field(tmp_path: Path, capsys, files,
                                                         words: str) -> None:
    source = _zip(tmp_path / "show.zip", files)
    out = tmp_path / "seq.json"
    assert main(["import", str(source), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert words in err, err
    assert "Traceback" not in err
    assert not out.exists()


def test_a_zip_bomb_stops_at_the_bound(tmp_path: Path) -> None:
    big = HEADER + "0,0,0,2,1,1,1\n" * 200_000  # 2.8 MB unpacked, a few kB packed
    source = _zip(tmp_path / "bomb.zip", {"a.csv": big})
    assert source.stat().st_size < 100_000
    with pytest.raises(ShowFileError, match=r"bomb.zip:a.csv: size: unpacks to more than 1 MiB"):
        read_csv_show(source, unpacked=1 << 20)


@pytest.mark.parametrize("name", ["huge.skyc", "huge.zip"])
def test_a_2_gb_file_is_refused_before_it_is_read(tmp_path: Path, capsys, name: str) -> None:
    source = tmp_path / name
    with source.open("wb") as sparse:
        sparse.truncate(2 << 30)  # 2 GiB on paper, no disk
    assert main(["import", str(source), "-o", str(tmp_path / "seq.json")]) == 2
    assert f"{name}: size:" in capsys.readouterr().err


@pytest.mark.parametrize(("change", "words"), [
    (lambda show: show["swarm"]["drones"][1]["settings"]["trajectory"].update(points=[]),
     "swarm.drones[1].settings.trajectory.points: drone 'uav2' has no keyframes"),
    (lambda show: show["swarm"]["drones"][0]["settings"]["trajectory"]["points"][3][1]
     .__setitem__(2, "high"), "swarm.drones[0].settings.trajectory.points[3]: drone 'uav1': "
                              "t, x, y, z must be numbers"),
    (lambda show: show["swarm"]["drones"][2]["settings"]["lights"].update(data="Ag=="),
     "swarm.drones[2].settings.lights.data: drone 'uav3': light program, byte 1"),
    (lambda show: show.pop("swarm"), "swarm: is missing"),
])
def test_a_bad_skyc_is_refused_naming_the_field(lit, tmp_path: Path, change, words) -> None:
    plan, _ = lit
    write_skyc(plan, tmp_path / "show.skyc")
    with zipfile.ZipFile(tmp_path / "show.skyc") as archive:
        show = json.loads(archive.read("show.json"))
    change(show)
    bad = tmp_path / "bad.skyc"
    with zipfile.ZipFile(bad, "w") as archive:
        archive.writestr("show.json", json.dumps(show))
    with pytest.raises(ShowFileError) as caught:
        read_skyc(bad)
    assert f"bad.skyc:show.json: {words}" in str(caught.value)


def test_a_zip_that_is_not_a_show(tmp_path: Path) -> None:
    (tmp_path / "x.skyc").write_bytes(b"PK not really")
    with pytest.raises(ShowFileError, match=r"x\.skyc: file: not a readable ZIP"):
        read_skyc(tmp_path / "x.skyc")
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("other.json", "{}")
    (tmp_path / "y.skyc").write_bytes(buffer.getvalue())
    with pytest.raises(ShowFileError, match=r"has no show\.json"):
        read_skyc(tmp_path / "y.skyc")


def test_a_show_on_the_ground_comes_back_with_its_takeoff_and_landing(tmp_path: Path) -> None:
    from tests.support.shows import ground_show as _show

    data = _show(landing={})
    data["formations"][0]["color"] = "#ff0000"
    shown = plan_sequence(data)
    assert shown.ok, shown.message
    write_skyc(shown.to_plan(), tmp_path / "ground.skyc")
    show = read_skyc(tmp_path / "ground.skyc")
    sequence = to_sequence(show.tracks, name="g", file="ground.skyc",
                           validation=show.validation)
    homes = shown.sequence.ground.homes
    assert np.abs(np.array(sequence["takeoff"]["homes"]) - homes[:, :2]).max() < 1e-6
    slots = np.array(sequence["landing"]["homes"])
    assert np.abs(slots - shown.sequence.ground.slots[:, :2]).max() < 1e-6
    back = parse_sequence(sequence)
    assert len(back.points) == 3
    for got, expected in zip(back.points, shown.sequence.points, strict=True):
        assert np.abs(got - expected).max() < 1e-3
    assert back.ground is not None
