"""Light programs in the .skyc export, read back by a decoder written here from Skybrush's
format alone (libskybrush's light executor: opcodes 0x00 END, 0x02 SLEEP, 0x04 SET_COLOR,
0x08 FADE_TO_COLOR; durations as varints of 1/50 s frames), sampled against the design."""

from __future__ import annotations

import base64
import copy
from typing import Any

import numpy as np
import pytest

from gcs.errors import ExportError
from gcs.export.lightcode import Change, colors_at, decode, encode
from gcs.export.skyc import check_exportable, skyc_chunks
from planner import Plan
from planner.errors import ScenarioError
from planner.families.generators import show_sequence
from planner.methods.sequence import parse_sequence, plan_sequence
from tests.export.reader import evaluate, read_show
from tests.support.shows import light_design as _design
from tests.support.shows import slot_colors as _slot_colors

RED, BLUE, BLACK = (255, 0, 0), (0, 0, 255), (0, 0, 0)


@pytest.fixture(scope="module")
def show() -> Plan:
    plan = plan_sequence(_design()).to_plan()
    assert plan.ok, plan.problems()
    return plan


# --------------------------------------------------------------- the independent decoder


def _varint(data: bytes, at: int) -> tuple[int, int]:
    value, shift = 0, 0
    while True:
        byte = data[at]
        at += 1
        value += (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, at


def _play(data: bytes, times: np.ndarray) -> np.ndarray:
    """The colour at each time, as the executor shows it: a program of SET_COLOR, FADE_TO_COLOR,
    SLEEP, END only (anything else fails the test)."""
    keyframes: list[tuple[float, np.ndarray]] = [(0.0, np.zeros(3))]  # (time, colour) corners
    at, frame = 0, 0
    while True:
        op = data[at]
        at += 1
        if op == 0x00:
            break
        if op == 0x02:
            frames, at = _varint(data, at)
        elif op in (0x04, 0x08):
            color = np.array(list(data[at:at + 3]), dtype=float)
            frames, at = _varint(data, at + 3)
            if op == 0x04:  # jump: the old colour up to now, the new one from now
                keyframes.append((frame / 50.0, keyframes[-1][1]))
                keyframes.append((frame / 50.0, color))
            else:  # linear from the colour shown now to `color` over the frames
                keyframes.append((frame / 50.0, keyframes[-1][1]))
                keyframes.append(((frame + frames) / 50.0, color))
        else:
            raise AssertionError(f"unexpected opcode 0x{op:02x} at byte {at - 1}")
        frame += frames
    assert at == len(data), "bytes after END"
    corner_t = np.array([k[0] for k in keyframes])
    corner_c = np.array([k[1] for k in keyframes])
    out = np.empty((len(times), 3))
    for i, t in enumerate(times):
        last = np.flatnonzero(corner_t <= t)[-1]  # the latest corner at or before t
        if last + 1 < len(corner_t) and corner_t[last + 1] > corner_t[last]:
            u = (t - corner_t[last]) / (corner_t[last + 1] - corner_t[last])
            out[i] = corner_c[last] + u * (corner_c[last + 1] - corner_c[last])
        else:
            out[i] = corner_c[last]
    return out


def _programs(plan: Plan) -> tuple[dict[str, Any], dict[str, bytes]]:
    show = read_show(b"".join(skyc_chunks(plan)))
    programs = {d["settings"]["name"]: base64.b64decode(d["settings"]["lights"]["data"])
                for d in show["swarm"]["drones"]}
    return show, programs


def _legs(plan: Plan) -> list[tuple[float, float]]:
    assert plan.sequence is not None
    return [(s["start_s"], s["end_s"]) for s in plan.sequence["timeline"] if s["kind"] == "leg"]


# ------------------------------------------------------------------------------ tests


def test_each_drone_shows_the_design_at_every_moment(show: Plan) -> None:
    _, programs = _programs(show)
    (a0, a1), (b0, b1), (c0, c1) = _legs(show)
    data = _design()
    sphere = np.array(data["formations"][1]["positions"])
    slot_colors = np.array(_slot_colors(9), dtype=float)
    drones = {d["settings"]["name"]: d["settings"] for d in
              read_show(b"".join(skyc_chunks(show)))["swarm"]["drones"]}
    for vid, program in programs.items():
        times = np.array([0.0, a0, 0.5 * (a0 + a1), a1, 0.5 * (b0 + b1), b1 - 0.02, b1,
                          c0 + 0.25 * (c1 - c0), 0.5 * (c0 + c1), c1, show.scenario.horizon])
        got = _play(program, times)
        # Which sphere slot the drone stands on when the first leg ends: its colour.
        where = evaluate(drones[vid]["trajectory"], np.array([a1]))[0]
        slot = int(np.argmin(np.linalg.norm(sphere - where, axis=1)))
        assert np.linalg.norm(sphere[slot] - where) < 1e-3
        mine = slot_colors[slot]
        expected = np.array([
            RED, RED, 0.5 * (np.array(RED) + mine), mine,   # fade over the first leg
            mine, mine, BLUE,                               # hold, switch on arrival
            0.5 * np.array(BLUE), BLACK, BLUE, BLUE,        # out and in through black
        ], dtype=float)
        # a frame (20 ms) of rounding moves a fade's sample by at most 255 * 0.02 / leg
        assert np.abs(got - expected).max() <= 255 * 0.02 / (a1 - a0) + 0.51, vid


def test_the_design_rides_in_the_plan_summary(show: Plan) -> None:
    assert show.sequence is not None
    formations = show.sequence["formations"]
    assert [f.get("lights") for f in formations] == [None, "fade", "hold", "black"]
    assert set(formations[0]["colors"].values()) == {"#ff0000"}
    assert set(formations[3]["colors"].values()) == {"#0000ff"}  # kept from the one before
    slots = formations[1]["slots"]
    for vid, hexcolor in formations[1]["colors"].items():
        r, g, b = _slot_colors(9)[slots[vid]]
        assert hexcolor == f"#{r:02x}{g:02x}{b:02x}"


def test_a_sequence_without_colours_is_dark_as_before() -> None:
    plan = plan_sequence(show_sequence(4, seed=1, hold=0.0)).to_plan()
    assert plan.sequence is not None
    assert all("colors" not in f and "lights" not in f for f in plan.sequence["formations"])
    _, programs = _programs(plan)
    assert set(programs.values()) == {b"\x00"}


def test_the_encoder_and_its_reader_agree_with_the_independent_player() -> None:
    changes = [Change(0.0, 0.0, (1, 2, 3)), Change(1.0, 3.5, (200, 100, 50)),
               Change(200.0, 200.0, (9, 9, 9)), Change(201.0, 203.0, (0, 0, 0))]
    program = encode(changes, 210.0)
    times = np.linspace(0.0, 210.0, 2101)
    assert np.allclose(_play(program, times), colors_at(decode(program), times))
    # byte by byte, as the format reads: sleeps of 9,825 and 350 frames are two-byte varints
    assert program == bytes([
        0x04, 1, 2, 3, 0x00,         # SET_COLOR (1, 2, 3), no wait
        0x02, 50,                    # SLEEP 1 s
        0x08, 200, 100, 50, 125,     # FADE_TO_COLOR over 2.5 s
        0x02, 0xE1, 0x4C,            # SLEEP 9,825 frames (97 + 76 * 128)
        0x04, 9, 9, 9, 0x00,
        0x02, 50,
        0x08, 0, 0, 0, 100,
        0x02, 0xDE, 0x02,            # SLEEP 350 frames (94 + 2 * 128)
        0x00,                        # END
    ])


@pytest.mark.parametrize(("change", "field", "words"), [
    ({"color": "red"}, "formations[1].color", "#rrggbb"),
    ({"color": [1, 2, 300]}, "formations[1].color", "0..255"),
    ({"color": ["#000000"] * 2}, "formations[1].color", "one per position"),
    ({"color": ["#000000"] * 8 + ["#00000"]}, "formations[1].color[8]", "#rrggbb"),
    ({"lights": "blink"}, "formations[1].lights", "fade, hold, black"),
])
def test_a_bad_design_names_its_field(change: dict[str, Any], field: str, words: str) -> None:
    data = _design()
    data["formations"][1].update(change)
    with pytest.raises(ScenarioError) as caught:
        parse_sequence(data)
    assert caught.value.field == field
    assert words in caught.value.reason


def test_the_first_formation_has_no_transition() -> None:
    data = _design()
    data["formations"][0]["lights"] = "fade"
    with pytest.raises(ScenarioError, match=r"formations\[0\]\.lights"):
        parse_sequence(data)


def test_a_malformed_design_in_a_plan_file_is_refused_naming_it(show: Plan) -> None:
    import dataclasses

    assert show.sequence is not None
    broken = copy.deepcopy(show.sequence)
    del broken["formations"][2]["colors"][show.vehicles[0].id]
    with pytest.raises(ExportError) as caught:
        check_exportable(dataclasses.replace(show, sequence=broken))
    assert caught.value.field == "sequence.formations[2].colors"
    assert show.vehicles[0].id in caught.value.reason
