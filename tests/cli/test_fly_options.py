"""`fleetplan fly`'s flight-option flags say what the fleet file says: each flag with choices
takes exactly the `FlightOptions` field's values, and each help states the field's default,
which `FlightOptions` and the flags both take from `gcs.fleet.choices`."""

from __future__ import annotations

import argparse
import re

import pytest

from gcs.cli import fly_options
from gcs.fleet import choices
from gcs.fleet.fleetfile import OPTION_CHOICES, FlightOptions


def _help_entries(monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """Each option's help entry (flag, choices and text, on one line) by its argparse dest."""
    monkeypatch.setenv("COLUMNS", "400")
    parser = argparse.ArgumentParser()
    fly_options.add_flags(parser)
    entries = re.split(r"\n(?=  -)", parser.format_help().split("options:", 1)[1])
    found: dict[str, str] = {}
    for entry in filter(str.strip, entries):
        flag = entry.split()[0].rstrip(",")
        found[flag.removeprefix("--").replace("-", "_")] = " ".join(entry.split())
    return found


def test_every_option_flag_sets_a_flight_option() -> None:
    assert set(fly_options.OPTION_FLAGS.values()) <= set(FlightOptions().to_dict())


#: The defaults `gcs.fleet.choices` holds, by the `FlightOptions` field each is named after
#: (DEFAULT_<FIELD>).
_DEFAULTS = {name.removeprefix("DEFAULT_").lower(): getattr(choices, name)
             for name in choices.__all__ if name.startswith("DEFAULT_")}


def test_the_flight_options_defaults_are_the_choices_modules() -> None:
    """`FlightOptions` takes its fields' defaults from `gcs.fleet.choices` (each a field's),
    and every flag's field has one there, so the help cannot state another."""
    options = FlightOptions().to_dict()
    assert {field: options[field] for field in _DEFAULTS} == _DEFAULTS
    assert set(fly_options.OPTION_FLAGS.values()) <= set(_DEFAULTS)


@pytest.mark.parametrize(("flag", "field"), sorted(fly_options.OPTION_FLAGS.items()))
def test_a_flag_takes_the_fleet_files_choices_and_states_its_default(
    flag: str, field: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    entry = _help_entries(monkeypatch)[flag]
    default = getattr(FlightOptions(), field)
    assert (f"default {default:g}" if isinstance(default, float)
            else f"default {default}") in entry, entry
    if field == "policy":  # no argparse choices: checked as the fleet file's, named in the help
        assert ", ".join(OPTION_CHOICES[field]) in entry, entry
    elif field in OPTION_CHOICES:
        assert f"{{{','.join(OPTION_CHOICES[field])}}}" in entry, entry


def test_the_stream_priority_help_states_the_real_default(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    entry = _help_entries(monkeypatch)["stream_priority"]
    assert "default realtime" in entry and "default normal" not in entry, entry


def test_a_choice_outside_the_fleet_files_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    parser = argparse.ArgumentParser()
    fly_options.add_flags(parser)
    with pytest.raises(SystemExit):
        parser.parse_args(["--stream-priority", "fastest"])
    assert "invalid choice: 'fastest'" in capsys.readouterr().err
